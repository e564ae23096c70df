// SPDX-License-Identifier: Apache-2.0
// "taa-improved": seed 000 chapter IV (METHODS.md "Improved TAA"). Per pixel
// an aliasedValue a in [0, 1] says how much TAA the pixel needs; the baseline
// kernel (taa.cpp: same reprojection, history, clip, feedback, static
// accumulation) then builds its moving-path clip box from it. Passes:
//   1. luminance planes: lit l (colour), unlit u (albedo, Blender's DiffCol);
//   2. Sobel magnitudes of l, u and depth, g = clamp01(0.3u + 0.7l + d)
//      (eq. 4.9); without albedo g = clamp01(l + d) (lit only, full weight);
//      sobel = sqrt(g^2 (3 - 2g)) (eq. 4.10 as printed: the square root of the
//      smoothstep). Depth enters relative: |Sobel(depth)| / centre depth, so
//      the term does not depend on scene units;
//   3. stabilisation (§4.3.3): a one-channel TAA of the Sobel plane: bilinear
//      fetch of last frame's stabilised value at p + motion(p), clamped (not
//      clipped) to the 3x3 range of this frame's raw values, blended with the
//      baseline's luma-difference feedback (feedbackMin/Max), no sharpen;
//   4. aliasedValue (eqs. 4.1, 4.4-4.6, 4.12-4.14):
//        modelAverage = #(3x3 taps whose object id != centre's) / 9 (eq. 4.1);
//        depths of the 3x3 relative to the centre's: avg, min, max;
//        m = min(|min - avg|, |max - avg|) (eq. 4.4), below depthThreshold
//        both variances are 0; depthPV = (|1 - avg| / m)^2 (eq. 4.5);
//        depthTPV = (|past - avg| / m)^4 (eq. 4.6), past = last frame's depth
//        at the nearest pixel of p + motion(p), relative to the centre;
//        sobelAvg = mix(sobelCross, sobel3x3, clamp01(modelAverage + sobel))
//        (eqs. 4.12-4.13, averages of the stabilised plane);
//        a = clamp01(sobelAvg + depthPV + depthTPV + modelAverage) (eq. 4.14);
//   5. the baseline kernel with the aliasedValue plane: moving-path box
//      mix(cross, 3x3, a) (eq. 4.15) shrunk to mix(current, box, a) (eq. 4.16);
//      sharpen with eq. 4.17 ([0,-.25,0;-.25,2,-.25;0,-.25,0] = the eq. 3.1
//      stencil at a quarter of the amount) or eq. 3.1.
// Missing inputs: no `id` (the add-on leaves it out when one object is
// visible) -> modelAverage from depth's background mask (object vs
// background), or 0 without depth; no albedo -> lit luminance only; no depth
// -> no depth Sobel, no (temporal) pseudo-variance; no motion -> static
// (stabilisation and past depth read the same pixel).
// Deliberate choice: the static accumulation path of the baseline is left as
// it is (its convergence to the reference beats any box), so aliasedValue
// steers only pixels on the feedback path (moving, or rejected static history).
// With aliasedNeighbourhood and aliasedBoxSize both off the output is the
// baseline's, bit for bit (tested).
#include "filters/taa_improved.h"

#include <algorithm>
#include <cmath>
#include <cstring>
#include <type_traits>

#include "core/color.h"
#include "core/error.h"
#include "core/filter.h"
#include "core/parallel.h"
#include "core/row_stage.h"
#include "temporal/history_fetch.h"
#include "temporal/isa.h"
#include "temporal/lanes.h"
#include "temporal/rows.h"
#include "temporal/vec4.h"
#include "temporal/velocity.h"

