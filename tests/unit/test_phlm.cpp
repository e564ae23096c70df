// SPDX-License-Identifier: Apache-2.0
// PHLM (native/filters/phlm*): the stabilised RLS against the paper's
// equations, the row staging against its formulas, quality on the moving
// synthetic sequences of synth/moving.h (exact motion, depth and
// references), the reference vs fast path, and the filter interface. The 20 000-frame stability suite is test_phlm_stability.cpp.
#include <gtest/gtest.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <limits>
#include <random>

#include "core/color.h"
#include "core/context.h"
#include "core/error.h"
#include "core/filter.h"
#include "filters/phlm.h"
#include "filters/phlm_stage.h"
#include "metrics/metrics.h"
#include "synth/moving.h"
#include "temporal_test_util.h"

using namespace crisp;

using test::allFinite;
using test::psnr;
using Driver = test::TemporalDriver;

namespace {

// The paper's update (eqs. 6-7) in plain form, double.
struct PaperRls {
  double beta[4][3];
  double P[4][4];
  void reset(const double colour[3], double p0) {
    std::memset(beta, 0, sizeof beta);
    std::memset(P, 0, sizeof P);
    for (int c = 0; c < 3; ++c) beta[0][c] = colour[c];
    for (int i = 0; i < 4; ++i) P[i][i] = p0;
  }
  void update(const double x[4], const double e[3], double lambda) {
    double Px[4], s = lambda;
    for (int i = 0; i < 4; ++i) {
      Px[i] = 0;
      for (int j = 0; j < 4; ++j) Px[i] += P[i][j] * x[j];
      s += x[i] * Px[i];
    }
    double Q[4];
    for (int i = 0; i < 4; ++i) Q[i] = Px[i] / s;
    for (int i = 0; i < 4; ++i)
      for (int c = 0; c < 3; ++c) beta[i][c] += Q[i] * e[c];
    double xP[4];  // x'P
    for (int j = 0; j < 4; ++j) {
      xP[j] = 0;
      for (int i = 0; i < 4; ++i) xP[j] += x[i] * P[i][j];
    }
    for (int i = 0; i < 4; ++i)
      for (int j = 0; j < 4; ++j) P[i][j] = (P[i][j] - Q[i] * xP[j]) / lambda;
  }
};

}  // namespace

// Without the regulariser, forget + Bierman is exactly eqs. 6-7 (checked in
// double on well-excited random inputs, 300 steps).
TEST(PhlmRls, UdUpdateEqualsPaperEquations) {
  std::mt19937 rng(3);
  std::uniform_real_distribution<double> u(-1.0, 1.0);
  const double lambda = 0.998, colour[3] = {0.2, 0.5, 0.9};
  PaperRls paper;
  paper.reset(colour, 1000.0);
  double m[phlm::kRecord];
  phlm::resetModel(m, colour, 1000.0, 1000.0);
  for (int t = 0; t < 300; ++t) {
    const double x[4] = {1.0, 0.5 + 0.4 * u(rng), 0.3 + 0.3 * u(rng), 0.6 + 0.2 * u(rng)};
    double f[3];
    phlm::predict(m, x, f);
    double e[3];
    for (int c = 0; c < 3; ++c) e[c] = 0.4 + 0.3 * u(rng) - f[c];
    paper.update(x, e, lambda);
    phlm::forget(m, 1.0 / lambda);
    phlm::rlsUpdate(m, x, e, 1.0, 1.0);
  }
  double P[4][4];
  phlm::covariance(m, P);
  for (int i = 0; i < 4; ++i) {
    for (int j = 0; j < 4; ++j) EXPECT_NEAR(P[i][j], paper.P[i][j], 1e-9 * (1.0 + std::fabs(paper.P[i][j])));
    for (int c = 0; c < 3; ++c) EXPECT_NEAR(m[phlm::kBeta + 3 * i + c], paper.beta[i][c], 1e-8);
  }
}

// Wind-up (METHODS.md): with a constant x (static camera over flat colour) the
// paper's P grows as lambda^-k in the 3 unexcited directions; the stabilised
// form stays under its bound, in float32, for 20 000 frames.
TEST(PhlmRls, PaperFormWindsUpStabilisedFormDoesNot) {
  const double lambda = 0.998, colour[3] = {0.3, 0.5, 0.7};
  const double x[4] = {1.0, 0.25, 0.4, 0.5};
  PaperRls paper;
  paper.reset(colour, 1000.0);
  float m[phlm::kRecord];
  const float c32[3] = {0.3f, 0.5f, 0.7f};
  phlm::resetModel(m, c32, 1000.0f, 1.0f);
  const float x32[4] = {1.0f, 0.25f, 0.4f, 0.5f};
  const float zero[3] = {0, 0, 0};
  double maxTrace = 0;
  for (int t = 0; t < 20000; ++t) {
    const double e[3] = {0, 0, 0};
    paper.update(x, e, lambda);
    phlm::forget(m, 1.0f / float(lambda));
    const float variance = float(1.0 / (4.0 * (1.0 - lambda))) * (t % 4 == 0 ? 1000.0f : 1.0f);
    phlm::regularise(m, t % 4, variance, 1.0f / variance);
    phlm::rlsUpdate(m, x32, zero, 1.0f, 1.0f);
    double P[4][4], trace = 0;
    phlm::covariance(m, P);
    for (int i = 0; i < 4; ++i) trace += P[i][i];
    maxTrace = std::max(maxTrace, trace);
    for (int i = 0; i < 4; ++i) ASSERT_GT(m[phlm::kD + i], 0.0f) << "frame " << t;
  }
  double paperTrace = 0;
  for (int i = 0; i < 4; ++i) paperTrace += paper.P[i][i];
  std::printf("constant x, 20000 frames: paper trace P %.3g, stabilised max trace %.3g\n", paperTrace, maxTrace);
  EXPECT_GT(paperTrace, 1e15);  // lambda^-20000 = e^40
  EXPECT_LE(maxTrace, (1000.0 + 3.0) / std::pow(lambda, 3));
}

