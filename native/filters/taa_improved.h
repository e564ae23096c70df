// SPDX-License-Identifier: Apache-2.0
// Improved TAA (seed 000 chapter IV; METHODS.md "Improved TAA"): the baseline
// TAA kernel (taa.h) steered per pixel by an aliasedValue in [0, 1]. The
// filter "taa-improved" (taa_improved.cpp) wraps this kernel.
//
// History kept between frames: the baseline's (taa.h) plus two float planes
// of the temporally stabilised Sobel value (ping-pong). Scratch: the
// aliasedValue plane, the fast path's rings of rows (taa_improved_rows.h),
// the reference path's luminance and raw Sobel planes once it has run, plus
// the baseline's band rings.
#pragma once

#include <cstddef>
#include <vector>

#include "core/image.h"
#include "filters/taa.h"

namespace crisp::taa_improved {

struct Settings {
  taa::Settings base;  // the baseline's parameters (its sharpen amount is set from `sharpen` below)
  // Ingredients; each can be switched off to measure its contribution.
  bool sobel = true;                  // Sobel edges (eqs. 4.9-4.10) in aliasedValue
  bool sobelUnlit = true;             // ... of the unlit luminance (albedo), when given
  bool sobelDepth = true;             // ... of depth, when given
  bool sobelStabilise = true;         // one-channel TAA of the Sobel plane (§4.3.3)
  bool modelAverage = true;           // object-ID edges (eq. 4.1)
  bool depthVariance = true;          // depth pseudo-variance (eqs. 4.4-4.5)
  bool temporalDepthVariance = true;  // temporal depth pseudo-variance (eq. 4.6)
  bool aliasedNeighbourhood = true;   // cross vs 3x3 by aliasedValue (eq. 4.15)
  bool aliasedBoxSize = true;         // box shrunk toward the current colour (eq. 4.16)
  bool normalizedSharpen = true;      // eq. 4.17 instead of eq. 3.1
  float sharpen = 0.0f;               // amount of the sharpen kernel, 0 = off
  float depthThreshold = 0.002f;      // eq. 4.4's threshold, relative to the centre depth
};

// The baseline's settings as the kernel runs it (pass 5): steering switches
// and the sharpen amount of `s` applied to s.base.
taa::Settings baselineSettings(const Settings& s);

struct Inputs {
  ImageView color;   // required
  ImageView motion;  // optional
  ImageView depth;   // optional
  ImageView id;      // optional, uint32 object ids (Cryptomatte hash), compared exactly
  ImageView albedo;  // optional, unlit colour (Blender's DiffCol)
  ImageView output;  // required
};

class Kernel {
 public:
  void allocate(int width, int height, bool withDepth = true);
  void reset();
  // reference: the baseline's scalar path, and the aliasedValue passes on one
  // thread (those passes are the same per-pixel code on either path).
  void run(const Inputs& in, const Settings& s, bool reference, int numThreads);

  std::size_t bytesKeptBetweenFrames() const;
  std::size_t bytesScratch() const;
  // This frame's aliasedValue plane and stabilised Sobel plane (width x height).
  const std::vector<float>& aliasedValue() const { return aliased_; }
  // The plane the baseline is steered by under `s` (taa::Inputs::aliasedValue): this frame's
  // aliasedValue plane, or null when neither steering is on.
  const float* steering(const Settings& s) const {
    return s.aliasedNeighbourhood || s.aliasedBoxSize ? aliased_.data() : nullptr;
  }
  const std::vector<float>& sobel() const { return sobel_[current_]; }
  const taa::Kernel& baseline() const { return taa_; }

 private:
  int width_ = 0, height_ = 0;
  taa::Kernel taa_;
  std::vector<float> aliased_;
  std::vector<float> lumaLit_, lumaUnlit_, sobelRaw_;  // the reference path's planes (empty until it runs)
  int bands_ = 0;
  std::vector<float> bandRings_;  // the fast path's: bands_ x rows::bandFloats(width)
  std::vector<float> sobel_[2];
  int current_ = 0;
  bool sobelValid_ = false;
};

}  // namespace crisp::taa_improved
