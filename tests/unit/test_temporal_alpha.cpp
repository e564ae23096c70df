// SPDX-License-Identifier: Apache-2.0
// The temporal methods' alpha (native/filters/temporal_alpha.h): a
// transparent render's coverage is anti-aliased as its colour is, opaque
// renders are left as they were, and the alpha's history follows the
// filter's (reset, in-place use, reference path).
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <limits>
#include <string>
#include <vector>

#include "core/context.h"
#include "core/filter.h"
#include "filters/phlm.h"
#include "filters/taa.h"
#include "filters/temporal_alpha.h"
#include "synth/moving.h"
#include "temporal_test_util.h"

using namespace crisp;

using test::psnr;
using Driver = test::TemporalDriver;

namespace {

constexpr const char* kMethods[] = {"taa", "taa-improved", "phlm"};

// White shapes over an empty background, as a render with Film > Transparent
// gives them: every pixel's sample is covered (1) or not (0), Blender
// premultiplies the colour, so colour and alpha carry the same coverage, and
// the reference's alpha is the filtered coverage its red channel shows.
void makeWhiteOverEmpty(synth::SceneState& s) {
  s.background[0] = s.background[1] = s.background[2] = 0.0f;
  for (synth::MovingShape& m : s.shapes) m.shape.rgb[0] = m.shape.rgb[1] = m.shape.rgb[2] = 1.0f;
}
void alphaFromRed(Image& im) {
  for (std::size_t i = 0; i + 3 < im.data.size(); i += 4) im.data[i + 3] = im.data[i];
}
std::vector<synth::FrameData> transparentFrames(synth::Sequence seq, int w, int h, int frames,
                                                const synth::FrameOptions& opt) {
  makeWhiteOverEmpty(seq.before);
  makeWhiteOverEmpty(seq.after);
  std::vector<synth::FrameData> out;
  for (int t = 0; t < frames; ++t) {
    synth::FrameData f = synth::renderFrame(seq, w, h, t, opt);
    alphaFromRed(f.color);
    alphaFromRed(f.reference);
    out.push_back(std::move(f));
  }
  return out;
}

// An image's alpha as an opaque grey picture, for PSNR.
Image alphaAsGrey(const Image& im) {
  Image g(im.width, im.height, 4);
  for (std::size_t i = 0; i < im.data.size(); i += 4) {
    g.data[i] = g.data[i + 1] = g.data[i + 2] = im.data[i + 3];
    g.data[i + 3] = 1.0f;
  }
  return g;
}

synth::FrameOptions eeveeJitter() {
  synth::FrameOptions opt;
  opt.jitter = synth::JitterKind::BlackmanHarris;
  opt.reference = synth::ReferenceKind::BlackmanHarris;
  return opt;
}

}  // namespace

// The still chart as a transparent render: after two jitter periods the
// alpha of every temporal method has converged toward EEVEE's filtered
// coverage as its colour has, far from the 1-sample render's 0-or-1 alpha.
// taa and taa-improved filter the alpha with the colour's kernel and
// settings, so for this input (colour = alpha) alpha equals red bit for bit.
TEST(TemporalAlpha, StillTransparentChartConvergesToTheFilteredCoverage) {
  const int w = 48, h = 32, frames = 32;
  const std::vector<synth::FrameData> input =
      transparentFrames(synth::staticChartSequence(w, h), w, h, frames, eeveeJitter());
  const Image& reference = input.back().reference;
  const double oneSample = psnr(alphaAsGrey(reference), alphaAsGrey(input.back().color));
  for (const char* method : kMethods) {
    Driver d(method);
    for (int t = 0; t < frames; ++t) d.run(input[std::size_t(t)], false, false);
    const double alpha = psnr(alphaAsGrey(reference), alphaAsGrey(d.output));
    const double colour = psnr(reference, d.output);
    std::printf("%s, still transparent chart %dx%d, frame %d: alpha PSNR %.2f dB (1 sample %.2f), colour %.2f dB\n",
                method, w, h, frames, alpha, oneSample, colour);
    EXPECT_GT(alpha, oneSample + 10.0) << method;
    EXPECT_NEAR(alpha, colour, 1.0) << method;
    bool alphaIsRed = true, inRange = true;
    for (std::size_t i = 0; i < d.output.data.size(); i += 4) {
      alphaIsRed &= d.output.data[i + 3] == std::clamp(d.output.data[i], 0.0f, 1.0f);
      inRange &= d.output.data[i + 3] >= 0.0f && d.output.data[i + 3] <= 1.0f;
    }
    EXPECT_TRUE(inRange) << method;
    if (std::string(method) != "phlm") {
      EXPECT_TRUE(alphaIsRed) << method;
    }
  }
}

