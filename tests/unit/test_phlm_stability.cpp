// SPDX-License-Identifier: Apache-2.0
// Numerical stability of PHLM (native/filters/phlm*.h, METHODS.md "PHLM":
// "numerical stability is a requirement"). 20 000-frame runs of the scenarios
// of stability_scenarios.h (35x8, EEVEE's jitter) of the float32 kernel (the
// product: its fast path, 8-lane groups, two threads) next to the same
// kernel's reference path (identical outputs every frame) and the float64
// kernel on the same input, with the default hold and
// with holdPeriod 0 (every still model keeps updating, so the RLS
// regularisation is what bounds P). At EVERY frame and pixel, for both:
//  * no safety net fired (FrameStats::guards: a non-finite prediction, an
//    overflowed beta, an output that needed its sanitise), so the outputs'
//    finiteness is the kernel's, not the sanitise's;
//  * the output is inside the colour range of the pixel's (unjittered) 3x3,
//    or its 5x5 where the documented exception applies (stability::outputRange);
//  * the model record is finite; P = U D U' is symmetric by construction and
//    positive definite iff every D > 0 (asserted), with
//    trace P <= (p0 + 3 ps) / lambda^3 (the bound of phlm_rls.h); P rebuilt
//    in double also passes a Cholesky factorisation (its conditioning), and
//    P stays above a floor set by lambda (checkState), which skipped
//    forgetting breaks;
//  * where nothing moved since the previous frame (stability::StillFrames),
//    no model was reset for its reprojection (FrameStats::reprojectionResets,
//    border pixels included; the same count on both paths and in float64),
//    and models were reset on the scenarios that need it
//    (stability::startsOver);
//  * releases from the hold (phlm.cpp "Hold") are the same on both float
//    paths, and none on the periodic scenarios (stability::periodic);
//  * float32 and float64 outputs agree within kTolerance times the local box
//    extent (+ rounding slack), over the whole run.
#include <gtest/gtest.h>

#include <array>
#include <memory>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <string>

#include "filters/phlm.h"
#include "stability_scenarios.h"

using namespace crisp;
using namespace crisp::test::stability;

