// SPDX-License-Identifier: Apache-2.0
// REPAIR (seed 001): each step against its definition, the angle estimate
// against the true edge angle over 0-180 degrees, PSNR gains on edge pixels
// against a 16x16 supersampled reference, fast path == reference path bit for
// bit, bad values, and the Filter interface.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <random>
#include <string>
#include <vector>

#include "core/color.h"
#include "core/context.h"
#include "core/error.h"
#include "core/filter.h"
#include "filters/repair.h"
#include "synth/synthetic.h"
#include "test_util.h"

using namespace crisp;
using repair::AngleEstimator;
using repair::MaskKind;
using repair::Settings;

namespace {

Image runKernel(const Image& input, const Settings& s, bool reference = false, int threads = 0,
                repair::Kernel* kernelOut = nullptr, repair::RowIsa isa = repair::RowIsa::Auto) {
  Image out(input.width, input.height, 4);
  repair::Kernel local;
  repair::Kernel& k = kernelOut ? *kernelOut : local;
  k.allocate(input.width, input.height);
  k.setRowIsa(isa);
  k.run(input.view(), out.view(), s, reference, threads);
  return out;
}

double angleError(double estimate, double truth) {
  double d = std::fmod(std::fabs(estimate - truth), 180.0);
  return std::min(d, 180.0 - d);
}

struct AngleSummary {
  double mean = 0, p95 = 0, max = 0, worstAngleMedian = 0;
  long samples = 0;
};

// Angle estimate at every detected edge pixel away from the border, for
// single edges at angles 0, step, ... < 180 and several sub-pixel offsets.
AngleSummary measureAngles(const Settings& s, double step, bool supersampled) {
  const int size = 32, border = 9;
  std::vector<double> all;
  double worstMedian = 0;
  for (double angle = 0; angle < 180.0; angle += step) {
    std::vector<double> errors;
    for (float offset : {0.0f, 0.37f, 0.71f}) {
      const synth::Scene scene = synth::edgeScene(size, size, float(angle), offset);
      const Image input = supersampled ? synth::renderSupersampled(scene, size, size, 4)
                                       : synth::renderCentre(scene, size, size);
      repair::Kernel k;
      runKernel(input, s, false, 1, &k);
      for (int y = border; y < size - border; ++y)
        for (int x = border; x < size - border; ++x) {
          if (!(repair::edgeValue(*k.gradient().at(x, y), float(k.threshold().threshold)) > 0)) continue;
          errors.push_back(angleError(repair::directionDegrees(k.directionAt(x, y, s)), angle));
        }
    }
    EXPECT_FALSE(errors.empty()) << "no edge pixels found at " << angle << " degrees";
    if (errors.empty()) continue;
    std::sort(errors.begin(), errors.end());
    worstMedian = std::max(worstMedian, errors[errors.size() / 2]);
    all.insert(all.end(), errors.begin(), errors.end());
  }
  AngleSummary r;
  std::sort(all.begin(), all.end());
  for (double e : all) r.mean += e;
  r.samples = long(all.size());
  r.mean /= double(all.size());
  r.p95 = all[all.size() * 95 / 100];
  r.max = all.back();
  r.worstAngleMedian = worstMedian;
  return r;
}

Image randomImage(int w, int h, unsigned seed) {
  std::mt19937 rng(seed);
  std::uniform_real_distribution<float> u(0.0f, 1.0f);
  Image im(w, h, 4);
  for (float& v : im.data) v = u(rng) < 0.7f ? 0.05f : u(rng) * 1.5f;  // flat patches and steps
  return im;
}

}  // namespace

// ---- step 1 ----------------------------------------------------------------

