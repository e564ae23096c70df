// SPDX-License-Identifier: Apache-2.0
// Metric benchmarks on the synthetic test chart: reference = 1 sample at the
// pixel centres, test = 1 jittered sample (a realistic aliased difference).
//  metrics.psnr    compareImages with SSIM and FLIP off: display encoding of
//                  both frames + MSE/RMSE/PSNR/SNR
//  metrics.ssim    the same + SSIM
//  metrics.flip    flipErrorMap alone, on already encoded frames
//  metrics.compare everything (what `crisp compare` runs per frame)
//  .st = 1 thread, .mt = all threads. metrics.floor.copy is the memory-copy
//  floor in the same run: reading both RGBA float frames and writing one.
#include <benchmark/benchmark.h>

#include <cstring>
#include <map>
#include <string>
#include <utility>

#include "metrics/flip.h"
#include "metrics/metrics.h"
#include "synth/synthetic.h"

namespace {

using crisp::Image;

struct Pair {
  Image reference, test, referenceSrgb, testSrgb;
};

const Pair& frames(int width, int height) {
  static std::map<std::pair<int, int>, Pair> cache;
  auto key = std::make_pair(width, height);
  auto it = cache.find(key);
  if (it == cache.end()) {
    const crisp::synth::Scene scene = crisp::synth::testChart(width, height);
    Pair p;
    p.reference = crisp::synth::renderCentre(scene, width, height);
    p.test = crisp::synth::renderCentre(scene, width, height, 0.3f, -0.2f);
    p.referenceSrgb = crisp::displayEncode(p.reference);
    p.testSrgb = crisp::displayEncode(p.test);
    it = cache.emplace(key, std::move(p)).first;
  }
  return it->second;
}

void pixelRate(benchmark::State& state, int width, int height) {
  state.counters["pixels_per_s"] =
      benchmark::Counter(double(width) * height, benchmark::Counter::kIsIterationInvariantRate);
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
  pixelRate(state, width, height);
}

void runFlip(benchmark::State& state, int width, int height, int threads) {
  const Pair& p = frames(width, height);
  for (auto _ : state) {
    Image map = crisp::flipErrorMap(p.referenceSrgb, p.testSrgb, 67.0f, threads);
    benchmark::DoNotOptimize(map.data.data());
  }
  pixelRate(state, width, height);
}

void copyFloor(benchmark::State& state, int width, int height) {
  const Pair& p = frames(width, height);
  Image output(width, height, 4);
  const std::size_t bytes = p.reference.data.size() * sizeof(float);
  for (auto _ : state) {
    std::memcpy(output.data.data(), p.reference.data.data(), bytes);
    benchmark::ClobberMemory();
    std::memcpy(output.data.data(), p.test.data.data(), bytes);
    benchmark::ClobberMemory();
  }
  state.SetBytesProcessed(int64_t(state.iterations()) * int64_t(bytes) * 4);
}

void registerAll() {
  const int sizes[2][2] = {{1920, 1080}, {64, 64}};
  for (const auto& s : sizes) {
    const int w = s[0], h = s[1];
    const std::string tag = "/" + std::to_string(w) + "x" + std::to_string(h);
    for (int threads : {1, 0}) {
      const std::string mode = threads == 1 ? ".st" : ".mt";
      benchmark::RegisterBenchmark(("metrics.psnr" + mode + tag).c_str(),
                                   [=](benchmark::State& st) { runCompare(st, w, h, threads, false, false); })
          ->Unit(benchmark::kMillisecond)->UseRealTime();
      benchmark::RegisterBenchmark(("metrics.ssim" + mode + tag).c_str(),
                                   [=](benchmark::State& st) { runCompare(st, w, h, threads, true, false); })
          ->Unit(benchmark::kMillisecond)->UseRealTime();
      benchmark::RegisterBenchmark(("metrics.flip" + mode + tag).c_str(),
                                   [=](benchmark::State& st) { runFlip(st, w, h, threads); })
          ->Unit(benchmark::kMillisecond)->UseRealTime();
      benchmark::RegisterBenchmark(("metrics.compare" + mode + tag).c_str(),
                                   [=](benchmark::State& st) { runCompare(st, w, h, threads, true, true); })
          ->Unit(benchmark::kMillisecond)->UseRealTime();
    }
    benchmark::RegisterBenchmark(("metrics.floor.copy" + tag).c_str(), [=](benchmark::State& st) { copyFloor(st, w, h); })
        ->Unit(benchmark::kMillisecond)->UseRealTime();
  }
}

const bool registered = (registerAll(), true);

}  // namespace
