// SPDX-License-Identifier: Apache-2.0
// REPAIR benchmarks: the whole filter (stage, grey, Sobel, threshold, slope,
// rotated smoothing, output) through the Filter interface, on the synthetic
// test chart, whose edge density is realistic (cost grows with the number of
// edge pixels; the fraction is reported as the counter `edge_fraction`).
// repair.floor.copy is the memory-copy floor in the same run: reading and
// writing one RGBA float frame, which any filter must do at least once.
#include <benchmark/benchmark.h>

#include <cstring>
#include <map>
#include <utility>

#include "core/context.h"
#include "core/filter.h"
#include "filters/repair.h"
#include "synth/synthetic.h"

namespace {

using crisp::Image;

const Image& chart(int width, int height) {
  static std::map<std::pair<int, int>, Image> cache;
  auto key = std::make_pair(width, height);
  auto it = cache.find(key);
  if (it == cache.end())
    it = cache.emplace(key, crisp::synth::renderCentre(crisp::synth::testChart(width, height), width, height)).first;
  return it->second;
}

void runRepair(benchmark::State& state, int width, int height, int threads, bool reference) {
  const Image& input = chart(width, height);
  Image output(width, height, 4);
  crisp::Context context;
  context.setInt("numThreads", threads);
  auto filter = crisp::createFilter(context, "repair");
  filter->setImage("color", input.view());
  filter->setImage("output", output.view());
  filter->params().setBool("reference", reference);
  filter->commit();
  for (auto _ : state) {
    filter->execute();
    benchmark::DoNotOptimize(output.data.data());
    benchmark::ClobberMemory();
  }
  // Edge fraction of this input (same threshold as the default filter).
  crisp::repair::Kernel kernel;
  kernel.allocate(width, height);
  Image scratch(width, height, 4);
  kernel.run(input.view(), scratch.view(), crisp::repair::Settings{}, false, threads);
  state.counters["edge_fraction"] = double(kernel.edgeCount()) / (double(width) * height);
  state.counters["pixels_per_s"] = benchmark::Counter(double(width) * height, benchmark::Counter::kIsIterationInvariantRate);
}

void copyFloor(benchmark::State& state, int width, int height) {
  const Image& input = chart(width, height);
  Image output(width, height, 4);
  for (auto _ : state) {
    std::memcpy(output.data.data(), input.data.data(), input.data.size() * sizeof(float));
    benchmark::ClobberMemory();
  }
  state.SetBytesProcessed(int64_t(state.iterations()) * int64_t(input.data.size() * sizeof(float)) * 2);
}

void registerAll() {
  const int sizes[2][2] = {{1920, 1080}, {64, 64}};
  for (const auto& s : sizes) {
    const int w = s[0], h = s[1];
    const std::string tag = "/" + std::to_string(w) + "x" + std::to_string(h);
    benchmark::RegisterBenchmark(("repair.fast.mt" + tag).c_str(), [w, h](benchmark::State& st) { runRepair(st, w, h, 0, false); })
        ->Unit(benchmark::kMillisecond)->UseRealTime();
    benchmark::RegisterBenchmark(("repair.fast.st" + tag).c_str(), [w, h](benchmark::State& st) { runRepair(st, w, h, 1, false); })
        ->Unit(benchmark::kMillisecond)->UseRealTime();
    benchmark::RegisterBenchmark(("repair.reference" + tag).c_str(), [w, h](benchmark::State& st) { runRepair(st, w, h, 1, true); })
        ->Unit(benchmark::kMillisecond)->UseRealTime();
    benchmark::RegisterBenchmark(("repair.floor.copy" + tag).c_str(), [w, h](benchmark::State& st) { copyFloor(st, w, h); })
        ->Unit(benchmark::kMillisecond)->UseRealTime();
  }
}

const bool registered = (registerAll(), true);

}  // namespace