namespace {

constexpr int kW = kWidth, kH = kHeight;
// float32 vs float64: |out32 - out64| <= kTolerance * (box extent) + slack.
constexpr double kTolerance = 1e-4;

// What checkState saw of one kernel over a run.
struct StateSeen {
  double maxTrace = 0.0;
  double maxFeature = 1.0;  // the largest |x|^2 = 1 + |z|^2 of a record so far (phlm_rls.h: x = [1, z])
  double floor = 0.0;       // the last floor of P asserted (checkState)
};

// One settings variant of a run: its two kernels and what they showed.
struct Variant {
  const char* label;
  phlm::Settings settings;
  bool checkAgreement = true;
  phlm::Kernel<float> k32, k32reference;
  phlm::Kernel<double> k64;
  Image out32{kW, kH, 4}, out32reference{kW, kH, 4}, out64{kW, kH, 4};
  double worstRelativeDiff = 0.0;  // float vs double, relative to box extent
  StateSeen seen32, seen64;
  long boxResets32 = 0, boxResets64 = 0, reprojectionResets = 0;  // after the first frame
  long releases = 0, releases64 = 0;  // from the hold (FrameStats::releases), float and double
};

// The smallest pivot of the Cholesky factorisation of P - floor I (P: 4x4,
// symmetric), or the first one <= 0: positive iff P - floor I is positive
// definite, i.e. every eigenvalue of P exceeds floor.
inline double smallestPivot(const double P[4][4], double floor) {
  double L[4][4] = {}, smallest = INFINITY;
  for (int i = 0; i < 4; ++i)
    for (int j = 0; j <= i; ++j) {
      double sum = P[i][j] - (i == j ? floor : 0.0);
      for (int k = 0; k < j; ++k) sum -= L[i][k] * L[j][k];
      if (i != j) {
        L[i][j] = sum / L[j][j];
        continue;
      }
      if (!(sum > 0.0)) return sum;
      smallest = std::min(smallest, sum);
      L[i][i] = std::sqrt(sum);
    }
  return smallest;
}

// The record of every pixel: finite, D > 0 (P = U D U' positive definite),
// trace P within the bound; every 8th frame also P rebuilt in double and
// factorised by Cholesky (its conditioning), and P above its floor.
//
// The floor (against skipped forgetting, which lets P shrink toward 0 and
// the models stop adapting, inside every other bound). In information form
// R = P^-1 (phlm_rls.h), a still frame makes R' = lambda R + r e_k e_k' +
// w x x' (forgetting, this frame's regulariser axis k with r = 4 (1 -
// lambda) / P0_kk, the sample of weight w = 1 without jitter weighting), so
// the largest eigenvalue obeys Rmax' <= lambda Rmax + 4 (1 - lambda) / P0min
// + w |x|^2; a moving frame forgets with lm <= lambda and refreshes every
// axis with (1 - lm) / P0_kk: Rmax' <= lm Rmax + (1 - lm) / P0min + w |x|^2.
// A reset gives Rmax = 1 / P0min, a box correction 1 / (scale P0min) (scale
// = boxResetCovariance / p0); a held model keeps its R, a moved one brings
// another pixel's. So with X the largest |x|^2 used so far (|z| < 4: X < 17),
//   Rmax <= B = w X / (1 - lambda) + max(4, 1 / scale) / P0min
// at every frame (each step above keeps it, for lm <= lambda), i.e.
// P >= I / B: every eigenvalue of P at least 1 / B (asserted as P - I / B
// positive definite, with 1e-3 of slack for rounding). A
// model that learns from a steady x converges to Rmax ~ |x|^2 / (1 - lambda) +
// 1 / P0min, just under B; without the forgetting R grows by |x|^2 a frame
// and passes B within ~B / |x|^2 frames (about 500 at the defaults). The
// records' z are the x of their last update, so X is taken over every
// record of every frame (first, then the check). Measured: with holdPeriod 0
// the smallest eigenvalue of P comes within 0.6 % of the floor on the
// constant colour and the camera cut (0.4 % in the 3000-frame runs with
// slopeCovariance 1000, not quite converged), so the floor is not vacuous.
template <class T, class Name>
void checkState(const phlm::Kernel<T>& k, const phlm::Settings& s, int t, const Name& name, StateSeen& seen) {
  ASSERT_EQ(s.weighting, phlm::JitterWeighting::None) << "the floor of P below takes w = 1";
  // Regularised forgetting bounds P by P0 / (lambda^3 c), c for moving frames
  // forgetting with lambdaMoving (phlm.cpp, "Stabilised RLS").
  const double l3 = std::pow(s.lambda, 3), lm = s.lambdaMoving;
  const double cMoving = std::min(1.0, (1.0 - lm) / (1.0 - lm * l3));
  const double bound = (s.initialCovariance + 3.0 * s.slopeCovariance) / (l3 * cMoving) * (1.0 + 1e-4);
  ASSERT_LE(lm, s.lambda) << "the floor of P below takes lambdaMoving <= lambda";
  for (int y = 0; y < kH; ++y)
    for (int x = 0; x < kW; ++x) {
      const std::array<T, phlm::kRecord> record = k.record(x, y);
      double feature = 1.0;
      for (int c = 0; c < 3; ++c) feature += double(record[phlm::kZ + c]) * double(record[phlm::kZ + c]);
      seen.maxFeature = std::max(seen.maxFeature, feature);
    }
  const double p0min = std::min(s.initialCovariance, s.slopeCovariance);
  const double scale = s.boxResetCovariance / s.initialCovariance;
  seen.floor = (1.0 - 1e-3) / (seen.maxFeature / (1.0 - s.lambda) + std::max(4.0, 1.0 / scale) / p0min);
  for (int y = 0; y < kH; ++y)
    for (int x = 0; x < kW; ++x) {
      const std::array<T, phlm::kRecord> record = k.record(x, y);
      const T* m = record.data();
      for (int i = 0; i < phlm::kRecord; ++i)
        ASSERT_TRUE(std::isfinite(double(m[i]))) << name() << " record scalar " << i << ", frame " << t;
      double trace = 0.0;  // P_jj = D_j + sum_{k > j} U_jk^2 D_k
      for (int j = 0; j < phlm::kDims; ++j) {
        const double d = double(m[phlm::kD + j]);
        ASSERT_TRUE(d > 0.0) << name() << " frame " << t << " (" << x << "," << y << "): D[" << j << "] = " << d
                             << ", P not positive definite";
        double column = 1.0;
        for (int i = 0; i < j; ++i) column += double(m[phlm::uIndex(i, j)]) * double(m[phlm::uIndex(i, j)]);
        trace += d * column;
      }
      seen.maxTrace = std::max(seen.maxTrace, trace);
      ASSERT_TRUE(trace <= bound) << name() << " frame " << t << " (" << x << "," << y << "): trace P " << trace
                                  << " > " << bound;
      if (t % 8 != 7) continue;
      double P[4][4];
      phlm::covariance(m, P);
      const double pivot = smallestPivot(P, 0.0);
      ASSERT_TRUE(pivot > 0.0) << name() << " frame " << t << " (" << x << "," << y << "): Cholesky pivot " << pivot;
      const double above = smallestPivot(P, seen.floor);
      ASSERT_TRUE(above > 0.0) << name() << " frame " << t << " (" << x << "," << y
                               << "): P has an eigenvalue below its floor " << seen.floor
                               << " (Cholesky pivot of P - floor I: " << above << ")";
    }
}

// `frames` frames of `sc` through every variant (the same input and ranges).
void runScenario(const Scenario& sc, std::vector<Variant>& variants, int frames = runFrames()) {
  for (Variant& v : variants) {
    v.k32.allocate(kW, kH, sc.motion, sc.depth);
    v.k32reference.allocate(kW, kH, sc.motion, sc.depth);
    v.k64.allocate(kW, kH, sc.motion, sc.depth);
  }
  Input in;
  StillFrames stillFrames;
  for (int t = 0; t < frames; ++t) {
    sc.make(t, in);
    const bool still = stillFrames.next(sc, t, in);
    const temporal::Jitter j = jitterAt(t);
    // The variants differ in neither unjitter nor footprintBox: one set of ranges.
    const phlm::Settings& first = variants.front().settings;
    const temporal::Unjitter u = temporal::unjitterFor(first.unjitter, j.x, j.y, first.filterSize);
    const std::vector<Range> ranges = outputRanges(in.color, sc.motion ? &in.motion : nullptr, u, first.footprintBox);
    for (Variant& v : variants) {
      phlm::Settings s = v.settings;
      s.jitterX = j.x, s.jitterY = j.y;
      EXPECT_TRUE(s.unjitter == first.unjitter && s.filterSize == first.filterSize &&
                  s.footprintBox == first.footprintBox);
      phlm::Inputs a;
      a.color = in.color.view();
      if (sc.motion) a.motion = in.motion.view();
      if (sc.depth) a.depth = in.depth.view();
      a.output = v.out32.view();
      v.k32.run(a, s, false, 2);
      a.output = v.out64.view();
      v.k64.run(a, s, false, 1);
      a.output = v.out32reference.view();
      v.k32reference.run(a, s, true, 1);
      if (std::memcmp(v.out32.data.data(), v.out32reference.data.data(), v.out32.data.size() * sizeof(float)) != 0) {
        ADD_FAILURE() << sc.name << ", " << v.label << " frame " << t << ": float fast path differs from its reference";
        return;
      }
      v.boxResets32 += v.k32.lastStats().boxResets;
      v.boxResets64 += v.k64.lastStats().boxResets;
      const auto name = [&] { return std::string(sc.name) + ", " + v.label; };
      const long resets = v.k32.lastStats().reprojectionResets;
      if (resets != v.k32reference.lastStats().reprojectionResets || resets != v.k64.lastStats().reprojectionResets) {
        ADD_FAILURE() << name() << " frame " << t << ": reprojection resets " << resets << " (float), "
                      << v.k32reference.lastStats().reprojectionResets << " (its reference), "
                      << v.k64.lastStats().reprojectionResets << " (double)";
        return;
      }
      if (still && resets != 0) {
        ADD_FAILURE() << name() << " frame " << t << ": nothing moved, yet " << resets << " models were reset";
        return;
      }
      if (t > 0) v.reprojectionResets += resets;
      // (float64 may release other pixels: its box corrections, which restart the windows, may differ.)
      const long releases = v.k32.lastStats().releases;
      if (releases != v.k32reference.lastStats().releases) {
        ADD_FAILURE() << name() << " frame " << t << ": releases " << releases << " (float), "
                      << v.k32reference.lastStats().releases << " (its reference)";
        return;
      }
      v.releases += releases;
      v.releases64 += v.k64.lastStats().releases;
      if (v.k32.lastStats().guards != 0 || v.k64.lastStats().guards != 0) {
        ADD_FAILURE() << name() << " frame " << t << ": guards fired, float " << v.k32.lastStats().guards
                      << ", double " << v.k64.lastStats().guards;
        return;
      }
      for (int y = 0; y < kH; ++y)
        for (int x = 0; x < kW; ++x) {
          const Range& r = ranges[std::size_t(y) * kW + x];
          for (int ch = 0; ch < 3; ++ch) {
            const float o = v.out32.at(x, y)[ch];
            const double d = v.out64.at(x, y)[ch];
            if (!r.contains(ch, o) || !r.contains(ch, d)) {
              ADD_FAILURE() << name() << " frame " << t << " (" << x << "," << y << ") ch " << ch << ": float " << o
                            << ", double " << d << ", range [" << r.lo[ch] << ", " << r.hi[ch] << "]";
              return;
            }
            const double extent = double(r.hi[ch]) - double(r.lo[ch]);
            const double diff = std::fabs(double(o) - d);
            if (v.checkAgreement && !(diff <= kTolerance * extent + r.slack(ch))) {
              ADD_FAILURE() << name() << " frame " << t << " (" << x << "," << y << ") ch " << ch << ": float " << o
                            << " vs double " << d << " (box extent " << extent << ")";
              return;
            }
            if (extent > 0) v.worstRelativeDiff = std::max(v.worstRelativeDiff, diff / extent);
          }
        }
      checkState(v.k32, s, t, name, v.seen32);
      checkState(v.k64, s, t, name, v.seen64);
      if (::testing::Test::HasFailure()) return;
    }
  }
  for (const Variant& v : variants)
    std::printf("%-30s %-36s max trace P %7.1f, floor of P %.3g, float-vs-double worst %.2e of box extent, box resets "
                "%ld/%ld (f32/f64), reprojection resets after the first frame %ld, releases from the hold %ld/%ld\n",
                sc.name, v.label, std::max(v.seen32.maxTrace, v.seen64.maxTrace), v.seen32.floor, v.worstRelativeDiff,
                v.boxResets32, v.boxResets64, v.reprojectionResets, v.releases, v.releases64);
  for (const Variant& v : variants) {
    if (startsOver(sc)) {
      EXPECT_GT(v.reprojectionResets, 0) << sc.name << ", " << v.label << ": no model was reset";
    }
    if (periodic(sc)) {
      EXPECT_EQ(v.releases, 0) << sc.name << ", " << v.label << ": a periodic input released models";
      EXPECT_EQ(v.releases64, 0) << sc.name << ", " << v.label << ": a periodic input released float64 models";
    }
  }
}

}  // namespace

