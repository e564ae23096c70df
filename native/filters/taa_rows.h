// SPDX-License-Identifier: Apache-2.0
// taa's per-pixel steps and its fast row loop (filters/taa.cpp describes the
// method and the parameters), in a header so that two translation units
// compile them: taa.cpp (the scalar reference and the SSE2 and AVX2 copies of
// the rows) and taa_rows_avx512.cpp, compiled for AVX-512 as a whole. A target
// attribute on the 16-lane row loop alone is not enough there: GCC 12 lowers a
// 16-lane comparison lane by lane when the inlined helper that makes it was
// compiled without AVX-512 (about 4x slower than the 8-lane copy).
// Everything here except the two structs the units pass each other has
// internal linkage (an anonymous namespace), so each unit keeps its own
// copies, compiled for its own instruction set. The helpers it includes from
// other headers have external linkage and stay out of the AVX-512 object only
// by being inlined: tests/check_sealed_object.cmake checks, at every build
// of crisp_core and as a ctest, that the object defines no symbol another
// unit could share, so the linker never trades one unit's copy for the other's.
#pragma once

#include <algorithm>
#include <atomic>
#include <cmath>
#include <cstdint>
#include <cstring>

#include "core/color.h"
#include "core/row_stage.h"
#include "filters/taa.h"
#include "temporal/color_space.h"
#include "temporal/history_fetch.h"
#include "temporal/hold_release.h"
#include "temporal/jitter.h"
#include "temporal/lanes.h"
#include "temporal/neighbourhood.h"
#include "temporal/vec4.h"
#include "temporal/velocity.h"

