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
#include "temporal/color_space.h"
#include "temporal/history_fetch.h"
#include "temporal/hold_release.h"
#include "temporal/isa.h"
#include "temporal/rows.h"
#include "temporal/jitter.h"
#include "temporal/lanes.h"
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
  temporal::HistoryPlanes previous;  // valid only if hasHistory
  bool hasHistory;
  float* history[4];           // written: planes R G B (or Y Co Cg) and the signed weight
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
};

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
    bool loaded = false;
    if constexpr (!std::is_same_v<T, float>) {
      if (temporal::sharedInteriorOffset<T>(r.x0, r.y0, valid, 0, 1, 0, 1, w, h)) {
        // Smooth motion: the lanes' taps are consecutive, the same values as the gathers.
        const float* upper = f.previousDepth + std::size_t(r.y0[0]) * w + r.x0[0];
        d00 = temporal::loadLanes<T>(upper);
        d10 = temporal::loadLanes<T>(upper + 1);
        d01 = temporal::loadLanes<T>(upper + w);
        d11 = temporal::loadLanes<T>(upper + w + 1);
        loaded = true;
      }
    }
    if (!loaded) {  // clamped to the image
      auto clampIndex = [](temporal::IntOf<T> v, int hi) { return v < 0 ? 0 : (hi < v ? hi : v); };
      const auto xa = clampIndex(r.x0, w - 1), xb = clampIndex(r.x0 + 1, w - 1);
      const auto ya = clampIndex(r.y0, h - 1), yb = clampIndex(r.y0 + 1, h - 1);
      d00 = temporal::gatherOf(f.previousDepth, w, xa, ya);
      d10 = temporal::gatherOf(f.previousDepth, w, xb, ya);
      d01 = temporal::gatherOf(f.previousDepth, w, xa, yb);
      d11 = temporal::gatherOf(f.previousDepth, w, xb, yb);
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
inline T lumaOf(const T c[3], ClipSpace space) {
  return space == ClipSpace::YCoCg ? c[0] : 0.2126f * c[0] + 0.7152f * c[1] + 0.0722f * c[2];
}

// clipTowardCentre4 (neighbourhood.h) on lanes 0-2: the clipped colour into
// `out` (when given) and the excess returned.
template <class T>
inline T clipTowardCentreOf(const T p[3], const T lo[3], const T hi[3], T* out) {
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

// Fast path scratch of one row band: a ring of five staged rows, one plane
// per channel (Y Co Cg, or R G B, then motion x and y; no alpha, which the
// output takes from the input, alphaOf), each padded by one
// pixel left (a copy of the edge pixel = clamp-to-edge) and by at least one
// right, up to a multiple of 8 past the last group's loads; five depth rows
// likewise; the current row's closest-depth taps.
constexpr int kRing = 5;
constexpr int kPlanes = 5;  // colour 3, motion 2
constexpr int kMotionX = 3, kMotionY = 4;  // plane indices
inline int planeFloats(int width) { return (width + 10 + 7) / 8 * 8; }
struct BandScratch {
  float* planes[kRing][kPlanes];
  float* depth[kRing];
  float* row;       // width x 4: one input row staged before the shift
  float* tap;       // planeFloats: closest-depth taps (int bits, read and written by memcpy)
  float* tapDepth;  // planeFloats: their depths
};

inline std::size_t bandFloats(int width) {
  return std::size_t(planeFloats(width)) * (kRing * (kPlanes + 1) + 2) + std::size_t(width) * 4;
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
// halo rows above and below), then eight pixels at a time: their taps, boxes,
// unjittered mix and reprojection from the planes, their history fetched as
// lanes where the group moves as one (else one pixel at a time), the same
// resolveLanes as the reference on all eight, the history stored as lanes.
// T: the lane type (temporal/lanes.h), Vec8 in the AVX2 copy, Vec4 in the
// baseline (SSE2) one.
template <class T>
__attribute__((always_inline)) inline void fastRowsBody(const Frame& f, const BandScratch& s, int y0, int y1,
                                                      float* depthNow) {
  using temporal::maxOf;
  using temporal::minOf;
  using Int = temporal::IntOf<T>;
  constexpr int kL = temporal::kLanesOf<T>;
  const auto load = [](const float* p) { return temporal::loadLanes<T>(p); };
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
    if (y + 2 < h) stageRow<T>(f, s, y + 2, y + 2 < y1 ? depthNow : nullptr);
    const int up = std::max(y - 1, 0) % kRing, mid = y % kRing, down = std::min(y + 1, h - 1) % kRing;
    float* const* rows[3] = {s.planes[up], s.planes[mid], s.planes[down]};
    float* const* rows5[5] = {s.planes[std::max(y - 2, 0) % kRing], rows[0], rows[1], rows[2],
                              s.planes[std::min(y + 2, h - 1) % kRing]};
    if (followDepth) temporal::closestDepthTapsRow<T>(s.depth[up], s.depth[mid], s.depth[down], w, s.tap, s.tapDepth);
    const std::size_t rowStart = std::size_t(y) * w;
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
        for (int c = 0; c < 3; ++c) temporal::storeLanes(f.history[c] + rowStart + x0, r.color[c]);
        temporal::storeLanes(f.history[3] + rowStart + x0, r.signedWeight);
        if (packedOutput) {
          // storeOutputPixel on packed RGBA, where it reads the input for the
          // alpha only (the unjittered mix is the current colour even on a reset).
          temporal::storeInterleaved4(f.output.pixel(x0, y), r.output[0], r.output[1], r.output[2],
                                      inputAlphaLanes<T>(f.color, x0, y));
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
  }
}

// The row loop's two copies (temporal/isa.h): the baseline and AVX2.
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
  storeOutput(f.output, x, y, toRgb4(Vec4{result[0], result[1], result[2], 0.0f}, f.space, alphaOf(f.color, x, y)));
}

// Row bands of the fast path: enough to keep the threads busy, few enough
// that the halo rows (staged twice) stay a small fraction.
int bandCount(int height) { return std::clamp(height / 32, 1, 16); }

}  // namespace

std::size_t Kernel::scratchFloatsPerBand() const { return bandFloats(width_); }

void Kernel::allocate(int width, int height, bool withDepth) {
  const bool sameShape = width == width_ && height == height_ && !history_[0].empty();
  if (!sameShape) {  // a new size starts over
    width_ = width;
    height_ = height;
    bands_ = bandCount(height);
    bandScratch_.assign(std::size_t(bands_) * bandFloats(width), 0.0f);
    history_[0] = Image(width, height, 4);
    history_[1] = Image(width, height, 4);
    historyState_.assign(std::size_t(width) * height, 0);
    holdWindows_.allocate(std::size_t(width) * height);
    sourceColumn_.assign(std::size_t(planeFloats(width)), 0);
    reset();
  }
  // A depth image that appears or goes keeps the colour history (as phlm
  // keeps its models): the next frame has no previous depth to test against.
  if (!sameShape || withDepth == depth_[0].empty()) {
    for (auto& d : depth_) {
      if (withDepth)
        d.assign(std::size_t(width) * height, kBackgroundDepth);
      else
        std::vector<float>().swap(d);
    }
    previousDepthValid_ = false;
  }
}

void Kernel::reset() {
  frames_ = 0;
  previousDepthValid_ = false;
}

std::size_t Kernel::bytesKeptBetweenFrames() const {
  return (history_[0].data.size() + history_[1].data.size() + depth_[0].size() + depth_[1].size()) * sizeof(float) +
         historyState_.size() + holdWindows_.bytes();
}

std::size_t Kernel::bytesScratch() const { return bandScratch_.size() * sizeof(float); }

float Kernel::largestSampleWeight() const {
  if (frames_ == 0) return 0.0f;
  const std::size_t planeSize = std::size_t(width_) * height_;
  const float* weight = history_[current_].data.data() + 3 * planeSize;
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
    f.previous.plane[c] = history_[current_].data.data() + c * planeSize;
    f.history[c] = history_[next].data.data() + c * planeSize;
  }
  f.previous.width = width_;
  f.previous.height = height_;
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
    in.color = inputApartFromOutput("color");
    if (hasImage("motion")) in.motion = inputApartFromOutput("motion");
    if (hasImage("depth")) in.depth = inputApartFromOutput("depth");
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