TEST(RepairGrey, FastEncodingMatchesSrgbEncode) {
  double worst = 0;
  for (int i = 0; i <= 200000; ++i) {
    const float v = float(i) / 200000.0f;
    worst = std::max(worst, double(std::fabs(repair::srgbEncodeFast(v) - srgbEncode(v))));
  }
  for (float v : {1e-30f, 1e-8f, 0.0031308f, 0.0031309f, 0.04f, 0.5f, 0.999999f}) 
    worst = std::max(worst, double(std::fabs(repair::srgbEncodeFast(v) - srgbEncode(v))));
  std::printf("[ repair ] fast sRGB encoding: max |error| vs srgbEncode = %.3g\n", worst);
  EXPECT_LT(worst, 1e-6);
  EXPECT_EQ(repair::srgbEncodeFast(-1.0f), 0.0f);
  EXPECT_EQ(repair::srgbEncodeFast(NAN), 0.0f);
  EXPECT_EQ(repair::srgbEncodeFast(7.0f), 1.0f);
}

TEST(RepairGrey, IsYiqLumaOfDisplayEncodedColour) {
  const float rgb[][3] = {{0.2f, 0.5f, 0.9f}, {1.0f, 0.0f, 0.0f}, {0.0f, 1.0f, 0.0f}, {0.0f, 0.0f, 1.0f}, {3.0f, -1.0f, 0.01f}};
  for (const auto& c : rgb) {
    const float expected = 0.299f * srgbEncode(c[0]) + 0.587f * srgbEncode(c[1]) + 0.114f * srgbEncode(c[2]);
    EXPECT_NEAR(repair::greyOf(c[0], c[1], c[2]), expected, 4e-6) << c[0] << "," << c[1] << "," << c[2];
  }
}

// ---- step 2 ----------------------------------------------------------------

TEST(RepairSobel, MagnitudeOfKnownNeighbourhoods) {
  const float vertical[3][3] = {{0, 1, 1}, {0, 1, 1}, {0, 1, 1}};  // gx = 4, gy = 0
  EXPECT_FLOAT_EQ(repair::sobelMagnitude(vertical), 4.0f);
  const float ramp[3][3] = {{0, 0, 0}, {1, 1, 1}, {2, 2, 2}};  // gy = 8
  EXPECT_FLOAT_EQ(repair::sobelMagnitude(ramp), 8.0f);
  const float corner[3][3] = {{0, 0, 0}, {0, 0, 1}, {0, 1, 1}};  // gx = (0 + 2 + 1) - 0, gy = (0 + 2 + 1) - 0
  EXPECT_FLOAT_EQ(repair::sobelMagnitude(corner), std::sqrt(9.0f + 9.0f));
}

// ---- step 3 ----------------------------------------------------------------

TEST(RepairThreshold, EqualsDefinitionOnHandComputedValues) {
  // Non-black values 1, 2, 3, 6: mu = 3, sigma^2 = (4 + 1 + 0 + 9) / 4 = 3.5. The black ones (below
  // kBlackGradient: float rounding in a flat area) are not counted.
  const float rowA[] = {0, 1, 2, 0, 9.9e-6f};
  const float rowB[] = {3, 2e-7f, 6, 0, 0};
  repair::RowStats rows[2] = {repair::rowStats(rowA, 5), repair::rowStats(rowB, 5)};
  for (float kappa : {-2.0f, -1.0f, 0.0f, 0.5f}) {
    const repair::ThresholdStats t = repair::combineRowStats(rows, 2, kappa);
    EXPECT_EQ(t.count, 4);
    EXPECT_DOUBLE_EQ(t.mean, 3.0);
    EXPECT_NEAR(t.sigma, std::sqrt(3.5), 1e-12);
    // kappa -2 takes mu + kappa sigma below 0: T stops at the black values, which are never edges.
    EXPECT_NEAR(t.threshold, std::max(3.0 + kappa * std::sqrt(3.5), double(repair::kBlackGradient)), 1e-12)
        << kappa;
    EXPECT_FALSE(repair::edgeValue(9.9e-6f, float(t.threshold)) > 0) << kappa;
  }
  // Algorithm 2 as printed (sigma^2 = s2 - 2 mu s + mu^2 = 50 - 72 + 9 < 0,
  // t = mu - kappa sigma) cannot give this: the fix matters.
  const repair::ThresholdStats none = repair::combineRowStats(rows, 0, -1.0f);
  EXPECT_EQ(none.count, 0);
  EXPECT_FALSE(repair::edgeValue(0.0f, float(none.threshold)) > 0);
}

