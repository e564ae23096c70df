// SPDX-License-Identifier: Apache-2.0
// "phlm": pixel history linear models (Iglesias-Guitian et al. 2016, seed 002;
// METHODS.md "PHLM"). Per pixel i, per frame (Algorithm 1):
//   1. velocity v_i: of the closest-depth pixel of the 3x3 with depth, else the
//      centre's (temporal/velocity.h); no motion image = static scene: pi(v) = i,
//      no reprojection work, the state is updated in place (§5.2 "Special case");
//   2. temporal feature z_i (§5.1, eq. 1): exponential history of the
//      low-frequency colour, reprojected with a bilinear fetch, blended with
//      this frame's low-frequency colour with the per-pixel weight
//      alpha_i = phi(v_i, l_i) / (l_i + Delta_i(Y)), phi = a l^2 + b |v| l^3;
//   3. model (beta, P) of pixel q = pi(v_i) = nearest pixel to i + v (§5.2
//      "Pixel history reprojection": the model placed at q); q off-screen,
//      non-finite motion or a depth mismatch (disocclusion) -> reset to y_i;
//   4. prediction f = beta' [1, z] (eq. 4); if f lies outside the 3x3 RGB
//      colour box (the axis-aligned approximation of Conv(Omega_i), §5.2
//      "Pixel history correction") it is moved onto the box along the ray
//      from f toward y_i (lines 14-17) and the model is reset to that colour;
//   5. e = y - f; RLS update (eqs. 5-7, lambda = 0.998) in the stabilised form
//      of phlm_rls.h; output beta' x after the update.
// Step 1, the neighbourhood and the choice of q run one pixel at a time
// (phlmPixel), except on 8 pixels that all move or all stand still, whose
// taps need no clamp, in the AVX2 copy of the float kernel: those run as
// lanes (phlmMovingGroup, phlmStillGroup: the same operations;
// Phlm.ReferencePathEqualsFastPath compares both); the
// model and feature fetches of steps 2-3 and steps 4-5 run on 8 pixels of a
// row at once (finishBatch: GCC vectors, lane i = pixel i, every branch as a
// per-lane select), in every path: lane by lane the same IEEE operations in
// the same order as the one-pixel form, so the same bits (measured: identical
// outputs and states to the one-pixel code of 992ccd5 on ghosting,
// disocclusion and moving-edge runs, float32 and float64; and to 17936ff's
// interleaved records after the change to blocks of 8, phlm.h kBlock). The
// records are stored as the batch's vectors: a block of 8 still pixels, or 8
// pixels whose models sit side by side (uniform motion), is read and written
// as whole vectors, the rest gathered lane by lane. A still pixel's 5x5 work
// (is anything moving, the footprint box) reads per-row results the fast
// path makes once per row (StillRow, FootprintRow).
// Initialisation (§6): beta intercept = y, slopes 0, P = 1000 I, z = y.
//
// Decisions the paper leaves open, and deviations (beside the code too):
//  * Stabilised RLS (phlm_rls.h): UD-factorised P (symmetric, positive
//    definite by construction) and regularised forgetting that bounds
//    P <= P0 / lambda^3 (trace <= (p0 + 3 ps) / lambda^3); identical to
//    eqs. 6-7 except where the paper's P would wind up past its reset value.
//    With lambdaMoving (below) a moving frame forgets with lambdaMoving and
//    refreshes every axis with information (1 - lambdaMoving) / P0_kk. In
//    information form R = P^-1, just after any refresh of an axis R_kk >=
//    c / P0_kk holds with c = min(1, (1 - lm) / (1 - lm lambda^3)), lm =
//    lambdaMoving: a still refresh gives lambda^4 c + 4 (1 - lambda) >= c, a
//    moving one lm lambda^3 c + 1 - lm >= c, and between refreshes at most 3
//    still frames decay it by lambda each. So P <= P0 / (lambda^3 c), trace
//    <= (p0 + 3 ps) / (lambda^3 c) (c = 0.986 at the defaults), the bound
//    test_phlm_stability.cpp asserts. Refreshing one axis per moving frame
//    instead left P unbounded when a pixel alternates between moving and
//    still frames (measured: trace 14910 > 11663 on the depth-at-infinity run).
//  * Forgetting: moving pixels (non-zero velocity) forget with lambdaMoving
//    = 0.7, still ones with the paper's lambda = 0.998 (the paper has one
//    lambda). A moving pixel's model is carried to a new pixel every frame
//    and its evidence was measured on other parts of the surface; with
//    EEVEE's +-1.5 px jitter and the unjittered measurement the current
//    frame is already a filtered estimate (taa's lower feedback, same
//    reason). Measured (crisp eval, 240x136, frames 9-48 vs 256 samples; PSNR
//    dB / temporal error), lambdaMoving 0.998 -> 0.7: camera_dolly
//    24.53/0.0146 -> 25.75/0.0156, spinning_cube 30.29/0.0036 ->
//    33.69/0.0029, ghosting 26.13/0.0079 -> 26.51/0.0078; synthetic moving
//    edge and disks +1.0 to +2.2 dB with less flicker, a slowly moving edge
//    +0.8 dB with more (0.0015 -> 0.0022).
//  * Resampling damping (parameter resampleDamping, beta = 0.25; taa's
//    rule): a moving model is fetched every frame, and each bilinear fetch
//    at a sub-pixel offset averages four models (most at half a pixel, none
//    at whole pixels); kept for 1/(1 - lm) frames, the blur builds up on
//    textured surfaces. A moving lane forgets with lm = lambdaMoving (1 -
//    beta s), s = max(4 tx (1 - tx), 4 ty (1 - ty)) of the fetch's
//    fractions, and refreshes with (1 - lm) / P0_kk (the bound above holds:
//    c(lm) grows as lm falls). Measured (as above), beta 0 -> 0.3 (0.2,
//    0.4, 0.5): spinning_cube 33.69/0.00288 -> 35.37/0.00280 (34.91/0.00279,
//    35.70/0.00284, 35.87/0.00293), camera_dolly 25.75/0.0156 ->
//    26.00/0.0170 (25.95/0.0165, 26.00/0.0176, 25.96/0.0183), ghosting
//    30.31/0.00565 -> 30.56/0.00557: the cube passes taa (35.23) and
//    Blender's SMAA node (34.87); the dolly flickers 9 % more, still less
//    than taa (0.0173). Test Phlm.ResampleDampingActsOnlyAtSubPixelMotion.
//    Those figures are with the bilinear model fetch; with the Catmull-Rom
//    intercepts (below), which blur less, beta = 0.25 (below).
//  * Model fetch (parameter modelFetch, default catmull-rom; §5.2 and §6
//    keep the models in textures read bilinearly): a moving lane's
//    intercepts beta[0][c] are read by Catmull-Rom over the 4x4 around the
//    bilinear footprint, each clamped to the range of its 4 central taps
//    (taa's history fetch, temporal/history_fetch.h: no ringing past the
//    neighbouring models); the slopes and the feature z stay bilinear, P is
//    the nearest model's. At whole-pixel offsets it reads the nearest model
//    exactly, as the bilinear fetch does. The intercepts carry the colour;
//    Catmull-Rom on the slopes as well changed nothing measurable, on z
//    neither. Measured (docs/temporal_figures.md: crisp eval, 240x136,
//    frames 9-48 vs 256 samples; PSNR dB / temporal error), bilinear and
//    beta 0.3 -> Catmull-Rom and beta 0.3 -> Catmull-Rom and beta 0.25:
//    spinning_cube 35.37/0.002797 -> 35.70/0.002686 -> 35.52/0.002662 (taa
//    35.23/0.002666), camera_dolly 25.99/0.01727 -> 25.92/0.01719 ->
//    25.90/0.01690 (taa 25.76/0.01756), ghosting 30.51/0.00530 ->
//    30.52/0.00530 -> 30.48/0.00531 (taa 29.39/0.00541). Unclamped
//    Catmull-Rom: spinning_cube 35.72/0.002709. Lower beta or higher
//    lambdaMoving trade PSNR for temporal error (beta 0, 0.15:
//    34.18/0.00269, 35.10/0.00266 on spinning_cube; lambdaMoving 0.74:
//    35.50/0.002661). Test Phlm.CatmullRomInterceptsKeepASubPixelPanSharper.
//    The fetch reads the intercepts from planes kept beside the records
//    (written with them, 24 bytes per pixel for the two buffers), where a
//    tap of 8 pixels is one unaligned load: gathered from the blocked
//    records it needed a shuffle per tap, and a copy pass over the records
//    each frame cost about 15 ms at 1920x1080 on 2 threads.
//  * Reset covariance P0 = diag(p0, ps, ps, ps) = diag(1000, 1, 1, 1), not the
//    paper's 1000 I: with 1000 on the slopes the fit "explains" per-frame
//    flicker by the feature's tiny per-frame changes (z is an exponential
//    history that includes this frame's low-frequency colour, so it is
//    correlated with y): slopes of ~1/|dz| that reproduce the aliasing, and an
//    ill-conditioned fit whose float32 and float64 runs drift apart. The
//    feature is in a bounded space (below), where slopes of O(1) are natural,
//    so a prior variance of 1 only removes implausible slopes. The first
//    sample after a reset still dominates (gain 1 - lambda/(lambda + x'P0 x)
//    > 0.999). slopeCovariance = 1000 is the paper's setting.
//  * The feature lives in a bounded space: z = c / (1 + Y(c)) of the clamped
//    (>= 0) low-frequency colour c, Y the YCgCo luminance (R + 2G + B) / 4
//    (§5.1 uses YCgCo luminance). So |z_k| < 4, x is well scaled whatever the
//    HDR range, and l, Delta are tonemapped luminances in [0, 1) (the paper's
//    a, b were tuned on LDR values).
//  * "Low-frequency colour" = the 3x3 box average of this frame.
//  * Box (footprintBox = true, a deviation from lines 13-19, which use the
//    3x3 colour box): where nothing in the 5x5 moves, the correction and the
//    output clamp use the footprint box, the 3x3 box united with the 5x5 box
//    of second-largest /
//    second-smallest values per channel (taa.cpp: one firefly does not widen
//    it). With samples jittered over +-filterSize = +-1.5 px (EEVEE's draw,
//    docs/sampling.md) a converged model next to an edge predicts a mix over
//    the whole footprint, which one frame's 3x3 (samples at [-1, 1] px
//    shifted by the jitter) misses: still_life frame 8 fell 31.0 -> 27.0 dB
//    on such box resets (30.7 dB with footprintBox). Where something moves
//    nearby, the 3x3 box stays (a trail must not hide in the wider box).
//    With motion, a pixel whose model moved, saw motion in its 5x5 or was
//    box-corrected since its last reset keeps the 3x3 box until its next
//    reset (a byte per pixel, as taa's feedback-since-reset bit): such a
//    model may hold another colour that lies inside the wider box, such as
//    the wall under ghosting's moving shadow, which has no motion at all.
//    Measured (docs/temporal_figures.md: crisp eval, 240x136, frames 9-48 vs
//    256 samples; PSNR dB / temporal error): ghosting 28.12/0.0064 ->
//    30.31/0.0056 (means over all 48 frames: the 3x3 box everywhere
//    30.42/0.0064, the box-corrected condition alone 29.54/0.0061);
//    spinning_cube, camera_dolly and still_life (no motion image) unchanged.
//    The price: box corrections at edges under jitter flag still pixels too
//    (a still chart with a zero motion image: -0.23 dB;
//    Phlm.ReturningShadowLeavesNoLag).
//    On by default (since 2026-11-22). The output of a still pixel then lies
//    in its 5x5 colour range rather than its 3x3 one (the bound
//    test_phlm_stability.cpp checks for such pixels), and a slow change of a
//    still gradient lags more (the wider box accepts older values); false
//    restores the paper's 3x3 box everywhere. Using the
//    footprint box for the correction only does not help (27.2 dB): the
//    output clamp to the 3x3 box throws the converged value away as well.
//  * Hold (parameter holdPeriod P, default 16; taa.cpp "Hold"): the jitter
//    cycles through P points and EEVEE repeats its 1-sample noise, so a
//    still pixel's input is periodic and a model that has seen P of its
//    samples has seen them all; learning on only moves the output back and
//    forth around the fit (and the feature z with this frame's colour). A
//    still model (nothing in its 5x5 moves, not reset this frame; a narrow
//    one too: requiring the narrow flag clear held too few pixels on
//    ghosting, temporal error 0.00538 against 0.00530) holding P samples
//    since its reset or last box correction keeps its beta, P and z: its
//    output stops changing. The prediction is still
//    tested against the box, so a change that leaves the box corrects and
//    restarts it. One that stays inside the box is caught by the release
//    (parameter holdRelease; taa.cpp "Hold", temporal/hold_release.h): a
//    still model, held or learning, whose input's window of P frames
//    differs from the last matching one twice running restarts from y, as
//    at a reset (before it, such a change was never taken in by a held
//    model and over hundreds of frames by a learning one: docs/
//    temporal_figures.md, "Weakness of the hold"). One byte per pixel
//    counts the samples (saturating), a word per pixel keeps the windows. A batch
//    of held lanes skips step 5, and in place (static scene) its store.
//    Measured: still_life's 16 jittered frames filtered twice over (32
//    frames), frame 32 against the 64-sample reference: 39.674 dB held,
//    39.676 learning (frame 16: 39.667); 0.6 % of the pixels still change
//    between frames 17 and 32 (box corrections at edges).
//  * l = distance of the feature's luminance to [Ymin, Ymax] of the 3x3 (0
//    inside), Delta = Ymax - Ymin. We read alpha as the weight of the CURRENT
//    low-frequency colour (alpha = 0 would freeze a feature that lies in range,
//    and grows as it leaves the range), clamped to [featureAlphaMin, 1]; the
//    floor (default 0.05, not in the paper) lets the feature follow slow
//    changes inside the range.
//  * The model is reprojected from the nearest pixel (no interpolation of
//    beta or P, which would mix the models of two surfaces at an edge); the
//    feature, a low-frequency colour, bilinearly.
//  * Output = f + g e with g = x'P x / (1/w + x'P x) in [0, 1), which equals
//    beta'x after the update (eq. 8) in exact arithmetic and is a convex
//    combination of two points of the box: the output lies in the 3x3 colour
//    box of the current frame (a final clamp absorbs rounding).
//  * Jitter: the measurement y is the unjittered mix of the 3x3 around the
//    sample nearest the pixel centre (unjitter, temporal/jitter.h and
//    taa.cpp "Jitter"; a deviation from the paper, which renders without
//    jitter): with EEVEE's +-1.5 px jitter a pixel's own sample jumps across
//    edges from frame to frame and the fit follows the jumps; the mix
//    converges to the same filtered pixel. The 3x3 (box, average, luminance
//    range, followed tap) is read around that sample; the box is widened to
//    contain y. unjitter = none fits the pixel's own samples. jitterX/Y also
//    set the sample weight w when jitterWeighting = blackman-harris
//    (weighted least squares: measurement variance 1/w), the "weighted
//    moving average" of §5.2's static special case.
//
// Parameters (also `crisp help phlm` / crispGetFilterDoc):
// | name | type | default | range | meaning | source |
// |---|---|---|---|---|---|
// | jitterX | float | 0 | [-4, 4] | this frame's sample offset, pixels, x right | §5.2, seed 000 app. B |
// | jitterY | float | 0 | [-4, 4] | sample offset, pixels, y DOWN | §5.2 |
// | jitterWeighting | string | none | none, blackman-harris | weight of each sample in the RLS | §5.2 static case |
// | filterSize | float | 1.5 | [0.01, 4] | Blackman-Harris width for the weighting | BLENDER.md |
// | lambda | float | 0.998 | [0.5, 0.99999] | forgetting factor | eqs. 6-7 |
// | lambdaMoving | float | 0.7 | [0.5, 0.99999] | forgetting factor of moving pixels | this file |
// | holdPeriod | int | 16 | [0, 127] | a still model with this many samples since its reset stops learning | this file (Hold) |
// | holdRelease | float | 0.002 | [0, 1] | a still model whose input's period mean changes by more, twice running, restarts; 1 = never | this file (Hold) |
// | resampleDamping | float | 0.25 | [0, 0.9] | moving pixels forget with lambdaMoving (1 - beta s) at sub-pixel fraction s | this file |
// | modelFetch | string | catmull-rom | catmull-rom, bilinear, nearest | how a moving pixel's model is read | §5.2, §6; this file |
// | initialCovariance | float | 1000 | [1e-3, 1e6] | p0: intercept variance at init/reset, and its bound | §6 |
// | slopeCovariance | float | 1 | [1e-3, 1e6] | ps: slope variances at init/reset, and their bound | §6 (deviation) |
// | featureA | float | 0.125 | [0, 10] | a of phi | §5.1 |
// | featureB | float | 0.25 | [0, 10] | b of phi | §5.1 |
// | featureAlphaMin | float | 0.05 | [0, 1] | floor of the feature's current weight | this file |
// | footprintBox | bool | true | - | still pixels: 3x3 box united with the 5x5 values seen twice | docs/sampling.md |
// | unjitter | string | blackman-harris | blackman-harris, nearest, none | the measurement: the unjittered 3x3 mix | temporal/jitter.h |
// | depthTolerance | float | 0.05 | [0, 10] | relative depth change still the same surface | this file |
// | reference | bool | false | - | scalar reference path | this file |
#include "filters/phlm.h"

