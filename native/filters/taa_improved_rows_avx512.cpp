// SPDX-License-Identifier: Apache-2.0
// The AVX-512 copy of taa-improved's fused band: 16 lanes (temporal/lanes.h
// Vec16). Compiled for AVX-512 as a unit of its own (native/CMakeLists.txt;
// taa_rows.h says why) and run only where temporal::useAvx512() says the CPU
// has it. Same source and operations as the other copies: the same bits.
#include "filters/taa_improved_rows.h"

namespace crisp::taa_improved::rows {

void bandAvx512(const Frame& f, const BandRings& r, int y0, int y1) { bandBody<temporal::Vec16>(f, r, y0, y1); }

}  // namespace crisp::taa_improved::rows
