// SPDX-License-Identifier: Apache-2.0
// taa-improved benchmarks: the whole filter through the Filter interface, one
// frame per iteration, alternating two frames of a camera pan (every pixel
// moves 0.7 px right, 0.3 px down) with colour, motion, depth, object ids and
// an albedo layer (the colour itself), so every pass runs; .object is the
// still camera with three moving shapes instead (bench_common.h chartFrames),
// as taa.rgb_object_depth and phlm.object; .avx2 runs taa's rows and the
// aliasedValue bands in their AVX2 copies where the CPU has AVX-512
// (temporal/isa.h). Counters as in bench_taa.cpp (kept_MB, scratch_MB); the
// floor is floor.memcpy_rgba.
#include <benchmark/benchmark.h>

#include <string>

#include "bench_common.h"
#include "filters/taa_improved.h"
#include "temporal/isa.h"

namespace {

namespace bench = crisp::bench;
using crisp::synth::FrameData;

// One benchmark: threads (0 = all), the scalar reference path or the fast one,
// the camera pan or a still camera with a few moving shapes.
struct Variant {
  const char* name;
  int threads;
  bool reference;
  bool objectOnly = false;
  crisp::temporal::Isa isa = crisp::temporal::Isa::Auto;
};

void runImproved(benchmark::State& state, int width, int height, const Variant& v) {
  crisp::temporal::setFastPathIsa(v.isa);
  crisp::Image output(width, height, 4);
  crisp::Context context;
  auto filter = bench::newFilter(context, "taa-improved", output, v.threads, v.reference);
  bench::temporalLoop(state, *filter, output, bench::chartFrames(width, height, v.objectOnly), [&](const FrameData& f) {
    filter->setImage("color", f.color.view());
    filter->setImage("motion", f.motion.view());
    filter->setImage("depth", f.depth.view());
    filter->setImage("id", f.id.view());
    filter->setImage("albedo", f.color.view());
  });
  crisp::taa_improved::Kernel k;
  k.allocate(width, height, true);
  bench::setMemoryCounters(state, k);
  bench::setPixelRate(state, width, height);
  crisp::temporal::setFastPathIsa(crisp::temporal::Isa::Auto);
}

void registerAll() {
  const Variant variants[] = {{"taa-improved.all_inputs.fast.mt", 0, false},
                              {"taa-improved.all_inputs.fast.st", 1, false},
                              {"taa-improved.object.fast.mt", 0, false, true},
                              {"taa-improved.all_inputs.reference", 1, true},
                              {"taa-improved.all_inputs.fast.mt.avx2", 0, false, false, crisp::temporal::Isa::Avx2},
                              {"taa-improved.object.fast.mt.avx2", 0, false, true, crisp::temporal::Isa::Avx2}};
  bench::registerVariants(variants, runImproved);
}

const bool registered = (registerAll(), true);

}  // namespace
