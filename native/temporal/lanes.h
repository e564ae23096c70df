// SPDX-License-Identifier: Apache-2.0
// Lane types for per-pixel code written once and run either one pixel at a
// time (float, bool: the scalar reference paths) or several at a time (GCC
// vector extensions: Vec4 in the SSE2 baseline copies, Vec8 = one AVX
// register in the AVX2 copies, Vec16 = one AVX-512 register in the AVX-512
// copies). The helpers below have the same meaning for both, lane
// by lane, and the build has no FMA contraction (-ffp-contract=off), so a
// kernel written against them gives the same bits in either form.
#pragma once

#include <cfloat>
#include <cmath>
#include <cstddef>
#include <cstring>
#include <type_traits>
#if defined(__SSE2__)
#include <immintrin.h>
#endif

#include "temporal/vec4.h"

// Vec8 by value between functions that are not inlined would change the ABI
// without AVX (GCC's -Wpsabi), and an out-of-line default-target copy called
// from an AVX2 clone would pass it by another ABI: every helper here is
// always inlined.
#pragma GCC diagnostic ignored "-Wpsabi"
#define CRISP_LANES_INLINE inline __attribute__((always_inline))

namespace crisp::temporal {

typedef float Vec8 __attribute__((vector_size(32)));
typedef int Mask8 __attribute__((vector_size(32)));  // per lane: -1 true, 0 false
typedef int Mask4 __attribute__((vector_size(16)));  // Vec4's (vec4.h)
typedef float Vec16 __attribute__((vector_size(64)));
typedef int Mask16 __attribute__((vector_size(64)));

// What a lane type is made of: float (1 lane, bool mask), Vec4 (4 lanes, one
// SSE register: the baseline copies of the fast paths) or Vec8 (8 lanes, one
// AVX register). The mask type is also the integer lane type (int32 lanes).
template <class T>
struct Lanes;
template <>
struct Lanes<float> {
  using Mask = bool;
  using Int = int;
  static constexpr int kCount = 1;
};
template <>
struct Lanes<Vec4> {
  using Mask = Mask4;
  using Int = Mask4;
  static constexpr int kCount = 4;
};
template <>
struct Lanes<Vec8> {
  using Mask = Mask8;
  using Int = Mask8;
  static constexpr int kCount = 8;
};
template <>
struct Lanes<Vec16> {
  using Mask = Mask16;
  using Int = Mask16;
  static constexpr int kCount = 16;
};
template <class T>
using MaskOfT = typename Lanes<T>::Mask;
template <class T>
using IntOf = typename Lanes<T>::Int;
template <class T>
constexpr int kLanesOf = Lanes<T>::kCount;
// The float lane type of an integer/mask lane type.
template <class M>
using FloatLanesOf =
    std::conditional_t<std::is_same_v<M, Mask16>, Vec16, std::conditional_t<std::is_same_v<M, Mask8>, Vec8, Vec4>>;
// Overloads for the vector lane types only (float and bool have their own).
template <class T>
using IfVector =
    std::enable_if_t<std::is_same_v<T, Vec4> || std::is_same_v<T, Vec8> || std::is_same_v<T, Vec16>, int>;
template <class M>
using IfMask =
    std::enable_if_t<std::is_same_v<M, Mask4> || std::is_same_v<M, Mask8> || std::is_same_v<M, Mask16>, int>;
// A Vec16's halves, and two halves joined (shuffles: registers, not memory).
CRISP_LANES_INLINE Vec8 lowHalf(Vec16 v) { return __builtin_shufflevector(v, v, 0, 1, 2, 3, 4, 5, 6, 7); }
CRISP_LANES_INLINE Vec8 highHalf(Vec16 v) { return __builtin_shufflevector(v, v, 8, 9, 10, 11, 12, 13, 14, 15); }
CRISP_LANES_INLINE Vec16 joinHalves(Vec8 lo, Vec8 hi) {
  return __builtin_shufflevector(lo, hi, 0, 1, 2, 3, 4, 5, 6, 7, 8, 9, 10, 11, 12, 13, 14, 15);
}

template <class T>
CRISP_LANES_INLINE T loadLanes(const float* p) {
  T v;
  std::memcpy(&v, p, sizeof v);
  return v;
}
template <class T>
CRISP_LANES_INLINE void storeLanes(float* p, T v) {
  std::memcpy(p, &v, sizeof v);
}
// Four channels of a lane group stored as packed pixels (p: r0 g0 b0 a0 r1 ...),
// transposed by shuffles instead of lane by lane.
template <class T, IfVector<T> = 0>
CRISP_LANES_INLINE void storeInterleaved4(float* p, T r, T g, T b, T a) {
  if constexpr (kLanesOf<T> == 16) {
    storeInterleaved4(p, lowHalf(r), lowHalf(g), lowHalf(b), lowHalf(a));
    storeInterleaved4(p + 32, highHalf(r), highHalf(g), highHalf(b), highHalf(a));
  } else if constexpr (kLanesOf<T> == 8) {
    const T rgLo = __builtin_shufflevector(r, g, 0, 8, 1, 9, 4, 12, 5, 13);  // r0 g0 r1 g1 | r4 g4 r5 g5
    const T rgHi = __builtin_shufflevector(r, g, 2, 10, 3, 11, 6, 14, 7, 15);
    const T baLo = __builtin_shufflevector(b, a, 0, 8, 1, 9, 4, 12, 5, 13);
    const T baHi = __builtin_shufflevector(b, a, 2, 10, 3, 11, 6, 14, 7, 15);
    const T p04 = __builtin_shufflevector(rgLo, baLo, 0, 1, 8, 9, 4, 5, 12, 13);  // pixel 0 | pixel 4
    const T p15 = __builtin_shufflevector(rgLo, baLo, 2, 3, 10, 11, 6, 7, 14, 15);
    const T p26 = __builtin_shufflevector(rgHi, baHi, 0, 1, 8, 9, 4, 5, 12, 13);
    const T p37 = __builtin_shufflevector(rgHi, baHi, 2, 3, 10, 11, 6, 7, 14, 15);
    storeLanes(p, T(__builtin_shufflevector(p04, p15, 0, 1, 2, 3, 8, 9, 10, 11)));
    storeLanes(p + 8, T(__builtin_shufflevector(p26, p37, 0, 1, 2, 3, 8, 9, 10, 11)));
    storeLanes(p + 16, T(__builtin_shufflevector(p04, p15, 4, 5, 6, 7, 12, 13, 14, 15)));
    storeLanes(p + 24, T(__builtin_shufflevector(p26, p37, 4, 5, 6, 7, 12, 13, 14, 15)));
  } else {
    const T rgLo = __builtin_shufflevector(r, g, 0, 4, 1, 5), rgHi = __builtin_shufflevector(r, g, 2, 6, 3, 7);
    const T baLo = __builtin_shufflevector(b, a, 0, 4, 1, 5), baHi = __builtin_shufflevector(b, a, 2, 6, 3, 7);
    storeLanes(p, T(__builtin_shufflevector(rgLo, baLo, 0, 1, 4, 5)));
    storeLanes(p + 4, T(__builtin_shufflevector(rgLo, baLo, 2, 3, 6, 7)));
    storeLanes(p + 8, T(__builtin_shufflevector(rgHi, baHi, 0, 1, 4, 5)));
    storeLanes(p + 12, T(__builtin_shufflevector(rgHi, baHi, 2, 3, 6, 7)));
  }
}

// storeInterleaved4's inverse: a lane group of packed pixels (p: r0 g0 b0 a0
// r1 ...) into four channel lanes, by shuffles.
template <class T, IfVector<T> = 0>
CRISP_LANES_INLINE void loadInterleaved4(const float* p, T& r, T& g, T& b, T& a) {
  if constexpr (kLanesOf<T> == 16) {
    Vec8 h[2][4];
    loadInterleaved4(p, h[0][0], h[0][1], h[0][2], h[0][3]);
    loadInterleaved4(p + 32, h[1][0], h[1][1], h[1][2], h[1][3]);
    r = joinHalves(h[0][0], h[1][0]);
    g = joinHalves(h[0][1], h[1][1]);
    b = joinHalves(h[0][2], h[1][2]);
    a = joinHalves(h[0][3], h[1][3]);
  } else if constexpr (kLanesOf<T> == 8) {
    const T q0 = loadLanes<T>(p), q1 = loadLanes<T>(p + 8), q2 = loadLanes<T>(p + 16), q3 = loadLanes<T>(p + 24);
    const T p04 = __builtin_shufflevector(q0, q2, 0, 1, 2, 3, 8, 9, 10, 11);  // pixel 0 | pixel 4
    const T p15 = __builtin_shufflevector(q0, q2, 4, 5, 6, 7, 12, 13, 14, 15);
    const T p26 = __builtin_shufflevector(q1, q3, 0, 1, 2, 3, 8, 9, 10, 11);
    const T p37 = __builtin_shufflevector(q1, q3, 4, 5, 6, 7, 12, 13, 14, 15);
    const T rgLo = __builtin_shufflevector(p04, p15, 0, 8, 1, 9, 4, 12, 5, 13);  // r0 r1 g0 g1 | r4 r5 g4 g5
    const T baLo = __builtin_shufflevector(p04, p15, 2, 10, 3, 11, 6, 14, 7, 15);
    const T rgHi = __builtin_shufflevector(p26, p37, 0, 8, 1, 9, 4, 12, 5, 13);  // r2 r3 g2 g3 | r6 r7 g6 g7
    const T baHi = __builtin_shufflevector(p26, p37, 2, 10, 3, 11, 6, 14, 7, 15);
    r = __builtin_shufflevector(rgLo, rgHi, 0, 1, 8, 9, 4, 5, 12, 13);
    g = __builtin_shufflevector(rgLo, rgHi, 2, 3, 10, 11, 6, 7, 14, 15);
    b = __builtin_shufflevector(baLo, baHi, 0, 1, 8, 9, 4, 5, 12, 13);
    a = __builtin_shufflevector(baLo, baHi, 2, 3, 10, 11, 6, 7, 14, 15);
  } else {
    const T q0 = loadLanes<T>(p), q1 = loadLanes<T>(p + 4), q2 = loadLanes<T>(p + 8), q3 = loadLanes<T>(p + 12);
    const T rg01 = __builtin_shufflevector(q0, q1, 0, 4, 1, 5), ba01 = __builtin_shufflevector(q0, q1, 2, 6, 3, 7);
    const T rg23 = __builtin_shufflevector(q2, q3, 0, 4, 1, 5), ba23 = __builtin_shufflevector(q2, q3, 2, 6, 3, 7);
    r = __builtin_shufflevector(rg01, rg23, 0, 1, 4, 5);
    g = __builtin_shufflevector(rg01, rg23, 2, 3, 6, 7);
    b = __builtin_shufflevector(ba01, ba23, 0, 1, 4, 5);
    a = __builtin_shufflevector(ba01, ba23, 2, 3, 6, 7);
  }
}

// Channels 0 and 1 of a lane group of packed pixels `step` = 2 or 4 floats
// apart (a motion pass), de-interleaved into x and y by shuffles: the values
// of a lane-by-lane copy.
template <class T, IfVector<T> = 0>
CRISP_LANES_INLINE void loadFirstTwoChannels(const float* p, int step, T& x, T& y) {
  if constexpr (std::is_same_v<T, Vec16>) {
    Vec8 x0, y0, x1, y1;
    loadFirstTwoChannels(p, step, x0, y0);
    loadFirstTwoChannels(p + 8 * step, step, x1, y1);
    x = joinHalves(x0, x1);
    y = joinHalves(y0, y1);
  } else if constexpr (std::is_same_v<T, Vec4>) {
    if (step == 2) {  // x0 y0 x1 y1 | x2 y2 x3 y3
      const T a = loadLanes<T>(p), b = loadLanes<T>(p + 4);
      x = __builtin_shufflevector(a, b, 0, 2, 4, 6);
      y = __builtin_shufflevector(a, b, 1, 3, 5, 7);
    } else {  // one pixel per load: a 4x4 transpose's first two rows
      const T a = loadLanes<T>(p), b = loadLanes<T>(p + 4), c = loadLanes<T>(p + 8), d = loadLanes<T>(p + 12);
      const T ab = __builtin_shufflevector(a, b, 0, 4, 1, 5), cd = __builtin_shufflevector(c, d, 0, 4, 1, 5);
      x = __builtin_shufflevector(ab, cd, 0, 1, 4, 5);
      y = __builtin_shufflevector(ab, cd, 2, 3, 6, 7);
    }
  } else {
    if (step == 2) {  // pixels 0-3 | pixels 4-7
      const T a = loadLanes<T>(p), b = loadLanes<T>(p + 8);
      x = __builtin_shufflevector(a, b, 0, 2, 4, 6, 8, 10, 12, 14);
      y = __builtin_shufflevector(a, b, 1, 3, 5, 7, 9, 11, 13, 15);
    } else {  // two pixels per load
      const T a = loadLanes<T>(p), b = loadLanes<T>(p + 8), c = loadLanes<T>(p + 16), d = loadLanes<T>(p + 24);
      const T ab = __builtin_shufflevector(a, b, 0, 4, 8, 12, 1, 5, 9, 13);  // x0-3 y0-3
      const T cd = __builtin_shufflevector(c, d, 0, 4, 8, 12, 1, 5, 9, 13);  // x4-7 y4-7
      x = __builtin_shufflevector(ab, cd, 0, 1, 2, 3, 8, 9, 10, 11);
      y = __builtin_shufflevector(ab, cd, 4, 5, 6, 7, 12, 13, 14, 15);
    }
  }
}

// storeInterleaved4's inverse for eight pixels held as Vec4s (pixel l's four
// channels in a[l]): channel c of pixel l in out[c][l], by shuffles.
CRISP_LANES_INLINE void transposeToLanes(const Vec4 a[8], Vec8 out[4]) {
  Vec8 p[4];  // pixel i | pixel i + 4
  for (int i = 0; i < 4; ++i) p[i] = __builtin_shufflevector(a[i], a[i + 4], 0, 1, 2, 3, 4, 5, 6, 7);
  const Vec8 t0 = __builtin_shufflevector(p[0], p[1], 0, 8, 1, 9, 4, 12, 5, 13);  // r0 r1 g0 g1 | r4 r5 g4 g5
  const Vec8 t1 = __builtin_shufflevector(p[0], p[1], 2, 10, 3, 11, 6, 14, 7, 15);
  const Vec8 t2 = __builtin_shufflevector(p[2], p[3], 0, 8, 1, 9, 4, 12, 5, 13);
  const Vec8 t3 = __builtin_shufflevector(p[2], p[3], 2, 10, 3, 11, 6, 14, 7, 15);
  out[0] = __builtin_shufflevector(t0, t2, 0, 1, 8, 9, 4, 5, 12, 13);
  out[1] = __builtin_shufflevector(t0, t2, 2, 3, 10, 11, 6, 7, 14, 15);
  out[2] = __builtin_shufflevector(t1, t3, 0, 1, 8, 9, 4, 5, 12, 13);
  out[3] = __builtin_shufflevector(t1, t3, 2, 3, 10, 11, 6, 7, 14, 15);
}

// One byte per lane (values 0..255) as int lanes, and back: a per-pixel byte
// plane read and written a lane group at a time, not lane by lane into a
// stack array read back as a vector, whose reload cannot be store-forwarded.
// Both convert through 16-bit lanes: GCC 12 lowers a direct 8 <-> 32-bit
// __builtin_convertvector to a byte-by-byte scalar loop (about 30
// instructions per group of 8 in taa's AVX2 rows), the two steps to
// vpmovzxbw/vpmovzxwd and vpackusdw/vpackuswb. storeBytesOf keeps the low 8
// bits.
typedef unsigned char Bytes4 __attribute__((vector_size(4)));
typedef unsigned char Bytes8 __attribute__((vector_size(8)));
typedef unsigned short Shorts4 __attribute__((vector_size(8)));
typedef unsigned short Shorts8 __attribute__((vector_size(16)));
typedef unsigned char Bytes16 __attribute__((vector_size(16)));
typedef unsigned short Shorts16 __attribute__((vector_size(32)));
template <class T>
using BytesOf = std::conditional_t<std::is_same_v<T, Vec16>, Bytes16,
                                   std::conditional_t<std::is_same_v<T, Vec8>, Bytes8, Bytes4>>;
template <class T>
using ShortsOf = std::conditional_t<std::is_same_v<T, Vec16>, Shorts16,
                                    std::conditional_t<std::is_same_v<T, Vec8>, Shorts8, Shorts4>>;
template <class T, IfVector<T> = 0>
CRISP_LANES_INLINE IntOf<T> loadBytesOf(const unsigned char* p) {
  BytesOf<T> b;
  std::memcpy(&b, p, sizeof b);
  return __builtin_convertvector(__builtin_convertvector(b, ShortsOf<T>), IntOf<T>);
}
template <class T, IfVector<T> = 0>
CRISP_LANES_INLINE void storeBytesOf(unsigned char* p, IntOf<T> v) {
  const BytesOf<T> b = __builtin_convertvector(__builtin_convertvector(v & 0xff, ShortsOf<T>), BytesOf<T>);
  std::memcpy(p, &b, sizeof b);
}

// A float broadcast to the lane type.
template <class T>
CRISP_LANES_INLINE T lanesOf(float v) {
  if constexpr (std::is_same_v<T, float>) {
    return v;
  } else {
    T r;
    for (int l = 0; l < kLanesOf<T>; ++l) r[l] = v;
    return r;
  }
}
// 0, 1, 2, ... in the lanes (0 for one pixel).
template <class T>
CRISP_LANES_INLINE T laneIndexOf() {
  if constexpr (std::is_same_v<T, float>) {
    return 0.0f;
  } else {
    T r;
    for (int l = 0; l < kLanesOf<T>; ++l) r[l] = float(l);
    return r;
  }
}

// Same operand order as std::min / std::max (which of +0 / -0 is returned;
// NaN as they do). Any lane type: float, Vec4, Vec8, or another GCC vector.
template <class T>
CRISP_LANES_INLINE T minOf(T a, T b) {
  return b < a ? b : a;
}
template <class T>
CRISP_LANES_INLINE T maxOf(T a, T b) {
  return a < b ? b : a;
}
// std::clamp(v, lo, hi).
template <class T>
CRISP_LANES_INLINE T clampOf(T v, T lo, T hi) {
  return v < lo ? lo : (hi < v ? hi : v);
}
// a < 0 ? -a : a (keeps -0, as temporal::vabs).
template <class T>
CRISP_LANES_INLINE T absOf(T a) {
  return a < T{} ? -a : a;
}
// std::fabs (clears the sign bit).
CRISP_LANES_INLINE float fabsOf(float a) { return std::fabs(a); }
template <class T, IfVector<T> = 0>
CRISP_LANES_INLINE T fabsOf(T a) {
  return (T)((IntOf<T>)a & 0x7fffffff);
}
// std::sqrt per lane. IEEE square roots are correctly rounded, so sqrtps
// (SSE, baseline on x86-64; two of them for Vec8, in any target) gives the
// scalar form's bits; GCC does not vectorise a lane loop of std::sqrt.
// Vec8's halves are split and joined in registers (vextractf128 /
// vinsertf128 in the AVX2 copy): through memory, as two 16-byte stores read
// back by one 32-byte load, the load cannot be forwarded from the stores and
// stalls; perf put 15 % of taa's fast path on that load.
CRISP_LANES_INLINE float sqrtOf(float a) { return std::sqrt(a); }
#if defined(__SSE2__)
CRISP_LANES_INLINE Vec4 sqrtOf(Vec4 a) { return (Vec4)_mm_sqrt_ps((__m128)a); }
CRISP_LANES_INLINE Vec8 sqrtOf(Vec8 a) {
  const Vec4 lo = sqrtOf(Vec4(__builtin_shufflevector(a, a, 0, 1, 2, 3)));
  const Vec4 hi = sqrtOf(Vec4(__builtin_shufflevector(a, a, 4, 5, 6, 7)));
  return __builtin_shufflevector(lo, hi, 0, 1, 2, 3, 4, 5, 6, 7);
}
#endif
#if defined(__AVX512F__)
// Vec16 runs only in units compiled for AVX-512 (filters/taa_rows_avx512.cpp).
// The masked form with every lane set: the same vsqrtps, and GCC 12 does not
// warn about _mm512_sqrt_ps's undefined pass-through operand.
CRISP_LANES_INLINE Vec16 sqrtOf(Vec16 a) { return (Vec16)_mm512_mask_sqrt_ps((__m512)a, 0xffff, (__m512)a); }
#endif
#if !defined(__SSE2__)
template <class T, IfVector<T> = 0>
CRISP_LANES_INLINE T sqrtOf(T a) {
  for (int l = 0; l < kLanesOf<T>; ++l) a[l] = std::sqrt(a[l]);
  return a;
}
#endif
// std::isfinite.
CRISP_LANES_INLINE bool finiteOf(float a) { return std::isfinite(a); }
template <class T, IfVector<T> = 0>
CRISP_LANES_INLINE MaskOfT<T> finiteOf(T a) {
  return fabsOf(a) <= lanesOf<T>(FLT_MAX);
}
CRISP_LANES_INLINE bool notOf(bool m) { return !m; }
template <class M, IfMask<M> = 0>
CRISP_LANES_INLINE M notOf(M m) {
  return ~m;
}
CRISP_LANES_INLINE bool anyOf(bool m) { return m; }
// Halves folded by shuffles (no lane-by-lane extraction; the same answer).
template <class M, IfMask<M> = 0>
CRISP_LANES_INLINE bool anyOf(M m) {
  if constexpr (sizeof(M) == 16 * sizeof(int)) {
    return anyOf(Mask8(__builtin_shufflevector(m, m, 0, 1, 2, 3, 4, 5, 6, 7) |
                    __builtin_shufflevector(m, m, 8, 9, 10, 11, 12, 13, 14, 15)));
  } else if constexpr (sizeof(M) == 8 * sizeof(int)) {
    return anyOf(Mask4(__builtin_shufflevector(m, m, 0, 1, 2, 3) | __builtin_shufflevector(m, m, 4, 5, 6, 7)));
  } else if constexpr (sizeof(M) == 4 * sizeof(int)) {
    const auto p = __builtin_shufflevector(m, m, 0, 1) | __builtin_shufflevector(m, m, 2, 3);
    return (p[0] | p[1]) != 0;
  } else {
    int any = 0;
    for (int i = 0; i < int(sizeof(M) / sizeof(int)); ++i) any |= m[i];
    return any != 0;
  }
}
CRISP_LANES_INLINE bool allOf(bool m) { return m; }
template <class M, IfMask<M> = 0>
CRISP_LANES_INLINE bool allOf(M m) {
  if constexpr (sizeof(M) == 16 * sizeof(int)) {
    return allOf(Mask8(__builtin_shufflevector(m, m, 0, 1, 2, 3, 4, 5, 6, 7) &
                    __builtin_shufflevector(m, m, 8, 9, 10, 11, 12, 13, 14, 15)));
  } else if constexpr (sizeof(M) == 8 * sizeof(int)) {
    return allOf(Mask4(__builtin_shufflevector(m, m, 0, 1, 2, 3) & __builtin_shufflevector(m, m, 4, 5, 6, 7)));
  } else if constexpr (sizeof(M) == 4 * sizeof(int)) {
    const auto p = __builtin_shufflevector(m, m, 0, 1) & __builtin_shufflevector(m, m, 2, 3);
    return (p[0] & p[1]) != 0;
  } else {
    int all = -1;
    for (int i = 0; i < int(sizeof(M) / sizeof(int)); ++i) all &= m[i];
    return all != 0;
  }
}
// Float lanes to int lanes (truncation) and back. Only for values inside the
// int range (callers clamp first).
CRISP_LANES_INLINE int truncOf(float v) { return int(v); }
template <class T, IfVector<T> = 0>
CRISP_LANES_INLINE IntOf<T> truncOf(T v) {
  return __builtin_convertvector(v, IntOf<T>);
}
CRISP_LANES_INLINE float floatOf(int v) { return float(v); }
template <class M, IfMask<M> = 0>
CRISP_LANES_INLINE FloatLanesOf<M> floatOf(M v) {
  return __builtin_convertvector(v, FloatLanesOf<M>);
}
// plane[y * width + x] per lane.
CRISP_LANES_INLINE float gatherOf(const float* plane, int width, int x, int y) {
  return plane[std::size_t(y) * std::size_t(width) + std::size_t(x)];
}
template <class M, IfMask<M> = 0>
CRISP_LANES_INLINE FloatLanesOf<M> gatherOf(const float* plane, int width, M x, M y) {
  FloatLanesOf<M> v;
  for (int l = 0; l < int(sizeof(M) / sizeof(int)); ++l)
    v[l] = plane[std::size_t(y[l]) * std::size_t(width) + std::size_t(x[l])];
  return v;
}

// Lane l of a value.
CRISP_LANES_INLINE void setLane(float& v, int, float x) { v = x; }
template <class T, IfVector<T> = 0>
CRISP_LANES_INLINE void setLane(T& v, int l, float x) {
  v[l] = x;
}
// Calls fn(l) for every set lane of m. An empty mask (the common case at
// every call) is tested as a vector first: the lane-by-lane loop reads the
// mask back from memory one lane at a time (perf: 4 % of taa's 16-lane pan
// on that loop when no lane was set).
template <class Fn>
CRISP_LANES_INLINE void forEachLane(bool m, Fn&& fn) {
  if (m) fn(0);
}
template <class M, class Fn, IfMask<M> = 0>
CRISP_LANES_INLINE void forEachLane(M m, Fn&& fn) {
  if (!anyOf(m)) return;
  for (int l = 0; l < int(sizeof(M) / sizeof(int)); ++l)
    if (m[l]) fn(l);
}

}  // namespace crisp::temporal
