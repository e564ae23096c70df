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
#include <cstdint>
#include <string>
#include <vector>

#include "core/conventions.h"
#include "core/error.h"
#include "core/filter.h"
#include "core/parallel.h"
#include "core/row_stage.h"
#include "filters/taa_improved_rows.h"
#include "filters/temporal_filter.h"
#include "temporal/isa.h"
#include "temporal/lanes.h"

namespace crisp::taa_improved {

namespace {

using rows::clamp01;

// A packed float plane read with clamp-to-edge addressing (the reference path).
struct Plane {
  const float* data;
  int width, height;
  float at(int x, int y) const {
    return data[std::size_t(std::clamp(y, 0, height - 1)) * width + std::clamp(x, 0, width - 1)];
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

// Passes 1-4 on the reference path: whole planes, one pass after the other,
// one pixel at a time with clamp-to-edge taps, on one thread. lit, unlit and
// raw are the luminance and raw Sobel planes (sized here on first use).
void referencePasses(const rows::Frame& f, float* depthPlane, std::vector<float>& litPlane,
                     std::vector<float>& unlitPlane, std::vector<float>& rawPlane) {
  const int w = f.width, h = f.height;
  const std::size_t n = std::size_t(w) * h;
  for (auto* v : {&litPlane, &unlitPlane, &rawPlane})
    if (v->size() != n) v->assign(n, 0.0f);
  const Plane dep{depthPlane, w, h}, lit{litPlane.data(), w, h}, unlit{unlitPlane.data(), w, h},
      raw{rawPlane.data(), w, h};
  // Pass 1: luminance planes and the depth plane.
  for (int y = 0; y < h; ++y) {
    if (f.depth) stageDepthRow(*f.depth, y, depthPlane + std::size_t(y) * w);
    if (!f.sobel) continue;
    for (int x = 0; x < w; ++x) {
      litPlane[std::size_t(y) * w + x] = rows::lumaOfView(*f.color, x, y);
      if (f.albedo) unlitPlane[std::size_t(y) * w + x] = rows::lumaOfView(*f.albedo, x, y);
    }
  }
  if (f.sobel) {
    // Pass 2: mixed, smoothstepped Sobel (eqs. 4.9-4.10).
    for (int y = 0; y < h; ++y)
      for (int x = 0; x < w; ++x) {
        const float l = sobelMagnitude([&](int i, int j) { return lit.at(i, j); }, x, y);
        float g = l;
        if (f.albedo) g = 0.3f * sobelMagnitude([&](int i, int j) { return unlit.at(i, j); }, x, y) + 0.7f * l;
        if (f.sobelOfDepth) g += sobelMagnitude([&](int i, int j) { return dep.at(i, j); }, x, y) / dep.at(x, y);
        g = clamp01(g);
        rawPlane[std::size_t(y) * w + x] = std::sqrt(g * g * (3.0f - 2.0f * g));
      }
    // Pass 3: one-channel TAA with clamping, no sharpen (§4.3.3).
    for (int y = 0; y < h; ++y)
      for (int x = 0; x < w; ++x) {
        const float c = raw.at(x, y);
        float lo = c, hi = c;
        for (int j = -1; j <= 1; ++j)
          for (int i = -1; i <= 1; ++i) {
            lo = temporal::minOf(lo, raw.at(x + i, y + j));
            hi = temporal::maxOf(hi, raw.at(x + i, y + j));
          }
        float vx, vy;
        rows::motionAt(*f.motion, x, y, vx, vy);
        f.stabilisedOut[std::size_t(y) * w + x] = rows::stabilisedSobel(f.stabilise, c, lo, hi, vx, vy, float(x), float(y));
      }
  }
  // Pass 4: aliasedValue (eqs. 4.1, 4.4-4.6, 4.12-4.14).
  const rows::AliasedParams& p = f.aliased;
  const Plane sob{f.stabilisedOut, w, h};
  for (int y = 0; y < h; ++y)
    for (int x = 0; x < w; ++x) {
      float model = 0.0f;
      if (p.modelOn) {
        auto objectAt = [&](int i, int j) -> std::uint32_t {
          const int cx = std::clamp(i, 0, w - 1), cy = std::clamp(j, 0, h - 1);
          if (p.id) return p.id->uintAt(cx, cy);
          return isBackgroundDepth(dep.at(cx, cy)) ? 0u : 1u;  // object vs background
        };
        const std::uint32_t centre = objectAt(x, y);
        int differ = 0;
        for (int j = -1; j <= 1; ++j)
          for (int i = -1; i <= 1; ++i) differ += objectAt(x + i, y + j) != centre;
        model = float(differ) / 9.0f;
      }
      float sobelAvg = 0.0f;
      if (f.sobel) {
        const float centre = sob.at(x, y);
        float sum9 = 0.0f;
        for (int j = -1; j <= 1; ++j)
          for (int i = -1; i <= 1; ++i) sum9 += sob.at(x + i, y + j);
        const float sumCross = sob.at(x, y - 1) + sob.at(x - 1, y) + centre + sob.at(x + 1, y) + sob.at(x, y + 1);
        const float avg3x3 = sum9 / 9.0f, avgCross = sumCross / 5.0f;
        const float t = clamp01(model + centre);
        sobelAvg = avgCross * (1.0f - t) + avg3x3 * t;
      }
      float depthPV = 0.0f, depthTPV = 0.0f;
      if (p.depthStats) {
        const float dc = dep.at(x, y);
        float lo = 1.0f, hi = 1.0f, sum = 0.0f;
        for (int j = -1; j <= 1; ++j)
          for (int i = -1; i <= 1; ++i) {
            const float d = dep.at(x + i, y + j) / dc;  // relative to the centre
            lo = std::min(lo, d);
            hi = std::max(hi, d);
            sum += d;
          }
        const float avg = sum / 9.0f;
        const float m = std::min(std::fabs(lo - avg), std::fabs(hi - avg));
        if (m >= p.depthThreshold) rows::depthVariances(p, x, y, avg, m, dc, depthPV, depthTPV);
      }
      const float a = sobelAvg + depthPV + depthTPV + model;
      // Non-finite (cannot happen with sanitised inputs): full TAA, the baseline's box.
      f.aliasedOut[std::size_t(y) * w + x] = std::isnan(a) ? 1.0f : clamp01(a);
    }
}

// The fast path's copies of the fused band (taa_improved_rows.h): 4 lanes
// (SSE2), 8 with AVX2 here; 16 with AVX-512 in taa_improved_rows_avx512.cpp.
void bandBaseline(const rows::Frame& f, const rows::BandRings& r, int y0, int y1) {
  rows::bandBody<temporal::Vec4>(f, r, y0, y1);
}
#ifdef CRISP_TEMPORAL_HAS_AVX2
CRISP_TEMPORAL_AVX2 void bandAvx2(const rows::Frame& f, const rows::BandRings& r, int y0, int y1) {
  rows::bandBody<temporal::Vec8>(f, r, y0, y1);
}
#endif

// Bands of 64 rows or more, at most 16: the halo rows each band recomputes
// (3 staged, 2 Sobel, 1 stabilised above and below) stay under 10 %, and
// 1080 rows make 16 bands, which two threads share evenly (11 bands of 96
// rows ran 1 ms slower than 16 or 8 at 1920x1080).
int bandCount(int height) { return std::clamp(height / 64, 1, 16); }

}  // namespace

void Kernel::allocate(int width, int height, bool withDepth) {
  const bool sameShape = width == width_ && height == height_ && !aliased_.empty();
  taa_.allocate(width, height, withDepth);
  if (sameShape) return;
  width_ = height_ = 0;  // no size until every buffer has it (a retry after a throw allocates again)
  const std::size_t n = std::size_t(width) * height;
  for (auto* v : {&aliased_, &sobel_[0], &sobel_[1]}) v->assign(n, 0.0f);
  for (auto* v : {&lumaLit_, &lumaUnlit_, &sobelRaw_}) v->clear();  // the reference path's, sized on first use
  bands_ = bandCount(height);
  bandRings_.assign(std::size_t(bands_) * rows::bandFloats(width), 0.0f);
  width_ = width;
  height_ = height;
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
  return taa_.bytesScratch() + (lumaLit_.size() + lumaUnlit_.size() + sobelRaw_.size() + aliased_.size() +
                                bandRings_.size()) * sizeof(float);
}

taa::Settings baselineSettings(const Settings& s) {
  taa::Settings base = s.base;
  base.aliasedNeighbourhood = s.aliasedNeighbourhood;
  base.aliasedBoxSize = s.aliasedBoxSize;
  base.sharpen = s.normalizedSharpen ? 0.25f * s.sharpen : s.sharpen;
  return base;
}

void Kernel::run(const Inputs& in, const Settings& s, bool reference, int numThreads) {
  if (in.color.width != width_ || in.color.height != height_)
    invalidData("taa-improved: colour is " + std::to_string(in.color.width) + "x" + std::to_string(in.color.height) +
                " but the filter was committed for " + std::to_string(width_) + "x" + std::to_string(height_));
  const int w = width_, h = height_;
  // The baseline starts over when the clip space changes (its history is
  // kept in that space); so do the passes below, which read the last frames.
  if (taa_.framesSinceReset() > 0 && s.base.clipSpace != taa_.historySpace()) reset();
  const bool hasHistory = taa_.framesSinceReset() > 0;
  const bool useDepth = in.depth.ptr != nullptr;
  // This frame's sanitised depth: the reference path stages it into the
  // plane the baseline kernel stages it into anyway (taa::Kernel::
  // nextDepthPlane); the fast path into its bands' rings.
  float* depthPlane = useDepth ? taa_.nextDepthPlane() : nullptr;
  if (useDepth && !depthPlane)
    invalidData("taa-improved: image 'depth' given but the kernel was allocated without depth");
  const int next = 1 - current_;

  rows::Frame f;
  f.width = w;
  f.height = h;
  f.color = &in.color;
  f.albedo = s.sobelUnlit && in.albedo.ptr ? &in.albedo : nullptr;
  f.depth = useDepth ? &in.depth : nullptr;
  f.motion = &in.motion;
  f.sobel = s.sobel;
  f.sobelOfDepth = useDepth && s.sobelDepth;
  f.stabilise = {sobel_[current_].data(), w, h, s.sobelStabilise && hasHistory && sobelValid_, s.base.feedbackMin,
                 s.base.feedbackMax};
  f.aliased = {in.id.ptr ? &in.id : nullptr,
               taa_.previousDepth(),
               &in.motion,
               w,
               h,
               s.modelAverage && (in.id.ptr || useDepth),
               useDepth && (s.depthVariance || s.temporalDepthVariance),
               s.depthVariance,
               s.temporalDepthVariance,
               s.depthThreshold};
  f.stabilisedOut = sobel_[next].data();
  f.aliasedOut = aliased_.data();

  // Passes 1-4: the aliasedValue plane (and this frame's stabilised Sobel).
  if (reference) {
    referencePasses(f, depthPlane, lumaLit_, lumaUnlit_, sobelRaw_);
  } else {
    auto band = bandBaseline;
#ifdef CRISP_TEMPORAL_HAS_AVX2
    if (temporal::useAvx2()) band = bandAvx2;
#endif
#ifdef CRISP_HAS_AVX512_ROWS
    if (temporal::useAvx512()) band = rows::bandAvx512;
#endif
    parallelBands(h, bands_, numThreads, [&](int b, int y0, int y1) {  // band b owns rings b
      band(f, rows::bandRings(bandRings_.data() + std::size_t(b) * rows::bandFloats(w), w), y0, y1);
    });
  }

  // Pass 5: the baseline kernel, steered.
  const taa::Settings base = baselineSettings(s);
  taa::Inputs tin;
  tin.color = in.color;
  tin.motion = in.motion;
  tin.depth = in.depth;
  tin.output = in.output;
  tin.aliasedValue = steering(s);
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

class TaaImprovedFilter final : public TemporalFilter<taa_improved::Kernel> {
 public:
  explicit TaaImprovedFilter(Context& c)
      : TemporalFilter(c, improvedParams(),
                       temporalImageRoles(
                           "planar depth (channel 0): closest-depth velocity, disocclusion, depth Sobel and pseudo-variances",
                           {{"id", false, 1, 1, true, "object ids (Cryptomatte hash): modelAverage (eq. 4.1)"},
                            {"albedo", false, 3, 4, false, "unlit colour (Blender's DiffCol): unlit luminance Sobel"}})) {}
  const char* type() const override { return "taa-improved"; }

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
    allocateAlpha();
  }
  void onExecute() override {
    taa_improved::Inputs in;
    readCommonInputs(in);
    if (hasImage("id")) in.id = inputApartFromOutput("id");
    if (hasImage("albedo")) in.albedo = inputApartFromOutput("albedo");
    kernel_.run(in, settings_, reference_, numThreads());
    // The alpha, steered by the colour's aliasedValue plane (temporal_alpha.h).
    alpha_.run(in.color, kernel_.baseline().alphaBelowOneLastFrame(), in.motion, in.depth, kernel_.steering(settings_),
               in.output, taa_improved::baselineSettings(settings_), reference_, numThreads());
  }

 private:
  taa_improved::Settings settings_;
};

}  // namespace

std::unique_ptr<Filter> newTaaImprovedFilter(Context& c) { return std::make_unique<TaaImprovedFilter>(c); }

}  // namespace crisp
