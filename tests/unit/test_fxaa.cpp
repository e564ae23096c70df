// SPDX-License-Identifier: Apache-2.0
// FXAA: the fast path is bit-identical to the scalar reference; FXAA raises
// edge PSNR against a 16x16 supersampled reference on analytic scenes; flat
// images pass unchanged; non-finite input gives finite output; the filter
// works through the Filter interface with 3/4 channels and strided views.
#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>
#include <cstring>
#include <limits>
#include <random>
#include <string>
#include <vector>

#include "core/color.h"
#include "core/context.h"
#include "core/error.h"
#include "core/filter.h"
#include "filters/fxaa.h"
#include "metrics/metrics.h"
#include "synth/synthetic.h"
#include "test_util.h"

using namespace crisp;

namespace {

// A strided float buffer: `channels` used of `pixelFloats` per pixel, rows of
// `rowFloats` (>= width * pixelFloats). Padding is filled with a sentinel so
// writes outside the view show up.
struct Strided {
  int width, height, channels, pixelFloats, rowFloats;
  std::vector<float> data;
  Strided(int w, int h, int c, int pixelPad = 0, int rowPad = 0, float fill = -7.0f)
      : width(w), height(h), channels(c), pixelFloats(c + pixelPad), rowFloats(w * (c + pixelPad) + rowPad),
        data(std::size_t(rowFloats) * h, fill) {}
  float* at(int x, int y) { return data.data() + std::size_t(y) * rowFloats + std::size_t(x) * pixelFloats; }
  ImageView view() {
    return makeView(data.data(), Format(channels), width, height, std::size_t(pixelFloats) * 4,
                    std::size_t(rowFloats) * 4);
  }
};

Strided fromImage(const Image& rgba, int channels, int pixelPad = 0, int rowPad = 0) {
  Strided s(rgba.width, rgba.height, channels, pixelPad, rowPad);
  for (int y = 0; y < rgba.height; ++y)
    for (int x = 0; x < rgba.width; ++x)
      for (int k = 0; k < channels; ++k) s.at(x, y)[k] = rgba.at(x, y)[k];
  return s;
}

Image noiseImage(int w, int h, unsigned seed, bool hdr, bool specials) {
  std::mt19937 rng(seed);
  std::uniform_real_distribution<float> unit(0.0f, 1.0f);
  Image im(w, h, 4);
  const float inf = std::numeric_limits<float>::infinity(), nan = std::numeric_limits<float>::quiet_NaN();
  for (float& v : im.data) {
    v = unit(rng);
    if (hdr) v = v * v * 40.0f - 2.0f;  // some negative, some far above 1
    if (specials) {
      const float r = unit(rng);
      if (r < 0.02f) v = nan;
      else if (r < 0.03f) v = inf;
      else if (r < 0.04f) v = -inf;
      else if (r < 0.05f) v = 1e30f;
    }
  }
  return im;
}

Image runPacked(const Image& rgba, const fxaa::Settings& st, bool reference, int threads = 0) {
  fxaa::Workspace ws;
  ws.allocate(rgba.width, rgba.height);
  Image out(rgba.width, rgba.height, 4, -1.0f);
  if (reference)
    fxaa::runReference(rgba.view(), out.view(), st, ws);
  else
    fxaa::runFast(rgba.view(), out.view(), st, ws, threads);
  return out;
}

bool sameBits(const std::vector<float>& a, const std::vector<float>& b) {
  return a.size() == b.size() && std::memcmp(a.data(), b.data(), a.size() * sizeof(float)) == 0;
}

// PSNR of the display-encoded (clamped, sRGB) RGB over mask > 0, by the
// library's metric, cross-checked against the direct computation of
// test::maskedPsnr.
double edgePsnr(const Image& ref, const Image& test, const Image& mask) {
  const double psnr = compareImages(ref, test, &mask).psnr;
  EXPECT_NEAR(psnr, test::maskedPsnr(ref, test, mask), 1e-3);
  return psnr;
}

long count(const Image& mask) {
  long n = 0;
  for (float v : mask.data) n += v > 0.0f;
  return n;
}

}  // namespace

