// SPDX-License-Identifier: Apache-2.0
// The FLIP-style perceptual error (native/metrics/flip.h): range, identity,
// symmetry, monotonicity, locality, the observer's distance, bad input.
#include <gtest/gtest.h>

#include <cmath>
#include <functional>
#include <random>
#include <string>
#include <vector>

#include "core/color.h"
#include "core/error.h"
#include "metrics/flip.h"
#include "metrics/metrics.h"
#include "synth/synthetic.h"
#include "test_util.h"

using namespace crisp;

namespace {

Image srgbImage(int w, int h, const std::function<float(int, int, int)>& value) {
  Image im(w, h, 3);
  for (int y = 0; y < h; ++y)
    for (int x = 0; x < w; ++x)
      for (int c = 0; c < 3; ++c) im.at(x, y)[c] = value(x, y, c);
  return im;
}

Image randomSrgb(int w, int h, unsigned seed) {
  std::mt19937 rng(seed);
  std::uniform_real_distribution<float> u(0.0f, 1.0f);
  return srgbImage(w, h, [&](int, int, int) { return u(rng); });
}

double mean(const Image& map) {
  double s = 0;
  for (float v : map.data) s += v;
  return s / double(map.data.size());
}

}  // namespace

TEST(Flip, IdenticalImagesGiveZero) {
  const Image a = randomSrgb(37, 23, 1);
  const Image map = flipErrorMap(a, a);
  ASSERT_EQ(map.width, 37);
  ASSERT_EQ(map.height, 23);
  ASSERT_EQ(map.channels, 1);
  for (float v : map.data) ASSERT_EQ(v, 0.0f);
}

TEST(Flip, InUnitRangeAndSymmetric) {
  const Image a = randomSrgb(40, 32, 2), b = randomSrgb(40, 32, 3);
  const Image ab = flipErrorMap(a, b), ba = flipErrorMap(b, a);
  for (float v : ab.data) {
    ASSERT_GE(v, 0.0f);
    ASSERT_LE(v, 1.0f);
  }
  EXPECT_EQ(ab.data, ba.data);
  EXPECT_GT(mean(ab), 0.1);
}

TEST(Flip, BlackVersusWhiteIsNearlyMaximal) {
  const Image black(24, 24, 3, 0.0f), white(24, 24, 3, 1.0f);
  const Image map = flipErrorMap(black, white);
  for (float v : map.data) ASSERT_GT(v, 0.9f);
  // Green vs blue is the largest colour difference the model knows: exactly 1.
  const Image green = srgbImage(8, 8, [](int, int, int c) { return c == 1 ? 1.0f : 0.0f; });
  const Image blue = srgbImage(8, 8, [](int, int, int c) { return c == 2 ? 1.0f : 0.0f; });
  for (float v : flipErrorMap(green, blue).data) ASSERT_NEAR(v, 1.0f, 1e-5f);
}

TEST(Flip, GrowsWithTheDifference) {
  const Image grey(16, 16, 3, 0.5f);
  double previous = 0;
  for (float d : {0.01f, 0.03f, 0.1f, 0.3f, 0.5f}) {
    const double e = mean(flipErrorMap(grey, Image(16, 16, 3, 0.5f + d)));
    EXPECT_GT(e, previous) << "offset " << d;
    previous = e;
  }
}

TEST(Flip, ErrorStaysLocal) {
  // Only pixels whose filter footprint reaches the changed pixel may differ
  // from 0; the widest footprint at 67 ppd is the blue-yellow CSF's ceil(3 sigma).
  const int n = 64, cx = 30, cy = 33;
  const Image a = srgbImage(n, n, [](int x, int y, int c) { return 0.3f + 0.004f * float(x + y + c); });
  Image b = a;
  b.at(cx, cy)[0] = 1.0f;
  const Image map = flipErrorMap(a, b);
  const int reach = int(std::ceil(3.0 * std::sqrt(0.04 / (2 * M_PI * M_PI)) * 67.0));
  EXPECT_GT(*map.at(cx, cy), 0.1f);
  for (int y = 0; y < n; ++y)
    for (int x = 0; x < n; ++x)
      if (std::max(std::abs(x - cx), std::abs(y - cy)) > reach) {
        ASSERT_EQ(*map.at(x, y), 0.0f) << x << "," << y;
      }
}

