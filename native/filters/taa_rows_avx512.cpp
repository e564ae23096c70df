// SPDX-License-Identifier: Apache-2.0
// The AVX-512 copy of taa's fast rows: 16 lanes (temporal/lanes.h Vec16).
// This unit alone is compiled for AVX-512 (native/CMakeLists.txt) and runs only
// where temporal::useAvx512() says the CPU has it; taa_rows.h says why it is a
// unit of its own. Same source and operations as the other copies, no FMA
// contraction: the same bits (tests run every copy the CPU has).
#include "filters/taa_rows.h"

namespace crisp::taa::rows {

void fastRowsAvx512(const Frame& f, const BandScratch& s, int y0, int y1, float* depthNow) {
  fastRowsBody<temporal::Vec16>(f, s, y0, y1, depthNow);
}

}  // namespace crisp::taa::rows
