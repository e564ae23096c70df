// SPDX-License-Identifier: Apache-2.0
// The synthetic long runs of the temporal filters' stability suite (issue 4:
// constant colour, slow gradients, black/white flicker, HDR fireflies,
// NaN/+-Inf pixels, zero and huge motion, off-screen reprojection,
// disocclusion, depth at infinity, camera cut), shared by
// test_phlm_stability.cpp and test_taa_stability.cpp, with the colour range
// each output pixel must stay inside.
//
// The frame is kWidth x kHeight = 35 x 8: wide enough that the fast paths'
// 8-lane groups run on its interior (phlm.cpp phlmGroup needs 17 columns,
// taa.cpp's rows are 8 lanes at a time) next to the clamped edge pixels,
// and not a multiple of 8, so the partial lane group at a row's end runs too.
// Every frame carries EEVEE's jitter (temporal::jitterForFrame,
// Blackman-Harris, +-1.5 px), so the unjitter shift moves the 3x3 as it does
// on a real render.
#pragma once

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <functional>
#include <initializer_list>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <limits>
#include <random>
#include <string>
#include <vector>

#include "core/color.h"
#include "core/image.h"
#include "temporal/jitter.h"
#include "temporal/velocity.h"

namespace crisp::test::stability {

constexpr int kWidth = 35, kHeight = 8;
// The long runs' length: 20 000 frames (issue 4). CRISP_STABILITY_FRAMES (at
// least 1000) shortens them where the code paths matter and the long-run
// drift does not: scripts/test.sh's sanitizer stage, where the 20 000-frame
// runs took over 6 minutes each.
inline int runFrames() {
  static const int frames = [] {
    const char* e = std::getenv("CRISP_STABILITY_FRAMES");
    const int n = e ? std::atoi(e) : 0;
    return n >= 1000 ? n : 20000;
  }();
  return frames;
}

struct Input {
  Image color{kWidth, kHeight, 4, 0.0f};
  Image motion{kWidth, kHeight, 2, 0.0f};
  Image depth{kWidth, kHeight, 1, 10.0f};
};

struct Scenario {
  const char* name;
  bool motion, depth;  // the filter is given these images
  std::function<void(int t, Input&)> make;
};

// This frame's sample offset (pixels, library convention).
inline temporal::Jitter jitterAt(int t) {
  return temporal::jitterForFrame(t, temporal::JitterDistribution::BlackmanHarris);
}

inline void fill(Image& im, float r, float g, float b) {
  for (int y = 0; y < im.height; ++y)
    for (int x = 0; x < im.width; ++x) {
      float* p = im.at(x, y);
      p[0] = r, p[1] = g, p[2] = b, p[3] = 1.0f;
    }
}

// A static texture: every pixel its own colour, periods 6, 5 and 4.
inline void texture(Image& im, float scale) {
  for (int y = 0; y < im.height; ++y)
    for (int x = 0; x < im.width; ++x) {
      float* p = im.at(x, y);
      p[0] = scale * (0.1f + 0.13f * float((x * 7 + y * 3) % 6));
      p[1] = scale * (0.2f + 0.11f * float((x * 5 + y) % 5));
      p[2] = scale * (0.05f + 0.17f * float((x + y * 4) % 4));
      p[3] = 1.0f;
    }
}

inline std::vector<Scenario> scenarios() {
  constexpr int W = kWidth, H = kHeight;
  const float nan = std::numeric_limits<float>::quiet_NaN(), inf = std::numeric_limits<float>::infinity();
  std::vector<Scenario> v;
  v.push_back({"constant colour", false, false, [](int, Input& in) { fill(in.color, 0.3f, 0.5f, 0.7f); }});
  v.push_back({"slow gradient", false, false, [](int t, Input& in) {
                 const float phase = 0.5f + 0.5f * std::sin(6.2831853f * float(t) / 5000.0f);
                 for (int y = 0; y < H; ++y)
                   for (int x = 0; x < W; ++x) {
                     float* p = in.color.at(x, y);
                     p[0] = phase * (0.1f + 0.03f * float(x));
                     p[1] = 0.5f * phase + 0.05f * float(y);
                     p[2] = 1.0f - 0.8f * phase;
                     p[3] = 1.0f;
                   }
               }});
  v.push_back({"black/white flicker", false, false, [](int t, Input& in) {
                 const float c = (t & 1) ? 1.0f : 0.0f;
                 fill(in.color, c, c, c);
               }});
  v.push_back({"checker flicker", false, false, [](int t, Input& in) {
                 for (int y = 0; y < H; ++y)
                   for (int x = 0; x < W; ++x) {
                     const float c = ((x + y + t) & 1) ? 1.0f : 0.0f;
                     float* p = in.color.at(x, y);
                     p[0] = p[1] = p[2] = c, p[3] = 1.0f;
                   }
               }});
  // Inputs are sanitised to +-65504 (conventions.h kMaxColor), so 1e5 and 1e6 arrive as 65504.
  v.push_back({"HDR fireflies 1e4-1e6", false, false, [](int t, Input& in) {
                 texture(in.color, 1.0f);
                 std::mt19937 rng{unsigned(t)};
                 for (int i = 0; i < 2; ++i)
                   if (rng() % 3 == 0) {
                     float* p = in.color.at(int(rng() % W), int(rng() % H));
                     const float mag = std::pow(10.0f, 4.0f + 2.0f * float(rng() % 1000) / 999.0f);
                     p[0] = p[1] = p[2] = mag;
                   }
               }});
  v.push_back({"NaN/+-Inf pixels", true, true, [nan, inf](int t, Input& in) {
                 texture(in.color, 2.0f);
                 std::mt19937 rng(unsigned(t) * 7u + 1u);
                 const float bad[4] = {nan, inf, -inf, -3.0f};
                 for (int i = 0; i < 6; ++i) in.color.at(int(rng() % W), int(rng() % H))[rng() % 3] = bad[rng() % 4];
                 for (int i = 0; i < W * H; ++i) {
                   in.motion.data[2 * i] = (rng() % 5 == 0) ? nan : 0.0f;
                   in.motion.data[2 * i + 1] = (rng() % 7 == 0) ? inf : 0.0f;
                   in.depth.data[i] = (rng() % 6 == 0) ? nan : 10.0f;
                 }
               }});
  v.push_back({"zero motion, noisy", true, true, [](int t, Input& in) {
                 std::mt19937 rng(unsigned(t) * 13u + 5u);
                 for (int y = 0; y < H; ++y)
                   for (int x = 0; x < W; ++x) {
                     float* p = in.color.at(x, y);
                     const float n = float(rng() % 1000) / 1000.0f;
                     p[0] = 0.2f + 0.6f * n, p[1] = 0.5f, p[2] = 0.8f - 0.6f * n, p[3] = 1.0f;
                   }
                 std::fill(in.motion.data.begin(), in.motion.data.end(), 0.0f);
               }});
  v.push_back({"huge motion", true, false, [](int t, Input& in) {
                 texture(in.color, 1.0f);
                 for (int i = 0; i < W * H; ++i) {
                   in.motion.data[2 * i] = (t % 2 ? 1e6f : -3e4f) * float(1 + i % 3);
                   in.motion.data[2 * i + 1] = (t % 3 ? -1e7f : 5e5f);
                 }
               }});
  v.push_back({"pan, off-screen reprojection", true, true, [](int t, Input& in) {
                 // Content scrolls left 0.7 px per frame: pixels near the right edge reproject off-screen.
                 for (int y = 0; y < H; ++y)
                   for (int x = 0; x < W; ++x) {
                     const float u = float(x) + 0.7f * float(t);
                     float* p = in.color.at(x, y);
                     p[0] = 0.5f + 0.5f * std::sin(0.9f * u), p[1] = 0.5f + 0.4f * std::cos(0.3f * u + float(y));
                     p[2] = 0.25f, p[3] = 1.0f;
                   }
                 for (int i = 0; i < W * H; ++i) in.motion.data[2 * i] = 0.7f, in.motion.data[2 * i + 1] = 0.0f;
               }});
  v.push_back({"disocclusion", true, true, [](int t, Input& in) {
                 // A near bar 3 px wide moving right 1 px/frame over a far static background, wrapping around.
                 const int bar = t % (W + 4) - 2;
                 for (int y = 0; y < H; ++y)
                   for (int x = 0; x < W; ++x) {
                     const bool near = x >= bar && x < bar + 3;
                     float* p = in.color.at(x, y);
                     p[0] = near ? 1.0f : 0.1f * float(x % 3), p[1] = near ? 0.9f : 0.2f, p[2] = near ? 0.0f : 0.6f;
                     p[3] = 1.0f;
                     in.motion.at(x, y)[0] = near ? -1.0f : 0.0f;
                     in.motion.at(x, y)[1] = 0.0f;
                     in.depth.at(x, y)[0] = near ? 2.0f : 50.0f;
                   }
               }});
  v.push_back({"depth at infinity", true, true, [inf](int t, Input& in) {
                 texture(in.color, 0.5f);
                 const float far[4] = {inf, 1e10f, 65504.0f, 3e38f};
                 for (int i = 0; i < W * H; ++i) {
                   in.depth.data[i] = far[(i + t) % 4];
                   in.motion.data[2 * i] = 0.25f * float((t % 4) - 2), in.motion.data[2 * i + 1] = 0.0f;
                 }
               }});
  v.push_back({"camera cut halfway", false, false, [](int t, Input& in) {
                 if (t < runFrames() / 2) texture(in.color, 1.0f);
                 else fill(in.color, 0.9f, 0.1f, 0.4f);
               }});
  return v;
}

inline bool isOneOf(const Scenario& sc, std::initializer_list<const char*> names) {
  for (const char* name : names)
    if (std::string(sc.name) == name) return true;
  return false;
}

// The scenarios whose history becomes unusable after the first frame (off
// screen, non-finite motion, disocclusion), so that a filter must start some
// pixels over: the reset counts the tests assert to be 0 where nothing moves
// must count there. Not the camera cut: it has no motion image, and the box
// replaces the old history without a reset.
inline bool startsOver(const Scenario& sc) {
  return isOneOf(sc, {"NaN/+-Inf pixels", "huge motion", "pan, off-screen reprojection", "disocclusion"});
}

// The scenarios whose input repeats with a period that divides the jitter's
// (16 frames): the hold's windows all match, so no still pixel is released
// from the hold (taa::Kernel::releasesLastFrame, phlm's FrameStats::releases;
// temporal/hold_release.h).
inline bool periodic(const Scenario& sc) {
  return isOneOf(sc, {"constant colour", "black/white flicker", "checker flicker"});
}

// Frames in which nothing moved since the previous one: no motion image, or
// one of exact zeros, and (with depth) the previous frame's depth bit for
// bit. Every reprojection is then on screen, finite and onto the same
// surface, so after the first frame a filter has no reason to start a
// pixel's history over (taa::Kernel::resetsLastFrame, phlm's
// FrameStats::reprojectionResets), border pixels included.
class StillFrames {
 public:
  // This frame t (its inputs in `in`) of `sc`: still after the first frame?
  bool next(const Scenario& sc, int t, const Input& in) {
    bool still = t > 0 && t == previous_ + 1;
    if (sc.motion)
      for (std::size_t i = 0; i < in.motion.data.size() && still; ++i) still = in.motion.data[i] == 0.0f;
    if (sc.depth)
      still = still && std::memcmp(in.depth.data.data(), depth_.data.data(), in.depth.data.size() * sizeof(float)) == 0;
    depth_ = in.depth;
    previous_ = t;
    return still;
  }