// Static scene (no motion image, §5.2 special case): with uniform jitter the
// output converges toward the 16x16 box reference.
TEST(Phlm, StaticSceneConverges) {
  const int w = 48, h = 40, frames = 64;
  const synth::Sequence seq = synth::staticChartSequence(w, h);
  Driver phlm("phlm"), taa("taa");
  double oneSample = 0, p[frames], t[frames];
  Image reference;
  for (int i = 0; i < frames; ++i) {
    const synth::FrameData f = synth::renderFrame(seq, w, h, i, {});
    if (i == 0) {
      reference = f.reference;
      oneSample = psnr(reference, f.color);
    }
    const Image& out = phlm.run(f, false, false);
    ASSERT_TRUE(allFinite(out));
    p[i] = psnr(reference, out);
    t[i] = psnr(reference, taa.run(f, false, false));
  }
  std::printf("static chart: PSNR 1-sample %.2f; phlm after 1/4/16/64 frames %.2f %.2f %.2f %.2f (taa %.2f %.2f %.2f "
              "%.2f)\n",
              oneSample, p[0], p[3], p[15], p[63], t[0], t[3], t[15], t[63]);
  EXPECT_GT(p[15], p[3]);
  EXPECT_GT(p[63], p[15] - 0.25);
  EXPECT_GT(p[63], oneSample + 3.0);
}

// Moving sequences with exact motion and depth: phlm beats the 1-sample
// frames on mean PSNR after warm-up (taa's figure printed beside it).
TEST(Phlm, MovingSequencesBeatOneSampleAfterWarmUp) {
  const int w = 48, h = 40, frames = 48, warmUp = 8;
  std::vector<test::MovingCase> cases = test::movingEdgeAndDisk(w, h);
  cases.push_back({"disocclusion bar v=1", synth::disocclusionSequence(w, h, 1.0f)});
  for (const test::MovingCase& c : cases) {
    Driver phlm("phlm"), taa("taa");
    double sumPhlm = 0, sumTaa = 0, sumOne = 0;
    for (int t = 0; t < frames; ++t) {
      const synth::FrameData f = synth::renderFrame(c.seq, w, h, t, {});
      const Image& out = phlm.run(f, true, true);
      ASSERT_TRUE(allFinite(out));
      const double pp = psnr(f.reference, out);
      const double pt = psnr(f.reference, taa.run(f, true, true));
      if (t < warmUp) continue;
      sumPhlm += pp;
      sumTaa += pt;
      sumOne += psnr(f.reference, f.color);
    }
    const int n = frames - warmUp;
    std::printf("%s: mean PSNR frames %d-%d: 1-sample %.2f dB, phlm %.2f dB, taa %.2f dB\n", c.name, warmUp,
                frames - 1, sumOne / n, sumPhlm / n, sumTaa / n);
    EXPECT_GT(sumPhlm / n, sumOne / n + 1.0) << c.name;
  }
}

// Resampling damping (phlm.cpp "Forgetting"; 0 against 0.3, the default's
// neighbour): the test chart panned by whole pixels gives the same bits with
// and without it (the model fetch reads whole models and does not blur);
// panned by half a pixel, where each fetch interpolates between models, the
// damped models keep the chart's thin lines sharper.
TEST(Phlm, ResampleDampingActsOnlyAtSubPixelMotion) {
  const int frames = 24, warmUp = 8;
  const test::DampingFigures d = test::resampleDampingFigures("phlm", 48, 32, frames, warmUp);
  EXPECT_TRUE(d.wholePixelSame) << "the whole-pixel pan differs with the damping";
  std::printf("chart panned by (0.5, 0.5) px per frame: phlm mean PSNR frames %d-%d %.2f dB without, %.2f dB with "
              "resampleDamping 0.3\n", warmUp, frames - 1, d.off, d.on);
  EXPECT_GT(d.on, d.off + 0.2);
  // Panned in y only: the damping acts the same (the larger axis fraction).
  std::printf("chart panned by (0, 0.5) px per frame: phlm mean PSNR %.2f dB without, %.2f dB with the damping\n",
              d.verticalOff, d.verticalOn);
  EXPECT_GT(d.verticalOn, d.verticalOff + 0.2);
}

