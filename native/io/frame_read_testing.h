// SPDX-License-Identifier: Apache-2.0
// For tests that compare readFrame's two OpenEXR readers. Not part of the
// public interface; the core reader is allowed in normal use.
#pragma once

namespace crisp {

// Allows (the default) or forbids readFrame's use of OpenEXR's C library
// ("core") reader; forbidden, every EXR is read by the C++ library's reader.
void allowExrCoreReaderForTesting(bool allowed);

}  // namespace crisp