 private:
  Image depth_{kWidth, kHeight, 1};
  int previous_ = -2;
};

// The colour range each output pixel must stay inside: the (sanitised)
// range of this frame's 3x3 that the unjitter reads (taa.cpp "Jitter": the
// 3x3 around the sample nearest the pixel centre, temporal::shiftedSource),
// or, where footprintExcept and nothing in the shifted 5x5 moves (as
// temporal::stillFootprint), of that 5x5 (the documented exception: still
// history is tested against the footprint box, taa.cpp "Deliberate choices",
// phlm.cpp "Box"). No motion image: nothing moves. Row-major, one per pixel.
struct Range {
  float lo[3], hi[3];
  // Rounding slack on a check against channel c: relative to the values involved.
  double slack(int c) const { return 1e-6 * (1.0 + std::fabs(lo[c]) + std::fabs(hi[c])); }
  bool contains(int c, double v) const { return v >= lo[c] - slack(c) && v <= hi[c] + slack(c); }  // false on NaN
};
inline std::vector<Range> outputRanges(const Image& color, const Image* motion, const temporal::Unjitter& u,
                                       bool footprintExcept) {
  const int w = color.width, h = color.height;
  std::vector<float> clean(std::size_t(w) * h * 3);
  std::vector<std::uint8_t> moving(std::size_t(w) * h, 0);
  for (int y = 0; y < h; ++y)
    for (int x = 0; x < w; ++x) {
      const std::size_t i = std::size_t(y) * w + x;
      for (int c = 0; c < 3; ++c) clean[3 * i + c] = sanitizeColor(color.at(x, y)[c]);
      if (motion) moving[i] = temporal::movesAt(motion->at(x, y));
    }
  std::vector<Range> ranges(std::size_t(w) * h);
  for (int y = 0; y < h; ++y)
    for (int x = 0; x < w; ++x) {
      int xs[5], ys[5];
      for (int k = 0; k < 5; ++k)
        xs[k] = temporal::shiftedSource(x + k - 2, w, u.shiftX), ys[k] = temporal::shiftedSource(y + k - 2, h, u.shiftY);
      bool still = footprintExcept;
      for (int k = 0; k < 25 && still; ++k) still = !moving[std::size_t(ys[k / 5]) * w + xs[k % 5]];
      const int first = still ? 0 : 1, last = still ? 4 : 3;
      Range& r = ranges[std::size_t(y) * w + x];
      for (int c = 0; c < 3; ++c) r.lo[c] = std::numeric_limits<float>::infinity(), r.hi[c] = -r.lo[c];
      for (int j = first; j <= last; ++j)
        for (int i = first; i <= last; ++i) {
          const float* p = &clean[3 * (std::size_t(ys[j]) * w + xs[i])];
          for (int c = 0; c < 3; ++c) r.lo[c] = std::min(r.lo[c], p[c]), r.hi[c] = std::max(r.hi[c], p[c]);
        }
    }
  return ranges;
}

// One firefly (1e6, sanitised to 65504) at frame `at` of the still image
// `still` (frames carry the jitter of jitterAt), put on every pixel in turn,
// against the same run without it. makeRun() gives a fresh filter as a
// callable (int t, const Image& color) -> const Image& (its output).
struct FireflyFade {
  bool sameBefore = true;   // no output differed before the firefly
  double atFirefly = INFINITY;  // the smallest largest-difference in its frame, over the positions
  double after[4] = {};     // the largest difference from frame at + afterFrames[i] on, over the positions
};
template <class MakeRun>
FireflyFade fireflyOnEveryPixel(const Image& still, const MakeRun& makeRun, int at, int frames,
                                const int (&afterFrames)[4]) {
  FireflyFade fade;
  std::vector<Image> clean;
  {
    auto run = makeRun();
    for (int t = 0; t < frames; ++t) clean.push_back(run(t, still));
  }
  for (int fy = 0; fy < still.height; ++fy)
    for (int fx = 0; fx < still.width; ++fx) {
      auto run = makeRun();
      for (int t = 0; t < frames; ++t) {
        Image color = still;
        if (t == at) color.at(fx, fy)[0] = color.at(fx, fy)[1] = color.at(fx, fy)[2] = 1e6f;
        const Image& out = run(t, color);
        double diff = 0;
        for (std::size_t i = 0; i < out.data.size(); ++i)
          diff = std::max(diff, double(std::fabs(clean[std::size_t(t)].data[i] - out.data[i])));
        if (t < at) fade.sameBefore &= diff == 0.0;
        if (t == at) fade.atFirefly = std::min(fade.atFirefly, diff);
        for (int i = 0; i < 4; ++i)
          if (t >= at + afterFrames[i]) fade.after[i] = std::max(fade.after[i], diff);
      }
    }
  return fade;
}

// Prints `fade` under `label` and checks it against stated bounds: no output
// differed before the firefly, it showed in its own frame wherever it landed
// (when mustShow), and the difference from frame +afterFrames[i] on stays
// within bound[i].
inline void expectFade(const FireflyFade& fade, const std::string& label, const int (&afterFrames)[4],
                       const double (&bound)[4], bool mustShow) {
  std::printf("%s, single firefly at each of %dx%d pixels: smallest difference in its frame %.3g; largest from +%d / "
              "+%d / +%d / +%d frames on: %.3g / %.3g / %.3g / %.3g\n",
              label.c_str(), kWidth, kHeight, fade.atFirefly, afterFrames[0], afterFrames[1], afterFrames[2],
              afterFrames[3], fade.after[0], fade.after[1], fade.after[2], fade.after[3]);
  EXPECT_TRUE(fade.sameBefore) << label;
  if (mustShow) {
    EXPECT_GT(fade.atFirefly, 1.0) << label;
  }
  for (int i = 0; i < 4; ++i) EXPECT_LE(fade.after[i], bound[i]) << label << " from frame +" << afterFrames[i];
}

// The hold (taa.cpp and phlm.cpp "Hold") on the still image `still` (frames
// carry the jitter of jitterAt), `frames` frames through run(t, color) ->
// const Image& (its output): the pixels whose output stays the same over
// frames [from, from + window] count as held; from then on their output must
// not change, bit for bit, however long the run. A frames-since-reset count
// that wrapped (taa's 7 bits) would release them every 128 frames.
struct HeldOutputs {
  int held = 0;          // pixels held over the window
  int firstChange = -1;  // the first later frame in which a held pixel's output changed (-1: none)
  int x = -1, y = -1;    // that pixel
};
template <class Run>
HeldOutputs heldOutputs(const Image& still, Run&& run, int from, int window, int frames) {
  HeldOutputs result;
  Image fixed;  // the output at `from`
  std::vector<std::uint8_t> held(std::size_t(still.width) * still.height, 1);
  for (int t = 0; t < frames; ++t) {
    const Image& out = run(t, still);
    if (t < from) continue;
    if (t == from) fixed = out;
    for (int y = 0; y < still.height; ++y)
      for (int x = 0; x < still.width; ++x) {
        std::uint8_t& h = held[std::size_t(y) * still.width + x];
        if (!h || std::memcmp(out.at(x, y), fixed.at(x, y), 3 * sizeof(float)) == 0) continue;
        if (t <= from + window) {
          h = 0;
        } else if (result.firstChange < 0) {
          result.firstChange = t, result.x = x, result.y = y;
        }
      }
  }
  for (std::uint8_t h : held) result.held += h;
  return result;
}

}  // namespace crisp::test::stability
