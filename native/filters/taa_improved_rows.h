// SPDX-License-Identifier: Apache-2.0
// taa-improved's aliasedValue passes on the fast path (filters/taa_improved.cpp
// describes the method), fused into one sweep per row band: luminance and
// depth rows, then their Sobel, then its stabilisation, then aliasedValue,
// each stage a few rows behind the one it reads, through rings of rows that
// stay in cache instead of whole-frame planes written by one pass and read
// back by the next. A band recomputes the few halo rows it needs from its
// neighbours' rows (the same per-pixel operations, so the same values).
//
// In a header, as taa_rows.h and for the same reason: taa_improved.cpp compiles
// the SSE2 and AVX2 copies and taa_improved_rows_avx512.cpp the 16-lane copy,
// compiled for AVX-512 as a whole. Everything here but the structs the units
// pass each other has internal linkage; the check of tests/
// check_sealed_object.cmake covers the AVX-512 object.
//
// The per-lane bodies below serve a lane group (4, 8 or 16 lanes, interior
// pixels: their taps are direct loads) and one pixel (T = float) with the
// column taps clamped to the image (the first and last column); rows are
// clamped by the caller, which picks the row pointers. The reference path
// (taa_improved.cpp, whole planes, one pixel at a time) performs the same
// operations in the same order per pixel: the same bits (tested).
#pragma once

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <cstring>
#include <type_traits>

#include "core/color.h"
#include "core/conventions.h"
#include "core/image.h"
#include "core/row_stage.h"
#include "temporal/history_fetch.h"
#include "temporal/lanes.h"
#include "temporal/velocity.h"