// Model fetch (phlm.cpp "Model fetch"): on the test chart panned by whole
// pixels the Catmull-Rom intercepts read the nearest model exactly, as the
// bilinear fetch does (the same bits); panned by sub-pixel steps, where each
// bilinear fetch averages four models, they keep the chart sharper.
TEST(Phlm, CatmullRomInterceptsKeepASubPixelPanSharper) {
  const int w = 48, h = 32, frames = 24, warmUp = 8;
  auto run = [&](const std::vector<synth::FrameData>& input, const char* fetch, std::vector<Image>* outputs) {
    return test::meanPsnrAfterWarmUp("phlm", input, warmUp, outputs,
                                     [&](ParamSet& p) { p.setString("modelFetch", fetch); });
  };
  std::vector<Image> bilinear, catmullRom;
  const std::vector<synth::FrameData> whole = test::pannedChart(w, h, frames, 1.0f, -1.0f);
  run(whole, "bilinear", &bilinear);
  run(whole, "catmull-rom", &catmullRom);
  for (int t = 0; t < frames; ++t)
    EXPECT_TRUE(bilinear[std::size_t(t)].data == catmullRom[std::size_t(t)].data) << "whole-pixel pan, frame " << t;
  for (const auto& [vx, vy] : {std::pair{0.5f, 0.5f}, std::pair{0.3f, -0.7f}}) {
    const std::vector<synth::FrameData> pan = test::pannedChart(w, h, frames, vx, vy);
    const double off = run(pan, "bilinear", nullptr), on = run(pan, "catmull-rom", nullptr);
    std::printf("chart panned by (%.1f, %.1f) px per frame: phlm mean PSNR frames %d-%d %.2f dB bilinear, %.2f dB "
                "Catmull-Rom intercepts\n", vx, vy, warmUp, frames - 1, off, on);
    EXPECT_GT(on, off + 0.2) << vx << ", " << vy;
  }
}

// Hold (phlm.cpp "Hold"): on the still chart under the 16-point jitter, a
// model that has seen a whole period (16 samples: frames 0-15) stops
// learning, so from frame 16 on most of the output no longer changes, with and
// without a (zero) motion image. What still changes are edge pixels whose
// box, in some jitter phases, excludes the held prediction: each correction
// restarts the model (measured: 4-7 % of the values per frame, against 47 %
// without the hold). The held output is as close to the reference as the
// learning one (within 0.1 dB).
TEST(Phlm, HoldStopsAStillOutputChanging) {
  const int w = 48, h = 40, frames = 40;
  const synth::Sequence seq = synth::staticChartSequence(w, h);
  for (bool withMotion : {false, true}) {
    Driver held("phlm"), learning("phlm");
    learning.filter->params().setInt("holdPeriod", 0);
    Image previousHeld, previousLearning;
    double heldPsnr = 0, learningPsnr = 0;
    long heldChanges = 0, learningChanges = 0, values = 0;
    for (int t = 0; t < frames; ++t) {
      const synth::FrameData f = synth::renderFrame(seq, w, h, t, {});
      const Image a = held.run(f, withMotion, withMotion);
      const Image b = learning.run(f, withMotion, withMotion);
      if (t >= 17) {
        for (std::size_t i = 0; i < a.data.size(); ++i) {
          heldChanges += a.data[i] != previousHeld.data[i];
          learningChanges += b.data[i] != previousLearning.data[i];
        }
        values += long(a.data.size());
      }
      if (t == frames - 1) heldPsnr = psnr(f.reference, a), learningPsnr = psnr(f.reference, b);
      previousHeld = a;
      previousLearning = b;
    }
    std::printf("still chart (%s), frames 17-%d: values changed per frame %.1f %% held, %.1f %% with holdPeriod 0; "
                "frame %d: %.2f / %.2f dB\n",
                withMotion ? "zero motion image" : "no motion image", frames - 1, 100.0 * heldChanges / values,
                100.0 * learningChanges / values, frames - 1, heldPsnr, learningPsnr);
    EXPECT_LT(heldChanges, learningChanges / 5);
    EXPECT_GT(heldPsnr, learningPsnr - 0.1);
  }
}

// Camera cut with zero motion afterwards: the frame after the cut is not
// worse than the 1-sample frame (box correction resets the models).
TEST(Phlm, CameraCutLeavesNoGhost) {
  const int w = 48, h = 40, cut = 20;
  const synth::Sequence seq = synth::cameraCutSequence(w, h, cut);
  Driver d("phlm");
  for (int t = 0; t <= cut + 2; ++t) {
    const synth::FrameData f = synth::renderFrame(seq, w, h, t, {});
    const Image& out = d.run(f, true, true);
    if (t >= cut) {
      const double p = psnr(f.reference, out), one = psnr(f.reference, f.color);
      std::printf("camera cut, frame %d: phlm %.2f dB, 1-sample %.2f dB\n", t, p, one);
      EXPECT_GT(p, one - 0.5);
    }
  }
}

// A synthetic frame's colour, motion and depth as phlm's inputs.
static phlm::Inputs movingInputs(const synth::FrameData& f) {
  phlm::Inputs in;
  in.color = f.color.view();
  in.motion = f.motion.view();
  in.depth = f.depth.view();
  return in;
}

