// SPDX-License-Identifier: Apache-2.0
// Set-up shared by the filter benchmarks: the cached synthetic test chart,
// the frame sizes, a filter committed through the Filter interface, and the
// pixel-rate counter.
#pragma once

#include <benchmark/benchmark.h>

#include <map>
#include <memory>
#include <string>
#include <utility>

#include "core/context.h"
#include "core/filter.h"
#include "synth/synthetic.h"

namespace crisp::bench {

// Every filter benchmark runs at these sizes: a full HD frame and a tiny one
// (per-call overhead).
constexpr int kSizes[2][2] = {{1920, 1080}, {64, 64}};

inline std::string sizeTag(int width, int height) {
  return "/" + std::to_string(width) + "x" + std::to_string(height);
}

// The 1-sample render of synth::testChart (realistic edge density), built
// once per size.
inline const Image& testChartImage(int width, int height) {
  static std::map<std::pair<int, int>, Image> cache;
  auto key = std::make_pair(width, height);
  auto it = cache.find(key);
  if (it == cache.end())
    it = cache.emplace(key, synth::renderCentre(synth::testChart(width, height), width, height)).first;
  return it->second;
}

// A committed filter of `type` from `input` to `output` (both kept alive by
// the caller) on `threads` threads, with the optional `reference` parameter.
inline std::unique_ptr<Filter> committedFilter(Context& context, const char* type, const Image& input, Image& output,
                                               int threads, bool reference) {
  context.setInt("numThreads", threads);
  auto filter = createFilter(context, type);
  filter->setImage("color", input.view());
  filter->setImage("output", output.view());
  filter->params().setBool("reference", reference);
  filter->commit();
  return filter;
}

// The benchmark loop over Filter::execute.
inline void executeLoop(benchmark::State& state, Filter& filter, Image& output) {
  for (auto _ : state) {
    filter.execute();
    benchmark::DoNotOptimize(output.data.data());
    benchmark::ClobberMemory();
  }
}

inline void setPixelRate(benchmark::State& state, int width, int height) {
  state.counters["pixels_per_s"] =
      benchmark::Counter(double(width) * height, benchmark::Counter::kIsIterationInvariantRate);
}

}  // namespace crisp::bench
