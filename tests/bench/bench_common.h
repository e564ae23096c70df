// SPDX-License-Identifier: Apache-2.0
// Set-up shared by the filter benchmarks: the frame sizes and registration,
// the cached synthetic test chart and camera-pan frames, a filter set up
// through the Filter interface, the benchmark loops (single frame and
// temporal), and the counters.
#pragma once

#include <benchmark/benchmark.h>

#include <cstddef>
#include <map>
#include <memory>
#include <string>
#include <tuple>
#include <utility>

#include "core/context.h"
#include "core/filter.h"
#include "synth/moving.h"
#include "synth/synthetic.h"

namespace crisp::bench {

// Every filter benchmark runs at these sizes: a full HD frame and a tiny one
// (per-call overhead).
constexpr int kSizes[2][2] = {{1920, 1080}, {64, 64}};

inline std::string sizeTag(int width, int height) {
  return "/" + std::to_string(width) + "x" + std::to_string(height);
}

// Registers `run` as benchmark `name`, timed in milliseconds of wall time (the
// filters run on several threads).
template <class Run>
benchmark::internal::Benchmark* registerTimed(const std::string& name, Run run) {
  return benchmark::RegisterBenchmark(name.c_str(), std::move(run))->Unit(benchmark::kMillisecond)->UseRealTime();
}

// Registers run(state, width, height, variant) as "<variant.name>/<width>x<height>"
// for every size (outer loop) and variant, timed as registerTimed, then calls
// tune(benchmark, width, variant) for any per-variant options.
template <class Variant, std::size_t N, class Run, class Tune>
void registerVariants(const Variant (&variants)[N], Run run, Tune tune) {
  for (const auto& size : kSizes)
    for (const Variant& v : variants) {
      const int w = size[0], h = size[1];
      auto* b = registerTimed(v.name + sizeTag(w, h), [w, h, v, run](benchmark::State& state) { run(state, w, h, v); });
      tune(b, w, v);
    }
}

template <class Variant, std::size_t N, class Run>
void registerVariants(const Variant (&variants)[N], Run run) {
  registerVariants(variants, run, [](benchmark::internal::Benchmark*, int, const Variant&) {});
}

// The 1-sample render of synth::testChart (realistic edge density), built
// once per size.
inline const Image& testChartImage(int width, int height) {
  static std::map<std::pair<int, int>, Image> cache;
  auto key = std::make_pair(width, height);
  auto it = cache.find(key);
  if (it == cache.end())
    it = cache.emplace(key, synth::renderCentre(synth::testChart(width, height), width, height)).first;
  return it->second;
}

using FramePair = std::pair<synth::FrameData, synth::FrameData>;

// Frames 1 and 2 of a camera pan over the test chart (colour, motion, depth,
// ids; no reference): every pixel moves 0.7 px right and 0.3 px down per
// frame, so every pixel of a temporal filter takes the reprojected path (the
// worst case). Built once per size.
// With objectOnly, the still-camera case instead (a turntable, the ghosting
// scene): the background and all but `kMovingShapes` of the chart's shapes
// stay; those move as above.
inline const FramePair& chartFrames(int width, int height, bool objectOnly) {
  static std::map<std::tuple<int, int, bool>, FramePair> cache;
  auto key = std::make_tuple(width, height, objectOnly);
  auto it = cache.find(key);
  if (it != cache.end()) return it->second;
  synth::Sequence seq = synth::staticChartSequence(width, height);
  constexpr std::size_t kMovingShapes = 3;
  for (std::size_t i = 0; i < seq.before.shapes.size(); ++i) {
    if (objectOnly && i >= kMovingShapes) break;
    seq.before.shapes[i].vx = 0.7f;
    seq.before.shapes[i].vy = 0.3f;
  }
  if (!objectOnly) {
    seq.before.backgroundVx = 0.7f;
    seq.before.backgroundVy = 0.3f;
  }
  synth::FrameOptions opt;
  opt.reference = synth::ReferenceKind::None;
  FramePair pair(synth::renderFrame(seq, width, height, 1, opt), synth::renderFrame(seq, width, height, 2, opt));
  return cache.emplace(key, std::move(pair)).first->second;
}
inline const FramePair& panFrames(int width, int height) { return chartFrames(width, height, false); }

// One benchmark of a temporal filter ("taa", "phlm"): threads (0 = all), the
// scalar reference path or the fast one, camera pan (motion and depth given)
// or still scene, and for taa the history fetch.
struct TemporalVariant {
  const char* name;
  int threads;
  bool reference, moving;
  const char* historyFilter = nullptr;
  const char* params = nullptr;  // more parameters, "name=value:name=value" (a baseline of earlier defaults)
  bool objectOnly = false;       // with moving: still camera, a few shapes move (chartFrames)
};

// A filter of `type` writing to `output` (kept alive by the caller) on
// `threads` threads, with the optional `reference` parameter; its inputs are
// the caller's to set, then commit.
inline std::unique_ptr<Filter> newFilter(Context& context, const char* type, Image& output, int threads,
                                         bool reference) {
  context.setInt("numThreads", threads);
  auto filter = createFilter(context, type);
  filter->setImage("output", output.view());
  filter->params().setBool("reference", reference);
  return filter;
}

// A committed filter of `type` from `input` to `output` (both kept alive by
// the caller) on `threads` threads, with the optional `reference` parameter.
inline std::unique_ptr<Filter> committedFilter(Context& context, const char* type, const Image& input, Image& output,
                                               int threads, bool reference) {
  auto filter = newFilter(context, type, output, threads, reference);
  filter->setImage("color", input.view());
  filter->commit();
  return filter;
}

// pixels_per_s: one frame of width x height per iteration.
inline void setPixelRate(benchmark::State& state, int width, int height) {
  state.counters["pixels_per_s"] =
      benchmark::Counter(double(width) * height, benchmark::Counter::kIsIterationInvariantRate);
}

// The benchmark loop over Filter::execute.
inline void executeLoop(benchmark::State& state, Filter& filter, Image& output) {
  for (auto _ : state) {
    filter.execute();
    benchmark::DoNotOptimize(output.data.data());
    benchmark::ClobberMemory();
  }
}

// The benchmark loop of a temporal filter, one frame per iteration, driven as
// a real caller drives it. Frame `a` makes the history before the loop; the
// iterations then alternate b, a, b, ..., re-committing each frame for its
// new jitter (which allocates nothing). `setInputs(frame)` points the filter
// at that frame's images (same shape: no re-commit needed for them).
template <class SetInputs>
void temporalLoop(benchmark::State& state, Filter& filter, Image& output, const FramePair& frames,
                  SetInputs setInputs) {
  const auto& [a, b] = frames;
  setInputs(a);
  filter.commit();
  filter.execute();  // history exists from here on
  bool odd = false;
  for (auto _ : state) {
    const synth::FrameData& f = odd ? a : b;
    setInputs(f);
    filter.params().setFloat("jitterX", f.jitter.x);
    filter.params().setFloat("jitterY", f.jitter.y);
    filter.markDirty("the jitter was set");
    filter.commit();
    filter.execute();
    odd = !odd;
    benchmark::DoNotOptimize(output.data.data());
    benchmark::ClobberMemory();
  }
}

// A temporal filter of `type` ("taa", "phlm") on the camera pan, colour with
// motion and depth when v.moving; counts the pixel rate.
inline void runTemporal(benchmark::State& state, int width, int height, const char* type, const TemporalVariant& v) {
  Image output(width, height, 4);
  Context context;
  auto filter = newFilter(context, type, output, v.threads, v.reference);
  if (v.historyFilter) filter->params().setString("historyFilter", v.historyFilter);
  for (std::string rest = v.params ? v.params : ""; !rest.empty();) {
    const std::size_t end = rest.find(':'), eq = rest.find('=');
    const std::string item = rest.substr(0, end);
    filter->params().setFromText(item.substr(0, eq), item.substr(eq + 1));
    rest = end == std::string::npos ? "" : rest.substr(end + 1);
  }
  const FramePair& frames = chartFrames(width, height, v.objectOnly);
  temporalLoop(state, *filter, output, frames, [&](const synth::FrameData& f) {
    filter->setImage("color", f.color.view());
    if (v.moving) {
      filter->setImage("motion", f.motion.view());
      filter->setImage("depth", f.depth.view());
    }
  });
  setPixelRate(state, width, height);
  if (v.moving) {  // the share of pixels whose motion is not zero
    std::size_t moving = 0;
    for (std::size_t i = 0; i < frames.second.motion.data.size(); i += 2)
      moving += frames.second.motion.data[i] != 0.0f || frames.second.motion.data[i + 1] != 0.0f;
    state.counters["moving_pct"] = 100.0 * double(moving) / (double(width) * height);
  }
}

// kept_MB = the memory a temporal kernel keeps between frames (history or
// state), scratch_MB = its scratch, from a kernel allocated like the filter's.
template <class Kernel>
void setMemoryCounters(benchmark::State& state, const Kernel& kernel) {
  state.counters["kept_MB"] = double(kernel.bytesKeptBetweenFrames()) / 1e6;
  state.counters["scratch_MB"] = double(kernel.bytesScratch()) / 1e6;
}

}  // namespace crisp::bench