// One frame on the threaded fast path (2 threads) and on the reference path:
// equal outputs and records, and with motion equal intercept planes.
static ::testing::AssertionResult runBothPaths(phlm::Kernel<float>& fast, phlm::Kernel<float>& reference, phlm::Inputs in,
                                               const phlm::Settings& s, Image& outFast, Image& outReference) {
  in.output = outFast.view();
  fast.run(in, s, false, 2);
  in.output = outReference.view();
  reference.run(in, s, true, 1);
  if (std::memcmp(outFast.data.data(), outReference.data.data(), outFast.data.size() * sizeof(float)) != 0)
    return ::testing::AssertionFailure() << "outputs differ";
  const phlm::FrameStats &a = fast.lastStats(), &b = reference.lastStats();
  if (a.reprojectionResets != b.reprojectionResets || a.boxResets != b.boxResets || a.guards != b.guards)
    return ::testing::AssertionFailure() << "counts differ: reprojection " << a.reprojectionResets << " / "
                                         << b.reprojectionResets << ", box " << a.boxResets << " / " << b.boxResets
                                         << ", guards " << a.guards << " / " << b.guards;
  for (int y = 0; y < fast.height(); ++y)
    for (int x = 0; x < fast.width(); ++x) {
      const std::array<float, phlm::kRecord> a = fast.record(x, y), b = reference.record(x, y);
      if (std::memcmp(a.data(), b.data(), sizeof a) != 0)
        return ::testing::AssertionFailure() << "records differ at (" << x << "," << y << ")";
      if (!in.motion.ptr) continue;
      const std::array<float, 3> pa = fast.planarIntercepts(x, y), pb = reference.planarIntercepts(x, y);
      if (std::memcmp(pa.data(), pb.data(), sizeof pa) != 0)
        return ::testing::AssertionFailure() << "intercept planes differ at (" << x << "," << y << ")";
    }
  return ::testing::AssertionSuccess();
}

// The threaded fast path (2 threads, unclamped interior taps) and the scalar
// reference give bit-identical outputs and states, float32. The width is not a
// multiple of the 8-pixel batch of the RLS step (phlm.cpp finishBatch), and
// the moving sphere over the still background puts moving and still pixels
// in one batch.
TEST(Phlm, ReferencePathEqualsFastPath) {
  const int w = 61, h = 48, frames = 12;
  const synth::Sequence ghosting = synth::ghostingSequence(w, h, 9.0f, 1.3f, 0.4f);
  // The test chart panned by a sub-pixel step: whole batches of moving lanes
  // whose Catmull-Rom footprints are consecutive and interior (loaded from the
  // intercept planes as vectors; the reference gathers from the records).
  const std::vector<synth::FrameData> pan = test::pannedChart(w, h, frames, 0.37f, -0.21f);
  // The pan with uneven motion: the models of consecutive moving pixels are
  // not consecutive, and some lanes reproject off screen, so the AVX2 copy's
  // moving groups test depth lane by lane (phlm.cpp phlmMovingGroup).
  std::vector<synth::FrameData> uneven = test::pannedChart(w, h, frames, 0.37f, -0.21f);
  for (synth::FrameData& f : uneven)
    for (int y = 0; y < h; ++y)
      for (int x = 0; x < w; ++x) {
        float* m = f.motion.at(x, y);
        m[0] = x % 11 == 5 ? 70.0f : 0.37f + 0.5f * float((x + 2 * y) % 4);
      }
  // A still camera over the chart, three of its shapes moving: still lane
  // groups (phlmStillGroup) beside moving shapes, on a textured background
  // whose footprint box is not the 3x3 box.
  const std::vector<synth::FrameData> object = test::pannedChart(w, h, frames, 0.37f, -0.21f, {}, 3);
  constexpr int kModes = 6;
  for (int run = 0; run < 3 * kModes; ++run) {
    // 0: ghosting, motion + depth; 1: static (in place); 2: the pan; 3: the pan
    // with frames 4-5 given no motion (the planes go stale and are copied at
    // frame 6) and frame 8 fetched bilinearly (the planes are written anyway);
    // 4: the uneven pan; 5: the still camera over the chart.
    const int mode = run % kModes;
    const test::FastPathIsa isa(test::kFastPathIsas[run / kModes]);
    phlm::Kernel<float> fast, reference;
    fast.allocate(w, h, mode != 1, mode != 1);
    reference.allocate(w, h, mode != 1, mode != 1);
    Image outFast(w, h, 4), outReference(w, h, 4);
    phlm::Settings s;
    s.holdPeriod = 4;  // held and learning lanes in one batch (phlm.cpp "Hold")
    for (int t = 0; t < frames; ++t) {
      const synth::FrameData f = mode == 5   ? object[std::size_t(t)]
                                 : mode == 4 ? uneven[std::size_t(t)]
                                 : mode >= 2 ? pan[std::size_t(t)]
                                             : synth::renderFrame(ghosting, w, h, t, {});
      // Jitter offsets whose unjitter shifts the taps by a whole pixel on
      // some frames (temporal::unjitterFor: shift = round(jitter)), so the
      // shifted, clamped taps are compared too.
      const float jitter[4][2] = {{0.2f, -0.3f}, {0.7f, 0.1f}, {-0.4f, -0.8f}, {-0.6f, 0.55f}};
      s.jitterX = jitter[t % 4][0];
      s.jitterY = jitter[t % 4][1];
      s.modelFetch = mode == 3 && t == 8 ? phlm::ModelFetch::Bilinear : phlm::ModelFetch::CatmullRom;
      phlm::Inputs in;
      in.color = f.color.view();
      if (mode != 1 && !(mode == 3 && (t == 4 || t == 5))) {
        in.motion = f.motion.view();
        in.depth = f.depth.view();
      }
      ASSERT_TRUE(runBothPaths(fast, reference, in, s, outFast, outReference))
          << "frame " << t << " mode " << mode << " " << temporal::fastPathIsaName();
    }
  }
}