TEST(Fxaa, SanitizeMatchesCoreSanitizer) {
  const float inf = std::numeric_limits<float>::infinity();
  const float values[] = {0.0f, -0.0f, 1.0f, -1.0f, 65504.0f, -65504.0f, 65505.0f, -65505.0f, 1e30f, -1e30f, inf,
                          -inf, std::numeric_limits<float>::quiet_NaN(), -std::numeric_limits<float>::quiet_NaN(),
                          std::numeric_limits<float>::denorm_min(), std::numeric_limits<float>::min(), 0.5f};
  for (float v : values) {
    const float a = fxaa::sanitize(v), b = sanitizeColor(v);
    EXPECT_EQ(std::memcmp(&a, &b, 4), 0) << "value " << v;
  }
}

TEST(Fxaa, LumaIsBoundedAndMonotonic) {
  EXPECT_EQ(fxaa::perceptualLuma(0, 0, 0), 0.0f);
  EXPECT_EQ(fxaa::perceptualLuma(-5, -5, -5), 0.0f);
  float previous = 0.0f;
  for (float v = 0.01f; v < 70000.0f; v *= 1.5f) {
    const float l = fxaa::perceptualLuma(v, v, v);
    EXPECT_GT(l, previous);
    EXPECT_LE(l, 1.0f);
    previous = l;
  }
}

TEST(Fxaa, FastPathIsBitIdenticalToReference) {
  struct Case {
    int w, h;
    bool chart, hdr, specials;
  };
  const Case cases[] = {{1, 1, false, false, false}, {2, 3, false, true, false},  {17, 9, false, false, true},
                        {3, 41, false, true, true},  {64, 48, true, false, false}, {131, 77, true, false, false},
                        {97, 61, false, false, false}, {200, 150, false, true, true},
                        {1, 37, false, false, true},  {37, 1, false, true, true}};  // a single column, a single row
  fxaa::Settings variants[4];
  variants[1].subpix = 0.0f;
  variants[2].edgeThreshold = 0.0f;
  variants[2].edgeThresholdMin = 0.0f;
  variants[3].subpix = 1.0f;
  variants[3].edgeThreshold = 0.063f;
  variants[3].edgeThresholdMin = 0.0312f;
  unsigned seed = 1;
  for (const Case& c : cases) {
    const Image in = c.chart ? synth::renderCentre(synth::testChart(c.w, c.h), c.w, c.h)
                             : noiseImage(c.w, c.h, seed++, c.hdr, c.specials);
    for (int v = 0; v < 4; ++v) {
      const Image ref = runPacked(in, variants[v], true);
      for (int threads : {1, 2, 0}) {
        const Image fast = runPacked(in, variants[v], false, threads);
        EXPECT_TRUE(sameBits(ref.data, fast.data))
            << c.w << "x" << c.h << " variant " << v << " threads " << threads;
      }
    }
  }
}

// Frames of 8 MiB and more take the streaming-store branch of the fast path.
TEST(Fxaa, FastPathIsBitIdenticalOnLargeFrames) {
  const int w = 1030, h = 520;
  ASSERT_GE(std::size_t(w) * h * 16, std::size_t(8) << 20);
  const Image chart = synth::renderCentre(synth::testChart(w, h), w, h);
  Image noisy = noiseImage(w, h, 5, true, true);
  for (int y = 0; y < h; y += 2)  // half chart rows, half HDR noise with NaN/Inf
    std::memcpy(noisy.at(0, y), chart.at(0, y), sizeof(float) * 4 * w);
  const Image ref = runPacked(noisy, fxaa::Settings{}, true);
  EXPECT_TRUE(sameBits(ref.data, runPacked(noisy, fxaa::Settings{}, false, 0).data));
  EXPECT_TRUE(sameBits(ref.data, runPacked(noisy, fxaa::Settings{}, false, 1).data));
}

