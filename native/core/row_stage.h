// SPDX-License-Identifier: Apache-2.0
// Row staging shared by the kernels that read the input row by row (taa,
// taa-improved, phlm): one image row of a strided view into a packed scratch
// row, sanitised by the conventions of conventions.h, so each kernel stages
// the same values with the same code. Filter::stageColor (filter.cpp) is the
// whole-image form of stageColorRow.
#pragma once

#include <cstddef>
#include <cstring>

#include "core/color.h"
#include "core/image.h"

namespace crisp {

// One pixel p of `channels` (1-4) floats as RGBA: sanitizeColor on every
// channel, a missing G or B repeats R, missing alpha is 1.
inline void stageColorPixel(const float* p, int channels, float rgba[4]) {
  rgba[0] = sanitizeColor(p[0]);
  rgba[1] = sanitizeColor(channels > 1 ? p[1] : p[0]);
  rgba[2] = sanitizeColor(channels > 2 ? p[2] : p[0]);
  rgba[3] = channels > 3 ? sanitizeColor(p[3]) : 1.0f;
}

// Row y of `color` (1-4 float channels) as packed RGBA: sanitizeColor on
// every channel, a missing G or B repeats R, missing alpha is 1. Out of line
// (row_stage.cpp), called once per row: the AVX-512 unit (filters/taa_rows.h)
// calls it and so never defines a copy of its own that others could take.
void stageColorRow(const ImageView& color, int y, float* rgba);

// Depth as the temporal filters use it (temporal/velocity.h sanitizeDepth):
// non-finite and far values (>= kFarDepth, NaN) read as kBackgroundDepth.
inline float sanitizedDepth(float d) { return d < kFarDepth ? d : kBackgroundDepth; }

// Row y of `depth` (channel 0) as packed sanitised depths (row_stage.cpp).
void stageDepthRow(const ImageView& depth, int y, float* out);

}  // namespace crisp
