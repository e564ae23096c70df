// SPDX-License-Identifier: Apache-2.0
// Metrics (native/metrics/metrics.h): analytic cases, a brute-force SSIM, masks,
// maps, thread-count independence and bad input.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <cstring>
#include <functional>
#include <random>
#include <string>
#include <vector>

#include "core/color.h"
#include "core/error.h"
#include "metrics/metrics.h"
#include "metrics/power_table.h"
#include "test_util.h"

using namespace crisp;
using test::fromEncoded;

namespace {

constexpr double kC1 = 0.01 * 0.01, kC2 = 0.03 * 0.03;  // Wang 2004 with L = 1

Image randomImage(int w, int h, unsigned seed, float lo = 0.0f, float hi = 1.0f) {
  std::mt19937 rng(seed);
  std::uniform_real_distribution<float> u(lo, hi);
  Image im(w, h, 4, 1.0f);
  for (int y = 0; y < h; ++y)
    for (int x = 0; x < w; ++x)
      for (int c = 0; c < 3; ++c) im.at(x, y)[c] = u(rng);
  return im;
}

// Smooth structure plus a bright disk: something SSIM has to look at.
Image structuredImage(int w, int h, float phase) {
  return fromEncoded(w, h, [=](int x, int y, int c) {
    const float dx = float(x) - 0.4f * float(w), dy = float(y) - 0.6f * float(h);
    const bool disk = dx * dx + dy * dy < 0.04f * float(w * w);
    const float wave = 0.5f + 0.3f * std::sin(0.31f * float(x) + phase + float(c)) * std::cos(0.17f * float(y));
    return disk ? 0.9f - 0.1f * float(c) : wave;
  });
}

double mapMean(const Image& map, const Image* mask = nullptr) {
  double s = 0;
  long n = 0;
  for (int y = 0; y < map.height; ++y)
    for (int x = 0; x < map.width; ++x)
      if (!mask || *mask->at(x, y) > 0) {
        s += *map.at(x, y);
        ++n;
      }
  return s / double(n);
}

// Straightforward 2-D SSIM with an 11x11 Gaussian window on a mirrored image,
// written independently of metrics.cpp (folding loop instead of modulo, 2-D
// window instead of separable passes).
// The encoding is the library's displayEncode (checked on its own elsewhere),
// so this isolates the window, border and formula.
std::vector<double> bruteForceSsim(const Image& refLinear, const Image& testLinear) {
  const int w = refLinear.width, h = refLinear.height;
  const Image refEnc = displayEncode(refLinear), testEnc = displayEncode(testLinear);
  auto lumaAt = [&](const Image& linear, int x, int y) {
    auto fold = [](int i, int n) {
      while (i < 0 || i >= n) i = i < 0 ? -i - 1 : 2 * n - i - 1;
      return i;
    };
    const float* p = (&linear == &refLinear ? refEnc : testEnc).at(fold(x, w), fold(y, h));
    return 0.299 * p[0] + 0.587 * p[1] + 0.114 * p[2];
  };
  double g[11], gs = 0;
  for (int i = -5; i <= 5; ++i) gs += g[i + 5] = std::exp(-double(i * i) / (2 * 1.5 * 1.5));
  std::vector<double> out(std::size_t(w * h));
  for (int y = 0; y < h; ++y)
    for (int x = 0; x < w; ++x) {
      double mx = 0, my = 0, mxx = 0, myy = 0, mxy = 0;
      for (int j = -5; j <= 5; ++j)
        for (int i = -5; i <= 5; ++i) {
          const double wt = g[i + 5] * g[j + 5] / (gs * gs);
          const double a = lumaAt(refLinear, x + i, y + j), b = lumaAt(testLinear, x + i, y + j);
          mx += wt * a;
          my += wt * b;
          mxx += wt * a * a;
          myy += wt * b * b;
          mxy += wt * a * b;
        }
      const double vx = mxx - mx * mx, vy = myy - my * my, vxy = mxy - mx * my;
      out[std::size_t(y * w + x)] = (2 * mx * my + kC1) * (2 * vxy + kC2) / ((mx * mx + my * my + kC1) * (vx + vy + kC2));
    }
  return out;
}

}  // namespace

