// SPDX-License-Identifier: Apache-2.0
// "taa": the baseline temporal reprojection anti-aliasing of seed 000 chapter
// III (after Xu 2016 / Uncharted 4 and Pedersen 2016 / INSIDE; Karis 2014),
// condensed in METHODS.md "TAA baseline". Per pixel:
//   1. current colour = this frame's jittered 1-sample value, NOT resampled
//      (see "Jitter" below);
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
//      difference), kmin/kmax = 0.88/0.97;
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
// p - j blurs it"): we never resample the current frame. Its value at pixel p
// is a sample of the pixel's footprint at p + j; averaging such samples over
// jitter phases IS the anti-aliased pixel, so the raw sample is the right
// input to the accumulation. The reprojected history is jitter-free (motion
// vectors never include jitter), so nothing else needs unjittering. The
// jitter parameters therefore only set the sample's weight (jitterWeighting).
//
// Deliberate choices, beside the code below:
//  * the static path tests history against the full 3x3 box (a converged edge
//    value always lies inside its 3x3 range), the moving path against the
//    rounded box as the seed does;
//  * with staticClip (default), history outside the 3x3 box in a static pixel
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
// | feedbackMin | float | 0.88 | [0, 1] | history weight at a large luma difference | §3.6.3 |
// | feedbackMax | float | 0.97 | [0, 1] | history weight at equal luma | §3.6.3 |
// | sharpen | float | 0 | [0, 1] | amount of the eq. 3.1 sharpen on the output | eq. 3.1 |
// | staticAccumulation | bool | true | - | running average where nothing moves | METHODS.md Jitter |
// | maxSamples | int | 128 | [1, 65536] | cap of the running average's sample count | this file |
// | staticClip | bool | true | - | clip static history too | this file |
// | depthTolerance | float | 0.05 | [0, 10] | relative depth change still the same surface | this file |
// | reference | bool | false | - | scalar reference path | this file |
#include "filters/taa.h"

#include <algorithm>
#include <cmath>
#include <cstring>

#include "core/color.h"
#include "core/error.h"
#include "core/filter.h"
#include "core/parallel.h"
#include "temporal/color_space.h"
#include "temporal/history_fetch.h"
#include "temporal/jitter.h"
#include "temporal/neighbourhood.h"
#include "temporal/vec4.h"
#include "temporal/velocity.h"