TEST(Flip, FinePatternFadesWithViewingDistance) {
  // 1-pixel black/white stripes vs the grey of the same linear luminance: the
  // contrast sensitivity filters blur the stripes away as pixels per degree grow.
  const Image stripes = srgbImage(48, 48, [](int x, int, int) { return float(x % 2); });
  const Image grey(48, 48, 3, srgbEncode(0.5f));
  double previous = 2.0;
  for (float ppd : {15.0f, 30.0f, 67.0f, 150.0f}) {
    const double e = mean(flipErrorMap(stripes, grey, ppd));
    EXPECT_LT(e, previous) << ppd << " ppd";
    previous = e;
  }
  EXPECT_LT(previous, 0.05);
}

TEST(Flip, AntialiasedEdgeBeatsAliasedOneAgainstTheReference) {
  const int w = 64, h = 48;
  const synth::Scene scene = synth::edgeScene(w, h, 30.0f);
  const Image ref = displayEncode(synth::renderSupersampled(scene, w, h, 8));
  const Image aliased = displayEncode(synth::renderCentre(scene, w, h));
  // An edge half a pixel off is an error too.
  const Image shifted = displayEncode(synth::renderCentre(scene, w, h, 0.5f, 0.0f));
  const double eAliased = mean(flipErrorMap(ref, aliased));
  EXPECT_GT(eAliased, 0.0);
  EXPECT_LT(eAliased, 0.5);
  EXPECT_GT(mean(flipErrorMap(ref, shifted)), 0.0);
}

TEST(Flip, ExtremeObserversStayFiniteAndInRange) {
  const Image a = randomSrgb(24, 20, 6), b = randomSrgb(24, 20, 7);
  for (float ppd : {0.1f, 1.0f, 400.0f, 1000.0f}) {
    const Image map = flipErrorMap(a, b, ppd);
    for (float v : map.data) {
      ASSERT_TRUE(v >= 0.0f && v <= 1.0f) << ppd << " ppd: " << v;
    }
    EXPECT_EQ(flipErrorMap(a, a, ppd).data, std::vector<float>(map.data.size(), 0.0f)) << ppd;
  }
}

TEST(Flip, IndependentOfThreadCount) {
  const Image a = randomSrgb(200, 90, 4), b = randomSrgb(200, 90, 5);
  const Image one = flipErrorMap(a, b, 67.0f, 1);
  for (int threads : {2, 0}) EXPECT_EQ(flipErrorMap(a, b, 67.0f, threads).data, one.data) << threads;
}

TEST(Flip, BadInput) {
  const Image a(8, 8, 3), b(8, 9, 3), rgba(8, 8, 4);
  EXPECT_EQ(test::errorCode([&] { flipErrorMap(a, b); }), CRISP_ERROR_INVALID_DATA);
  EXPECT_EQ(test::errorCode([&] { flipErrorMap(a, rgba); }), CRISP_ERROR_INVALID_DATA);
  EXPECT_EQ(test::errorCode([&] { flipErrorMap(Image(), Image()); }), CRISP_ERROR_INVALID_DATA);
  for (float ppd : {0.0f, -5.0f, std::nanf(""), 5000.0f})
    EXPECT_EQ(test::errorCode([&] { flipErrorMap(a, a, ppd); }), CRISP_ERROR_INVALID_ARGUMENT) << ppd;
  try {
    flipErrorMap(a, b);
  } catch (const Exception& e) {
    EXPECT_NE(std::string(e.what()).find("8x9"), std::string::npos) << e.what();
  }
}