TEST(RepairThreshold, KernelMatchesDefinitionOverNonBlackGradient) {
  // Widths that are not multiples of the row statistics' vector width too, so its tail loop runs.
  for (int width : {96, 97, 101})
  for (float kappa : {-1.0f, 0.0f, 1.0f}) {
    SCOPED_TRACE("width " + std::to_string(width) + ", kappa " + std::to_string(kappa));
    const Image input = synth::renderCentre(synth::testChart(width, 64), width, 64);
    Settings s;
    s.kappa = kappa;
    repair::Kernel k;
    runKernel(input, s, false, 0, &k);
    bool lastColumn = false;  // the tail's pixels must take part
    for (int y = 0; y < 64; ++y) lastColumn |= k.gradient().data[std::size_t(y) * width + (width - 1)] != 0;
    EXPECT_TRUE(lastColumn);
    long double sum = 0, n = 0;
    for (float z : k.gradient().data)
      if (z >= repair::kBlackGradient) sum += z, n += 1;
    const long double mean = sum / n;
    long double squares = 0;
    for (float z : k.gradient().data)
      if (z >= repair::kBlackGradient) squares += (z - mean) * (z - mean);
    const double sigma = double(std::sqrt(squares / n));
    EXPECT_EQ(k.threshold().count, long(n));
    EXPECT_NEAR(k.threshold().mean, double(mean), 1e-12);
    EXPECT_NEAR(k.threshold().sigma, sigma, 1e-9);
    EXPECT_NEAR(k.threshold().threshold, double(mean) + kappa * sigma, 1e-9);
  }
}

// ---- step 4 ----------------------------------------------------------------

TEST(RepairAngle, LiteralEq36IsNotTheEdgeAngle) {
  // An ideal line y = m x through a 5 x 5 patch (y down): alpha1 ~ m,
  // beta1 ~ 1/m, so eq. 3.6 gives ~1/m^2 while our estimator gives m.
  const float m = 0.25f;
  float patch[25] = {};
  for (int i = -2; i <= 2; ++i) {
    const float yLine = m * float(i);
    const int j0 = int(std::floor(yLine));
    const float frac = yLine - float(j0);
    if (j0 >= -2 && j0 <= 2) patch[(j0 + 2) * 5 + (i + 2)] += 1.0f - frac;
    if (j0 + 1 >= -2 && j0 + 1 <= 2) patch[(j0 + 3) * 5 + (i + 2)] += frac;
  }
  const repair::SlopeFit fit = repair::fitPatch(patch, 5);
  EXPECT_NEAR(fit.alpha1, m, 0.05);
  // Screen angle of y_down = 0.25 x is -14.04 deg, i.e. 165.96 in [0, 180).
  const double truth = 180.0 - std::atan(double(m)) * 180.0 / M_PI;
  EXPECT_LT(angleError(repair::directionDegrees(repair::edgeDirection(fit, AngleEstimator::Regression)), truth), 3.0);
  EXPECT_GT(angleError(repair::directionDegrees(repair::edgeDirection(fit, AngleEstimator::Thesis)), truth), 20.0);
}