namespace crisp::taa {

using temporal::ColorBox;
using temporal::Float3;

namespace {

// Everything one frame's pixels read, set up once per frame.
struct Frame {
  int width, height;
  const float* staged;         // RGBA, colour in the clip space
  const float* depth;          // this frame's sanitised depth, or null
  const float* previousDepth;  // previous frame's, or null (no depth test)
  ImageView color;             // the input, for exact resets
  ImageView motion;            // ptr null: static scene
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
  float maxSamples;
  float depthTolerance;
};

inline float lumaOf(const temporal::Vec4& c, ClipSpace space) {
  return space == ClipSpace::YCoCg ? c[0] : 0.2126f * c[0] + 0.7152f * c[1] + 0.0722f * c[2];
}

inline Float3 toRgb(const Float3& c, ClipSpace space) {
  return space == ClipSpace::YCoCg ? temporal::yCoCgToRgb(c) : c;
}

inline void storeOutput(const ImageView& out, int x, int y, const Float3& rgb, float alpha) {
  float* p = out.pixel(x, y);
  const int channels = out.channels();
  p[0] = sanitizeColor(rgb[0]);
  p[1] = sanitizeColor(rgb[1]);
  p[2] = sanitizeColor(rgb[2]);
  if (channels > 3) p[3] = alpha;
}

// One pixel of the TAA pass. Clamp: clamp the 3x3 taps to the image (border
// pixels, and every pixel on the reference path); interior pixels of the fast
// path skip it. Both read the same values, so results are identical.
template <bool Clamp>
inline void taaPixel(const Frame& f, int x, int y) {
  using temporal::Vec4;
  const int w = f.width, h = f.height;
  Vec4 taps[9];  // RGBA staged: colour in the clip space, alpha in lane 3
  float depth9[9];
  int tapX[9], tapY[9];
  for (int j = 0, i = 0; j < 3; ++j)
    for (int k = 0; k < 3; ++k, ++i) {
      const int tx = Clamp ? std::clamp(x + k - 1, 0, w - 1) : x + k - 1;
      const int ty = Clamp ? std::clamp(y + j - 1, 0, h - 1) : y + j - 1;
      tapX[i] = tx;
      tapY[i] = ty;
      taps[i] = temporal::load4(f.staged + (std::size_t(ty) * w + tx) * 4);
      if (f.depth) depth9[i] = f.depth[std::size_t(ty) * w + tx];
    }
  const Vec4 current = taps[4];
  const float alpha = current[3];

  // Step 3: velocity of the closest-depth tap (seed 000 §3.6.3).
  const int tap = (f.depth && f.motion.ptr) ? temporal::closestDepthTap(depth9) : 4;
  float vx = 0.0f, vy = 0.0f;
  if (f.motion.ptr) {
    const float* m = f.motion.pixel(tapX[tap], tapY[tap]);
    vx = m[0];
    vy = m[1];
  }
  const bool moving = vx != 0.0f || vy != 0.0f;

  // Step 8: is there usable history at p + v?
  bool valid = f.hasHistory && temporal::finiteMotion(vx, vy);
  const float qx = float(x) + vx, qy = float(y) + vy;
  if (valid) valid = temporal::onScreen(qx, qy, w, h);
  if (valid && f.previousDepth) {
    // Disocclusion: some tap of the bilinear footprint must hold the surface
    // whose velocity we follow (depth is compared, never interpolated).
    const float d = depth9[tap];
    const temporal::Footprint fp = temporal::footprintOf(qx, qy);
    bool match = false;
    for (int j = 0; j < 2 && !match; ++j)
      for (int k = 0; k < 2 && !match; ++k) {
        if ((k == 1 && fp.tx == 0.0f) || (j == 1 && fp.ty == 0.0f)) continue;  // zero-weight tap
        const int sx = std::clamp(fp.x0 + k, 0, w - 1), sy = std::clamp(fp.y0 + j, 0, h - 1);
        match = temporal::sameSurfaceDepth(d, f.previousDepth[std::size_t(sy) * w + sx], f.depthTolerance);
      }
    valid = match;
  }

  Vec4 hist = temporal::splat(0.0f);
  if (valid) {
    if (!moving)
      hist = temporal::load4(f.previous.at(x, y));  // exact: no filtering at zero motion
    else if (f.filter == HistoryFilter::CatmullRom)
      hist = temporal::fetchCatmullRom4(f.previous, qx, qy);
    else
      hist = temporal::fetchBilinear4(f.previous, qx, qy);
  }
  const float historyWeight = valid ? std::fabs(hist[3]) : 0.0f;
  const float weight = f.sampleWeight;
  const float weightSum = historyWeight + weight;

  Vec4 result = current;
  float newWeight = weight;
  bool reset = !valid || !(weightSum > 0.0f);  // first frame bootstrap / invalid reprojection
  if (!reset) {
    temporal::ColorBox4 box3x3, cross;
    temporal::neighbourhoodBoxes4(taps, box3x3, cross);
    const bool staticPixel = f.staticAccumulation && !moving && hist[3] > 0.0f;
    // Static pixels are tested against the full 3x3 box (a converged edge
    // value always lies in its 3x3 range); moving ones against the rounded box.
    const temporal::ColorBox4 box = staticPixel ? box3x3 : temporal::roundedBox4(box3x3, cross);
    float excess;
    const Vec4 clipped = temporal::clipTowardCentre4(hist, box.min, box.max, &excess);
    if (staticPixel && (!f.staticClip || !(excess > 1.0f))) {
      // Running average, weight w/W, in linear light.
      result = hist + (current - hist) * (weight / weightSum);
      newWeight = std::min(weightSum, f.maxSamples);
    } else {
      // Step 6: luma-difference feedback on the clipped history.
      const float l0 = lumaOf(clipped, f.space), l1 = lumaOf(current, f.space);
      const float diff = std::clamp(std::fabs(l0 - l1) / std::max(std::max(l0, l1), 0.2f), 0.0f, 1.0f);
      const float unbiased = (1.0f - diff) * (1.0f - diff);
      const float k = f.feedbackMin + (f.feedbackMax - f.feedbackMin) * unbiased;
      const float a = std::max(1.0f - k, weight / weightSum);
      result = clipped + (current - clipped) * a;
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
  }
  result[3] = moving ? -newWeight : newWeight;  // sign: was this pixel static this frame
  temporal::store4(f.history + (std::size_t(y) * w + x) * 4, result);
  if (!f.writeOutput) return;
  if (reset) {
    // Reset to current: the input colour itself (sanitised), not its YCoCg
    // round trip, which can differ in the last bit.
    const float* p = f.color.pixel(x, y);
    const int cc = f.color.channels();
    storeOutput(f.output, x, y, {{sanitizeColor(p[0]), sanitizeColor(cc > 1 ? p[1] : p[0]), sanitizeColor(cc > 2 ? p[2] : p[0])}},
                alpha);
  } else {
    storeOutput(f.output, x, y, toRgb({{result[0], result[1], result[2]}}, f.space), alpha);
  }
}

// Step 7: sharpen the blended image (eq. 3.1) into the output, clamped to the
// range of the 5 taps.
template <bool Clamp>
inline void sharpenPixel(const Frame& f, const float* staged, float amount, int x, int y) {
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
  storeOutput(f.output, x, y, toRgb(result, f.space), staged[(std::size_t(y) * w + x) * 4 + 3]);
}

// Runs a per-pixel function over rows [y0, y1): clamped taps on the border,
// unclamped inside (fast path), or clamped everywhere (reference).
template <class Fn>
void rowsWithBorder(int width, int height, int y0, int y1, bool clampAll, Fn&& fn) {
  for (int y = y0; y < y1; ++y) {
    if (clampAll || y == 0 || y == height - 1 || width < 3) {
      for (int x = 0; x < width; ++x) fn(std::true_type{}, x, y);
    } else {
      fn(std::true_type{}, 0, y);
      for (int x = 1; x < width - 1; ++x) fn(std::false_type{}, x, y);
      fn(std::true_type{}, width - 1, y);
    }
  }
}

}  // namespace

void Kernel::allocate(int width, int height) {
  if (width == width_ && height == height_ && !staged_.empty()) return;  // keep the history
  width_ = width;
  height_ = height;
  staged_ = Image(width, height, 4);
  history_[0] = Image(width, height, 4);
  history_[1] = Image(width, height, 4);
  depth_[0].assign(std::size_t(width) * height, kBackgroundDepth);
  depth_[1].assign(std::size_t(width) * height, kBackgroundDepth);
  reset();
}

void Kernel::reset() {
  frames_ = 0;
  previousDepthValid_ = false;
}

std::size_t Kernel::bytesKeptBetweenFrames() const {
  return (history_[0].data.size() + history_[1].data.size() + depth_[0].size() + depth_[1].size()) * sizeof(float);
}

std::size_t Kernel::bytesScratch() const { return staged_.data.size() * sizeof(float); }

void Kernel::run(const Inputs& in, const Settings& s, bool reference, int numThreads) {
  if (in.color.width != width_ || in.color.height != height_)
    invalidData("taa: colour is " + std::to_string(in.color.width) + "x" + std::to_string(in.color.height) +
                " but the filter was committed for " + std::to_string(width_) + "x" + std::to_string(height_));
  if (frames_ > 0 && s.clipSpace != historySpace_) reset();  // history is stored in the clip space
  historySpace_ = s.clipSpace;
  const int threads = reference ? 1 : numThreads;
  const bool hasDepth = in.depth.ptr != nullptr;
  const int next = 1 - current_;
  float* depthNow = depth_[next].data();
  const int colorChannels = in.color.channels();
  const ClipSpace space = s.clipSpace;

  // Stage the current frame: sanitised (conventions.h), in the clip space;
  // sanitised depth for this frame.
  auto stageRows = [&](int y0, int y1) {
    for (int y = y0; y < y1; ++y)
      for (int x = 0; x < width_; ++x) {
        const float* p = in.color.pixel(x, y);
        Float3 rgb = {{sanitizeColor(p[0]), sanitizeColor(colorChannels > 1 ? p[1] : p[0]),
                       sanitizeColor(colorChannels > 2 ? p[2] : p[0])}};
        const Float3 c = space == ClipSpace::YCoCg ? temporal::rgbToYCoCg(rgb) : rgb;
        float* d = staged_.at(x, y);
        d[0] = c[0];
        d[1] = c[1];
        d[2] = c[2];
        d[3] = colorChannels > 3 ? sanitizeColor(p[3]) : 1.0f;
        if (hasDepth) depthNow[std::size_t(y) * width_ + x] = temporal::sanitizeDepth(in.depth.pixel(x, y)[0]);
      }
  };
  if (reference)
    stageRows(0, height_);
  else
    parallelRows(width_, height_, threads, stageRows);

  Frame f;
  f.width = width_;
  f.height = height_;
  f.staged = staged_.data.data();
  f.depth = hasDepth ? depthNow : nullptr;
  f.previousDepth = hasDepth && previousDepthValid_ ? depth_[current_].data() : nullptr;
  f.color = in.color;
  f.motion = in.motion;
  f.previous = {history_[current_].data.data(), width_, height_};
  f.hasHistory = frames_ > 0;
  f.history = history_[next].data.data();
  f.output = in.output;
  f.writeOutput = !(s.sharpen > 0.0f);
  f.space = space;
  f.filter = s.historyFilter;
  f.sampleWeight = s.weighting == JitterWeighting::BlackmanHarris
                       ? temporal::blackmanHarrisWeight(s.jitterX, s.jitterY, s.filterSize)
                       : 1.0f;
  f.feedbackMin = s.feedbackMin;
  f.feedbackMax = s.feedbackMax;
  f.staticAccumulation = s.staticAccumulation;
  f.staticClip = s.staticClip;
  f.maxSamples = float(std::max(1, s.maxSamples));
  f.depthTolerance = s.depthTolerance;

  auto taaRows = [&](int y0, int y1) {
    rowsWithBorder(width_, height_, y0, y1, reference, [&](auto clamp, int x, int y) {
      taaPixel<decltype(clamp)::value>(f, x, y);
    });
  };
  if (reference)
    taaRows(0, height_);
  else
    parallelRows(width_, height_, threads, taaRows);

  if (!f.writeOutput) {
    const float amount = s.sharpen;
    const float* staged = f.staged;
    auto sharpenRows = [&](int y0, int y1) {
      rowsWithBorder(width_, height_, y0, y1, reference, [&](auto clamp, int x, int y) {
        sharpenPixel<decltype(clamp)::value>(f, staged, amount, x, y);
      });
    };
    if (reference)
      sharpenRows(0, height_);
    else
      parallelRows(width_, height_, threads, sharpenRows);
  }

  current_ = next;
  previousDepthValid_ = hasDepth;
  ++frames_;
}

}  // namespace crisp::taa

// ---------------------------------------------------------------------------
// The filter.

namespace crisp {
namespace {

std::vector<ParamSpec> taaParams() {
  return {
      {"jitterX", ParamType::Float, 0.0, -4.0, 4.0, nullptr,
       "this frame's sub-pixel sample offset in pixels, x right (set per frame from the sidecar's jitter)",
       "seed 000 §3.6.1 and appendix B; seed 004 Halton"},
      {"jitterY", ParamType::Float, 0.0, -4.0, 4.0, nullptr,
       "this frame's sample offset in pixels, y DOWN (the library convention: negate the sidecar's / Blender's "
       "y-up value)",
       "seed 000 §3.6.1 and appendix B"},
      {"jitterWeighting", ParamType::String, 0, 0, 0, "none|blackman-harris",
       "weight of each frame's sample in the static accumulation: none = the jitter already follows the wanted "
       "pixel filter (EEVEE's Blackman-Harris draw -> EEVEE's reference; uniform -> box); blackman-harris = "
       "weight uniformly drawn jitter by a Blackman-Harris filter of width filterSize",
       "METHODS.md Jitter and references; BLENDER.md Sampling and jitter"},
      {"filterSize", ParamType::Float, 1.5, 0.01, 4.0, nullptr,
       "width in pixels of the Blackman-Harris pixel filter used by jitterWeighting (EEVEE's filter_size)",
       "BLENDER.md Sampling and jitter"},
      {"historyFilter", ParamType::String, 0, 0, 0, "catmull-rom|bilinear",
       "filtered fetch of the reprojected history; Catmull-Rom's negative lobes are clamped to the 2x2 range",
       "seed 000 §3.6.3; Karis 2014"},
      {"clipSpace", ParamType::String, 0, 0, 0, "ycocg|rgb",
       "colour space of the clip box (changing it resets the history)", "seed 000 §3.6.4"},
      {"feedbackMin", ParamType::Float, 0.88, 0.0, 1.0, nullptr,
       "history weight k when the lumas of clipped history and current colour differ most", "seed 000 §3.6.3"},
      {"feedbackMax", ParamType::Float, 0.97, 0.0, 1.0, nullptr,
       "history weight k when the lumas agree: k = lerp(min, max, (1 - |l0-l1|/max(l0,l1,0.2))^2)",
       "seed 000 §3.6.3"},
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
       "test static history against the 3x3 box too and fall back to the clipped feedback blend when outside "
       "(rejects cuts, fireflies, light changes; loses sub-pixel features a frame's 3x3 misses); false = pure "
       "accumulation (call reset on a cut)",
       "this file"},
      {"depthTolerance", ParamType::Float, 0.05, 0.0, 10.0, nullptr,
       "relative depth difference between the followed surface and the previous depth still counted as the same "
       "surface (larger: disocclusion reset)",
       "this file"},
      {"reference", ParamType::Bool, 0, 0, 1, nullptr,
       "run the scalar reference path (one thread, clamped taps everywhere); bit-identical to the fast path",
       "this file"},
  };
}

class TaaFilter final : public Filter {
 public:
  explicit TaaFilter(Context& c)
      : Filter(c, taaParams(),
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
    settings_.jitterX = p.getFloat("jitterX");
    settings_.jitterY = p.getFloat("jitterY");
    settings_.weighting = p.getString("jitterWeighting") == "blackman-harris" ? taa::JitterWeighting::BlackmanHarris
                                                                              : taa::JitterWeighting::None;
    settings_.filterSize = p.getFloat("filterSize");
    settings_.historyFilter =
        p.getString("historyFilter") == "bilinear" ? taa::HistoryFilter::Bilinear : taa::HistoryFilter::CatmullRom;
    settings_.clipSpace = p.getString("clipSpace") == "rgb" ? taa::ClipSpace::Rgb : taa::ClipSpace::YCoCg;
    settings_.feedbackMin = p.getFloat("feedbackMin");
    settings_.feedbackMax = p.getFloat("feedbackMax");
    if (settings_.feedbackMin > settings_.feedbackMax)
      invalidArgument("filter 'taa': parameter 'feedbackMin' (" + std::to_string(settings_.feedbackMin) +
                      ") must not exceed 'feedbackMax' (" + std::to_string(settings_.feedbackMax) + ")");
    settings_.sharpen = p.getFloat("sharpen");
    settings_.staticAccumulation = p.getBool("staticAccumulation");
    settings_.maxSamples = p.getInt("maxSamples");
    settings_.staticClip = p.getBool("staticClip");
    settings_.depthTolerance = p.getFloat("depthTolerance");
    reference_ = p.getBool("reference");
    // Re-committing for a new jitter keeps the history; a new size starts over.
    kernel_.allocate(width(), height());
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
