// SPDX-License-Identifier: Apache-2.0
// Colour spaces for temporal filters: YCoCg (Malvar & Sullivan 2003; the space
// INSIDE's and Karis' TAA clip in, seed 000 §3.6.4) and luma. All linear, so
// averages and blends commute with the conversion up to float rounding.
#pragma once

namespace crisp::temporal {

struct Float3 {
  float v[3];
  float& operator[](int i) { return v[i]; }
  float operator[](int i) const { return v[i]; }
};

// Y = R/4 + G/2 + B/4, Co = R/2 - B/2, Cg = -R/4 + G/2 - B/4.
inline Float3 rgbToYCoCg(const Float3& c) {
  return {{0.25f * c[0] + 0.5f * c[1] + 0.25f * c[2], 0.5f * c[0] - 0.5f * c[2], -0.25f * c[0] + 0.5f * c[1] - 0.25f * c[2]}};
}
// R = Y + Co - Cg, G = Y + Cg, B = Y - Co - Cg.
inline Float3 yCoCgToRgb(const Float3& c) { return {{c[0] + c[1] - c[2], c[0] + c[2], c[0] - c[1] - c[2]}}; }

// Rec. 709 luminance (core/color.h) on a Float3.
inline float luma709(const Float3& c) { return 0.2126f * c[0] + 0.7152f * c[1] + 0.0722f * c[2]; }

}  // namespace crisp::temporal