TEST(Fxaa, FastPathIsBitIdenticalOnStridedViews) {
  const Image chart = synth::renderCentre(synth::testChart(53, 37), 53, 37);
  fxaa::Settings st;
  const Image expected = runPacked(chart, st, true);
  for (int channels : {3, 4}) {
    Strided in = fromImage(chart, channels, 1, 5);  // padded pixels and rows
    for (bool reference : {true, false}) {
      Strided out(53, 37, channels, 2, 3);
      fxaa::Workspace ws;
      ws.allocate(53, 37);
      if (reference)
        fxaa::runReference(in.view(), out.view(), st, ws);
      else
        fxaa::runFast(in.view(), out.view(), st, ws, 0);
      for (int y = 0; y < 37; ++y)
        for (int x = 0; x < 53; ++x) {
          for (int k = 0; k < 3; ++k) ASSERT_EQ(out.at(x, y)[k], expected.at(x, y)[k]) << x << "," << y;
          if (channels == 4) {
            ASSERT_EQ(out.at(x, y)[3], chart.at(x, y)[3]);
          }
          ASSERT_EQ(out.at(x, y)[channels], -7.0f) << "pixel padding overwritten";
        }
    }
  }
}

// FXAA must bring edge pixels closer to the 16x16 box-filtered reference.
TEST(Fxaa, RaisesEdgePsnrOnTestChart) {
  const int w = 192, h = 128;
  const auto [one, ref, mask] = test::renderEdgeFrames(synth::testChart(w, h), w, h);
  ASSERT_GT(count(mask), 500);
  const Image out = runPacked(one, fxaa::Settings{}, false);
  const double before = edgePsnr(ref, one, mask), after = edgePsnr(ref, out, mask);
  std::printf("[ fxaa ] test chart %dx%d, %ld edge pixels: 1-sample %.2f dB -> fxaa %.2f dB (%+.2f dB)\n", w, h,
              count(mask), before, after, after - before);
  EXPECT_GT(after - before, 1.0);
}

TEST(Fxaa, RaisesEdgePsnrOnEdgesAtManyAngles) {
  const int w = 64, h = 64;
  double sumGain = 0.0, worst = 1e9;
  int measured = 0;
  for (float angle = 2.0f; angle < 180.0f; angle += 11.0f) {
    const synth::Scene scene = synth::edgeScene(w, h, angle, 0.3f);
    const auto [one, ref, mask] = test::renderEdgeFrames(scene, w, h);
    if (count(mask) < 20) continue;
    const Image out = runPacked(one, fxaa::Settings{}, false);
    const double before = edgePsnr(ref, one, mask), after = edgePsnr(ref, out, mask);
    std::printf("[ fxaa ] edge %5.1f deg: 1-sample %.2f dB -> fxaa %.2f dB (%+.2f dB)\n", angle, before, after,
                after - before);
    EXPECT_GT(after - before, 0.5) << "angle " << angle;
    sumGain += after - before;
    worst = std::min(worst, after - before);
    ++measured;
  }
  ASSERT_GE(measured, 14);
  std::printf("[ fxaa ] edges: mean gain %+.2f dB, worst %+.2f dB over %d angles\n", sumGain / measured, worst,
              measured);
  EXPECT_GT(sumGain / measured, 2.0);
}

TEST(Fxaa, FlatImagesAreUnchangedExactly) {
  const float colours[][4] = {{0.0f, 0.0f, 0.0f, 1.0f}, {0.18f, 0.5f, 0.9f, 0.25f}, {250.0f, 3.0f, 0.0f, 1.0f},
                              {-0.5f, 0.2f, 1e-30f, 0.0f}};
  for (const auto& c : colours)
    for (bool reference : {true, false}) {
      Image flat(23, 11, 4);
      for (int i = 0; i < 23 * 11; ++i) std::memcpy(&flat.data[std::size_t(i) * 4], c, sizeof(c));
      fxaa::Settings st;
      st.edgeThresholdMin = 0.0f;  // no absolute floor: only flatness keeps pixels unchanged
      st.edgeThreshold = 0.0f;
      EXPECT_TRUE(sameBits(runPacked(flat, st, reference).data, flat.data)) << c[0] << " ref " << reference;
    }
}

