// SPDX-License-Identifier: Apache-2.0
// The release of held still pixels (temporal/hold_release.h; taa.cpp and
// phlm.cpp "Hold"): a persistent change next to held pixels is taken in, a
// one-frame firefly is not, and a periodic input never releases anything.
#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>
#include <cstring>
#include <limits>
#include <string>

#include "core/image.h"
#include "temporal/hold_release.h"
#include "temporal/jitter.h"
#include "temporal_test_util.h"

using namespace crisp;

namespace {

// One pixel's windows driven by hand: P = 4, limit 8.
struct Windows {
  std::uint32_t word = temporal::kHoldWindowNone;
  long frames = 0;
  bool step(int luma, bool still = true) {
    bool released = false;
    word = std::uint32_t(temporal::stepHoldWindow<float>(int(word), luma, still,
                                                         temporal::holdWindowEnds(frames++, 4), 8, released));
    return released;
  }
};

// A still picture of w x h under EEVEE's jitter: `background` (flat, or with
// a texture of +-0.1), its part right of x = 16 turned to 0.6 from frame
// `change` on; `fireflyFrame`: that frame has 1e4 at pixel (8, 8) (its sample
// lands in it).
struct StillPicture {
  int w = 32, h = 16;
  float background = 0.3f;
  bool textured = false;
  int change = 1 << 30;
  int fireflyFrame = -1;
  bool uniformJitter = false;  // inside the pixel (no unjitter shift: the fast paths' lane groups run) instead of EEVEE's
  bool movingSquare = false;  // a 4x4 square at rows 2-5 moving 1 px per frame to the right (motion and depth given)
  float squareX(int frame) const { return float(frame % (w + 8) - 4); }
  float at(float sx, float sy, int frame) const {
    if (movingSquare && sy >= 2.0f && sy < 6.0f && sx >= squareX(frame) && sx < squareX(frame) + 4.0f) return 0.9f;
    if (frame >= change && sx >= 16.0f) return 0.6f;
    if (frame == fireflyFrame && int(std::floor(sx)) == 8 && int(std::floor(sy)) == 8) return 1e4f;
    return textured ? background + 0.1f * std::sin(1.7f * std::floor(sx)) * std::cos(1.3f * std::floor(sy)) : background;
  }
  synth::FrameData frame(int t) const {
    synth::FrameData f;
    f.frame = t;
    f.jitter = temporal::jitterForFrame(t, uniformJitter ? temporal::JitterDistribution::Uniform
                                                         : temporal::JitterDistribution::BlackmanHarris);
    f.color = Image(w, h, 4);
    for (int y = 0; y < h; ++y)
      for (int x = 0; x < w; ++x) {
        const float v = at(float(x) + 0.5f + f.jitter.x, float(y) + 0.5f + f.jitter.y, t);
        float* p = f.color.at(x, y);
        p[0] = p[1] = p[2] = v;
        p[3] = 1.0f;
      }
    if (movingSquare) {
      f.motion = Image(w, h, 4);
      f.depth = Image(w, h, 1, 10.0f);
      for (int y = 2; y < 6; ++y)
        for (int x = 0; x < w; ++x)
          if (float(x) + 0.5f >= squareX(t) && float(x) + 0.5f < squareX(t) + 4.0f) {
            f.motion.at(x, y)[0] = -1.0f;  // previous - current
            f.depth.at(x, y)[0] = 2.0f;
          }
    }
    return f;
  }
};

// The outputs of frames 0 .. frames - 1 of a temporal filter on the picture
// (no motion, no depth: a still scene), with holdRelease `release` (< 0: default).
std::vector<Image> filterPicture(const char* type, const StillPicture& picture, int frames, float release = -1.0f,
                                 int holdPeriod = -1, bool reference = false) {
  test::TemporalDriver d(type);
  if (release >= 0.0f) d.filter->params().setFloat("holdRelease", release);
  if (holdPeriod >= 0) d.filter->params().setInt("holdPeriod", holdPeriod);
  d.filter->params().setBool("reference", reference);
  std::vector<Image> out;
  for (int t = 0; t < frames; ++t) {
    const bool aux = picture.movingSquare;
    out.push_back(d.run(picture.frame(t), aux, aux, false));
  }
  return out;
}

float largestDifference(const Image& a, const Image& b) {
  float largest = 0.0f;
  for (std::size_t i = 0; i < a.data.size(); ++i) largest = std::max(largest, std::fabs(a.data[i] - b.data[i]));
  return largest;
}

}  // namespace

