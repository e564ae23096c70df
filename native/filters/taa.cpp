// SPDX-License-Identifier: Apache-2.0
// "taa": the baseline temporal reprojection anti-aliasing of seed 000 chapter
// III (after Xu 2016 / Uncharted 4 and Pedersen 2016 / INSIDE; Karis 2014),
// condensed in METHODS.md "TAA baseline". Per pixel:
//   1. current colour = the unjittered 3x3 mix of this frame (see "Jitter"
//      below), or the pixel's own jittered sample with unjitter = none;
//   2. 3x3 and cross (5-tap) min/max/avg of the current frame, "rounded" (the
//      mean of the two) (§3.6.3, Fig. 3.7);
//   3. velocity of the closest-depth pixel of the 3x3 (§3.6.3), or the
//      centre's velocity without depth; no motion image = static scene;
//   4. history reprojected to p + v (conventions.h: motion = previous -
//      current) with a bilinear or Catmull-Rom fetch whose negative lobes are
//      clamped (temporal/history_fetch.h) (§3.6.3, seed 004 "TAA steps" 3-5);
//   5. history clipped (not clamped) toward the box centre, in YCoCg or RGB
//      (§3.6.4, Fig. 3.9);
//   6. blend: history weight k = lerp(kmin, kmax, (1 - |l0-l1|/max(l0,l1,0.2))^2)
//      (§3.6.3 "valor de retroalimentacion"; Pedersen's unbiased luma
//      difference), kmin/kmax = 0.7/0.85 (the seed's 0.88/0.97 is a
//      parameter setting; see "Deliberate choices");
//   7. optional sharpen of the output with [0,-1,0;-1,5,-1;0,-1,0] (eq. 3.1);
//   8. off-screen, non-finite or depth-rejected reprojection -> reset to the
//      current colour; first frame after commit/reset -> current colour.
// Static-scene accumulation (METHODS.md "Jitter and references"; seed 004
// "TAA for ray tracing"; PHLM's special case): where the reprojection
// velocity is exactly zero and the pixel was static in the previous frame
// too, the history is a running average with weight w/W (W = accumulated
// sample weight, capped at maxSamples) in linear light, so a still scene
// converges to the average of its jittered samples: to the box-filtered image
// for uniform jitter, to EEVEE's Blackman-Harris-filtered reference for
// jitter drawn like EEVEE's (temporal/jitter.h) or uniform jitter weighted by
// jitterWeighting = blackman-harris. The feedback blend of step 6 still
// floors the current-frame weight everywhere else, and W also bootstraps it
// (weight max(1 - k, w/W)), so a reset pixel converges quickly.
//
// Jitter (METHODS.md: "unjittering the current frame by resampling it at
// p - j blurs it"; its TAA baseline: "unjittered current colour"). A pixel's
// own sample sits at p + j; with EEVEE's jitter (+-filterSize = +-1.5 px) it
// jumps across edges from frame to frame, and so does a 3x3 box around it.
// `unjitter` (default blackman-harris; Karis 2014) reads the 3x3 around the
// sample nearest the pixel centre (the image shifted by round(j), |j -
// round(j)| <= 0.5) for the clip box and the followed tap, and takes as the
// current colour of every pixel that 3x3 weighted by EEVEE's Blackman-Harris
// filter at the unjittered centre (tap q sits at q + j - round(j)); no
// resampling of the image, only weights. Averaged over EEVEE's jitter phases
// the mix converges to the same filtered pixel as the raw samples: phase d
// weighs tap q by BH(q + d) / sum_q' BH(q' + d), and d's density under
// EEVEE's draw is that same sum up to a constant, so offset u = q + d gets
// weight BH(u). Each mix already integrates 9 samples, so the average
// converges far faster, and it smooths EEVEE's first-sample shadow/AO noise,
// which every 1-sample frame repeats and averaging raw samples never removes.
// Measured (crisp eval; docs/temporal_figures.md): still_life 480x270 frame
// 16 31.96 -> 39.62 dB (EEVEE at 16 samples: 34.40); camera_dolly 240x136,
// frames 9-48, 21.24 -> 24.34 dB, temporal error 0.0230 -> 0.0176 (feedback
// 0.88/0.97). The price: 16-64 discrete phases leave a small bias (synthetic
// still edges: 41-50 dB where raw samples keep converging; test_taa.cpp
// BlackmanHarrisJitterConvergesToEeveeStyleReference). unjitter = none keeps
// the raw samples (exact accumulation; converges to a box filter for jitter
// drawn uniformly inside the pixel). The reprojected history is jitter-free
// (motion vectors never include jitter), so nothing else needs unjittering.
//
// Deliberate choices, beside the code below:
//  * feedback 0.7/0.85 by default, not seed 000's 0.88/0.97 (METHODS.md's
//    defaults, tuned for game TAA with jitter inside the pixel): with
//    EEVEE's +-1.5 px jitter and the unjittered current colour, the current
//    frame is already a filtered estimate and each frame kept in the history
//    went through one more filtered resample. Only pixels on the feedback
//    path change (moving, or rejected); still pixels average all samples.
//    Measured (crisp eval, 240x136, frames 9-48 vs 256 samples; PSNR dB /
//    temporal error), 0.88/0.97 -> 0.7/0.85: camera_dolly 24.34/0.0176 ->
//    24.97/0.0177, ghosting 26.26/0.0069 -> 27.59/0.0066, spinning_cube
//    29.44/0.0035 -> 32.67/0.0029; still_life frame 16 32.30 -> 32.28. Lower
//    still (0.5/0.7) helps these three scenes more but doubles the flicker of
//    a slowly moving synthetic edge (0.0012 -> 0.0024); 0.7/0.85 is the best
//    PSNR there (41.2 vs 39.4 dB). A speed-dependent weight (k s / (s + |v|))
//    was measured too and lost on camera_dolly's temporal error.
//  * the static path tests history against the footprint box, the moving
//    path clips against the rounded box as the seed does. The converged value
//    mixes the scene over the jitter's footprint (+-filterSize = +-1.5 px for
//    EEVEE's draw), which one frame's 3x3 (samples at [-1, 1] px shifted by up
//    to 1.5 px of jitter) misses next to an edge: still_life frame 8 lost
//    4 dB (31.2 -> 27.2) to such rejections. The footprint box is the 3x3 box
//    united with the 5x5 box of second-largest/second-smallest values per
//    channel (a colour must show in two of the 25 samples, so a lone firefly
//    does not widen it). History that went through the feedback path since
//    its last reset (moving, or rejected: a trail, a clipped firefly) is
//    tested against the 3x3 box, as before (a 1-byte plane per pixel). A
//    wider tolerance on the 3x3 box does not help: next to an edge one
//    frame's 3x3 is often flat (measured: +0.4 dB at best on frame 8);
//  * with staticClip (default), history outside that box in a static pixel
//    leaves the running average for the feedback blend: cuts, fireflies and
//    light changes are rejected at once, but a sub-pixel feature that a
//    frame's whole 3x3 misses is clipped like plain TAA; staticClip = false
//    trusts static history (pure accumulation, converges on thin lines; the
//    caller must reset() on a cut or lighting change);
//  * the sharpened image goes to the output only; the history keeps the
//    unsharpened blend so sharpening never accumulates. The sharpened value is
//    clamped to the range of its 5 taps (no ringing, no negative colours).
//
// Parameters (also `crisp help taa` / crispGetFilterDoc):
// | name | type | default | range | meaning | source |
// |---|---|---|---|---|---|
// | jitterX | float | 0 | [-4, 4] | this frame's sample offset, pixels, x right | §3.6.1, app. B |
// | jitterY | float | 0 | [-4, 4] | this frame's sample offset, pixels, y DOWN (negate Blender's/sidecar's y) | §3.6.1, app. B |
// | jitterWeighting | string | none | none, blackman-harris | weight of each frame's sample in the accumulation | METHODS.md Jitter |
// | filterSize | float | 1.5 | [0.01, 4] | Blackman-Harris filter width for the weighting | BLENDER.md Sampling |
// | historyFilter | string | catmull-rom | catmull-rom, bilinear | reprojected history fetch | §3.6.3 |
// | clipSpace | string | ycocg | ycocg, rgb | space of the clip box | §3.6.4 |
// | feedbackMin | float | 0.7 | [0, 1] | history weight at a large luma difference | §3.6.3 (seed: 0.88) |
// | feedbackMax | float | 0.85 | [0, 1] | history weight at equal luma | §3.6.3 (seed: 0.97) |
// | sharpen | float | 0 | [0, 1] | amount of the eq. 3.1 sharpen on the output | eq. 3.1 |
// | staticAccumulation | bool | true | - | running average where nothing moves | METHODS.md Jitter |
// | maxSamples | int | 128 | [1, 65536] | cap of the running average's sample count | this file |
// | staticClip | bool | true | - | clip static history too | this file |
// | depthTolerance | float | 0.05 | [0, 10] | relative depth change still the same surface | this file |
// | unjitter | string | blackman-harris | blackman-harris, nearest, none | the current colour: the unjittered 3x3 mix | Karis 2014 |
// | reference | bool | false | - | scalar reference path | this file |
#include "filters/taa.h"

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <cstring>