#include <algorithm>
#include <climits>
#include <cmath>
#include <cstring>
#include <type_traits>
#if defined(__SSE2__)
#include <xmmintrin.h>
#endif

#include "core/color.h"
#include "core/error.h"
#include "core/filter.h"
#include "core/parallel.h"
#include "filters/phlm_feature.h"
#include "filters/phlm_stage.h"
#include "filters/temporal_filter.h"
#include "temporal/history_fetch.h"
#include "temporal/hold_release.h"
#include "temporal/isa.h"
#include "temporal/rows.h"
#include "temporal/jitter.h"
#include "temporal/lanes.h"
#include "temporal/neighbourhood.h"
#include "temporal/vec4.h"
#include "temporal/velocity.h"

namespace crisp::phlm {

namespace {

template <class T>
struct Frame {
  int width, height;
  const float* staged;         // sanitised linear RGB + tonemapped YCgCo luminance Y / (1 + Y)
  const std::uint8_t* alphaOne;  // per row: every input alpha is 1 (Kernel::alphaOne_)
  ImageView color;             // the input (alpha)
  const float* depth;          // this frame's sanitised depth, or null
  const float* previousDepth;  // previous frame's, or null (no depth test)
  ImageView motion;            // ptr null: static scene
  bool hasHistory;
  const T* previous;           // records of the last frame (== next when static), Kernel::recordIndex layout
  T* next;                     // records written
  int blocksPerRow;            // blocks of kBatch pixels per row of records
  ImageView output;
  T inverseLambda, regulariserVariance[kDims], regulariserWeight[kDims], sampleVariance, sampleWeight, p0, ps;
  // Moving pixels (header "Forgetting"): lambdaMoving (1 - resampleDamping s) per lane.
  T lambdaMoving, resampleDamping, p0Diagonal[kDims];
  bool update;                 // sample weight > 0
  bool bilinearBeta;           // reproject beta's slopes bilinearly (else nearest)
  bool catmullRomIntercepts;   // and its intercepts by clamped Catmull-Rom (else as the slopes; "Model fetch")
  const T* intercepts;         // with motion: the previous records' intercepts, interceptRow's layout
  T* interceptsNext;           // with motion: the intercepts of the records written (else null)
  bool streamNext;             // write next and interceptsNext with streaming stores (Kernel::run)
  bool reference;              // the reference path: the Catmull-Rom fetch gathers from the records
  bool footprintBox;           // still pixels use the footprint box (header, "Box")
  std::uint8_t* narrowBox;  // per pixel: 1 = its model keeps the 3x3 box until its reset ("Box"); null: static scene
  std::uint8_t* stillSamples;  // per pixel: samples since its reset or box correction, while still (header, "Hold")
  const std::uint8_t* movingFlags = nullptr;  // fast path with motion: per pixel, temporal::movingRow; else null
  int holdPeriod;              // a model with this many still samples is held; 0: off
  temporal::HoldWindowFrame release;  // Kernel::holdWindows_ (temporal/hold_release.h)
  T boxResetScale;             // P after a box correction = boxResetScale * P0
  int axis;                    // regularised axis of this frame
  T featureA, featureB, featureAlphaMin;
  float depthTolerance;
  temporal::Unjitter unjitter;  // the 3x3 is read around the sample nearest the centre (header, "Jitter")
};

// Step 5 runs on kBatch pixels of a row at once (finishBatch): lane i of
// every vector is pixel x0 + i; model is the record transposed (model[j] =
// scalar j of every lane). GCC vector extensions: one AVX register of floats
// in the AVX2 copy of the row loop (temporal/isa.h), two SSE ones in the
// baseline copy.
constexpr int kBatch = kBlock;  // a batch is a block of the records (phlm.h)
template <class T>
struct LanesOf;
template <>
struct LanesOf<float> {
  typedef float V __attribute__((vector_size(kBatch * sizeof(float))));
  typedef int M __attribute__((vector_size(kBatch * sizeof(int))));
};
template <>
struct LanesOf<double> {
  typedef double V __attribute__((vector_size(kBatch * sizeof(double))));
  typedef long long M __attribute__((vector_size(kBatch * sizeof(long long))));
};
template <class T>
struct Batch {
  using V = typename LanesOf<T>::V;
  using M = typename LanesOf<T>::M;
  // Step 3, per lane: where the nearest model q = pi(v) is (read only when
  // valid) and, for a moving lane, the bilinear footprint of the feature (and
  // beta) fetch: its four taps and fractions. Pixels as indices into the
  // padded rows (phlm.h paddedPixel).
  std::size_t source[kBatch], tap[4][kBatch];
  float tx[kBatch], ty[kBatch];
  int footX[kBatch], footY[kBatch];  // the footprint's top-left tap, unclamped (Catmull-Rom's 4x4 around it)
  bool allValid = true;      // every lane reprojected (no reset)
  bool allBilinear = true;   // every lane valid and moving
  bool anyBilinear = false;  // some lane valid and moving
  // Step 2's inputs: the 3x3 sum and luminance range, |v|; valid: 1
  // (history reprojected) or 0 (reset).
  V sum[3], yMin, yMax, speed, valid;
  V current[3], lo[3], hi[3], moving;  // moving: 1 or 0
  V held;                              // 1: keep the model and feature as they are (header, "Hold")
  bool anyHeld = false;
  int count = 0, x0 = 0, y = 0;
};

// The lanes' pixels are consecutive (pixel[i] = pixel[0] + i).
CRISP_PHLM_INLINE bool isRun(const std::size_t pixel[kBatch]) {
  bool run = true;
  for (int i = 1; i < kBatch; ++i) run &= pixel[i] == pixel[0] + std::size_t(i);
  return run;
}
// The footprint's extremes: the 25 taps of the 5x5 around (x, y), each
// clamped to the image (shiftedSource) in every path, as the merge
// (mergeExtremes, left to right) of its five columns' extremes (each top to
// bottom). The fast path keeps each column's extremes for the row
// (FootprintRow), so a still pixel merges five columns instead of taking 25
// taps; the order is the same, so are the bits.
template <class T>
CRISP_PHLM_INLINE void footprintRows(const Frame<T>& f, int y, const float* row[5]) {
#pragma GCC unroll 5
  for (int j = 0; j < 5; ++j)
    row[j] = f.staged + std::size_t(temporal::shiftedSource(y + j - 2, f.height, f.unjitter.shiftY)) * f.width * 4;
}
// Column x (may lie outside the image: clamped) of the 5 rows.
template <class T>
CRISP_PHLM_INLINE temporal::TwoExtremes4 footprintColumn(const Frame<T>& f, int x, const float* const row[5]) {
  const int c = temporal::shiftedSource(x, f.width, f.unjitter.shiftX) * 4;
  temporal::TwoExtremes4 e = temporal::twoExtremesOf(temporal::load4(row[0] + c), temporal::load4(row[1] + c));
#pragma GCC unroll 3
  for (int j = 2; j < 5; ++j) temporal::addTap(e, temporal::load4(row[j] + c));
  return e;
}
template <class T>
CRISP_PHLM_INLINE temporal::TwoExtremes4 footprintExtremes(const Frame<T>& f, int x, int y) {
  const float* row[5];
  footprintRows(f, y, row);
  temporal::TwoExtremes4 e = footprintColumn(f, x - 2, row);
#pragma GCC unroll 4
  for (int k = 1; k < 5; ++k) temporal::mergeExtremes(e, footprintColumn(f, x - 2 + k, row));
  return e;
}
// The fast path's column extremes of a row (index k: column k - 2), made when
// a pixel of the row first asks for its footprint.
struct FootprintRow {
  std::vector<temporal::TwoExtremes4> columns;
  int row = -1;
  template <class T>
  temporal::TwoExtremes4 of(const Frame<T>& f, int x, int y) {
    if (row != y) {
      columns.resize(std::size_t(f.width) + 4);
      const float* rows[5];
      footprintRows(f, y, rows);
      for (int k = 0; k < f.width + 4; ++k) columns[std::size_t(k)] = footprintColumn(f, k - 2, rows);
      row = y;
    }
    temporal::TwoExtremes4 e = columns[std::size_t(x)];
#pragma GCC unroll 4
    for (int k = 1; k < 5; ++k) temporal::mergeExtremes(e, columns[std::size_t(x + k)]);
    return e;
  }
};

// The fast path's stillFootprint of a row, from the frame's moving flags
// (Kernel::run), made when a still pixel of the row first asks (a pan never
// does).
struct StillRow {
  std::vector<std::uint8_t> bytes;  // width flags, then width + 4 scratch
  int row = -1;
  template <class T>
  const std::uint8_t* of(const Frame<T>& f, int y) {
    if (row != y) {
      bytes.resize(std::size_t(2) * f.width + 4);
      temporal::stillFootprintRow(f.movingFlags, y, f.width, f.height, f.unjitter.shiftX, f.unjitter.shiftY,
                                  bytes.data() + f.width, bytes.data());
      row = y;
    }
    return bytes.data();
  }
};

// Step 1's closest-depth taps of a pixel's row, computed ahead a lane group
// at a time (phlmRowsBody), or null: phlmPixel calls closestDepthTap. Also
// the row's still footprints and footprint columns, or null: phlmPixel
// works on its 5x5.
struct RowTaps {
  const float* tap = nullptr;    // int bits (temporal::closestDepthTapsRow)
  const float* depth = nullptr;  // the tap's depth
  StillRow* still = nullptr;
  FootprintRow* footprint = nullptr;  // or null: footprintExtremes per pixel
};

// The 3x3 box and sum of nine taps, in tap order (min/max are exact and the
// sum runs in tap order, so every path gets the same bits).
CRISP_PHLM_INLINE void boxOfTaps(const temporal::Vec4 taps[9], temporal::Vec4& lo, temporal::Vec4& hi,
                                 temporal::Vec4& sum) {
  lo = hi = sum = taps[0];
#pragma GCC unroll 8
  for (int i = 1; i < 9; ++i) {
    lo = temporal::vmin(lo, taps[i]);
    hi = temporal::vmax(hi, taps[i]);
    sum += taps[i];
  }
}

// Disocclusion: the followed surface (depth d) must be in the previous
// frame's 3x3 around q (a jittered edge pixel's own sample may be of either
// surface). An interior q reads its 3x3 directly (the same taps as clamping each).
template <class T>
CRISP_PHLM_INLINE bool followedSurfaceAround(const Frame<T>& f, int qx, int qy, float d) {
  const int w = f.width, h = f.height;
  if (qx >= 1 && qx + 1 < w && qy >= 1 && qy + 1 < h) {
    const float* around = f.previousDepth + std::size_t(qy - 1) * w + (qx - 1);
    for (int i = 0; i < 9; ++i)
      if (temporal::sameSurfaceDepth(d, around[std::size_t(i / 3) * w + i % 3], f.depthTolerance)) return true;
    return false;
  }
  for (int j = -1; j <= 1; ++j)
    for (int k = -1; k <= 1; ++k) {
      const int sx = std::clamp(qx + k, 0, w - 1), sy = std::clamp(qy + j, 0, h - 1);
      if (temporal::sameSurfaceDepth(d, f.previousDepth[std::size_t(sy) * w + sx], f.depthTolerance)) return true;
    }
  return false;
}

// A still pixel (x, y) that failed the depth test above keeps its model when
// the surface of its own previous sample is still, and still, in this frame's
// 5x5 (temporal::stillSurfaceNear). The depth planes are unshifted, so the
// 5x5 is read around (x, y) itself.
template <class T>
CRISP_PHLM_INLINE bool stillSurfaceNear(const Frame<T>& f, int x, int y) {
  if (!f.motion.ptr || !f.depth || !f.previousDepth) return false;
  const int w = f.width;
  return temporal::stillSurfaceNear(f.motion, x, y, w, f.height, 0, 0, f.previousDepth[std::size_t(y) * w + x],
                                    f.depthTolerance,
                                    [&](int sx, int sy) { return f.depth[std::size_t(sy) * w + sx]; });
}

// Always inlined: into both copies of the row loop (temporal/isa.h).
template <class T, bool Clamp>
__attribute__((always_inline)) inline void phlmPixel(const Frame<T>& f, int x, int y, FrameStats& stats,
                                                     Batch<T>& batch, const RowTaps& rowTaps) {
  const int w = f.width, h = f.height;
  // 3x3 neighbourhood of this frame: box, average (the low-frequency colour),
  // tonemapped luminance range.
  // Four lanes at once (temporal/vec4.h): RGB and, in lane 3, the staged
  // tonemapped luminance; min/max are exact and the sum runs in tap order, so
  // every path gets the same bits.
  using temporal::Vec4;
  // With unjitter the taps are those of the shifted image (header, "Jitter");
  // shiftedSource is the reference's clamp, so every path reads the same taps.
  // Clamp is true on the border, in the reference path and whenever the
  // image is shifted (phlmRowsBody); elsewhere the taps need no clamp.
  Vec4 boxLo, boxHi, boxSum, taps[9];
  float depth9[9];
  int tapX[3], tapY[3];  // tap i is (tapX[i % 3], tapY[i / 3])
  const int sx = f.unjitter.shiftX, sy = f.unjitter.shiftY;
#pragma GCC unroll 3
  for (int k = 0; k < 3; ++k) {
    tapX[k] = Clamp ? temporal::shiftedSource(x + k - 1, w, sx) : x + k - 1;
    tapY[k] = Clamp ? temporal::shiftedSource(y + k - 1, h, sy) : y + k - 1;
  }
#pragma GCC unroll 9
  for (int i = 0; i < 9; ++i) taps[i] = temporal::load4(f.staged + (std::size_t(tapY[i / 3]) * w + tapX[i % 3]) * 4);
  boxOfTaps(taps, boxLo, boxHi, boxSum);
  if (f.depth && !rowTaps.tap) {
#pragma GCC unroll 9
    for (int i = 0; i < 9; ++i) depth9[i] = f.depth[std::size_t(tapY[i / 3]) * w + tapX[i % 3]];
  }
  const T sum[3] = {T(boxSum[0]), T(boxSum[1]), T(boxSum[2])};
  const T yMin = T(boxLo[3]), yMax = T(boxHi[3]);

  // Step 1: velocity (closest depth of the 3x3 when depth is given).
  float vx = 0.0f, vy = 0.0f;
  int tap = 4;
  float tapDepth = 0.0f;  // depth9[tap], read below only with previousDepth (which comes with depth)
  if (rowTaps.tap) {
    std::memcpy(&tap, rowTaps.tap + x, sizeof tap);
    tapDepth = rowTaps.depth[x];
  } else if (f.depth) {
    if (f.motion.ptr) tap = temporal::closestDepthTap(depth9);
    tapDepth = depth9[tap];
  }
  if (f.motion.ptr) {
    const float* m = f.motion.pixel(tapX[tap % 3], tapY[tap / 3]);
    vx = m[0];
    vy = m[1];
  }
  const bool moving = vx != 0.0f || vy != 0.0f;
  // The measurement y: the unjittered mix of the 3x3 (the centre tap without
  // unjitter).
  const Vec4 sample = f.unjitter.enabled ? temporal::unjitteredMix(taps, f.unjitter.weights) : taps[4];
  const T current[3] = {T(sample[0]), T(sample[1]), T(sample[2])};
  bool valid = f.hasHistory && temporal::finiteMotion(vx, vy);
  const float px = float(x) + vx, py = float(y) + vy;
  if (valid) valid = temporal::onScreen(px, py, w, h);
  int qx = x, qy = y;
  if (valid && moving) {
    qx = std::clamp(int(std::floor(px + 0.5f)), 0, w - 1);
    qy = std::clamp(int(std::floor(py + 0.5f)), 0, h - 1);
  }
  if (valid && f.previousDepth)
    valid = followedSurfaceAround(f, qx, qy, tapDepth) || (!moving && stillSurfaceNear(f, x, y));

  // The footprint box trusts a still model. A model that moved, saw
  // something move in its 5x5 or was box-corrected since its reset may hold
  // another surface's or an earlier light's colour (the depth test accepts a
  // neighbour's depth and surfaces close in depth, the measurement mixes the
  // 3x3, and a moving shadow has no motion at all): it keeps the 3x3 box,
  // which corrects it once the other colour has gone (header, "Box").
  // Still, and nothing in the 5x5 moves.
  const bool stillAround =
      !moving && (rowTaps.still ? rowTaps.still->of(f, y)[x] != 0
                                : temporal::stillFootprint(f.motion, x, y, w, h, f.unjitter.shiftX, f.unjitter.shiftY));
  // A still model whose input changed for two windows running restarts
  // from y, as at a reset (header, "Hold").
  bool released = false;
  if (f.release.words) {
    std::uint32_t& word = f.release.words[std::size_t(y) * w + x];
    const bool still = valid && !moving && stillAround;
    word = std::uint32_t(temporal::stepHoldWindow<float>(int(word), temporal::holdLumaOfTonemapped(sample[3]), still,
                                                         f.release.windowEnd, f.release.limit, released));
    valid = valid && !released;
  }
  bool narrow = false;
  if (f.narrowBox) {
    std::uint8_t& flag = f.narrowBox[std::size_t(y) * w + x];
    narrow = valid && flag != 0;
    flag = narrow || !stillAround ? 1 : 0;  // finishBatch sets it on a box correction
  }
  // Hold: a still model that holds a whole jitter period of
  // samples stops learning (header, "Hold"). Its count restarts at a reset
  // (1 sample: the model is y) and at a box correction (finishBatch).
  bool held = false;
  {
    std::uint8_t& count = f.stillSamples[std::size_t(y) * w + x];
    const bool calm = valid && !moving && stillAround;
    held = calm && f.holdPeriod > 0 && count >= f.holdPeriod;
    count = !valid ? 1 : (!calm ? 0 : (held || count == 255 ? count : std::uint8_t(count + 1)));
  }
  Vec4 lo4 = boxLo, hi4 = boxHi;  // lanes 0-2 are used
  if (f.footprintBox && !narrow && stillAround) {
    // The box of the correction and of the output clamp: the footprint box
    // (header, "Box"), the 3x3 box united with the 5x5's second extremes.
    const temporal::MinMax4 foot = temporal::footprintBox(
        {boxLo, boxHi}, rowTaps.footprint ? rowTaps.footprint->of(f, x, y) : footprintExtremes(f, x, y));
    lo4 = foot.min;
    hi4 = foot.max;
  }
  // The correction needs y inside the box (lines 13-17): the weighted mix can
  // pass a face by rounding. Without unjitter y is a tap and this changes
  // nothing. (vmin/vmax are std::min/max lane by lane, and T(float) is exact.)
  lo4 = temporal::vmin(lo4, sample);
  hi4 = temporal::vmax(hi4, sample);

  // Step 3 (the model of q) and the fetch of step 2 run in finishBatch, on
  // the batch's lanes: here only where to read.
  const int lane = batch.count;
  if (lane == 0) {
    batch.x0 = x;
    batch.y = y;
    batch.allValid = batch.allBilinear = true;
    batch.anyBilinear = false;
    batch.anyHeld = false;
  }
  T speed = T(0);
  batch.tx[lane] = batch.ty[lane] = 0.0f;
  batch.footX[lane] = batch.footY[lane] = 0;
  if (valid) {
    batch.source[lane] = paddedPixel(f.blocksPerRow, qx, qy);
    if (moving) {
      // Step 2: feature history at pi(v) (exact at zero motion), eq. 1,
      // bilinear with clamp to edge (temporal/history_fetch.h's footprint).
      const temporal::Footprint fp = temporal::footprintOf(px, py);
      const int xa = std::clamp(fp.x0, 0, w - 1), xb = std::clamp(fp.x0 + 1, 0, w - 1);
      const int ya = std::clamp(fp.y0, 0, h - 1), yb = std::clamp(fp.y0 + 1, 0, h - 1);
      batch.tap[0][lane] = paddedPixel(f.blocksPerRow, xa, ya);
      batch.tap[1][lane] = paddedPixel(f.blocksPerRow, xb, ya);
      batch.tap[2][lane] = paddedPixel(f.blocksPerRow, xa, yb);
      batch.tap[3][lane] = paddedPixel(f.blocksPerRow, xb, yb);
      batch.tx[lane] = fp.tx;
      batch.ty[lane] = fp.ty;
      batch.footX[lane] = fp.x0;
      batch.footY[lane] = fp.y0;
      batch.anyBilinear = true;
    } else {
      batch.allBilinear = false;
    }
    speed = T(std::sqrt(vx * vx + vy * vy));
  } else {
    // Lines 7-9 / §6: reset to the input; z = y (finishBatch).
    ++(released ? stats.releases : stats.reprojectionResets);
    batch.allValid = batch.allBilinear = false;
  }
  for (int c = 0; c < 3; ++c) {
    batch.sum[c][lane] = sum[c];
    batch.current[c][lane] = current[c];
    batch.lo[c][lane] = T(lo4[c]);
    batch.hi[c][lane] = T(hi4[c]);
  }
  batch.yMin[lane] = yMin;
  batch.yMax[lane] = yMax;
  batch.speed[lane] = speed;
  batch.valid[lane] = valid ? T(1) : T(0);
  batch.moving[lane] = moving ? T(1) : T(0);
  batch.held[lane] = held ? T(1) : T(0);
  batch.anyHeld |= held;
  ++batch.count;
}

// Eight non-negative int lanes widened into size_t indices.
template <class Int>
__attribute__((always_inline)) inline void storeIndices(std::size_t out[kBatch], Int v) {
  typedef long long Wide __attribute__((vector_size(32)));
  static_assert(sizeof(std::size_t) == sizeof(long long));
  const Wide lo = __builtin_convertvector(__builtin_shufflevector(v, v, 0, 1, 2, 3), Wide);
  const Wide hi = __builtin_convertvector(__builtin_shufflevector(v, v, 4, 5, 6, 7), Wide);
  std::memcpy(out, &lo, sizeof lo);
  std::memcpy(out + 4, &hi, sizeof hi);
}

// Step 1 for the eight pixels x0 .. x0 + 7 of row y (a lane group): the
// followed tap's velocity and depth, lane by lane as phlmPixel; 0 without
// motion. Needs the closest-depth taps ahead (rowTaps) with depth.
struct GroupVelocity {
  temporal::Vec8 vx, vy, tapDepth;
};
template <class T>
__attribute__((always_inline)) inline GroupVelocity groupVelocity(const Frame<T>& f, int x0, int y,
                                                                  const RowTaps& rowTaps) {
  using Int = temporal::IntOf<temporal::Vec8>;
  GroupVelocity v;
  v.vx = v.vy = v.tapDepth = temporal::lanesOf<temporal::Vec8>(0.0f);
  if (!f.motion.ptr) return v;
  Int tap = Int{} + 4;
  if (rowTaps.tap) {
    std::memcpy(&tap, rowTaps.tap + x0, sizeof tap);
    v.tapDepth = temporal::loadLanes<temporal::Vec8>(rowTaps.depth + x0);
  }
  const int sx = f.unjitter.shiftX, sy = f.unjitter.shiftY;
  for (int l = 0; l < kBatch; ++l) {
    const float* m = f.motion.pixel(x0 + l + tap[l] % 3 - 1 - sx, y + tap[l] / 3 - 1 - sy);
    v.vx[l] = m[0];
    v.vy[l] = m[1];
  }
  return v;
}

// The 3x3 box, sum and measurement of a lane group's eight pixels, pixel by
// pixel as phlmPixel (four channels at once: RGB and the luminance). Every
// tap lies inside the image (phlmRowsBody's group rows), so none is clamped.
template <class T>
__attribute__((always_inline)) inline void groupNeighbourhood(const Frame<T>& f, int x0, int y,
                                                              temporal::Vec4 lo4[kBatch], temporal::Vec4 hi4[kBatch],
                                                              temporal::Vec4 sum4[kBatch],
                                                              temporal::Vec4 sample4[kBatch]) {
  const int w = f.width, sx = f.unjitter.shiftX, sy = f.unjitter.shiftY;
  const float* topLeft = f.staged + (std::size_t(y - 1 - sy) * w + std::size_t(x0 - 1 - sx)) * 4;
  for (int l = 0; l < kBatch; ++l) {
    temporal::Vec4 taps[9];
#pragma GCC unroll 9
    for (int i = 0; i < 9; ++i) taps[i] = temporal::load4(topLeft + (std::size_t(i / 3) * w + std::size_t(l + i % 3)) * 4);
    boxOfTaps(taps, lo4[l], hi4[l], sum4[l]);
    sample4[l] = f.unjitter.enabled ? temporal::unjitteredMix(taps, f.unjitter.weights) : taps[4];
  }
}

// phlmPixel on the eight pixels x0 .. x0 + 7 of row y at once, for what a
// moving shot's pixels mostly are: every lane moves (v), and every tap of
// their (shifted) 3x3 lies inside the image, so no tap needs a clamp. The
// same operations lane by lane as phlmPixel (lanes.h: lane-wise IEEE
// operations), so the same bits; the batch's lanes are written as vectors,
// which finishBatch then reads without waiting for eight scalar stores each.
// Moving pixels use neither the footprint box nor the hold, so those parts
// reduce to constants here.
template <class T>
__attribute__((always_inline)) inline void phlmMovingGroup(const Frame<T>& f, int x0, int y, FrameStats& stats,
                                                           Batch<T>& batch, const GroupVelocity& v) {
  using temporal::Vec4;
  using temporal::Vec8;
  using Int = temporal::IntOf<Vec8>;
  using M = temporal::MaskOfT<Vec8>;
  const int w = f.width, h = f.height;
  const Vec8 vx = v.vx, vy = v.vy, tapDepth = v.tapDepth;

  Vec4 lo4[kBatch], hi4[kBatch], sum4[kBatch], sample4[kBatch];
  groupNeighbourhood(f, x0, y, lo4, hi4, sum4, sample4);
  Vec8 boxLo[4], boxHi[4], boxSum[4], sample[4];
  temporal::transposeToLanes(lo4, boxLo);
  temporal::transposeToLanes(hi4, boxHi);
  temporal::transposeToLanes(sum4, boxSum);
  temporal::transposeToLanes(sample4, sample);

  // Validity, the nearest model q and the depth test (phlmPixel's order).
  const Vec8 px = (float(x0) + temporal::laneIndexOf<Vec8>()) + vx, py = temporal::lanesOf<Vec8>(float(y)) + vy;
  M valid = f.hasHistory ? M(temporal::finiteOf(vx) & temporal::finiteOf(vy) & M(px >= -0.5f) & M(py >= -0.5f) &
                             M(px <= float(w) - 0.5f) & M(py <= float(h) - 0.5f))
                         : M{};
  const Vec8 zero = temporal::lanesOf<Vec8>(0.0f);
  const Vec8 safeX = valid ? px : zero, safeY = valid ? py : zero;  // other lanes: harmless
  const Int last = Int{} + (w - 1), lastRow = Int{} + (h - 1);
  Int qx = temporal::truncOf(temporal::floorExact(safeX + 0.5f)), qy = temporal::truncOf(temporal::floorExact(safeY + 0.5f));
  qx = qx < 0 ? Int{} : (last < qx ? last : qx);
  qy = qy < 0 ? Int{} : (lastRow < qy ? lastRow : qy);
  if (f.previousDepth && temporal::anyOf(valid)) {
    if (temporal::sharedInteriorOffset<Vec8>(qx, qy, valid, -1, 1, -1, 1, w, h)) {
      const float* around = f.previousDepth + std::size_t(qy[0] - 1) * w + (qx[0] - 1);
      M match{};
      for (int i = 0; i < 9; ++i)
        match |= temporal::sameSurfaceDepth(tapDepth, temporal::loadLanes<Vec8>(around + std::size_t(i / 3) * w + i % 3),
                                            f.depthTolerance);
      valid &= match;
    } else {
      for (int l = 0; l < kBatch; ++l)
        if (valid[l] && !followedSurfaceAround(f, qx[l], qy[l], tapDepth[l])) valid[l] = 0;
    }
  }

  // Moving: the 3x3 box from now on ("Box"), no hold, the still count restarts (1 after a reset).
  const std::size_t row = std::size_t(y) * w + x0;
  if (f.narrowBox) std::memset(f.narrowBox + row, 1, kBatch);
  temporal::storeBytesOf<Vec8>(f.stillSamples + row, valid ? Int{} : Int{} + 1);
  if (f.release.words) {  // nothing stands still: the windows restart
    const Int restarted = Int{} + int(temporal::holdWindowRestarted(f.release.windowEnd));
    temporal::storeHoldWords<Vec8>(f.release.words + row, restarted);
  }

  // The batch, as phlmPixel leaves it after its eight pixels.
  batch.x0 = x0;
  batch.y = y;
  batch.anyHeld = false;
  const bool allValid = temporal::allOf(valid);
  batch.allValid = batch.allBilinear = allValid;
  batch.anyBilinear = temporal::anyOf(valid);
  const Vec8 fx = temporal::floorExact(safeX), fy = temporal::floorExact(safeY);
  const Int footX = valid ? temporal::truncOf(fx) : Int{}, footY = valid ? temporal::truncOf(fy) : Int{};
  const Vec8 tx = valid ? safeX - fx : zero, ty = valid ? safeY - fy : zero;
  std::memcpy(batch.footX, &footX, sizeof footX);
  std::memcpy(batch.footY, &footY, sizeof footY);
  temporal::storeLanes(batch.tx, tx);
  temporal::storeLanes(batch.ty, ty);
  for (int l = 0; l < kBatch; ++l) stats.reprojectionResets += valid[l] == 0;
  // Where each lane reads (phlm.h paddedPixel; read only for valid lanes), as
  // int lanes: phlmRowsBody runs groups only where every padded index fits.
  const int rowPixels = f.blocksPerRow * kBatch;
  auto clampTo = [](Int v, int hi) __attribute__((always_inline)) { return v < 0 ? Int{} : (hi < v ? Int{} + hi : v); };
  const Int xa = clampTo(footX, w - 1), xb = clampTo(footX + 1, w - 1);
  const Int ya = clampTo(footY, h - 1) * rowPixels, yb = clampTo(footY + 1, h - 1) * rowPixels;
  storeIndices(batch.source, qy * rowPixels + qx);
  storeIndices(batch.tap[0], ya + xa);
  storeIndices(batch.tap[1], ya + xb);
  storeIndices(batch.tap[2], yb + xa);
  storeIndices(batch.tap[3], yb + xb);
  const Vec8 one = temporal::lanesOf<Vec8>(1.0f);
  for (int c = 0; c < 3; ++c) {
    batch.sum[c] = boxSum[c];
    batch.current[c] = sample[c];
    batch.lo[c] = temporal::minOf(boxLo[c], sample[c]);  // phlmPixel's vmin(lo4, sample)
    batch.hi[c] = temporal::maxOf(boxHi[c], sample[c]);
  }
  batch.yMin = boxLo[3];
  batch.yMax = boxHi[3];
  batch.speed = valid ? temporal::sqrtOf(vx * vx + vy * vy) : zero;
  batch.valid = valid ? one : zero;
  batch.moving = one;
  batch.held = zero;
  batch.count = kBatch;
}

// phlmPixel on the eight pixels x0 .. x0 + 7 of row y at once where none
// moves (a still camera's background; every pixel of a still scene), with
// the taps inside the image as in phlmMovingGroup; the same bits. A still
// pixel's model is its own (q = p), so it needs no fetch footprint; what
// remains per pixel is the 3x3 and the footprint box. The byte planes (the
// narrow box, the still count) are read and written a lane group at a time.
// Needs the row's still footprints (rowTaps.still) with motion.
template <class T>
__attribute__((always_inline)) inline void phlmStillGroup(const Frame<T>& f, int x0, int y, FrameStats& stats,
                                                          Batch<T>& batch, const RowTaps& rowTaps,
                                                          const GroupVelocity& v) {
  using temporal::Vec4;
  using temporal::Vec8;
  using Int = temporal::IntOf<Vec8>;
  using M = temporal::MaskOfT<Vec8>;
  const int w = f.width;
  const std::size_t row = std::size_t(y) * w + x0;
  const M all = M{} == M{};

  // Validity: history, and the followed surface in the previous 3x3 of the
  // pixel itself (q = p: an interior 3x3, read as lanes).
  M valid = f.hasHistory ? all : M{};
  if (f.previousDepth && f.hasHistory) {
    const float* around = f.previousDepth + std::size_t(y - 1) * w + (x0 - 1);
    M match{};
    for (int i = 0; i < 9; ++i)
      match |= temporal::sameSurfaceDepth(v.tapDepth, temporal::loadLanes<Vec8>(around + std::size_t(i / 3) * w + i % 3),
                                          f.depthTolerance);
    if (!temporal::allOf(match))
      for (int l = 0; l < kBatch; ++l)
        if (!match[l] && stillSurfaceNear(f, x0 + l, y)) match[l] = -1;
    valid &= match;
  }
  // Nothing in the 5x5 moves (always, without motion); the narrow box; the
  // hold (phlmPixel's order and rules).
  const M stillAround = rowTaps.still ? M(temporal::loadBytesOf<Vec8>(rowTaps.still->of(f, y) + x0) != 0) : all;
  Vec4 lo4[kBatch], hi4[kBatch], sum4[kBatch], sample4[kBatch];
  groupNeighbourhood(f, x0, y, lo4, hi4, sum4, sample4);
  Vec8 sample[4];
  temporal::transposeToLanes(sample4, sample);
  M released{};
  if (f.release.words) {  // the release (phlmPixel's order and rules)
    const M still = valid & stillAround;
    const Int word = temporal::stepHoldWindow<Vec8>(temporal::loadHoldWords<Vec8>(f.release.words + row),
                                                    temporal::holdLumaOfTonemapped(sample[3]), still,
                                                    f.release.windowEnd, f.release.limit, released);
    temporal::storeHoldWords<Vec8>(f.release.words + row, word);
    valid &= ~released;
  }
  M narrow{};
  if (f.narrowBox) {
    narrow = valid & M(temporal::loadBytesOf<Vec8>(f.narrowBox + row) != 0);
    temporal::storeBytesOf<Vec8>(f.narrowBox + row, M(narrow | ~stillAround) & 1);
  }
  const Int count = temporal::loadBytesOf<Vec8>(f.stillSamples + row);
  const M calm = valid & stillAround;
  const M held = f.holdPeriod > 0 ? M(calm & M(count >= f.holdPeriod)) : M{};
  const Int kept = M(held | M(count == 255)) ? count : count + 1;
  temporal::storeBytesOf<Vec8>(f.stillSamples + row, valid ? (calm ? kept : Int{}) : Int{} + 1);

  // The boxes, pixel by pixel: the footprint box where phlmPixel takes it,
  // then united with the measurement; lane 3 keeps the 3x3's luminance
  // extreme (yMin, yMax).
  const M footprint = f.footprintBox ? M(~narrow & stillAround) : M{};
  for (int l = 0; l < kBatch; ++l) {
    Vec4 lo = lo4[l], hi = hi4[l];
    if (footprint[l]) {
      const temporal::MinMax4 foot = temporal::footprintBox({lo, hi}, rowTaps.footprint->of(f, x0 + l, y));
      lo = foot.min;
      hi = foot.max;
    }
    lo4[l] = __builtin_shufflevector(temporal::vmin(lo, sample4[l]), lo4[l], 0, 1, 2, 7);
    hi4[l] = __builtin_shufflevector(temporal::vmax(hi, sample4[l]), hi4[l], 0, 1, 2, 7);
  }
  Vec8 lo[4], hi[4], sum[4];
  temporal::transposeToLanes(lo4, lo);
  temporal::transposeToLanes(hi4, hi);
  temporal::transposeToLanes(sum4, sum);

  // The batch, as phlmPixel leaves it after its eight pixels.
  batch.x0 = x0;
  batch.y = y;
  batch.allValid = temporal::allOf(valid);
  batch.allBilinear = batch.anyBilinear = false;
  batch.anyHeld = temporal::anyOf(held);
  for (int l = 0; l < kBatch; ++l) {
    batch.source[l] = paddedPixel(f.blocksPerRow, x0 + l, y);
    batch.tx[l] = batch.ty[l] = 0.0f;
    batch.footX[l] = batch.footY[l] = 0;
    stats.releases += released[l] != 0;
    stats.reprojectionResets += valid[l] == 0 && released[l] == 0;
  }
  const Vec8 one = temporal::lanesOf<Vec8>(1.0f), zero = temporal::lanesOf<Vec8>(0.0f);
  for (int c = 0; c < 3; ++c) {
    batch.sum[c] = sum[c];
    batch.current[c] = sample[c];
    batch.lo[c] = lo[c];
    batch.hi[c] = hi[c];
  }
  batch.yMin = lo[3];
  batch.yMax = hi[3];
  batch.speed = zero;
  batch.valid = valid ? one : zero;
  batch.moving = zero;
  batch.held = held ? one : zero;
  batch.count = kBatch;
}

// A lane group of row y at x0 as one batch (phlmMovingGroup or
// phlmStillGroup) where its lanes all move or all stand still; false,
// having changed nothing, where they mix (or the kind has no group here):
// the caller then runs phlmPixel on the eight.
template <class T>
__attribute__((always_inline)) inline bool phlmGroup(const Frame<T>& f, int x0, int y, FrameStats& stats,
                                                     Batch<T>& batch, const RowTaps& rowTaps, bool movingGroups,
                                                     bool stillGroups) {
  using M = temporal::MaskOfT<temporal::Vec8>;
  const GroupVelocity v = groupVelocity(f, x0, y, rowTaps);
  const M moves = M(v.vx != 0.0f) | M(v.vy != 0.0f);  // phlmPixel's `moving`
  if (movingGroups && temporal::allOf(moves)) {
    phlmMovingGroup(f, x0, y, stats, batch, v);
    return true;
  }
  if (stillGroups && !temporal::anyOf(moves)) {
    phlmStillGroup(f, x0, y, stats, batch, rowTaps, v);
    return true;
  }
  return false;
}

// A scalar broadcast to every lane.
template <class V, class T>
CRISP_PHLM_INLINE V splatOf(T v) {
  return V{} + v;
}

// kBatch scalars to and from lanes (any alignment).
template <class V, class T>
CRISP_PHLM_INLINE V loadLanes(const T* p) {
  V v;
  std::memcpy(&v, p, sizeof v);
  return v;
}
template <class V, class T>
CRISP_PHLM_INLINE void storeLanes(T* p, const V& v) {
  std::memcpy(p, &v, sizeof v);
}
// The same to a buffer this frame does not read again (the next records with
// motion, 16-byte aligned: phlm.h's AlignedVector and whole blocks): a
// streaming store, which skips reading the line in first. At 1920x1080 the
// records and intercepts written per frame are 230 MB. (With float, every
// other block and every intercept store ends mid-line; the next batch
// completes the line.)
template <class V, class T>
CRISP_PHLM_INLINE void streamLanes(T* p, const V& v) {
#if defined(__SSE2__)
  static_assert(sizeof v % 16 == 0);
  for (std::size_t k = 0; k < sizeof v / 16; ++k) {
    __m128 q;
    std::memcpy(&q, reinterpret_cast<const char*>(&v) + 16 * k, 16);
    _mm_stream_ps(reinterpret_cast<float*>(reinterpret_cast<char*>(p) + 16 * k), q);
  }
#else
  storeLanes(p, v);
#endif
}
template <class V, class T>
CRISP_PHLM_INLINE void putLanes(T* p, const V& v, bool stream) {
  if (stream)
    streamLanes(p, v);
  else
    storeLanes(p, v);
}

// Scalar j of the kBatch consecutive pixels from `first` (padded): one block's
// vector, or the tail of one block's and the head of the next one's (blocks
// follow each other in memory, across rows too).
template <class V, class T>
CRISP_PHLM_INLINE V loadRun(const T* records, std::size_t first, int j) {
  const T* block = records + first / kBlock * (kRecord * kBlock) + j * kBatch;
  const int shift = int(first % kBlock);
  const V a = loadLanes<V>(block);
  if (shift == 0) return a;
  const V b = loadLanes<V>(block + kRecord * kBlock);
#if defined(__GNUC__) && !defined(__clang__)
  using M = typename LanesOf<T>::M;
  M lanes;
  for (int i = 0; i < kBatch; ++i) lanes[i] = i;  // a constant, plus one broadcast
  return __builtin_shuffle(a, b, lanes + shift);
#else
  // Clang (the fuzzing build) has no run-time-mask shuffle: the same values through memory.
  T both[2 * kBatch];
  storeLanes(both, a);
  storeLanes(both + kBatch, b);
  return loadLanes<V>(both + shift);
#endif
}

// The records a batch reads lie block after block along the row, 800 bytes
// (float) a block, so a batch enters a new 4 KB page every five blocks,
// where the hardware prefetcher stops: the block kPrefetchBlocks ahead of the
// pixel `from` (padded) is asked for in advance. Measured (crisp_bench
// phlm.fast.mt, 1920x1080): 61.2 -> 57.3 ms at 4 blocks ahead (2: 57.9, 8: 58.9).
constexpr std::size_t kPrefetchBlocks = 4;
template <class T>
CRISP_PHLM_INLINE void prefetchRecordsAhead(const Frame<T>& f, std::size_t from) {
  const std::size_t ahead = from / kBlock + kPrefetchBlocks;
  if (ahead >= std::size_t(f.height) * std::size_t(f.blocksPerRow)) return;
  const char* block = reinterpret_cast<const char*>(f.previous + ahead * (kRecord * kBlock));
  for (std::size_t b = 0; b < kRecord * kBlock * sizeof(T); b += 64) __builtin_prefetch(block + b);
}

// kBatch floats as lanes of V (exact: float to float or double).
template <class V>
CRISP_PHLM_INLINE V floatLanes(const float* p) {
  typedef float F __attribute__((vector_size(kBatch * sizeof(float))));
  return __builtin_convertvector(loadLanes<F>(p), V);
}

// std::max, std::min, std::clamp and |a| lane by lane: temporal/lanes.h.
using temporal::absOf;
using temporal::clampOf;
using temporal::maxOf;
using temporal::minOf;

// Lines 13-17 of Algorithm 1 on the axis-aligned box [lo, hi] (which contains
// y): the smallest t in [0, 1] with f + t (y - f) inside the box (0 = inside).
// The inside test allows a slack of 1e-3 of the box extent plus 1e-5 of the
// colour's magnitude: y itself is often a corner of its box, and a prediction
// that equals y up to rounding must not reset the model in one precision and
// not in the other (the float32 and float64 paths would part ways). The
// output is clamped to the exact box afterwards.
// Lane by lane: both quotients are computed, each lane keeps the one its
// branch needs.
template <class T, class V>
CRISP_PHLM_INLINE V rayEntryOf(const V f[3], const V y[3], const V lo[3], const V hi[3]) {
  V t = zeroOf<V>();
  for (int c = 0; c < 3; ++c) {
    const V magnitude = maxOf(absOf(lo[c]), absOf(hi[c]));
    const V slack = T(1e-3) * (hi[c] - lo[c]) + T(1e-5) * magnitude;
    const V below = maxOf(t, (lo[c] - f[c]) / (y[c] - f[c]));
    const V above = maxOf(t, (f[c] - hi[c]) / (f[c] - y[c]));
    t = f[c] < lo[c] - slack ? below : (f[c] > hi[c] + slack ? above : t);
  }
  return minOf(t, oneOf<V>());
}

// The forgetting and regulariser of Step 5 on every lane (phlm_rls.h; header,
// "Stabilised RLS"): a moving pixel forgets with lambdaMoving and refreshes
// every axis, a still one forgets with lambda and refreshes this frame's axis.
template <class T, class V>
CRISP_PHLM_INLINE void forgetAndRegularise(const Frame<T>& f, const Batch<T>& batch, V* m, bool moving) {
  if (moving) {
    // Every axis each moving frame, with information (1 - lm) / P0_kk (with
    // two lambdas the 4-frame cycle alone no longer bounds P, "Forgetting").
    // Per lane lm = lambdaMoving (1 - beta s), s = max(4 tx (1 - tx), 4 ty (1 - ty))
    // of the bilinear fetch's fractions (0 for still lanes, whose U and D the
    // caller takes from the still branch; lm = lambdaMoving exactly when beta
    // = 0). c(lm) = (1 - lm) / (1 - lm lambda^3) grows as lm falls, so the
    // bound holds.
    const V tx = floatLanes<V>(batch.tx), ty = floatLanes<V>(batch.ty);
    const V s = maxOf(T(4) * tx * (T(1) - tx), T(4) * ty * (T(1) - ty));  // std::max lane by lane
    const V lm = splatOf<V>(f.lambdaMoving) * (oneOf<V>() - splatOf<V>(f.resampleDamping) * s);
    forget(m, oneOf<V>() / lm);
    auto refresh = [&](auto axis) __attribute__((always_inline)) {
      const V variance = splatOf<V>(f.p0Diagonal[axis]) / (oneOf<V>() - lm);
      regularise<decltype(axis)::value>(m, variance, oneOf<V>() / variance);
    };
    refresh(std::integral_constant<int, 0>{});
    refresh(std::integral_constant<int, 1>{});
    refresh(std::integral_constant<int, 2>{});
    refresh(std::integral_constant<int, 3>{});
  } else {
    forget(m, splatOf<V>(f.inverseLambda));
    regularise(m, f.axis, splatOf<V>(f.regulariserVariance[f.axis]),
               splatOf<V>(f.regulariserWeight[f.axis]));
  }
}

// The intercepts beta[0][c] of the moving lanes (bilinearLanes) by Catmull-Rom
// over the 4x4 around the bilinear footprint, clamp to edge, each clamped to
// the range of its 4 central taps (header, "Model fetch"; the filter and
// clamp of taa's history fetch, temporal/history_fetch.h). Read from the
// planes f.intercepts (Kernel::run), where a tap of 8 consecutive pixels is
// one unaligned load: a whole batch of moving lanes whose footprints are
// consecutive and interior loads each tap so; otherwise lane by lane (other
// lanes read 0). The reference path gathers every tap from the records
// themselves, so comparing the paths checks the planes too. Lane by lane the
// same operations either way, so the same bits.
template <class T, class V, class M>
CRISP_PHLM_INLINE void fetchInterceptsCatmullRom(const Frame<T>& f, const Batch<T>& batch, V tx, V ty,
                                                 M bilinearLanes, V* m) {
  const int n = batch.count;
  bool run = !f.reference && n == kBatch && batch.allBilinear;
  for (int i = 1; i < kBatch && run; ++i)
    run = batch.footX[i] == batch.footX[0] + i && batch.footY[i] == batch.footY[0];
  run = run && batch.footX[0] >= 1 && batch.footX[0] + kBatch + 1 < f.width && batch.footY[0] >= 1 &&
        batch.footY[0] + 2 < f.height;
  V wx[4], wy[4];
  temporal::catmullRomWeights(tx, wx);
  temporal::catmullRomWeights(ty, wy);
  // Off the run, each lane's 16 taps per plane are gathered first (other
  // lanes read 0); on it, a tap of the 8 lanes is one unaligned load.
  alignas(sizeof(V)) T gathered[3][4][4][kBatch];
  if (!run) {
    for (int i = 0; i < kBatch; ++i) {
      const int from = i < n ? i : 0;
      const bool read = batch.valid[from] != T(0) && batch.moving[from] != T(0);
      for (int j = 0; j < 4; ++j) {
        const int y = std::clamp(batch.footY[from] - 1 + j, 0, f.height - 1);
        for (int k = 0; k < 4; ++k) {
          const int x = std::clamp(batch.footX[from] - 1 + k, 0, f.width - 1);
          const T* record = f.previous + recordIndex(f.blocksPerRow, x, y);
          for (int c = 0; c < 3; ++c) {
            const T* plane = interceptRow(f.intercepts, f.blocksPerRow, c, y);
            const T value = f.reference ? record[(kBeta + c) * kBatch] : plane[x];
            gathered[c][j][k][i] = read ? value : T(0);
          }
        }
      }
    }
  }
  for (int c = 0; c < 3; ++c) {
    V acc = zeroOf<V>(), lo = zeroOf<V>(), hi = zeroOf<V>();
    for (int j = 0; j < 4; ++j) {
      V tap[4];
      if (run) {
        const T* first = interceptRow(f.intercepts, f.blocksPerRow, c, batch.footY[0] - 1 + j) + batch.footX[0] - 1;
        for (int k = 0; k < 4; ++k) tap[k] = loadLanes<V>(first + k);
      } else {
        for (int k = 0; k < 4; ++k) tap[k] = loadLanes<V>(gathered[c][j][k]);
      }
      temporal::addCatmullRomRow(tap, wx, wy[j], j, acc, lo, hi);
    }
    m[kBeta + c] = bilinearLanes ? temporal::catmullRomClamped(acc, lo, hi) : m[kBeta + c];
  }
}

// The rest of step 2 and steps 4-5 for the batch's pixels, eight at once:
// lane i performs the scalar operations of pixel x0 + i in the scalar order,
// so every path (and the float64 kernel, lane type double) gives the bits of
// the one-pixel form. Output beta' x = f + g e (clamped to the box: only
// rounding and the inside-test slack can reach past it). Writes the records
// and the output; counts the box corrections and the guards that fired
// (FrameStats) in `stats`.
template <class T>
CRISP_PHLM_INLINE void finishBatch(const Frame<T>& f, Batch<T>& batch, FrameStats& stats) {
  using V = typename Batch<T>::V;
  using M = typename Batch<T>::M;
  const int n = batch.count;
  // Unused lanes repeat lane 0 (finite, harmless values; written to the
  // row's padding records only). What follows reads every lane of these
  // arrays as vectors (floatLanes of tx, ty) and relies on that.
  for (int i = n; i < kBatch; ++i) {
    for (int c = 0; c < 3; ++c) {
      batch.sum[c][i] = batch.sum[c][0];
      batch.current[c][i] = batch.current[c][0];
      batch.lo[c][i] = batch.lo[c][0];
      batch.hi[c][i] = batch.hi[c][0];
    }
    batch.yMin[i] = batch.yMin[0];
    batch.yMax[i] = batch.yMax[0];
    batch.speed[i] = batch.speed[0];
    batch.valid[i] = batch.valid[0];
    batch.moving[i] = batch.moving[0];
    batch.held[i] = batch.held[0];
    batch.tx[i] = batch.tx[0];
    batch.ty[i] = batch.ty[0];
    batch.footX[i] = batch.footX[0];
    batch.footY[i] = batch.footY[0];
  }
  // Step 3: the model of q = pi(v) (beta, U, D) and the feature history,
  // lane i from recordIndex (the record layout is the batch's: scalar j of
  // the kBatch pixels of a block is one vector). Reset lanes: the reset model
  // (lines 7-9 / §6) and history 0.
  const M validLanes = batch.valid != zeroOf<V>();
  if (!f.reference)  // lane 0's model (source[] is set for valid lanes only), else the batch's own
    prefetchRecordsAhead(f, validLanes[0] ? batch.source[0] : paddedPixel(f.blocksPerRow, batch.x0, batch.y));
  V m[kZ], history[3];
  auto anyValid = [&validLanes] {
    bool any = false;
    for (int i = 0; i < kBatch; ++i) any |= validLanes[i] != 0;
    return any;
  };
  if (n == kBatch && batch.allValid && isRun(batch.source)) {
    // Lanes reading consecutive records (a still block reads its own; a
    // uniform motion a shifted run): whole vectors (loadRun).
    for (int j = 0; j < kZ; ++j) m[j] = loadRun<V>(f.previous, batch.source[0], j);
    for (int c = 0; c < 3; ++c) history[c] = loadRun<V>(f.previous, batch.source[0], kZ + c);
  } else if (!anyValid()) {
    // No lane reprojected (a first frame, a cut): what the gather below
    // leaves, without its scalar stores (a vector load of eight of them
    // waits for them all).
    for (int c = 0; c < 3; ++c) history[c] = zeroOf<V>();
    resetModel(m, batch.current, splatOf<V>(f.p0), splatOf<V>(f.ps));
  } else {
    alignas(sizeof(V)) T gathered[kRecord][kBatch];
    for (int i = 0; i < kBatch; ++i) {
      const int from = i < n ? i : 0;
      if (batch.valid[from] != T(0)) {
        const T* source = f.previous + recordIndexOf(batch.source[from]);
        for (int j = 0; j < kRecord; ++j) gathered[j][i] = source[j * kBatch];
      } else {
        for (int j = 0; j < kRecord; ++j) gathered[j][i] = T(0);
      }
    }
    for (int j = 0; j < kZ; ++j) m[j] = loadLanes<V>(gathered[j]);
    for (int c = 0; c < 3; ++c) history[c] = loadLanes<V>(gathered[kZ + c]);
    V reset[kZ];
    resetModel(reset, batch.current, splatOf<V>(f.p0), splatOf<V>(f.ps));
    for (int j = 0; j < kZ; ++j) m[j] = validLanes ? m[j] : reset[j];
  }
  if (batch.anyBilinear) {
    // Moving lanes: the feature (and beta with bilinearBeta: the blended
    // model predicts the bilinear blend of the four models' predictions, §6:
    // models live in textures read with bilinear filtering; P stays the
    // nearest model's) from the bilinear footprint, clamp to edge. With
    // catmullRomIntercepts the intercepts come from fetchInterceptsCatmullRom
    // instead (header, "Model fetch").
    const int firstBeta = f.catmullRomIntercepts ? 3 : 0;  // beta's scalars fetched here: firstBeta .. 11
    const int planes = f.bilinearBeta ? 15 - firstBeta : 3;  // plane p: z (p < 3), then beta (if bilinear)
    auto planeOf = [firstBeta](int p) { return p < 3 ? kZ + p : kBeta + firstBeta + p - 3; };
    const V tx = floatLanes<V>(batch.tx), ty = floatLanes<V>(batch.ty);
    V taps[4][15];
    for (int k = 0; k < 4; ++k) {
      if (n == kBatch && batch.allBilinear && isRun(batch.tap[k])) {
        for (int p = 0; p < planes; ++p) taps[k][p] = loadRun<V>(f.previous, batch.tap[k][0], planeOf(p));
      } else {
        alignas(sizeof(V)) T gathered[15][kBatch];  // other lanes: zeros
        for (int i = 0; i < kBatch; ++i) {
          const int from = i < n ? i : 0;
          if (batch.valid[from] != T(0) && batch.moving[from] != T(0)) {
            const T* source = f.previous + recordIndexOf(batch.tap[k][from]);
            for (int p = 0; p < planes; ++p) gathered[p][i] = source[planeOf(p) * kBatch];
          } else {
            for (int p = 0; p < planes; ++p) gathered[p][i] = T(0);
          }
        }
        for (int p = 0; p < planes; ++p) taps[k][p] = loadLanes<V>(gathered[p]);
      }
    }
    const M bilinearLanes = validLanes & (batch.moving != zeroOf<V>());
    for (int p = 0; p < planes; ++p) {
      const V top = taps[0][p] + (taps[1][p] - taps[0][p]) * tx;
      const V bottom = taps[2][p] + (taps[3][p] - taps[2][p]) * tx;
      const V blended = top + (bottom - top) * ty;
      V& target = p < 3 ? history[p] : m[kBeta + firstBeta + p - 3];
      target = bilinearLanes ? blended : target;
    }
    if (f.catmullRomIntercepts) fetchInterceptsCatmullRom(f, batch, tx, ty, bilinearLanes, m);
  }
  // Step 2 (§5.1, eq. 1): z = history + alpha (low-frequency colour - history),
  // alpha = phi / (l + Delta) in [featureAlphaMin, 1]; z = y after a reset.
  V z[3];
  {
    const V featureLuma = lumaYCgCo<T>(history);
    const V l = maxOf(zeroOf<V>(), maxOf(batch.yMin - featureLuma, featureLuma - batch.yMax));
    const V delta = batch.yMax - batch.yMin;
    const V phi = f.featureA * l * l + f.featureB * batch.speed * l * l * l;
    const V alpha = clampOf(phi / (l + delta + T(1e-6)), splatOf<V>(f.featureAlphaMin), oneOf<V>());
    V average[3], lowFrequency[3], reset[3];
    for (int c = 0; c < 3; ++c) average[c] = batch.sum[c] * T(1.0 / 9.0);
    toFeature<T>(average, lowFrequency);
    toFeature<T>(batch.current, reset);
    for (int c = 0; c < 3; ++c) z[c] = validLanes ? history[c] + (lowFrequency[c] - history[c]) * alpha : reset[c];
    if (batch.anyHeld) {
      const M heldLanes = batch.held != zeroOf<V>();
      for (int c = 0; c < 3; ++c) z[c] = heldLanes ? history[c] : z[c];
    }
  }
  // Step 4: prediction and box correction (lines 12-19).
  const V x4[kDims] = {oneOf<V>(), z[0], z[1], z[2]};
  V predicted[3];
  predict(m, x4, predicted);
  M finite = (predicted[0] - predicted[0]) == zeroOf<V>();  // std::isfinite
  finite &= (predicted[1] - predicted[1]) == zeroOf<V>();
  finite &= (predicted[2] - predicted[2]) == zeroOf<V>();
  const V t = finite ? rayEntryOf<T>(predicted, batch.current, batch.lo, batch.hi) : oneOf<V>();
  const M corrected = t > zeroOf<V>();
  bool anyCorrected = false;
  for (int i = 0; i < n; ++i)
    if (corrected[i]) {
      anyCorrected = true;
      ++stats.boxResets;
      const std::size_t pixel = std::size_t(batch.y) * std::size_t(f.width) + std::size_t(batch.x0 + i);
      if (f.narrowBox) f.narrowBox[pixel] = 1;
      if (f.stillSamples[pixel] != 0) f.stillSamples[pixel] = 1;  // the model restarts from the corrected value
      // and so do its windows: the correction took the change in, no release needed ("Hold").
      if (f.release.words) f.release.words[pixel] = temporal::holdWindowRestarted(f.release.windowEnd);
    }
  if (anyCorrected) {
    // Lines 14-18: onto the box along the ray toward y, the model reset there.
    for (int c = 0; c < 3; ++c) {
      const V onBox = clampOf(predicted[c] + t * (batch.current[c] - predicted[c]), batch.lo[c], batch.hi[c]);
      predicted[c] = corrected ? (finite ? onBox : batch.current[c]) : predicted[c];
    }
    V reset[kZ];
    resetModel(reset, predicted, splatOf<V>(f.p0 * f.boxResetScale), splatOf<V>(f.ps * f.boxResetScale));
    for (int j = 0; j < kZ; ++j) m[j] = corrected ? reset[j] : m[j];
  }

  // Step 5 (held lanes that were not corrected keep their model, below;
  // a batch of such lanes only: nothing to compute, and in place nothing to
  // store).
  const M keptLanes = batch.anyHeld ? (batch.held != zeroOf<V>()) & ~corrected : corrected & 0;
  bool allKept = batch.anyHeld;
  for (int i = 0; i < kBatch && allKept; ++i) allKept = keptLanes[i] != 0;
  V out[3];
  M overflow = keptLanes & 0;
  if (allKept) {
    for (int c = 0; c < 3; ++c) out[c] = clampOf(predicted[c], batch.lo[c], batch.hi[c]);
  } else {
    V kept[kZ];
    if (batch.anyHeld)
      for (int j = 0; j < kZ; ++j) kept[j] = m[j];
    const M movingLanes = batch.moving != zeroOf<V>();
    bool anyMoving = false, anyStill = false;
    for (int i = 0; i < kBatch; ++i) (movingLanes[i] ? anyMoving : anyStill) = true;
    if (anyMoving && anyStill) {
      V still[kZ];  // U and D of the still lanes (beta is not touched)
      for (int j = kU; j < kZ; ++j) still[j] = m[j];
      forgetAndRegularise(f, batch, m, true);
      forgetAndRegularise(f, batch, still, false);
      for (int j = kU; j < kZ; ++j) m[j] = movingLanes ? m[j] : still[j];
    } else {
      forgetAndRegularise(f, batch, m, anyMoving);
    }
    for (int c = 0; c < 3; ++c) out[c] = predicted[c];
    if (f.update) {
      V e[3];
      for (int c = 0; c < 3; ++c) e[c] = batch.current[c] - predicted[c];
      const V g = rlsUpdate(m, x4, e, splatOf<V>(f.sampleVariance), splatOf<V>(f.sampleWeight));
      for (int c = 0; c < 3; ++c) {
        const V v = predicted[c] + g * e[c];
        out[c] = v < batch.lo[c] ? batch.lo[c] : (batch.hi[c] < v ? batch.hi[c] : v);  // std::clamp
      }
      // Guard: beta can only become non-finite through an overflow; restart from the output.
      V check = zeroOf<V>();
      for (int i = 0; i < 12; ++i) check += m[kBeta + i] * T(0);
      overflow = check != zeroOf<V>();  // also NaN
    }
    if (batch.anyHeld) {
      for (int j = 0; j < kZ; ++j) m[j] = keptLanes ? kept[j] : m[j];
      for (int c = 0; c < 3; ++c) {
        const V v = clampOf(predicted[c], batch.lo[c], batch.hi[c]);
        out[c] = keptLanes ? v : out[c];
      }
      overflow &= ~keptLanes;
    }
  }
  // The records: the block at (x0, y), every lane (lanes past the row's end
  // land in the row's padding); a lane whose beta overflowed restarts from
  // its output. Held lanes only, in place: the records are unchanged.
  if (!allKept || f.next != f.previous) {
    V restart[kZ];
    resetModel(restart, out, splatOf<V>(f.p0), splatOf<V>(f.ps));
    T* block = f.next + recordIndex(f.blocksPerRow, batch.x0, batch.y);
    // Records: in place (still scene) the lines were just read, so cached
    // stores; with motion, on a large frame, streamed (Frame::streamNext).
    for (int j = 0; j < kZ; ++j) putLanes(block + j * kBatch, V(overflow ? restart[j] : m[j]), f.streamNext);
    for (int c = 0; c < 3; ++c) putLanes(block + (kZ + c) * kBatch, z[c], f.streamNext);
    if (f.interceptsNext)
      for (int c = 0; c < 3; ++c)
        putLanes(interceptRow(f.interceptsNext, f.blocksPerRow, c, batch.y) + batch.x0,
                 V(overflow ? restart[kBeta + c] : m[kBeta + c]), f.streamNext);
  }
  // The guards (FrameStats::guards): a non-finite prediction, an overflowed
  // beta, an output that needs the sanitise below to be finite.
  M guarded = overflow | ~finite;
  for (int c = 0; c < 3; ++c) guarded |= (out[c] - out[c]) != zeroOf<V>();
  for (int i = 0; i < n; ++i) stats.guards += guarded[i] != 0;
  // sanitizeColor on all lanes at once (sanitizeColorLanes: the same values), then pixel by pixel.
  const int y = batch.y;
  using F = typename LanesOf<float>::V;
  F rgb[3];
  for (int c = 0; c < 3; ++c) rgb[c] = sanitizeColorLanes(F(__builtin_convertvector(out[c], F)));
  const bool alphaOut = f.output.channels() > 3, alphaIn = f.color.channels() > 3 && !f.alphaOne[y];
  if (n == kBatch && alphaOut && !alphaIn && f.output.pixelStride == 4 * sizeof(float)) {
    temporal::storeInterleaved4(f.output.pixel(batch.x0, y), rgb[0], rgb[1], rgb[2], temporal::lanesOf<F>(1.0f));
  } else {
    for (int i = 0; i < n; ++i) {
      const int x = batch.x0 + i;
      float* o = f.output.pixel(x, y);
      o[0] = rgb[0][i];
      o[1] = rgb[1][i];
      o[2] = rgb[2][i];
      if (alphaOut) o[3] = alphaIn ? sanitizeColor(f.color.pixel(x, y)[3]) : 1.0f;
    }
  }
  batch.count = 0;
}

// Rows [y0, y1), counting the resets per row; two copies (temporal/isa.h).
template <class T, bool Groups>
__attribute__((always_inline)) inline void phlmRowsBody(const Frame<T>& f, int y0, int y1, bool reference,
                                                        FrameStats* rowStats) {
  for (int y = y0; y < y1; ++y) rowStats[y] = {};
  Batch<T> batch;
  const bool clampAll = reference || f.unjitter.shiftX != 0 || f.unjitter.shiftY != 0;
  // Step 1's closest-depth taps, a row at a time on the fast path (the
  // reference keeps closestDepthTap per pixel, so the tests compare the two):
  // the row's three depth rows staged with the taps' clamp (shiftedSource,
  // the same taps as phlmPixel's, interior or not), padded by one pixel.
  const int w = f.width, h = f.height;
  const bool tapsAhead = !reference && f.motion.ptr && f.depth;
  std::vector<float> depthRows, taps;
  RowTaps rowTaps;
  if (tapsAhead) {
    depthRows.resize(std::size_t(3) * (w + 2));
    taps.resize(std::size_t(2) * w);
    rowTaps.tap = taps.data();
    rowTaps.depth = taps.data() + w;
  }
  // The still footprints a row at a time on the fast path (StillRow); the
  // reference tests each pixel's 5x5.
  StillRow stillRow;
  if (f.movingFlags) rowTaps.still = &stillRow;
  FootprintRow footprintRow;
  if (!reference) rowTaps.footprint = &footprintRow;
  const int sx = f.unjitter.shiftX;
  const temporal::UnclampedRun run = temporal::unclampedRun(w, sx);
  auto stageTaps = [&](int y) __attribute__((always_inline)) {  // inlined: compiled for each copy's ISA
    float* rows[3];
    for (int k = 0; k < 3; ++k) {
      const float* src = f.depth + std::size_t(temporal::shiftedSource(y + k - 1, h, f.unjitter.shiftY)) * w;
      float* dst = rows[k] = depthRows.data() + std::size_t(k) * (w + 2);
      temporal::forEachClampedIndex(run, w + 2, [&](int j) { dst[j] = src[temporal::shiftedSource(j - 1, w, sx)]; });
      if (run.hi > run.lo) std::memcpy(dst + run.lo, src + (run.lo - 1 - sx), sizeof(float) * (run.hi - run.lo));
    }
    temporal::closestDepthTapsRow<temporal::Vec8>(rows[0], rows[1], rows[2], w, taps.data(), taps.data() + w);
  };
  // Lane groups (phlmGroup), in the AVX2 copy on the float kernel's fast
  // path: moving ones with motion (and so the closest-depth taps ahead with
  // depth), where every padded pixel index fits in an int (their index
  // lanes); still ones with the row's still footprints, or without motion.
  const bool indicesFit = std::size_t(h) * std::size_t(f.blocksPerRow) * kBatch <= std::size_t(INT_MAX);
  const bool movingGroups = f.motion.ptr && indicesFit;
  const bool stillGroups = !f.motion.ptr || rowTaps.still;
  if (!Groups || reference || !(movingGroups || stillGroups)) {
    temporal::rowsWithBorder(w, h, y0, y1, clampAll, [&](auto clamp, int x, int y) __attribute__((always_inline)) {
      if (tapsAhead && x == 0) stageTaps(y);
      phlmPixel<T, decltype(clamp)::value>(f, x, y, rowStats[y], batch, rowTaps);
      if (batch.count == kBatch || x == f.width - 1) finishBatch(f, batch, rowStats[y]);
    });
    return;
  }
  if constexpr (Groups) {
    const int sy = f.unjitter.shiftY;
    for (int y = y0; y < y1; ++y) {
      if (tapsAhead) stageTaps(y);
      const bool clampRow = clampAll || y == 0 || y == h - 1 || w < 3;
      // Batches start at x = 0, 8, 16, ...; a group's taps are the columns
      // x0 - 1 - shiftX .. x0 + 8 - shiftX of the rows y - 1 - shiftY ..
      // y + 1 - shiftY: where these and the unshifted 3x3s lie inside, they
      // are the taps phlmPixel reads, clamped (shiftedSource) or not.
      const bool groupRow = y >= 1 && y + 1 < h && y - 1 - sy >= 0 && y + 1 - sy < h;
      for (int x = 0; x < w;) {
        if (groupRow && x >= kBatch && x % kBatch == 0 && x + kBatch <= w - 1 && x - 1 - sx >= 0 &&
            x + kBatch - sx < w &&
            phlmGroup(f, x, y, rowStats[y], batch, rowTaps, movingGroups, stillGroups)) {
          x += kBatch;
        } else {
          if (clampRow || x == 0 || x == w - 1)
            phlmPixel<T, true>(f, x, y, rowStats[y], batch, rowTaps);
          else
            phlmPixel<T, false>(f, x, y, rowStats[y], batch, rowTaps);
          ++x;
        }
        if (batch.count == kBatch || x == w) finishBatch(f, batch, rowStats[y]);
      }
    }
  }
}

// Each copy ends with a store fence: the streaming stores of its rows are
// visible before the thread pool reports the band done.
template <class T>
void phlmRowsBaseline(const Frame<T>& f, int y0, int y1, bool reference, FrameStats* rowStats) {
  phlmRowsBody<T, false>(f, y0, y1, reference, rowStats);
#if defined(__SSE2__)
  _mm_sfence();
#endif
}
#ifdef CRISP_TEMPORAL_HAS_AVX2
template <class T>
CRISP_TEMPORAL_AVX2 void phlmRowsAvx2(const Frame<T>& f, int y0, int y1, bool reference, FrameStats* rowStats) {
  phlmRowsBody<T, std::is_same_v<T, float>>(f, y0, y1, reference, rowStats);
  _mm_sfence();
}
#endif

}  // namespace

template <class T>
void Kernel<T>::allocate(int width, int height, bool withMotion, bool withDepth) {
  const std::size_t pixels = std::size_t(width) * std::size_t(height);
  const bool sameSize = width == width_ && height == height_ && !staged_.empty();
  if (!sameSize) {
    width_ = height_ = 0;  // no size until every buffer has it (a retry after a throw allocates again)
    staged_ = Image(width, height, 4);
    blocksPerRow_ = (width + kBlock - 1) / kBlock;
    models_[0].assign(std::size_t(blocksPerRow_) * kBlock * std::size_t(height) * kRecord, T(0));
    models_[1].clear();
    models_[1].shrink_to_fit();
    narrowBox_.clear();
    movingFlags_.clear();
    for (auto& planes : intercepts_) planes.clear();
    stillSamples_.assign(pixels, 0);
    holdWindows_.allocate(pixels);
    depth_[0].clear();
    depth_[1].clear();
    current_ = 0;
    withMotion_ = withDepth_ = false;
    rowStats_.assign(std::size_t(height), FrameStats{});
    alphaOne_.assign(std::size_t(height), 0);
    width_ = width;
    height_ = height;
    reset();
  }
  if (withMotion && !withMotion_) {
    models_[1 - current_] = models_[current_];  // keeps the history
    narrowBox_.assign(pixels, 0);
    movingFlags_.assign(pixels, 0);
    for (auto& planes : intercepts_) planes.assign(3 * std::size_t(blocksPerRow_) * kBlock * std::size_t(height), T(0));
    interceptsValid_ = false;
  } else if (!withMotion && withMotion_) {
    models_[1 - current_].clear();
    models_[1 - current_].shrink_to_fit();
    narrowBox_ = std::vector<std::uint8_t>();
    movingFlags_ = std::vector<std::uint8_t>();
    for (auto& planes : intercepts_) planes = AlignedVector<T>();
  }
  withMotion_ = withMotion;
  if (withDepth && !withDepth_) {
    depth_[0].assign(pixels, kBackgroundDepth);
    depth_[1].assign(pixels, kBackgroundDepth);
    previousDepthValid_ = false;
  } else if (!withDepth && withDepth_) {
    depth_[0] = std::vector<float>();
    depth_[1] = std::vector<float>();
    previousDepthValid_ = false;
  }
  withDepth_ = withDepth;
}

template <class T>
void Kernel<T>::reset() {
  frames_ = 0;
  previousDepthValid_ = false;
}

template <class T>
std::size_t Kernel<T>::bytesKeptBetweenFrames() const {
  return (models_[0].size() + models_[1].size() + intercepts_[0].size() + intercepts_[1].size()) * sizeof(T) +
         (depth_[0].size() + depth_[1].size()) * sizeof(float) +
         narrowBox_.size() + stillSamples_.size() + holdWindows_.bytes();
}

template <class T>
std::size_t Kernel<T>::bytesScratch() const {
  return staged_.data.size() * sizeof(float) + rowStats_.size() * sizeof(FrameStats) + alphaOne_.size() + movingFlags_.size();
}

// Next records at least this large (with motion) are written with streaming
// stores (Kernel::run; 1920x1080: 230 MB, 640x360: 26 MB).
constexpr std::size_t kStreamBytes = std::size_t(16) << 20;

template <class T>
void Kernel<T>::run(const Inputs& in, const Settings& s, bool reference, int numThreads) {
  if (in.color.width != width_ || in.color.height != height_)
    invalidData("phlm: colour is " + std::to_string(in.color.width) + "x" + std::to_string(in.color.height) +
                " but the filter was committed for " + std::to_string(width_) + "x" + std::to_string(height_));
  if (in.motion.ptr && !withMotion_) invalidData("phlm: a motion image is given but the state was allocated without one");
  if (in.depth.ptr && !withDepth_) invalidData("phlm: a depth image is given but the state was allocated without one");
  if (!(s.lambda > 0.0 && s.lambda < 1.0)) invalidArgument("phlm: parameter 'lambda' must lie in (0, 1)");
  if (!(s.lambdaMoving > 0.0 && s.lambdaMoving < 1.0))
    invalidArgument("phlm: parameter 'lambdaMoving' must lie in (0, 1)");
  const int threads = reference ? 1 : numThreads;
  const bool hasDepth = in.depth.ptr != nullptr;
  const int nextDepth = frames_ % 2;
  float* depthNow = hasDepth ? depth_[nextDepth].data() : nullptr;
  // The fast path's still footprints (phlmRowsBody) read these flags.
  std::uint8_t* movingFlags = !reference && in.motion.ptr ? movingFlags_.data() : nullptr;

  StagedRow row;
  row.color = in.color;
  row.depth = in.depth;
  row.motion = in.motion;
  row.staged = staged_.data.data();
  row.alphaOne = alphaOne_.data();
  row.depthOut = depthNow;
  row.movingFlags = movingFlags;
  auto stageRow = stageRowBaseline;
#ifdef CRISP_TEMPORAL_HAS_AVX2
  if (!reference && temporal::useAvx2()) stageRow = stageRowAvx2;
#endif
  auto stageRows = [&](int y0, int y1) {
    for (int y = y0; y < y1; ++y) stageRow(row, y);
  };
  if (reference) stageRows(0, height_);
  else parallelRows(width_, height_, threads, stageRows);

  const bool moving = in.motion.ptr != nullptr;
  const int next = moving ? 1 - current_ : current_;
  Frame<T> f;
  f.width = width_;
  f.height = height_;
  f.staged = staged_.data.data();
  f.alphaOne = alphaOne_.data();
  f.color = in.color;
  f.depth = depthNow;
  // No motion image: nothing moves, nothing is disoccluded; a depth test would
  // only reset silhouettes whose jittered depth flips between frames.
  f.previousDepth = hasDepth && moving && previousDepthValid_ ? depth_[1 - nextDepth].data() : nullptr;
  f.motion = in.motion;
  f.hasHistory = frames_ > 0;
  f.previous = models_[current_].data();
  f.next = models_[next].data();
  f.blocksPerRow = blocksPerRow_;
  f.output = in.output;
  const T lambda = T(s.lambda);
  f.p0 = T(s.initialCovariance);
  f.ps = T(s.slopeCovariance);
  if (!(f.p0 > T(0) && f.ps > T(0))) invalidArgument("phlm: parameters 'initialCovariance' and 'slopeCovariance' must be > 0");
  f.inverseLambda = T(1) / lambda;
  const T lambdaMoving = T(s.lambdaMoving);
  f.lambdaMoving = lambdaMoving;
  f.resampleDamping = T(s.resampleDamping);
  if (!(f.resampleDamping >= T(0) && f.resampleDamping < T(1)))
    invalidArgument("phlm: parameter 'resampleDamping' must lie in [0, 1)");
  for (int k = 0; k < kDims; ++k) f.p0Diagonal[k] = k == 0 ? f.p0 : f.ps;
  for (int k = 0; k < kDims; ++k) {  // information 4 (1 - lambda) / P0_kk (phlm_rls.h point 3)
    f.regulariserVariance[k] = (k == 0 ? f.p0 : f.ps) / (T(4) * (T(1) - lambda));
    f.regulariserWeight[k] = T(1) / f.regulariserVariance[k];
  }
  const float weight = s.weighting == JitterWeighting::BlackmanHarris
                           ? temporal::blackmanHarrisWeight(s.jitterX, s.jitterY, s.filterSize)
                           : 1.0f;
  f.update = weight > 0.0f;
  f.sampleVariance = f.update ? T(1) / T(weight) : T(1);
  f.sampleWeight = f.update ? T(weight) : T(1);
  f.axis = frames_ % kDims;
  f.bilinearBeta = s.modelFetch != ModelFetch::Nearest;
  f.catmullRomIntercepts = s.modelFetch == ModelFetch::CatmullRom;
  // With motion the intercepts are also kept as planes (interceptRow), written
  // with the records, which the Catmull-Rom fetch reads with one unaligned
  // load per tap of 8 pixels. After a frame without motion or a new
  // allocation they are copied from the records once (a strided pass over
  // them: about 15 ms at 1920x1080 on 2 threads, which is why they are kept).
  f.intercepts = moving ? intercepts_[current_].data() : nullptr;
  f.interceptsNext = moving ? intercepts_[next].data() : nullptr;
  // Streaming stores pay where the state written this frame would not stay
  // in the caches until the next frame reads it (previous and next records
  // together larger than a 32 MB last-level cache); below that they would
  // push it out to memory. The reference path keeps plain stores, so the
  // tests that compare the two paths compare streamed records with cached ones.
  const std::size_t bytesWritten = (models_[next].size() + intercepts_[next].size()) * sizeof(T);
  f.streamNext = !reference && moving && bytesWritten >= kStreamBytes;
  f.reference = reference;
  if (moving && f.hasHistory && f.catmullRomIntercepts && !interceptsValid_) {
    T* planes = intercepts_[current_].data();
    auto copyRows = [&](int y0, int y1) {
      for (int y = y0; y < y1; ++y)
        for (int b = 0; b < blocksPerRow_; ++b) {
          const T* block = f.previous + recordIndex(blocksPerRow_, b * kBlock, y);
          for (int c = 0; c < 3; ++c)
            std::memcpy(interceptRow(planes, blocksPerRow_, c, y) + b * kBlock, block + (kBeta + c) * kBlock,
                        kBlock * sizeof(T));
        }
    };
    if (reference) copyRows(0, height_);
    else parallelRows(width_, height_, threads, copyRows);
  }
  f.footprintBox = s.footprintBox;
  f.narrowBox = moving ? narrowBox_.data() : nullptr;
  f.movingFlags = movingFlags;
  f.stillSamples = stillSamples_.data();
  f.holdPeriod = s.holdPeriod;
  f.release = temporal::holdWindowFrame(holdWindows_, frames_, s.holdPeriod, s.holdRelease);
  f.unjitter = temporal::unjitterFor(s.unjitter, s.jitterX, s.jitterY, s.filterSize);
  f.boxResetScale = T(s.boxResetCovariance) / f.p0;
  if (!(f.boxResetScale > T(0))) invalidArgument("phlm: parameter 'boxResetCovariance' must be > 0");
  f.featureA = T(s.featureA);
  f.featureB = T(s.featureB);
  f.featureAlphaMin = T(s.featureAlphaMin);
  f.depthTolerance = s.depthTolerance;
  FrameStats* rowStats = rowStats_.data();

  auto pixelRows = phlmRowsBaseline<T>;
#ifdef CRISP_TEMPORAL_HAS_AVX2
  if (!reference && temporal::useAvx2()) pixelRows = phlmRowsAvx2<T>;
#endif
  if (reference) pixelRows(f, 0, height_, true, rowStats);
  else parallelRows(width_, height_, threads, [&](int y0, int y1) { pixelRows(f, y0, y1, false, rowStats); });

  stats_ = {};
  for (int y = 0; y < height_; ++y) {
    stats_.reprojectionResets += rowStats[y].reprojectionResets;
    stats_.releases += rowStats[y].releases;
    stats_.boxResets += rowStats[y].boxResets;
    stats_.guards += rowStats[y].guards;
  }
  current_ = next;
  interceptsValid_ = moving;  // with motion every record's intercepts went to the planes too
  previousDepthValid_ = hasDepth;
  ++frames_;
}

template class Kernel<float>;
template class Kernel<double>;

}  // namespace crisp::phlm

