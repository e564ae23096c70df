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
// Hold (parameter holdPeriod P, default 16). The add-on, the viewport and
// temporal/jitter.h cycle through P = 16 Halton points, and EEVEE repeats its
// 1-sample noise, so a still pixel's input is periodic: the average of any P
// consecutive frames is the average of all of them, and averaging more only
// moves the output back and forth around it (by (x - mean)/n per frame). A
// still pixel whose history has averaged exactly its frames since its last
// reset (no feedback blend since: Kernel::historyState_ bit 0) and holds P or
// more of them keeps it as is: its output stops changing, bit for bit, and
// equals the converged average. History that went through a feedback blend
// keeps averaging (its old tail would otherwise stay forever), and the held
// history is tested and clipped like any other, so a change in the scene
// that leaves the pixel's box still replaces it. A change that leaves the
// held value inside the box (the rim of a region that changed colour: the
// footprint box still holds the old colour) is caught by the release
// (parameter holdRelease, temporal/hold_release.h): each pixel sums its input
// over windows of P frames, which a periodic input makes all equal; a still
// averaging pixel, held or not, whose window differs from the last matching
// one twice running restarts from this frame's colour, as at a reset, and is
// exact again P frames later (HoldRelease.HeldPixelsTakeInAPersistentChange:
// before it, a band two pixels wide along an edge that appeared in a still
// picture kept the old colour for good; docs/temporal_figures.md,
// "Weakness of the hold"). One different window does not release, so a
// one-frame firefly still never shows
// (HoldRelease.AOneFrameFireflyInAHeldPictureChangesNothing). The window
// sums take 4 bytes per pixel (Kernel::holdWindows_). Frames since
// reset live in bits 1-7 of the state byte.
// Measured (crisp eval, ghosting 240x136, frames 9-48 vs 256 samples): temporal
// error 0.00583 -> 0.00562, PSNR 29.03 dB either way; camera_dolly and
// spinning_cube unchanged (nothing still has edges there); chunked still_life
// with a 16-frame pre-roll 43.7 -> 58.0 dB against the sequential run
// (docs/farm.md). A jitter sequence of another period needs its own P; 0
// averages on up to maxSamples.
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
//  * clip box in RGB by default, not the seed's YCoCg (§3.6.4; parameter
//    clipSpace). Measured (crisp eval as above; PSNR dB / temporal error),
//    YCoCg -> RGB: camera_dolly 24.97/0.0177 -> 25.47/0.0162 (taa-improved
//    24.88/0.0179 -> 25.44/0.0163), ghosting 29.00/0.0056 -> 29.03/0.0056,
//    spinning_cube 32.67/0.0029 -> 32.66/0.0029; still_life 480x270 frame 16
//    39.62 -> 39.51 dB. The running average is the same in either space (a
//    linear map); only the boxes differ;
//  * variance clipping (Salvi 2016; parameter varianceClip, gamma = 1): the
//    feedback path's box is narrowed to mean +- gamma sigma per channel of
//    this frame's 3x3 (the mean and standard deviation of the taps, summed
//    in tap order: momentsOf), each end clamped into the box so it is never
//    empty. Min/max boxes of a jittered 3x3 let a trail or the blur of a
//    resampled history stay wherever one outlying tap allows it. Measured
//    (crisp eval as above; PSNR dB / temporal error), gamma 0 -> 1:
//    camera_dolly 25.47/0.0162 -> 25.58/0.0162, ghosting 29.03/0.0056 ->
//    29.36/0.0054, spinning_cube 32.66/0.0029 -> 32.90/0.0028;
//    taa-improved 25.44/0.0163 -> 25.57/0.0164, 29.61/0.0052 -> 29.75/0.0051,
//    32.72/0.0029 -> 33.13/0.0028. Gamma 0.75 gains more PSNR (cube 33.40,
//    ghosting 29.52) with more flicker on camera_dolly (0.0165); 0.5 and
//    below flicker clearly more (dolly 0.0192 at 0.5). Applied before
//    taa-improved's shrink toward the current colour (eq. 4.16);
//  * resampling damping (parameter resampleDamping, beta = 0.3): a moving
//    history is fetched with a filter every frame, and each fetch at a
//    sub-pixel offset blurs it (most at half a pixel; none at whole pixels);
//    kept for 1/(1-k) frames, the blur builds up on textured surfaces. The
//    feedback weight becomes k (1 - beta s), s = max(4 tx (1 - tx), 4 ty (1 -
//    ty)) for the fractions of p + v. Measured (crisp eval as above; PSNR dB /
//    temporal error), beta 0 -> 0.3 (0.15, 0.6): spinning_cube 32.90/0.0028
//    -> 35.23/0.0027 (34.25/0.0027, 35.83/0.0030), ghosting 29.36/0.0054 ->
//    29.39/0.0054, camera_dolly 25.58/0.0162 -> 25.76/0.0173 (25.71/0.0167,
//    25.56/0.0195): the rotating textured cube gains 2.3 dB at less flicker;
//    the dolly, where every pixel moves by fractions, flickers 7 % more. A
//    lower k everywhere (0.5/0.7) gives the cube the same (35.29) with more
//    flicker on the dolly (0.0176);
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
// | clipSpace | string | rgb | rgb, ycocg | space of the clip box | §3.6.4 (seed: YCoCg) |
// | feedbackMin | float | 0.7 | [0, 1] | history weight at a large luma difference | §3.6.3 (seed: 0.88) |
// | feedbackMax | float | 0.85 | [0, 1] | history weight at equal luma | §3.6.3 (seed: 0.97) |
// | sharpen | float | 0 | [0, 1] | amount of the eq. 3.1 sharpen on the output | eq. 3.1 |
// | staticAccumulation | bool | true | - | running average where nothing moves | METHODS.md Jitter |
// | maxSamples | int | 128 | [1, 65536] | cap of the running average's sample count | this file |
// | resampleDamping | float | 0.3 | [0, 1] | history weight k (1 - beta s) at sub-pixel motion fraction s | this file |
// | varianceClip | float | 1 | [0, 10] | gamma: the feedback box narrowed to mean +- gamma sigma of the 3x3 | Salvi 2016 |
// | holdPeriod | int | 16 | [0, 127] | the jitter's period: pure still history stops averaging after it | this file (Hold) |
// | holdRelease | float | 0.002 | [0, 1] | a still pixel whose input's period mean changes by more, twice running, restarts; 1 = never | this file (Hold) |
// | staticClip | bool | true | - | clip static history too | this file |
// | depthTolerance | float | 0.05 | [0, 10] | relative depth change still the same surface | this file |
// | unjitter | string | blackman-harris | blackman-harris, nearest, none | the current colour: the unjittered 3x3 mix | Karis 2014 |
// | reference | bool | false | - | scalar reference path | this file |
#include "filters/taa.h"