TEST(Metrics, IdenticalImages) {
  const Image a = randomImage(40, 30, 1, -0.2f, 1.5f);  // out-of-range values are clamped by the encoding
  const Metrics m = compareImages(a, a);
  EXPECT_EQ(m.mse, 0.0);
  EXPECT_EQ(m.rmse, 0.0);
  EXPECT_EQ(m.psnr, 100.0);
  EXPECT_EQ(m.snr, 100.0);
  EXPECT_NEAR(m.ssim, 1.0, 1e-12);
  EXPECT_EQ(m.flip, 0.0);
  EXPECT_EQ(m.pixels, 40 * 30);
}

TEST(Metrics, ConstantOffsetInEncodedSpace) {
  for (float d : {0.01f, 0.05f, 0.2f}) {
    std::mt19937 rng(7);
    std::uniform_real_distribution<float> u(0.05f, 0.7f);
    std::vector<float> base(24 * 20 * 3);
    for (float& v : base) v = u(rng);
    auto at = [&](int x, int y, int c) { return base[std::size_t((y * 24 + x) * 3 + c)]; };
    const Image ref = fromEncoded(24, 20, at);
    const Image test = fromEncoded(24, 20, [&](int x, int y, int c) { return at(x, y, c) + d; });
    const Metrics m = compareImages(ref, test);
    // Encode(decode(v)) round-trips to ~1e-7, so d^2 holds to ~1e-8 absolute.
    EXPECT_NEAR(m.mse, double(d) * d, 2e-7 * d) << "d " << d;
    EXPECT_NEAR(m.rmse, double(d), 2e-6) << "d " << d;
    EXPECT_NEAR(m.psnr, -20.0 * std::log10(double(d)), 1e-3) << "d " << d;
    EXPECT_NEAR(m.psnr, 10.0 * std::log10(1.0 / m.mse), 1e-9);
    EXPECT_LT(m.ssim, 1.0);
  }
}

TEST(Metrics, SnrOfFlatImages) {
  // Reference a, test a + d everywhere: SNR = 10 log10(a^2 / d^2).
  const float a = 0.6f, d = 0.15f;
  const Image ref = fromEncoded(16, 16, [&](int, int, int) { return a; });
  const Image test = fromEncoded(16, 16, [&](int, int, int) { return a + d; });
  const Metrics m = compareImages(ref, test);
  EXPECT_NEAR(m.snr, 20.0 * std::log10(double(a) / double(d)), 1e-4);
  // Black reference, different test: no signal, the floor.
  const Image black(8, 8, 3, 0.0f);
  EXPECT_EQ(compareImages(black, Image(8, 8, 3, 0.5f)).snr, -100.0);
}

TEST(Metrics, SsimOfFlatImages) {
  // Flat luma a vs b: variances vanish, SSIM = (2ab + C1) / (a^2 + b^2 + C1) (Wang 2004 eq. 13).
  for (auto [a, b] : {std::pair{0.2f, 0.25f}, std::pair{0.5f, 0.9f}, std::pair{0.05f, 0.6f}}) {
    const Image ref = fromEncoded(20, 14, [a = a](int, int, int) { return a; });
    const Image test = fromEncoded(20, 14, [b = b](int, int, int) { return b; });
    const double ea = srgbEncode(srgbDecode(a)), eb = srgbEncode(srgbDecode(b));
    const double expected = (2 * ea * eb + kC1) / (ea * ea + eb * eb + kC1);
    EXPECT_NEAR(compareImages(ref, test).ssim, expected, 1e-6) << a << " vs " << b;
  }
}

TEST(Metrics, SsimFallsWithContrastLoss) {
  const Image ref = structuredImage(48, 40, 0.0f);
  double previous = 1.0;
  for (float keep : {0.9f, 0.6f, 0.3f}) {
    // Same local means' neighbourhood, contrast scaled around mid-grey in encoded space.
    const Image test = fromEncoded(48, 40, [&](int x, int y, int c) {
      return 0.5f + keep * (srgbEncode(ref.at(x, y)[c]) - 0.5f);
    });
    const double s = compareImages(ref, test).ssim;
    EXPECT_LT(s, previous) << "keep " << keep;
    EXPECT_GT(s, 0.0);
    previous = s;
  }
}

