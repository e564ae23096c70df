// SPDX-License-Identifier: Apache-2.0
// The reusable temporal helpers (native/temporal/) and the moving synthetic
// sequences (native/synth/moving.h).
#include <gtest/gtest.h>

#include <cmath>
#include <set>
#include <vector>

#include "core/conventions.h"
#include "synth/moving.h"
#include "temporal/color_space.h"
#include "temporal/history_fetch.h"
#include "temporal/jitter.h"
#include "temporal/lanes.h"
#include "temporal/neighbourhood.h"
#include "temporal/vec4.h"
#include "temporal/velocity.h"

using namespace crisp;
using namespace crisp::temporal;

TEST(TemporalJitter, RadicalInverseDigits) {
  // Base 2: 1 -> .1b, 2 -> .01b, 3 -> .11b; base 3: 1 -> .1t, 2 -> .2t, 3 -> .01t.
  EXPECT_DOUBLE_EQ(radicalInverse(1, 2), 0.5);
  EXPECT_DOUBLE_EQ(radicalInverse(2, 2), 0.25);
  EXPECT_DOUBLE_EQ(radicalInverse(3, 2), 0.75);
  EXPECT_DOUBLE_EQ(radicalInverse(1, 3), 1.0 / 3.0);
  EXPECT_DOUBLE_EQ(radicalInverse(2, 3), 2.0 / 3.0);
  EXPECT_NEAR(radicalInverse(3, 3), 1.0 / 9.0, 1e-15);
  // The 16 TAA phases are distinct points inside the pixel.
  std::set<std::pair<float, float>> points;
  for (int f = 0; f < 16; ++f) {
    Jitter j = jitterForFrame(f, JitterDistribution::Uniform);
    EXPECT_GT(j.x, -0.5f);
    EXPECT_LT(j.x, 0.5f);
    EXPECT_GT(j.y, -0.5f);
    EXPECT_LT(j.y, 0.5f);
    points.insert({j.x, j.y});
  }
  EXPECT_EQ(points.size(), 16u);
  // Period: frame 16 repeats frame 0; y is returned y-down (Halton's v is y up).
  EXPECT_EQ(jitterForFrame(16, JitterDistribution::Uniform).x, jitterForFrame(0, JitterDistribution::Uniform).x);
  EXPECT_FLOAT_EQ(jitterForFrame(0, JitterDistribution::Uniform).y, -float(1.0 / 3.0 - 0.5));
}

TEST(TemporalJitter, BlackmanHarrisCdfMatchesNumericalIntegral) {
  const int n = 20000;
  double acc = 0.0, total = 0.0;
  std::vector<double> cdf(n + 1, 0.0);
  for (int i = 0; i < n; ++i) {
    const double a = blackmanHarrisWindow(double(i) / n), b = blackmanHarrisWindow(double(i + 1) / n);
    acc += 0.5 * (a + b) / n;
    cdf[i + 1] = acc;
  }
  total = acc;
  for (int i = 0; i <= n; i += 997) EXPECT_NEAR(blackmanHarrisCdf(double(i) / n), cdf[i] / total, 1e-7) << i;
  EXPECT_DOUBLE_EQ(blackmanHarrisCdf(0.0), 0.0);
  EXPECT_NEAR(blackmanHarrisCdf(0.5), 0.5, 1e-12);
  EXPECT_NEAR(blackmanHarrisCdf(1.0), 1.0, 1e-12);
  // Inverse: round trip, and the support is [-width/2, width/2].
  for (double u = 0.01; u < 1.0; u += 0.07) EXPECT_NEAR(blackmanHarrisCdf(blackmanHarrisInverse(u, 1.0) + 0.5), u, 1e-9);
  EXPECT_NEAR(blackmanHarrisInverse(0.0, 1.5), -0.75, 1e-9);
  EXPECT_NEAR(blackmanHarrisInverse(1.0, 1.5), 0.75, 1e-9);
}