// The sub-pixel path by hand (FXAA 3.11 step 2): a grey pixel of linear 0.5625
// (luma m ~ 0.6) on black (luma 0), its 4 diagonal neighbours 0.25 (luma d ~
// 0.447). The 3x3 low-pass (weights 1 2 1 / 2 0 2 / 1 2 1) is 4d / 12 = d / 3,
// the range (centre and cross) m, so subpixContrast = |d / 3 - m| / m ~ 0.7516,
// eased = (3 - 2 c) c^2 ~ 0.8455 and the blend eased^2 subpix ~ 0.7149 * 0.75
// ~ 0.5362 (eased subpix would give 0.634). The pattern is symmetric: the
// edge counts as horizontal (a tie), the step as upward (a tie) and the search
// ends at equal distances both ways, so the edge blend is 0.5 - 1/2 = 0 and the
// offset is -0.5362: the colour is fetched 0.5362 px up, lerp(black, centre,
// 1 - 0.5362), i.e. 0.5625 (1 - 0.5362) ~ 0.2609.
TEST(Fxaa, SubPixelBlendOfALoneBrightPixelIsComputedByHand) {
  const int w = 9, h = 9, cx = 4, cy = 4;
  const float centre = 0.5625f, diagonal = 0.25f;
  Image in(w, h, 4, 0.0f);
  for (int c = 0; c < 3; ++c) {
    in.at(cx, cy)[c] = centre;
    for (int dy : {-1, 1})
      for (int dx : {-1, 1}) in.at(cx + dx, cy + dy)[c] = diagonal;
  }
  const float m = fxaa::perceptualLuma(centre, centre, centre), d = fxaa::perceptualLuma(diagonal, diagonal, diagonal);
  const double contrast = std::fabs(d / 3.0 - m) / m;
  const double eased = (3.0 - 2.0 * contrast) * contrast * contrast;
  const double blend = eased * eased * fxaa::Settings{}.subpix;
  EXPECT_NEAR(blend, 0.5362, 1e-3);
  for (bool reference : {true, false}) {
    const Image out = runPacked(in, fxaa::Settings{}, reference);
    for (int c = 0; c < 3; ++c) EXPECT_NEAR(out.at(cx, cy)[c], centre * (1.0 - blend), 1e-5) << "reference " << reference;
  }
}

TEST(Fxaa, NonFiniteInputGivesFiniteOutput) {
  for (bool reference : {true, false}) {
    const Image in = noiseImage(37, 29, 99, true, true);
    const Image out = runPacked(in, fxaa::Settings{}, reference);
    for (float v : out.data) ASSERT_TRUE(std::isfinite(v));
    // A NaN pixel in a flat area becomes 0, an Inf one the largest kept value.
    Image flat(9, 9, 4, 0.5f);
    flat.at(4, 4)[0] = std::numeric_limits<float>::quiet_NaN();
    flat.at(1, 1)[3] = std::numeric_limits<float>::infinity();
    const Image o = runPacked(flat, fxaa::Settings{}, reference);
    for (float v : o.data) ASSERT_TRUE(std::isfinite(v));
    EXPECT_EQ(o.at(1, 1)[3], kMaxColor);
  }
}

