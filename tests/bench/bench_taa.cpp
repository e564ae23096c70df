// SPDX-License-Identifier: Apache-2.0
// TAA benchmarks: the whole filter through the Filter interface, one frame per
// iteration, alternating two pre-rendered frames of a camera pan (every pixel
// moves 0.7 px right, 0.3 px down per frame: every pixel takes the reprojected,
// clipped path, the worst case) with colour, motion and depth. Variants: the
// history fetch (Catmull-Rom default, bilinear), and a still scene without
// motion and depth (the static accumulation path, no reprojection work), and
// the fast path's x86-64 baseline (SSE2) row loop where AVX2 exists (.sse2),
// its AVX2 copy where AVX-512 exists (.avx2; the default runs the widest copy
// the CPU has, temporal/isa.h), and the defaults before the RGB box, variance
// clipping and the hold.
// Counters: kept_MB = memory kept between frames (history), scratch_MB = the
// fast path's per-band row rings. The memory-copy floor of the same run is floor.memcpy_rgba
// (bench_floor.cpp).
#include <benchmark/benchmark.h>

#include <string>

#include "bench_common.h"
#include "filters/taa.h"
#include "temporal/isa.h"

namespace {

namespace bench = crisp::bench;
using Variant = crisp::bench::TemporalVariant;

void runTaa(benchmark::State& state, int width, int height, const Variant& v) {
  bench::runTemporal(state, width, height, "taa", v);
  crisp::taa::Kernel k;
  k.allocate(width, height, v.moving);  // depth planes only when depth is given
  bench::setMemoryCounters(state, k);
}

// The same with the baseline or the AVX2 copy of the row loop (temporal/isa.h).
void runTaaBaselineRows(benchmark::State& state, int width, int height, const Variant& v) {
  crisp::temporal::setFastPathIsa(crisp::temporal::Isa::Baseline);
  runTaa(state, width, height, v);
  crisp::temporal::setFastPathIsa(crisp::temporal::Isa::Auto);
}
void runTaaAvx2Rows(benchmark::State& state, int width, int height, const Variant& v) {
  crisp::temporal::setFastPathIsa(crisp::temporal::Isa::Avx2);
  runTaa(state, width, height, v);
  crisp::temporal::setFastPathIsa(crisp::temporal::Isa::Auto);
}

void registerAll() {
  // The row copy the default variants run, in the run's header.
  benchmark::AddCustomContext("temporal_rows", crisp::temporal::fastPathIsaName());
  const Variant variants[] = {{"taa.rgb_motion_depth.fast.mt", 0, false, true, "catmull-rom"},
                              {"taa.rgb_motion_depth.fast.st", 1, false, true, "catmull-rom"},
                              {"taa.rgb_motion_depth.reference", 1, true, true, "catmull-rom"},
                              {"taa.rgb_motion_depth.bilinear.fast.mt", 0, false, true, "bilinear"},
                              {"taa.rgb_static.fast.mt", 0, false, false, "catmull-rom"},
                              {"taa.rgb_object_depth.fast.mt", 0, false, true, "catmull-rom", nullptr, true},
                              // The defaults before the RGB box, variance clipping, resampling damping and the hold (7ba9b04):
                              // the same run's baseline for what those cost.
                              {"taa.rgb_motion_depth.ycocg_minmax.fast.mt", 0, false, true, "catmull-rom",
                               "clipSpace=ycocg:varianceClip=0:resampleDamping=0"},
                              {"taa.rgb_static.ycocg_nohold.fast.mt", 0, false, false, "catmull-rom",
                               "clipSpace=ycocg:holdPeriod=0"}};
  bench::registerVariants(variants, runTaa);
  const Variant baseline[] = {{"taa.rgb_motion_depth.fast.st.sse2", 1, false, true, "catmull-rom"}};
  bench::registerVariants(baseline, runTaaBaselineRows);
  const Variant avx2[] = {{"taa.rgb_motion_depth.fast.mt.avx2", 0, false, true, "catmull-rom"},
                          {"taa.rgb_motion_depth.fast.st.avx2", 1, false, true, "catmull-rom"},
                          {"taa.rgb_static.fast.mt.avx2", 0, false, false, "catmull-rom"},
                          {"taa.rgb_object_depth.fast.mt.avx2", 0, false, true, "catmull-rom", nullptr, true}};
  bench::registerVariants(avx2, runTaaAvx2Rows);
}

const bool registered = (registerAll(), true);

}  // namespace