TEST(TemporalJitter, BlackmanHarrisJitterHasTheWindowsSpread) {
  // Over many Halton points the jitter's variance is the window's variance;
  // EEVEE's filter_size 1.5 spreads the window over [-1.5, 1.5] px.
  double windowVar = 0.0, windowSum = 0.0;
  for (int i = 0; i < 100000; ++i) {
    const double t = (i + 0.5) / 100000.0, x = (t - 0.5) * 3.0;
    windowVar += blackmanHarrisWindow(t) * x * x;
    windowSum += blackmanHarrisWindow(t);
  }
  windowVar /= windowSum;
  double mean = 0.0, var = 0.0;
  const int frames = 4096;
  for (int f = 0; f < frames; ++f) {
    Jitter j = jitterForFrame(f, JitterDistribution::BlackmanHarris, 1.5f, frames);
    EXPECT_LE(std::fabs(j.x), 1.5f);
    EXPECT_LE(std::fabs(j.y), 1.5f);
    mean += j.x;
    var += double(j.x) * j.x;
  }
  mean /= frames;
  var /= frames;
  EXPECT_NEAR(mean, 0.0, 2e-3);
  EXPECT_NEAR(var, windowVar, 0.02 * windowVar);
  // Uniform jitter's variance is 1/12: the two really differ.
  EXPECT_GT(std::fabs(windowVar - 1.0 / 12.0), 0.02);
}

TEST(TemporalJitter, BlackmanHarrisWeightHasUnitMean) {
  const int n = 400;
  double sum = 0.0;
  for (int j = 0; j < n; ++j)
    for (int i = 0; i < n; ++i)
      sum += blackmanHarrisWeight(((i + 0.5f) / n - 0.5f) * 3.0f, ((j + 0.5f) / n - 0.5f) * 3.0f, 1.5f);
  EXPECT_NEAR(sum / (double(n) * n), 1.0, 1e-4);
  EXPECT_EQ(blackmanHarrisWeight(1.6f, 0.0f, 1.5f), 0.0f);  // outside the support [-1.5, 1.5]
  EXPECT_GT(blackmanHarrisWeight(0.8f, 0.0f, 1.5f), 0.0f);
  EXPECT_GT(blackmanHarrisWeight(0.0f, 0.0f, 1.5f), blackmanHarrisWeight(0.3f, 0.0f, 1.5f));
}

TEST(TemporalColor, YCoCgRoundTripAndLuma) {
  const Float3 colours[] = {{{0.2f, 0.5f, 0.9f}}, {{1e4f, 0.0f, 3.0f}}, {{-1.0f, 2.0f, 0.0f}}, {{0.0f, 0.0f, 0.0f}}};
  for (const Float3& c : colours) {
    const Float3 y = rgbToYCoCg(c), back = yCoCgToRgb(y);
    for (int k = 0; k < 3; ++k) EXPECT_NEAR(back[k], c[k], 1e-6f * (1.0f + std::fabs(c[k]))) << k;
    EXPECT_FLOAT_EQ(y[0], 0.25f * c[0] + 0.5f * c[1] + 0.25f * c[2]);
  }
  // Grey has no chroma.
  const Float3 g = rgbToYCoCg({{0.4f, 0.4f, 0.4f}});
  EXPECT_FLOAT_EQ(g[0], 0.4f);
  EXPECT_FLOAT_EQ(g[1], 0.0f);
  EXPECT_FLOAT_EQ(g[2], 0.0f);
}

