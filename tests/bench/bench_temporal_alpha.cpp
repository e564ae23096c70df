// SPDX-License-Identifier: Apache-2.0
// What a transparent render costs the temporal methods (native/filters/
// temporal_alpha.h): bench_taa.cpp's camera pan with the colour's alpha at 0.5
// on the chart's shapes, so the alpha's own taa kernel runs beside the colour's
// (compare taa.rgb_motion_depth.fast.mt and phlm.fast.mt, the opaque pan).
#include <benchmark/benchmark.h>

#include <string>

#include "bench_common.h"

namespace {

namespace bench = crisp::bench;

void transparentPan(benchmark::State& state, int width, int height, const char* type) {
  bench::FramePair frames = bench::panFrames(width, height);
  for (crisp::synth::FrameData* f : {&frames.first, &frames.second})
    for (std::size_t i = 0; i < f->depth.data.size(); ++i)
      if (f->depth.data[i] != f->depth.data[0]) f->color.data[4 * i + 3] = 0.5f;  // not the background's depth
  crisp::Image output(width, height, 4);
  crisp::Context context;
  auto filter = bench::newFilter(context, type, output, 0, false);
  bench::temporalLoop(state, *filter, output, frames, [&](const crisp::synth::FrameData& f) {
    filter->setImage("color", f.color.view());
    filter->setImage("motion", f.motion.view());
    filter->setImage("depth", f.depth.view());
  });
  bench::setPixelRate(state, width, height);
}

void registerAll() {
  for (const auto& s : bench::kSizes) {
    const int w = s[0], h = s[1];
    for (const char* type : {"taa", "phlm"})
      bench::registerTimed(std::string(type) + ".transparent.fast.mt" + bench::sizeTag(w, h),
                           [w, h, type](benchmark::State& st) { transparentPan(st, w, h, type); });
  }
}

const bool registered = (registerAll(), true);

}  // namespace
