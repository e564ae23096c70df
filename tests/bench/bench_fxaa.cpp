// SPDX-License-Identifier: Apache-2.0
// FXAA benchmarks: the whole filter through the Filter interface (luma plane,
// contrast check, search, output), on the synthetic test chart (realistic
// edge density) and on uniform noise (worst case: nearly every pixel passes
// the contrast check and runs the end-of-edge search). The counter
// `searched_fraction` is the share of pixels that ran the search.
// The memory-copy floor of the same run is floor.memcpy_rgba (bench_floor.cpp).
#include <benchmark/benchmark.h>

#include <map>
#include <random>
#include <string>
#include <tuple>

#include "core/context.h"
#include "core/filter.h"
#include "filters/fxaa.h"
#include "synth/synthetic.h"

namespace {

using crisp::Image;

const Image& input(int width, int height, bool noise) {
  static std::map<std::tuple<int, int, bool>, Image> cache;
  auto key = std::make_tuple(width, height, noise);
  auto it = cache.find(key);
  if (it != cache.end()) return it->second;
  Image im;
  if (noise) {
    im = Image(width, height, 4, 1.0f);
    std::mt19937 rng(7);
    std::uniform_real_distribution<float> unit(0.0f, 1.0f);
    for (float& v : im.data) v = unit(rng);
  } else {
    im = crisp::synth::renderCentre(crisp::synth::testChart(width, height), width, height);
  }
  return cache.emplace(key, std::move(im)).first->second;
}

void runFxaa(benchmark::State& state, int width, int height, int threads, bool reference, bool noise) {
  const Image& in = input(width, height, noise);
  Image output(width, height, 4);
  crisp::Context context;
  context.setInt("numThreads", threads);
  auto filter = crisp::createFilter(context, "fxaa");
  filter->setImage("color", in.view());
  filter->setImage("output", output.view());
  filter->params().setBool("reference", reference);
  filter->commit();
  for (auto _ : state) {
    filter->execute();
    benchmark::DoNotOptimize(output.data.data());
    benchmark::ClobberMemory();
  }
  crisp::fxaa::Workspace ws;
  ws.allocate(width, height);
  crisp::fxaa::runFast(in.view(), output.view(), crisp::fxaa::Settings{}, ws, threads);
  state.counters["searched_fraction"] = double(ws.searchedPixels()) / (double(width) * height);
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
      bool reference, noise;
    };
    const Variant variants[] = {{"fxaa.fast.mt", 0, false, false},
                                {"fxaa.fast.st", 1, false, false},
                                {"fxaa.reference", 1, true, false},
                                {"fxaa.fast.mt.noise", 0, false, true},
                                {"fxaa.fast.st.noise", 1, false, true}};
    for (const Variant& v : variants)
      benchmark::RegisterBenchmark((v.name + tag).c_str(),
                                   [w, h, v](benchmark::State& st) { runFxaa(st, w, h, v.threads, v.reference, v.noise); })
          ->Unit(benchmark::kMillisecond)
          ->UseRealTime();
  }
}

const bool registered = (registerAll(), true);

}  // namespace
