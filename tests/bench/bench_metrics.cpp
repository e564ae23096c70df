// SPDX-License-Identifier: Apache-2.0
// Metric benchmarks on the synthetic test chart: reference = 1 sample at the
// pixel centres, test = 1 jittered sample (a realistic aliased difference).
//  metrics.psnr    compareImages with SSIM and FLIP off: display encoding of
//                  both frames + MSE/RMSE/PSNR/SNR
//  metrics.ssim    the same + SSIM
//  metrics.flip    flipErrorMap alone, on already encoded frames
//  metrics.compare everything (what `crisp compare` runs per frame)
//  .st = 1 thread, .mt = all threads. The memory-copy floor of the same run
//  is floor.memcpy_rgba (bench_floor.cpp).
#include <benchmark/benchmark.h>

#include <map>
#include <string>
#include <utility>

#include "bench_common.h"
#include "metrics/flip.h"
#include "metrics/metrics.h"

namespace {

namespace bench = crisp::bench;
using crisp::Image;

struct Pair {
  Image reference, test, referenceSrgb, testSrgb;
};

const Pair& frames(int width, int height) {
  static std::map<std::pair<int, int>, Pair> cache;
  auto key = std::make_pair(width, height);
  auto it = cache.find(key);
  if (it == cache.end()) {
    Pair p;
    p.reference = bench::testChartImage(width, height);
    p.test = crisp::synth::renderCentre(crisp::synth::testChart(width, height), width, height, 0.3f, -0.2f);
    p.referenceSrgb = crisp::displayEncode(p.reference);
    p.testSrgb = crisp::displayEncode(p.test);
    it = cache.emplace(key, std::move(p)).first;
  }
  return it->second;
}

void runCompare(benchmark::State& state, int width, int height, int threads, bool ssim, bool flip) {
  const Pair& p = frames(width, height);
  crisp::CompareOptions options;
  options.ssim = ssim;
  options.flip = flip;
  for (auto _ : state) {
    crisp::Metrics m = crisp::compareImages(p.reference, p.test, nullptr, {}, threads, options);
    benchmark::DoNotOptimize(m);
  }
  bench::setPixelRate(state, width, height);
}

void runFlip(benchmark::State& state, int width, int height, int threads) {
  const Pair& p = frames(width, height);
  for (auto _ : state) {
    Image map = crisp::flipErrorMap(p.referenceSrgb, p.testSrgb, 67.0f, threads);
    benchmark::DoNotOptimize(map.data.data());
  }
  bench::setPixelRate(state, width, height);
}

void registerAll() {
  for (const auto& s : bench::kSizes) {
    const int w = s[0], h = s[1];
    const std::string tag = bench::sizeTag(w, h);
    for (int threads : {1, 0}) {
      const std::string mode = threads == 1 ? ".st" : ".mt";
      bench::registerTimed("metrics.psnr" + mode + tag,
                           [=](benchmark::State& st) { runCompare(st, w, h, threads, false, false); });
      bench::registerTimed("metrics.ssim" + mode + tag,
                           [=](benchmark::State& st) { runCompare(st, w, h, threads, true, false); });
      bench::registerTimed("metrics.flip" + mode + tag, [=](benchmark::State& st) { runFlip(st, w, h, threads); });
      bench::registerTimed("metrics.compare" + mode + tag,
                           [=](benchmark::State& st) { runCompare(st, w, h, threads, true, true); });
    }
  }
}

const bool registered = (registerAll(), true);

}  // namespace