TEST(TemporalNeighbourhood, BoxesRoundingAndClip) {
  Float3 taps[9];
  for (int i = 0; i < 9; ++i) taps[i] = {{float(i), float(10 - i), i == 0 ? 100.0f : 1.0f}};
  ColorBox b3, cr;
  neighbourhoodBoxes(taps, b3, cr);
  EXPECT_EQ(b3.min[0], 0.0f);
  EXPECT_EQ(b3.max[0], 8.0f);
  EXPECT_FLOAT_EQ(b3.avg[0], 4.0f);
  EXPECT_EQ(cr.min[0], 1.0f);  // cross = taps 1, 3, 4, 5, 7
  EXPECT_EQ(cr.max[0], 7.0f);
  EXPECT_FLOAT_EQ(cr.avg[0], 4.0f);
  EXPECT_EQ(b3.max[2], 100.0f);  // the corner outlier is in the 3x3 box only
  EXPECT_EQ(cr.max[2], 1.0f);
  const ColorBox r = roundedBox(b3, cr);
  EXPECT_FLOAT_EQ(r.min[0], 0.5f);
  EXPECT_FLOAT_EQ(r.max[0], 7.5f);
  EXPECT_FLOAT_EQ(r.max[2], 50.5f);

  const Float3 lo = {{0.0f, 0.0f, 0.0f}}, hi = {{1.0f, 2.0f, 1.0f}};
  // Inside: unchanged.
  ClipResult in = clipTowardCentre({{0.2f, 1.5f, 0.9f}}, lo, hi);
  EXPECT_LE(in.excess, 1.0f);
  EXPECT_EQ(in.color[1], 1.5f);
  // Outside: on the box surface, on the segment to the centre (0.5, 1, 0.5).
  const Float3 p = {{3.0f, 1.0f, 0.5f}};
  ClipResult out = clipTowardCentre(p, lo, hi);
  EXPECT_NEAR(out.excess, 5.0f, 1e-5f);
  EXPECT_NEAR(out.color[0], 1.0f, 1e-6f);
  EXPECT_NEAR(out.color[1], 1.0f, 1e-6f);
  // A clamp would keep (1, 1, 0.5) too here; a diagonal case shows the difference:
  const Float3 q = {{3.0f, 3.0f, 0.5f}};
  ClipResult d = clipTowardCentre(q, lo, hi);
  EXPECT_NEAR(d.color[0], 1.0f, 1e-6f);                     // first face hit: x = 1
  EXPECT_NEAR(d.color[1], 1.0f + 2.0f * 0.5f / 2.5f, 1e-6f);  // y moved proportionally, not clamped to 2
  // Flat box: everything outside goes to the centre (no division by zero).
  ClipResult flat = clipTowardCentre({{5.0f, -5.0f, 1e30f}}, hi, hi);
  for (int k = 0; k < 3; ++k) EXPECT_TRUE(std::isfinite(flat.color[k]));
  EXPECT_NEAR(flat.color[0], 1.0f, 1e-5f);
}

namespace {
std::vector<float> rampImage(int w, int h, bool step) {
  std::vector<float> d(std::size_t(w) * h * 4);
  for (int y = 0; y < h; ++y)
    for (int x = 0; x < w; ++x) {
      float* p = d.data() + (std::size_t(y) * w + x) * 4;
      p[0] = step ? (x < w / 2 ? 0.0f : 1.0f) : 0.1f * x + 0.05f * y;
      p[1] = 2.0f;
      p[2] = float(x * 100 + y);
      p[3] = float(y * w + x);  // the carried channel
    }
  return d;
}
}  // namespace

