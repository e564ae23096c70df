// SPDX-License-Identifier: Apache-2.0
// RSAA benchmarks: the whole filter through the Filter interface on the
// synthetic test chart given geometry (each chart shape a plane facing the
// camera at its own depth, the background a far plane; sub-samples exact),
// so edge density is realistic; the fraction of resampled pixels is the
// counter `resolved_fraction`. rsaa.floor.read is the memory floor of the
// same run: reading every input once (colour, depth, normal, 8 float4
// sub-sample images) and writing the output; rsaa.floor.read.packed the same
// with the sub-samples as packed records (rsaa/subsample_record.h, 80 bytes
// per pixel), the form the library's frames hand the filter. rsaa.* run the
// filter's default (textureAA = fxaa), rsaa.none.* the thesis' RSAA alone
// (textureAA = none), both from the 8 float4 images; rsaa.packed.* the same
// from the packed records. rsaa.fxaa-part.mt is the FXAA kernel alone on the
// same colour, the part textureAA adds.
#include <benchmark/benchmark.h>

#include <cstdlib>
#include <map>
#include <memory>
#include <string>
#include <utility>

#include "bench_common.h"
#include "core/parallel.h"
#include "filters/fxaa.h"
#include "filters/rsaa.h"
#include "rsaa/offset_table.h"

