// SPDX-License-Identifier: Apache-2.0
// TAA baseline (seed 000 chapter III; METHODS.md "TAA baseline"): the kernel
// and its history, drivable by tests and benchmarks without the Filter
// interface. The filter "taa" (taa.cpp) wraps it.
//
// History kept between frames (bytesKeptBetweenFrames): two RGBA float
// images (ping-pong: the reprojected fetch reads neighbours of the pixel being
// written) holding the accumulated colour in the clip space plus a signed
// sample weight, and, when depth is given, two float depth planes (this
// frame's and the previous frame's). Scratch (bytesScratch): the staged
// current frame, RGBA float.
#pragma once

#include <cstddef>
#include <vector>

#include "core/image.h"

namespace crisp::taa {

enum class HistoryFilter { CatmullRom, Bilinear };
enum class ClipSpace { YCoCg, Rgb };
enum class JitterWeighting { None, BlackmanHarris };

struct Settings {
  float jitterX = 0.0f;  // this frame's sample offset, pixels, x right
  float jitterY = 0.0f;  // pixels, y DOWN (library convention; Blender's y up negated)
  JitterWeighting weighting = JitterWeighting::None;
  float filterSize = 1.5f;  // width of the Blackman-Harris pixel filter for weighting (EEVEE's filter_size)
  HistoryFilter historyFilter = HistoryFilter::CatmullRom;
  ClipSpace clipSpace = ClipSpace::YCoCg;
  float feedbackMin = 0.88f;  // history weight for a large luma difference
  float feedbackMax = 0.97f;  // history weight for equal lumas
  float sharpen = 0.0f;       // 0 = off, 1 = the full [0,-1,0;-1,5,-1;0,-1,0] kernel (eq. 3.1)
  bool staticAccumulation = true;
  int maxSamples = 128;       // cap of the running average's sample count (weighted units)
  bool staticClip = true;     // clip history in static pixels too (rejects cuts, fireflies, light changes)
  float depthTolerance = 0.05f;  // relative depth difference still the same surface
};

struct Inputs {
  ImageView color;   // required, 3-4 float channels
  ImageView motion;  // optional (ptr null = static scene): 2-4 channels, pixels, previous - current, y down
  ImageView depth;   // optional: planar depth, channel 0
  ImageView output;  // required, 3-4 channels
};

class Kernel {
 public:
  void allocate(int width, int height);
  // Forgets the history: the next frame is a first frame (bootstrap).
  void reset();
  // One frame. reference: the scalar path (one thread, clamp-to-edge on every
  // tap); otherwise row bands on numThreads threads with unclamped interior
  // taps. Both give bit-identical outputs and histories.
  void run(const Inputs& in, const Settings& s, bool reference, int numThreads);

  std::size_t bytesKeptBetweenFrames() const;
  std::size_t bytesScratch() const;
  int framesSinceReset() const { return frames_; }
  // The history written by the last run: RGBA, colour in the clip space of
  // that run, alpha = signed sample weight (negative: the pixel was moving).
  const Image& history() const { return history_[current_]; }
  ClipSpace historySpace() const { return historySpace_; }

 private:
  int width_ = 0, height_ = 0;
  Image staged_;
  Image history_[2];
  std::vector<float> depth_[2];
  int current_ = 0;           // index of the history written last
  int frames_ = 0;            // frames since reset; 0 = no history
  bool previousDepthValid_ = false;
  ClipSpace historySpace_ = ClipSpace::YCoCg;
};

}  // namespace crisp::taa