// The still count saturates at 255 (phlm.cpp "Hold") on both paths: a
// still scene filtered for 260 frames with the hold off, then with it on,
// whose models are held at once (a count that wrapped would start again).
TEST(Phlm, StillCountSaturatesOnBothPaths) {
  const int w = 29, h = 12;
  const synth::Sequence still = synth::staticChartSequence(w, h);
  phlm::Kernel<float> fast, reference;
  fast.allocate(w, h, false, false);
  reference.allocate(w, h, false, false);
  Image outFast(w, h, 4), outReference(w, h, 4);
  const synth::FrameData f = synth::renderFrame(still, w, h, 0, {});
  phlm::Inputs in;
  in.color = f.color.view();
  phlm::Settings s;
  s.holdPeriod = 0;
  for (int t = 0; t < 262; ++t) {
    if (t == 260) s.holdPeriod = 16;
    ASSERT_TRUE(runBothPaths(fast, reference, in, s, outFast, outReference)) << "frame " << t;
  }
  // Held: the last frame changed nothing.
  const std::array<float, phlm::kRecord> before = fast.record(w / 2, h / 2);
  ASSERT_TRUE(runBothPaths(fast, reference, in, s, outFast, outReference));
  EXPECT_EQ(0, std::memcmp(before.data(), fast.record(w / 2, h / 2).data(), sizeof before));
}

// The output's alpha is the input's, sanitised, on both paths: rows whose
// alphas are all 1 skip reading it again (phlm.cpp finishBatch), the others
// read it pixel by pixel, in moving groups and on the border alike.
TEST(Phlm, OutputAlphaIsTheInputAlpha) {
  const int w = 61, h = 24, frames = 3;
  std::vector<synth::FrameData> pan = test::pannedChart(w, h, frames, 0.37f, -0.21f);
  ASSERT_EQ(pan[0].color.channels, 4);
  for (synth::FrameData& f : pan) {
    f.color.at(20, 5)[3] = 0.5f;                                      // inside a moving group
    f.color.at(58, 6)[3] = 0.5f;  // in the row's last, partial lane group (staging's tail)
    f.color.at(0, 9)[3] = std::numeric_limits<float>::quiet_NaN();  // border pixel: 0
    f.color.at(40, 9)[3] = 1e30f;                                     // kMaxColor
    f.color.at(7, h - 1)[3] = -2.0f;                                  // last row
  }
  for (const bool reference : {false, true}) {
    phlm::Kernel<float> k;
    k.allocate(w, h, true, true);
    Image out(w, h, 4);
    for (int t = 0; t < frames; ++t) {
      const synth::FrameData& f = pan[std::size_t(t)];
      phlm::Inputs in = movingInputs(f);
      in.output = out.view();
      k.run(in, phlm::Settings{}, reference, 2);
      for (int y = 0; y < h; ++y)
        for (int x = 0; x < w; ++x)
          ASSERT_EQ(out.at(x, y)[3], sanitizeColor(f.color.at(x, y)[3]))
              << "(" << x << "," << y << ") frame " << t << (reference ? " reference" : " fast");
    }
  }
}

// The model reset by a box correction (Algorithm 1 line 18) starts from
// P = scale P0, scale = boxResetCovariance / initialCovariance, not from P0:
// a flat grey frame, then a flat brighter one, whose prediction leaves the
// (single-valued) box at every pixel. With boxResetCovariance c = 0.01 (slope
// variances 1 * 1e-5), the still frame forgets (P / lambda, c' = c / lambda)
// and takes in one sample x = [1, z] of weight 1; the slopes' variances are
// too small to matter, so the intercept variance is c' / (1 + c') ~ 0.00992
// and the slopes' ps scale / lambda ~ 1.002e-5 (from P0 they would be ~ 1.1
// and ~ 1). At the default (c = initialCovariance) the intercept stays ~ 1.
TEST(Phlm, BoxCorrectionResetsToBoxResetCovariance) {
  const int w = 16, h = 8;
  for (const double boxCovariance : {0.01, 1000.0}) {
    for (const bool reference : {false, true}) {
      phlm::Kernel<float> k;
      k.allocate(w, h, false, false);
      phlm::Settings s;
      s.holdPeriod = 0;
      s.boxResetCovariance = boxCovariance;
      Image out(w, h, 4);
      for (int t = 0; t < 2; ++t) {
        const Image in(w, h, 4, t == 0 ? 0.2f : 0.8f);
        phlm::Inputs inputs;
        inputs.color = in.view();
        inputs.output = out.view();
        k.run(inputs, s, reference, 1);
      }
      EXPECT_EQ(k.lastStats().boxResets, long(w * h));
      double P[phlm::kDims][phlm::kDims];
      phlm::covariance(k.record(w / 2, h / 2).data(), P);
      const double scale = boxCovariance / s.initialCovariance, forgotten = boxCovariance / s.lambda;
      if (boxCovariance < 1.0) {
        EXPECT_NEAR(P[0][0], forgotten / (1.0 + forgotten), 1e-3 * forgotten) << "reference " << reference;
        EXPECT_NEAR(P[1][1], s.slopeCovariance * scale / s.lambda, 1e-2 * s.slopeCovariance * scale)
            << "reference " << reference;
      } else {
        EXPECT_GT(P[0][0], 0.5) << "reference " << reference;
      }
    }
  }
}