#include <algorithm>
#include <atomic>
#include <cmath>
#include <cstdint>
#include <cstring>

#include "core/color.h"
#include "core/error.h"
#include "core/filter.h"
#include "core/parallel.h"
#include "core/row_stage.h"
#include "filters/taa_rows.h"
#include "filters/temporal_filter.h"
#include "temporal/color_space.h"
#include "temporal/history_fetch.h"
#include "temporal/hold_release.h"
#include "temporal/isa.h"
#include "temporal/jitter.h"
#include "temporal/lanes.h"
#include "temporal/neighbourhood.h"
#include "temporal/rows.h"
#include "temporal/vec4.h"
#include "temporal/velocity.h"

namespace crisp::taa {

using rows::BandScratch;
using rows::Frame;

namespace {

using namespace rows;

// The scalar reference: every tap clamped to the image and staged on the
// spot, boxes by the column-first definition, depth sanitised per tap.
void referencePixel(const Frame& f, int x, int y, float* depthNow) {
  const int w = f.width, h = f.height;
  const int cc = f.color.channels();
  Vec4 taps[9];
  float depth9[9];
  // Without unjitter the shift is 0 and shiftedSource a plain clamp.
  for (int i = 0; i < 9; ++i) {
    const int tx = temporal::shiftedSource(x + kTapDx[i], w, f.unjitter.shiftX),
              ty = temporal::shiftedSource(y + kTapDy[i], h, f.unjitter.shiftY);
    taps[i] = stagePixel(f.color.pixel(tx, ty), cc, f.space);
    depth9[i] = f.depth.ptr ? temporal::sanitizeDepth(f.depth.pixel(tx, ty)[0]) : kBackgroundDepth;
  }
  const Vec4 current = f.unjitter.enabled ? temporal::unjitteredMix(taps, f.unjitter.weights) : taps[4];
  temporal::MinMax4 box3x3, cross;
  temporal::columnFirstBoxes4(taps, box3x3, cross);
  const int tap = (f.depth.ptr && f.motion.ptr) ? temporal::closestDepthTap(depth9) : 4;
  if (depthNow) depthNow[std::size_t(y) * w + x] = depth9[4];
  // Step 3: velocity of the followed tap (clamped to the image, as the taps are).
  float vx = 0.0f, vy = 0.0f;
  if (f.motion.ptr) {
    const float* m = f.motion.pixel(temporal::shiftedSource(x + kTapDx[tap], w, f.unjitter.shiftX),
                                    temporal::shiftedSource(y + kTapDy[tap], h, f.unjitter.shiftY));
    vx = m[0];
    vy = m[1];
  }
  const ReprojectionLanes<float> rp = reprojectLanes<float>(f, float(x), float(y), vx, vy, depth9[tap]);
  const Vec4 hist =
      rp.valid ? fetchHistory(f, x, y, rp.moving, {rp.x0, rp.y0, rp.tx, rp.ty}, rp.qx, rp.qy) : temporal::splat(0.0f);

  const std::size_t index = std::size_t(y) * w + x;
  PixelLanes<float> in;
  for (int c = 0; c < 3; ++c) in.current[c] = current[c];
  for (int c = 0; c < 4; ++c) in.hist[c] = hist[c];
  for (int c = 0; c < 3; ++c) {
    in.boxMin[c] = box3x3.min[c];
    in.boxMax[c] = box3x3.max[c];
    in.crossMin[c] = cross.min[c];
    in.crossMax[c] = cross.max[c];
  }
  for (int c = 0; c < 3; ++c) {
    float t[9];
    for (int k = 0; k < 9; ++k) t[k] = taps[k][c];
    momentsOf(t, in.mean[c], in.sigma[c]);
  }
  in.tx = rp.tx;
  in.ty = rp.ty;
  in.valid = rp.valid;
  in.moving = rp.moving;
  in.feedbackSinceReset = (f.historyState[index] & 1) != 0;
  in.framesSinceReset = float(f.historyState[index] >> 1);
  in.aliased = f.aliased ? f.aliased[index] : 0.0f;
  if (f.release.words) in.holdWord = int(f.release.words[index]);
  const ResolvedLanes<float> r = resolveLanes(f, in, [&](int, float* excess) {
    if (!temporal::stillFootprint(f.motion, x, y, w, h, f.unjitter.shiftX, f.unjitter.shiftY)) return false;
    auto tap5 = [&](int i) {
      const int tx = temporal::shiftedSource(x + i % 5 - 2, w, f.unjitter.shiftX),
                ty = temporal::shiftedSource(y + i / 5 - 2, h, f.unjitter.shiftY);
      return stagePixel(f.color.pixel(tx, ty), cc, f.space);
    };
    temporal::TwoExtremes4 e = temporal::twoExtremesOf(tap5(0), tap5(1));
    for (int i = 2; i < 25; ++i) temporal::addTap(e, tap5(i));
    const temporal::MinMax4 box = temporal::footprintBox(box3x3, e);
    temporal::clipTowardCentre4(hist, box.min, box.max, excess);
    return true;
  });
  f.historyState[index] = historyStateOf(r.feedbackSinceReset, r.framesSinceReset);
  if (f.release.words) f.release.words[index] = std::uint32_t(r.holdWord);
  if (r.guarded) f.guards->fetch_add(1, std::memory_order_relaxed);
  if (r.released) f.releases->fetch_add(1, std::memory_order_relaxed);
  else if (r.reset) f.resets->fetch_add(1, std::memory_order_relaxed);
  storePixel(f, x, y, r.color, r.signedWeight, r.output, r.reset);
}

BandScratch bandScratch(float* base, int width) {
  const int n = planeFloats(width);
  BandScratch s;
  float* next = base;
  for (int r = 0; r < kRing; ++r)
    for (int c = 0; c < kPlanes; ++c, next += n) s.planes[r][c] = next;
  for (int r = 0; r < kRing; ++r, next += n) s.depth[r] = next;
  s.tap = next;
  s.tapDepth = next + n;
  s.row = next + 2 * n;
  return s;
}

// The row loop's copies (temporal/isa.h): the baseline and AVX2 here, AVX-512
// in taa_rows_avx512.cpp.
void fastRowsBaseline(const Frame& f, const BandScratch& s, int y0, int y1, float* depthNow) {
  fastRowsBody<Vec4>(f, s, y0, y1, depthNow);
}
#ifdef CRISP_TEMPORAL_HAS_AVX2
CRISP_TEMPORAL_AVX2 void fastRowsAvx2(const Frame& f, const BandScratch& s, int y0, int y1, float* depthNow) {
  fastRowsBody<temporal::Vec8>(f, s, y0, y1, depthNow);
}
#endif

// Step 7: sharpen the blended image (eq. 3.1; eq. 4.17 is the same stencil at
// a quarter of the amount) into the output, clamped to the range of the 5 taps.
template <bool Clamp>
inline void sharpenPixel(const Frame& f, float amount, int x, int y) {
  const int w = f.width, h = f.height;
  auto at = [&](int dx, int dy) {
    const int tx = Clamp ? std::clamp(x + dx, 0, w - 1) : x + dx;
    const int ty = Clamp ? std::clamp(y + dy, 0, h - 1) : y + dy;
    return std::size_t(ty) * w + tx;
  };
  const std::size_t c = at(0, 0);
  const std::size_t n[4] = {at(0, -1), at(-1, 0), at(1, 0), at(0, 1)};
  Float3 result;
  for (int ch = 0; ch < 3; ++ch) {
    const float* plane = f.history[ch];
    float lo = plane[c], hi = plane[c];
    float sum = 0.0f;
    for (int i = 0; i < 4; ++i) {
      sum += plane[n[i]];
      lo = std::min(lo, plane[n[i]]);
      hi = std::max(hi, plane[n[i]]);
    }
    const float sharpened = plane[c] + amount * (4.0f * plane[c] - sum);
    result[ch] = std::clamp(sharpened, lo, hi);
  }
  const float alpha = alphaOf(f.color, x, y);
  if (alpha != 1.0f) noteAlphaBelowOne(f);
  storeOutput(f.output, x, y, toRgb4(Vec4{result[0], result[1], result[2], 0.0f}, f.space, alpha));
}

// A history at least this large (4 planes; 1024x1024 and up) is written with
// streaming stores where the rows run on 16 lanes (Frame::streamHistory):
// nothing reads it before the next frame, and it would not stay in the caches.
constexpr std::size_t kStreamHistoryBytes = std::size_t(16) << 20;

// Row bands of the fast path: enough to keep the threads busy, few enough
// that the halo rows (staged twice) stay a small fraction.
int bandCount(int height) { return std::clamp(height / 32, 1, 16); }

}  // namespace

std::size_t Kernel::scratchFloatsPerBand() const { return bandFloats(width_); }

void Kernel::allocate(int width, int height, bool withDepth) {
  const bool sameShape = width == width_ && height == height_ && !history_[0].empty();
  if (!sameShape) {  // a new size starts over
    // No size until every buffer has it: after an allocation that throws, the next call allocates
    // again instead of taking the old size's buffers for the new size.
    width_ = height_ = 0;
    bands_ = bandCount(height);
    bandScratch_.assign(std::size_t(bands_) * bandFloats(width), 0.0f);
    history_[0].assign(std::size_t(width) * height * 4, 0.0f);
    history_[1].assign(std::size_t(width) * height * 4, 0.0f);
    historyState_.assign(std::size_t(width) * height, 0);
    holdWindows_.allocate(std::size_t(width) * height);
    sourceColumn_.assign(std::size_t(planeFloats(width)), 0);
    width_ = width;
    height_ = height;
    reset();
  }
  // A depth image that appears or goes keeps the colour history (as phlm
  // keeps its models): the next frame has no previous depth to test against.
  if (!sameShape || withDepth == depth_[0].empty()) {
    try {
      for (auto& d : depth_) {
        if (withDepth)
          d.assign(std::size_t(width) * height, kBackgroundDepth);
        else
          std::vector<float>().swap(d);
      }
    } catch (...) {
      for (auto& d : depth_) std::vector<float>().swap(d);  // both planes or none, so a retry allocates both
      throw;
    }
    previousDepthValid_ = false;
  }
}

void Kernel::reset() {
  frames_ = 0;
  previousDepthValid_ = false;
}

std::size_t Kernel::bytesKeptBetweenFrames() const {
  return (history_[0].size() + history_[1].size() + depth_[0].size() + depth_[1].size()) * sizeof(float) +
         historyState_.size() + holdWindows_.bytes();
}

std::size_t Kernel::bytesScratch() const { return bandScratch_.size() * sizeof(float); }

float Kernel::largestSampleWeight() const {
  if (frames_ == 0) return 0.0f;
  const std::size_t planeSize = std::size_t(width_) * height_;
  const float* weight = history_[current_].data() + 3 * planeSize;
  float largest = 0.0f;
  for (std::size_t i = 0; i < planeSize; ++i) largest = std::max(largest, std::fabs(weight[i]));
  return largest;
}

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
  // Each history image holds four planes (Kernel::history_).
  const std::size_t planeSize = std::size_t(width_) * height_;
  for (int c = 0; c < 4; ++c) {
    f.previous.plane[c] = history_[current_].data() + c * planeSize;
    f.history[c] = history_[next].data() + c * planeSize;
  }
  f.previous.width = width_;
  f.previous.height = height_;
  f.streamHistory = 4 * planeSize * sizeof(float) >= kStreamHistoryBytes;
  f.hasHistory = frames_ > 0;
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
  f.historyState = historyState_.data();
  f.maxSamples = float(std::max(1, s.maxSamples));
  f.holdPeriod = float(s.holdPeriod);
  f.release = temporal::holdWindowFrame(holdWindows_, frames_, s.holdPeriod, s.holdRelease);
  f.varianceClip = s.varianceClip;
  f.resampleDamping = s.resampleDamping;
  f.depthTolerance = s.depthTolerance;
  f.aliased = in.aliasedValue;
  f.aliasedNeighbourhood = s.aliasedNeighbourhood;
  f.aliasedBoxSize = s.aliasedBoxSize;
  f.unjitter = temporal::unjitterFor(s.unjitter, s.jitterX, s.jitterY, s.filterSize);
  for (std::size_t k = 0; k < sourceColumn_.size(); ++k)
    sourceColumn_[k] = temporal::shiftedSource(int(k) - 1, width_, f.unjitter.shiftX);
  f.sourceColumn = sourceColumn_.data();
  guards_ = 0;
  f.guards = &guards_;
  resets_ = 0;
  f.resets = &resets_;
  releases_ = 0;
  f.releases = &releases_;
  alphaBelowOne_ = false;
  f.alphaBelowOne = &alphaBelowOne_;

