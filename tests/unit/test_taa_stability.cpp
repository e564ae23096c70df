// SPDX-License-Identifier: Apache-2.0
// Numerical stability of "taa" and "taa-improved" (issue 4's stability
// suite): 20 000-frame runs of the scenarios of stability_scenarios.h (35x8,
// EEVEE's jitter) through each kernel's fast path (8-lane rows) and its
// scalar reference path on the same input, with the
// defaults and with holdPeriod 0 (still history keeps averaging). At EVERY
// frame and pixel:
//  * the non-finite guard never fired (taa::Kernel::guardsLastFrame: a
//    blend that was not finite, reset to the current colour), so finite
//    outputs are the kernel's, not the guard's;
//  * the output is inside the colour range of the pixel's unjittered 3x3 (or
//    its 5x5 where nothing there moves: the footprint-box exception) of the
//    sanitised input (stability::outputRanges; clip in RGB, no sharpen: every
//    path is a convex mix of values inside that box);
//  * the fast path's output (and taa-improved's aliasedValue plane) equals
//    the reference's bit for bit, and so do their reset counts;
//  * the accumulated sample weight W stays at or below maxSamples
//    (taa::Kernel::largestSampleWeight), and reaches it with holdPeriod 0 on
//    the scenarios that keep to the running average (kAccumulating): a
//    running average with an uncapped W stays inside the box too;
//  * where nothing moved since the previous frame (stability::StillFrames),
//    no pixel started over (taa::Kernel::resetsLastFrame), border pixels
//    included, and pixels did on the scenarios with off-screen, non-finite or
//    disoccluded reprojection (stability::startsOver);
//  * releases from the hold (taa.cpp "Hold") match between the paths and are
//    none on the periodic scenarios (stability::periodic). (The slow drift
//    leaves taa's box every frame, so its pixels never average or hold.)
// Then a single firefly on every pixel in turn, with a stated bound on how
// long it affects the output.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <memory>
#include <set>
#include <string>
#include <vector>

#include "filters/taa.h"
#include "filters/taa_improved.h"
#include "stability_scenarios.h"

using namespace crisp;
using namespace crisp::test::stability;

namespace {

constexpr int kW = kWidth, kH = kHeight;

// taa or taa-improved on one path, driven through its kernel.
class Runner {
 public:
  Runner(bool improved, bool depth, int holdPeriod) : improved_(improved) {
    if (improved) {
      improvedKernel_.allocate(kW, kH, depth);
      improvedSettings_.base.holdPeriod = holdPeriod;
    } else {
      taaKernel_.allocate(kW, kH, depth);
      taaSettings_.holdPeriod = holdPeriod;
    }
  }
  // One frame; id: the object-id image (taa-improved only).
  const Image& run(const Input& in, const Image& id, bool motion, bool depth, temporal::Jitter j, bool reference) {
    const int threads = 1;  // 8 rows: one band either way (band borders: test_taa.cpp)
    if (improved_) {
      taa_improved::Inputs a;
      a.color = in.color.view();
      if (motion) a.motion = in.motion.view();
      if (depth) a.depth = in.depth.view();
      a.id = id.view();
      a.output = output_.view();
      improvedSettings_.base.jitterX = j.x, improvedSettings_.base.jitterY = j.y;
      improvedKernel_.run(a, improvedSettings_, reference, threads);
    } else {
      taa::Inputs a;
      a.color = in.color.view();
      if (motion) a.motion = in.motion.view();
      if (depth) a.depth = in.depth.view();
      a.output = output_.view();
      taaSettings_.jitterX = j.x, taaSettings_.jitterY = j.y;
      taaKernel_.run(a, taaSettings_, reference, threads);
    }
    return output_;
  }
  // taa-improved's aliasedValue plane of the last frame (empty for taa).
  std::vector<float> aliasedValue() const { return improved_ ? improvedKernel_.aliasedValue() : std::vector<float>{}; }
  // The taa kernel (taa-improved's baseline): its guard and reset counts, its sample weights.
  const taa::Kernel& kernel() const { return improved_ ? improvedKernel_.baseline() : taaKernel_; }

 private:
  bool improved_;
  taa::Kernel taaKernel_;
  taa::Settings taaSettings_;
  taa_improved::Kernel improvedKernel_;
  taa_improved::Settings improvedSettings_;
  Image output_{kW, kH, 4};
};

// The object ids of a frame: the near surface (depth < 5) is object 2.
void idsOf(const Input& in, bool depth, Image& id) {
  for (int y = 0; y < kH; ++y)
    for (int x = 0; x < kW; ++x) id.setUint(x, y, depth && in.depth.at(x, y)[0] < 5.0f ? 2u : 1u);
}

const char* filterName(bool improved) { return improved ? "taa-improved" : "taa"; }

}  // namespace

// Scenarios whose pixels keep to the running average once it has started,
// so that with holdPeriod 0 their sample weight W reaches maxSamples
// (measured; on the flickers and the slow gradient the history leaves the
// box and takes the feedback blend, whose W stays near 1 / (1 - k)).
const std::set<std::string> kAccumulating = {"constant colour", "checker flicker", "HDR fireflies 1e4-1e6",
                                             "zero motion, noisy", "camera cut halfway"};