TEST(PhlmStability, TwentyThousandFrameRuns) {
  for (const Scenario& sc : scenarios()) {
    std::vector<Variant> variants(2);
    variants[0].label = "defaults";
    variants[1].label = "holdPeriod 0";
    variants[1].settings.holdPeriod = 0;
    runScenario(sc, variants);
    if (::testing::Test::HasFailure()) return;
  }
}

// The paper's reset covariance 1000 I (slopeCovariance = 1000): still bounded,
// positive definite, finite and inside the box every frame (shorter runs).
// The float32/float64 agreement is NOT asserted here: with slope variances of
// 1000 the fit is ill-conditioned (slopes of ~1/|dz|) and, on HDR fireflies,
// the two precisions part ways (measured: 4% of the box extent after ~2800
// frames) -- the reason for the default slopeCovariance = 1 (phlm.cpp).
TEST(PhlmStability, PaperCovarianceStaysBounded) {
  for (const Scenario& sc : scenarios()) {
    std::vector<Variant> variants(1);
    variants[0].label = "slopeCovariance 1000, holdPeriod 0";
    variants[0].settings.slopeCovariance = 1000.0;
    variants[0].settings.holdPeriod = 0;
    variants[0].checkAgreement = false;
    runScenario(sc, variants, 3000);
    if (::testing::Test::HasFailure()) return;
  }
}

