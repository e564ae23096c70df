// SPDX-License-Identifier: Apache-2.0
// The memory-copy floor of this machine, measured in the same run as the
// filters: copying one RGBA float frame (read + write of 16 bytes per pixel),
// which every filter must do at least once. bytes_per_second counts both.
#include <benchmark/benchmark.h>

#include <cstring>
#include <vector>

#include "bench_common.h"

namespace {

namespace bench = crisp::bench;

void memcpyRgba(benchmark::State& state, int width, int height) {
  const std::size_t floats = std::size_t(width) * std::size_t(height) * 4;
  std::vector<float> source(floats), destination(floats);
  for (std::size_t i = 0; i < floats; ++i) source[i] = float(i % 1024) * (1.0f / 1024.0f);
  for (auto _ : state) {
    std::memcpy(destination.data(), source.data(), floats * sizeof(float));
    benchmark::DoNotOptimize(destination.data());
    benchmark::ClobberMemory();
  }
  state.SetBytesProcessed(int64_t(state.iterations()) * int64_t(floats * sizeof(float)) * 2);
}

void registerAll() {
  for (const auto& s : bench::kSizes) {
    const int w = s[0], h = s[1];
    bench::registerTimed("floor.memcpy_rgba" + bench::sizeTag(w, h),
                         [w, h](benchmark::State& st) { memcpyRgba(st, w, h); });
  }
}

const bool registered = (registerAll(), true);

}  // namespace