TEST(TemporalStability, TaaTwentyThousandFrameRuns) {
  const taa::Settings defaults;  // the range check below assumes these
  ASSERT_EQ(defaults.clipSpace, taa::ClipSpace::Rgb);
  ASSERT_EQ(defaults.sharpen, 0.0f);
  ASSERT_TRUE(defaults.staticAccumulation);
  for (const Scenario& sc : scenarios()) {
    struct Variant {
      bool improved;
      int holdPeriod;
      std::unique_ptr<Runner> fast, reference;
      float heaviest = 0;  // the largest sample weight W over the run (taa::Kernel::largestSampleWeight)
      long resets = 0;     // pixels that started over after the first frame (taa::Kernel::resetsLastFrame)
      long releases = 0;   // still pixels released from the hold (taa::Kernel::releasesLastFrame)
    };
    std::vector<Variant> variants;
    for (bool improved : {false, true})
      for (int hold : {defaults.holdPeriod, 0})
        variants.push_back({improved, hold, std::make_unique<Runner>(improved, sc.depth, hold),
                            std::make_unique<Runner>(improved, sc.depth, hold)});
    Input in;
    Image id = Image::uintImage(kW, kH);
    StillFrames stillFrames;
    for (int t = 0; t < runFrames(); ++t) {
      sc.make(t, in);
      const bool still = stillFrames.next(sc, t, in);
      idsOf(in, sc.depth, id);
      const temporal::Jitter j = jitterAt(t);
      const temporal::Unjitter u = temporal::unjitterFor(defaults.unjitter, j.x, j.y, defaults.filterSize);
      const std::vector<Range> ranges = outputRanges(in.color, sc.motion ? &in.motion : nullptr, u, true);
      for (Variant& v : variants) {
        const auto name = [&] {
          return std::string(filterName(v.improved)) + " holdPeriod " + std::to_string(v.holdPeriod) + ", " + sc.name +
                 ", frame " + std::to_string(t);
        };
        const Image& fast = v.fast->run(in, id, sc.motion, sc.depth, j, false);
        const taa::Kernel& kernel = v.fast->kernel();
        if (kernel.guardsLastFrame() != 0) {
          ADD_FAILURE() << name() << ": the non-finite guard fired on " << kernel.guardsLastFrame() << " pixels";
          return;
        }
        const Image& reference = v.reference->run(in, id, sc.motion, sc.depth, j, true);
        if (std::memcmp(fast.data.data(), reference.data.data(), fast.data.size() * sizeof(float)) != 0 ||
            v.fast->aliasedValue() != v.reference->aliasedValue()) {
          ADD_FAILURE() << name() << ": fast path differs from the reference (output or aliasedValue)";
          return;
        }
        const long resets = kernel.resetsLastFrame();
        if (resets != v.reference->kernel().resetsLastFrame()) {
          ADD_FAILURE() << name() << ": " << resets << " resets on the fast path, "
                        << v.reference->kernel().resetsLastFrame() << " on the reference";
          return;
        }
        if (still && resets != 0) {
          ADD_FAILURE() << name() << ": nothing moved, yet " << resets << " pixels started over";
          return;
        }
        if (t > 0) v.resets += resets;
        if (kernel.releasesLastFrame() != v.reference->kernel().releasesLastFrame()) {
          ADD_FAILURE() << name() << ": " << kernel.releasesLastFrame() << " releases on the fast path, "
                        << v.reference->kernel().releasesLastFrame() << " on the reference";
          return;
        }
        v.releases += kernel.releasesLastFrame();
        const float heaviest = kernel.largestSampleWeight();
        if (!(heaviest <= float(defaults.maxSamples))) {
          ADD_FAILURE() << name() << ": sample weight " << heaviest << " above maxSamples " << defaults.maxSamples;
          return;
        }
        v.heaviest = std::max(v.heaviest, heaviest);
        for (int y = 0; y < kH; ++y)
          for (int x = 0; x < kW; ++x) {
            const Range& r = ranges[std::size_t(y) * kW + x];
            for (int c = 0; c < 3; ++c) {
              const float o = fast.at(x, y)[c];
              if (!r.contains(c, o)) {
                ADD_FAILURE() << name() << " (" << x << "," << y << ") ch " << c << ": output " << o
                              << " outside [" << r.lo[c] << ", " << r.hi[c] << "]";
                return;
              }
            }
          }
      }
    }
    std::printf("%-30s %d frames: taa and taa-improved (holdPeriod %d and 0): no guard fired, inside the range, "
                "fast == reference\n", sc.name, runFrames(), defaults.holdPeriod);
    const std::string name = sc.name;
    for (const Variant& v : variants) {
      std::printf("  %-12s holdPeriod %2d: largest sample weight %g, resets after the first frame %ld, releases "
                  "from the hold %ld\n",
                  filterName(v.improved), v.holdPeriod, double(v.heaviest), v.resets, v.releases);
      const std::string label = std::string(filterName(v.improved)) + " holdPeriod " + std::to_string(v.holdPeriod) +
                                ", " + name;
      if (v.holdPeriod == 0 && kAccumulating.count(name)) {
        EXPECT_EQ(v.heaviest, float(defaults.maxSamples)) << label << ": the running average never reached its cap";
      }
      if (startsOver(sc)) {
        EXPECT_GT(v.resets, 0) << label << ": no pixel started over";
      }
      if (periodic(sc)) {
        EXPECT_EQ(v.releases, 0) << label << ": a periodic input released held pixels";
      }
    }
  }
}