// A single firefly (1e6, sanitised to 65504) at frame 100 of a static scene
// with EEVEE's jitter, at EVERY pixel of the frame in turn (its effect
// depends on where it lands), against the same run without it: the largest
// output difference from +1, +5, +20 and +100 frames after it on, worst over
// all positions, against a stated bound per case (kBound: the measured worst,
// printed, with ~1.5x margin).
//  * Constant colour: only the firefly's own frame shows it (with the hold,
//    not even that: the held model lies inside the box it widens).
//  * Texture, holdPeriod 0: A WEAKNESS, measured here, not fixed. The
//    unjittered measurement (the 3x3 Blackman-Harris mix, phlm.cpp "Jitter")
//    brings the firefly into the neighbours' samples at a fraction of its
//    value; a converged model takes that sample with a small gain, its
//    prediction moves by up to ~0.3 but stays inside the textured 3x3 box, so
//    no box correction restarts it, and the error leaves only as fast as the
//    RLS forgets (lambda 0.998): 0.32 at +1, 0.21 at +20, still 0.095 at +100
//    (0.04 at +275). Without jitter the same pixel differs by 4e-4 at +1.
//    The likely fix is a firefly-robust mix (taps weighted by 1 / (1 + luma),
//    Karis 2014) or a clipped innovation in the RLS update.
//  * Texture, default hold: the held models do not take the sample in; a box
//    correction that releases one gives 0.34 at +1, 0.05 at +5, 3e-5 at +20.
TEST(PhlmStability, SingleFireflyStopsAffectingOutput) {
  constexpr int kFirefly = 100, kRun = 300;
  constexpr int kAfter[4] = {1, 5, 20, 100};
  for (int run = 0; run < 4; ++run) {
    const int scene = run % 2;
    const bool hold = run >= 2;
    phlm::Settings s;
    if (!hold) s.holdPeriod = 0;
    Input in;
    if (scene == 0) fill(in.color, 0.3f, 0.5f, 0.7f);
    else texture(in.color, 1.0f);
    const FireflyFade fade = fireflyOnEveryPixel(
        in.color,
        [&] {
          auto k = std::make_shared<phlm::Kernel<float>>();
          k->allocate(kW, kH, false, false);
          auto out = std::make_shared<Image>(kW, kH, 4);
          return [=](int t, const Image& color) -> const Image& {
            phlm::Settings st = s;
            const temporal::Jitter j = jitterAt(t);
            st.jitterX = j.x, st.jitterY = j.y;
            phlm::Inputs a;
            a.color = color.view();
            a.output = out->view();
            k->run(a, st, false, 1);
            return *out;
          };
        },
        kFirefly, kRun, kAfter);
    const double kBound[3][4] = {{1e-5, 1e-5, 1e-5, 1e-5},   // constant colour
                                 {0.5, 0.45, 0.3, 0.15},     // texture, holdPeriod 0
                                 {0.5, 0.08, 5e-5, 5e-7}};   // texture, held
    expectFade(fade,
               std::string("phlm (") + (scene == 0 ? "constant colour" : "static texture") + ", " +
                   (hold ? "held" : "holdPeriod 0") + ")",
               kAfter, kBound[scene == 0 ? 0 : hold ? 2 : 1], !hold);
  }
}

