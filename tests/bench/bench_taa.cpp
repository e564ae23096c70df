// SPDX-License-Identifier: Apache-2.0
// TAA benchmarks: the whole filter through the Filter interface, one frame per
// iteration, alternating two pre-rendered frames of a camera pan (every pixel
// moves 0.7 px right, 0.3 px down per frame: every pixel takes the reprojected,
// clipped path, the worst case) with colour, motion and depth. Variants: the
// history fetch (Catmull-Rom default, bilinear), and a still scene without
// motion and depth (the static accumulation path, no reprojection work).
// Counters: kept_MB = memory kept between frames (history), scratch_MB = the
// fast path's per-band row rings. The memory-copy floor of the same run is floor.memcpy_rgba
// (bench_floor.cpp).
#include <benchmark/benchmark.h>

#include <map>
#include <string>
#include <utility>

#include "core/context.h"
#include "core/filter.h"
#include "filters/taa.h"
#include "synth/moving.h"

namespace {

using crisp::synth::FrameData;

const std::pair<FrameData, FrameData>& frames(int width, int height) {
  static std::map<std::pair<int, int>, std::pair<FrameData, FrameData>> cache;
  auto key = std::make_pair(width, height);
  auto it = cache.find(key);
  if (it != cache.end()) return it->second;
  crisp::synth::Sequence seq = crisp::synth::staticChartSequence(width, height);
  for (auto& s : seq.before.shapes) {
    s.vx = 0.7f;
    s.vy = 0.3f;
  }
  seq.before.backgroundVx = 0.7f;
  seq.before.backgroundVy = 0.3f;
  crisp::synth::FrameOptions opt;
  opt.reference = crisp::synth::ReferenceKind::None;
  auto pair = std::make_pair(crisp::synth::renderFrame(seq, width, height, 1, opt),
                             crisp::synth::renderFrame(seq, width, height, 2, opt));
  return cache.emplace(key, std::move(pair)).first->second;
}

void runTaa(benchmark::State& state, int width, int height, int threads, bool reference, bool moving,
            const char* historyFilter) {
  const auto& [a, b] = frames(width, height);
  crisp::Image output(width, height, 4);
  crisp::Context context;
  context.setInt("numThreads", threads);
  auto filter = crisp::createFilter(context, "taa");
  filter->params().setBool("reference", reference);
  filter->params().setString("historyFilter", historyFilter);
  filter->setImage("output", output.view());
  bool odd = false;
  auto point = [&](const FrameData& f) {
    filter->setImage("color", f.color.view());  // same shape: no re-commit needed
    if (moving) {
      filter->setImage("motion", f.motion.view());
      filter->setImage("depth", f.depth.view());
    }
  };
  point(a);
  filter->commit();
  filter->execute();  // history exists from here on
  for (auto _ : state) {
    // A real caller re-commits per frame for the new jitter; that costs no allocation.
    point(odd ? a : b);
    filter->params().setFloat("jitterX", (odd ? a : b).jitter.x);
    filter->params().setFloat("jitterY", (odd ? a : b).jitter.y);
    filter->markDirty();
    filter->commit();
    filter->execute();
    odd = !odd;
    benchmark::DoNotOptimize(output.data.data());
    benchmark::ClobberMemory();
  }
  crisp::taa::Kernel k;
  k.allocate(width, height, moving);  // depth planes only when depth is given
  state.counters["kept_MB"] = double(k.bytesKeptBetweenFrames()) / 1e6;
  state.counters["scratch_MB"] = double(k.bytesScratch()) / 1e6;
  state.counters["pixels_per_s"] =
      benchmark::Counter(double(width) * height, benchmark::Counter::kIsIterationInvariantRate);
}

void registerAll() {
  const int sizes[2][2] = {{1920, 1080}, {64, 64}};
  for (const auto& s : sizes) {
    const int w = s[0], h = s[1];
    const std::string tag = "/" + std::to_string(w) + "x" + std::to_string(h);
    struct Variant {
      const char* name;
      int threads;
      bool reference, moving;
      const char* filter;
    };
    const Variant variants[] = {{"taa.rgb_motion_depth.fast.mt", 0, false, true, "catmull-rom"},
                                {"taa.rgb_motion_depth.fast.st", 1, false, true, "catmull-rom"},
                                {"taa.rgb_motion_depth.reference", 1, true, true, "catmull-rom"},
                                {"taa.rgb_motion_depth.bilinear.fast.mt", 0, false, true, "bilinear"},
                                {"taa.rgb_static.fast.mt", 0, false, false, "catmull-rom"}};
    for (const Variant& v : variants)
      benchmark::RegisterBenchmark((v.name + tag).c_str(), [w, h, v](benchmark::State& st) {
        runTaa(st, w, h, v.threads, v.reference, v.moving, v.filter);
      })
          ->Unit(benchmark::kMillisecond)
          ->UseRealTime();
  }
}

const bool registered = (registerAll(), true);

}  // namespace
