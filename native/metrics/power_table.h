// SPDX-License-Identifier: Apache-2.0
// Tabulated power functions for the metrics' colour conversions. powf/cbrtf
// cost 20-40 ns each and the metrics need up to ~14 per pixel (sRGB
// encode/decode, CIELAB cube roots); a 4097-entry table with linear
// interpolation costs a few ns and is accurate to ~1e-7 absolute on [0,1]
// (tests/unit/test_metrics.cpp checks the bounds against the exact functions).
#pragma once

#include <algorithm>
#include <cmath>
#include <vector>

namespace crisp::metrics_detail {

// f on [0,1], tabulated at u = i / kSize. Lookups for v in [0,1]; values a
// little above 1 (rounding) extrapolate the last segment.
//  * Uniform: v -> f(v). For functions with bounded second derivative on [0,1]
//    (e.g. t^2.4): error <= max|f''| / (8 kSize^2).
//  * SqrtDomain: v -> f(sqrt(v)), the table holds g(u) = f(u^2). Used for
//    roots (t^(1/3), t^(1/2.4)) whose curvature is unbounded at 0: in u the
//    curvature stays moderate away from 0, where callers use their linear toe.
class PowerTable {
 public:
  static constexpr int kSize = 4096;
  enum Domain { Uniform, SqrtDomain };

  template <class F>
  PowerTable(Domain domain, F&& f) : domain_(domain), table_(kSize + 2) {
    for (int i = 0; i <= kSize + 1; ++i) {
      const double u = double(i) / kSize;
      table_[std::size_t(i)] = float(domain == Uniform ? f(u) : f(u * u));
    }
  }

  float operator()(float v) const {
    const float u = domain_ == Uniform ? v : std::sqrt(v);
    const float pos = u * float(kSize);
    const int i = std::clamp(int(pos), 0, kSize);
    const float frac = pos - float(i);
    const float a = table_[std::size_t(i)], b = table_[std::size_t(i) + 1];
    return a + frac * (b - a);
  }

 private:
  Domain domain_;
  std::vector<float> table_;
};

// The tables, built once (thread-safe static initialisation). Hot loops fetch
// them once and pass them in, keeping the guard check out of the loop.
inline const PowerTable& srgbEncodeTable() {
  static const PowerTable t(PowerTable::SqrtDomain, [](double v) { return 1.055 * std::pow(v, 1.0 / 2.4) - 0.055; });
  return t;
}
inline const PowerTable& srgbDecodeTable() {
  static const PowerTable t(PowerTable::Uniform, [](double e) { return std::pow((e + 0.055) / 1.055, 2.4); });
  return t;
}
inline const PowerTable& cbrtTable() {
  static const PowerTable t(PowerTable::SqrtDomain, [](double v) { return std::cbrt(v); });
  return t;
}

// sRGB encoding (IEC 61966-2-1) of a linear value, clamped to [0,1], NaN -> 0.
// Same function as core/color.h srgbEncode, within ~2e-7.
inline float fastSrgbEncode(float linear, const PowerTable& table = srgbEncodeTable()) {
  float v = std::clamp(linear, 0.0f, 1.0f);
  if (!(v == v)) v = 0.0f;
  return v <= 0.0031308f ? 12.92f * v : table(v);
}

// sRGB decoding of an encoded value clamped to [0,1], NaN -> 0. Same function
// as core/color.h srgbDecode, within ~1e-7.
inline float fastSrgbDecode(float encoded, const PowerTable& table = srgbDecodeTable()) {
  float v = std::clamp(encoded, 0.0f, 1.0f);
  if (!(v == v)) v = 0.0f;
  return v <= 0.04045f ? v / 12.92f : table(v);
}

// Cube root of t in [0, ~1] (CIELAB's f above its linear toe, t > 0.008856).
inline float fastCbrt(float t, const PowerTable& table = cbrtTable()) { return table(t); }

}  // namespace crisp::metrics_detail