namespace crisp::taa_improved::rows {

// Pass 3's inputs (§4.3.3).
struct StabiliseParams {
  const float* previous;  // last frame's stabilised plane
  int width, height;
  bool stabilise;         // history exists and the plane is valid
  float feedbackMin, feedbackMax;
};

// Pass 4's inputs besides the planes the stages pass on (eqs. 4.1, 4.4-4.6).
struct AliasedParams {
  const ImageView* id;      // object ids, or nullptr
  const float* pastDepth;   // last frame's sanitised depth plane, or nullptr
  const ImageView* motion;  // may be empty (static)
  int width, height;
  bool modelOn, depthStats, depthVariance, temporalDepthVariance;
  float depthThreshold;
};

// Everything a band reads and writes, set up once per frame.
struct Frame {
  int width, height;
  const ImageView* color;
  const ImageView* albedo;  // nullptr: lit luminance only
  const ImageView* depth;   // nullptr: no depth
  const ImageView* motion;  // may be empty (static)
  bool sobel, sobelOfDepth;
  StabiliseParams stabilise;
  AliasedParams aliased;
  float* stabilisedOut;  // this frame's stabilised plane (kept for the next frame)
  float* aliasedOut;     // the aliasedValue plane
};

// A band's rings: kRing rows of width floats per plane, row y in slot y % kRing.
// Eight rows cover the furthest look-back (aliasedValue at row t - 3 reads
// depth rows down to t - 4 while row t is staged).
constexpr int kRing = 8;
enum RingPlane { kLit, kUnlit, kDepth, kRaw, kStabilised, kRingPlanes };
struct BandRings {
  float* rows[kRingPlanes][kRing];
};

// The 16-lane copy (taa_improved_rows_avx512.cpp); call only where
// temporal::useAvx512().
void bandAvx512(const Frame& f, const BandRings& r, int y0, int y1);

namespace {

#define CRISP_ROWS_INLINE inline __attribute__((always_inline))
// Lambdas that take or return lane groups are always inlined too: a vector
// passed to or returned from a helper compiled for another instruction set
// changes the calling convention.
#define CRISP_STAGE_LAMBDA __attribute__((always_inline))

inline std::size_t bandFloats(int width) { return std::size_t(kRingPlanes) * kRing * std::size_t(width); }
// The rings of a band whose block of bandFloats(width) starts at base.
inline BandRings bandRings(float* base, int width) {
  BandRings r;
  for (int p = 0; p < kRingPlanes; ++p)
    for (int k = 0; k < kRing; ++k, base += width) r.rows[p][k] = base;
  return r;
}

// NaN -> 0; two selects, so one pixel (T = float) and a lane group
// (temporal/lanes.h) perform the same operations.
template <class T>
CRISP_ROWS_INLINE T clamp01(T v) {
  const T below = v < 1.0f ? v : temporal::lanesOf<T>(1.0f);
  return v > 0.0f ? below : temporal::lanesOf<T>(0.0f);
}

// Tap x of a row: a direct load of lanes x .. x + lanes - 1, or (ClampX, one
// pixel) column x clamped to the image.
template <class T, bool ClampX>
CRISP_ROWS_INLINE T tapOf(const float* row, int x, int w) {
  if constexpr (ClampX) {
    static_assert(std::is_same_v<T, float>);
    return row[std::clamp(x, 0, w - 1)];
  } else {
    return temporal::loadLanes<T>(row + x);
  }
}

// A true lane counted as 1 (masks are -1 per true lane, bool is 1).
template <class M>
CRISP_ROWS_INLINE auto countOf(M m) {
  if constexpr (std::is_same_v<M, bool>) {
    return int(m);
  } else {
    return -m;
  }
}

inline void motionAt(const ImageView& motion, int x, int y, float& vx, float& vy) {
  vx = vy = 0.0f;
  if (!motion.ptr) return;
  const float* m = motion.pixel(x, y);
  vx = m[0];
  vy = m[1];
}

// Luminance (luminance709's order) of a packed RGB(A) run, a lane group at a
// time for RGBA (GCC left the strided loop scalar, with a branch per channel).
template <class T, int C>
CRISP_ROWS_INLINE void lumaRun(const float* p, int width, float* out) {
  int x = 0;
  if constexpr (C == 4) {
    constexpr int kL = temporal::kLanesOf<T>;
    for (; x + kL <= width; x += kL, p += 4 * kL) {
      T r, g, b, a;
      temporal::loadInterleaved4(p, r, g, b, a);
      temporal::storeLanes(out + x, 0.2126f * sanitizeColorLanes(r) + 0.7152f * sanitizeColorLanes(g) +
                                        0.0722f * sanitizeColorLanes(b));
    }
  }
  for (; x < width; ++x, p += C)
    out[x] = 0.2126f * sanitizeColorLanes(p[0]) + 0.7152f * sanitizeColorLanes(p[1]) +
             0.0722f * sanitizeColorLanes(p[2]);
}
// One pixel of any layout: channels beyond the view's repeat its first.
CRISP_ROWS_INLINE float lumaOfView(const ImageView& v, int x, int y) {
  const float* p = v.pixel(x, y);
  const int c = v.channels();
  const float r = sanitizeColorLanes(p[0]), g = sanitizeColorLanes(c > 1 ? p[1] : p[0]),
              b = sanitizeColorLanes(c > 2 ? p[2] : p[0]);
  return 0.2126f * r + 0.7152f * g + 0.0722f * b;
}
template <class T>
CRISP_ROWS_INLINE void lumaRow(const ImageView& v, int y, float* out) {
  const int c = v.channels();
  if (c == 4 && v.pixelStride == 4 * sizeof(float)) return lumaRun<T, 4>(v.pixel(0, y), v.width, out);
  if (c == 3 && v.pixelStride == 3 * sizeof(float)) return lumaRun<T, 3>(v.pixel(0, y), v.width, out);
  for (int x = 0; x < v.width; ++x) out[x] = lumaOfView(v, x, y);
}

// Eqs. 4.9-4.10 at x: the Sobel magnitudes (Sobel 1968; seed 000 §3.8) of the
// lit luminance, the unlit one and depth (relative to the centre depth),
// mixed g = clamp01(0.3 u + 0.7 l + d), then sqrt(g^2 (3 - 2g)). Each
// argument is the row above, the row and the row below.
template <class T, bool ClampX, bool Unlit, bool Depth>
CRISP_ROWS_INLINE T sobelMixed(const float* const* lit, const float* const* unlit, const float* const* depth, int x,
                               int w) {
  auto sobelAt = [&](const float* const* r) CRISP_STAGE_LAMBDA {
    auto at = [&](int j, int i) CRISP_STAGE_LAMBDA { return tapOf<T, ClampX>(r[j], x + i, w); };  // j: 0 above, 2 below
    const T gx = (at(0, 1) + 2.0f * at(1, 1) + at(2, 1)) - (at(0, -1) + 2.0f * at(1, -1) + at(2, -1));
    const T gy = (at(2, -1) + 2.0f * at(2, 0) + at(2, 1)) - (at(0, -1) + 2.0f * at(0, 0) + at(0, 1));
    return temporal::sqrtOf(gx * gx + gy * gy);
  };
  const T l = sobelAt(lit);
  T g = l;
  if constexpr (Unlit) g = 0.3f * sobelAt(unlit) + 0.7f * l;
  if constexpr (Depth) g += sobelAt(depth) / tapOf<T, ClampX>(depth[1], x, w);
  g = clamp01(g);
  return temporal::sqrtOf(g * g * (3.0f - 2.0f * g));
}

// Pass 3 (§4.3.3) on one pixel or a lane group: the bilinear fetch of last
// frame's stabilised plane at p + v (clamp-to-edge taps), clamped to this
// frame's 3x3 range [lo, hi] of raw values, blended with the baseline's
// luma-difference feedback; the raw value c where there is no usable history
// or the result is not finite.
template <class T>
CRISP_ROWS_INLINE T stabilisedSobel(const StabiliseParams& p, T c, T lo, T hi, T vx, T vy, T px, T py) {
  using M = temporal::MaskOfT<T>;
  using temporal::lanesOf;
  if (!p.stabilise) return c;
  const int w = p.width, h = p.height;
  const T qx = px + vx, qy = py + vy;
  const M valid = M(temporal::finiteOf(vx) & temporal::finiteOf(vy) & M(qx >= -0.5f) & M(qy >= -0.5f) &
                    M(qx <= float(w) - 0.5f) & M(qy <= float(h) - 0.5f));  // finiteMotion, onScreen
  if (!temporal::anyOf(valid)) return c;
  const T zero = lanesOf<T>(0.0f);
  const T sx = valid ? qx : zero, sy = valid ? qy : zero;
  const T fx = temporal::floorExact(sx), fy = temporal::floorExact(sy);  // footprintOf
  const auto x0 = temporal::truncOf(fx), y0 = temporal::truncOf(fy);
  const T tx = sx - fx, ty = sy - fy;
  T p00, p10, p01, p11;
  auto gatherClamped = [&]() CRISP_STAGE_LAMBDA {  // the taps clamped to the image
    auto clampIndex = [](temporal::IntOf<T> v, int top) CRISP_STAGE_LAMBDA { return v < 0 ? 0 : (top < v ? top : v); };
    const auto xa = clampIndex(x0, w - 1), xb = clampIndex(x0 + 1, w - 1);
    const auto ya = clampIndex(y0, h - 1), yb = clampIndex(y0 + 1, h - 1);
    p00 = temporal::gatherOf(p.previous, w, xa, ya), p10 = temporal::gatherOf(p.previous, w, xb, ya);
    p01 = temporal::gatherOf(p.previous, w, xa, yb), p11 = temporal::gatherOf(p.previous, w, xb, yb);
  };
  if constexpr (!std::is_same_v<T, float>) {
    if (temporal::sharedInteriorOffset<T>(x0, y0, valid, 0, 1, 0, 1, w, h)) {
      // Smooth motion: the lanes' taps are consecutive, the same values as the gathers.
      const float* upper = p.previous + std::size_t(y0[0]) * w + x0[0];
      p00 = temporal::loadLanes<T>(upper), p10 = temporal::loadLanes<T>(upper + 1);
      p01 = temporal::loadLanes<T>(upper + w), p11 = temporal::loadLanes<T>(upper + w + 1);
    } else {
      gatherClamped();
    }
  } else {
    gatherClamped();
  }
  const T top = p00 + (p10 - p00) * tx;
  const T bottom = p01 + (p11 - p01) * tx;
  const T hist = temporal::clampOf(top + (bottom - top) * ty, lo, hi);
  const T diff = temporal::clampOf(temporal::fabsOf(hist - c) / temporal::maxOf(temporal::maxOf(hist, c), lanesOf<T>(0.2f)),
                                   zero, lanesOf<T>(1.0f));
  const T k = p.feedbackMin + (p.feedbackMax - p.feedbackMin) * (1.0f - diff) * (1.0f - diff);
  const T result = valid ? hist + (c - hist) * (1.0f - k) : c;
  return temporal::finiteOf(result) ? result : c;
}

// Pass 3 at x of row y: the 3x3 range of the raw rows, this pixel's motion.
template <class T, bool ClampX>
CRISP_ROWS_INLINE T stabiliseAt(const StabiliseParams& sp, const ImageView& motion, const float* const* raw, int x,
                                int y) {
  const int w = sp.width;
  const T c = tapOf<T, ClampX>(raw[1], x, w);
  T lo = c, hi = c;
  for (int j = 0; j < 3; ++j)
    for (int i = -1; i <= 1; ++i) {
      const T v = tapOf<T, ClampX>(raw[j], x + i, w);
      lo = temporal::minOf(lo, v);
      hi = temporal::maxOf(hi, v);
    }
  T vx = temporal::lanesOf<T>(0.0f), vy = vx;
  if constexpr (!std::is_same_v<T, float>) {
    if (motion.ptr && temporal::motionLanesReadable(motion)) {  // packed: de-interleaved by shuffles
      temporal::loadFirstTwoChannels(motion.pixel(x, y), int(motion.pixelStride / sizeof(float)), vx, vy);
      return stabilisedSobel(sp, c, lo, hi, vx, vy, float(x) + temporal::laneIndexOf<T>(),
                             temporal::lanesOf<T>(float(y)));
    }
  }
  if (motion.ptr)
    for (int l = 0; l < temporal::kLanesOf<T>; ++l) {
      const float* m = motion.pixel(x + l, y);
      temporal::setLane(vx, l, m[0]);
      temporal::setLane(vy, l, m[1]);
    }
  return stabilisedSobel(sp, c, lo, hi, vx, vy, float(x) + temporal::laneIndexOf<T>(), temporal::lanesOf<T>(float(y)));
}

// Eqs. 4.5-4.6 where m passes the threshold (few pixels: depth edges).
inline void depthVariances(const AliasedParams& p, int x, int y, float avg, float m, float dc, float& depthPV,
                           float& depthTPV) {
  if (p.depthVariance) depthPV = std::pow(std::fabs(1.0f - avg) / m, 2.0f);
  if (p.temporalDepthVariance && p.pastDepth) {
    float vx, vy;
    motionAt(*p.motion, x, y, vx, vy);
    const float qx = float(x) + vx, qy = float(y) + vy;
    if (temporal::finiteMotion(vx, vy) && temporal::onScreen(qx, qy, p.width, p.height)) {
      const int px = std::clamp(int(temporal::floorExact(qx + 0.5f)), 0, p.width - 1);
      const int py = std::clamp(int(temporal::floorExact(qy + 0.5f)), 0, p.height - 1);
      const float past = p.pastDepth[std::size_t(py) * p.width + px] / dc;
      depthTPV = std::pow(std::fabs(past - avg) / m, 4.0f);
    }
  }
}

// True where eq. 4.4's m is below the threshold in every lane, found from
// two divisions instead of nine; the full computation gives 0 for both
// pseudo-variances there too, so the result has the same bits. Why: division
// by a fixed dc is correctly rounded, hence monotone (order-preserving for
// dc > 0, reversing for dc < 0), so |max d / dc - min d / dc| is exactly
// hi - lo of the nine relative depths q = d / dc (the centre's q = 1 is among
// them, so lo and hi starting at 1 change nothing). Where that range is below
// 1, every q lies within 1 of the centre's 1, the float sum of the nine is
// off by at most 8 half-ulps of 16 (8e-6) and their average lies within 1e-6
// of [lo, hi]; so m = min(|lo - avg|, |hi - avg|) <= (hi - lo) / 2 + 1e-6, below
// a threshold that exceeds hi - lo by 1e-4. A NaN or infinite range (dc 0 or
// not finite) takes the full computation.
template <class T, bool ClampX>
CRISP_ROWS_INLINE bool depthRangeBelowThreshold(const AliasedParams& p, const float* const* depth, int x) {
  const int w = p.width;
  T dmin = tapOf<T, ClampX>(depth[1], x, w), dmax = dmin;
  for (int j = 0; j < 3; ++j)
    for (int i = -1; i <= 1; ++i) {
      const T d = tapOf<T, ClampX>(depth[j], x + i, w);
      dmin = temporal::minOf(dmin, d);
      dmax = temporal::maxOf(dmax, d);
    }
  const T dc = tapOf<T, ClampX>(depth[1], x, w);
  const T range = temporal::fabsOf(dmax / dc - dmin / dc);
  return temporal::allOf(range + 1e-4f < p.depthThreshold);
}

// Pass 4 (eqs. 4.1, 4.4-4.6, 4.12-4.14) at x of row y. sobel: the stabilised
// rows above, at and below (nullptr: Sobel off); depth: the sanitised depth
// rows (nullptr: no depth); idRows: the id rows (used when p.id is set).
template <class T, bool ClampX>
CRISP_ROWS_INLINE T aliasedAt(const AliasedParams& p, const float* const* sobel, const float* const* depth,
                              const unsigned char* const* idRows, int x, int y) {
  using Int = temporal::IntOf<T>;
  constexpr int kL = temporal::kLanesOf<T>;
  const int w = p.width;
  const T zero = temporal::lanesOf<T>(0.0f), one = temporal::lanesOf<T>(1.0f);
  T model = zero;
  if (p.modelOn) {
    Int differ = Int{};
    if (p.id) {
      const std::size_t stride = p.id->pixelStride;
      auto ids = [&](int j, int i) CRISP_STAGE_LAMBDA {
        Int v;
        if constexpr (std::is_same_v<T, float>) {
          const int column = ClampX ? std::clamp(x + i, 0, w - 1) : x + i;
          std::uint32_t u;
          std::memcpy(&u, idRows[j] + stride * std::size_t(column), 4);
          v = Int(u);
        } else if (stride == 4) {
          std::memcpy(&v, idRows[j] + 4 * std::size_t(x + i), sizeof v);
        } else {
          for (int l = 0; l < kL; ++l) {
            std::uint32_t u;
            std::memcpy(&u, idRows[j] + stride * std::size_t(x + i + l), 4);
            v[l] = int(u);
          }
        }
        return v;
      };
      const Int centre = ids(1, 0);
      for (int j = 0; j < 3; ++j)
        for (int i = -1; i <= 1; ++i) differ += countOf(ids(j, i) != centre);
    } else {
      // Object vs background from depth (isBackgroundDepth per lane).
      auto background = [&](int j, int i) CRISP_STAGE_LAMBDA {
        return temporal::notOf(tapOf<T, ClampX>(depth[j], x + i, w) < kFarDepth);
      };
      const auto centre = background(1, 0);
      for (int j = 0; j < 3; ++j)
        for (int i = -1; i <= 1; ++i) differ += countOf(background(j, i) != centre);
    }
    model = temporal::floatOf(differ) / 9.0f;
  }
  T sobelAvg = zero;
  if (sobel) {
    const T centre = tapOf<T, ClampX>(sobel[1], x, w);
    T sum9 = zero;
    for (int j = 0; j < 3; ++j)
      for (int i = -1; i <= 1; ++i) sum9 += tapOf<T, ClampX>(sobel[j], x + i, w);
    const T sumCross = tapOf<T, ClampX>(sobel[0], x, w) + tapOf<T, ClampX>(sobel[1], x - 1, w) + centre +
                       tapOf<T, ClampX>(sobel[1], x + 1, w) + tapOf<T, ClampX>(sobel[2], x, w);
    const T avg3x3 = sum9 / 9.0f, avgCross = sumCross / 5.0f;
    const T t = clamp01(model + centre);
    sobelAvg = avgCross * (1.0f - t) + avg3x3 * t;
  }
  T depthPV = zero, depthTPV = zero;
  if (p.depthStats && !depthRangeBelowThreshold<T, ClampX>(p, depth, x)) {
    const T dc = tapOf<T, ClampX>(depth[1], x, w);
    T lo = one, hi = one, sum = zero;
    for (int j = 0; j < 3; ++j)
      for (int i = -1; i <= 1; ++i) {
        const T d = tapOf<T, ClampX>(depth[j], x + i, w) / dc;  // relative to the centre
        lo = temporal::minOf(lo, d);
        hi = temporal::maxOf(hi, d);
        sum += d;
      }
    const T avg = sum / 9.0f;
    const T m = temporal::minOf(temporal::fabsOf(lo - avg), temporal::fabsOf(hi - avg));
    if (temporal::anyOf(m >= p.depthThreshold)) {
      for (int k = 0; k < kL; ++k) {
        float mk, avgk, dck;
        if constexpr (std::is_same_v<T, float>) {
          mk = m, avgk = avg, dck = dc;
        } else {
          mk = m[k], avgk = avg[k], dck = dc[k];
        }
        if (!(mk >= p.depthThreshold)) continue;  // as the reference: a NaN m (depth 0 or -inf) takes none
        float pv = 0.0f, tpv = 0.0f;
        depthVariances(p, x + k, y, avgk, mk, dck, pv, tpv);
        temporal::setLane(depthPV, k, pv);
        temporal::setLane(depthTPV, k, tpv);
      }
    }
  }
  const T a = sobelAvg + depthPV + depthTPV + model;
  return a != a ? one : clamp01(a);  // non-finite (cannot happen with sanitised inputs): the baseline's box
}

// The lane type a stage's lambda is instantiated for (a tag, not a value).
template <class T>
struct LanesTag {
  using type = T;
};
// One row of a stage: the first and the last column one pixel at a time
// with clamped taps, the interior a lane group at a time, then pixel by pixel.
template <class T, class At>
CRISP_ROWS_INLINE void rowOf(int w, float* out, At&& at) {
  constexpr int kL = temporal::kLanesOf<T>;
  out[0] = at(std::true_type{}, LanesTag<float>{}, 0);
  if (w == 1) return;
  int x = 1;
  for (; x + kL <= w - 1; x += kL) temporal::storeLanes(out + x, at(std::false_type{}, LanesTag<T>{}, x));
  for (; x < w - 1; ++x) out[x] = at(std::false_type{}, LanesTag<float>{}, x);
  out[w - 1] = at(std::true_type{}, LanesTag<float>{}, w - 1);
}

// Rows [y0, y1) of the aliasedValue plane (and of the stabilised plane): one
// sweep, step t staging row t and running the Sobel at row t - 1, the
// stabilisation at t - 2 and aliasedValue at t - 3, over the halo rows each
// stage needs (3, 2 and 1 beyond the band; clamped at the image's edges).
template <class T>
CRISP_ROWS_INLINE void bandBody(const Frame& f, const BandRings& r, int y0, int y1) {
  const int w = f.width, h = f.height;
  auto row = [&](int plane, int y) CRISP_STAGE_LAMBDA -> float* { return r.rows[plane][std::clamp(y, 0, h - 1) % kRing]; };
  auto rows3 = [&](int plane, int y, const float* out[3]) CRISP_STAGE_LAMBDA {
    for (int j = 0; j < 3; ++j) out[j] = row(plane, y - 1 + j);
  };
  const bool unlit = f.albedo != nullptr;
  const int stageEnd = std::min(y1 + 3, h), rawBegin = std::max(y0 - 2, 0), rawEnd = std::min(y1 + 2, h);
  const int stabBegin = std::max(y0 - 1, 0), stabEnd = std::min(y1 + 1, h);
  for (int t = std::max(y0 - 3, 0); t < y1 + 3; ++t) {
    if (t < stageEnd) {  // stage rows: luminance (for the Sobel) and depth
      if (f.depth) stageDepthRow(*f.depth, t, row(kDepth, t));
      if (f.sobel) {
        lumaRow<T>(*f.color, t, row(kLit, t));
        if (unlit) lumaRow<T>(*f.albedo, t, row(kUnlit, t));
      }
    }
    if (f.sobel && t - 1 >= rawBegin && t - 1 < rawEnd) {  // Sobel (eqs. 4.9-4.10)
      const int y = t - 1;
      const float *lit[3], *un[3], *dep[3];
      rows3(kLit, y, lit);
      rows3(kUnlit, y, un);
      rows3(kDepth, y, dep);
      auto sobelRow = [&](auto unlitOn, auto depthOn) CRISP_STAGE_LAMBDA {
        rowOf<T>(w, row(kRaw, y), [&](auto clamp, auto lanes, int x) CRISP_STAGE_LAMBDA {
          return sobelMixed<typename decltype(lanes)::type, decltype(clamp)::value, decltype(unlitOn)::value,
                            decltype(depthOn)::value>(lit, un, dep, x, w);
        });
      };
      if (unlit) {
        if (f.sobelOfDepth) sobelRow(std::true_type{}, std::true_type{});
        else sobelRow(std::true_type{}, std::false_type{});
      } else {
        if (f.sobelOfDepth) sobelRow(std::false_type{}, std::true_type{});
        else sobelRow(std::false_type{}, std::false_type{});
      }
    }
    if (f.sobel && t - 2 >= stabBegin && t - 2 < stabEnd) {  // stabilisation (§4.3.3)
      const int y = t - 2;
      const float* raw[3];
      rows3(kRaw, y, raw);
      float* out = row(kStabilised, y);
      rowOf<T>(w, out, [&](auto clamp, auto lanes, int x) CRISP_STAGE_LAMBDA {
        return stabiliseAt<typename decltype(lanes)::type, decltype(clamp)::value>(f.stabilise, *f.motion, raw, x, y);
      });
      if (y >= y0 && y < y1) std::memcpy(f.stabilisedOut + std::size_t(y) * w, out, sizeof(float) * std::size_t(w));
    }
    if (t - 3 >= y0) {  // aliasedValue (eqs. 4.1, 4.4-4.6, 4.12-4.14)
      const int y = t - 3;
      const float *sob[3], *dep[3];
      rows3(kStabilised, y, sob);
      rows3(kDepth, y, dep);
      const unsigned char* ids[3] = {};
      if (f.aliased.id)
        for (int j = 0; j < 3; ++j)
          ids[j] = static_cast<const unsigned char*>(f.aliased.id->ptr) +
                   std::size_t(std::clamp(y - 1 + j, 0, h - 1)) * f.aliased.id->rowStride;
      rowOf<T>(w, f.aliasedOut + std::size_t(y) * w, [&](auto clamp, auto lanes, int x) CRISP_STAGE_LAMBDA {
        return aliasedAt<typename decltype(lanes)::type, decltype(clamp)::value>(
            f.aliased, f.sobel ? sob : nullptr, f.depth ? dep : nullptr, ids, x, y);
      });
    }
  }
}

#undef CRISP_STAGE_LAMBDA
#undef CRISP_ROWS_INLINE

}  // namespace

}  // namespace crisp::taa_improved::rows