  if (reference) {
    for (int y = 0; y < height_; ++y)
      for (int x = 0; x < width_; ++x) referencePixel(f, x, y, depthNow);
  } else {
    auto fastRows = fastRowsBaseline;
#ifdef CRISP_TEMPORAL_HAS_AVX2
    if (temporal::useAvx2()) fastRows = fastRowsAvx2;
#endif
#ifdef CRISP_HAS_AVX512_ROWS
    if (temporal::useAvx512()) fastRows = rows::fastRowsAvx512;
#endif
    parallelBands(height_, bands_, numThreads, [&](int b, int y0, int y1) {  // band b owns scratch b
      fastRows(f, bandScratch(bandScratch_.data() + std::size_t(b) * bandFloats(width_), width_), y0, y1, depthNow);
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
      {"clipSpace", ParamType::String, 0, 0, 0, "rgb|ycocg",
       "colour space of the clip box (changing it resets the history)",
       "seed 000 §3.6.4 (seed: YCoCg; RGB measured better here, taa.cpp Deliberate choices)"},
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
      {"varianceClip", ParamType::Float, 1.0, 0.0, 10.0, nullptr,
       "gamma of variance clipping: the feedback path's box (moving or rejected history) is narrowed to mean +- "
       "gamma sigma of this frame's 3x3, clamped into the box; 0 = the box alone",
       "Salvi 2016 (variance clipping); this file"},
      {"resampleDamping", ParamType::Float, 0.3, 0.0, 1.0, nullptr,
       "beta: the feedback path's history weight k becomes k (1 - beta s), s = max over x and y of 4 t (1 - t) "
       "for the sub-pixel fraction t of the reprojected position (0 at whole-pixel motion, 1 at half a pixel, "
       "where each filtered fetch blurs the history most); 0 = off",
       "this file (Deliberate choices)"},
      {"holdPeriod", ParamType::Int, 16, 0, 127, nullptr,
       "the jitter sequence's period in frames (16: the Halton sequence of the add-on, the viewport and "
       "temporal/jitter.h); a still pixel whose running average holds exactly that many frames since its reset, "
       "and no feedback blend, keeps it instead of averaging more: the average of a whole period of a still, "
       "periodic input is final, so the output stops changing; 0 = keep averaging (up to maxSamples)",
       "this file (Hold)"},
      {"holdRelease", ParamType::Float, 0.002, 0.0, 1.0, nullptr,
       "a still averaging pixel (held or not) whose input, summed over a period of holdPeriod frames as "
       "tonemapped luminance, differs from the last period that matched by more than this per frame, two periods "
       "running, restarts from the current colour (a change the held value would hide: a light switched on, an "
       "object appearing in a still shot); 0 = on any change, 1 = never; no effect with holdPeriod 0",
       "this file (Hold); temporal/hold_release.h"},
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
  settings.clipSpace = p.getString("clipSpace") == "ycocg" ? ClipSpace::YCoCg : ClipSpace::Rgb;
  settings.feedbackMin = p.getFloat("feedbackMin");
  settings.feedbackMax = p.getFloat("feedbackMax");
  if (settings.feedbackMin > settings.feedbackMax)
    invalidArgument(std::string("filter '") + filterName + "': parameter 'feedbackMin' (" +
                    std::to_string(settings.feedbackMin) + ") must not exceed 'feedbackMax' (" +
                    std::to_string(settings.feedbackMax) + ")");
  settings.sharpen = p.getFloat("sharpen");
  settings.staticAccumulation = p.getBool("staticAccumulation");
  settings.maxSamples = p.getInt("maxSamples");
  settings.holdPeriod = p.getInt("holdPeriod");
  settings.holdRelease = p.getFloat("holdRelease");
  settings.varianceClip = p.getFloat("varianceClip");
  settings.resampleDamping = p.getFloat("resampleDamping");
  settings.staticClip = p.getBool("staticClip");
  settings.depthTolerance = p.getFloat("depthTolerance");
  settings.unjitter = temporal::parseUnjitterMode(p.getString("unjitter"));
}

}  // namespace taa

namespace {

class TaaFilter final : public TemporalFilter<taa::Kernel> {
 public:
  explicit TaaFilter(Context& c) : TemporalFilter(c, taa::parameterSpecs(), temporalImageRoles(kTemporalDepthMeaning)) {}
  const char* type() const override { return "taa"; }

 protected:
  void onCommit() override {
    const ParamSet& p = params();
    taa::readSettings(p, "taa", settings_);
    reference_ = p.getBool("reference");
    // Re-committing for a new jitter keeps the history; a new size starts over.
    kernel_.allocate(width(), height(), hasImage("depth"));
    allocateAlpha();
  }
  void onExecute() override {
    taa::Inputs in;
    readCommonInputs(in);
    kernel_.run(in, settings_, reference_, numThreads());
    alpha_.run(in.color, kernel_.alphaBelowOneLastFrame(), in.motion, in.depth, nullptr, in.output, settings_, reference_, numThreads());
  }

 private:
  taa::Settings settings_;
};

}  // namespace

std::unique_ptr<Filter> newTaaFilter(Context& c) { return std::make_unique<TaaFilter>(c); }

}  // namespace crisp