TEST(Metrics, SsimMatchesBruteForceWindowWithMirroredBorders) {
  for (auto [w, h] : {std::pair{23, 17}, std::pair{7, 12}, std::pair{3, 2}}) {
    const Image ref = structuredImage(w, h, 0.0f);
    const Image test = randomImage(w, h, unsigned(w * 100 + h));
    Image ssimMap;
    MetricMaps maps;
    maps.ssim = &ssimMap;
    const Metrics m = compareImages(ref, test, nullptr, maps, 1);
    const std::vector<double> expected = bruteForceSsim(ref, test);
    double mean = 0;
    for (int y = 0; y < h; ++y)
      for (int x = 0; x < w; ++x) {
        const double e = expected[std::size_t(y * w + x)];
        mean += e;
        ASSERT_NEAR(*ssimMap.at(x, y), e, 1e-6) << w << "x" << h << " at " << x << "," << y;
      }
    EXPECT_NEAR(m.ssim, mean / double(w * h), 1e-10) << w << "x" << h;
  }
}

TEST(Metrics, SymmetricWhereItShouldBe) {
  const Image a = structuredImage(33, 29, 0.0f), b = structuredImage(33, 29, 0.7f);
  const Metrics ab = compareImages(a, b), ba = compareImages(b, a);
  EXPECT_EQ(ab.mse, ba.mse);
  EXPECT_EQ(ab.psnr, ba.psnr);
  EXPECT_EQ(ab.ssim, ba.ssim);
  EXPECT_EQ(ab.flip, ba.flip);
  EXPECT_NE(ab.snr, ba.snr);  // SNR uses the reference's energy: not symmetric
}

TEST(Metrics, MaskRestrictsCounting) {
  const int w = 32, h = 16;
  const Image ref = randomImage(w, h, 3);
  Image test = ref;
  for (int y = 0; y < h; ++y)  // change the left half only
    for (int x = 0; x < w / 2; ++x) test.at(x, y)[1] = srgbDecode(std::min(1.0f, srgbEncode(ref.at(x, y)[1]) + 0.3f));
  Image left(w, h, 1, 0.0f), right(w, h, 1, 0.0f);
  for (int y = 0; y < h; ++y)
    for (int x = 0; x < w; ++x) *(x < w / 2 ? left : right).at(x, y) = 1.0f;
  const Metrics all = compareImages(ref, test);
  const Metrics l = compareImages(ref, test, &left);
  const Metrics r = compareImages(ref, test, &right);
  EXPECT_EQ(l.pixels, w * h / 2);
  EXPECT_EQ(r.pixels, w * h / 2);
  EXPECT_EQ(r.mse, 0.0);
  EXPECT_EQ(r.psnr, 100.0);
  EXPECT_GT(l.mse, 0.0);
  EXPECT_NEAR(l.mse, 2.0 * all.mse, 1e-12);
  // SSIM and FLIP spread across the boundary, but the untouched half still scores better.
  EXPECT_GT(r.ssim, l.ssim);
  EXPECT_LT(r.flip, l.flip);
  // Negative and NaN mask values do not count.
  Image odd = left;
  *odd.at(w - 1, 0) = -1.0f;
  *odd.at(w - 2, 0) = std::nanf("");
  EXPECT_EQ(compareImages(ref, test, &odd).pixels, w * h / 2);
}

TEST(Metrics, MapsHaveTheImageSizeAndAverageToTheFigures) {
  const int w = 41, h = 27;
  const Image ref = structuredImage(w, h, 0.0f), test = structuredImage(w, h, 0.4f);
  Image mask(w, h, 1, 0.0f);
  for (int y = 0; y < h; ++y)
    for (int x = 0; x < w; ++x) *mask.at(x, y) = (x * 7 + y * 3) % 5 < 2 ? 1.0f : 0.0f;
  for (const Image* m : {static_cast<const Image*>(nullptr), static_cast<const Image*>(&mask)}) {
    Image err, ssim, flip;
    const Metrics r = compareImages(ref, test, m, MetricMaps{&err, &ssim, &flip});
    for (const Image* map : {&err, &ssim, &flip}) {
      EXPECT_EQ(map->width, w);
      EXPECT_EQ(map->height, h);
      EXPECT_EQ(map->channels, 1);
    }
    EXPECT_NEAR(mapMean(err, m), r.mse, 1e-6 * r.mse);
    EXPECT_NEAR(mapMean(ssim, m), r.ssim, 1e-6);
    EXPECT_NEAR(mapMean(flip, m), r.flip, 1e-6);
    EXPECT_GT(r.flip, 0.0);
  }
}