// A white disk crossing an empty background (seed 000's ghosting sequence
// as a transparent render, exact motion and depth): the alpha follows the
// disk, with no trail where it has been, and beats the 1-sample alpha.
TEST(TemporalAlpha, MovingDiskAlphaFollowsWithoutATrail) {
  const int w = 64, h = 40, frames = 24, warmUp = 8;
  const std::vector<synth::FrameData> input =
      transparentFrames(synth::ghostingSequence(w, h, 8.0f, 1.3f, 0.0f), w, h, frames, eeveeJitter());
  for (const char* method : kMethods) {
    Driver d(method);
    double filtered = 0, oneSample = 0;
    for (int t = 0; t < frames; ++t) {
      const synth::FrameData& f = input[std::size_t(t)];
      d.run(f, true, true);
      if (t < warmUp) continue;
      const Image ref = alphaAsGrey(f.reference);
      filtered += psnr(ref, alphaAsGrey(d.output)) / (frames - warmUp);
      oneSample += psnr(ref, alphaAsGrey(f.color)) / (frames - warmUp);
    }
    std::printf("%s, moving transparent disk %dx%d: mean alpha PSNR after frame %d %.2f dB (1 sample %.2f)\n", method,
                w, h, warmUp, filtered, oneSample);
    EXPECT_GT(filtered, oneSample + 10.0) << method;
  }
}

// An opaque render (alpha 1 everywhere) keeps no alpha history and its
// outputs' alpha is 1; alpha that shows up later starts the alpha's history,
// which then runs every frame until a reset.
TEST(TemporalAlpha, OpaqueFramesKeepNothingAndAlphaStartsItsHistory) {
  const int w = 32, h = 16;
  synth::FrameOptions opt = eeveeJitter();
  opt.reference = synth::ReferenceKind::None;
  const synth::FrameData opaque = synth::renderFrame(synth::staticChartSequence(w, h), w, h, 0, opt);
  const std::vector<synth::FrameData> transparent =
      transparentFrames(synth::staticChartSequence(w, h), w, h, 1, opt);
  taa::Settings s;
  TemporalAlpha alpha;
  alpha.allocate(w, h, false);
  Image out(w, h, 4);
  for (float& v : out.data) v = 0.25f;
  alpha.run(opaque.color.view(), false, {}, {}, nullptr, out.view(), s, false, 1);
  EXPECT_FALSE(alpha.active());
  EXPECT_EQ(alpha.bytesKeptBetweenFrames(), 0u);
  EXPECT_EQ(out.data[3], 0.25f);  // left alone: the method passed the input's alpha through

  alpha.run(transparent[0].color.view(), true, {}, {}, nullptr, out.view(), s, false, 1);
  ASSERT_TRUE(alpha.active());
  EXPECT_GT(alpha.bytesKeptBetweenFrames(), 0u);
  EXPECT_EQ(alpha.kernel()->framesSinceReset(), 1);
  alpha.run(opaque.color.view(), false, {}, {}, nullptr, out.view(), s, false, 1);  // still filtered: no gap
  EXPECT_EQ(alpha.kernel()->framesSinceReset(), 2);
  const std::size_t held = alpha.bytesKeptBetweenFrames();
  alpha.reset();
  EXPECT_FALSE(alpha.active());
  alpha.run(opaque.color.view(), false, {}, {}, nullptr, out.view(), s, false, 1);
  EXPECT_FALSE(alpha.active());
  EXPECT_EQ(alpha.bytesKeptBetweenFrames(), held);  // a reset keeps the memory for the next alpha
  alpha.allocate(w + 1, h, false);
  EXPECT_EQ(alpha.bytesKeptBetweenFrames(), 0u);  // a new size frees it

  // Through the filters: the opaque chart's outputs keep alpha 1.
  for (const char* method : kMethods) {
    Driver d(method);
    for (int t = 0; t < 3; ++t) d.run(opaque, false, false);
    bool one = true;
    for (std::size_t i = 3; i < d.output.data.size(); i += 4) one &= d.output.data[i] == 1.0f;
    EXPECT_TRUE(one) << method;
  }
}