// A frame large enough that the fast path writes its next records and
// intercept planes with streaming stores (phlm.cpp kStreamBytes: here 21 MB)
// gives the same outputs, records and planes as the reference path, whose
// stores are plain ones.
TEST(Phlm, StreamedRecordsEqualTheReference) {
  const int w = 581, h = 320, frames = 3;  // 73 blocks a row: the last one padded
  synth::FrameOptions options;
  options.referenceSamples = 1;  // the references are not read here
  const std::vector<synth::FrameData> pan = test::pannedChart(w, h, frames, 0.37f, -0.21f, options);
  phlm::Kernel<float> fast, reference;
  fast.allocate(w, h, true, true);
  reference.allocate(w, h, true, true);
  Image outFast(w, h, 4), outReference(w, h, 4);
  phlm::Settings s;
  for (int t = 0; t < frames; ++t) {
    const synth::FrameData& f = pan[std::size_t(t)];
    ASSERT_TRUE(runBothPaths(fast, reference, movingInputs(f), s, outFast, outReference)) << "frame " << t;
  }
}

// The intercept planes beside the records (phlm.cpp "Model fetch") hold the
// records' intercepts after every frame with motion (written with the
// records), and the first moving frame after still ones (the state
// re-allocated with motion) reads them copied from the records.
TEST(Phlm, InterceptPlanesFollowTheRecords) {
  const int w = 37, h = 21, frames = 12;
  const std::vector<synth::FrameData> pan = test::pannedChart(w, h, frames, 0.4f, -0.3f);
  phlm::Kernel<float> k;
  k.allocate(w, h, false, false);
  Image out(w, h, 4);
  phlm::Settings s;
  for (int t = 0; t < frames; ++t) {
    const bool moving = t >= 3;
    if (t == 3) k.allocate(w, h, true, true);
    if (t == 8) k.reset();
    phlm::Inputs in;
    in.color = pan[std::size_t(t)].color.view();
    if (moving) {
      in.motion = pan[std::size_t(t)].motion.view();
      in.depth = pan[std::size_t(t)].depth.view();
    }
    in.output = out.view();
    s.jitterX = pan[std::size_t(t)].jitter.x;
    s.jitterY = pan[std::size_t(t)].jitter.y;
    k.run(in, s, false, 2);
    // The first moving frame read planes copied from the records: had it read
    // stale planes (zeros), every prediction would leave its box (measured:
    // 777 of 777 pixels, against 140 with the copy and 144 a frame later).
    if (t == 3) {
      EXPECT_LT(k.lastStats().boxResets, w * h / 2);
    }
    if (!moving) continue;
    for (int y = 0; y < h; ++y)
      for (int x = 0; x < w; ++x) {
        const std::array<float, phlm::kRecord> r = k.record(x, y);
        const std::array<float, 3> p = k.planarIntercepts(x, y);
        for (int c = 0; c < 3; ++c)
          ASSERT_EQ(r[std::size_t(phlm::kBeta + c)], p[std::size_t(c)])
              << "frame " << t << " (" << x << "," << y << ")";
      }
  }
}

// Memory kept between frames: one 100-byte record, the hold's byte and its
// 4-byte windows per pixel when static; with motion two records, their intercepts as planes
// (2 x 12 bytes, phlm.cpp "Model fetch") and the narrow-box byte more; plus
// two depth planes with depth; nothing allocated by run().
// Record and intercept rows are padded to whole blocks of 8 pixels (phlm.h recordIndex).
TEST(Phlm, MemoryKeptBetweenFrames) {
  phlm::Kernel<float> k;
  k.allocate(96, 10, false, false);
  EXPECT_EQ(k.bytesKeptBetweenFrames(), 960u * (100u + 1u + 4u));
  k.allocate(96, 10, true, true);
  EXPECT_EQ(k.bytesKeptBetweenFrames(), 960u * (200u + 24u + 1u + 1u + 4u + 8u));
  k.allocate(100, 10, true, true);  // 100 = 12.5 blocks: records of 104 pixels per row, depth of 100
  EXPECT_EQ(k.bytesKeptBetweenFrames(), 1040u * (200u + 24u) + 1000u * (1u + 1u + 4u + 8u));
  k.allocate(100, 10, false, false);  // motion dropped: its buffers freed
  EXPECT_EQ(k.bytesKeptBetweenFrames(), 1040u * 100u + 1000u * (1u + 4u));
  std::printf("phlm float32 state: %zu bytes/pixel static, %zu with motion and depth\n", std::size_t(105),
              std::size_t(238));
}