TEST(TemporalFetch, BilinearAndCatmullRom) {
  const int w = 12, h = 9;
  std::vector<float> ramp = rampImage(w, h, false);
  HistoryImage img{ramp.data(), w, h};
  float out[4];
  // At a pixel centre both return the texel exactly.
  fetchBilinear(img, 5.0f, 4.0f, out);
  EXPECT_EQ(out[0], img.at(5, 4)[0]);
  EXPECT_EQ(out[3], img.at(5, 4)[3]);
  fetchCatmullRom(img, 5.0f, 4.0f, out);
  EXPECT_EQ(out[0], img.at(5, 4)[0]);
  EXPECT_EQ(out[2], img.at(5, 4)[2]);
  // Both reproduce a linear ramp inside the image; the carried channel is the nearest tap's.
  fetchBilinear(img, 5.3f, 4.6f, out);
  EXPECT_NEAR(out[0], 0.1f * 5.3f + 0.05f * 4.6f, 1e-5f);
  EXPECT_EQ(out[3], img.at(5, 5)[3]);
  fetchCatmullRom(img, 5.3f, 4.6f, out);
  EXPECT_NEAR(out[0], 0.1f * 5.3f + 0.05f * 4.6f, 1e-5f);
  EXPECT_NEAR(out[1], 2.0f, 1e-6f);
  // Catmull-Rom weights sum to 1 and have negative outer lobes.
  float wts[4];
  catmullRomWeights(0.3f, wts);
  EXPECT_NEAR(wts[0] + wts[1] + wts[2] + wts[3], 1.0f, 1e-6f);
  EXPECT_LT(wts[0], 0.0f);
  EXPECT_LT(wts[3], 0.0f);
  // On a step, the unclamped cubic would overshoot; the clamped fetch stays in [0, 1].
  std::vector<float> step = rampImage(w, h, true);
  HistoryImage s{step.data(), w, h};
  bool anyOvershootAvoided = false;
  for (float x = 3.0f; x < 8.0f; x += 0.1f) {
    fetchCatmullRom(s, x, 4.0f, out);
    EXPECT_GE(out[0], 0.0f);
    EXPECT_LE(out[0], 1.0f);
    catmullRomWeights(x - std::floor(x), wts);
    float raw = 0.0f;
    for (int i = 0; i < 4; ++i) raw += wts[i] * s.at(std::clamp(int(std::floor(x)) - 1 + i, 0, w - 1), 4)[0];
    if (raw < -1e-3f || raw > 1.0f + 1e-3f) anyOvershootAvoided = true;
  }
  EXPECT_TRUE(anyOvershootAvoided);
  // Screen test: pixel centres at integers, the image covers [-0.5, size - 0.5].
  EXPECT_TRUE(onScreen(-0.5f, 0.0f, w, h));
  EXPECT_FALSE(onScreen(-0.51f, 0.0f, w, h));
  EXPECT_FALSE(onScreen(float(w) - 0.49f, 0.0f, w, h));
  EXPECT_FALSE(onScreen(std::nanf(""), 1.0f, w, h));
  EXPECT_FALSE(onScreen(1.0f, INFINITY, w, h));
}

// The lane-group fetches (a group whose footprints share one integer offset, as taa's fast path
// reads a smooth motion) give, lane by lane, the bits of the one-pixel fetches, with the carried
// channel of the nearest tap; on Vec4 and Vec8, over fractions that include 0 and 0.5.
template <class T>
void rowFetchesEqualPixelFetches() {
  constexpr int kL = kLanesOf<T>;
  const int w = 23, h = 7;
  std::vector<float> planes[4];
  for (int c = 0; c < 4; ++c) {
    planes[c].resize(std::size_t(w) * h);
    for (int i = 0; i < w * h; ++i) planes[c][i] = std::sin(0.37f * float(i) + 1.3f * float(c)) * (c == 3 ? 5 : 1);
  }
  const HistoryPlanes hp{{planes[0].data(), planes[1].data(), planes[2].data(), planes[3].data()}, w, h};
  const float fractions[] = {0.0f, 0.25f, 0.5f, 0.73f, 0.99f};
  for (float fx : fractions)
    for (float fy : fractions)
      for (int x0 = 1; x0 + kL + 2 <= w; x0 += 3) {
        const int y0 = 2;
        // Reprojected positions and their fractions as taa derives them (footprintOf).
        float qx[kL], qy[kL];
        T tx, ty, bilinear[4], cubic[4];
        for (int l = 0; l < kL; ++l) {
          qx[l] = float(x0 + l) + fx + 0.003f * float(l % 3);
          qy[l] = float(y0) + fy;
          const Footprint fp = footprintOf(qx[l], qy[l]);
          ASSERT_EQ(fp.x0, x0 + l);
          setLane(tx, l, fp.tx);
          setLane(ty, l, fp.ty);
        }
        fetchBilinearRow(hp, x0, y0, tx, ty, bilinear);
        fetchCatmullRomRow(hp, x0, y0, tx, ty, cubic);
        for (int l = 0; l < kL; ++l) {
          const Footprint fp = footprintOf(qx[l], qy[l]);
          const Vec4 b = fetchBilinear4(hp, qx[l], qy[l]);
          const Vec4 c = fetchCatmullRomAt4<false>(hp, fp);
          for (int ch = 0; ch < 4; ++ch) {
            EXPECT_EQ(bilinear[ch][l], b[ch]) << "bilinear lane " << l << " channel " << ch << " at " << fx << "," << fy;
            EXPECT_EQ(cubic[ch][l], c[ch]) << "catmull-rom lane " << l << " channel " << ch << " at " << fx << "," << fy;
          }
        }
      }
}

