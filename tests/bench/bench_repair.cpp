// SPDX-License-Identifier: Apache-2.0
// REPAIR benchmarks: the whole filter (stage, grey, Sobel, threshold, slope,
// rotated smoothing, output) on the synthetic test chart, whose edge density
// is realistic (cost grows with the number of edge pixels; the fraction is
// reported as the counter `edge_fraction`).
//  repair.fast.mt / .fast.st   the fast path through the Filter interface,
//                              all threads / one thread
//  repair.fast.st.sse2         the fast path on one thread with the x86-64
//                              baseline row loops even where AVX2 exists
//                              (repair::Kernel directly)
//  repair.reference            the scalar reference path, one thread
// The memory-copy floor of the same run is floor.memcpy_rgba (bench_floor.cpp).
#include <benchmark/benchmark.h>

#include <string>

#include "bench_common.h"
#include "filters/repair.h"

namespace {

namespace bench = crisp::bench;
using crisp::Image;

double edgeFraction(const Image& input, int threads) {
  crisp::repair::Kernel kernel;
  kernel.allocate(input.width, input.height);
  Image scratch(input.width, input.height, 4);
  kernel.run(input.view(), scratch.view(), crisp::repair::Settings{}, false, threads);
  return double(kernel.edgeCount()) / (double(input.width) * input.height);
}

void runRepair(benchmark::State& state, int width, int height, int threads, bool reference) {
  const Image& input = bench::testChartImage(width, height);
  Image output(width, height, 4);
  crisp::Context context;
  auto filter = bench::committedFilter(context, "repair", input, output, threads, reference);
  bench::executeLoop(state, *filter, output);
  state.counters["edge_fraction"] = edgeFraction(input, threads);
  bench::setPixelRate(state, width, height);
}

void runBaselineRows(benchmark::State& state, int width, int height) {
  const Image& input = bench::testChartImage(width, height);
  Image output(width, height, 4);
  crisp::repair::Kernel kernel;
  kernel.allocate(width, height);
  kernel.setRowIsa(crisp::repair::RowIsa::Baseline);
  for (auto _ : state) {
    kernel.run(input.view(), output.view(), crisp::repair::Settings{}, false, 1);
    benchmark::DoNotOptimize(output.data.data());
    benchmark::ClobberMemory();
  }
  state.counters["edge_fraction"] = edgeFraction(input, 1);
  bench::setPixelRate(state, width, height);
}

void registerAll() {
  for (const auto& s : bench::kSizes) {
    const int w = s[0], h = s[1];
    const std::string tag = bench::sizeTag(w, h);
    bench::registerTimed("repair.fast.mt" + tag, [w, h](benchmark::State& st) { runRepair(st, w, h, 0, false); });
    bench::registerTimed("repair.fast.st" + tag, [w, h](benchmark::State& st) { runRepair(st, w, h, 1, false); });
    bench::registerTimed("repair.fast.st.sse2" + tag, [w, h](benchmark::State& st) { runBaselineRows(st, w, h); });
    bench::registerTimed("repair.reference" + tag, [w, h](benchmark::State& st) { runRepair(st, w, h, 1, true); });
  }
}

const bool registered = (registerAll(), true);

}  // namespace
