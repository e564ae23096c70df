// SPDX-License-Identifier: Apache-2.0
// A 4-lane float vector (GCC/Clang vector extension: one SSE/NEON register)
// for per-pixel RGBA work in the temporal kernels. Lane-wise IEEE arithmetic
// only (no fused multiply-add: the build uses -ffp-contract=off), so a kernel
// gives the same bits whichever path or thread runs it.
#pragma once

#include <cmath>
#include <cstring>

namespace crisp::temporal {

typedef float Vec4 __attribute__((vector_size(16)));

inline Vec4 load4(const float* p) {
  Vec4 v;
  std::memcpy(&v, p, sizeof v);
  return v;
}
inline void store4(float* p, Vec4 v) { std::memcpy(p, &v, sizeof v); }
inline Vec4 splat(float s) { return Vec4{s, s, s, s}; }
// Same operand order as std::min / std::max.
inline Vec4 vmin(Vec4 a, Vec4 b) { return b < a ? b : a; }
inline Vec4 vmax(Vec4 a, Vec4 b) { return a < b ? b : a; }
inline Vec4 vabs(Vec4 a) { return a < 0.0f ? -a : a; }
// std::fabs per lane (clears the sign bit: -0 -> +0 as fabs does; vabs keeps -0).
inline Vec4 vfabs(Vec4 a) {
  typedef int Int4 __attribute__((vector_size(16)));
  return (Vec4)((Int4)a & 0x7fffffff);
}
// Correctly rounded square root per lane (the same bits as std::sqrt).
inline Vec4 vsqrt(Vec4 v) {
#if defined(__SSE__) && defined(__GNUC__) && !defined(__clang__)
  return __builtin_ia32_sqrtps(v);
#else
  for (int i = 0; i < 4; ++i) v[i] = std::sqrt(v[i]);
  return v;
#endif
}

}  // namespace crisp::temporal