TEST(HoldRelease, WindowsOfAPeriodicInputNeverRelease) {
  Windows wnd;
  const int period[4] = {10, 200, 35, 90};
  for (int t = 0; t < 400; ++t) EXPECT_FALSE(wnd.step(period[t % 4])) << "frame " << t;
  EXPECT_EQ(wnd.word >> 31, 0u);  // not pending
}

TEST(HoldRelease, APersistentChangeReleasesAtTheSecondDifferentWindow) {
  Windows wnd;
  for (int t = 0; t < 16; ++t) EXPECT_FALSE(wnd.step(100));  // frames 0-15: windows end at 3, 7, 11, 15
  EXPECT_FALSE(wnd.step(103));  // frame 16
  EXPECT_FALSE(wnd.step(103));
  EXPECT_FALSE(wnd.step(103));
  EXPECT_FALSE(wnd.step(103));  // frame 19 closes a window 12 above: pending
  EXPECT_NE(wnd.word >> 31, 0u);
  EXPECT_FALSE(wnd.step(103));
  EXPECT_FALSE(wnd.step(103));
  EXPECT_FALSE(wnd.step(103));
  EXPECT_TRUE(wnd.step(103));  // frame 23: the second one: released
  // Restarted: no complete window before frame 31, so nothing is released
  // before then whatever the input does.
  for (int t = 24; t < 32; ++t) EXPECT_FALSE(wnd.step(t % 2 ? 0 : 255)) << "frame " << t;
}

TEST(HoldRelease, AChangeWithinTheLimitOrAOneWindowEventDoesNotRelease) {
  Windows small, spike, moving;
  for (int t = 0; t < 40; ++t) {
    EXPECT_FALSE(small.step(t < 12 ? 100 : 102));                 // 8 per window: not more than the limit
    EXPECT_FALSE(spike.step(t == 14 ? 255 : 100));               // one window differs, the next matches
    EXPECT_FALSE(moving.step(t < 12 ? 100 : 200, false));        // not still: nothing to release
  }
  EXPECT_EQ(spike.word >> 31, 0u);
  // A frame that is not still restarts the windows (no sum, no baseline).
  EXPECT_FALSE(small.step(100, false));
  EXPECT_EQ(small.word & 0x7fff0000u, 0x7fff0000u);
}

TEST(HoldRelease, QuantisedLuminanceIsBoundedAndSaneOnEveryInput) {
  EXPECT_EQ(temporal::holdLumaOfLinear(0.0f), 0);
  EXPECT_EQ(temporal::holdLumaOfLinear(-5.0f), 0);
  EXPECT_EQ(temporal::holdLumaOfLinear(1.0f), 128);
  EXPECT_EQ(temporal::holdLumaOfLinear(std::numeric_limits<float>::infinity()), 255);
  EXPECT_EQ(temporal::holdLumaOfLinear(std::numeric_limits<float>::quiet_NaN()), 0);
  EXPECT_EQ(temporal::holdLumaOfLinear(1e30f), 255);
}

TEST(HoldRelease, LimitAndFrameKeepToTheirRanges) {
  EXPECT_EQ(temporal::holdWindowLimit(0.002f, 16), 8);
  EXPECT_EQ(temporal::holdWindowLimit(1.0f, 16), 255 * 16);  // never: |window - baseline| <= 255 P
  EXPECT_EQ(temporal::holdWindowLimit(7.0f, 16), 255 * 16);
  EXPECT_EQ(temporal::holdWindowLimit(-1.0f, 16), 0);
  EXPECT_EQ(temporal::holdWindowLimit(std::numeric_limits<float>::quiet_NaN(), 16), 255 * 16);
  temporal::HoldWindows windows;
  windows.allocate(4);
  EXPECT_NE(temporal::holdWindowFrame(windows, 0, 16, 0.002f).words, nullptr);
  EXPECT_EQ(temporal::holdWindowFrame(windows, 0, 0, 0.002f).words, nullptr);  // no hold
  EXPECT_EQ(temporal::holdWindowFrame(windows, 0, temporal::kHoldPeriodMax + 1, 0.002f).words, nullptr);  // sums would overflow
  EXPECT_TRUE(temporal::holdWindowFrame(windows, 15, 16, 0.002f).windowEnd);
  EXPECT_FALSE(temporal::holdWindowFrame(windows, 16, 16, 0.002f).windowEnd);
}

