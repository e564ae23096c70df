// SPDX-License-Identifier: Apache-2.0
// Set-up shared by the temporal filter tests (test_taa.cpp,
// test_taa_improved.cpp, test_phlm.cpp): PSNR alone, a finite check, the
// common moving sequences, and a driver feeding the frames of synth/moving.h
// to a filter one at a time.
#pragma once

#include <cmath>
#include <memory>
#include <string>
#include <vector>

#include "core/context.h"
#include "core/filter.h"
#include "metrics/metrics.h"
#include "synth/moving.h"
#include "temporal/isa.h"

namespace crisp::test {

// PSNR on one thread, with SSIM and FLIP off (not read, and slow).
inline double psnr(const Image& ref, const Image& test) {
  CompareOptions options;
  options.ssim = false;
  options.flip = false;
  return compareImages(ref, test, nullptr, {}, 1, options).psnr;
}

// Selects the temporal kernels' fast-path copy (temporal/isa.h) for its
// lifetime: fast-equals-reference tests run once per copy.
struct FastPathIsa {
  explicit FastPathIsa(temporal::Isa isa) { temporal::setFastPathIsa(isa); }
  ~FastPathIsa() { temporal::setFastPathIsa(temporal::Isa::Auto); }
  FastPathIsa(const FastPathIsa&) = delete;
  FastPathIsa& operator=(const FastPathIsa&) = delete;
};
// Every copy: the widest (AVX-512 for taa's rows where the CPU has it), AVX2
// (when the CPU has it) and the SSE2 baseline. A kernel without an AVX-512
// copy runs AVX2 for the first two.
constexpr temporal::Isa kFastPathIsas[3] = {temporal::Isa::Auto, temporal::Isa::Avx2, temporal::Isa::Baseline};

inline bool allFinite(const Image& im) {
  for (float v : im.data)
    if (!std::isfinite(v)) return false;
  return true;
}

// A named moving sequence of synth/moving.h.
struct MovingCase {
  const char* name;
  synth::Sequence seq;
};

// The moving sequences every temporal filter is measured on (exact motion and
// depth): an edge at 30 degrees and the ghosting disk, both moving.
inline std::vector<MovingCase> movingEdgeAndDisk(int width, int height) {
  return {{"edge 30deg v=(0.7,0.3)", synth::movingEdgeSequence(width, height, 30.0f, 0.7f, 0.3f)},
          {"ghosting disk v=(1.3,0)", synth::ghostingSequence(width, height, 8.0f, 1.3f, 0.0f)}};
}

// A temporal filter of `type` on `threads` threads, driven as a caller drives
// it: each run() points it at one frame (the auxiliary images only when
// asked; id and albedo only for taa-improved, the one filter that reads
// them), sets that frame's jitter, re-commits and executes.
struct TemporalDriver {
  Context context;
  std::unique_ptr<Filter> filter;
  Image output;
  explicit TemporalDriver(const char* type, int threads = 1) {
    context.setInt("numThreads", threads);
    filter = createFilter(context, type);
  }
  const Image& run(const synth::FrameData& f, bool motion = true, bool depth = true, bool id = true,
                   const Image* albedo = nullptr) {
    if (output.width != f.color.width) output = Image(f.color.width, f.color.height, 4);
    filter->setImage("color", f.color.view());
    if (motion) filter->setImage("motion", f.motion.view()); else filter->unsetImage("motion");
    if (depth) filter->setImage("depth", f.depth.view()); else filter->unsetImage("depth");
    if (std::string(filter->type()) == "taa-improved") {
      if (id) filter->setImage("id", f.id.view()); else filter->unsetImage("id");
      if (albedo) filter->setImage("albedo", albedo->view()); else filter->unsetImage("albedo");
    }
    filter->setImage("output", output.view());
    filter->params().setFloat("jitterX", f.jitter.x);
    filter->params().setFloat("jitterY", f.jitter.y);
    filter->markDirty("the jitter was set");
    filter->commit();
    filter->execute();
    return output;
  }
};

// The still chart (depth: its shapes in front of the background; the motion
// image all zero) under EEVEE's jitter, frames 0 .. frames - 1, no references.
inline std::vector<synth::FrameData> stillChartUnderEeveeJitter(int w, int h, int frames) {
  const synth::Sequence seq = synth::staticChartSequence(w, h);
  synth::FrameOptions jitter;
  jitter.jitter = synth::JitterKind::BlackmanHarris;
  jitter.reference = synth::ReferenceKind::None;
  std::vector<synth::FrameData> input;
  for (int t = 0; t < frames; ++t) input.push_back(synth::renderFrame(seq, w, h, t, jitter));
  return input;
}

// The test chart panned by (vx, vy) pixels per frame (a uniform motion
// image): frames 0 .. frames - 1.
// With movingShapes >= 0, a still camera instead: only the chart's first
// movingShapes shapes move, over the still chart.
inline std::vector<synth::FrameData> pannedChart(int w, int h, int frames, float vx, float vy,
                                                 const synth::FrameOptions& options = {}, int movingShapes = -1) {
  synth::Sequence seq = synth::staticChartSequence(w, h);
  for (std::size_t i = 0; i < seq.before.shapes.size(); ++i)
    if (movingShapes < 0 || int(i) < movingShapes) seq.before.shapes[i].vx = vx, seq.before.shapes[i].vy = vy;
  if (movingShapes < 0) {
    seq.before.backgroundVx = vx;
    seq.before.backgroundVy = vy;
  }
  std::vector<synth::FrameData> input;
  for (int t = 0; t < frames; ++t) input.push_back(synth::renderFrame(seq, w, h, t, options));
  return input;
}

// `method` over the frames of `input` with motion and depth, its parameters
// set by `setParams`: the mean PSNR against the references of the frames
// from warmUp on; each output appended to `outputs` when given.
template <class SetParams>
double meanPsnrAfterWarmUp(const char* method, const std::vector<synth::FrameData>& input, int warmUp,
                           std::vector<Image>* outputs, const SetParams& setParams) {
  TemporalDriver d(method);
  setParams(d.filter->params());
  const int frames = int(input.size());
  double sum = 0;
  for (int t = 0; t < frames; ++t) {
    const Image& out = d.run(input[std::size_t(t)], true, true);
    if (outputs) outputs->push_back(out);
    if (t >= warmUp) sum += psnr(input[std::size_t(t)].reference, out) / (frames - warmUp);
  }
  return sum;
}

// The resampling-damping check of taa and phlm (their
// ResampleDampingActsOnlyAtSubPixelMotion tests): the test chart panned by
// whole pixels (1, -1) and by half pixels (0.5, 0.5) per frame, filtered
// with resampleDamping 0 and 0.3. wholePixelSame: the whole-pixel pan gave
// the same bits either way; off / on: the half-pixel pan's mean PSNR after
// warmUp without / with the damping; verticalOff / verticalOn: the same for
// the chart panned by (0, 0.5) per frame, whose fetch fraction is sub-pixel
// in y only (the damping takes the larger of the two axes' fractions).
struct DampingFigures {
  bool wholePixelSame = true;
  double off = 0, on = 0;
  double verticalOff = 0, verticalOn = 0;
};
inline DampingFigures resampleDampingFigures(const char* method, int w, int h, int frames, int warmUp) {
  auto run = [&](const std::vector<synth::FrameData>& input, float damping, std::vector<Image>* outputs) {
    return meanPsnrAfterWarmUp(method, input, warmUp, outputs,
                               [&](ParamSet& p) { p.setFloat("resampleDamping", damping); });
  };
  DampingFigures r;
  const std::vector<synth::FrameData> whole = pannedChart(w, h, frames, 1.0f, -1.0f);
  const std::vector<synth::FrameData> half = pannedChart(w, h, frames, 0.5f, 0.5f);
  std::vector<Image> plain, damped;
  run(whole, 0.0f, &plain);
  run(whole, 0.3f, &damped);
  for (int t = 0; t < frames; ++t) r.wholePixelSame &= plain[std::size_t(t)].data == damped[std::size_t(t)].data;
  r.off = run(half, 0.0f, nullptr);
  r.on = run(half, 0.3f, nullptr);
  const std::vector<synth::FrameData> vertical = pannedChart(w, h, frames, 0.0f, 0.5f);
  r.verticalOff = run(vertical, 0.0f, nullptr);
  r.verticalOn = run(vertical, 0.3f, nullptr);
  return r;
}

}  // namespace crisp::test