TEST(TemporalFetch, LaneGroupFetchesEqualPixelFetches) {
  rowFetchesEqualPixelFetches<Vec4>();
  rowFetchesEqualPixelFetches<Vec8>();
}

TEST(TemporalVelocity, ClosestDepthAndSurfaceTests) {
  float d[9] = {5, 5, 5, 5, 5, 5, 5, 5, 5};
  EXPECT_EQ(closestDepthTap(d), 4);  // ties: the centre
  d[7] = 2.0f;
  d[2] = 2.0f;
  EXPECT_EQ(closestDepthTap(d), 2);  // then the first in row order
  EXPECT_EQ(sanitizeDepth(std::nanf("")), kBackgroundDepth);
  EXPECT_EQ(sanitizeDepth(INFINITY), kBackgroundDepth);
  EXPECT_EQ(sanitizeDepth(65504.0f), kBackgroundDepth);
  EXPECT_EQ(sanitizeDepth(3.5f), 3.5f);
  EXPECT_TRUE(sameSurfaceDepth(10.0f, 10.4f, 0.05f));
  EXPECT_FALSE(sameSurfaceDepth(10.0f, 10.6f, 0.05f));
  EXPECT_TRUE(sameSurfaceDepth(kBackgroundDepth, kBackgroundDepth, 0.05f));
  EXPECT_FALSE(sameSurfaceDepth(5.0f, kBackgroundDepth, 0.05f));
  EXPECT_FALSE(finiteMotion(std::nanf(""), 0.0f));
}