// The alpha's history is the filter's: the reference path gives the same
// bits as the fast one, an output written over its own colour input gives
// the same as separate buffers, a reset starts both histories over, and NaN
// alphas give finite alphas in [0, 1].
TEST(TemporalAlpha, FollowsTheFiltersReferencePathInPlaceUseAndReset) {
  const int w = 40, h = 24, frames = 10;
  std::vector<synth::FrameData> input =
      transparentFrames(synth::ghostingSequence(w, h, 6.0f, 1.3f, 0.0f), w, h, frames, eeveeJitter());
  input[5].color.data[4 * (w * 10 + 20) + 3] = std::numeric_limits<float>::quiet_NaN();
  for (const char* method : kMethods) {
    Driver fast(method, 2), reference(method), inPlace(method, 2);
    reference.filter->params().setBool("reference", true);
    for (int t = 0; t < frames; ++t) {
      const synth::FrameData& f = input[std::size_t(t)];
      const Image& a = fast.run(f, true, true);
      const Image& b = reference.run(f, true, true);
      EXPECT_EQ(a.data, b.data) << method << " frame " << t;
      // In place: the output is the colour buffer.
      Image buffer = f.color;
      Filter& filter = *inPlace.filter;
      filter.setImage("color", buffer.view());
      filter.setImage("motion", f.motion.view());
      filter.setImage("depth", f.depth.view());
      if (std::string(method) == "taa-improved") filter.setImage("id", f.id.view());
      filter.setImage("output", buffer.view());
      filter.params().setFloat("jitterX", f.jitter.x);
      filter.params().setFloat("jitterY", f.jitter.y);
      filter.markDirty("the jitter was set");
      filter.commit();
      filter.execute();
      EXPECT_EQ(buffer.data, a.data) << method << " in place, frame " << t;
      bool ok = true;
      for (std::size_t i = 3; i < a.data.size(); i += 4) ok &= a.data[i] >= 0.0f && a.data[i] <= 1.0f;
      EXPECT_TRUE(ok) << method << " frame " << t;
    }
    // A reset starts the alpha over with the colour: the next frame is a first frame for both.
    fast.filter->reset();
    Driver fresh(method, 2);
    EXPECT_EQ(fast.run(input[3], true, true).data, fresh.run(input[3], true, true).data) << method;
  }
}

// The kernels note an input alpha below 1 as they read the colour (so an
// opaque frame is not read again for it), on every path that writes the
// output's alpha: whole and partial lane groups of each fast-path copy,
// strided output, sharpen, no unjitter, the reference; never for alpha 1 or
// an RGB input. A NaN alpha counts (it reads as 0).
TEST(TemporalAlpha, KernelsNoteAnAlphaBelowOneOnEveryPath) {
  const int w = 37, h = 9;  // 37: a partial lane group at the end of each row
  synth::FrameOptions opt = eeveeJitter();
  opt.reference = synth::ReferenceKind::None;
  std::vector<synth::FrameData> pan = test::pannedChart(w, h, 2, 0.37f, -0.21f, opt);
  struct Where { int x, y; float alpha; };
  const Where cases[] = {{-1, -1, 1.0f}, {5, 4, 0.5f}, {36, 7, 0.0f}, {0, 0, 0.99f},
                         {20, 8, std::numeric_limits<float>::quiet_NaN()}};
  int checked = 0;
  for (const Where& c : cases)
    for (int run = 0; run < 24; ++run) {
      const bool reference = run % 2, sharpen = run / 2 % 2, unjitter = run / 4 % 2, strided = run / 8 % 3 == 1;
      const bool rgb = run / 8 % 3 == 2;
      const test::FastPathIsa isa(test::kFastPathIsas[run % 3]);
      taa::Settings s;
      s.sharpen = sharpen ? 0.5f : 0.0f;
      s.unjitter = unjitter ? temporal::UnjitterMode::BlackmanHarris : temporal::UnjitterMode::None;
      taa::Kernel taaKernel;
      taaKernel.allocate(w, h, true);
      phlm::Kernel<float> phlmKernel;
      phlmKernel.allocate(w, h, true, true);
      Image wide(w + 3, h, 4);  // the output as a strided view into a wider image
      for (int t = 0; t < 2; ++t) {
        synth::FrameData f = pan[std::size_t(t)];
        if (c.x >= 0) f.color.at(c.x, c.y)[3] = c.alpha;
        Image rgbColor(w, h, 3);
        for (int i = 0; i < w * h; ++i)
          for (int k = 0; k < 3; ++k) rgbColor.data[std::size_t(3 * i + k)] = f.color.data[std::size_t(4 * i + k)];
        Image out(w, h, 4);
        taa::Inputs in;
        in.color = rgb ? rgbColor.view() : f.color.view();
        in.motion = f.motion.view();
        in.depth = f.depth.view();
        in.output = strided ? makeView(wide.data.data(), Format::Float4, w, h, 16, std::size_t(w + 3) * 16)
                            : out.view();
        s.jitterX = f.jitter.x;
        s.jitterY = f.jitter.y;
        taaKernel.run(in, s, reference, 2);
        phlm::Inputs pin;
        pin.color = in.color;
        pin.motion = in.motion;
        pin.depth = in.depth;
        pin.output = out.view();
        phlm::Settings ps;
        ps.jitterX = f.jitter.x;
        ps.jitterY = f.jitter.y;
        phlmKernel.run(pin, ps, reference, 2);
        const bool want = c.x >= 0 && !rgb;
        EXPECT_EQ(taaKernel.alphaBelowOneLastFrame(), want)
            << "taa (" << c.x << "," << c.y << ") run " << run << " frame " << t << " " << temporal::fastPathIsaName();
        EXPECT_EQ(phlmKernel.alphaBelowOneLastFrame(), want) << "phlm (" << c.x << "," << c.y << ") run " << run;
        ++checked;
      }
    }
  EXPECT_EQ(checked, 5 * 24 * 2);
}