TEST(Metrics, IndependentOfThreadCount) {
  // Large enough (> 8192 pixels) for parallelRows to split it.
  const int w = 256, h = 144;
  const Image ref = structuredImage(w, h, 0.0f), test = randomImage(w, h, 11, 0.0f, 0.8f);
  auto run = [&](int threads, Image& err, Image& ssim, Image& flip) {
    return compareImages(ref, test, nullptr, MetricMaps{&err, &ssim, &flip}, threads);
  };
  Image e1, s1, f1;
  const Metrics m1 = run(1, e1, s1, f1);
  for (int threads : {2, 0, 3}) {
    Image e, s, f;
    const Metrics m = run(threads, e, s, f);
    EXPECT_EQ(std::memcmp(&m, &m1, sizeof(Metrics)), 0) << threads << " threads";
    EXPECT_EQ(e.data, e1.data) << threads << " threads";
    EXPECT_EQ(s.data, s1.data) << threads << " threads";
    EXPECT_EQ(f.data, f1.data) << threads << " threads";
  }
}

TEST(Metrics, SizeMismatchNamesBothSizes) {
  try {
    compareImages(Image(64, 48, 4), Image(64, 50, 4));
    FAIL() << "no exception";
  } catch (const Exception& e) {
    EXPECT_EQ(e.code(), CRISP_ERROR_INVALID_DATA);
    const std::string msg = e.what();
    EXPECT_NE(msg.find("64x48"), std::string::npos) << msg;
    EXPECT_NE(msg.find("64x50"), std::string::npos) << msg;
  }
}

TEST(Metrics, BadInputIsInvalidData) {
  const Image rgb(8, 8, 3, 0.5f), rgba(8, 8, 4, 0.5f), grey(8, 8, 1, 0.5f);
  EXPECT_EQ(test::errorCode([&] { compareImages(rgb, rgba); }), CRISP_ERROR_INVALID_DATA);  // channel mismatch
  EXPECT_EQ(test::errorCode([&] { compareImages(grey, grey); }), CRISP_ERROR_INVALID_DATA);
  EXPECT_EQ(test::errorCode([&] { compareImages(Image(), Image()); }), CRISP_ERROR_INVALID_DATA);
  const Image wrongMask(8, 7, 1, 1.0f), twoChannelMask(8, 8, 2, 1.0f), emptyMask(8, 8, 1, 0.0f);
  EXPECT_EQ(test::errorCode([&] { compareImages(rgb, rgb, &wrongMask); }), CRISP_ERROR_INVALID_DATA);
  EXPECT_EQ(test::errorCode([&] { compareImages(rgb, rgb, &twoChannelMask); }), CRISP_ERROR_INVALID_DATA);
  EXPECT_EQ(test::errorCode([&] { compareImages(rgb, rgb, &emptyMask); }), CRISP_ERROR_INVALID_DATA);
  EXPECT_EQ(test::errorCode([&] { displayEncode(grey); }), CRISP_ERROR_INVALID_DATA);
  Image ssimMap;
  CompareOptions noSsim;
  noSsim.ssim = false;
  EXPECT_EQ(
      test::errorCode([&] { compareImages(rgb, rgb, nullptr, MetricMaps{nullptr, &ssimMap, nullptr}, 0, noSsim); }),
      CRISP_ERROR_INVALID_ARGUMENT);
}