TEST(RepairAngle, AlwaysFiniteOnDegeneratePatches) {
  std::vector<std::vector<float>> patches;
  patches.push_back(std::vector<float>(25, 0.0f));                  // all zero
  patches.push_back(std::vector<float>(25, 1.0f));                  // all equal (tie)
  std::vector<float> centre(25, 0.0f);
  centre[12] = 1.0f;
  patches.push_back(centre);                                        // isolated pixel
  std::vector<float> cross(25, 0.0f);
  for (int i = 0; i < 5; ++i) cross[2 * 5 + i] = cross[i * 5 + 2] = 1.0f;
  patches.push_back(cross);                                         // a cross: opposite axes
  std::vector<float> column(25, 0.0f);
  for (int j = 0; j < 5; ++j) column[j * 5 + 2] = 1.0f;
  patches.push_back(column);                                        // vertical: alpha1 -> 0
  std::vector<float> huge(25, 0.0f);
  for (int i = 0; i < 25; ++i) huge[i] = (i % 3) ? 3e38f : 0.0f;
  patches.push_back(huge);
  for (const auto& p : patches)
    for (AngleEstimator e : {AngleEstimator::Regression, AngleEstimator::Thesis}) {
      const repair::Direction d = repair::edgeDirection(repair::fitPatch(p.data(), 5), e);
      EXPECT_TRUE(std::isfinite(d.cosTheta) && std::isfinite(d.sinTheta));
      EXPECT_NEAR(d.cosTheta * d.cosTheta + d.sinTheta * d.sinTheta, 1.0f, 1e-5f);
      const float deg = repair::directionDegrees(d);
      EXPECT_TRUE(deg >= 0.0f && deg < 180.0f) << deg;
    }
  // The vertical line is read as vertical (90 deg), not as alpha1 = 0 -> 0 deg.
  EXPECT_NEAR(repair::directionDegrees(repair::edgeDirection(repair::fitPatch(column.data(), 5), AngleEstimator::Regression)),
              90.0f, 1e-3f);
}

// The requirement: the angle estimate matches the true edge angle
// across 0-180 degrees. Tolerances, measured on 1-sample (aliased) edges at
// every 2.5 degrees and 3 sub-pixel offsets (staircases make single pixels
// look locally horizontal/vertical, hence a looser max than mean):
//   mean <= 4.5 deg, 95th percentile <= 11 deg, max <= 17 deg, and the median
//   error at every angle <= 9 deg. On anti-aliased edges mean <= 3 deg.
TEST(RepairAngle, MatchesTrueEdgeAngleAcross0To180) {
  Settings s;
  const AngleSummary aliased = measureAngles(s, 2.5, false);
  const AngleSummary smooth = measureAngles(s, 5.0, true);
  s.estimator = AngleEstimator::Thesis;
  const AngleSummary literal = measureAngles(s, 5.0, false);
  std::printf("[ repair ] angle error, regression, 1-sample edges (%ld px): mean %.2f  p95 %.2f  max %.2f  "
              "worst per-angle median %.2f deg\n",
              aliased.samples, aliased.mean, aliased.p95, aliased.max, aliased.worstAngleMedian);
  std::printf("[ repair ] angle error, regression, 4x4 supersampled edges: mean %.2f  p95 %.2f  max %.2f deg\n",
              smooth.mean, smooth.p95, smooth.max);
  std::printf("[ repair ] angle error, literal eq. 3.6 (for the record): mean %.2f  p95 %.2f  max %.2f deg\n",
              literal.mean, literal.p95, literal.max);
  EXPECT_LE(aliased.mean, 4.5);
  EXPECT_LE(aliased.p95, 11.0);
  EXPECT_LE(aliased.max, 17.0);
  EXPECT_LE(aliased.worstAngleMedian, 9.0);
  EXPECT_LE(smooth.mean, 3.0);
  EXPECT_GT(literal.mean, 20.0);  // eq. 3.6 literally is not an angle estimate
}

// ---- step 5 ----------------------------------------------------------------