// The same on a pan (0.7 px/frame, motion and depth given): the 1e6 firefly
// itself is gone the next frame; what remains is the models it reset
// re-converging, which fades (measured: 0.13 at +1, 0.009 at +14, < 1e-6 from
// +26, 0 from +32).
TEST(PhlmStability, SingleFireflyOnPanFades) {
  constexpr int W = 16, H = 12, kFirefly = 100;
  const phlm::Settings s;
  phlm::Kernel<float> clean, hit;
  clean.allocate(W, H, true, true);
  hit.allocate(W, H, true, true);
  Image color(W, H, 4), motion(W, H, 2), depth(W, H, 1, 10.0f), outClean(W, H, 4), outHit(W, H, 4);
  for (int t = 0; t < 200; ++t) {
    for (int y = 0; y < H; ++y)
      for (int x = 0; x < W; ++x) {
        const float u = float(x) + 0.7f * float(t);
        float* p = color.at(x, y);
        p[0] = 0.5f + 0.5f * std::sin(0.9f * u), p[1] = 0.5f + 0.4f * std::cos(0.3f * u + float(y));
        p[2] = 0.25f, p[3] = 1.0f;
        motion.at(x, y)[0] = 0.7f, motion.at(x, y)[1] = 0.0f;
      }
    phlm::Inputs in;
    in.color = color.view();
    in.motion = motion.view();
    in.depth = depth.view();
    in.output = outClean.view();
    clean.run(in, s, false, 1);
    if (t == kFirefly) color.at(8, 6)[0] = color.at(8, 6)[1] = color.at(8, 6)[2] = 1e6f;
    in.output = outHit.view();
    hit.run(in, s, false, 1);
    double diff = 0;
    for (std::size_t i = 0; i < outClean.data.size(); ++i)
      diff = std::max(diff, double(std::fabs(outClean.data[i] - outHit.data[i])));
    if (t < kFirefly) {
      ASSERT_EQ(diff, 0.0);
    } else if (t == kFirefly) {
      EXPECT_GT(diff, 1.0);
    } else {
      EXPECT_LT(diff, 0.2) << "frame " << t;
      // 20 frames: unjitter's moving measurement mixes the 3x3, so the
      // firefly reaches 9 models at a fraction of its value (15 without it).
      if (t >= kFirefly + 20) {
        EXPECT_LT(diff, 0.01) << "frame " << t;
      }
      if (t >= kFirefly + 30) {
        EXPECT_LT(diff, 1e-5) << "frame " << t;
      }
    }
  }
}