TEST(MovingSequences, MotionConventionAndPasses) {
  const int w = 40, h = 30;
  // A disk moving (+2, +1) px per frame reads (-2, -1): previous - current, y down.
  synth::Sequence seq = synth::ghostingSequence(w, h, 6.0f, 2.0f, 1.0f);
  synth::FrameOptions opt;
  opt.jitter = synth::JitterKind::None;
  opt.reference = synth::ReferenceKind::None;
  const int t = 8;
  synth::FrameData now = synth::renderFrame(seq, w, h, t, opt);
  synth::FrameData before = synth::renderFrame(seq, w, h, t - 1, opt);
  int onBall = 0;
  for (int y = 0; y < h; ++y)
    for (int x = 0; x < w; ++x) {
      const float* m = now.motion.at(x, y);
      if (now.id.uintAt(x, y) == 1) {
        ++onBall;
        EXPECT_EQ(m[0], -2.0f);
        EXPECT_EQ(m[1], -1.0f);
        EXPECT_EQ(*now.depth.at(x, y), 8.0f);
        // The point was at p + motion in the previous frame, with the same colour and id.
        const int px = x + int(m[0]), py = y + int(m[1]);
        ASSERT_TRUE(px >= 0 && py >= 0);
        EXPECT_EQ(before.id.uintAt(px, py), 1u);
        EXPECT_EQ(before.color.at(px, py)[0], now.color.at(x, y)[0]);
      } else if (now.id.uintAt(x, y) == 0) {
        EXPECT_EQ(m[0], 0.0f);
        EXPECT_EQ(*now.depth.at(x, y), kBackgroundDepth);
      }
    }
  EXPECT_GT(onBall, 50);
  // Jittered colour = the still scene sampled at centre + jitter; box reference = 16x16 supersampling.
  synth::FrameOptions jit;
  jit.jitter = synth::JitterKind::BlackmanHarris;
  synth::FrameData j = synth::renderFrame(seq, w, h, 5, jit);
  Image expect = synth::renderCentre(seq.sceneAt(5), w, h, j.jitter.x, j.jitter.y);
  Image ref = synth::renderSupersampled(seq.sceneAt(5), w, h, 16);
  EXPECT_NE(j.jitter.x, 0.0f);
  EXPECT_EQ(j.color.data, expect.data);
  EXPECT_EQ(j.reference.data, ref.data);
  // The camera cut switches scenes.
  synth::Sequence cut = synth::cameraCutSequence(w, h, 3);
  EXPECT_NE(synth::renderFrame(cut, w, h, 2, opt).color.data, synth::renderFrame(cut, w, h, 3, opt).color.data);
  EXPECT_EQ(synth::renderFrame(cut, w, h, 3, opt).color.data, synth::renderFrame(cut, w, h, 4, opt).color.data);
}

TEST(MovingSequences, BlackmanHarrisReferenceIsSmootherThanBox) {
  const int w = 24, h = 16;
  synth::Sequence seq = synth::movingEdgeSequence(w, h, 20.0f, 0.0f, 0.0f);
  synth::FrameOptions box, bh;
  bh.reference = synth::ReferenceKind::BlackmanHarris;
  Image a = synth::renderFrame(seq, w, h, 0, box).reference, b = synth::renderFrame(seq, w, h, 0, bh).reference;
  // Same mean (energy kept) but the wider filter touches more pixels.
  double sa = 0, sb = 0;
  int mixedA = 0, mixedB = 0;
  for (int y = 2; y < h - 2; ++y)
    for (int x = 2; x < w - 2; ++x) {
      sa += a.at(x, y)[0];
      sb += b.at(x, y)[0];
      mixedA += a.at(x, y)[0] > 0.0501f && a.at(x, y)[0] < 0.7999f;
      mixedB += b.at(x, y)[0] > 0.0501f && b.at(x, y)[0] < 0.7999f;
    }
  EXPECT_NEAR(sa, sb, 0.02 * sa);
  EXPECT_GT(mixedB, mixedA);
}

