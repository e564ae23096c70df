// SPDX-License-Identifier: Apache-2.0
// The row stagers of row_stage.h that are not inlined.
#include "core/row_stage.h"

namespace crisp {

void stageColorRow(const ImageView& color, int y, float* rgba) {
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

void stageDepthRow(const ImageView& depth, int y, float* out) {
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