TEST(Fxaa, ThroughTheFilterInterface) {
  Context context;
  const int w = 45, h = 31;
  const Image chart = synth::renderCentre(synth::testChart(w, h), w, h);
  const Image expected = runPacked(chart, fxaa::Settings{}, true);
  for (int inChannels : {3, 4})
    for (int outChannels : {3, 4})
      for (bool reference : {false, true}) {
        std::unique_ptr<Filter> f = createFilter(context, "fxaa");
        EXPECT_STREQ(f->type(), "fxaa");
        Strided in = fromImage(chart, inChannels, inChannels == 3 ? 1 : 0, 7);
        Strided out(w, h, outChannels, 0, 2);
        f->setImage("color", in.view());
        f->setImage("output", out.view());
        f->params().setBool("reference", reference);
        f->commit();
        f->execute();
        for (int y = 0; y < h; ++y)
          for (int x = 0; x < w; ++x) {
            for (int k = 0; k < 3; ++k) ASSERT_EQ(out.at(x, y)[k], expected.at(x, y)[k]);
            if (outChannels == 4) {
              ASSERT_EQ(out.at(x, y)[3], inChannels == 4 ? chart.at(x, y)[3] : 1.0f);
            }
          }
      }
}

TEST(Fxaa, InPlaceMatchesOutOfPlace) {
  Context context;
  const int w = 40, h = 26;
  const Image chart = synth::renderCentre(synth::testChart(w, h), w, h);
  const Image expected = runPacked(chart, fxaa::Settings{}, true);
  for (bool reference : {false, true}) {
    Image buffer = chart;
    std::unique_ptr<Filter> f = createFilter(context, "fxaa");
    f->setImage("color", buffer.view());
    f->setImage("output", buffer.view());
    f->params().setBool("reference", reference);
    f->commit();
    f->execute();
    EXPECT_TRUE(sameBits(buffer.data, expected.data)) << "reference " << reference;
  }
}

TEST(Fxaa, ParametersAreValidatedAndDocumented) {
  Context context;
  std::unique_ptr<Filter> f = createFilter(context, "fxaa");
  EXPECT_FLOAT_EQ(f->params().getFloat("edgeThreshold"), 0.166f);
  EXPECT_FLOAT_EQ(f->params().getFloat("edgeThresholdMin"), 0.0833f);
  EXPECT_FLOAT_EQ(f->params().getFloat("subpix"), 0.75f);
  EXPECT_FALSE(f->params().getBool("reference"));
  EXPECT_THROW(f->params().setFloat("subpix", 1.5f), Exception);
  EXPECT_THROW(f->params().setFloat("edgeThreshold", -0.1f), Exception);
  EXPECT_THROW(f->params().setFloat("sharpness", 1.0f), Exception);
  const std::string doc = f->doc();
  for (const char* name : {"edgeThreshold", "edgeThresholdMin", "subpix", "reference"})
    EXPECT_NE(doc.find(name), std::string::npos) << name;
  // Parameters change the result: no sub-pixel blending leaves more of the input.
  const int w = 64, h = 48;
  const Image chart = synth::renderCentre(synth::testChart(w, h), w, h);
  fxaa::Settings none;
  none.subpix = 0.0f;
  EXPECT_FALSE(sameBits(runPacked(chart, none, false).data, runPacked(chart, fxaa::Settings{}, false).data));
  // Missing output image: clear error at commit.
  Image in = chart;
  f->setImage("color", in.view());
  try {
    f->commit();
    FAIL() << "commit without output succeeded";
  } catch (const Exception& e) {
    EXPECT_NE(std::string(e.what()).find("output"), std::string::npos) << e.what();
  }
}

TEST(Fxaa, WorkspaceSizeMismatchIsAnError) {
  fxaa::Workspace ws;
  ws.allocate(8, 8);
  Image a(9, 8, 4), b(9, 8, 4);
  EXPECT_THROW(fxaa::runFast(a.view(), b.view(), fxaa::Settings{}, ws, 0), Exception);
  EXPECT_THROW(fxaa::runReference(a.view(), b.view(), fxaa::Settings{}, ws), Exception);
  fxaa::Workspace empty;
  EXPECT_THROW(fxaa::runFast(a.view(), b.view(), fxaa::Settings{}, empty, 0), Exception);
  Image three(8, 8, 4), two(8, 8, 2);
  EXPECT_THROW(fxaa::runFast(three.view(), two.view(), fxaa::Settings{}, ws, 0), Exception);
}