// docs/temporal_figures.md "Weakness of the hold": before the release, a
// band about two pixels wide along the new edge kept the old colour for good.
// 100 frames after the change every pixel is where a run that saw the new
// picture from the start is (that run's last frame).
TEST(HoldRelease, HeldPixelsTakeInAPersistentChange) {
  const int frames = 160;
  for (const char* type : {"taa", "taa-improved", "phlm"})
    for (float background : {0.3f, 0.45f, 0.7f})
      for (bool textured : {false, true}) {
        StillPicture picture;
        picture.background = background;
        picture.textured = textured;
        picture.change = 60;
        StillPicture changed = picture;
        changed.change = 0;
        const std::vector<Image> out = filterPicture(type, picture, frames);
        const std::vector<Image> control = filterPicture(type, changed, frames);
        const std::vector<Image> neverReleased = filterPicture(type, picture, frames, 1.0f);
        const float after = largestDifference(out.back(), control.back());
        const float stale = largestDifference(neverReleased.back(), control.back());
        std::printf("%-12s background %.2f%s: largest difference to the changed picture's run at frame %d: %.4f "
                    "released, %.4f never released; row 8, pixels 14-17: %.3f %.3f %.3f %.3f\n",
                    type, background, textured ? " textured" : "", frames - 1, after, stale,
                    out.back().at(14, 8)[0], out.back().at(15, 8)[0], out.back().at(16, 8)[0],
                    out.back().at(17, 8)[0]);
        EXPECT_LT(after, 0.01f) << type << " background " << background << (textured ? " textured" : "");
      }
}

// A one-frame firefly in a held still picture changes nothing: the window
// that holds it differs, the next one matches (no release), and the held
// values never took it in.
TEST(HoldRelease, AOneFrameFireflyInAHeldPictureChangesNothing) {
  const int frames = 120;
  for (const char* type : {"taa", "taa-improved", "phlm"}) {
    StillPicture picture, clean;
    picture.textured = clean.textured = true;
    picture.fireflyFrame = 70;
    const std::vector<Image> out = filterPicture(type, picture, frames);
    const std::vector<Image> control = filterPicture(type, clean, frames);
    int differing = 0;
    for (int t = picture.fireflyFrame + 1; t < frames; ++t) differing += largestDifference(out[t], control[t]) > 0.0f;
    std::printf("%-12s firefly 1e4 at frame %d: frames %d-%d differing from the run without it: %d\n", type,
                picture.fireflyFrame, picture.fireflyFrame + 1, frames - 1, differing);
    EXPECT_EQ(differing, 0) << type;
  }
}

// The release on the fast path (both instruction-set copies; lane groups of
// still and of moving pixels, which run where the jitter needs no unjitter
// shift, and single pixels; a partial group at the row's end) gives the
// reference path's bits, with a moving square beside the still part that
// changes: windows of 4 frames, so releases come early and often.
TEST(HoldRelease, FastPathEqualsReference) {
  for (bool uniform : {true, false}) {
  StillPicture picture;
  picture.uniformJitter = uniform;
  picture.w = 45;
  picture.textured = true;
  picture.change = 20;
  picture.movingSquare = true;
  const int frames = 40;
  for (const char* type : {"taa", "taa-improved", "phlm"}) {
    const std::vector<Image> reference = filterPicture(type, picture, frames, -1.0f, 4, true);
    const std::vector<Image> never = filterPicture(type, picture, frames, 1.0f, 4, true);
    float released = 0.0f;
    for (int t = 0; t < frames; ++t) released = std::max(released, largestDifference(reference[t], never[t]));
    EXPECT_GT(released, 0.01f) << type << ": the change must release pixels";
    for (temporal::Isa isa : test::kFastPathIsas) {
      const test::FastPathIsa use(isa);
      const std::vector<Image> fast = filterPicture(type, picture, frames, -1.0f, 4);
      for (int t = 0; t < frames; ++t)
        ASSERT_EQ(std::memcmp(fast[t].data.data(), reference[t].data.data(), fast[t].data.size() * sizeof(float)), 0)
            << type << " frame " << t << " (" << temporal::fastPathIsaName() << " copy)"
            << (uniform ? ", uniform jitter" : ", EEVEE's jitter");
    }
  }
  }
}