// Once alpha has shown up, its history runs every frame until a reset, also
// through a frame whose colour has no alpha (read as 1, as the colour kernel
// writes it) or whose output has none (nothing to write it to): the frames
// after it are the same bits as a run where that frame had alpha 1, and as a
// run that wrote every frame's alpha. (The alpha's history skipped such a
// frame, so its reprojection missed that frame's motion.)
TEST(TemporalAlpha, AFrameWithoutAlphaKeepsTheAlphasHistoryGoing) {
  const int w = 40, h = 24, frames = 8, gap = 3;
  const std::vector<synth::FrameData> input =
      transparentFrames(synth::ghostingSequence(w, h, 6.0f, 1.3f, 0.0f), w, h, frames, eeveeJitter());
  std::vector<synth::FrameData> opaqueAtGap = input;
  for (std::size_t i = 3; i < opaqueAtGap[gap].color.data.size(); i += 4) opaqueAtGap[gap].color.data[i] = 1.0f;
  for (const char* method : kMethods) {
    Driver all(method), rgbColour(method), rgbOutput(method), opaque(method);
    for (int t = 0; t < frames; ++t) {
      const synth::FrameData& f = input[std::size_t(t)];
      const Image& expected = all.run(f, true, true);
      const Image& withOpaque = opaque.run(opaqueAtGap[std::size_t(t)], true, true);
      if (t != gap) {
        EXPECT_EQ(rgbColour.run(f, true, true).data, withOpaque.data) << method << " frame " << t;
        EXPECT_EQ(rgbOutput.run(f, true, true).data, expected.data) << method << " frame " << t;
        continue;
      }
      // This frame's colour as RGB: its RGBA buffer read through a 16-byte pixel stride.
      Filter& c = *rgbColour.filter;
      c.setImage("color", makeView(const_cast<float*>(f.color.data.data()), Format::Float3, w, h, 16));
      c.setImage("motion", f.motion.view());
      c.setImage("depth", f.depth.view());
      if (std::string(method) == "taa-improved") c.setImage("id", f.id.view());
      c.setImage("output", rgbColour.output.view());
      c.params().setFloat("jitterX", f.jitter.x);
      c.params().setFloat("jitterY", f.jitter.y);
      c.commit();
      c.execute();
      EXPECT_EQ(rgbColour.output.data, withOpaque.data) << method << " frame " << t << ", RGB colour";
      // This frame's output as RGB: no alpha written, the alpha's history still runs.
      Filter& o = *rgbOutput.filter;
      o.setImage("color", f.color.view());
      o.setImage("motion", f.motion.view());
      o.setImage("depth", f.depth.view());
      if (std::string(method) == "taa-improved") o.setImage("id", f.id.view());
      o.setImage("output", makeView(rgbOutput.output.data.data(), Format::Float3, w, h, 16));
      o.params().setFloat("jitterX", f.jitter.x);
      o.params().setFloat("jitterY", f.jitter.y);
      o.commit();
      o.execute();
    }
  }
}

// Alpha is coverage: an input alpha above 1 (+Inf, or 1.5 from a careless
// composite) is filtered as 1, not as a value up to 65504 whose pixel filter
// made its 3x3 neighbours opaque over an empty background.
TEST(TemporalAlpha, AlphaAboveOneIsFilteredAsOne) {
  const int w = 40, h = 24, frames = 4;
  const std::vector<synth::FrameData> input =
      transparentFrames(synth::ghostingSequence(w, h, 6.0f, 1.3f, 0.0f), w, h, frames, eeveeJitter());
  for (const float above : {1.5f, std::numeric_limits<float>::infinity()}) {
    for (const char* method : kMethods) {
      Driver one(method), high(method);
      for (int t = 0; t < frames; ++t) {
        synth::FrameData a = input[std::size_t(t)], b = a;
        for (int y = 0; y < h; y += 5)
          for (int x = 0; x < w; x += 7) {  // background pixels (alpha 0) and the disk's (1) alike
            a.color.data[4 * std::size_t(y * w + x) + 3] = 1.0f;
            b.color.data[4 * std::size_t(y * w + x) + 3] = above;
          }
        const Image& expected = one.run(a, true, true);
        const Image& got = high.run(b, true, true);
        bool same = true;
        for (std::size_t i = 3; i < got.data.size(); i += 4) same &= got.data[i] == expected.data[i];
        EXPECT_TRUE(same) << method << " alpha " << above << ", frame " << t;
      }
    }
  }
}