TEST(Metrics, NonFiniteAndTinyImages) {
  Image ref(1, 1, 3, 0.5f), test(1, 1, 3, 0.5f);
  test.at(0, 0)[0] = std::nanf("");                          // encodes as 0
  test.at(0, 0)[1] = std::numeric_limits<float>::infinity();  // encodes as 1
  const Metrics m = compareImages(ref, test);
  const double e = srgbEncode(0.5f);
  EXPECT_NEAR(m.mse, (e * e + (1 - e) * (1 - e)) / 3.0, 1e-7);
  EXPECT_TRUE(std::isfinite(m.ssim));
  EXPECT_TRUE(std::isfinite(m.flip));
  for (auto [w, h] : {std::pair{1, 1}, std::pair{2, 3}, std::pair{5, 1}}) {
    const Image a = randomImage(w, h, 5);
    const Metrics same = compareImages(a, a);
    EXPECT_NEAR(same.ssim, 1.0, 1e-12);
    EXPECT_EQ(same.flip, 0.0);
  }
}

TEST(Metrics, OptionsSwitchFiguresOff) {
  const Image a = structuredImage(20, 20, 0.0f), b = structuredImage(20, 20, 1.0f);
  CompareOptions cheap;
  cheap.ssim = false;
  cheap.flip = false;
  const Metrics full = compareImages(a, b), part = compareImages(a, b, nullptr, {}, 0, cheap);
  EXPECT_EQ(part.mse, full.mse);
  EXPECT_EQ(part.snr, full.snr);
  EXPECT_EQ(part.ssim, 0.0);
  EXPECT_EQ(part.flip, 0.0);
  EXPECT_GT(full.flip, 0.0);
}

TEST(Metrics, DisplayEncodeDropsAlphaAndClamps) {
  Image im(3, 1, 4, 1.0f);
  const float values[3][3] = {{-1.0f, 0.0f, 0.002f}, {0.18f, 0.5f, 1.0f}, {2.0f, std::nanf(""), 0.7f}};
  for (int x = 0; x < 3; ++x)
    for (int c = 0; c < 3; ++c) im.at(x, 0)[c] = values[x][c];
  const Image enc = displayEncode(im);
  ASSERT_EQ(enc.channels, 3);
  for (int x = 0; x < 3; ++x)
    for (int c = 0; c < 3; ++c) {
      const float v = enc.at(x, 0)[c];
      EXPECT_GE(v, 0.0f);
      EXPECT_LE(v, 1.0f);
      if (std::isfinite(values[x][c])) {
        EXPECT_NEAR(v, srgbEncode(values[x][c]), 3e-7);
      }
    }
  EXPECT_EQ(enc.at(0, 0)[0], 0.0f);
  EXPECT_NEAR(enc.at(2, 0)[0], 1.0f, 1e-7f);  // 1.055 - 0.055 in float: 0.99999994
  EXPECT_EQ(enc.at(2, 0)[1], 0.0f);  // NaN
  EXPECT_NEAR(enc.at(1, 0)[1], 0.7354f, 1e-4);  // sRGB of 0.5 (IEC 61966-2-1)
}

TEST(Metrics, TabulatedPowersMatchTheExactFunctions) {
  // Every 257th float in [0, 1] (~4M values), against the functions in double.
  double worstEncode = 0, worstDecode = 0, worstCbrt = 0;
  const std::uint32_t one = 0x3f800000u;
  for (std::uint32_t bits = 0; bits <= one; bits += 257) {
    float v;
    std::memcpy(&v, &bits, 4);
    const double d = v;
    const double encode = d <= 0.0031308 ? 12.92 * d : 1.055 * std::pow(d, 1 / 2.4) - 0.055;
    const double decode = d <= 0.04045 ? d / 12.92 : std::pow((d + 0.055) / 1.055, 2.4);
    worstEncode = std::max(worstEncode, std::fabs(metrics_detail::fastSrgbEncode(v) - encode));
    worstDecode = std::max(worstDecode, std::fabs(metrics_detail::fastSrgbDecode(v) - decode));
    if (v > 0.008856f) worstCbrt = std::max(worstCbrt, std::fabs(metrics_detail::fastCbrt(v) - std::cbrt(d)));
  }
  EXPECT_LT(worstEncode, 2.5e-7);
  EXPECT_LT(worstDecode, 1.5e-7);
  EXPECT_LT(worstCbrt, 2e-7);
  std::printf("tabulated powers, worst absolute error: encode %.3g decode %.3g cbrt %.3g\n", worstEncode, worstDecode,
              worstCbrt);
}
