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
#include <utility>

#include "bench_common.h"
#include "filters/fxaa.h"

namespace {

namespace bench = crisp::bench;
using crisp::Image;

// Uniform noise in [0, 1), alpha included, built once per size.
const Image& noiseImage(int width, int height) {
  static std::map<std::pair<int, int>, Image> cache;
  auto key = std::make_pair(width, height);
  auto it = cache.find(key);
  if (it != cache.end()) return it->second;
  Image im(width, height, 4, 1.0f);
  std::mt19937 rng(7);
  std::uniform_real_distribution<float> unit(0.0f, 1.0f);
  for (float& v : im.data) v = unit(rng);
  return cache.emplace(key, std::move(im)).first->second;
}

// One benchmark: threads (0 = all), the scalar reference path or the fast
// one, test chart or noise.
struct Variant {
  const char* name;
  int threads;
  bool reference, noise;
};

void runFxaa(benchmark::State& state, int width, int height, const Variant& v) {
  const Image& in = v.noise ? noiseImage(width, height) : bench::testChartImage(width, height);
  Image output(width, height, 4);
  crisp::Context context;
  auto filter = bench::committedFilter(context, "fxaa", in, output, v.threads, v.reference);
  bench::executeLoop(state, *filter, output);
  crisp::fxaa::Workspace ws;
  ws.allocate(width, height);
  crisp::fxaa::runFast(in.view(), output.view(), crisp::fxaa::Settings{}, ws, v.threads);
  state.counters["searched_fraction"] = double(ws.searchedPixels()) / (double(width) * height);
  bench::setPixelRate(state, width, height);
}

void registerAll() {
  const Variant variants[] = {{"fxaa.fast.mt", 0, false, false},
                              {"fxaa.fast.st", 1, false, false},
                              {"fxaa.reference", 1, true, false},
                              {"fxaa.fast.mt.noise", 0, false, true},
                              {"fxaa.fast.st.noise", 1, false, true}};
  bench::registerVariants(variants, runFxaa);
}

const bool registered = (registerAll(), true);

}  // namespace