// ---------------------------------------------------------------------------
// The filter (float32 kernel).

namespace crisp {
namespace {

std::vector<ParamSpec> phlmParams() {
  std::vector<ParamSpec> specs = temporal::jitterParamSpecs(
      "weight w of each frame's sample in the RLS (measurement variance 1/w): none = 1; blackman-harris = a "
      "Blackman-Harris filter of width filterSize at the jitter (for uniformly drawn jitter)",
      "seed 002 §5.2 static case (weighted moving average); METHODS.md Jitter and references");
  specs.insert(specs.end(), {
      {"lambda", ParamType::Float, 0.998, 0.5, 0.99999, nullptr,
       "RLS forgetting factor: weight of the previous frames' evidence", "seed 002 eqs. 6-7"},
      {"lambdaMoving", ParamType::Float, 0.7, 0.5, 0.99999, nullptr,
       "RLS forgetting factor of moving pixels (non-zero velocity): their models are reprojected every frame",
       "this file (Forgetting; seed 002 uses one lambda)"},
      {"modelFetch", ParamType::String, 0, 0, 0, "catmull-rom|bilinear|nearest",
       "how a moving pixel's model is read at its reprojected position: catmull-rom = the intercepts by "
       "Catmull-Rom clamped to the central 2x2 (as taa's history), the slopes bilinear; bilinear = all of beta "
       "bilinear (the paper's textures); nearest = the nearest model. P is always the nearest model's",
       "seed 002 §5.2, §6; this file (Model fetch)"},
      {"resampleDamping", ParamType::Float, 0.25, 0.0, 0.9, nullptr,
       "beta: a moving pixel forgets with lambdaMoving (1 - beta s), s = max over x and y of 4 t (1 - t) for the "
       "sub-pixel fraction t of the reprojected position (each interpolating model fetch blurs most at half a "
       "pixel); 0 = off",
       "this file (Forgetting; taa's resampleDamping)"},
      {"holdPeriod", ParamType::Int, 16, 0, 127, nullptr,
       "the jitter's period: a still model (nothing in its 5x5 moves) that holds this many samples since its "
       "reset or last box correction stops learning, and its output stops changing; 0 = off",
       "this file (Hold; taa's holdPeriod)"},
      {"holdRelease", ParamType::Float, 0.002, 0.0, 1.0, nullptr,
       "a still model (held or learning) whose input, summed over a period of holdPeriod frames as tonemapped "
       "luminance, differs from the last period that matched by more than this per frame, two periods running, "
       "restarts from the input (a change a held or slowly forgetting model would hide); 0 = on any change, 1 = "
       "never; no effect with holdPeriod 0",
       "this file (Hold); temporal/hold_release.h"},
      {"initialCovariance", ParamType::Float, 1000.0, 1e-3, 1e6, nullptr,
       "p0: variance of the intercept at initialisation and every reset (large: the first sample after a reset "
       "dominates), and its bound: P <= diag(p0, ps, ps, ps) / lambda^3",
       "seed 002 §6 Initialization; phlm_rls.h"},
      {"slopeCovariance", ParamType::Float, 1.0, 1e-3, 1e6, nullptr,
       "ps: variance of the 3 feature slopes at initialisation/reset and their bound (the paper: 1000 for all; "
       "smaller keeps the fit from explaining flicker with tiny feature changes)",
       "seed 002 §6 (deviation, phlm.cpp); phlm_rls.h"},
      {"footprintBox", ParamType::Bool, 1, 0, 1, nullptr,
       "where nothing in the 5x5 moves, correct and clamp against the 3x3 box united with the 5x5 values seen "
       "twice: keeps converged models next to edges under jitter over +-1.5 px; false = the 3x3 box (the paper; "
       "the output then always lies in the current 3x3 box)",
       "seed 002 Alg. 1 lines 13-19 (deviation, phlm.cpp); docs/sampling.md"},
      {"boxResetCovariance", ParamType::Float, 1000.0, 1e-4, 1e6, nullptr,
       "intercept variance of the model reset to the box-corrected prediction (Algorithm 1 line 18); the slope "
       "variances are scaled alike. = initialCovariance: the paper (the output then follows y); small: the "
       "corrected history is trusted like TAA's clipped history (gain ~ value / (1 + value))",
       "seed 002 Alg. 1 line 18 (the reset's covariance is not given)"},
      {"featureA", ParamType::Float, 0.125, 0.0, 10.0, nullptr, "a of phi(v, l) = a l^2 + b |v| l^3",
       "seed 002 §5.1"},
      {"featureB", ParamType::Float, 0.25, 0.0, 10.0, nullptr, "b of phi(v, l) (v in pixels per frame)",
       "seed 002 §5.1"},
      {"featureAlphaMin", ParamType::Float, 0.05, 0.0, 1.0, nullptr,
       "floor of the temporal feature's current-frame weight alpha = phi / (l + Delta(Y)) (lets the feature "
       "follow slow changes inside the neighbourhood's range)",
       "phlm.cpp (not in the paper)"},
      {"depthTolerance", ParamType::Float, 0.05, 0.0, 10.0, nullptr,
       "relative depth difference between this pixel and the reprojected one still counted as the same surface "
       "(larger: disocclusion, reset)",
       "phlm.cpp"},
      {"reference", ParamType::Bool, 0, 0, 1, nullptr,
       "run the scalar reference path (one thread, clamped taps everywhere); bit-identical to the fast path",
       "phlm.cpp"},
  });
  return specs;
}

class PhlmFilter final : public TemporalFilter<phlm::Kernel<float>> {
 public:
  explicit PhlmFilter(Context& c) : TemporalFilter(c, phlmParams(), temporalImageRoles(kTemporalDepthMeaning)) {}
  const char* type() const override { return "phlm"; }

