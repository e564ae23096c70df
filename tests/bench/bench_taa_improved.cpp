// SPDX-License-Identifier: Apache-2.0
// taa-improved benchmarks: the whole filter through the Filter interface, one
// frame per iteration, alternating two frames of a camera pan (every pixel
// moves 0.7 px right, 0.3 px down) with colour, motion, depth, object ids and
// an albedo layer (the colour itself), so every pass runs. Counters as in
// bench_taa.cpp (kept_MB, scratch_MB); the floor is floor.memcpy_rgba.
#include <benchmark/benchmark.h>

#include <map>
#include <string>
#include <utility>

#include "core/context.h"
#include "core/filter.h"
#include "filters/taa_improved.h"
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

void runImproved(benchmark::State& state, int width, int height, int threads, bool reference) {
  const auto& [a, b] = frames(width, height);
  crisp::Image output(width, height, 4);
  crisp::Context context;
  context.setInt("numThreads", threads);
  auto filter = crisp::createFilter(context, "taa-improved");
  filter->params().setBool("reference", reference);
  filter->setImage("output", output.view());
  bool odd = false;
  auto point = [&](const FrameData& f) {
    filter->setImage("color", f.color.view());
    filter->setImage("motion", f.motion.view());
    filter->setImage("depth", f.depth.view());
    filter->setImage("id", f.id.view());
    filter->setImage("albedo", f.color.view());
  };
  point(a);
  filter->commit();
  filter->execute();
  for (auto _ : state) {
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
  crisp::taa_improved::Kernel k;
  k.allocate(width, height, true);
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
      bool reference;
    };
    const Variant variants[] = {{"taa-improved.all_inputs.fast.mt", 0, false},
                                {"taa-improved.all_inputs.fast.st", 1, false},
                                {"taa-improved.all_inputs.reference", 1, true}};
    for (const Variant& v : variants)
      benchmark::RegisterBenchmark((v.name + tag).c_str(), [w, h, v](benchmark::State& st) {
        runImproved(st, w, h, v.threads, v.reference);
      })
          ->Unit(benchmark::kMillisecond)
          ->UseRealTime();
  }
}

const bool registered = (registerAll(), true);

}  // namespace