#include "core/color.h"
#include "core/error.h"
#include "core/filter.h"
#include "core/parallel.h"
#include "core/row_stage.h"
#include "temporal/color_space.h"
#include "temporal/history_fetch.h"
#include "temporal/isa.h"
#include "temporal/rows.h"
#include "temporal/jitter.h"
#include "temporal/neighbourhood.h"
#include "temporal/vec4.h"
#include "temporal/velocity.h"

namespace crisp::taa {

using temporal::Float3;
using temporal::Vec4;

namespace {

// Everything one frame's pixels read, set up once per frame.
struct Frame {
  int width, height;
  const float* previousDepth;  // previous frame's sanitised depth, or null (no depth test)
  ImageView color;             // the input, for exact resets
  ImageView motion;            // ptr null: static scene
  ImageView depth;             // ptr null: no depth
  temporal::HistoryImage previous;  // valid only if hasHistory
  bool hasHistory;
  float* history;              // written: RGBA
  ImageView output;            // written unless sharpening
  bool writeOutput;
  ClipSpace space;
  HistoryFilter filter;
  float sampleWeight;          // w of this frame's sample
  float feedbackMin, feedbackMax;
  bool staticAccumulation, staticClip;
  std::uint8_t* feedbackSinceReset;    // Kernel::feedbackSinceReset_, read and written in place
  float maxSamples;
  float depthTolerance;
  const float* aliased;        // aliasedValue plane or null
  bool aliasedNeighbourhood, aliasedBoxSize;
  // Unjitter (see "Jitter"): the 3x3 of pixel p is read around p - shift, the
  // samples nearest p, and its taps weighted give the current colour.
  temporal::Unjitter unjitter;
};

// The current frame as the kernel reads it (conventions.h): sanitised, in
// the clip space, alpha 1 for RGB input. Both paths stage through this.
inline Vec4 stagePixel(const float* p, int channels, ClipSpace space) {
  Vec4 v = channels > 3 ? temporal::load4(p)
                        : Vec4{p[0], channels > 1 ? p[1] : p[0], channels > 2 ? p[2] : p[0], 1.0f};
  v = temporal::sanitize4(v, kMaxColor);  // sanitizeColor per lane; alpha 1 stays 1
  if (space == ClipSpace::YCoCg) {
    const Float3 c = temporal::rgbToYCoCg({{v[0], v[1], v[2]}});
    v = Vec4{c[0], c[1], c[2], v[3]};
  }
  return v;
}

inline float lumaOf(const Vec4& c, ClipSpace space) {
  return space == ClipSpace::YCoCg ? c[0] : 0.2126f * c[0] + 0.7152f * c[1] + 0.0722f * c[2];
}

inline Float3 toRgb(const Float3& c, ClipSpace space) {
  return space == ClipSpace::YCoCg ? temporal::yCoCgToRgb(c) : c;
}

// rgb in lanes 0-2 (sanitised here), alpha in lane 3.
inline void storeOutput(const ImageView& out, int x, int y, Vec4 rgba) {
  const float alpha = rgba[3];
  rgba = temporal::sanitize4(rgba, kMaxColor);
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

// What the per-pixel core needs from the 3x3 block, however it was gathered.
struct Neighbourhood {
  Vec4 current;                  // staged: the unjittered mix, or the centre tap without unjitter
  temporal::MinMax4 box3x3, cross;
  int tap;                       // followed tap (closest depth; 4 = centre), row order
  float tapDepth;                // its sanitised depth (with depth only)
};

constexpr int kTapDx[9] = {-1, 0, 1, -1, 0, 1, -1, 0, 1};
constexpr int kTapDy[9] = {-1, -1, -1, 0, 0, 0, 1, 1, 1};

// Row `px` (w pixels of `comps` floats) shifted in place: px'[q] = px[clamp(q - shift)].
inline void shiftRowInPlace(float* px, int w, int comps, int shift) {
  if (shift > 0)
    for (int q = w - 1; q >= 0; --q) std::memmove(px + q * comps, px + std::max(q - shift, 0) * comps, comps * 4);
  else if (shift < 0)
    for (int q = 0; q < w; ++q) std::memmove(px + q * comps, px + std::min(q - shift, w - 1) * comps, comps * 4);
}

// Steps 3-8 for one pixel: the part both paths share (and taa-improved, through
// the aliasedValue plane). Writes the history and, unless sharpening, the output.
// footprintBox() returns the 5x5 box of this frame (MinMax4); it is called only
// for the static test, so moving pixels never pay for it.
template <class FootprintBox>
__attribute__((always_inline)) inline void resolvePixel(const Frame& f, int x, int y, const Neighbourhood& nb,
                                                        FootprintBox&& footprintBox) {
  const int w = f.width, h = f.height;
  const Vec4 current = nb.current;
  const float alpha = current[3];

  // Step 3: velocity of the followed tap (clamped to the image, as the taps are).
  float vx = 0.0f, vy = 0.0f;
  if (f.motion.ptr) {
    const float* m = f.motion.pixel(temporal::shiftedSource(x + kTapDx[nb.tap], w, f.unjitter.shiftX),
                                    temporal::shiftedSource(y + kTapDy[nb.tap], h, f.unjitter.shiftY));
    vx = m[0];
    vy = m[1];
  }
  const bool moving = vx != 0.0f || vy != 0.0f;

  // Step 8: is there usable history at p + v?
  const float qx = float(x) + vx, qy = float(y) + vy;
  bool valid = f.hasHistory && temporal::finiteMotion(vx, vy) && temporal::onScreen(qx, qy, w, h);
  // The reprojected position's taps, shared by the depth test and the fetch.
  temporal::Footprint fp{};
  if (valid && (moving || f.previousDepth)) fp = temporal::footprintOf(qx, qy);
  if (valid && f.previousDepth) {
    // Disocclusion: some tap of the bilinear footprint with non-zero weight
    // must hold the surface whose velocity we follow (depth is compared,
    // never interpolated). Evaluated without branches.
    const int xa = std::clamp(fp.x0, 0, w - 1), xb = std::clamp(fp.x0 + 1, 0, w - 1);
    const float* r0 = f.previousDepth + std::size_t(std::clamp(fp.y0, 0, h - 1)) * w;
    const float* r1 = f.previousDepth + std::size_t(std::clamp(fp.y0 + 1, 0, h - 1)) * w;
    const float d = nb.tapDepth, tol = f.depthTolerance;
    const bool useX1 = fp.tx != 0.0f, useY1 = fp.ty != 0.0f;
    // 0/1 integers, combined without short-circuit branches.
    const int x1 = useX1, y1 = useY1;
    valid = (int(temporal::sameSurfaceDepth(d, r0[xa], tol)) | (x1 & int(temporal::sameSurfaceDepth(d, r0[xb], tol))) |
             (y1 & int(temporal::sameSurfaceDepth(d, r1[xa], tol))) |
             (x1 & y1 & int(temporal::sameSurfaceDepth(d, r1[xb], tol)))) != 0;
  }

  Vec4 hist = temporal::splat(0.0f);
  if (valid) {
    if (!moving)
      hist = temporal::load4(f.previous.at(x, y));  // exact: no filtering at zero motion
    else if (f.filter == HistoryFilter::CatmullRom)
      hist = temporal::footprintInterior4x4(fp, w, h) ? temporal::fetchCatmullRomAt4<false>(f.previous, fp)
                                                      : temporal::fetchCatmullRomAt4<true>(f.previous, fp);
    else
      hist = temporal::fetchBilinear4(f.previous, qx, qy);
  }
  const float historyWeight = valid ? std::fabs(hist[3]) : 0.0f;
  const float weight = f.sampleWeight;
  const float weightSum = historyWeight + weight;

  Vec4 result = current;
  float newWeight = weight;
  bool reset = !valid || !(weightSum > 0.0f);  // first frame bootstrap / invalid reprojection
  std::uint8_t& feedbackSinceReset = f.feedbackSinceReset[std::size_t(y) * w + x];
  if (!reset) {
    const bool staticPixel = f.staticAccumulation && !moving && hist[3] > 0.0f;
    float excess = 0.0f;
    // Static history built by the running average alone since its last reset
    // is tested against the footprint box (3x3 united with the robust 5x5):
    // the converged value mixes the scene over the jitter's whole footprint
    // (+-filterSize = +-1.5 px for EEVEE's draw), which one frame's 3x3,
    // shifted by up to 1.5 px of jitter, misses near an edge. History that
    // went through the feedback path (a trail behind a moving object, a
    // clipped firefly: plausible colours of the footprint, but wrong) keeps
    // the 3x3 box.
    // The footprint box contains the 3x3 box: it is gathered only for
    // history outside the 3x3 box (the same decision, at a fraction of the cost).
    if (staticPixel && f.staticClip) {
      temporal::clipTowardCentre4(hist, nb.box3x3.min, nb.box3x3.max, &excess);
      if (excess > 1.0f && !feedbackSinceReset && temporal::stillFootprint(f.motion, x, y, w, h, f.unjitter.shiftX, f.unjitter.shiftY)) {
        const temporal::MinMax4 box = footprintBox();
        temporal::clipTowardCentre4(hist, box.min, box.max, &excess);
      }
    }
    if (staticPixel && (!f.staticClip || !(excess > 1.0f))) {
      // Running average, weight w/W, in linear light.
      result = hist + (current - hist) * (weight / weightSum);
      newWeight = std::min(weightSum, f.maxSamples);
    } else {
      // Kept until a reset: averaging dilutes a trail or a clipped firefly,
      // never removes it, and the footprint box would let it stay.
      feedbackSinceReset = 1;
      // The moving path's box: the rounded box (mean of 3x3 and cross), or
      // steered by aliasedValue a (seed 000 §4.3.4): mix(cross, 3x3, a)
      // (eq. 4.15) and shrunk toward the current colour, mix(current, box, a)
      // (eq. 4.16); mix(x, y, t) = x(1 - t) + yt (eq. 4.11).
      Vec4 lo, hi;
      const float a = f.aliased ? f.aliased[std::size_t(y) * w + x] : 0.0f;
      if (f.aliased && f.aliasedNeighbourhood) {
        lo = nb.cross.min * (1.0f - a) + nb.box3x3.min * a;
        hi = nb.cross.max * (1.0f - a) + nb.box3x3.max * a;
      } else {
        lo = 0.5f * (nb.box3x3.min + nb.cross.min);
        hi = 0.5f * (nb.box3x3.max + nb.cross.max);
      }
      if (f.aliased && f.aliasedBoxSize) {
        lo = current * (1.0f - a) + lo * a;
        hi = current * (1.0f - a) + hi * a;
      }
      const Vec4 clipped = temporal::clipTowardCentre4(hist, lo, hi, &excess);
      // Step 6: luma-difference feedback on the clipped history.
      const float l0 = lumaOf(clipped, f.space), l1 = lumaOf(current, f.space);
      const float diff = std::clamp(std::fabs(l0 - l1) / std::max(std::max(l0, l1), 0.2f), 0.0f, 1.0f);
      const float unbiased = (1.0f - diff) * (1.0f - diff);
      const float k = f.feedbackMin + (f.feedbackMax - f.feedbackMin) * unbiased;
      const float mixWeight = std::max(1.0f - k, weight / weightSum);
      result = clipped + (current - clipped) * mixWeight;
      // The effective sample count of an exponential blend is about 1/(1-k).
      newWeight = 1.0f - k > 0.0f ? std::min(weightSum, 1.0f / (1.0f - k)) : weightSum;
      newWeight = std::min(newWeight, f.maxSamples);
    }
    // Guard: never let a non-finite value into the history.
    reset = !(std::isfinite(result[0]) && std::isfinite(result[1]) && std::isfinite(result[2]));
  }
  if (reset) {
    result = current;
    newWeight = weight;
    feedbackSinceReset = 0;
  }
  result[3] = moving ? -newWeight : newWeight;  // sign: was this pixel static this frame
  temporal::store4(f.history + (std::size_t(y) * w + x) * 4, result);
  if (!f.writeOutput) return;
  if (reset && !f.unjitter.enabled) {
    // Reset to current: the input colour itself (sanitised), not its YCoCg
    // round trip, which can differ in the last bit.
    const float* p = f.color.pixel(x, y);
    const int cc = f.color.channels();
    storeOutput(f.output, x, y, Vec4{p[0], cc > 1 ? p[1] : p[0], cc > 2 ? p[2] : p[0], alpha});
  } else {
    storeOutput(f.output, x, y, toRgb4(result, f.space, alpha));
  }
}

// The scalar reference: every tap clamped to the image and staged on the
// spot, boxes by the column-first definition, depth sanitised per tap.
void referencePixel(const Frame& f, int x, int y, float* depthNow) {
  const int w = f.width, h = f.height;
  const int cc = f.color.channels();
  Vec4 taps[9];
  float depth9[9];
  // Without unjitter the shift is 0 and shiftedSource a plain clamp.
  for (int i = 0; i < 9; ++i) {
    const int tx = temporal::shiftedSource(x + kTapDx[i], w, f.unjitter.shiftX), ty = temporal::shiftedSource(y + kTapDy[i], h, f.unjitter.shiftY);
    taps[i] = stagePixel(f.color.pixel(tx, ty), cc, f.space);
    depth9[i] = f.depth.ptr ? temporal::sanitizeDepth(f.depth.pixel(tx, ty)[0]) : kBackgroundDepth;
  }
  Neighbourhood nb;
  nb.current = f.unjitter.enabled ? temporal::unjitteredMix(taps, f.unjitter.weights) : taps[4];
  temporal::columnFirstBoxes4(taps, nb.box3x3, nb.cross);
  nb.tap = (f.depth.ptr && f.motion.ptr) ? temporal::closestDepthTap(depth9) : 4;
  nb.tapDepth = depth9[nb.tap];
  if (depthNow) depthNow[std::size_t(y) * w + x] = depth9[4];
  resolvePixel(f, x, y, nb, [&] {
    auto tap = [&](int i) {
      const int tx = temporal::shiftedSource(x + i % 5 - 2, w, f.unjitter.shiftX), ty = temporal::shiftedSource(y + i / 5 - 2, h, f.unjitter.shiftY);
      return stagePixel(f.color.pixel(tx, ty), cc, f.space);
    };
    temporal::TwoExtremes4 e = temporal::twoExtremesOf(tap(0), tap(1));
    for (int i = 2; i < 25; ++i) temporal::addTap(e, tap(i));
    return temporal::footprintBox(nb.box3x3, e);
  });
}

// Fast path scratch of one row band: a ring of five staged rows and five
// depth rows, each padded by one pixel left and right (a copy of the edge
// pixel = clamp-to-edge), and the 3- and 5-row column reductions of the
// current row.
constexpr int kRing = 5;
struct BandScratch {
  float* staged[kRing];  // (width + 2) x 4
  float* depth[kRing];   // width + 2
  float* columnMin;  // (width + 2) x 4: column reductions of the current row
  float* columnMax;
  float* columnExtremes;  // (width + 2) x 16: TwoExtremes4 of rows y - 2 .. y + 2
  float* tap;        // width: the current row's closest-depth taps (int bits, read and written by memcpy)
  float* tapDepth;   // width: their depths
};

inline std::size_t bandFloats(int width) { return std::size_t(width + 2) * (kRing * 4 + kRing + 8 + 16 + 2); }

BandScratch bandScratch(float* base, int width) {
  const std::size_t row = std::size_t(width + 2);
  BandScratch s;
  for (int i = 0; i < kRing; ++i) s.staged[i] = base + i * row * 4;
  float* next = base + kRing * 4 * row;
  for (int i = 0; i < kRing; ++i) s.depth[i] = next + i * row;
  next += kRing * row;
  s.columnMin = next;
  s.columnMax = next + 4 * row;
  s.columnExtremes = next + 8 * row;
  s.tap = next + 24 * row;
  s.tapDepth = next + 25 * row;
  return s;
}

// Stages image row y into ring slot y % kRing (and this frame's depth plane when
// the row belongs to the band).
// The same values as stagePixel, a row at a time (core/row_stage.h); inlined
// into both copies of the row loop.
__attribute__((always_inline)) inline void stageRow(const Frame& f, const BandScratch& s, int y, float* depthNow) {
  const int w = f.width;
  float* dst = s.staged[y % kRing];
  // Row y of the shifted image (Frame::shiftX/Y; no shift without unjitter).
  const int source = std::clamp(y - f.unjitter.shiftY, 0, f.height - 1);
  stageColorRow(f.color, source, dst + 4);
  shiftRowInPlace(dst + 4, w, 4, f.unjitter.shiftX);
  if (f.space == ClipSpace::YCoCg)
    for (int x = 1; x <= w; ++x) {
      const Vec4 v = temporal::load4(dst + 4 * x);
      const Float3 c = temporal::rgbToYCoCg({{v[0], v[1], v[2]}});
      temporal::store4(dst + 4 * x, Vec4{c[0], c[1], c[2], v[3]});
    }
  std::memcpy(dst, dst + 4, 4 * sizeof(float));
  std::memcpy(dst + 4 * (w + 1), dst + 4 * w, 4 * sizeof(float));
  if (!f.depth.ptr) return;
  float* d = s.depth[y % kRing];
  stageDepthRow(f.depth, source, d + 1);
  shiftRowInPlace(d + 1, w, 1, f.unjitter.shiftX);
  d[0] = d[1];
  d[w + 1] = d[w];
  if (depthNow) std::memcpy(depthNow + std::size_t(y) * w, d + 1, std::size_t(w) * sizeof(float));
}

// Rows [y0, y1) on the fast path: staging folded into the pass (each row is
// staged once per band, plus two halo rows above and below), the 3x3 and
// cross boxes from shared column reductions (3 min + 3 max per column instead
// of 9 + 9 per pixel), the 5x5 box of the static test likewise (5 columns of
// 5-row reductions, only for pixels that take the test), the same per-pixel core.
__attribute__((always_inline)) inline void fastRowsBody(const Frame& f, const BandScratch& s, int y0, int y1,
                                                      float* depthNow) {
  const int w = f.width, h = f.height;
  const bool followDepth = f.depth.ptr && f.motion.ptr;
  if (y0 > 1) stageRow(f, s, y0 - 2, nullptr);
  if (y0 > 0) stageRow(f, s, y0 - 1, nullptr);
  stageRow(f, s, y0, depthNow);
  if (y0 + 1 < h) stageRow(f, s, y0 + 1, y0 + 1 < y1 ? depthNow : nullptr);
  for (int y = y0; y < y1; ++y) {
    if (y + 2 < h) stageRow(f, s, y + 2, y + 2 < y1 ? depthNow : nullptr);
    const int up = std::max(y - 1, 0) % kRing, mid = y % kRing, down = std::min(y + 1, h - 1) % kRing;
    const float* s0 = s.staged[up];
    const float* s1 = s.staged[mid];
    const float* s2 = s.staged[down];
    const float* sUp2 = s.staged[std::max(y - 2, 0) % kRing];
    const float* sDown2 = s.staged[std::min(y + 2, h - 1) % kRing];
    // Unaligned loads/stores only (memcpy): the scratch carries no alignment promise.
    for (int i = 0; i < w + 2; ++i) {
      const temporal::ColumnReduction4 c = temporal::reduceColumn4(
          temporal::load4(s0 + 4 * i), temporal::load4(s1 + 4 * i), temporal::load4(s2 + 4 * i));
      temporal::store4(s.columnMin + 4 * i, c.min);
      temporal::store4(s.columnMax + 4 * i, c.max);
    }
    // The 5-row column extremes, gathered for the whole row when its first
    // pixel takes the footprint test (never in a row where everything moves).
    bool extremesReady = false;
    auto gatherExtremes = [&] {
      for (int i = 0; i < w + 2; ++i) {
        temporal::TwoExtremes4 e = temporal::twoExtremesOf(temporal::load4(sUp2 + 4 * i), temporal::load4(s0 + 4 * i));
        temporal::addTap(e, temporal::load4(s1 + 4 * i));
        temporal::addTap(e, temporal::load4(s2 + 4 * i));
        temporal::addTap(e, temporal::load4(sDown2 + 4 * i));
        std::memcpy(s.columnExtremes + 16 * i, &e, sizeof e);
      }
      extremesReady = true;
    };
    const float* d1 = s.depth[mid];
    if (followDepth) temporal::closestDepthTapsRow(s.depth[up], d1, s.depth[down], w, s.tap, s.tapDepth);
    for (int x = 0; x < w; ++x) {
      const int i = x + 1;
      Neighbourhood nb;
      nb.current = temporal::load4(s1 + 4 * i);
      if (f.unjitter.enabled) {  // the 3x3 of the shifted image, as the reference
        const float* rows[3] = {s0, s1, s2};
        Vec4 taps[9];
        for (int t = 0; t < 9; ++t) taps[t] = temporal::load4(rows[t / 3] + 4 * (i + t % 3 - 1));
        nb.current = temporal::unjitteredMix(taps, f.unjitter.weights);
      }
      auto column = [&](int k) {
        return temporal::ColumnReduction4{temporal::load4(s.columnMin + 4 * k), temporal::load4(s.columnMax + 4 * k)};
      };
      temporal::boxesFromColumns4(column(i - 1), column(i), column(i + 1), temporal::load4(s1 + 4 * (i - 1)),
                                  temporal::load4(s1 + 4 * (i + 1)), nb.box3x3, nb.cross);
      if (followDepth) {
        std::memcpy(&nb.tap, s.tap + x, sizeof(int));
        nb.tapDepth = s.tapDepth[x];
      } else {
        nb.tap = 4;
        nb.tapDepth = f.depth.ptr ? d1[i] : kBackgroundDepth;
      }
      resolvePixel(f, x, y, nb, [&] {
        if (!extremesReady) gatherExtremes();
        // Columns x - 2 .. x + 2, clamped as the reference's taps are (padding
        // column 0 / w + 1 = the edge pixel, so index -1 reads it again).
        auto column = [&](int k) {
          temporal::TwoExtremes4 e;
          std::memcpy(&e, s.columnExtremes + 16 * std::clamp(k, 0, w + 1), sizeof e);
          return e;
        };
        temporal::TwoExtremes4 e = column(i - 2);
        for (int k = i - 1; k <= i + 2; ++k) temporal::mergeExtremes(e, column(k));
        return temporal::footprintBox(nb.box3x3, e);
      });
    }
  }
}

// The row loop's two copies (temporal/isa.h): the baseline and AVX2.
void fastRowsBaseline(const Frame& f, const BandScratch& s, int y0, int y1, float* depthNow) {
  fastRowsBody(f, s, y0, y1, depthNow);
}
#ifdef CRISP_TEMPORAL_HAS_AVX2
CRISP_TEMPORAL_AVX2 void fastRowsAvx2(const Frame& f, const BandScratch& s, int y0, int y1, float* depthNow) {
  fastRowsBody(f, s, y0, y1, depthNow);
}
#endif

inline float alphaOf(const ImageView& color, int x, int y) {
  return color.channels() > 3 ? sanitizeColor(color.pixel(x, y)[3]) : 1.0f;
}

// Step 7: sharpen the blended image (eq. 3.1; eq. 4.17 is the same stencil at
// a quarter of the amount) into the output, clamped to the range of the 5 taps.
template <bool Clamp>
inline void sharpenPixel(const Frame& f, float amount, int x, int y) {
  const int w = f.width, h = f.height;
  auto at = [&](int dx, int dy) {
    const int tx = Clamp ? std::clamp(x + dx, 0, w - 1) : x + dx;
    const int ty = Clamp ? std::clamp(y + dy, 0, h - 1) : y + dy;
    return f.history + (std::size_t(ty) * w + tx) * 4;
  };
  const float* c = at(0, 0);
  const float* n[4] = {at(0, -1), at(-1, 0), at(1, 0), at(0, 1)};
  Float3 result;
  for (int ch = 0; ch < 3; ++ch) {
    float lo = c[ch], hi = c[ch];
    float sum = 0.0f;
    for (int i = 0; i < 4; ++i) {
      sum += n[i][ch];
      lo = std::min(lo, n[i][ch]);
      hi = std::max(hi, n[i][ch]);
    }
    const float sharpened = c[ch] + amount * (4.0f * c[ch] - sum);
    result[ch] = std::clamp(sharpened, lo, hi);
  }
  storeOutput(f.output, x, y, toRgb4(Vec4{result[0], result[1], result[2], 0.0f}, f.space, alphaOf(f.color, x, y)));
}

// Row bands of the fast path: enough to keep the threads busy, few enough
// that the halo rows (staged twice) stay a small fraction.
int bandCount(int height) { return std::clamp(height / 32, 1, 16); }

}  // namespace

std::size_t Kernel::scratchFloatsPerBand() const { return bandFloats(width_); }

void Kernel::allocate(int width, int height, bool withDepth) {
  const bool sameShape = width == width_ && height == height_ && !history_[0].empty();
  if (sameShape && withDepth == !depth_[0].empty()) return;  // keep the history
  width_ = width;
  height_ = height;
  if (!sameShape) {
    bands_ = bandCount(height);
    bandScratch_.assign(std::size_t(bands_) * bandFloats(width), 0.0f);
    history_[0] = Image(width, height, 4);
    history_[1] = Image(width, height, 4);
    feedbackSinceReset_.assign(std::size_t(width) * height, 0);
  }
  for (auto& d : depth_) {
    if (withDepth)
      d.assign(std::size_t(width) * height, kBackgroundDepth);
    else
      std::vector<float>().swap(d);
  }
  reset();
}

void Kernel::reset() {
  frames_ = 0;
  previousDepthValid_ = false;
}

std::size_t Kernel::bytesKeptBetweenFrames() const {
  return (history_[0].data.size() + history_[1].data.size() + depth_[0].size() + depth_[1].size()) * sizeof(float) +
         feedbackSinceReset_.size();
}

std::size_t Kernel::bytesScratch() const { return bandScratch_.size() * sizeof(float); }

void Kernel::run(const Inputs& in, const Settings& s, bool reference, int numThreads) {
  if (in.color.width != width_ || in.color.height != height_)
    invalidData("taa: colour is " + std::to_string(in.color.width) + "x" + std::to_string(in.color.height) +
                " but the filter was committed for " + std::to_string(width_) + "x" + std::to_string(height_));
  const bool hasDepth = in.depth.ptr != nullptr;
  if (hasDepth && depth_[0].empty())
    invalidData("taa: image 'depth' given but the kernel was allocated without depth planes");
  if (frames_ > 0 && s.clipSpace != historySpace_) reset();  // history is stored in the clip space
  historySpace_ = s.clipSpace;
  const int next = 1 - current_;
  float* depthNow = hasDepth ? depth_[next].data() : nullptr;

  Frame f;
  f.width = width_;
  f.height = height_;
  // Without a motion image nothing moves, so nothing can be disoccluded: the
  // depth test would only reset silhouette pixels whose jittered depth flips
  // between object and background from frame to frame.
  f.previousDepth =
      hasDepth && in.motion.ptr && previousDepthValid_ && frames_ > 0 ? depth_[current_].data() : nullptr;
  f.color = in.color;
  f.motion = in.motion;
  f.depth = in.depth;
  f.previous = {history_[current_].data.data(), width_, height_};
  f.hasHistory = frames_ > 0;
  f.history = history_[next].data.data();
  f.output = in.output;
  f.writeOutput = !(s.sharpen > 0.0f);
  f.space = s.clipSpace;
  f.filter = s.historyFilter;
  f.sampleWeight = s.weighting == JitterWeighting::BlackmanHarris
                       ? temporal::blackmanHarrisWeight(s.jitterX, s.jitterY, s.filterSize)
                       : 1.0f;
  f.feedbackMin = s.feedbackMin;
  f.feedbackMax = s.feedbackMax;
  f.staticAccumulation = s.staticAccumulation;
  f.staticClip = s.staticClip;
  f.feedbackSinceReset = feedbackSinceReset_.data();
  f.maxSamples = float(std::max(1, s.maxSamples));
  f.depthTolerance = s.depthTolerance;
  f.aliased = in.aliasedValue;
  f.aliasedNeighbourhood = s.aliasedNeighbourhood;
  f.aliasedBoxSize = s.aliasedBoxSize;
  f.unjitter = temporal::unjitterFor(s.unjitter, s.jitterX, s.jitterY, s.filterSize);

  if (reference) {
    for (int y = 0; y < height_; ++y)
      for (int x = 0; x < width_; ++x) referencePixel(f, x, y, depthNow);
  } else {
    // Band b covers rows [b h / bands, (b + 1) h / bands) and owns scratch b;
    // parallelRows hands out bands (a virtual image one band per row).
    const int bands = bands_;
    auto fastRows = fastRowsBaseline;
#ifdef CRISP_TEMPORAL_HAS_AVX2
    if (temporal::useAvx2()) fastRows = fastRowsAvx2;
#endif
    parallelRows(8192, bands, numThreads, [&](int b0, int b1) {
      for (int b = b0; b < b1; ++b) {
        const BandScratch scratch = bandScratch(bandScratch_.data() + std::size_t(b) * bandFloats(width_), width_);
        fastRows(f, scratch, int(std::int64_t(b) * height_ / bands), int(std::int64_t(b + 1) * height_ / bands),
                 depthNow);
      }
    });
  }

  if (!f.writeOutput) {
    const float amount = s.sharpen;
    auto sharpenRows = [&](int y0, int y1) {
      temporal::rowsWithBorder(width_, height_, y0, y1, reference, [&](auto clamp, int x, int y) {
        sharpenPixel<decltype(clamp)::value>(f, amount, x, y);
      });
    };
    if (reference)
      sharpenRows(0, height_);
    else
      parallelRows(width_, height_, numThreads, sharpenRows);
  }

  current_ = next;
  previousDepthValid_ = hasDepth;
  ++frames_;
}

}  // namespace crisp::taa

// ---------------------------------------------------------------------------
// The filter.

namespace crisp {
namespace taa {

std::vector<ParamSpec> parameterSpecs() {
  std::vector<ParamSpec> specs = temporal::jitterParamSpecs(
      "weight of each frame's sample in the static accumulation: none = the jitter already follows the wanted "
      "pixel filter (EEVEE's Blackman-Harris draw -> EEVEE's reference; uniform -> box); blackman-harris = "
      "weight uniformly drawn jitter by a Blackman-Harris filter of width filterSize",
      "METHODS.md Jitter and references; BLENDER.md Sampling and jitter");
  specs.insert(specs.end(), {
      {"historyFilter", ParamType::String, 0, 0, 0, "catmull-rom|bilinear",
       "filtered fetch of the reprojected history; Catmull-Rom's negative lobes are clamped to the 2x2 range",
       "seed 000 §3.6.3; Karis 2014"},
      {"clipSpace", ParamType::String, 0, 0, 0, "ycocg|rgb",
       "colour space of the clip box (changing it resets the history)", "seed 000 §3.6.4"},
      {"feedbackMin", ParamType::Float, 0.7, 0.0, 1.0, nullptr,
       "history weight k when the lumas of clipped history and current colour differ most",
       "seed 000 §3.6.3 (seed: 0.88; lower for EEVEE's wide jitter, taa.cpp Deliberate choices)"},
      {"feedbackMax", ParamType::Float, 0.85, 0.0, 1.0, nullptr,
       "history weight k when the lumas agree: k = lerp(min, max, (1 - |l0-l1|/max(l0,l1,0.2))^2)",
       "seed 000 §3.6.3 (seed: 0.97)"},
      {"sharpen", ParamType::Float, 0.0, 0.0, 1.0, nullptr,
       "amount of the [0,-1,0;-1,5,-1;0,-1,0] sharpen on the output (history stays unsharpened); clamped to "
       "the 5-tap range",
       "seed 000 eq. 3.1"},
      {"staticAccumulation", ParamType::Bool, 1, 0, 1, nullptr,
       "where the velocity is zero (and was), average all samples (weight w/W) instead of the feedback blend, "
       "so a still scene converges to the filtered reference",
       "METHODS.md Jitter and references; seed 004 TAA for ray tracing"},
      {"maxSamples", ParamType::Int, 128, 1, 65536, nullptr,
       "cap of the accumulated sample weight W (the running average becomes an exponential one of 1/maxSamples)",
       "this file"},
      {"staticClip", ParamType::Bool, 1, 0, 1, nullptr,
       "test static history against its footprint box (3x3 united with the 5x5 values seen twice; 3x3 once the "
       "history went through a feedback blend) and fall back to the clipped feedback blend when outside (rejects "
       "cuts, fireflies, light changes; loses sub-pixel features the box misses); false = pure accumulation (call "
       "reset on a cut)",
       "this file"},
      {"depthTolerance", ParamType::Float, 0.05, 0.0, 10.0, nullptr,
       "relative depth difference between the followed surface and the previous depth still counted as the same "
       "surface (larger: disocclusion reset)",
       "this file"},
      {"reference", ParamType::Bool, 0, 0, 1, nullptr,
       "run the scalar reference path (one thread, clamped taps everywhere); bit-identical to the fast path",
       "this file"},
  });
  return specs;
}

void readSettings(const ParamSet& p, const char* filterName, Settings& settings) {
  settings.jitterX = p.getFloat("jitterX");
  settings.jitterY = p.getFloat("jitterY");
  settings.weighting =
      p.getString("jitterWeighting") == "blackman-harris" ? JitterWeighting::BlackmanHarris : JitterWeighting::None;
  settings.filterSize = p.getFloat("filterSize");
  settings.historyFilter =
      p.getString("historyFilter") == "bilinear" ? HistoryFilter::Bilinear : HistoryFilter::CatmullRom;
  settings.clipSpace = p.getString("clipSpace") == "rgb" ? ClipSpace::Rgb : ClipSpace::YCoCg;
  settings.feedbackMin = p.getFloat("feedbackMin");
  settings.feedbackMax = p.getFloat("feedbackMax");
  if (settings.feedbackMin > settings.feedbackMax)
    invalidArgument(std::string("filter '") + filterName + "': parameter 'feedbackMin' (" +
                    std::to_string(settings.feedbackMin) + ") must not exceed 'feedbackMax' (" +
                    std::to_string(settings.feedbackMax) + ")");
  settings.sharpen = p.getFloat("sharpen");
  settings.staticAccumulation = p.getBool("staticAccumulation");
  settings.maxSamples = p.getInt("maxSamples");
  settings.staticClip = p.getBool("staticClip");
  settings.depthTolerance = p.getFloat("depthTolerance");
  settings.unjitter = temporal::parseUnjitterMode(p.getString("unjitter"));
}

}  // namespace taa

namespace {

class TaaFilter final : public Filter {
 public:
  explicit TaaFilter(Context& c)
      : Filter(c, taa::parameterSpecs(),
               {{"color", true, 3, 4, false, "linear RGB(A) colour, 1 jittered sample per pixel"},
                {"motion", false, 2, 4, false,
                 "motion vectors in pixels, previous - current, y down (absent: static scene, no reprojection)"},
                {"depth", false, 1, 4, false, "planar depth (channel 0): closest-depth velocity, disocclusion"},
                {"output", true, 3, 4, false, "anti-aliased linear colour; alpha passes through"}}) {}
  const char* type() const override { return "taa"; }
  void reset() override { kernel_.reset(); }

 protected:
  void onCommit() override {
    const ParamSet& p = params();
    taa::readSettings(p, "taa", settings_);
    reference_ = p.getBool("reference");
    // Re-committing for a new jitter keeps the history; a new size starts over.
    kernel_.allocate(width(), height(), hasImage("depth"));
  }
  void onExecute() override {
    taa::Inputs in;
    in.color = image("color");
    if (hasImage("motion")) in.motion = image("motion");
    if (hasImage("depth")) in.depth = image("depth");
    in.output = image("output");
    kernel_.run(in, settings_, reference_, numThreads());
  }

 private:
  taa::Settings settings_;
  bool reference_ = false;
  taa::Kernel kernel_;
};

}  // namespace

std::unique_ptr<Filter> newTaaFilter(Context& c) { return std::make_unique<TaaFilter>(c); }

}  // namespace crisp
