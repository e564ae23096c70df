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
// every channel, a missing G or B repeats R, missing alpha is 1.
inline void stageColorRow(const ImageView& color, int y, float* rgba) {
  const int w = color.width, c = color.channels();
  const char* src = static_cast<const char*>(color.ptr) + std::size_t(y) * color.rowStride;
  if (c == 4 && color.pixelStride == 16) {
    // Packed RGBA: one element-wise pass the compiler vectorises.
    const float* p = reinterpret_cast<const float*>(src);
    for (int i = 0; i < 4 * w; ++i) rgba[i] = sanitizeColorLanes(p[i]);
    return;
  }
  for (int x = 0; x < w; ++x, src += color.pixelStride)
    stageColorPixel(reinterpret_cast<const float*>(src), c, rgba + 4 * x);
}

// Depth as the temporal filters use it (temporal/velocity.h sanitizeDepth):
// non-finite and far values (>= kFarDepth, NaN) read as kBackgroundDepth.
inline float sanitizedDepth(float d) { return d < kFarDepth ? d : kBackgroundDepth; }

// Row y of `depth` (channel 0) as packed sanitised depths.
inline void stageDepthRow(const ImageView& depth, int y, float* out) {
  const char* src = static_cast<const char*>(depth.ptr) + std::size_t(y) * depth.rowStride;
  const std::size_t stride = depth.pixelStride;
  if (stride == 4) {
    const float* p = reinterpret_cast<const float*>(src);
    for (int x = 0; x < depth.width; ++x) out[x] = sanitizedDepth(p[x]);
    return;
  }
  for (int x = 0; x < depth.width; ++x) {
    float d;
    std::memcpy(&d, src + std::size_t(x) * stride, sizeof d);
    out[x] = sanitizedDepth(d);
  }
}

}  // namespace crisp