// A single firefly (1e6, sanitised to 65504) at frame 100, with EEVEE's
// jitter, on a constant colour and on a static texture, on every pixel in
// turn: the largest output difference against the same run without it from
// +1, +5, +20 and +80 frames after it on, worst over the positions, against
// the stated bounds (kBound: about 1.5x the measured worst, printed).
//  * Defaults (holdPeriod 16): on a constant colour only its own frame shows
//    it; on the texture the neighbours' unjittered mixes carry a fraction of
//    it into their averages for a few frames, and from +80 frames on the
//    output is the clean run's (to 1e-6).
//  * holdPeriod 0 on the texture: A WEAKNESS, measured here, not fixed. A
//    neighbour whose average took the firefly's share is rejected by the
//    static clip and moves to the feedback blend for good (taa.cpp:
//    historyState_ bit 0 is kept until a reset, and a still pixel is never
//    reset), so it follows each frame's jittered mix with ~7 frames of memory
//    instead of its converged average: up to 0.18 (taa) / 0.21
//    (taa-improved) away from the clean run, not fading. Tried 2026-12-03:
//    testing such history against the footprint box as well (the bit no
//    longer narrows the test) makes this case fade, slowly (0.15 at +20,
//    0.099 at +80), but the defaults' texture case then stays 0.099 away at
//    +80 instead of 1e-6, and crisp eval's ghosting renders give the same
//    bits either way (no pixel there takes that path); not adopted.
TEST(TemporalStability, TaaSingleFireflyOnEveryPixel) {
  // [held][scene: constant, texture][from +1, +5, +20, +80]
  const double kBound[2][2][4] = {{{1e-6, 1e-6, 1e-6, 1e-6}, {0.4, 0.33, 0.33, 0.33}},
                                  {{1e-6, 1e-6, 1e-6, 1e-6}, {0.25, 0.1, 0.004, 1e-6}}};
  constexpr int kFirefly = 100, kRun = 200;
  constexpr int kAfter[4] = {1, 5, 20, 80};
  for (bool improved : {false, true})
    for (int run = 0; run < 4; ++run) {
      const int scene = run % 2;
      const int hold = run >= 2 ? 16 : 0;
      Input in;
      if (scene == 0) fill(in.color, 0.3f, 0.5f, 0.7f);
      else texture(in.color, 1.0f);
      Image id = Image::uintImage(kW, kH);
      idsOf(in, false, id);
      const FireflyFade fade = fireflyOnEveryPixel(
          in.color,
          [&] {
            auto runner = std::make_shared<Runner>(improved, false, hold);
            return [runner, &in, &id](int t, const Image& color) -> const Image& {
              Input frame = in;
              frame.color = color;
              return runner->run(frame, id, false, false, jitterAt(t), false);
            };
          },
          kFirefly, kRun, kAfter);
      expectFade(fade,
                 std::string(filterName(improved)) + " (" + (scene == 0 ? "constant colour" : "static texture") +
                     ", holdPeriod " + std::to_string(hold) + ")",
                 kAfter, kBound[hold ? 1 : 0][scene], !(scene == 1 && hold));
    }
}

// The hold (taa.cpp "Hold") on a static texture with EEVEE's jitter and the
// default holdPeriod 16, 4000 frames through the fast path: the pixels held
// over frames 48-80 (two jitter periods; kMinHeld of the 280 at least, so the
// check is not vacuous) keep their output bit for bit to the end. The
// frames since a pixel's reset live in 7 bits (Kernel::historyState_); if the
// count wrapped instead of saturating at 127, the hold would let go every
// 128 frames and the output move again.
TEST(TemporalStability, TaaHeldPixelsStayHeld) {
  constexpr int kMinHeld = 180;  // measured: 204 (taa and taa-improved)
  Input in;
  texture(in.color, 1.0f);
  Image id = Image::uintImage(kW, kH);
  idsOf(in, false, id);
  const taa::Settings defaults;
  for (bool improved : {false, true}) {
    Runner runner(improved, false, defaults.holdPeriod);
    const HeldOutputs held = heldOutputs(
        in.color,
        [&](int t, const Image& color) -> const Image& {
          Input frame = in;
          frame.color = color;
          return runner.run(frame, id, false, false, jitterAt(t), false);
        },
        48, 32, 4000);
    std::printf("%s: %d of %dx%d pixels held from frame 48 on\n", filterName(improved), held.held, kW, kH);
    EXPECT_GE(held.held, kMinHeld) << filterName(improved);
    EXPECT_EQ(held.firstChange, -1) << filterName(improved) << ": held pixel (" << held.x << "," << held.y
                                    << ") changed at frame " << held.firstChange;
  }
}