namespace crisp::taa_improved {

namespace {

// NaN -> 0; two selects, so one pixel (T = float) and a lane group
// (temporal/lanes.h) perform the same operations.
template <class T>
__attribute__((always_inline)) inline T clamp01(T v) {
  const T below = v < 1.0f ? v : temporal::lanesOf<T>(1.0f);
  return v > 0.0f ? below : temporal::lanesOf<T>(0.0f);
}

// A packed float plane read with clamp-to-edge addressing; at<false> skips
// the clamps for taps known to be inside (temporal::rowsWithBorder).
struct Plane {
  const float* data;
  int width, height;
  template <bool Clamp = true>
  float at(int x, int y) const {
    if constexpr (Clamp) return data[std::size_t(std::clamp(y, 0, height - 1)) * width + std::clamp(x, 0, width - 1)];
    return data[std::size_t(y) * width + x];
  }
};

// |Sobel| of a clamp-to-edge sampled function (Sobel 1968; seed 000 §3.8).
template <class At>
inline float sobelMagnitude(At&& at, int x, int y) {
  const float gx = (at(x + 1, y - 1) + 2.0f * at(x + 1, y) + at(x + 1, y + 1)) -
                   (at(x - 1, y - 1) + 2.0f * at(x - 1, y) + at(x - 1, y + 1));
  const float gy = (at(x - 1, y + 1) + 2.0f * at(x, y + 1) + at(x + 1, y + 1)) -
                   (at(x - 1, y - 1) + 2.0f * at(x, y - 1) + at(x + 1, y - 1));
  return std::sqrt(gx * gx + gy * gy);
}

// Pass 2 on the interior pixels x in [1, w - 2] of a row whose neighbours
// above and below exist: sobelMagnitude's arithmetic, in its order, on
// direct taps of packed planes (row pointers at the current row, stride w),
// a lane group per step (temporal/lanes.h: lane-wise IEEE operations and
// correctly rounded square roots, so the same bits as the per-pixel code),
// then the remaining pixels one by one with the same template. Two copies of
// the row loop (temporal/isa.h): 8 lanes with AVX2, 4 in the baseline copy.
template <class V, bool Unlit, bool Depth>
__attribute__((always_inline)) inline V sobelMixed(const float* lit, const float* unlit, const float* depth, int w,
                                                   int x) {
  auto load = [](const float* p) { return temporal::loadLanes<V>(p); };
  auto sobelAt = [&](const float* p) {
    const float* up = p - w;
    const float* down = p + w;
    const V gx = (load(up + x + 1) + 2.0f * load(p + x + 1) + load(down + x + 1)) -
                 (load(up + x - 1) + 2.0f * load(p + x - 1) + load(down + x - 1));
    const V gy = (load(down + x - 1) + 2.0f * load(down + x) + load(down + x + 1)) -
                 (load(up + x - 1) + 2.0f * load(up + x) + load(up + x + 1));
    return temporal::sqrtOf(gx * gx + gy * gy);
  };
  const V l = sobelAt(lit);
  V g = l;
  if constexpr (Unlit) g = 0.3f * sobelAt(unlit) + 0.7f * l;
  if constexpr (Depth) g += sobelAt(depth) / load(depth + x);
  g = clamp01(g);
  return temporal::sqrtOf(g * g * (3.0f - 2.0f * g));
}
template <class V, bool Unlit, bool Depth>
__attribute__((always_inline)) inline void sobelInteriorBody(const float* lit, const float* unlit, const float* depth,
                                                             int w, float* out) {
  constexpr int kL = temporal::kLanesOf<V>;
  int x = 1;
  for (; x + kL <= w - 1; x += kL)
    temporal::storeLanes(out + x, sobelMixed<V, Unlit, Depth>(lit, unlit, depth, w, x));
  for (; x < w - 1; ++x) out[x] = sobelMixed<float, Unlit, Depth>(lit, unlit, depth, w, x);
}
template <bool Unlit, bool Depth>
void sobelInteriorBaseline(const float* lit, const float* unlit, const float* depth, int w, float* out) {
  sobelInteriorBody<temporal::Vec4, Unlit, Depth>(lit, unlit, depth, w, out);
}
#ifdef CRISP_TEMPORAL_HAS_AVX2
template <bool Unlit, bool Depth>
CRISP_TEMPORAL_AVX2 void sobelInteriorAvx2(const float* lit, const float* unlit, const float* depth, int w,
                                           float* out) {
  sobelInteriorBody<temporal::Vec8, Unlit, Depth>(lit, unlit, depth, w, out);
}
#endif
using SobelInteriorRow = void (*)(const float*, const float*, const float*, int, float*);
template <bool Unlit, bool Depth>
SobelInteriorRow sobelInteriorRow() {
#ifdef CRISP_TEMPORAL_HAS_AVX2
  if (temporal::useAvx2()) return sobelInteriorAvx2<Unlit, Depth>;
#endif
  return sobelInteriorBaseline<Unlit, Depth>;
}

inline float lumaOfView(const ImageView& v, int x, int y) {
  const float* p = v.pixel(x, y);
  const int c = v.channels();
  return luminance709(sanitizeColor(p[0]), sanitizeColor(c > 1 ? p[1] : p[0]), sanitizeColor(c > 2 ? p[2] : p[0]));
}

// lumaOfView of row y into out[0 .. width): packed RGB(A) with the same
// values, packed RGBA a lane group at a time (GCC left the strided loop
// scalar, with a branch per channel: 13 % of taa-improved's time), in an
// AVX2 copy where the CPU has it; other layouts pixel by pixel.
template <class T, int C>
__attribute__((always_inline)) inline void lumaRun(const float* p, int width, float* out) {
  int x = 0;
  if constexpr (C == 4) {
    constexpr int kL = temporal::kLanesOf<T>;
    for (; x + kL <= width; x += kL, p += 4 * kL) {
      T r, g, b, a;
      temporal::loadInterleaved4(p, r, g, b, a);
      temporal::storeLanes(out + x, 0.2126f * sanitizeColorLanes(r) + 0.7152f * sanitizeColorLanes(g) +
                                        0.0722f * sanitizeColorLanes(b));  // luminance709's order
    }
  }
  for (; x < width; ++x, p += C)
    out[x] = luminance709(sanitizeColorLanes(p[0]), sanitizeColorLanes(p[1]), sanitizeColorLanes(p[2]));
}
void lumaRunRgbaBaseline(const float* p, int width, float* out) { lumaRun<temporal::Vec4, 4>(p, width, out); }
#ifdef CRISP_TEMPORAL_HAS_AVX2
CRISP_TEMPORAL_AVX2 void lumaRunRgbaAvx2(const float* p, int width, float* out) {
  lumaRun<temporal::Vec8, 4>(p, width, out);
}
#endif
inline void lumaRow(const ImageView& v, int y, float* out) {
  const int c = v.channels();
  if (c == 4 && v.pixelStride == 4 * sizeof(float)) {
#ifdef CRISP_TEMPORAL_HAS_AVX2
    if (temporal::useAvx2()) return lumaRunRgbaAvx2(v.pixel(0, y), v.width, out);
#endif
    return lumaRunRgbaBaseline(v.pixel(0, y), v.width, out);
  }
  if (c == 3 && v.pixelStride == 3 * sizeof(float)) return lumaRun<temporal::Vec4, 3>(v.pixel(0, y), v.width, out);
  for (int x = 0; x < v.width; ++x) out[x] = lumaOfView(v, x, y);
}

inline void motionAt(const ImageView& motion, int x, int y, float& vx, float& vy) {
  vx = vy = 0.0f;
  if (!motion.ptr) return;
  const float* m = motion.pixel(x, y);
  vx = m[0];
  vy = m[1];
}

// Pass 3 (§4.3.3) on one pixel (T = float) or a lane group (Vec4, Vec8), written once
// against temporal/lanes.h so both give the same bits: the bilinear fetch of
// last frame's stabilised plane at p + v (clamp-to-edge taps), clamped to
// this frame's 3x3 range [lo, hi] of raw values, blended with the baseline's
// luma-difference feedback; the raw value c where there is no usable history
// or the result is not finite.
struct StabiliseParams {
  const float* previous;  // last frame's stabilised plane
  int width, height;
  bool stabilise;         // history exists and the plane is valid
  float feedbackMin, feedbackMax;
};
template <class T>
__attribute__((always_inline)) inline T stabilisedSobel(const StabiliseParams& p, T c, T lo, T hi, T vx, T vy, T px,
                                                        T py) {
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
  bool loaded = false;
  if constexpr (!std::is_same_v<T, float>) {
    if (temporal::sharedInteriorOffset<T>(x0, y0, valid, 0, 1, 0, 1, w, h)) {
      // Smooth motion: the lanes' taps are consecutive, the same values as the gathers.
      const float* upper = p.previous + std::size_t(y0[0]) * w + x0[0];
      p00 = temporal::loadLanes<T>(upper), p10 = temporal::loadLanes<T>(upper + 1);
      p01 = temporal::loadLanes<T>(upper + w), p11 = temporal::loadLanes<T>(upper + w + 1);
      loaded = true;
    }
  }
  if (!loaded) {  // clamped to the image
    auto clampIndex = [](temporal::IntOf<T> v, int top) { return v < 0 ? 0 : (top < v ? top : v); };
    const auto xa = clampIndex(x0, w - 1), xb = clampIndex(x0 + 1, w - 1);
    const auto ya = clampIndex(y0, h - 1), yb = clampIndex(y0 + 1, h - 1);
    p00 = temporal::gatherOf(p.previous, w, xa, ya), p10 = temporal::gatherOf(p.previous, w, xb, ya);
    p01 = temporal::gatherOf(p.previous, w, xa, yb), p11 = temporal::gatherOf(p.previous, w, xb, yb);
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

// Pass 3 on the interior of row y (1 <= y < height - 1), a lane group at a
// time from x = 1 while a whole group fits before the last column; returns
// the first pixel left for the caller. Two copies of one body, as the taa
// kernel's rows (temporal/isa.h): 8 lanes with AVX2, 4 in the baseline copy.
template <class T>
__attribute__((always_inline)) inline int stabiliseInteriorBody(const StabiliseParams& sp, const float* raw,
                                                                const ImageView& motion, float* out, int y) {
  constexpr int kL = temporal::kLanesOf<T>;
  const int w = sp.width;
  const T laneIndex = temporal::laneIndexOf<T>();
  int x = 1;
  for (; x + kL <= w - 1; x += kL) {
    const float* row = raw + std::size_t(y) * w + x;
    const T c = temporal::loadLanes<T>(row);
    T lo = c, hi = c;
    for (int j = -1; j <= 1; ++j)
      for (int i = -1; i <= 1; ++i) {
        const T v = temporal::loadLanes<T>(row + std::ptrdiff_t(j) * w + i);
        lo = temporal::minOf(lo, v);
        hi = temporal::maxOf(hi, v);
      }
    T vx = temporal::lanesOf<T>(0.0f), vy = vx;
    if (motion.ptr)
      for (int l = 0; l < kL; ++l) {
        const float* m = motion.pixel(x + l, y);
        vx[l] = m[0];
        vy[l] = m[1];
      }
    temporal::storeLanes(out + std::size_t(y) * w + x,
                         stabilisedSobel(sp, c, lo, hi, vx, vy, float(x) + laneIndex, temporal::lanesOf<T>(float(y))));
  }
  return x;
}
int stabiliseInteriorBaseline(const StabiliseParams& sp, const float* raw, const ImageView& motion, float* out, int y) {
  return stabiliseInteriorBody<temporal::Vec4>(sp, raw, motion, out, y);
}
#ifdef CRISP_TEMPORAL_HAS_AVX2
CRISP_TEMPORAL_AVX2 int stabiliseInteriorAvx2(const StabiliseParams& sp, const float* raw, const ImageView& motion,
                                              float* out, int y) {
  return stabiliseInteriorBody<temporal::Vec8>(sp, raw, motion, out, y);
}
#endif
int stabiliseInterior(const StabiliseParams& sp, const float* raw, const ImageView& motion, float* out, int y) {
#ifdef CRISP_TEMPORAL_HAS_AVX2
  if (temporal::useAvx2()) return stabiliseInteriorAvx2(sp, raw, motion, out, y);
#endif
  return stabiliseInteriorBaseline(sp, raw, motion, out, y);
}

// Pass 4's inputs (eqs. 4.1, 4.4-4.6, 4.12-4.14), shared by the per-pixel
// form in Kernel::run and the lane-group rows below.
struct AliasedParams {
  const ImageView* id;      // object ids (packed uint32 on the lane path), or nullptr
  const float* depth;       // this frame's sanitised depth plane, or nullptr
  const float* pastDepth;   // last frame's, or nullptr
  const float* sobel;       // the stabilised Sobel plane, or nullptr (Sobel off)
  const ImageView* motion;  // may be empty (static)
  float* aliased;           // the aliasedValue plane written
  int width, height;
  bool modelOn, depthStats, depthVariance, temporalDepthVariance;
  float depthThreshold;
};

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

// Pass 4 on the interior of row y (1 <= y < height - 1), a lane group at a
// time from x = 1 while a whole group fits before the last column: Kernel::
// run's aliasedPixel lane-wise, the same operations in the same order per
// lane, so the same bits; eqs. 4.5-4.6 per lane where needed. Returns the
// first pixel left for the caller. Ids must be packed. Two copies
// (temporal/isa.h): 8 lanes with AVX2, 4 in the baseline copy.
template <class T>
__attribute__((always_inline)) inline int aliasedInteriorBody(const AliasedParams& p, int y) {
  using Int = temporal::IntOf<T>;
  constexpr int kL = temporal::kLanesOf<T>;
  const int w = p.width;
  const T zero = temporal::lanesOf<T>(0.0f), one = temporal::lanesOf<T>(1.0f);
  auto load = [](const float* q) { return temporal::loadLanes<T>(q); };
  int x = 1;
  for (; x + kL <= w - 1; x += kL) {
    T model = zero;
    if (p.modelOn) {
      Int differ = Int{};
      if (p.id) {
        auto ids = [&](int i, int j) {
          const char* row = static_cast<const char*>(p.id->ptr) + std::size_t(y + j) * p.id->rowStride;
          Int v;
          std::memcpy(&v, row + 4 * std::size_t(x + i), sizeof v);
          return v;
        };
        const Int centre = ids(0, 0);
        for (int j = -1; j <= 1; ++j)
          for (int i = -1; i <= 1; ++i) differ -= ids(i, j) != centre;  // a true lane is -1
      } else {
        auto background = [&](int i, int j) {  // isBackgroundDepth per lane: -1 background, 0 object
          return ~(load(p.depth + std::size_t(y + j) * w + x + i) < kFarDepth);
        };
        const Int centre = background(0, 0);
        for (int j = -1; j <= 1; ++j)
          for (int i = -1; i <= 1; ++i) differ -= background(i, j) != centre;
      }
      model = __builtin_convertvector(differ, T) / 9.0f;
    }
    T sobelAvg = zero;
    if (p.sobel) {
      const float* r[3] = {p.sobel + std::size_t(y - 1) * w, p.sobel + std::size_t(y) * w,
                           p.sobel + std::size_t(y + 1) * w};
      const T centre = load(r[1] + x);
      T sum9 = zero;
      for (int j = 0; j < 3; ++j)
        for (int i = -1; i <= 1; ++i) sum9 += load(r[j] + x + i);
      const T sumCross = load(r[0] + x) + load(r[1] + x - 1) + centre + load(r[1] + x + 1) + load(r[2] + x);
      const T avg3x3 = sum9 / 9.0f, avgCross = sumCross / 5.0f;
      const T t = clamp01(model + centre);
      sobelAvg = avgCross * (1.0f - t) + avg3x3 * t;
    }
    T depthPV = zero, depthTPV = zero;
    if (p.depthStats) {
      const T dc = load(p.depth + std::size_t(y) * w + x);
      T lo = one, hi = one, sum = zero;
      for (int j = -1; j <= 1; ++j)
        for (int i = -1; i <= 1; ++i) {
          const T d = load(p.depth + std::size_t(y + j) * w + x + i) / dc;
          lo = temporal::minOf(lo, d);
          hi = temporal::maxOf(hi, d);
          sum += d;
        }
      const T avg = sum / 9.0f;
      const T m = temporal::minOf(temporal::fabsOf(lo - avg), temporal::fabsOf(hi - avg));
      if (temporal::anyOf(m >= p.depthThreshold))
        for (int k = 0; k < kL; ++k)
          if (m[k] >= p.depthThreshold) {
            float pv = 0.0f, tpv = 0.0f;
            depthVariances(p, x + k, y, avg[k], m[k], dc[k], pv, tpv);
            depthPV[k] = pv;
            depthTPV[k] = tpv;
          }
    }
    const T a = sobelAvg + depthPV + depthTPV + model;
    temporal::storeLanes(p.aliased + std::size_t(y) * w + x, a != a ? one : clamp01(a));
  }
  return x;
}
int aliasedInteriorBaseline(const AliasedParams& p, int y) { return aliasedInteriorBody<temporal::Vec4>(p, y); }
#ifdef CRISP_TEMPORAL_HAS_AVX2
CRISP_TEMPORAL_AVX2 int aliasedInteriorAvx2(const AliasedParams& p, int y) {
  return aliasedInteriorBody<temporal::Vec8>(p, y);
}
#endif
int aliasedInterior(const AliasedParams& p, int y) {
#ifdef CRISP_TEMPORAL_HAS_AVX2
  if (temporal::useAvx2()) return aliasedInteriorAvx2(p, y);
#endif
  return aliasedInteriorBaseline(p, y);
}

}  // namespace

void Kernel::allocate(int width, int height, bool withDepth) {
  const bool sameShape = width == width_ && height == height_ && !aliased_.empty();
  taa_.allocate(width, height, withDepth);
  if (sameShape) return;
  width_ = width;
  height_ = height;
  const std::size_t n = std::size_t(width) * height;
  for (auto* v : {&lumaLit_, &lumaUnlit_, &sobelRaw_, &aliased_, &sobel_[0], &sobel_[1]}) v->assign(n, 0.0f);
  reset();
}

void Kernel::reset() {
  taa_.reset();
  sobelValid_ = false;
}

std::size_t Kernel::bytesKeptBetweenFrames() const {
  return taa_.bytesKeptBetweenFrames() + (sobel_[0].size() + sobel_[1].size()) * sizeof(float);
}

std::size_t Kernel::bytesScratch() const {
  return taa_.bytesScratch() + (lumaLit_.size() + lumaUnlit_.size() + sobelRaw_.size() + aliased_.size()) * sizeof(float);
}

void Kernel::run(const Inputs& in, const Settings& s, bool reference, int numThreads) {
  if (in.color.width != width_ || in.color.height != height_)
    invalidData("taa-improved: colour is " + std::to_string(in.color.width) + "x" + std::to_string(in.color.height) +
                " but the filter was committed for " + std::to_string(width_) + "x" + std::to_string(height_));
  const int w = width_, h = height_;
  const int threads = reference ? 1 : numThreads;
  // The baseline starts over when the clip space changes (its history is
  // kept in that space); so do the passes below, which read the last frames.
  if (taa_.framesSinceReset() > 0 && s.base.clipSpace != taa_.historySpace()) reset();
  const bool hasHistory = taa_.framesSinceReset() > 0;
  const bool useAlbedo = s.sobelUnlit && in.albedo.ptr;
  const bool useDepth = in.depth.ptr != nullptr;
  // This frame's sanitised depth, staged once in pass 1 into the plane the
  // baseline kernel stages it into anyway (taa::Kernel::nextDepthPlane).
  float* depthPlane = useDepth ? taa_.nextDepthPlane() : nullptr;
  if (useDepth && !depthPlane)
    invalidData("taa-improved: image 'depth' given but the kernel was allocated without depth");
  // Taps of 3x3 stencils are clamped on the border (and on the reference
  // path) and direct inside (temporal::rowsWithBorder): the same taps either way.
  const Plane dep{depthPlane, w, h};
  auto depthAt = [&](auto clamp, int x, int y) { return dep.at<decltype(clamp)::value>(x, y); };
  const Plane lit{lumaLit_.data(), w, h}, unlit{lumaUnlit_.data(), w, h}, raw{sobelRaw_.data(), w, h};
  const int next = 1 - current_;
  const bool stabilise = s.sobelStabilise && hasHistory && sobelValid_;

  // Pass 1: luminance planes (with the Sobel) and the depth plane.
  parallelRows(w, h, threads, [&](int y0, int y1) {
    for (int y = y0; y < y1; ++y) {
      if (useDepth) stageDepthRow(in.depth, y, depthPlane + std::size_t(y) * w);
      if (!s.sobel) continue;
      lumaRow(in.color, y, lumaLit_.data() + std::size_t(y) * w);
      if (useAlbedo) lumaRow(in.albedo, y, lumaUnlit_.data() + std::size_t(y) * w);
    }
  });
  if (s.sobel) {
    // Pass 2: mixed, smoothstepped Sobel (eqs. 4.9-4.10).
    const bool sobelOfDepth = useDepth && s.sobelDepth;
    auto sobelPixel = [&](int x, int y) {  // clamped taps: the border and the reference path
      const float l = sobelMagnitude([&](int i, int j) { return lit.at(i, j); }, x, y);
      float g = l;
      if (useAlbedo) g = 0.3f * sobelMagnitude([&](int i, int j) { return unlit.at(i, j); }, x, y) + 0.7f * l;
      if (sobelOfDepth) g += sobelMagnitude([&](int i, int j) { return dep.at(i, j); }, x, y) / dep.at(x, y);
      g = clamp01(g);
      sobelRaw_[std::size_t(y) * w + x] = std::sqrt(g * g * (3.0f - 2.0f * g));
    };
    const SobelInteriorRow interior =
        useAlbedo ? (sobelOfDepth ? sobelInteriorRow<true, true>() : sobelInteriorRow<true, false>())
                  : (sobelOfDepth ? sobelInteriorRow<false, true>() : sobelInteriorRow<false, false>());
    parallelRows(w, h, threads, [&](int y0, int y1) {
      for (int y = y0; y < y1; ++y) {
        if (reference || y == 0 || y == h - 1 || w < 3) {
          for (int x = 0; x < w; ++x) sobelPixel(x, y);
          continue;
        }
        const std::size_t row = std::size_t(y) * w;
        sobelPixel(0, y);
        interior(lumaLit_.data() + row, lumaUnlit_.data() + row, sobelOfDepth ? depthPlane + row : nullptr, w,
                 sobelRaw_.data() + row);
        sobelPixel(w - 1, y);
      }
    });
    // Pass 3: one-channel TAA with clamping, no sharpen (§4.3.3); the border
    // (and the reference) one pixel at a time, the interior eight at a time.
    const float* previous = sobel_[current_].data();
    float* stabilised = sobel_[next].data();
    const StabiliseParams sp{previous, w, h, stabilise, s.base.feedbackMin, s.base.feedbackMax};
    parallelRows(w, h, threads, [&](int y0, int y1) {
      auto pixel = [&](auto clamp, int x, int y) {
        constexpr bool C = decltype(clamp)::value;
        const float c = raw.at<C>(x, y);
        float lo = c, hi = c;
        for (int j = -1; j <= 1; ++j)
          for (int i = -1; i <= 1; ++i) {
            lo = temporal::minOf(lo, raw.at<C>(x + i, y + j));
            hi = temporal::maxOf(hi, raw.at<C>(x + i, y + j));
          }
        float vx, vy;
        motionAt(in.motion, x, y, vx, vy);
        stabilised[std::size_t(y) * w + x] = stabilisedSobel(sp, c, lo, hi, vx, vy, float(x), float(y));
      };
      for (int y = y0; y < y1; ++y) {
        if (reference || y == 0 || y == h - 1 || w < 3) {
          for (int x = 0; x < w; ++x) pixel(std::true_type{}, x, y);
          continue;
        }
        pixel(std::true_type{}, 0, y);
        int x = stabiliseInterior(sp, raw.data, in.motion, stabilised, y);
        for (; x < w - 1; ++x) pixel(std::false_type{}, x, y);
        pixel(std::true_type{}, w - 1, y);
      }
    });
  }

  // Pass 4: aliasedValue (eqs. 4.1, 4.4-4.6, 4.12-4.14).
  const float* pastDepth = taa_.previousDepth();
  const Plane sob{sobel_[next].data(), w, h};
  const bool modelOn = s.modelAverage && (in.id.ptr || useDepth);
  const bool depthStats = useDepth && (s.depthVariance || s.temporalDepthVariance);
  const AliasedParams ap{in.id.ptr ? &in.id : nullptr, depthPlane, pastDepth, s.sobel ? sob.data : nullptr,
                        &in.motion, aliased_.data(), w, h, modelOn, depthStats, s.depthVariance,
                        s.temporalDepthVariance, s.depthThreshold};
  auto aliasedPixel = [&](auto clamp, int x, int y) {
    constexpr bool C = decltype(clamp)::value;
    float sobelCentre = 0.0f, sobelAvg = 0.0f;
    float model = 0.0f;
    if (modelOn) {
      auto objectAt = [&](int i, int j) -> std::uint32_t {
        const int cx = C ? std::clamp(i, 0, w - 1) : i, cy = C ? std::clamp(j, 0, h - 1) : j;
        if (in.id.ptr) return in.id.uintAt(cx, cy);
        return isBackgroundDepth(dep.at<false>(cx, cy)) ? 0u : 1u;  // object vs background (same test on sanitised)
      };
      const std::uint32_t centre = objectAt(x, y);
      int differ = 0;
      for (int j = -1; j <= 1; ++j)
        for (int i = -1; i <= 1; ++i) differ += objectAt(x + i, y + j) != centre;
      model = float(differ) / 9.0f;
    }
    if (s.sobel) {
      sobelCentre = sob.at<C>(x, y);
      float sum9 = 0.0f;
      for (int j = -1; j <= 1; ++j)
        for (int i = -1; i <= 1; ++i) sum9 += sob.at<C>(x + i, y + j);
      const float sumCross =
          sob.at<C>(x, y - 1) + sob.at<C>(x - 1, y) + sobelCentre + sob.at<C>(x + 1, y) + sob.at<C>(x, y + 1);
      const float avg3x3 = sum9 / 9.0f, avgCross = sumCross / 5.0f;
      const float t = clamp01(model + sobelCentre);
      sobelAvg = avgCross * (1.0f - t) + avg3x3 * t;
    }
    float depthPV = 0.0f, depthTPV = 0.0f;
    if (depthStats) {
      const float dc = depthAt(clamp, x, y);
      float lo = 1.0f, hi = 1.0f, sum = 0.0f;
      for (int j = -1; j <= 1; ++j)
        for (int i = -1; i <= 1; ++i) {
          const float d = depthAt(clamp, x + i, y + j) / dc;  // relative to the centre
          lo = std::min(lo, d);
          hi = std::max(hi, d);
          sum += d;
        }
      const float avg = sum / 9.0f;
      const float m = std::min(std::fabs(lo - avg), std::fabs(hi - avg));
      if (m >= s.depthThreshold) depthVariances(ap, x, y, avg, m, dc, depthPV, depthTPV);
    }
    const float a = sobelAvg + depthPV + depthTPV + model;
    // Non-finite (cannot happen with sanitised inputs): full TAA, the baseline's box.
    aliased_[std::size_t(y) * w + x] = std::isnan(a) ? 1.0f : clamp01(a);
  };
  const bool vectorRows = !reference && (!in.id.ptr || in.id.pixelStride == 4);
  parallelRows(w, h, threads, [&](int y0, int y1) {
    if (!vectorRows) {
      temporal::rowsWithBorder(w, h, y0, y1, reference, aliasedPixel);
      return;
    }
    for (int y = y0; y < y1; ++y) {
      if (y == 0 || y == h - 1 || w < 3) {
        for (int x = 0; x < w; ++x) aliasedPixel(std::true_type{}, x, y);
        continue;
      }
      aliasedPixel(std::true_type{}, 0, y);
      int x = aliasedInterior(ap, y);
      for (; x < w - 1; ++x) aliasedPixel(std::false_type{}, x, y);
      aliasedPixel(std::true_type{}, w - 1, y);
    }
  });

  // Pass 5: the baseline kernel, steered.
  taa::Settings base = s.base;
  base.aliasedNeighbourhood = s.aliasedNeighbourhood;
  base.aliasedBoxSize = s.aliasedBoxSize;
  base.sharpen = s.normalizedSharpen ? 0.25f * s.sharpen : s.sharpen;
  taa::Inputs tin;
  tin.color = in.color;
  tin.motion = in.motion;
  tin.depth = in.depth;
  tin.output = in.output;
  tin.aliasedValue = (s.aliasedNeighbourhood || s.aliasedBoxSize) ? aliased_.data() : nullptr;
  taa_.run(tin, base, reference, numThreads);
  if (s.sobel) {
    current_ = next;
    sobelValid_ = true;
  } else {
    sobelValid_ = false;
  }
}

}  // namespace crisp::taa_improved

// ---------------------------------------------------------------------------
// The filter.

namespace crisp {
namespace {

std::vector<ParamSpec> improvedParams() {
  std::vector<ParamSpec> specs = taa::parameterSpecs();
  for (ParamSpec& p : specs)
    if (std::string(p.name) == "sharpen")
      p.meaning = "amount of the output sharpen: eq. 4.17's normalised kernel (normalizedSharpen) or eq. 3.1's; the "
                  "history stays unsharpened; clamped to the 5-tap range";
  const std::vector<ParamSpec> extra = {
      {"sobel", ParamType::Bool, 1, 0, 1, nullptr, "Sobel edges of lit/unlit luminance and depth in aliasedValue",
       "seed 000 §4.3.3, eqs. 4.9-4.10"},
      {"sobelUnlit", ParamType::Bool, 1, 0, 1, nullptr,
       "include the unlit luminance (image 'albedo') in the Sobel mix g = 0.3u + 0.7l + d", "seed 000 eq. 4.9"},
      {"sobelDepth", ParamType::Bool, 1, 0, 1, nullptr, "include the depth Sobel (relative to the centre depth)",
       "seed 000 eq. 4.9"},
      {"sobelStabilise", ParamType::Bool, 1, 0, 1, nullptr,
       "stabilise the Sobel plane over time with a one-channel TAA (clamp, no sharpen)", "seed 000 §4.3.3"},
      {"modelAverage", ParamType::Bool, 1, 0, 1, nullptr,
       "fraction of 3x3 neighbours with another object id (image 'id'; without it, object vs background from depth)",
       "seed 000 §4.3.1, eq. 4.1"},
      {"depthVariance", ParamType::Bool, 1, 0, 1, nullptr, "depth pseudo-variance (|d - avg| / m)^2",
       "seed 000 §4.3.2, eqs. 4.4-4.5"},
      {"temporalDepthVariance", ParamType::Bool, 1, 0, 1, nullptr,
       "temporal depth pseudo-variance (|d_prev - avg| / m)^4", "seed 000 §4.3.2, eq. 4.6"},
      {"depthThreshold", ParamType::Float, 0.002, 0.0, 1.0, nullptr,
       "m (eq. 4.4, relative to the centre depth) below which both pseudo-variances are 0", "seed 000 §4.3.2"},
      {"aliasedNeighbourhood", ParamType::Bool, 1, 0, 1, nullptr,
       "clip box colours mix(cross, 3x3, aliasedValue) instead of the rounded box", "seed 000 §4.3.4, eq. 4.15"},
      {"aliasedBoxSize", ParamType::Bool, 1, 0, 1, nullptr,
       "shrink the clip box toward the current colour: mix(current, box, aliasedValue)", "seed 000 §4.3.4, eq. 4.16"},
      {"normalizedSharpen", ParamType::Bool, 1, 0, 1, nullptr,
       "sharpen with [0,-.25,0;-.25,2,-.25;0,-.25,0] (eq. 4.17) instead of [0,-1,0;-1,5,-1;0,-1,0] (eq. 3.1)",
       "seed 000 §4.3.5"},
  };
  specs.insert(specs.end() - 1, extra.begin(), extra.end());  // keep `reference` last
  return specs;
}

class TaaImprovedFilter final : public Filter {
 public:
  explicit TaaImprovedFilter(Context& c)
      : Filter(c, improvedParams(),
               {{"color", true, 3, 4, false, "linear RGB(A) colour, 1 jittered sample per pixel"},
                {"motion", false, 2, 4, false,
                 "motion vectors in pixels, previous - current, y down (absent: static scene, no reprojection)"},
                {"depth", false, 1, 4, false,
                 "planar depth (channel 0): closest-depth velocity, disocclusion, depth Sobel and pseudo-variances"},
                {"id", false, 1, 1, true, "object ids (Cryptomatte hash): modelAverage (eq. 4.1)"},
                {"albedo", false, 3, 4, false, "unlit colour (Blender's DiffCol): unlit luminance Sobel"},
                {"output", true, 3, 4, false, "anti-aliased linear colour; alpha passes through"}}) {}
  const char* type() const override { return "taa-improved"; }
  void reset() override { kernel_.reset(); }