// movingRow (in every lane form) and stillFootprintRow give every pixel's stillFootprint: sparse motion (zero,
// -0, NaN and small values) in 2- and 4-channel passes, every jitter shift
// the unjitter uses (up to 2 px each way), narrow images included.
TEST(TemporalVelocity, StillFootprintRowEqualsPerPixelTest) {
  using namespace crisp::temporal;
  for (int channels : {2, 4})
    for (int w : {1, 3, 17}) {
      const int h = 11;
      Image motion(w, h, channels);
      for (int y = 0; y < h; ++y)
        for (int x = 0; x < w; ++x) {
          const int k = (x * 7 + y * 13) % 29;
          float* m = motion.at(x, y);
          m[0] = k == 0 ? 0.25f : (k == 5 ? std::nanf("") : (k == 9 ? -0.0f : 0.0f));
          m[1] = k == 17 ? -1e-6f : 0.0f;
          if (channels == 4) m[2] = m[3] = 5.0f;  // other channels are not motion
        }
      std::vector<std::uint8_t> plane(std::size_t(w) * h), columns(w + 4), row(w);
      for (int y = 0; y < h; ++y) movingRow(motion.view(), y, plane.data() + std::size_t(y) * w);
      // The lane forms give the same flags.
      for (int lanes : {4, 8}) {
        std::vector<std::uint8_t> laned(plane.size(), 7);
        for (int y = 0; y < h; ++y) {
          std::uint8_t* out = laned.data() + std::size_t(y) * w;
          if (lanes == 4) movingRow<Vec4>(motion.view(), y, out);
          else movingRow<Vec8>(motion.view(), y, out);
        }
        ASSERT_EQ(laned, plane) << channels << " channels, " << w << " wide, " << lanes << " lanes";
      }
      int still = 0, moving = 0;
      for (int sy = -2; sy <= 2; ++sy)
        for (int sx = -2; sx <= 2; ++sx)
          for (int y = 0; y < h; ++y) {
            stillFootprintRow(plane.data(), y, w, h, sx, sy, columns.data(), row.data());
            for (int x = 0; x < w; ++x) {
              const bool expected = stillFootprint(motion.view(), x, y, w, h, sx, sy);
              ASSERT_EQ(row[x] != 0, expected) << channels << " channels, " << w << " wide, shift " << sx << ","
                                               << sy << " pixel " << x << "," << y;
              if (expected) ++still;
              else ++moving;
            }
          }
      if (w == 17) {  // both answers occur
        EXPECT_GT(still, 0) << channels;
        EXPECT_GT(moving, 0) << channels;
      }
    }
}

TEST(TemporalNeighbourhood, FourLaneVersionsMatchScalar) {
  std::vector<float> values = {0.3f, -2.0f, 7.5f, 1e4f, 0.0f, 0.25f, 3.0f, -0.5f, 9.0f, 2.0f, 4.0f, 0.1f};
  Float3 taps[9];
  Vec4 taps4[9];
  for (int i = 0; i < 9; ++i) {
    for (int c = 0; c < 3; ++c) taps[i][c] = values[(i * 5 + c * 7) % values.size()];
    taps4[i] = Vec4{taps[i][0], taps[i][1], taps[i][2], 42.0f};
  }
  ColorBox b3, cr;
  ColorBox4 b34, cr4;
  neighbourhoodBoxes(taps, b3, cr);
  neighbourhoodBoxes4(taps4, b34, cr4);
  const ColorBox r = roundedBox(b3, cr);
  const ColorBox4 r4 = roundedBox4(b34, cr4);
  for (int c = 0; c < 3; ++c) {
    EXPECT_EQ(b3.min[c], b34.min[c]);
    EXPECT_EQ(b3.max[c], b34.max[c]);
    EXPECT_FLOAT_EQ(b3.avg[c], b34.avg[c]);
    EXPECT_EQ(cr.max[c], cr4.max[c]);
    EXPECT_EQ(r.min[c], r4.min[c]);
  }
  for (const Float3& p : {Float3{{0.0f, 0.0f, 0.0f}}, Float3{{50.0f, -3.0f, 2.0f}}, Float3{{1.0f, 1.0f, 1.0f}}}) {
    const ClipResult s = clipTowardCentre(p, r.min, r.max);
    float excess;
    const Vec4 v = clipTowardCentre4(Vec4{p[0], p[1], p[2], 5.0f}, r4.min, r4.max, &excess);
    EXPECT_EQ(s.excess, excess);
    for (int c = 0; c < 3; ++c) EXPECT_EQ(s.color[c], v[c]);
    EXPECT_EQ(v[3], 5.0f);  // lane 3 rides along
  }
}

