// SPDX-License-Identifier: Apache-2.0
// Lane types for per-pixel code written once and run either one pixel at a
// time (float, bool: the scalar reference paths) or eight pixels at a time
// (Vec8, Mask8: GCC vector extensions, one AVX register; two SSE registers in
// the baseline copy). The helpers below have the same meaning for both, lane
// by lane, and the build has no FMA contraction (-ffp-contract=off), so a
// kernel written against them gives the same bits in either form.
#pragma once

#include <cfloat>
#include <cmath>
#include <cstddef>
#include <cstring>
#include <type_traits>

// Vec8 by value between functions that are not inlined would change the ABI
// without AVX (GCC's -Wpsabi); every helper here is inlined.
#pragma GCC diagnostic ignored "-Wpsabi"

namespace crisp::temporal {

typedef float Vec8 __attribute__((vector_size(32)));
typedef int Mask8 __attribute__((vector_size(32)));  // per lane: -1 true, 0 false
constexpr int kLanes8 = 8;

inline Vec8 load8(const float* p) {
  Vec8 v;
  std::memcpy(&v, p, sizeof v);
  return v;
}
inline void store8(float* p, Vec8 v) { std::memcpy(p, &v, sizeof v); }

// A float broadcast to the lane type.
template <class T>
inline T lanesOf(float v);
template <>
inline float lanesOf<float>(float v) {
  return v;
}
template <>
inline Vec8 lanesOf<Vec8>(float v) {
  return Vec8{v, v, v, v, v, v, v, v};
}

// The mask and integer lane types of a lane type (Mask8 is both for Vec8).
template <class T>
using MaskOfT = std::conditional_t<std::is_same_v<T, float>, bool, Mask8>;
template <class T>
using IntOf = std::conditional_t<std::is_same_v<T, float>, int, Mask8>;

// Same operand order as std::min / std::max (which of +0 / -0 is returned;
// NaN as they do). Any lane type: float, Vec8, or another GCC vector.
template <class T>
inline T minOf(T a, T b) {
  return b < a ? b : a;
}
template <class T>
inline T maxOf(T a, T b) {
  return a < b ? b : a;
}
// std::clamp(v, lo, hi).
template <class T>
inline T clampOf(T v, T lo, T hi) {
  return v < lo ? lo : (hi < v ? hi : v);
}
// a < 0 ? -a : a (keeps -0, as temporal::vabs).
template <class T>
inline T absOf(T a) {
  return a < T{} ? -a : a;
}
// std::fabs (clears the sign bit).
inline float fabsOf(float a) { return std::fabs(a); }
inline Vec8 fabsOf(Vec8 a) { return (Vec8)((Mask8)a & 0x7fffffff); }
// std::isfinite.
inline bool finiteOf(float a) { return std::isfinite(a); }
inline Mask8 finiteOf(Vec8 a) { return fabsOf(a) <= lanesOf<Vec8>(FLT_MAX); }
inline bool notOf(bool m) { return !m; }
inline Mask8 notOf(Mask8 m) { return ~m; }
inline bool anyOf(bool m) { return m; }
inline bool anyOf(Mask8 m) {
  Mask8 r = m;
  int any = 0;
  for (int i = 0; i < kLanes8; ++i) any |= r[i];
  return any != 0;
}
// Float lanes to int lanes (truncation) and back. Only for values inside the
// int range (callers clamp first).
inline int truncOf(float v) { return int(v); }
inline Mask8 truncOf(Vec8 v) { return __builtin_convertvector(v, Mask8); }
inline float floatOf(int v) { return float(v); }
inline Vec8 floatOf(Mask8 v) { return __builtin_convertvector(v, Vec8); }
// plane[y * width + x] per lane.
inline float gatherOf(const float* plane, int width, int x, int y) {
  return plane[std::size_t(y) * std::size_t(width) + std::size_t(x)];
}
inline Vec8 gatherOf(const float* plane, int width, Mask8 x, Mask8 y) {
  Vec8 v;
  for (int l = 0; l < kLanes8; ++l) v[l] = plane[std::size_t(y[l]) * std::size_t(width) + std::size_t(x[l])];
  return v;
}

// Lane l of a value (l = 0 for the scalar form).
inline float laneOf(float v, int) { return v; }
inline float laneOf(Vec8 v, int l) { return v[l]; }
inline bool laneOf(bool m, int) { return m; }
inline bool laneOf(Mask8 m, int l) { return m[l] != 0; }
inline int intLaneOf(int v, int) { return v; }
inline int intLaneOf(Mask8 v, int l) { return v[l]; }
inline void setLane(float& v, int, float x) { v = x; }
inline void setLane(Vec8& v, int l, float x) { v[l] = x; }
// Calls fn(l) for every set lane of m.
template <class Fn>
inline void forEachLane(bool m, Fn&& fn) {
  if (m) fn(0);
}
template <class Fn>
inline void forEachLane(Mask8 m, Fn&& fn) {
  for (int l = 0; l < kLanes8; ++l)
    if (m[l]) fn(l);
}

}  // namespace crisp::temporal