// The filter: registered, parameter table documented, bad input named,
// re-commit for a new jitter keeps the state, reset forgets it.
TEST(Phlm, FilterInterface) {
  Context context;
  auto filter = createFilter(context, "phlm");
  const std::string doc = filter->doc();
  for (const char* name : {"lambda", "initialCovariance", "slopeCovariance", "featureA", "featureB",
                           "featureAlphaMin", "jitterX", "jitterY", "reference"})
    EXPECT_NE(doc.find(name), std::string::npos) << name;
  EXPECT_THROW(filter->params().setFloat("lambda", 1.5f), Exception);
  EXPECT_THROW(filter->commit(), Exception);  // no colour

  const int w = 16, h = 12;
  const synth::Sequence seq = synth::staticChartSequence(w, h);
  Driver kept("phlm"), fresh("phlm");
  Image last;
  for (int t = 0; t < 6; ++t) last = kept.run(synth::renderFrame(seq, w, h, t, {}), false, false);
  const synth::FrameData f6 = synth::renderFrame(seq, w, h, 6, {});
  const Image a = kept.run(f6, false, false);
  const Image b = fresh.run(f6, false, false);
  EXPECT_NE(0, std::memcmp(a.data.data(), b.data.data(), a.data.size() * sizeof(float)));  // history used
  kept.filter->reset();
  const Image c = kept.run(f6, false, false);
  EXPECT_EQ(0, std::memcmp(c.data.data(), b.data.data(), c.data.size() * sizeof(float)));  // forgotten
}

// A shadow sweeping over a still chart and back, with the motion image given
// and zero everywhere (a shadow has no motion, like the one on the wall of the
// bundled ghosting scene). Next to the shadow's edge the footprint box spans
// lit and shadowed colours, so it would accept a lit model for the first
// frames in the shadow (a trail of lag along the leading edge). Models the
// first pass box-corrected keep the 3x3 box (phlm.cpp "Box"), so on the way
// back phlm must follow the shadow as well as with the paper's 3x3 box
// everywhere (footprintBox = false); the never-shadowed run is printed
// beside it.
TEST(Phlm, ReturningShadowLeavesNoLag) {
  const int w = 64, h = 48, shadowWidth = 20, speed = 4, first = 24;
  const int across = (w + shadowWidth) / speed;  // frames of one pass
  const auto shadowStart = [&](int t) {  // left end of the shadow in frame t (pass 1 right, pass 2 left)
    const int k = t - first;
    return k <= across ? -shadowWidth + k * speed : w - (k - across) * speed;
  };
  const synth::Sequence seq = synth::staticChartSequence(w, h);
  const auto shade = [&](Image& img, int t) {
    if (t < first || t > first + 2 * across) return;
    const int x0 = shadowStart(t);
    for (int y = 0; y < h; ++y)
      for (int x = std::max(x0, 0); x < std::min(x0 + shadowWidth, w); ++x)
        for (int c = 0; c < 3; ++c) img.at(x, y)[c] *= 0.1f;
  };
  Driver shadowed("phlm"), paperBox("phlm"), unshadowed("phlm");
  paperBox.filter->params().setBool("footprintBox", false);
  double sumShadowed = 0, sumPaper = 0, sumUnshadowed = 0;
  const int back0 = first + across + 2, back1 = first + 2 * across - 2;  // the shadow on the image, pass 2
  for (int t = 0; t <= back1; ++t) {
    synth::FrameData f = synth::renderFrame(seq, w, h, t, {});
    const double u = psnr(f.reference, unshadowed.run(f, true, true));
    shade(f.color, t);
    shade(f.reference, t);
    const double s = psnr(f.reference, shadowed.run(f, true, true));
    const double p = psnr(f.reference, paperBox.run(f, true, true));
    if (t < back0) continue;
    sumShadowed += s, sumPaper += p, sumUnshadowed += u;
  }
  const int n = back1 - back0 + 1;
  std::printf("a shadow's way back, frames %d-%d: phlm %.2f dB, with the 3x3 box everywhere %.2f dB, never "
              "shadowed %.2f dB\n",
              back0, back1, sumShadowed / n, sumPaper / n, sumUnshadowed / n);
  EXPECT_GT(sumShadowed / n, sumPaper / n - 0.5);
}