 protected:
  void onCommit() override {
    const ParamSet& p = params();
    taa::readSettings(p, "taa-improved", settings_.base);
    settings_.sharpen = p.getFloat("sharpen");
    settings_.sobel = p.getBool("sobel");
    settings_.sobelUnlit = p.getBool("sobelUnlit");
    settings_.sobelDepth = p.getBool("sobelDepth");
    settings_.sobelStabilise = p.getBool("sobelStabilise");
    settings_.modelAverage = p.getBool("modelAverage");
    settings_.depthVariance = p.getBool("depthVariance");
    settings_.temporalDepthVariance = p.getBool("temporalDepthVariance");
    settings_.depthThreshold = p.getFloat("depthThreshold");
    settings_.aliasedNeighbourhood = p.getBool("aliasedNeighbourhood");
    settings_.aliasedBoxSize = p.getBool("aliasedBoxSize");
    settings_.normalizedSharpen = p.getBool("normalizedSharpen");
    reference_ = p.getBool("reference");
    kernel_.allocate(width(), height(), hasImage("depth"));
  }
  void onExecute() override {
    taa_improved::Inputs in;
    in.color = inputApartFromOutput("color");
    if (hasImage("motion")) in.motion = inputApartFromOutput("motion");
    if (hasImage("depth")) in.depth = inputApartFromOutput("depth");
    if (hasImage("id")) in.id = inputApartFromOutput("id");
    if (hasImage("albedo")) in.albedo = inputApartFromOutput("albedo");
    in.output = image("output");
    kernel_.run(in, settings_, reference_, numThreads());
  }

 private:
  taa_improved::Settings settings_;
  bool reference_ = false;
  taa_improved::Kernel kernel_;
};

}  // namespace

std::unique_ptr<Filter> newTaaImprovedFilter(Context& c) { return std::make_unique<TaaImprovedFilter>(c); }

}  // namespace crisp
