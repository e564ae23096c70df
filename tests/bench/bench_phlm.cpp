// SPDX-License-Identifier: Apache-2.0
// PHLM benchmarks: the whole "phlm" filter through the Filter interface, one
// frame per iteration, alternating two pre-rendered frames of a camera pan
// (every pixel moves 0.7 px right, 0.3 px down per frame: every pixel takes
// the reprojected path with its feature and model fetches, the worst case)
// with colour, motion and depth; and a still scene without motion and depth
// (in-place update, no reprojection work). Variants: fast.mt (all threads),
// fast.st (one thread), reference (scalar path), bilinear.fast.mt (the pan
// with the bilinear model fetch and its damping, modelFetch=bilinear:
// resampleDamping=0.3: the fetch itself in the same run; it still keeps and
// writes the intercept planes, so it is not the code before them). Wall
// time is the reported time; process CPU time (all threads) is measured too
// (MeasureProcessCPUTime). Counters: kept_MB = state kept between frames
// (with motion, the intercept planes too), scratch_MB = staged frame. The
// memory-copy floor of the same run is floor.memcpy_rgba (bench_floor.cpp).
#include <benchmark/benchmark.h>

#include <string>

#include "bench_common.h"
#include "filters/phlm.h"

namespace {

namespace bench = crisp::bench;
using Variant = crisp::bench::TemporalVariant;

void runPhlm(benchmark::State& state, int width, int height, const Variant& v) {
  bench::runTemporal(state, width, height, "phlm", v);
  crisp::phlm::Kernel<float> k;
  k.allocate(width, height, v.moving, v.moving);
  bench::setMemoryCounters(state, k);
}

void registerAll() {
  const Variant variants[] = {{"phlm.fast.mt", 0, false, true},
                              {"phlm.fast.st", 1, false, true},
                              {"phlm.reference", 1, true, true},
                              {"phlm.static.fast.mt", 0, false, false},
                              {"phlm.object.fast.mt", 0, false, true, nullptr, nullptr, true},
                              // the bilinear model fetch (phlm.cpp "Model fetch")
                              {"phlm.bilinear.fast.mt", 0, false, true, nullptr,
                               "modelFetch=bilinear:resampleDamping=0.3"}};
  bench::registerVariants(variants, runPhlm, [](benchmark::internal::Benchmark* b, int width, const Variant& v) {
    b->MeasureProcessCPUTime();
    if (width > 256) b->Iterations(v.reference || v.threads == 1 ? 6 : 12)->Repetitions(3)->ReportAggregatesOnly(true);
  });
}

const bool registered = (registerAll(), true);

}  // namespace