// The lane helpers that only move data or fold masks: storeInterleaved4 writes
// packed pixels in order and loadInterleaved4 reads them back, anyOf/allOf match a lane-by-lane fold, byte planes
// read and write each value as it is, on 4 and 8 lanes.
template <class T>
void checkLaneHelpers() {
  using namespace crisp::temporal;
  constexpr int n = kLanesOf<T>;
  T ch[4];
  for (int c = 0; c < 4; ++c)
    for (int l = 0; l < n; ++l) ch[c][l] = float(10 * l + c);
  float out[4 * n + 1];
  out[4 * n] = -1.0f;  // past the end: untouched
  storeInterleaved4(out, ch[0], ch[1], ch[2], ch[3]);
  for (int i = 0; i < 4 * n; ++i) EXPECT_EQ(out[i], float(10 * (i / 4) + i % 4)) << n << " lanes, float " << i;
  EXPECT_EQ(out[4 * n], -1.0f);
  T unpacked[4];
  loadInterleaved4(out, unpacked[0], unpacked[1], unpacked[2], unpacked[3]);
  for (int c = 0; c < 4; ++c)
    for (int l = 0; l < n; ++l) EXPECT_EQ(unpacked[c][l], ch[c][l]) << n << " lanes, channel " << c << " lane " << l;
  for (int bits = 0; bits < (1 << n); ++bits) {
    T a{}, b{};
    for (int l = 0; l < n; ++l) (bits >> l & 1 ? b : a)[l] = 1.0f;
    const auto mask = a < b;  // lane l true where bit l is set
    EXPECT_EQ(anyOf(mask), bits != 0) << bits;
    EXPECT_EQ(allOf(mask), bits == (1 << n) - 1) << bits;
  }
  // Byte planes: every value 0..255 read back as itself; stores keep the low
  // 8 bits and touch nothing past the group.
  unsigned char bytes[256], back[257];
  for (int i = 0; i < 256; ++i) bytes[i] = static_cast<unsigned char>(i);
  back[256] = 7;
  for (int x = 0; x < 256; x += n) {
    const IntOf<T> v = loadBytesOf<T>(bytes + x);
    for (int l = 0; l < n; ++l) EXPECT_EQ(v[l], x + l) << n << " lanes, byte " << x + l;
    storeBytesOf<T>(back + x, v + 256 * (x / n % 3) - 512 * (x / n % 2));  // high bits dropped, some negative
  }
  for (int i = 0; i < 256; ++i) EXPECT_EQ(back[i], i) << n << " lanes, stored byte " << i;
  EXPECT_EQ(back[256], 7);
  // Motion passes of 2 and 4 channels: x and y of each pixel, in order.
  for (int step : {2, 4}) {
    float packed[4 * n];
    for (int i = 0; i < step * n; ++i) packed[i] = float(100 * (i / step) + i % step);
    T x, y;
    loadFirstTwoChannels(packed, step, x, y);
    for (int l = 0; l < n; ++l) {
      EXPECT_EQ(x[l], float(100 * l)) << n << " lanes, step " << step << " lane " << l;
      EXPECT_EQ(y[l], float(100 * l + 1)) << n << " lanes, step " << step << " lane " << l;
    }
  }
}

TEST(TemporalLanes, InterleavedStoreAndMaskFolds) {
  checkLaneHelpers<crisp::temporal::Vec4>();
  checkLaneHelpers<crisp::temporal::Vec8>();
}

// transposeToLanes undoes storeInterleaved4: eight packed pixels back to channels.
TEST(TemporalLanes, TransposeToLanesInvertsTheInterleavedStore) {
  using namespace crisp::temporal;
  Vec4 pixels[8];
  for (int l = 0; l < 8; ++l) pixels[l] = Vec4{float(10 * l), float(10 * l + 1), float(10 * l + 2), float(10 * l + 3)};
  Vec8 ch[4];
  transposeToLanes(pixels, ch);
  for (int c = 0; c < 4; ++c)
    for (int l = 0; l < 8; ++l) EXPECT_EQ(ch[c][l], float(10 * l + c)) << "channel " << c << " lane " << l;
  float packed[32];
  storeInterleaved4(packed, ch[0], ch[1], ch[2], ch[3]);
  for (int i = 0; i < 32; ++i) EXPECT_EQ(packed[i], float(10 * (i / 4) + i % 4)) << i;
}