namespace crisp::taa::rows {

// Everything one frame's pixels read, set up once per frame.
struct Frame {
  int width, height;
  const float* previousDepth;  // previous frame's sanitised depth, or null (no depth test)
  ImageView color;             // the input, for exact resets
  ImageView motion;            // ptr null: static scene
  ImageView depth;             // ptr null: no depth
  temporal::HistoryPlanes previous;  // valid only if hasHistory
  bool hasHistory;
  float* history[4];           // written: planes R G B (or Y Co Cg) and the signed weight
  bool streamHistory;          // written by streaming stores where aligned (16 lanes only; taa.cpp)
  ImageView output;            // written unless sharpening
  bool writeOutput;
  ClipSpace space;
  HistoryFilter filter;
  float sampleWeight;          // w of this frame's sample
  float feedbackMin, feedbackMax;
  bool staticAccumulation, staticClip;
  std::uint8_t* historyState;  // Kernel::historyState_, read and written in place
  float maxSamples;
  float holdPeriod;            // see "Hold"; 0: off
  temporal::HoldWindowFrame release;  // Kernel::holdWindows_ (temporal/hold_release.h)
  float varianceClip;          // gamma of the variance box; 0: off
  float resampleDamping;       // beta: k (1 - beta s) at sub-pixel fraction s; 0: off
  float depthTolerance;
  const float* aliased;        // aliasedValue plane or null
  bool aliasedNeighbourhood, aliasedBoxSize;
  // Unjitter (see "Jitter"): the 3x3 of pixel p is read around p - shift, the
  // samples nearest p, and its taps weighted give the current colour.
  temporal::Unjitter unjitter;
  // Fast path: plane index k of a staged row holds input column
  // sourceColumn[k] (shiftedSource(k - 1)), k < planeFloats(width).
  const int* sourceColumn;
  std::atomic<long>* guards;   // Kernel::guards_: lanes whose guard fired (rare: counted on the spot)
  std::atomic<long>* resets;   // Kernel::resets_: lanes that started over (summed per row)
  std::atomic<long>* releases;  // Kernel::releases_: lanes released from the hold (summed per row)
  std::atomic<bool>* alphaBelowOne;  // Kernel::alphaBelowOne_: an output pixel's input alpha is not 1
};

// Sets Frame::alphaBelowOne, reading it first: once set, no thread writes the
// shared line again.
inline void noteAlphaBelowOne(const Frame& f) {
  if (!f.alphaBelowOne->load(std::memory_order_relaxed)) f.alphaBelowOne->store(true, std::memory_order_relaxed);
}

// Fast path scratch of one row band: a ring of five staged rows, one plane
// per channel (Y Co Cg, or R G B, then motion x and y; no alpha, which the
// output takes from the input, alphaOf), each padded by one
// pixel left (a copy of the edge pixel = clamp-to-edge) and by at least one
// right, up to a multiple of 16 past the last group's loads (a group of 16
// lanes at x0 <= width - 1 reads plane indices up to x0 + 17); five depth rows
// likewise; the current row's closest-depth taps.
constexpr int kRing = 5;
constexpr int kPlanes = 5;  // colour 3, motion 2
constexpr int kMotionX = 3, kMotionY = 4;  // plane indices
struct BandScratch {
  float* planes[kRing][kPlanes];
  float* depth[kRing];
  float* row;       // width x 4: one input row staged before the shift
  float* tap;       // planeFloats: closest-depth taps (int bits, read and written by memcpy)
  float* tapDepth;  // planeFloats: their depths
};

// The AVX-512 copy of the fast rows (taa_rows_avx512.cpp); the other copies
// are in taa.cpp. Call only where temporal::useAvx512().
void fastRowsAvx512(const Frame& f, const BandScratch& s, int y0, int y1, float* depthNow);

namespace {

using temporal::Float3;
using temporal::Vec4;

// The current frame as the kernel reads it (conventions.h): sanitised, in
// the clip space, alpha 1 for RGB input. Both paths stage through this.
inline Vec4 stagePixel(const float* p, int channels, ClipSpace space) {
  Vec4 v = channels > 3 ? temporal::load4(p)
                        : Vec4{p[0], channels > 1 ? p[1] : p[0], channels > 2 ? p[2] : p[0], 1.0f};
  v = sanitizeColorLanes(v);  // sanitizeColor per lane; alpha 1 stays 1
  if (space == ClipSpace::YCoCg) {
    const Float3 c = temporal::rgbToYCoCg({{v[0], v[1], v[2]}});
    v = Vec4{c[0], c[1], c[2], v[3]};
  }
  return v;
}

inline Float3 toRgb(const Float3& c, ClipSpace space) {
  return space == ClipSpace::YCoCg ? temporal::yCoCgToRgb(c) : c;
}

// rgb in lanes 0-2 (sanitised here), alpha in lane 3.
inline void storeOutput(const ImageView& out, int x, int y, Vec4 rgba) {
  const float alpha = rgba[3];
  rgba = sanitizeColorLanes(rgba);
  rgba[3] = alpha;
  float* p = out.pixel(x, y);
  if (out.channels() > 3) {
    temporal::store4(p, rgba);
  } else {
    p[0] = rgba[0];
    p[1] = rgba[1];
    p[2] = rgba[2];
  }
}
inline Vec4 toRgb4(Vec4 c, ClipSpace space, float alpha) {
  const Float3 rgb = toRgb({{c[0], c[1], c[2]}}, space);
  return Vec4{rgb[0], rgb[1], rgb[2], alpha};
}

constexpr int kTapDx[9] = {-1, 0, 1, -1, 0, 1, -1, 0, 1};
constexpr int kTapDy[9] = {-1, -1, -1, 0, 0, 0, 1, 1, 1};

// Steps 3 (from the followed tap's velocity v) and 8's validity, and the
// bilinear footprint of p + v, on one pixel (T = float) or a lane group (Vec4, Vec8),
// written once against temporal/lanes.h so both give the same bits.
template <class T>
struct ReprojectionLanes {
  T qx, qy;                      // p + v
  temporal::IntOf<T> x0, y0;     // footprint: top-left tap (valid lanes only)
  T tx, ty;                      // and fractions
  temporal::MaskOfT<T> valid;    // usable history at p + v
  temporal::MaskOfT<T> moving;   // v != 0
};
// temporal::stillSurfaceNear on the input images (the shifted 5x5).
inline bool stillSurfaceNear(const Frame& f, int x, int y, float d) {
  if (!f.depth.ptr || !f.motion.ptr) return false;
  return temporal::stillSurfaceNear(f.motion, x, y, f.width, f.height, f.unjitter.shiftX, f.unjitter.shiftY, d,
                                    f.depthTolerance,
                                    [&](int sx, int sy) { return temporal::sanitizeDepth(f.depth.pixel(sx, sy)[0]); });
}

template <class T>
__attribute__((always_inline)) inline ReprojectionLanes<T> reprojectLanes(const Frame& f, T px, T py, T vx, T vy,
                                                                          T tapDepth) {
  using M = temporal::MaskOfT<T>;
  const int w = f.width, h = f.height;
  ReprojectionLanes<T> r;
  r.moving = M(M(vx != 0.0f) | M(vy != 0.0f));
  r.qx = px + vx;
  r.qy = py + vy;
  // Step 8: finite motion, on screen (history_fetch.h onScreen; NaN fails).
  M valid = f.hasHistory ? M(temporal::finiteOf(vx) & temporal::finiteOf(vy) & M(r.qx >= -0.5f) &
                             M(r.qy >= -0.5f) & M(r.qx <= float(w) - 0.5f) & M(r.qy <= float(h) - 0.5f))
                         : M{};
  // The reprojected position's taps (history_fetch.h footprintOf), shared by
  // the depth test and the fetch; other lanes read a harmless 0.
  const T zero = temporal::lanesOf<T>(0.0f);
  const T qx = valid ? r.qx : zero, qy = valid ? r.qy : zero;
  const T fx = temporal::floorExact(qx), fy = temporal::floorExact(qy);
  r.x0 = temporal::truncOf(fx);
  r.y0 = temporal::truncOf(fy);
  r.tx = qx - fx;
  r.ty = qy - fy;
  if (f.previousDepth) {
    // Disocclusion: some tap of the bilinear footprint with non-zero weight
    // must hold the surface whose velocity we follow (depth is compared,
    // never interpolated).
    T d00, d10, d01, d11;  // the previous depth at the four taps
    auto gatherClamped = [&]() __attribute__((always_inline)) {  // the taps clamped to the image
      auto clampIndex = [](temporal::IntOf<T> v, int hi) __attribute__((always_inline)) {
        return v < 0 ? 0 : (hi < v ? hi : v);
      };
      const auto xa = clampIndex(r.x0, w - 1), xb = clampIndex(r.x0 + 1, w - 1);
      const auto ya = clampIndex(r.y0, h - 1), yb = clampIndex(r.y0 + 1, h - 1);
      d00 = temporal::gatherOf(f.previousDepth, w, xa, ya);
      d10 = temporal::gatherOf(f.previousDepth, w, xb, ya);
      d01 = temporal::gatherOf(f.previousDepth, w, xa, yb);
      d11 = temporal::gatherOf(f.previousDepth, w, xb, yb);
    };
    if constexpr (!std::is_same_v<T, float>) {
      if (temporal::sharedInteriorOffset<T>(r.x0, r.y0, valid, 0, 1, 0, 1, w, h)) {
        // Smooth motion: the lanes' taps are consecutive, the same values as the gathers.
        const float* upper = f.previousDepth + std::size_t(r.y0[0]) * w + r.x0[0];
        d00 = temporal::loadLanes<T>(upper);
        d10 = temporal::loadLanes<T>(upper + 1);
        d01 = temporal::loadLanes<T>(upper + w);
        d11 = temporal::loadLanes<T>(upper + w + 1);
      } else {
        gatherClamped();
      }
    } else {
      gatherClamped();
    }
    const float tol = f.depthTolerance;
    const M x1 = r.tx != 0.0f, y1 = r.ty != 0.0f;
    M same = M(temporal::sameSurfaceDepth(tapDepth, d00, tol) | M(x1 & temporal::sameSurfaceDepth(tapDepth, d10, tol)) |
               M(y1 & temporal::sameSurfaceDepth(tapDepth, d01, tol)) |
               M(x1 & y1 & temporal::sameSurfaceDepth(tapDepth, d11, tol)));
    // A still pixel (its footprint is the pixel: d00) that failed: keep it
    // where that surface is still, and still, nearby (stillSurfaceNear).
    temporal::forEachLane(M(valid & temporal::notOf(r.moving) & temporal::notOf(same)), [&](int l) {
      if constexpr (std::is_same_v<T, float>) {
        if (stillSurfaceNear(f, int(px), int(py), d00)) same = true;
      } else {
        if (stillSurfaceNear(f, int(px[l]), int(py[l]), d00[l])) same[l] = -1;
      }
    });
    valid = M(valid & same);
  }
  r.valid = valid;
  return r;
}

// Step 4 for one pixel with valid history: exact at zero motion, else the
// filtered fetch. A gather at a different place for every pixel, so both
// paths call it one pixel at a time.
__attribute__((always_inline)) inline Vec4 fetchHistory(const Frame& f, int x, int y, bool moving,
                                                        const temporal::Footprint& fp, float qx, float qy) {
  if (!moving) return temporal::tapOf(f.previous, x, y);  // exact: no filtering at zero motion
  if (f.filter == HistoryFilter::Bilinear) return temporal::fetchBilinear4(f.previous, qx, qy);
  return temporal::footprintInterior4x4(fp, f.width, f.height) ? temporal::fetchCatmullRomAt4<false>(f.previous, fp)
                                                                : temporal::fetchCatmullRomAt4<true>(f.previous, fp);
}

// Steps 5-8 on one pixel (T = float: the reference) or a lane group (Vec4, Vec8: the
// fast path), written once against temporal/lanes.h so both give the same
// bits: every lane computes both blends and selects, where the reference
// used to branch.
template <class T>
struct PixelLanes {
  using M = temporal::MaskOfT<T>;
  T current[3];  // the current colour in the clip space (the unjittered mix, or the centre tap)
  T boxMin[3], boxMax[3];      // 3x3 box of the current frame
  T crossMin[3], crossMax[3];  // cross (5-tap) box
  T mean[3], sigma[3];         // of the 3x3 (only with varianceClip)
  T tx, ty;                    // sub-pixel fractions of p + v (ReprojectionLanes)
  T hist[4];                   // Reprojection::hist
  M valid, moving;
  M feedbackSinceReset;  // Kernel::historyState_ before this frame: bit 0
  T framesSinceReset;    // and bits 1-7
  T aliased;             // aliasedValue (0 without a plane)
  temporal::IntOf<T> holdWord;  // Kernel::holdWindows_ (with a hold)
};
template <class T>
struct ResolvedLanes {
  using M = temporal::MaskOfT<T>;
  T color[3];       // the new history colour, clip space
  T signedWeight;   // its lane 3: -W moving, +W static
  T output[3];      // color as sanitised RGB (unless reset without unjitter: the input itself)
  M reset;          // took the current colour as is
  M guarded;        // the non-finite guard fired (Kernel::guardsLastFrame)
  M released;       // released from the hold ("Hold"; Kernel::releasesLastFrame)
  M feedbackSinceReset;
  T framesSinceReset;
  temporal::IntOf<T> holdWord;
};

template <class T>
CRISP_LANES_INLINE T lumaOf(const T c[3], ClipSpace space) {
  return space == ClipSpace::YCoCg ? c[0] : 0.2126f * c[0] + 0.7152f * c[1] + 0.0722f * c[2];
}

// clipTowardCentre4 (neighbourhood.h) on lanes 0-2: the clipped colour into
// `out` (when given) and the excess returned.
template <class T>
CRISP_LANES_INLINE T clipTowardCentreOf(const T p[3], const T lo[3], const T hi[3], T* out) {
  T centre[3], offset[3], ratio[3];
  for (int c = 0; c < 3; ++c) {
    centre[c] = 0.5f * (hi[c] + lo[c]);
    const T half = 0.5f * (hi[c] - lo[c]) + temporal::kClipEpsilon;
    offset[c] = p[c] - centre[c];
    ratio[c] = temporal::absOf(offset[c]) / half;
  }
  const T excess = temporal::maxOf(temporal::maxOf(ratio[0], ratio[1]), ratio[2]);
  if (out) {
    const auto outside = excess > 1.0f;
    const T scale = 1.0f / excess;
    for (int c = 0; c < 3; ++c) out[c] = outside ? centre[c] + offset[c] * scale : p[c];
  }
  return excess;
}

// footprintExcess(lane, &excess): for a static lane whose history is outside
// the 3x3 box and has not been through the feedback path, the excess against
// the footprint box, or false where the 5x5 moves (see "Deliberate choices").
template <class T, class FootprintExcess>
__attribute__((always_inline)) inline ResolvedLanes<T> resolveLanes(const Frame& f, const PixelLanes<T>& in,
                                                                    FootprintExcess&& footprintExcess) {
  using M = temporal::MaskOfT<T>;
  using temporal::lanesOf;
  using temporal::maxOf;
  using temporal::minOf;
  using temporal::notOf;
  const T zero = lanesOf<T>(0.0f);
  const float weight = f.sampleWeight;
  const T historyWeight = in.valid ? temporal::fabsOf(in.hist[3]) : zero;
  const T weightSum = historyWeight + weight;
  // First frame bootstrap / invalid reprojection.
  M reset = M(notOf(in.valid) | notOf(M(weightSum > 0.0f)));
  const M staticPixel = f.staticAccumulation ? M(notOf(in.moving) & M(in.hist[3] > 0.0f)) : M{};

  // Static history built by the running average alone since its last reset
  // is tested against the footprint box (3x3 united with the robust 5x5):
  // the converged value mixes the scene over the jitter's whole footprint
  // (+-filterSize = +-1.5 px for EEVEE's draw), which one frame's 3x3,
  // shifted by up to 1.5 px of jitter, misses near an edge. History that
  // went through the feedback path (a trail behind a moving object, a
  // clipped firefly: plausible colours of the footprint, but wrong) keeps
  // the 3x3 box. The footprint box contains the 3x3 box: it is gathered only
  // for history outside the 3x3 box (the same decision, at a fraction of the cost).
  M useAverage = staticPixel;
  if (f.staticClip) {
    const M tested = M(staticPixel & notOf(reset));
    T excess = zero;
    if (temporal::anyOf(tested)) {
      excess = clipTowardCentreOf<T>(in.hist, in.boxMin, in.boxMax, nullptr);
      const M wider = M(tested & M(excess > 1.0f) & notOf(in.feedbackSinceReset));
      temporal::forEachLane(wider, [&](int l) {
        float e;
        if (footprintExcess(l, &e)) temporal::setLane(excess, l, e);
      });
    }
    useAverage = M(staticPixel & notOf(M(excess > 1.0f)));
  }

  // Running average, weight w/W, in linear light; held (see "Hold") once it
  // averages a whole jitter period and nothing else since its reset.
  const M hold = f.holdPeriod > 0.0f ? M(useAverage & notOf(in.feedbackSinceReset) &
                                         M(in.framesSinceReset >= f.holdPeriod))
                                     : M{};
  const T averageWeight = weight / weightSum;
  T average[3];
  for (int c = 0; c < 3; ++c)
    average[c] = hold ? in.hist[c] : in.hist[c] + (in.current[c] - in.hist[c]) * averageWeight;
  const T averageSum = hold ? historyWeight : minOf(weightSum, lanesOf<T>(f.maxSamples));
  // A still averaging pixel (held or not) whose input changed for two
  // windows running is released: it restarts from this frame's colour, as
  // at a reset ("Hold").
  ResolvedLanes<T> r;
  M released{};
  if (f.release.words) {
    const M averaging = M(useAverage & notOf(reset));
    r.holdWord = temporal::stepHoldWindow<T>(in.holdWord, temporal::holdLumaOfLinear(lumaOf(in.current, f.space)),
                                             averaging, f.release.windowEnd, f.release.limit, released);
    reset = M(reset | released);
  }
  r.released = released;

  // The feedback path. The box: the rounded box (mean of 3x3 and cross), or
  // steered by aliasedValue a (seed 000 §4.3.4): mix(cross, 3x3, a) (eq. 4.15)
  // and shrunk toward the current colour, mix(current, box, a) (eq. 4.16);
  // mix(x, y, t) = x(1 - t) + yt (eq. 4.11).
  T lo[3], hi[3];
  const T a = in.aliased;
  for (int c = 0; c < 3; ++c) {
    if (f.aliased && f.aliasedNeighbourhood) {
      lo[c] = in.crossMin[c] * (1.0f - a) + in.boxMin[c] * a;
      hi[c] = in.crossMax[c] * (1.0f - a) + in.boxMax[c] * a;
    } else {
      lo[c] = 0.5f * (in.boxMin[c] + in.crossMin[c]);
      hi[c] = 0.5f * (in.boxMax[c] + in.crossMax[c]);
    }
    if (f.varianceClip > 0.0f) {  // mean +- gamma sigma, clamped into the box (never empty)
      const T vlo = in.mean[c] - f.varianceClip * in.sigma[c], vhi = in.mean[c] + f.varianceClip * in.sigma[c];
      const T boxLo = lo[c], boxHi = hi[c];
      lo[c] = temporal::clampOf(vlo, boxLo, boxHi);
      hi[c] = temporal::clampOf(vhi, boxLo, boxHi);
    }
    if (f.aliased && f.aliasedBoxSize) {
      lo[c] = in.current[c] * (1.0f - a) + lo[c] * a;
      hi[c] = in.current[c] * (1.0f - a) + hi[c] * a;
    }
  }
  T clipped[3];
  clipTowardCentreOf<T>(in.hist, lo, hi, clipped);
  // Step 6: luma-difference feedback on the clipped history.
  const T l0 = lumaOf(clipped, f.space), l1 = lumaOf(in.current, f.space);
  const T diff = temporal::clampOf(temporal::fabsOf(l0 - l1) / maxOf(maxOf(l0, l1), lanesOf<T>(0.2f)), zero,
                                   lanesOf<T>(1.0f));
  const T unbiased = (1.0f - diff) * (1.0f - diff);
  T k = f.feedbackMin + (f.feedbackMax - f.feedbackMin) * unbiased;
  if (f.resampleDamping > 0.0f) {  // see "Deliberate choices": 0 at whole-pixel motion, 1 at half a pixel
    const T sx = 4.0f * in.tx * (1.0f - in.tx), sy = 4.0f * in.ty * (1.0f - in.ty);
    k = k * (1.0f - f.resampleDamping * maxOf(sx, sy));
  }
  const T mixWeight = maxOf(1.0f - k, weight / weightSum);
  T feedback[3];
  for (int c = 0; c < 3; ++c) feedback[c] = clipped[c] + (in.current[c] - clipped[c]) * mixWeight;
  // The effective sample count of an exponential blend is about 1/(1-k).
  const T oneMinusK = 1.0f - k;
  T feedbackSum = oneMinusK > 0.0f ? minOf(weightSum, 1.0f / oneMinusK) : weightSum;
  feedbackSum = minOf(feedbackSum, lanesOf<T>(f.maxSamples));

  for (int c = 0; c < 3; ++c) r.color[c] = useAverage ? average[c] : feedback[c];
  T newWeight = useAverage ? averageSum : feedbackSum;
  // Kept until a reset: averaging dilutes a trail or a clipped firefly, never
  // removes it, and the footprint box would let it stay.
  M feedbackSinceReset = M(in.feedbackSinceReset | M(notOf(reset) & notOf(useAverage)));
  // Guard: never let a non-finite value into the history.
  r.guarded = notOf(M(temporal::finiteOf(r.color[0]) & temporal::finiteOf(r.color[1]) &
                      temporal::finiteOf(r.color[2])));
  reset = M(reset | r.guarded);
  for (int c = 0; c < 3; ++c) r.color[c] = reset ? in.current[c] : r.color[c];
  newWeight = reset ? lanesOf<T>(weight) : newWeight;
  r.feedbackSinceReset = reset ? M{} : feedbackSinceReset;
  r.framesSinceReset = reset ? lanesOf<T>(1.0f) : minOf(in.framesSinceReset + 1.0f, lanesOf<T>(127.0f));
  r.reset = reset;
  r.signedWeight = in.moving ? -newWeight : newWeight;  // sign: was this pixel static this frame
  // Output: back to RGB, sanitised.
  T rgb[3];
  if (f.space == ClipSpace::YCoCg) {  // R = Y + Co - Cg, G = Y + Cg, B = Y - Co - Cg (color_space.h)
    rgb[0] = r.color[0] + r.color[1] - r.color[2];
    rgb[1] = r.color[0] + r.color[2];
    rgb[2] = r.color[0] - r.color[1] - r.color[2];
  } else {
    for (int c = 0; c < 3; ++c) rgb[c] = r.color[c];
  }
  for (int c = 0; c < 3; ++c) r.output[c] = sanitizeColorLanes(rgb[c]);
  return r;
}

// The output's alpha: the input's at the pixel, sanitised (1 for RGB input).
// It passes through: the unjittered mix and the history are colour only.
inline float alphaOf(const ImageView& color, int x, int y) {
  return color.channels() > 3 ? sanitizeColor(color.pixel(x, y)[3]) : 1.0f;
}

// Writes one resolved pixel's output, unless sharpening.
inline void storeOutputPixel(const Frame& f, int x, int y, const float output[3], bool reset) {
  if (!f.writeOutput) return;
  const float alpha = alphaOf(f.color, x, y);
  if (alpha != 1.0f) noteAlphaBelowOne(f);
  if (reset && !f.unjitter.enabled) {
    // Reset to current: the input colour itself (sanitised), not its YCoCg
    // round trip, which can differ in the last bit.
    const float* p = f.color.pixel(x, y);
    const int cc = f.color.channels();
    storeOutput(f.output, x, y, Vec4{p[0], cc > 1 ? p[1] : p[0], cc > 2 ? p[2] : p[0], alpha});
    return;
  }
  float* p = f.output.pixel(x, y);
  p[0] = output[0];
  p[1] = output[1];
  p[2] = output[2];
  if (f.output.channels() > 3) p[3] = alpha;
}
// Writes one resolved pixel: its history and its output.
inline void storePixel(const Frame& f, int x, int y, const float color[3], float signedWeight, const float output[3],
                       bool reset) {
  const std::size_t i = std::size_t(y) * f.width + x;
  for (int c = 0; c < 3; ++c) f.history[c][i] = color[c];
  f.history[3][i] = signedWeight;
  storeOutputPixel(f, x, y, output, reset);
}

// Mean and standard deviation of 9 taps (variance clipping), summed in tap order.
template <class T>
inline void momentsOf(const T t[9], T& mean, T& sigma) {
  T sum = t[0], squares = t[0] * t[0];
  for (int k = 1; k < 9; ++k) sum = sum + t[k], squares = squares + t[k] * t[k];
  mean = sum * (1.0f / 9.0f);
  sigma = temporal::sqrtOf(temporal::maxOf(squares * (1.0f / 9.0f) - mean * mean, temporal::lanesOf<T>(0.0f)));
}

// Kernel::historyState_ of one pixel.
inline std::uint8_t historyStateOf(bool feedbackSinceReset, float framesSinceReset) {
  return std::uint8_t((feedbackSinceReset ? 1 : 0) | int(framesSinceReset) << 1);
}

inline int planeFloats(int width) { return (width + 18 + 15) / 16 * 16; }

inline std::size_t bandFloats(int width) {
  return std::size_t(planeFloats(width)) * (kRing * (kPlanes + 1) + 2) + std::size_t(width) * 4;
}

using temporal::UnclampedRun;  // plane index k holds shifted pixel k - 1 (Frame::sourceColumn)
using temporal::unclampedRun;
using temporal::forEachClampedIndex;

// One staged colour (core/row_stage.h stageColorPixel) into plane index k.
inline void stageColorTap(const float* px, int channels, float* const* p, int k) {
  float rgba[4];
  stageColorPixel(px, channels, rgba);
  for (int c = 0; c < 3; ++c) p[c][k] = rgba[c];
}
// stageColorTap over `count` packed pixels of C = 3 or 4 floats, into plane
// indices 0 .. count - 1. RGBA runs a lane group at a time (T: the lane type):
// GCC's own vectorisation of the packed loop if-converts the clamp into about
// twice the operations of sanitizeColorLanes on lanes. RGB is left to GCC.
template <class T, int C>
__attribute__((always_inline)) inline void stageColorRun(const float* src, int count, float* p0, float* p1,
                                                         float* p2) {
  const auto sanitize = sanitizeColorLanes<float>;
  int i = 0;
  if constexpr (C == 4) {
    constexpr int kL = temporal::kLanesOf<T>;
    for (; i + kL <= count; i += kL) {
      T r, g, b, a;
      temporal::loadInterleaved4(src + 4 * i, r, g, b, a);
      temporal::storeLanes(p0 + i, sanitizeColorLanes(r));
      temporal::storeLanes(p1 + i, sanitizeColorLanes(g));
      temporal::storeLanes(p2 + i, sanitizeColorLanes(b));
    }
  }
  for (; i < count; ++i) {
    const float* px = src + C * i;
    p0[i] = sanitize(px[0]);
    p1[i] = sanitize(px[1]);
    p2[i] = sanitize(px[2]);
  }
}

// Stages image row y of the shifted image (Frame::unjitter; no shift without
// unjitter) into ring slot y % kRing (and this frame's depth plane when the
// row belongs to the band): the same values as stagePixel (core/row_stage.h)
// and the same motion and depth taps as the reference reads, de-interleaved.
// Plane index k holds shifted pixel k - 1 clamped (Frame::sourceColumn); the
// unclamped run is copied straight from packed inputs, the rest tap by tap.
template <class T>
__attribute__((always_inline)) inline void stageRow(const Frame& f, const BandScratch& s, int y, float* depthNow) {
  const int w = f.width, n = planeFloats(w);
  const int* column = f.sourceColumn;
  const int source = std::clamp(y - f.unjitter.shiftY, 0, f.height - 1);
  const UnclampedRun run = unclampedRun(w, f.unjitter.shiftX);
  const int first = run.lo - 1 - f.unjitter.shiftX;  // source column of plane index run.lo
  float* const* p = s.planes[y % kRing];
  const int cc = f.color.channels();
  const std::size_t colorStride = f.color.pixelStride;
  if ((cc == 3 || cc == 4) && colorStride == std::size_t(cc) * sizeof(float)) {
    forEachClampedIndex(run, n, [&](int k) { stageColorTap(f.color.pixel(column[k], source), cc, p, k); });
    const float* src = f.color.pixel(std::clamp(first, 0, w - 1), source);  // = first where the run is not empty
    if (cc == 4)
      stageColorRun<T, 4>(src, run.hi - run.lo, p[0] + run.lo, p[1] + run.lo, p[2] + run.lo);
    else
      stageColorRun<T, 3>(src, run.hi - run.lo, p[0] + run.lo, p[1] + run.lo, p[2] + run.lo);
  } else {
    stageColorRow(f.color, source, s.row);
    for (int k = 0; k < n; ++k) {
      const float* px = s.row + 4 * column[k];
      p[0][k] = px[0];
      p[1][k] = px[1];
      p[2][k] = px[2];
    }
  }
  if (f.space == ClipSpace::YCoCg)
    for (int k = 0; k < n; k += temporal::kLanesOf<T>) {  // rgbToYCoCg (color_space.h), a lane group at a time
      const T r = temporal::loadLanes<T>(p[0] + k), g = temporal::loadLanes<T>(p[1] + k),
              b = temporal::loadLanes<T>(p[2] + k);
      temporal::storeLanes(p[0] + k, 0.25f * r + 0.5f * g + 0.25f * b);
      temporal::storeLanes(p[1] + k, 0.5f * r - 0.5f * b);
      temporal::storeLanes(p[2] + k, -0.25f * r + 0.5f * g - 0.25f * b);
    }
  if (f.motion.ptr) {
    auto motionTap = [&](int k) {
      const float* m = f.motion.pixel(column[k], source);
      p[kMotionX][k] = m[0];
      p[kMotionY][k] = m[1];
    };
    const std::size_t stride = f.motion.pixelStride;
    if (stride == 8 || stride == 16) {
      forEachClampedIndex(run, n, motionTap);
      const float* m = f.motion.pixel(std::clamp(first, 0, w - 1), source);
      const int step = int(stride / sizeof(float));
      const bool wholePixels = temporal::motionLanesReadable(f.motion);
      int k = run.lo;
      for (; wholePixels && k + temporal::kLanesOf<T> <= run.hi;
           k += temporal::kLanesOf<T>, m += temporal::kLanesOf<T> * step) {
        T mx, my;
        temporal::loadFirstTwoChannels(m, step, mx, my);
        temporal::storeLanes(p[kMotionX] + k, mx);
        temporal::storeLanes(p[kMotionY] + k, my);
      }
      for (; k < run.hi; ++k, m += step) {
        p[kMotionX][k] = m[0];
        p[kMotionY][k] = m[1];
      }
    } else {
      for (int k = 0; k < n; ++k) motionTap(k);
    }
  }
  if (!f.depth.ptr) return;
  float* d = s.depth[y % kRing];
  stageDepthRow(f.depth, source, s.row);
  forEachClampedIndex(run, n, [&](int k) { d[k] = s.row[column[k]]; });
  if (run.hi > run.lo)  // the unclamped run: one copy (column[k] = k - 1 - shiftX there)
    std::memcpy(d + run.lo, s.row + first, sizeof(float) * std::size_t(run.hi - run.lo));
  if (depthNow) std::memcpy(depthNow + std::size_t(y) * w, d + 1, std::size_t(w) * sizeof(float));
}

// alphaOf for a whole lane group x0 .. x0 + lanes - 1 of row y: packed RGBA a
// lane group at a time, other layouts pixel by pixel.
template <class T>
__attribute__((always_inline)) inline T inputAlphaLanes(const ImageView& color, int x0, int y) {
  if (color.channels() == 4 && color.pixelStride == 4 * sizeof(float)) {
    T r, g, b, a;
    temporal::loadInterleaved4(color.pixel(x0, y), r, g, b, a);
    return sanitizeColorLanes(a);
  }
  T a;
  for (int l = 0; l < temporal::kLanesOf<T>; ++l) temporal::setLane(a, l, alphaOf(color, x0 + l, y));
  return a;
}

// Rows [y0, y1) on the fast path: each row staged once per band (plus two
// halo rows above and below), then a lane group of pixels at a time: their taps, boxes,
// unjittered mix and reprojection from the planes, their history fetched as
// lanes where the group moves as one (else one pixel at a time), the same
// resolveLanes as the reference on all eight, the history stored as lanes.
// T: the lane type (temporal/lanes.h): Vec16 in the AVX-512 copy, Vec8 in
// the AVX2 one, Vec4 in the baseline (SSE2) one.
template <class T>
__attribute__((always_inline)) inline void fastRowsBody(const Frame& f, const BandScratch& s, int y0, int y1,
                                                      float* depthNow) {
  using temporal::maxOf;
  using temporal::minOf;
  using Int = temporal::IntOf<T>;
  constexpr int kL = temporal::kLanesOf<T>;
  const auto load = [](const float* p) __attribute__((always_inline)) { return temporal::loadLanes<T>(p); };
  const int w = f.width, h = f.height;
  const bool followDepth = f.depth.ptr && f.motion.ptr;
  if (y0 > 1) stageRow<T>(f, s, y0 - 2, nullptr);
  if (y0 > 0) stageRow<T>(f, s, y0 - 1, nullptr);
  stageRow<T>(f, s, y0, depthNow);
  if (y0 + 1 < h) stageRow<T>(f, s, y0 + 1, y0 + 1 < y1 ? depthNow : nullptr);
  const T laneIndex = temporal::laneIndexOf<T>();
  T mixWeights[9];  // f.unjitter.weights broadcast once, not in every group
  for (int k = 0; k < 9; ++k) mixWeights[k] = temporal::lanesOf<T>(f.unjitter.weights[k]);
  const bool packedOutput = f.writeOutput && f.unjitter.enabled && f.output.channels() == 4 &&
                            f.output.pixelStride == 4 * sizeof(float);
  for (int y = y0; y < y1; ++y) {
    long resets = 0, releases = 0;  // Kernel::resetsLastFrame and releasesLastFrame, this row's
    temporal::MaskOfT<T> alphaNotOne{};  // the packed output's lanes whose input alpha is not 1, this row's
    if (y + 2 < h) stageRow<T>(f, s, y + 2, y + 2 < y1 ? depthNow : nullptr);
    const int up = std::max(y - 1, 0) % kRing, mid = y % kRing, down = std::min(y + 1, h - 1) % kRing;
    float* const* rows[3] = {s.planes[up], s.planes[mid], s.planes[down]};
    float* const* rows5[5] = {s.planes[std::max(y - 2, 0) % kRing], rows[0], rows[1], rows[2],
                              s.planes[std::min(y + 2, h - 1) % kRing]};
    if (followDepth) temporal::closestDepthTapsRow<T>(s.depth[up], s.depth[mid], s.depth[down], w, s.tap, s.tapDepth);
    const std::size_t rowStart = std::size_t(y) * w;
    // The history row by streaming stores (no read of the lines first), on
    // 16 lanes where its four planes' rows start on a cache line.
    bool streamRow = false;
#if defined(__AVX512F__)
    if constexpr (std::is_same_v<T, temporal::Vec16>) {
      streamRow = f.streamHistory;
      for (int c = 0; c < 4; ++c)
        streamRow = streamRow && reinterpret_cast<std::uintptr_t>(f.history[c] + rowStart) % 64 == 0;
    }
#endif
    for (int x0 = 0; x0 < w; x0 += kL) {
      const int lanes = std::min(kL, w - x0), i = x0 + 1;  // i: plane index of pixel x0
      PixelLanes<T> in;
      for (int c = 0; c < 3; ++c) {
        T t[9];
        for (int k = 0; k < 9; ++k) t[k] = load(rows[k / 3][c] + i + k % 3 - 1);
        in.current[c] = f.unjitter.enabled ? temporal::unjitteredMix(t, mixWeights) : t[4];
        // Column-first boxes (neighbourhood.h columnFirstBoxes4).
        const T minL = minOf(minOf(t[0], t[3]), t[6]), minC = minOf(minOf(t[1], t[4]), t[7]),
                   minR = minOf(minOf(t[2], t[5]), t[8]);
        const T maxL = maxOf(maxOf(t[0], t[3]), t[6]), maxC = maxOf(maxOf(t[1], t[4]), t[7]),
                   maxR = maxOf(maxOf(t[2], t[5]), t[8]);
        in.boxMin[c] = minOf(minOf(minL, minC), minR);
        in.boxMax[c] = maxOf(maxOf(maxL, maxC), maxR);
        in.crossMin[c] = minOf(minOf(t[3], minC), t[5]);
        in.crossMax[c] = maxOf(maxOf(t[3], maxC), t[5]);
        if (f.varianceClip > 0.0f) momentsOf(t, in.mean[c], in.sigma[c]);
      }

      // Step 3: the followed tap's velocity, selected from the nine staged taps.
      T vx = temporal::lanesOf<T>(0.0f), vy = vx, tapDepth = temporal::lanesOf<T>(kBackgroundDepth);
      if (f.motion.ptr) {
        Int tap = temporal::truncOf(temporal::lanesOf<T>(4.0f));
        if (followDepth) {
          std::memcpy(&tap, s.tap + x0, sizeof tap);
          tapDepth = load(s.tapDepth + x0);
        }
        for (int k = 0; k < 9; ++k) {
          const Int chosen = tap == k;
          vx = chosen ? load(rows[k / 3][kMotionX] + i + k % 3 - 1) : vx;
          vy = chosen ? load(rows[k / 3][kMotionY] + i + k % 3 - 1) : vy;
        }
      }
      const ReprojectionLanes<T> rp =
          reprojectLanes<T>(f, float(x0) + laneIndex, temporal::lanesOf<T>(float(y)), vx, vy, tapDepth);
      // A whole group with valid history fetches it as lanes when nothing in it
      // moves (exact taps) or when every footprint (4x4 Catmull-Rom, 2x2
      // bilinear) is interior and shares one integer offset (smooth motion);
      // else one pixel at a time.
      const bool whole = lanes == kL && temporal::allOf(rp.valid);
      if (whole && !temporal::anyOf(rp.moving)) {
        for (int c = 0; c < 4; ++c) in.hist[c] = load(f.previous.plane[c] + rowStart + x0);
      } else if (whole && temporal::allOf(rp.moving) && f.filter == HistoryFilter::CatmullRom &&
                 temporal::sharedInteriorOffset<T>(rp.x0, rp.y0, rp.valid, -1, 2, -1, 2, w, h)) {
        // footprintInterior4x4 on every lane: the unclamped fetch's taps.
        temporal::fetchCatmullRomRow(f.previous, rp.x0[0], rp.y0[0], rp.tx, rp.ty, in.hist);
      } else if (whole && temporal::allOf(rp.moving) && f.filter == HistoryFilter::Bilinear &&
                 temporal::sharedInteriorOffset<T>(rp.x0, rp.y0, rp.valid, 0, 1, 0, 1, w, h)) {
        // Every lane's 2x2 inside the image: fetchBilinear4's taps, unclamped.
        temporal::fetchBilinearRow(f.previous, rp.x0[0], rp.y0[0], rp.tx, rp.ty, in.hist);
      } else {
        alignas(32) float hist[4][kL] = {};
        for (int l = 0; l < lanes; ++l) {
          if (!rp.valid[l]) continue;
          const Vec4 v = fetchHistory(f, x0 + l, y, rp.moving[l] != 0, {rp.x0[l], rp.y0[l], rp.tx[l], rp.ty[l]},
                                      rp.qx[l], rp.qy[l]);
          for (int c = 0; c < 4; ++c) hist[c][l] = v[c];
        }
        for (int c = 0; c < 4; ++c) in.hist[c] = load(hist[c]);
      }
      // The history state (historyStateOf) and aliasedValue: a lane group at a
      // time (a partial group at the row's end pads with zeros).
      if (lanes == kL) {
        const Int state = temporal::loadBytesOf<T>(f.historyState + rowStart + x0);
        in.feedbackSinceReset = 0 - (state & 1);
        in.framesSinceReset = temporal::floatOf(state >> 1);
        in.aliased = f.aliased ? load(f.aliased + rowStart + x0) : temporal::lanesOf<T>(0.0f);
        if (f.release.words) in.holdWord = temporal::loadHoldWords<T>(f.release.words + rowStart + x0);
      } else {
        alignas(32) float aliased[kL] = {}, frames[kL] = {};
        alignas(32) int since[kL] = {};
        for (int l = 0; l < lanes; ++l) {
          since[l] = -int((f.historyState[rowStart + x0 + l] & 1) != 0);
          frames[l] = float(f.historyState[rowStart + x0 + l] >> 1);
          if (f.aliased) aliased[l] = f.aliased[rowStart + x0 + l];
        }
        std::memcpy(&in.feedbackSinceReset, since, sizeof since);
        in.framesSinceReset = load(frames);
        in.aliased = load(aliased);
        if (f.release.words) {
          alignas(32) std::uint32_t words[kL] = {};
          std::memcpy(words, f.release.words + rowStart + x0, sizeof(std::uint32_t) * std::size_t(lanes));
          in.holdWord = temporal::loadHoldWords<T>(words);
        }
      }
      in.tx = rp.tx;
      in.ty = rp.ty;
      in.valid = rp.valid;
      in.moving = rp.moving;

      const ResolvedLanes<T> r = resolveLanes(f, in, [&](int l, float* excess) {
        const int x = x0 + l;
        if (!temporal::stillFootprint(f.motion, x, y, w, h, f.unjitter.shiftX, f.unjitter.shiftY)) return false;
        // The reference's 25 taps in its order; plane column i + l + dx,
        // clamped to the padding (= the edge pixel, as the reference's clamp).
        auto tap5 = [&](int k) {
          const int column = std::clamp(i + l + k % 5 - 2, 0, w + 1);
          float* const* p = rows5[k / 5];
          return Vec4{p[0][column], p[1][column], p[2][column], 0.0f};  // lane 3: unused by the clip
        };
        temporal::TwoExtremes4 e = temporal::twoExtremesOf(tap5(0), tap5(1));
        for (int k = 2; k < 25; ++k) temporal::addTap(e, tap5(k));
        const temporal::MinMax4 box3x3{Vec4{in.boxMin[0][l], in.boxMin[1][l], in.boxMin[2][l], 0.0f},
                                       Vec4{in.boxMax[0][l], in.boxMax[1][l], in.boxMax[2][l], 0.0f}};
        const temporal::MinMax4 box = temporal::footprintBox(box3x3, e);
        temporal::clipTowardCentre4(Vec4{in.hist[0][l], in.hist[1][l], in.hist[2][l], in.hist[3][l]}, box.min, box.max,
                                    excess);
        return true;
      });
      if (temporal::anyOf(r.guarded)) {
        long hits = 0;
        for (int l = 0; l < lanes; ++l) hits += r.guarded[l] != 0;
        f.guards->fetch_add(hits, std::memory_order_relaxed);
      }
      if (temporal::anyOf(r.reset))
        for (int l = 0; l < lanes; ++l) {
          releases += r.released[l] != 0;
          resets += r.reset[l] != 0 && r.released[l] == 0;
        }

      if (lanes == kL) {
        // historyStateOf, a lane group at a time.
        temporal::storeBytesOf<T>(f.historyState + rowStart + x0,
                                  (r.feedbackSinceReset & 1) | temporal::truncOf(r.framesSinceReset) << 1);
        if (f.release.words) temporal::storeHoldWords<T>(f.release.words + rowStart + x0, r.holdWord);
        if (streamRow) {
#if defined(__AVX512F__)
          for (int c = 0; c < 3; ++c) _mm512_stream_ps(f.history[c] + rowStart + x0, (__m512)r.color[c]);
          _mm512_stream_ps(f.history[3] + rowStart + x0, (__m512)r.signedWeight);
#endif
        } else {
          for (int c = 0; c < 3; ++c) temporal::storeLanes(f.history[c] + rowStart + x0, r.color[c]);
          temporal::storeLanes(f.history[3] + rowStart + x0, r.signedWeight);
        }
        if (packedOutput) {
          // storeOutputPixel on packed RGBA, where it reads the input for the
          // alpha only (the unjittered mix is the current colour even on a reset).
          const T alpha = inputAlphaLanes<T>(f.color, x0, y);
          alphaNotOne |= alpha != temporal::lanesOf<T>(1.0f);
          temporal::storeInterleaved4(f.output.pixel(x0, y), r.output[0], r.output[1], r.output[2], alpha);
        } else {
          for (int l = 0; l < kL; ++l) {
            const float output[3] = {r.output[0][l], r.output[1][l], r.output[2][l]};
            storeOutputPixel(f, x0 + l, y, output, r.reset[l] != 0);
          }
        }
      } else {
        for (int l = 0; l < lanes; ++l) {
          f.historyState[rowStart + x0 + l] = historyStateOf(r.feedbackSinceReset[l] != 0, r.framesSinceReset[l]);
          if (f.release.words) f.release.words[rowStart + x0 + l] = std::uint32_t(r.holdWord[l]);
          const float color[3] = {r.color[0][l], r.color[1][l], r.color[2][l]};
          const float output[3] = {r.output[0][l], r.output[1][l], r.output[2][l]};
          storePixel(f, x0 + l, y, color, r.signedWeight[l], output, r.reset[l] != 0);
        }
      }
    }
    if (resets) f.resets->fetch_add(resets, std::memory_order_relaxed);
    if (releases) f.releases->fetch_add(releases, std::memory_order_relaxed);
    if (temporal::anyOf(alphaNotOne)) noteAlphaBelowOne(f);
  }
#if defined(__AVX512F__)
  // The streamed stores are weakly ordered: visible before the band is done.
  if constexpr (std::is_same_v<T, temporal::Vec16>) _mm_sfence();
#endif
}

}  // namespace

}  // namespace crisp::taa::rows