TEST(RepairMask, RotationFollowsTheEdgeDirection) {
  // A one-tap mask at (w, h) = (1, 0) on the ramp f = x + 10 y (bilinear
  // interpolation reproduces it exactly) reads f at the rotated offset: eq. 3.7
  // must put tap w along the edge direction, (cos theta, -sin theta) in y-down
  // pixels for a screen angle theta.
  Image ramp(16, 16, 4);
  for (int y = 0; y < 16; ++y)
    for (int x = 0; x < 16; ++x)
      for (int k = 0; k < 4; ++k) ramp.at(x, y)[k] = float(x + 10 * y);
  repair::Mask oneTap;
  oneTap.radius = 1;
  oneTap.weights[1 * 3 + 2] = 1.0f;
  for (double deg : {0.0, 30.0, 90.0, 150.0, 179.0}) {
    const repair::Direction d{float(std::cos(deg * M_PI / 180)), float(std::sin(deg * M_PI / 180))};
    float out[4];
    repair::smoothPixel(ramp, 7, 8, d, oneTap, out);
    EXPECT_NEAR(out[0], (7.0 + std::cos(deg * M_PI / 180)) + 10.0 * (8.0 - std::sin(deg * M_PI / 180)), 2e-4) << deg;
  }
  // Both masks are normalised and sample the centre exactly at theta = 0.
  for (MaskKind m : {MaskKind::Gauss5, MaskKind::Box3}) {
    const repair::Mask& mask = repair::maskFor(m);
    float sum = 0;
    for (int i = 0; i < (2 * mask.radius + 1) * (2 * mask.radius + 1); ++i) sum += mask.weights[i];
    EXPECT_NEAR(sum, 1.0f, 1e-6f);
  }
}

// ---- the whole filter: quality ---------------------------------------------

TEST(RepairQuality, RaisesEdgePsnrOnChartAndSingleEdges) {
  const int W = 180, H = 120;
  const auto [one, reference, edges] = test::renderEdgeFrames(synth::testChart(W, H), W, H);
  const Image all(W, H, 1, 1.0f);
  const double before = test::maskedPsnr(reference, one, edges);
  for (MaskKind m : {MaskKind::Gauss5, MaskKind::Box3}) {
    Settings s;
    s.mask = m;
    repair::Kernel k;
    const Image out = runKernel(one, s, false, 0, &k);
    const double gain = test::maskedPsnr(reference, out, edges) - before;
    const double wholeGain = test::maskedPsnr(reference, out, all) - test::maskedPsnr(reference, one, all);
    std::printf("[ repair ] chart %dx%d mask %s: edge-pixel PSNR %.2f -> %.2f dB (%+.2f), whole image %+.2f dB, "
                "%.1f%% pixels filtered\n",
                W, H, m == MaskKind::Gauss5 ? "gauss5" : "box3", before, before + gain, gain, wholeGain,
                100.0 * double(k.edgeCount()) / (W * H));
    EXPECT_GT(gain, 0.5);
    EXPECT_GT(wholeGain, -0.3);  // the default kappa must not blur the picture as a whole
  }
  // Why kappa's default is 0 (the parameter table): the thesis's -1 gains more on edge pixels but
  // blurs the flanks of the Sobel band, which costs the image as a whole.
  double edgeGain[2], wholeGain[2];
  for (int i = 0; i < 2; ++i) {
    Settings s;
    s.kappa = i == 0 ? 0.0f : -1.0f;
    const Image out = runKernel(one, s, false, 0);
    edgeGain[i] = test::maskedPsnr(reference, out, edges) - before;
    wholeGain[i] = test::maskedPsnr(reference, out, all) - test::maskedPsnr(reference, one, all);
    std::printf("[ repair ] chart %dx%d kappa %g: edge-pixel PSNR %+.2f dB, whole image %+.2f dB\n", W, H,
                double(s.kappa), edgeGain[i], wholeGain[i]);
  }
  EXPECT_GT(edgeGain[1], edgeGain[0]);
  EXPECT_LT(wholeGain[1], wholeGain[0] - 0.3);
  // Single edges at many angles.
  const int size = 40;
  double sum = 0, worst = 1e9;
  std::string line;
  for (double angle = 4; angle < 180; angle += 16) {
    const synth::Scene scene = synth::edgeScene(size, size, float(angle), 0.3f);
    const auto [in, ref, mask] = test::renderEdgeFrames(scene, size, size);
    const double gain = test::maskedPsnr(ref, runKernel(in, Settings{}), mask) - test::maskedPsnr(ref, in, mask);
    char buf[32];
    std::snprintf(buf, sizeof buf, " %g:%+.2f", angle, gain);
    line += buf;
    sum += gain;
    worst = std::min(worst, gain);
    EXPECT_GT(gain, 0.0) << "edge at " << angle << " degrees";
  }
  std::printf("[ repair ] single-edge gains (deg:dB):%s\n", line.c_str());
  EXPECT_GT(sum / 11.0, 2.0);
}

