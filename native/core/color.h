// SPDX-License-Identifier: Apache-2.0
// Colour helpers shared by filters and metrics.
#pragma once

#include <algorithm>
#include <cmath>

#include "core/conventions.h"

namespace crisp {

// Non-finite values never reach a filter: NaN -> 0, +-Inf -> +-kMaxColor.
inline float sanitizeColor(float v) {
  if (std::isnan(v)) return 0.0f;
  return std::clamp(v, -kMaxColor, kMaxColor);
}

// sanitizeColor as three selects, on a float or on every lane of a GCC vector of floats (the temporal
// kernels' Vec4 and Vec8, phlm's lanes): the same value for every input, in a form the compiler
// vectorises. Always inlined, so an AVX2 copy of a row loop runs it with AVX2.
template <class T>
__attribute__((always_inline)) inline T sanitizeColorLanes(T v) {
  v = v == v ? v : T{};
  v = v < -kMaxColor ? T{} - kMaxColor : v;
  return kMaxColor < v ? T{} + kMaxColor : v;
}

// Rec. 709 luminance of linear RGB.
inline float luminance709(float r, float g, float b) { return 0.2126f * r + 0.7152f * g + 0.0722f * b; }

// sRGB transfer function (IEC 61966-2-1) on a value clamped to [0, 1]: the
// display encoding used by PNG output and every metric.
inline float srgbEncode(float linear) {
  float v = std::clamp(linear, 0.0f, 1.0f);
  if (!(v == v)) v = 0.0f;
  if (v >= 1.0f) return 1.0f;  // 1.055f - 0.055f is not exactly 1 in float
  return v <= 0.0031308f ? 12.92f * v : 1.055f * std::pow(v, 1.0f / 2.4f) - 0.055f;
}
inline float srgbDecode(float encoded) {
  float v = std::clamp(encoded, 0.0f, 1.0f);
  return v <= 0.04045f ? v / 12.92f : std::pow((v + 0.055f) / 1.055f, 2.4f);
}

}  // namespace crisp
