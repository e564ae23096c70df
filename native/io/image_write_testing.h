// SPDX-License-Identifier: Apache-2.0
// Fault injection for tests of writeImage's all-or-nothing guarantee. Not part
// of the public interface; the hook is empty in normal use.
#pragma once

#include <functional>
#include <string>

namespace crisp {

// Called with the temporary file's path after it is fully written and before
// it is renamed into place; a hook that throws simulates a late failure (disk
// full, close error). Pass an empty function to clear it. Not thread-safe:
// for single-threaded tests only.
void setWriteImageFaultForTesting(std::function<void(const std::string& temporaryPath)> hook);

}  // namespace crisp