// PHLM's row staging (phlm_stage.h) against the formulas, in both copies:
// the kernel's two paths read the same staged rows, so comparing them cannot
// catch a wrong formula here. Width 21: two whole Vec8 groups (five Vec4)
// and a partial tail in each copy.
TEST(PhlmStage, StagesSanitisedColourTonemappedLuminanceAlphaDepthAndMotion) {
  constexpr int w = 21, h = 4;
  const float inf = std::numeric_limits<float>::infinity(), nan = std::numeric_limits<float>::quiet_NaN();
  std::mt19937 rng(7);
  std::uniform_real_distribution<float> value(-0.5f, 4.0f);
  Image color(w, h, 4), depth(w, h, 1), motion(w, h, 2);
  for (int y = 0; y < h; ++y)
    for (int x = 0; x < w; ++x) {
      float* c = color.at(x, y);
      for (int k = 0; k < 3; ++k) c[k] = value(rng);
      c[3] = 1.0f;
      depth.at(x, y)[0] = value(rng) + 1.0f;
      motion.at(x, y)[0] = (x + y) % 3 == 0 ? 0.25f : 0.0f;
      motion.at(x, y)[1] = (x * y) % 5 == 1 ? -0.5f : 0.0f;
    }
  // Extremes: HDR, non-finite colour, far and non-finite depth, NaN and -0 motion.
  color.at(3, 0)[1] = 1e6f;
  color.at(9, 0)[0] = nan;
  color.at(17, 0)[2] = inf;
  color.at(20, 0)[0] = -inf;
  depth.at(4, 0)[0] = inf;
  depth.at(5, 0)[0] = nan;
  depth.at(19, 0)[0] = 1e9f;
  motion.at(6, 0)[0] = nan;
  motion.at(7, 0)[1] = -0.0f;
  // Alpha: row 0 all 1; row 1 not 1 in the tail only; row 2 not 1 in the first group; row 3 NaN (read as 0).
  color.at(20, 1)[3] = 0.5f;
  color.at(2, 2)[3] = 0.0f;
  color.at(11, 3)[3] = nan;

  using Stage = void (*)(const phlm::StagedRow&, int);
  std::vector<std::pair<const char*, Stage>> copies = {{"baseline", phlm::stageRowBaseline}};
#ifdef CRISP_TEMPORAL_HAS_AVX2
  if (temporal::cpuHasAvx2()) copies.push_back({"avx2", phlm::stageRowAvx2});
#endif
  for (const auto& [name, stage] : copies) {
    SCOPED_TRACE(name);
    std::vector<float> staged(std::size_t(w) * h * 4, -1.0f), depthOut(std::size_t(w) * h, -1.0f);
    std::vector<std::uint8_t> alphaOne(h, 7), moving(std::size_t(w) * h, 7);
    phlm::StagedRow row;
    row.color = color.view();
    row.depth = depth.view();
    row.motion = motion.view();
    row.staged = staged.data();
    row.alphaOne = alphaOne.data();
    row.depthOut = depthOut.data();
    row.movingFlags = moving.data();
    for (int y = 0; y < h; ++y) stage(row, y);
    for (int y = 0; y < h; ++y) {
      EXPECT_EQ(alphaOne[y], y == 0 ? 1 : 0) << "row " << y;
      for (int x = 0; x < w; ++x) {
        const std::size_t i = std::size_t(y) * w + x;
        const float* in = color.at(x, y);
        const float* out = &staged[i * 4];
        double rgb[3];
        for (int k = 0; k < 3; ++k) {
          // NaN -> 0, +-Inf -> +-kMaxColor (conventions.h), otherwise as given.
          const float expected = std::isnan(in[k]) ? 0.0f : std::clamp(in[k], -kMaxColor, kMaxColor);
          EXPECT_EQ(out[k], expected) << x << "," << y << " channel " << k;
          rgb[k] = std::max(double(expected), 0.0);
        }
        // Y / (1 + Y), Y the YCgCo luminance (R + 2G + B) / 4 of the colour clamped to >= 0 (§5.1).
        const double luma = (rgb[0] + 2.0 * rgb[1] + rgb[2]) / 4.0, expected = luma / (1.0 + luma);
        EXPECT_NEAR(out[3], expected, 4e-7 * std::max(expected, 1e-3)) << x << "," << y;
        const float d = depth.at(x, y)[0];
        EXPECT_EQ(depthOut[i], d < kFarDepth ? d : kBackgroundDepth) << x << "," << y;
        const float* m = motion.at(x, y);
        EXPECT_EQ(moving[i], (m[0] != 0.0f || m[1] != 0.0f) ? 1 : 0) << x << "," << y;
      }
    }
  }
  // Without alpha (RGB input) every row's alpha counts as 1.
  Image rgb(w, 1, 3, 0.5f);
  std::vector<float> staged(std::size_t(w) * 4);
  std::uint8_t one = 7;
  phlm::StagedRow row;
  row.color = rgb.view();
  row.staged = staged.data();
  row.alphaOne = &one;
  row.depthOut = nullptr;
  row.movingFlags = nullptr;
  phlm::stageRowBaseline(row, 0);
  EXPECT_EQ(one, 1);
  EXPECT_NEAR(staged[3], 0.5 / 1.5, 1e-7);
}

// Taa.StillSilhouettesUnderJitterAreNotReset for phlm: a still scene with depth
// and a zero motion image resets next to no model after the first frame, where
// a silhouette pixel's jittered depth sample flips between the two surfaces
// (phlm.cpp stillSurfaceNear), on the fast path and the reference.
TEST(Phlm, StillSilhouettesUnderJitterAreNotReset) {
  const int w = 48, h = 32, frames = 48;
  const std::vector<synth::FrameData> input = test::stillChartUnderEeveeJitter(w, h, frames);
  for (const bool reference : {false, true}) {
    phlm::Kernel<float> k;
    k.allocate(w, h, true, true);
    phlm::Settings s;
    Image out(w, h, 4);
    long resets = 0;
    for (int t = 0; t < frames; ++t) {
      const synth::FrameData& f = input[std::size_t(t)];
      phlm::Inputs in = movingInputs(f);  // the motion image is all zero: nothing moves
      in.output = out.view();
      s.jitterX = f.jitter.x, s.jitterY = f.jitter.y;
      k.run(in, s, reference, 2);
      if (t > 0) resets += k.lastStats().reprojectionResets;
    }
    std::printf("phlm still chart, EEVEE jitter, zero motion image%s: %ld model resets after the first frame\n",
                reference ? " (reference)" : "", resets);
    EXPECT_LE(resets, 16) << (reference ? "reference" : "fast");
  }
}
