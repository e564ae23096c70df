// SPDX-License-Identifier: Apache-2.0
// Temporal error (native/metrics/temporal_error.h, METHODS.md Metrics):
// analytic cases on display-encoded values, the warp along motion vectors,
// the valid set (off-screen, mask), the per-pixel map and bad input.
#include <gtest/gtest.h>

#include <cmath>
#include <functional>

#include "core/color.h"
#include "core/error.h"
#include "metrics/temporal_error.h"
#include "test_util.h"

using namespace crisp;
using test::fromEncoded;

namespace {

// A pattern in display values, shifted right by `shift` pixels.
Image stripes(int w, int h, int shift) {
  return fromEncoded(w, h, [&](int x, int y, int c) { return float(((x - shift) * 7 + y * 3 + c) % 11) / 10.0f; });
}

Image constantMotion(int w, int h, float mx, float my) {
  Image m(w, h, 2);
  for (std::size_t i = 0; i < m.data.size(); i += 2) m.data[i] = mx, m.data[i + 1] = my;
  return m;
}

}  // namespace

// A still reference and an output that flickers by +-d in display units: TE =
// |2d| on the pixels that flicker; an output that follows the reference's own
// changes exactly has TE 0.
TEST(TemporalError, FlickerOnAStillReferenceCountsInDisplayUnits) {
  const int w = 12, h = 8;
  const Image ref = fromEncoded(w, h, [](int, int, int) { return 0.5f; });
  const Image a = fromEncoded(w, h, [](int x, int, int) { return x < 6 ? 0.5f : 0.45f; });
  const Image b = fromEncoded(w, h, [](int x, int, int) { return x < 6 ? 0.5f : 0.55f; });
  Image map;
  const TemporalError te = temporalError(b, a, ref, ref, nullptr, nullptr, 1, &map);
  EXPECT_EQ(te.pixels, long(w * h));
  EXPECT_NEAR(te.value, 0.5 * 0.1, 1e-5);  // half the pixels change by 0.1
  EXPECT_NEAR(map.at(8, 3)[0], 0.1f, 1e-5f);
  EXPECT_EQ(map.at(2, 3)[0], 0.0f);
  const Image refA = stripes(w, h, 0), refB = fromEncoded(w, h, [](int x, int y, int c) {
    return float(((x * 7 + y * 3 + c) % 11)) / 10.0f * 0.5f + 0.2f;
  });
  EXPECT_NEAR(temporalError(refB, refA, refB, refA).value, 0.0, 1e-9);
}

// A pattern translated by whole pixels: with the true motion vectors the warp
// lines the frames up and a perfect output has TE 0 while a frozen output
// (the previous frame again) does not; without them even the reference seems
// to change. Pixels whose previous position lies off-screen are not counted.
TEST(TemporalError, WarpFollowsMotionAndSkipsOffScreenPixels) {
  const int w = 16, h = 8;
  const Image previous = stripes(w, h, 0), current = stripes(w, h, 2);
  const Image motion = constantMotion(w, h, -2.0f, 0.0f);  // pixel p was at p - (2, 0)
  const TemporalError perfect = temporalError(current, previous, current, previous, &motion);
  EXPECT_NEAR(perfect.value, 0.0, 1e-9);
  EXPECT_EQ(perfect.pixels, long((w - 2) * h));  // columns 0 and 1 came from off-screen
  const TemporalError frozen = temporalError(previous, previous, current, previous, &motion);
  EXPECT_GT(frozen.value, 0.05);
  const TemporalError unwarped = temporalError(current, previous, current, previous);
  EXPECT_NEAR(unwarped.value, 0.0, 1e-9);  // out and reference change alike: no flicker either way
  EXPECT_EQ(unwarped.pixels, long(w * h));
}

// The mask removes pixels from the mean, the map is 0 there, and the map's
// mean over counted pixels is the value.
TEST(TemporalError, MaskAndMapAgreeWithTheValue) {
  const int w = 10, h = 6;
  const Image ref = stripes(w, h, 0), refPrev = stripes(w, h, 1);
  const Image out = fromEncoded(w, h, [](int x, int y, int c) { return float((x + 2 * y + c) % 5) / 4.0f; });
  const Image outPrev = fromEncoded(w, h, [](int x, int y, int c) { return float((3 * x + y + c) % 7) / 6.0f; });
  Image mask(w, h, 1, 1.0f);
  for (int x = 0; x < w; ++x) mask.at(x, 2)[0] = 0.0f;
  Image map;
  const TemporalError te = temporalError(out, outPrev, ref, refPrev, nullptr, &mask, 2, &map);
  EXPECT_EQ(te.pixels, long(w * (h - 1)));
  double sum = 0;
  for (int y = 0; y < h; ++y)
    for (int x = 0; x < w; ++x) {
      if (y == 2) {
        EXPECT_EQ(map.at(x, y)[0], 0.0f);
      }
      sum += map.at(x, y)[0];
    }
  EXPECT_NEAR(sum / double(te.pixels), te.value, 1e-6);
  EXPECT_GT(te.value, 0.0);
  // The same figure on any number of threads.
  EXPECT_EQ(temporalError(out, outPrev, ref, refPrev, nullptr, &mask, 1).value, te.value);
}

// The disocclusion mask (motion only): a pixel whose previous position lies
// past the outer edge of the last column / row (x > w - 0.5 or y > h - 0.5)
// left the picture and is masked out (0); one landing on that edge or inside
// is kept (1).
TEST(TemporalError, DisocclusionMaskDropsMotionJustPastTheRightAndBottomEdges) {
  const int w = 8, h = 6;
  Image motion(w, h, 2, 0.0f);
  motion.at(w - 1, 1)[0] = 0.75f;  // x = w - 0.25: off screen
  motion.at(w - 1, 2)[0] = 0.5f;   // x = w - 0.5: the edge, on screen
  motion.at(w - 1, 3)[0] = 0.25f;  // x = w - 0.75
  motion.at(1, h - 1)[1] = 0.75f;  // y = h - 0.25: off screen
  motion.at(2, h - 1)[1] = 0.5f;   // y = h - 0.5: the edge, on screen
  motion.at(3, h - 1)[1] = 0.25f;  // y = h - 0.75
  const Image mask = disocclusionMask(&motion, nullptr, nullptr, nullptr, nullptr, 0.05f, 1);
  for (int y = 0; y < h; ++y)
    for (int x = 0; x < w; ++x) {
      const bool off = (x == w - 1 && y == 1) || (x == 1 && y == h - 1);
      EXPECT_EQ(mask.at(x, y)[0], off ? 0.0f : 1.0f) << "(" << x << "," << y << ")";
    }
}

TEST(TemporalError, MismatchedSizesAreNamed) {
  const Image a(8, 8, 4), b(8, 7, 4), motion(8, 8, 1);
  try {
    temporalError(a, a, b, a);
    FAIL() << "no error";
  } catch (const Exception& e) {
    EXPECT_NE(std::string(e.what()).find("reference"), std::string::npos) << e.what();
  }
  try {
    temporalError(a, a, a, a, &motion);
    FAIL() << "no error";
  } catch (const Exception& e) {
    EXPECT_NE(std::string(e.what()).find("motion"), std::string::npos) << e.what();
  }
}
