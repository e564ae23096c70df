// SPDX-License-Identifier: Apache-2.0
// PHLM's row staging (phlm.cpp Kernel::run), in a file of its own so the unit
// tests can check what it stages against the formulas, independently of the
// kernel (test_phlm.cpp PhlmStage.*): the kernel's fast and reference paths
// both read these rows, so comparing the two paths cannot catch a wrong one.
#pragma once

#include <cstdint>

#include "core/image.h"
#include "temporal/isa.h"

namespace crisp::phlm {

// What Kernel::run stages of one input row: the sanitised colour with the
// tonemapped luminance in lane 3 (the luminance range of §5.1, Delta and l,
// on tonemapped YCgCo luminance), whether every alpha of the row is 1 (or
// absent: finishBatch then does not read it again for the output's alpha),
// the sanitised depth and, on the fast path with motion, the moving flags.
struct StagedRow {
  ImageView color, depth, motion;
  float* staged;             // width x height packed RGBA
  std::uint8_t* alphaOne;    // per row
  float* depthOut;           // or null
  std::uint8_t* movingFlags;  // or null
};

// One row y of r. The baseline copy (Vec4 lane groups) runs on the reference
// path and without AVX2, the AVX2 copy (Vec8) on the fast path; both give the
// same bits.
void stageRowBaseline(const StagedRow& r, int y);
#ifdef CRISP_TEMPORAL_HAS_AVX2
void stageRowAvx2(const StagedRow& r, int y);
#endif

}  // namespace crisp::phlm