TEST(RepairQuality, FlatImageIsUnchanged) {
  Image flat(17, 9, 4);
  for (int i = 0; i < 17 * 9; ++i) {
    flat.data[std::size_t(i) * 4 + 0] = 0.3f;
    flat.data[std::size_t(i) * 4 + 1] = 0.6f;
    flat.data[std::size_t(i) * 4 + 2] = 0.1f;
    flat.data[std::size_t(i) * 4 + 3] = 1.0f;
  }
  for (bool reference : {false, true}) {
    repair::Kernel k;
    const Image out = runKernel(flat, Settings{}, reference, 0, &k);
    EXPECT_EQ(k.edgeCount(), 0);
    EXPECT_EQ(std::memcmp(out.data.data(), flat.data.data(), flat.data.size() * 4), 0);
  }
}

TEST(RepairQuality, NonFiniteInputsGiveFiniteOutput) {
  Image im = randomImage(23, 17, 7);
  const float bad[] = {NAN, INFINITY, -INFINITY};
  for (int i = 0; i < 60; ++i) im.data[std::size_t(i * 29) % im.data.size()] = bad[i % 3];
  for (bool reference : {false, true}) {
    repair::Kernel k;
    const Image out = runKernel(im, Settings{}, reference, 0, &k);
    EXPECT_GT(k.edgeCount(), 0);
    for (float v : out.data) ASSERT_TRUE(std::isfinite(v));
  }
}

// README: "alpha as rendered. Alpha is not anti-aliased" (rsaa alone resamples it), and the add-on's
// log tells an artist with a transparent film that repair "anti-aliases the colour, not the alpha".
// An object on a transparent film (premultiplied colour, alpha 1 inside and 0 outside, a few
// fractional and non-finite alphas): the colour is smoothed on the outline, the alpha is the input's.
TEST(RepairQuality, OutputAlphaIsTheInputAlpha) {
  const int W = 37, H = 70;  // two bands of the fast path's first pass
  Image in(W, H, 4);
  for (int y = 0; y < H; ++y)
    for (int x = 0; x < W; ++x) {
      float a = float(y) < 0.6f * float(x) + 5.0f ? 1.0f : 0.0f;
      if ((x * 7 + y * 3) % 41 == 0) a = 0.5f;
      float* p = in.at(x, y);
      p[0] = 0.8f * a;
      p[1] = 0.4f * a;
      p[2] = 0.2f * a;
      p[3] = a;
    }
  in.at(3, 60)[3] = NAN;
  in.at(20, 10)[3] = INFINITY;
  for (bool reference : {true, false})
    for (int threads : {1, 0}) {
      for (bool inPlace : {false, true}) {
        repair::Kernel k;
        k.allocate(W, H);
        Image out = inPlace ? in : Image(W, H, 4);  // in place: the output is the colour buffer
        k.run(inPlace ? out.view() : in.view(), out.view(), Settings{}, reference, threads);
        ASSERT_GT(k.edgeCount(), 0);
        long colourChanged = 0;
        for (int y = 0; y < H; ++y)
          for (int x = 0; x < W; ++x) {
            colourChanged += out.at(x, y)[0] != sanitizeColor(in.at(x, y)[0]);
            ASSERT_EQ(out.at(x, y)[3], sanitizeColor(in.at(x, y)[3]))
                << "alpha changed at " << x << "," << y << (reference ? " (reference)" : " (fast)")
                << (inPlace ? " in place" : "");
          }
        EXPECT_GT(colourChanged, 20);
      }
    }
}