namespace {

namespace bench = crisp::bench;
using crisp::Image;
namespace rsaa = crisp::rsaa;

struct Frame {
  Image color, depth, normal, sub[rsaa::kSamples];
  Image records;  // the same sub-samples as packed records
};

// Index of the topmost chart shape containing (x, y), -1 for the background.
int shapeAt(const crisp::synth::Scene& s, float x, float y) {
  for (int i = int(s.shapes.size()) - 1; i >= 0; --i)
    if (s.shapes[std::size_t(i)].contains(x, y)) return i;
  return -1;
}

const Frame& frame(int width, int height) {
  static std::map<std::pair<int, int>, std::unique_ptr<Frame>> cache;
  auto& slot = cache[{width, height}];
  if (slot) return *slot;
  slot = std::make_unique<Frame>();
  Frame& f = *slot;
  const crisp::synth::Scene scene = crisp::synth::testChart(width, height);
  f.color = crisp::synth::renderCentre(scene, width, height);
  f.depth = Image(width, height, 1);
  f.normal = Image(width, height, 3);
  for (auto& s : f.sub) s = Image(width, height, 4);
  auto depthOf = [](int shape) { return shape < 0 ? 40.0f : 10.0f + 0.5f * float(shape); };
  for (int y = 0; y < height; ++y)
    for (int x = 0; x < width; ++x) {
      *f.depth.at(x, y) = depthOf(shapeAt(scene, x + 0.5f, y + 0.5f));
      f.normal.at(x, y)[2] = 1.0f;
      for (int k = 0; k < rsaa::kSamples; ++k) {
        float* p = f.sub[k].at(x, y);
        p[2] = 1.0f;
        p[3] = depthOf(shapeAt(scene, x + 0.5f + rsaa::kTablePattern.x[k], y + 0.5f + rsaa::kTablePattern.y[k]));
      }
    }
  f.records = rsaa::packSubsamples(f.sub);
  return f;
}

// The chart's colour on a smooth sphere (radius 12, centre 20 in front of the
// camera, filling the frame's height; a plane at depth 40 behind it), depth
// and normal exact at every point: no two sub-samples share a normal, so the
// packed path's flat-face shortcut never applies (its worst case; real scenes
// mix flat and smooth-shaded faces).
const Frame& sphereFrame(int width, int height) {
  static std::map<std::pair<int, int>, std::unique_ptr<Frame>> cache;
  auto& slot = cache[{width, height}];
  if (slot) return *slot;
  slot = std::make_unique<Frame>();
  Frame& f = *slot;
  f = frame(width, height);  // colour, and the image shapes
  rsaa::Camera cam;
  cam.proj11 = float(width) / float(height);
  const auto geometry = [&](double px, double py, float& depth, float n[3]) {
    const double v[3] = {rsaa::rayUx(px, width, cam), rsaa::rayUy(py, height, cam), -1.0};
    const double c[3] = {0.0, 0.0, -20.0}, r = 12.0;
    const double vv = v[0] * v[0] + v[1] * v[1] + v[2] * v[2], vc = v[0] * c[0] + v[1] * c[1] + v[2] * c[2];
    const double disc = vc * vc - vv * (c[2] * c[2] - r * r);  // |t v - c|^2 = r^2
    if (disc < 0) {
      depth = 40.0f, n[0] = n[1] = 0.0f, n[2] = 1.0f;
      return;
    }
    const double t = (vc - std::sqrt(disc)) / vv;  // nearest hit; planar depth = t (v.z = -1)
    depth = float(t);
    for (int k = 0; k < 3; ++k) n[k] = float((t * v[k] - c[k]) / r);
  };
  for (int y = 0; y < height; ++y)
    for (int x = 0; x < width; ++x) {
      geometry(x + 0.5, y + 0.5, *f.depth.at(x, y), f.normal.at(x, y));
      for (int k = 0; k < rsaa::kSamples; ++k) {
        float* p = f.sub[k].at(x, y);
        geometry(x + 0.5 + rsaa::kTablePattern.x[k], y + 0.5 + rsaa::kTablePattern.y[k], p[3], p);
      }
    }
  f.records = rsaa::packSubsamples(f.sub);
  return f;
}

void runRsaa(benchmark::State& state, int width, int height, int threads, bool reference,
             const char* textureAA = "fxaa", bool packed = false, bool sphere = false) {
  const Frame& f = sphere ? sphereFrame(width, height) : frame(width, height);
  Image output(width, height, 4);
  crisp::Context context;
  auto filter = bench::newFilter(context, "rsaa", output, threads, reference);
  filter->params().setString("textureAA", textureAA);
  filter->setImage("color", f.color.view());
  filter->setImage("depth", f.depth.view());
  filter->setImage("normal", f.normal.view());
  if (packed)
    filter->setImage("subsamples", f.records.view());
  else
    for (int k = 0; k < rsaa::kSamples; ++k) filter->setImage("sub" + std::to_string(k), f.sub[k].view());
  filter->params().setFloat("proj00", 1.0f);
  filter->params().setFloat("proj11", float(width) / float(height));
  filter->commit();
  bench::executeLoop(state, *filter, output);
  bench::setPixelRate(state, width, height);
  // CRISP_BENCH_PROFILE=1: nothing but the filter runs on the worker threads
  // (callgrind --separate-threads=yes counts exactly the executions).
  if (std::getenv("CRISP_BENCH_PROFILE")) return;
  rsaa::Kernel kernel;
  rsaa::Settings settings;
  settings.camera.proj11 = float(width) / float(height);
  kernel.allocate(width, height, settings);
  rsaa::Inputs in;
  in.color = f.color.view();
  in.depth = f.depth.view();
  in.normal = f.normal.view();
  for (int k = 0; k < rsaa::kSamples; ++k) in.sub[k] = f.sub[k].view();
  if (packed) in.packed = f.records.view();
  Image scratch(width, height, 4);
  kernel.run(in, scratch.view(), false, threads);
  state.counters["resolved_fraction"] = double(kernel.resolvedCount()) / (double(width) * height);
}

// The FXAA kernel alone on the frame's colour (what textureAA = fxaa adds).
void runFxaaPart(benchmark::State& state, int width, int height) {
  const Frame& f = frame(width, height);
  Image output(width, height, 4);
  crisp::fxaa::Workspace ws;
  ws.allocate(width, height);
  for (auto _ : state) {
    crisp::fxaa::runFast(f.color.view(), output.view(), crisp::fxaa::Settings(), ws, 0);
    benchmark::DoNotOptimize(output.data.data());
  }
  bench::setPixelRate(state, width, height);
}

// Reads every input float once and writes the output: the memory floor, on
// one thread or (threads = 0) on all cores through parallelRows as the filter.
// packed: the sub-samples from the packed records (one float of every 16
// bytes, as the float4 floor reads two of each float4) instead of the 8
// float4 images.
void readFloor(benchmark::State& state, int width, int height, int threads = 1, bool packed = false) {
  const Frame& f = frame(width, height);
  Image output(width, height, 4);
  const std::size_t n = std::size_t(width) * std::size_t(height);
  const auto rows = [&](int y0, int y1) {
    for (std::size_t i = std::size_t(y0) * std::size_t(width); i < std::size_t(y1) * std::size_t(width); ++i) {
      float s = f.depth.data[i] + f.normal.data[3 * i];
      if (packed) {
        const float* r = f.records.data.data() + std::size_t(crisp::kRsaaSubsampleWords) * i;
        for (int w = 0; w < crisp::kRsaaSubsampleWords; w += 4) s += r[w];
      } else {
        for (int k = 0; k < rsaa::kSamples; ++k) s += f.sub[k].data[4 * i + 3] + f.sub[k].data[4 * i];
      }
      for (int c = 0; c < 4; ++c) output.data[4 * i + std::size_t(c)] = f.color.data[4 * i + std::size_t(c)] + s;
    }
  };
  for (auto _ : state) {
    if (threads == 1)
      rows(0, height);
    else
      crisp::parallelRows(width, height, threads, rows);
    benchmark::ClobberMemory();
  }
  const std::size_t subBytes = packed ? sizeof(rsaa::SubsampleRecord) : rsaa::kSamples * 16;
  const std::size_t bytes = n * (4 * 4 + 4 + 12 + subBytes + 4 * 4);
  state.SetBytesProcessed(int64_t(state.iterations()) * int64_t(bytes));
}

void registerAll() {
  for (const auto& s : bench::kSizes) {
    const int w = s[0], h = s[1];
    const std::string tag = bench::sizeTag(w, h);
    bench::registerTimed("rsaa.fast.mt" + tag, [w, h](benchmark::State& st) { runRsaa(st, w, h, 0, false); });
    bench::registerTimed("rsaa.fast.st" + tag, [w, h](benchmark::State& st) { runRsaa(st, w, h, 1, false); });
    // The SSE fast path on a CPU where the AVX2 one would be chosen (same output).
    bench::registerTimed("rsaa.fast.sse.st" + tag, [w, h](benchmark::State& st) {
      rsaa::setSimdLanesForTesting(4);
      runRsaa(st, w, h, 1, false);
      rsaa::setSimdLanesForTesting(0);
    });
    bench::registerTimed("rsaa.reference" + tag, [w, h](benchmark::State& st) { runRsaa(st, w, h, 1, true); });
    bench::registerTimed("rsaa.none.fast.mt" + tag,
                         [w, h](benchmark::State& st) { runRsaa(st, w, h, 0, false, "none"); });
    bench::registerTimed("rsaa.none.fast.st" + tag,
                         [w, h](benchmark::State& st) { runRsaa(st, w, h, 1, false, "none"); });
    bench::registerTimed("rsaa.none.reference" + tag,
                         [w, h](benchmark::State& st) { runRsaa(st, w, h, 1, true, "none"); });
    bench::registerTimed("rsaa.fxaa-part.mt" + tag, [w, h](benchmark::State& st) { runFxaaPart(st, w, h); });
    bench::registerTimed("rsaa.floor.read" + tag, [w, h](benchmark::State& st) { readFloor(st, w, h); });
    bench::registerTimed("rsaa.floor.read.mt" + tag, [w, h](benchmark::State& st) { readFloor(st, w, h, 0); });
    // The same filters and floor from the packed records.
    bench::registerTimed("rsaa.packed.fast.mt" + tag,
                         [w, h](benchmark::State& st) { runRsaa(st, w, h, 0, false, "fxaa", true); });
    bench::registerTimed("rsaa.packed.fast.st" + tag,
                         [w, h](benchmark::State& st) { runRsaa(st, w, h, 1, false, "fxaa", true); });
    bench::registerTimed("rsaa.packed.reference" + tag,
                         [w, h](benchmark::State& st) { runRsaa(st, w, h, 1, true, "fxaa", true); });
    bench::registerTimed("rsaa.packed.none.fast.mt" + tag,
                         [w, h](benchmark::State& st) { runRsaa(st, w, h, 0, false, "none", true); });
    bench::registerTimed("rsaa.packed.none.fast.st" + tag,
                         [w, h](benchmark::State& st) { runRsaa(st, w, h, 1, false, "none", true); });
    bench::registerTimed("rsaa.floor.read.packed" + tag,
                         [w, h](benchmark::State& st) { readFloor(st, w, h, 1, true); });
    bench::registerTimed("rsaa.floor.read.packed.mt" + tag,
                         [w, h](benchmark::State& st) { readFloor(st, w, h, 0, true); });
    // Smooth geometry (sphereFrame): no flat-face shortcut.
    bench::registerTimed("rsaa.sphere.packed.fast.mt" + tag,
                         [w, h](benchmark::State& st) { runRsaa(st, w, h, 0, false, "fxaa", true, true); });
    bench::registerTimed("rsaa.sphere.packed.none.fast.mt" + tag,
                         [w, h](benchmark::State& st) { runRsaa(st, w, h, 0, false, "none", true, true); });
    bench::registerTimed("rsaa.sphere.none.fast.mt" + tag,
                         [w, h](benchmark::State& st) { runRsaa(st, w, h, 0, false, "none", false, true); });
  }
}

// The eval's 480x270, for instruction counts under callgrind (the 1080p
// chart takes minutes to build there): the RSAA test alone from each layout.
void registerProfileSize() {
  constexpr int w = 480, h = 270;  // constants: the lambdas need no capture
  const std::string tag = bench::sizeTag(w, h);
  bench::registerTimed("rsaa.none.fast.st" + tag, [](benchmark::State& st) { runRsaa(st, w, h, 1, false, "none"); });
  bench::registerTimed("rsaa.packed.none.fast.st" + tag,
                       [](benchmark::State& st) { runRsaa(st, w, h, 1, false, "none", true); });
  bench::registerTimed("rsaa.fast.st" + tag, [](benchmark::State& st) { runRsaa(st, w, h, 1, false); });
  bench::registerTimed("rsaa.packed.fast.st" + tag,
                       [](benchmark::State& st) { runRsaa(st, w, h, 1, false, "fxaa", true); });
  bench::registerTimed("rsaa.sphere.none.fast.st" + tag,
                       [](benchmark::State& st) { runRsaa(st, w, h, 1, false, "none", false, true); });
  bench::registerTimed("rsaa.sphere.packed.none.fast.st" + tag,
                       [](benchmark::State& st) { runRsaa(st, w, h, 1, false, "none", true, true); });
}

const bool registered = (registerAll(), registerProfileSize(), true);

}  // namespace