// The hold (phlm.cpp "Hold") on a static texture with EEVEE's jitter and the
// default holdPeriod 16, 4000 frames through the fast path: the pixels held
// over frames 48-80 (kMinHeld of the 280 at least, so the check is not
// vacuous) keep their output bit for bit to the end. A held model's sample
// count (one byte, Kernel::stillSamples_) stops at holdPeriod; one that kept
// counting and wrapped would let the model learn again every 256 frames.
TEST(PhlmStability, HeldPixelsStayHeld) {
  constexpr int kMinHeld = 180;  // measured: 204
  Image still(kW, kH, 4);
  texture(still, 1.0f);
  phlm::Kernel<float> k;
  k.allocate(kW, kH, false, false);
  Image out(kW, kH, 4);
  const phlm::Settings defaults;
  const HeldOutputs held = heldOutputs(
      still,
      [&](int t, const Image& color) -> const Image& {
        phlm::Settings s = defaults;
        const temporal::Jitter j = jitterAt(t);
        s.jitterX = j.x, s.jitterY = j.y;
        phlm::Inputs a;
        a.color = color.view();
        a.output = out.view();
        k.run(a, s, false, 2);
        return out;
      },
      48, 32, 4000);
  std::printf("phlm: %d of %dx%d pixels held from frame 48 on\n", held.held, kW, kH);
  EXPECT_GE(held.held, kMinHeld);
  EXPECT_EQ(held.firstChange, -1) << "held pixel (" << held.x << "," << held.y << ") changed at frame "
                                  << held.firstChange;
}
