// SPDX-License-Identifier: Apache-2.0
// The alpha of the temporal methods' outputs: temporal_alpha.h says why and how.
#include "filters/temporal_alpha.h"

#include <algorithm>
#include <cstring>
#include <utility>

#include "core/color.h"
#include "core/parallel.h"
#include "filters/phlm.h"
#include "filters/taa.h"

namespace crisp {

namespace {

float alphaAt(const ImageView& v, int x, int y) {
  float a;
  std::memcpy(&a, reinterpret_cast<const char*>(v.pixel(x, y)) + 3 * sizeof(float), sizeof a);
  return a;
}

}  // namespace

TemporalAlpha::TemporalAlpha() = default;
TemporalAlpha::~TemporalAlpha() = default;

void TemporalAlpha::allocate(int width, int height, bool withDepth) {
  if (width != width_ || height != height_) {  // a new size starts over, opaque until alpha shows up
    active_ = false;
    kernel_ = nullptr;
    grey_ = Image();
    filtered_ = Image();
  }
  width_ = width;
  height_ = height;
  withDepth_ = withDepth;
  if (kernel_) kernel_->allocate(width, height, withDepth);  // keeps the history (taa.h)
}

void TemporalAlpha::reset() {
  active_ = false;
  if (kernel_) kernel_->reset();
}

void TemporalAlpha::run(const ImageView& color, bool alphaBelowOne, const ImageView& motion, const ImageView& depth,
                        const float* aliasedValue, const ImageView& output, const taa::Settings& base, bool reference,
                        int numThreads) {
  const bool alphaIn = color.channels() >= 4, alphaOut = output.channels() >= 4;
  if (!active_) {
    if (!alphaIn || !alphaOut || !alphaBelowOne) return;
    if (!kernel_) kernel_ = std::make_unique<taa::Kernel>();
    kernel_->allocate(width_, height_, withDepth_);
    kernel_->reset();  // the first filtered frame bootstraps, whatever came before
    if (grey_.width != width_ || grey_.height != height_ || filtered_.width != width_ || filtered_.height != height_) {
      // Both or neither: an allocation that throws part-way leaves them for the next frame to make.
      Image grey(width_, height_, 3), filtered(width_, height_, 3);
      grey_ = std::move(grey);
      filtered_ = std::move(filtered);
    }
    active_ = true;
  }
  const int w = width_;
  parallelRows(w, height_, numThreads, [&](int y0, int y1) {
    for (int y = y0; y < y1; ++y) {
      float* g = grey_.data.data() + std::size_t(y) * w * 3;
      // Coverage in [0, 1] (NaN 0, above 1 or +Inf 1); an RGB colour's: 1, as the colour kernel writes it.
      for (int x = 0; x < w; ++x)
        g[3 * x] = g[3 * x + 1] = g[3 * x + 2] =
            alphaIn ? std::clamp(sanitizeColor(alphaAt(color, x, y)), 0.0f, 1.0f) : 1.0f;
    }
  });
  taa::Inputs in;
  in.color = grey_.view();
  in.motion = motion;
  in.depth = depth;
  in.output = filtered_.view();
  in.aliasedValue = aliasedValue;
  kernel_->run(in, base, reference, numThreads);
  if (!alphaOut) return;  // the history ran: it never skips a frame
  parallelRows(w, height_, numThreads, [&](int y0, int y1) {
    for (int y = y0; y < y1; ++y) {
      const float* f = filtered_.data.data() + std::size_t(y) * w * 3;
      for (int x = 0; x < w; ++x) output.pixel(x, y)[3] = std::clamp(f[3 * x], 0.0f, 1.0f);
    }
  });
}

void TemporalAlpha::run(const ImageView& color, bool alphaBelowOne, const ImageView& motion, const ImageView& depth,
                        const ImageView& output, const phlm::Settings& s, bool reference, int numThreads) {
  if (!active_ && !alphaBelowOne) return;
  taa::Settings a;
  a.jitterX = s.jitterX;
  a.jitterY = s.jitterY;
  a.weighting = s.weighting == phlm::JitterWeighting::BlackmanHarris ? taa::JitterWeighting::BlackmanHarris
                                                                     : taa::JitterWeighting::None;
  a.filterSize = s.filterSize;
  a.unjitter = s.unjitter;
  a.holdPeriod = s.holdPeriod;
  a.holdRelease = s.holdRelease;
  a.depthTolerance = s.depthTolerance;
  run(color, alphaBelowOne, motion, depth, nullptr, output, a, reference, numThreads);
}

std::size_t TemporalAlpha::bytesKeptBetweenFrames() const {  // held from the first alpha until the size changes
  return (kernel_ ? kernel_->bytesKeptBetweenFrames() : 0) + (grey_.data.size() + filtered_.data.size()) * sizeof(float);
}

}  // namespace crisp
