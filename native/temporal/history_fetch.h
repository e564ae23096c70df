// SPDX-License-Identifier: Apache-2.0
// Filtered fetch of a reprojected history (seed 000 §3.6.3: the history is
// read where the pixel was in the previous frame; seed 004 "TAA steps" 4-5).
// Positions are in pixel-index units: the centre of pixel (i, j) is (i, j).
// Addressing is clamp-to-edge, as a texture sampler with clamp addressing.
// The buffer is packed RGBA float (4 floats per pixel, the fourth is carried).
#pragma once

#include <algorithm>
#include <cmath>
#include <cstddef>
#include <type_traits>

#include "temporal/lanes.h"
#include "temporal/vec4.h"

namespace crisp::temporal {

// True when every lane of a whole group is valid and lane l's footprint
// starts at (x0[0] + l, y0[0]) with taps left .. x0 + right and top .. y0 +
// bottom all inside [0, w) x [0, h): then the lanes' taps are consecutive in
// memory and clamping changes none. False for one pixel (T = float: the
// reference gathers as before).
template <class T>
__attribute__((always_inline)) inline bool sharedInteriorOffset(IntOf<T> x0, IntOf<T> y0, MaskOfT<T> valid, int left,
                                                                int right, int top, int bottom, int w, int h) {
  if constexpr (std::is_same_v<T, float>) {
    return false;
  } else {
    using Int = IntOf<T>;
    constexpr int kL = kLanesOf<T>;
    const int gx = x0[0], gy = y0[0];
    return allOf(valid) && allOf(Int(Int(x0 - truncOf(laneIndexOf<T>()) == gx) & Int(y0 == gy))) && gx + left >= 0 &&
           gx + kL - 1 + right < w && gy + top >= 0 && gy + bottom < h;
  }
}

struct HistoryImage {
  const float* data;  // 4 floats per pixel, rows top-down
  int width;
  int height;
  const float* at(int x, int y) const { return data + (std::size_t(y) * std::size_t(width) + std::size_t(x)) * 4; }
};

// True when (x, y) lies on a pixel of a width x height image (centres at
// integers, so the image covers [-0.5, size - 0.5]); false for NaN/Inf too.
inline bool onScreen(float x, float y, int width, int height) {
  return x >= -0.5f && y >= -0.5f && x <= float(width) - 0.5f && y <= float(height) - 0.5f;
}

// Bilinear weights at fractional position t: (1 - t, t) for the taps floor, floor + 1.
struct Footprint {
  int x0, y0;    // top-left tap (may be -1 or size - 1 + 1: clamped on read)
  float tx, ty;  // fractions in [0, 1)
};
// floor without a libm call (x86-64 without SSE4.1 has no rounding
// instruction): truncate, step down for negative non-integers. Exact for
// |x| < 2^23; larger floats are integers already (and NaN stays NaN).
inline float floorExact(float x) {
  if (!(std::fabs(x) < 8388608.0f)) return x;
  const float t = float(int(x));
  return t > x ? t - 1.0f : t;
}
// floorExact on vector lanes (lanes.h: Vec4, Vec8), the same values lane by lane.
template <class T, IfVector<T> = 0>
CRISP_LANES_INLINE T floorExact(T x) {
  const MaskOfT<T> big = notOf(fabsOf(x) < 8388608.0f);
  const T safe = big ? lanesOf<T>(0.0f) : x;
  const T t = floatOf(truncOf(safe));
  return big ? x : (t > safe ? t - 1.0f : t);
}
inline Footprint footprintOf(float x, float y) {
  const float fx = floorExact(x), fy = floorExact(y);
  return {int(fx), int(fy), x - fx, y - fy};
}

// The history as four planes (channels 0-2 filtered, 3 carried): the layout
// the taa kernel keeps, so a lane group's taps are contiguous loads. The
// fetches below take either layout and give the same bits for both.
struct HistoryPlanes {
  const float* plane[4];
  int width;
  int height;
  std::size_t index(int x, int y) const { return std::size_t(y) * std::size_t(width) + std::size_t(x); }
};

// Pixel (x, y) as RGBA, from either layout.
inline Vec4 tapOf(const HistoryImage& h, int x, int y) { return load4(h.at(x, y)); }
inline Vec4 tapOf(const HistoryPlanes& h, int x, int y) {
  const std::size_t i = h.index(x, y);
  return Vec4{h.plane[0][i], h.plane[1][i], h.plane[2][i], h.plane[3][i]};
}

// Bilinear fetch of the first 3 channels; out[3] = the carried channel of the
// nearest tap (never interpolated). H: HistoryImage or HistoryPlanes.
template <class H>
CRISP_LANES_INLINE Vec4 fetchBilinear4(const H& h, float x, float y) {
  const Footprint f = footprintOf(x, y);
  const int xa = std::clamp(f.x0, 0, h.width - 1), xb = std::clamp(f.x0 + 1, 0, h.width - 1);
  const int ya = std::clamp(f.y0, 0, h.height - 1), yb = std::clamp(f.y0 + 1, 0, h.height - 1);
  const Vec4 p00 = tapOf(h, xa, ya), p10 = tapOf(h, xb, ya);
  const Vec4 p01 = tapOf(h, xa, yb), p11 = tapOf(h, xb, yb);
  const Vec4 top = p00 + (p10 - p00) * f.tx;
  const Vec4 bottom = p01 + (p11 - p01) * f.tx;
  Vec4 out = top + (bottom - top) * f.ty;
  out[3] = tapOf(h, f.tx < 0.5f ? xa : xb, f.ty < 0.5f ? ya : yb)[3];
  return out;
}
inline void fetchBilinear(const HistoryImage& h, float x, float y, float out[4]) { store4(out, fetchBilinear4(h, x, y)); }

// Catmull-Rom (cubic convolution, Keys 1981 with a = -0.5) weights of the taps
// floor - 1 .. floor + 2 at fraction t. They sum to 1; w0 and w3 are <= 0.
// T: float, or a lane type (lanes.h) for a lane group's fractions.
template <class T>
CRISP_LANES_INLINE void catmullRomWeights(T t, T w[4]) {
  w[0] = t * (-0.5f + t * (1.0f - 0.5f * t));
  w[1] = 1.0f + t * t * (-2.5f + 1.5f * t);
  w[2] = t * (0.5f + t * (2.0f - 1.5f * t));
  w[3] = t * t * (-0.5f + 0.5f * t);
}

// Row j (0-3) of a 4x4 Catmull-Rom footprint on lanes T (lanes.h, or any
// vector type minOf / maxOf take): adds the row's taps weighted by wx, times
// wy, to acc; rows 1 and 2 set lo / hi, the range of the central 2x2 the
// result is clamped to (catmullRomClamped). The order of operations is the
// fetches' (fetchCatmullRomAt4 spells the same steps on Vec4 with scalar
// weights).
template <class T>
CRISP_LANES_INLINE void addCatmullRomRow(const T tap[4], const T wx[4], T wy, int j, T& acc, T& lo, T& hi) {
  const T r = ((tap[0] * wx[0] + tap[1] * wx[1]) + tap[2] * wx[2]) + tap[3] * wx[3];
  acc = acc + r * wy;
  if (j == 1) {
    lo = minOf(tap[1], tap[2]);
    hi = maxOf(tap[1], tap[2]);
  } else if (j == 2) {
    lo = minOf(lo, minOf(tap[1], tap[2]));
    hi = maxOf(hi, maxOf(tap[1], tap[2]));
  }
}
template <class T>
CRISP_LANES_INLINE T catmullRomClamped(T acc, T lo, T hi) {
  return minOf(maxOf(acc, lo), hi);
}

// True when the 4x4 Catmull-Rom footprint at f lies inside the image, so
// clamp-to-edge addressing changes no tap.
inline bool footprintInterior4x4(const Footprint& f, int width, int height) {
  return f.x0 >= 1 && f.y0 >= 1 && f.x0 + 2 < width && f.y0 + 2 < height;
}

// Catmull-Rom fetch (16 taps, separable) of the first 3 channels. Negative-lobe
// clamping: the result is clamped per channel to the range of the 4 central
// (bilinear) taps, so the sharpening lobes cannot ring past the local colours
// (no overshoot, no negative colour from positive history). out[3] = the
// carried channel of the nearest tap. fetchCatmullRomAt4 takes a footprint
// already computed (footprintOf); Clamp = false is for footprints known to be
// interior (footprintInterior4x4): the same taps without the clamps, so the
// same bits.
template <bool Clamp, class H>
CRISP_LANES_INLINE Vec4 fetchCatmullRomAt4(const H& h, const Footprint& f) {
  float wx[4], wy[4];
  catmullRomWeights(f.tx, wx);
  catmullRomWeights(f.ty, wy);
  int xs[4];
  for (int i = 0; i < 4; ++i) xs[i] = Clamp ? std::clamp(f.x0 - 1 + i, 0, h.width - 1) : f.x0 - 1 + i;
  Vec4 acc = splat(0.0f), lo = splat(0.0f), hi = splat(0.0f);
  // The carried channel: the nearest of the 4 central taps (row j = 1 or 2, column 1 or 2).
  const int carriedRow = f.ty < 0.5f ? 1 : 2;
  const bool carriedLeft = f.tx < 0.5f;
  float carried = 0.0f;
  for (int j = 0; j < 4; ++j) {
    const int y = Clamp ? std::clamp(f.y0 - 1 + j, 0, h.height - 1) : f.y0 - 1 + j;
    const Vec4 t0 = tapOf(h, xs[0], y), t1 = tapOf(h, xs[1], y);
    const Vec4 t2 = tapOf(h, xs[2], y), t3 = tapOf(h, xs[3], y);
    const Vec4 r = ((t0 * wx[0] + t1 * wx[1]) + t2 * wx[2]) + t3 * wx[3];
    acc += r * wy[j];
    if (j == 1) {
      lo = vmin(t1, t2);
      hi = vmax(t1, t2);
    } else if (j == 2) {
      lo = vmin(lo, vmin(t1, t2));
      hi = vmax(hi, vmax(t1, t2));
    }
    if (j == carriedRow) carried = carriedLeft ? t1[3] : t2[3];
  }
  Vec4 out = vmin(vmax(acc, lo), hi);
  out[3] = carried;
  return out;
}

// The carried channel (3) of a lane group's interior footprints, lane l's 2x2 at (x0 + l, y0): the
// nearest of the four taps, never interpolated (as fetchBilinear4 and fetchCatmullRomAt4 take it).
template <class T>
CRISP_LANES_INLINE T carriedNearestRow(const HistoryPlanes& h, int x0, int y0, T tx, T ty) {
  const float* upper = h.plane[3] + h.index(x0, y0);
  const float* lower = h.plane[3] + h.index(x0, y0 + 1);
  const auto left = tx < 0.5f;
  const T up = left ? loadLanes<T>(upper) : loadLanes<T>(upper + 1);
  const T down = left ? loadLanes<T>(lower) : loadLanes<T>(lower + 1);
  return ty < 0.5f ? up : down;
}

// fetchCatmullRomAt4<false> on a lane group (lanes.h) of planar history
// whose footprints are all interior and share their integer offset: lane l's
// top-left tap is (x0 + l, y0), its fractions tx[l], ty[l]. Per lane the same
// operations in the same order, so the same bits; channel c into out[c].
template <class T>
CRISP_LANES_INLINE void fetchCatmullRomRow(const HistoryPlanes& h, int x0, int y0, T tx, T ty, T out[4]) {
  T wx[4], wy[4];
  catmullRomWeights(tx, wx);
  catmullRomWeights(ty, wy);
  T acc[3], lo[3], hi[3];
  for (int c = 0; c < 3; ++c) acc[c] = lanesOf<T>(0.0f);
  for (int j = 0; j < 4; ++j) {
    const std::size_t row = h.index(x0 - 1, y0 - 1 + j);
    for (int c = 0; c < 3; ++c) {
      const float* p = h.plane[c] + row;
      const T tap[4] = {loadLanes<T>(p), loadLanes<T>(p + 1), loadLanes<T>(p + 2), loadLanes<T>(p + 3)};
      addCatmullRomRow(tap, wx, wy[j], j, acc[c], lo[c], hi[c]);
    }
  }
  for (int c = 0; c < 3; ++c) out[c] = catmullRomClamped(acc[c], lo[c], hi[c]);
  out[3] = carriedNearestRow(h, x0, y0, tx, ty);
}

// fetchBilinear4 on a lane group as fetchCatmullRomRow reads Catmull-Rom: every lane's 2x2 footprint
// inside the image, lane l's at (x0 + l, y0) (sharedInteriorOffset with 0..1); the same operations
// in the same order, so the same bits.
template <class T>
CRISP_LANES_INLINE void fetchBilinearRow(const HistoryPlanes& h, int x0, int y0, T tx, T ty, T out[4]) {
  const std::size_t upper = h.index(x0, y0), lower = h.index(x0, y0 + 1);
  for (int c = 0; c < 3; ++c) {
    const float* p = h.plane[c];
    const T p00 = loadLanes<T>(p + upper), p10 = loadLanes<T>(p + upper + 1);
    const T p01 = loadLanes<T>(p + lower), p11 = loadLanes<T>(p + lower + 1);
    const T top = p00 + (p10 - p00) * tx;
    const T bottom = p01 + (p11 - p01) * tx;
    out[c] = top + (bottom - top) * ty;
  }
  out[3] = carriedNearestRow(h, x0, y0, tx, ty);
}

inline Vec4 fetchCatmullRom4(const HistoryImage& h, float x, float y) {
  return fetchCatmullRomAt4<true>(h, footprintOf(x, y));
}
inline void fetchCatmullRom(const HistoryImage& h, float x, float y, float out[4]) {
  store4(out, fetchCatmullRom4(h, x, y));
}

}  // namespace crisp::temporal