 protected:
  void onCommit() override {
    const ParamSet& p = params();
    settings_.jitterX = p.getFloat("jitterX");
    settings_.jitterY = p.getFloat("jitterY");
    settings_.weighting = p.getString("jitterWeighting") == "blackman-harris" ? phlm::JitterWeighting::BlackmanHarris
                                                                               : phlm::JitterWeighting::None;
    settings_.filterSize = p.getFloat("filterSize");
    settings_.lambda = p.getFloat("lambda");
    settings_.lambdaMoving = p.getFloat("lambdaMoving");
    settings_.resampleDamping = p.getFloat("resampleDamping");
    const std::string fetch = p.getString("modelFetch");
    settings_.modelFetch = fetch == "bilinear" ? phlm::ModelFetch::Bilinear
                           : fetch == "nearest" ? phlm::ModelFetch::Nearest
                                                : phlm::ModelFetch::CatmullRom;
    settings_.holdPeriod = p.getInt("holdPeriod");
    settings_.holdRelease = p.getFloat("holdRelease");
    settings_.initialCovariance = p.getFloat("initialCovariance");
    settings_.slopeCovariance = p.getFloat("slopeCovariance");
    settings_.boxResetCovariance = p.getFloat("boxResetCovariance");
    settings_.footprintBox = p.getBool("footprintBox");
    settings_.unjitter = temporal::parseUnjitterMode(p.getString("unjitter"));
    settings_.featureA = p.getFloat("featureA");
    settings_.featureB = p.getFloat("featureB");
    settings_.featureAlphaMin = p.getFloat("featureAlphaMin");
    settings_.depthTolerance = p.getFloat("depthTolerance");
    reference_ = p.getBool("reference");
    // Re-committing for a new jitter keeps the state; a new size starts over.
    kernel_.allocate(width(), height(), hasImage("motion"), hasImage("depth"));
    allocateAlpha();
  }
  void onExecute() override {
    phlm::Inputs in;
    readCommonInputs(in);
    kernel_.run(in, settings_, reference_, numThreads());
    alpha_.run(in.color, kernel_.alphaBelowOneLastFrame(), in.motion, in.depth, in.output, settings_, reference_, numThreads());
  }

 private:
  phlm::Settings settings_;
};

}  // namespace

std::unique_ptr<Filter> newPhlmFilter(Context& c) { return std::make_unique<PhlmFilter>(c); }

}  // namespace crisp