// ---- fast path == reference path ---------------------------------------------

namespace {
// Copies a packed RGBA image into a strided buffer with `channels` channels,
// `pad` extra floats per pixel and `rowPad` extra floats per row.
struct Strided {
  std::vector<float> data;
  ImageView view;
};
Strided stridedCopy(const Image& im, int channels, int pad, int rowPad) {
  Strided s;
  const int pixelFloats = channels + pad, rowFloats = pixelFloats * im.width + rowPad;
  s.data.assign(std::size_t(rowFloats) * std::size_t(im.height), -7.0f);
  for (int y = 0; y < im.height; ++y)
    for (int x = 0; x < im.width; ++x)
      for (int k = 0; k < channels; ++k)
        s.data[std::size_t(y) * rowFloats + std::size_t(x) * pixelFloats + k] = im.at(x, y)[k];
  s.view = makeView(s.data.data(), channels == 3 ? Format::Float3 : Format::Float4, im.width, im.height,
                    std::size_t(pixelFloats) * 4, std::size_t(rowFloats) * 4);
  return s;
}
}  // namespace

TEST(RepairPaths, FastIsBitIdenticalToReference) {
  std::vector<Image> inputs;
  inputs.push_back(synth::renderCentre(synth::testChart(120, 80), 120, 80));
  // 37x150: three bands of the fast path's first pass (grey rows recomputed at their edges).
  // 1x70 and 70x1: a single column over two bands, a single row (Sobel and patches clamp on both sides).
  for (auto [w, h] : {std::pair{1, 1}, {2, 3}, {17, 9}, {9, 17}, {33, 20}, {5, 64}, {37, 150}, {1, 70}, {70, 1}})
    inputs.push_back(randomImage(w, h, unsigned(w * 100 + h)));
  Image withBad = randomImage(31, 13, 3);
  withBad.data[5] = NAN;
  withBad.data[77] = INFINITY;
  withBad.data[300] = -INFINITY;
  inputs.push_back(withBad);
  long compared = 0;
  for (const Image& in : inputs)
    for (MaskKind m : {MaskKind::Gauss5, MaskKind::Box3})
      for (AngleEstimator e : {AngleEstimator::Regression, AngleEstimator::Thesis})
        for (float kappa : {-1.0f, 0.0f})
          for (int n : {3, 5, 7}) {
            Settings s;
            s.mask = m;
            s.estimator = e;
            s.kappa = kappa;
            s.patchSize = n;
            const Image expected = runKernel(in, s, true, 1);
            for (int threads : {0, 1, 2})
              for (repair::RowIsa isa : {repair::RowIsa::Auto, repair::RowIsa::Baseline}) {
                const Image fast = runKernel(in, s, false, threads, nullptr, isa);
                ASSERT_EQ(std::memcmp(fast.data.data(), expected.data.data(), expected.data.size() * 4), 0)
                    << in.width << "x" << in.height << " threads " << threads << " n " << n << " rows "
                    << repair::rowIsaName(isa);
                ++compared;
              }
          }
  // Strided 3/4-channel views and in-place filtering.
  for (const Image& in : inputs) {
    const Image expected = runKernel(in, Settings{}, true, 1);
    for (int channels : {3, 4})
      for (auto [pad, rowPad] : {std::pair{0, 0}, {1, 3}, {2, 0}}) {
        Strided src = stridedCopy(in, channels, pad, rowPad);
        Strided dst = stridedCopy(Image(in.width, in.height, 4), channels, pad + 1, rowPad);
        repair::Kernel k;
        k.allocate(in.width, in.height);
        k.setRowIsa(pad == 1 ? repair::RowIsa::Baseline : repair::RowIsa::Auto);
        for (bool reference : {false, true}) {
          k.run(src.view, dst.view, Settings{}, reference, 0);
          Strided inPlace = stridedCopy(in, channels, pad, rowPad);
          k.run(inPlace.view, inPlace.view, Settings{}, reference, 0);
          const ImageView& o = dst.view;
          const ImageView& p = inPlace.view;
          for (int y = 0; y < in.height; ++y)
            for (int x = 0; x < in.width; ++x)
              for (int c = 0; c < channels; ++c) {
                ASSERT_EQ(std::memcmp(o.pixel(x, y) + c, p.pixel(x, y) + c, 4), 0) << "in-place differs";
                // RGB does not depend on alpha, so 3-channel views match the 4-channel reference too.
                ASSERT_EQ(std::memcmp(o.pixel(x, y) + c, expected.at(x, y) + c, 4), 0)
                    << in.width << "x" << in.height << " channels " << channels << " pad " << pad;
              }
          ++compared;
        }
      }
  }
  std::printf("[ repair ] fast == reference on %ld configurations (row loops: %s and %s)\n", compared,
              repair::rowIsaName(repair::RowIsa::Auto), repair::rowIsaName(repair::RowIsa::Baseline));
}

