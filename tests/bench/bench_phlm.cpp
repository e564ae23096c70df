// SPDX-License-Identifier: Apache-2.0
// PHLM benchmarks: the whole "phlm" filter through the Filter interface, one
// frame per iteration, alternating two pre-rendered frames of a camera pan
// (every pixel moves 0.7 px right, 0.3 px down per frame: every pixel takes
// the reprojected path with bilinear feature and coefficient fetches, the
// worst case) with colour, motion and depth; and a still scene without motion
// and depth (in-place update, no reprojection work). Variants: fast.mt (all
// threads), fast.st (one thread), reference (scalar path). Wall time is the
// reported time; process CPU time (all threads) is measured too
// (MeasureProcessCPUTime). Counters: kept_MB = state kept between frames,
// scratch_MB = staged frame. The memory-copy floor of the same run is
// floor.memcpy_rgba (bench_floor.cpp).
#include <benchmark/benchmark.h>

#include <map>
#include <string>
#include <utility>

#include "core/context.h"
#include "core/filter.h"
#include "filters/phlm.h"
#include "synth/moving.h"

namespace {

using crisp::synth::FrameData;

const std::pair<FrameData, FrameData>& panFrames(int width, int height) {
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

void runPhlm(benchmark::State& state, int width, int height, int threads, bool reference, bool moving) {
  const auto& [a, b] = panFrames(width, height);
  crisp::Image output(width, height, 4);
  crisp::Context context;
  context.setInt("numThreads", threads);
  auto filter = crisp::createFilter(context, "phlm");
  filter->params().setBool("reference", reference);
  filter->setImage("output", output.view());
  auto point = [&](const FrameData& f) {
    filter->setImage("color", f.color.view());  // same shape: no re-commit needed
    if (moving) {
      filter->setImage("motion", f.motion.view());
      filter->setImage("depth", f.depth.view());
    }
  };
  point(a);
  filter->commit();
  filter->execute();  // state exists from here on
  bool odd = false;
  for (auto _ : state) {
    // A real caller re-commits per frame for the new jitter; that allocates nothing.
    const FrameData& f = odd ? a : b;
    point(f);
    filter->params().setFloat("jitterX", f.jitter.x);
    filter->params().setFloat("jitterY", f.jitter.y);
    filter->markDirty();
    filter->commit();
    filter->execute();
    odd = !odd;
    benchmark::DoNotOptimize(output.data.data());
    benchmark::ClobberMemory();
  }
  crisp::phlm::Kernel<float> k;
  k.allocate(width, height, moving, moving);
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
    };
    const Variant variants[] = {{"phlm.fast.mt", 0, false, true},
                                {"phlm.fast.st", 1, false, true},
                                {"phlm.reference", 1, true, true},
                                {"phlm.static.fast.mt", 0, false, false}};
    for (const Variant& v : variants) {
      auto* b = benchmark::RegisterBenchmark((v.name + tag).c_str(), [=](benchmark::State& st) {
        runPhlm(st, w, h, v.threads, v.reference, v.moving);
      });
      b->Unit(benchmark::kMillisecond)->UseRealTime()->MeasureProcessCPUTime();
      if (w > 256) b->Iterations(v.reference || v.threads == 1 ? 6 : 12)->Repetitions(3)->ReportAggregatesOnly(true);
    }
  }
}

const bool registered = (registerAll(), true);

}  // namespace