// ---- through the Filter interface ------------------------------------------------

TEST(RepairFilter, RunsThroughFilterInterfaceWithStridedViews) {
  Context context;
  auto filter = createFilter(context, "repair");
  const Image in = synth::renderCentre(synth::testChart(60, 40), 60, 40);
  Strided src = stridedCopy(in, 3, 1, 5);
  Strided dst = stridedCopy(Image(60, 40, 4), 4, 0, 2);
  filter->setImage("color", src.view);
  filter->setImage("output", dst.view);
  filter->params().setString("mask", "box3");
  filter->params().setFloat("kappa", -0.5f);
  filter->commit();
  filter->execute();
  // The same through the kernel on the packed image (alpha 1 for 3 channels).
  Settings s;
  s.mask = MaskKind::Box3;
  s.kappa = -0.5f;
  Image packed = in;
  for (int i = 0; i < 60 * 40; ++i) packed.data[std::size_t(i) * 4 + 3] = 1.0f;
  const Image expected = runKernel(packed, s);
  long changed = 0;
  for (int y = 0; y < 40; ++y)
    for (int x = 0; x < 60; ++x)
      for (int c = 0; c < 4; ++c) {
        ASSERT_EQ(dst.view.pixel(x, y)[c], expected.at(x, y)[c]) << x << "," << y << "," << c;
        changed += dst.view.pixel(x, y)[c] != in.at(x, y)[c] && c < 3;
      }
  EXPECT_GT(changed, 0);
  // Padding between pixels/rows of the output is never written.
  EXPECT_EQ(dst.data[std::size_t(60 * 4)], -7.0f);

  // The reference path through the same filter gives the same output.
  std::vector<float> first(dst.data);
  filter->params().setBool("reference", true);
  filter->commit();
  filter->execute();
  EXPECT_EQ(std::memcmp(first.data(), dst.data.data(), first.size() * 4), 0);
}

TEST(RepairFilter, BadParametersNameTheParameter) {
  Context context;
  auto filter = createFilter(context, "repair");
  Image in(8, 8, 4), out(8, 8, 4);
  filter->setImage("color", in.view());
  filter->setImage("output", out.view());
  filter->params().setInt("patchSize", 4);
  try {
    filter->commit();
    FAIL() << "even patchSize accepted";
  } catch (const Exception& e) {
    EXPECT_NE(std::string(e.what()).find("patchSize"), std::string::npos) << e.what();
  }
  EXPECT_THROW(filter->params().setInt("patchSize", 17), Exception);
  EXPECT_THROW(filter->params().setString("mask", "gauss7"), Exception);
  EXPECT_THROW(filter->params().setString("angleEstimator", "magic"), Exception);
  const std::string doc = filter->doc();
  for (const char* name : {"kappa", "patchSize", "mask", "angleEstimator", "reference", "eq. 3.1", "eq. 3.7"})
    EXPECT_NE(doc.find(name), std::string::npos) << name;
}
