// SPDX-License-Identifier: Apache-2.0
// Filtered fetch of a reprojected history (seed 000 §3.6.3: the history is
// read where the pixel was in the previous frame; seed 004 "TAA steps" 4-5).
// Positions are in pixel-index units: the centre of pixel (i, j) is (i, j).
// Addressing is clamp-to-edge, as a texture sampler with clamp addressing.
// The buffer is packed RGBA float (4 floats per pixel, the fourth is carried).
#pragma once

#include <algorithm>
#include <cmath>
#include <cstddef>

namespace crisp::temporal {

struct HistoryImage {
  const float* data;  // 4 floats per pixel, rows top-down
  int width;
  int height;
  const float* at(int x, int y) const { return data + (std::size_t(y) * std::size_t(width) + std::size_t(x)) * 4; }
};

// True when (x, y) lies on a pixel of a width x height image (centres at
// integers, so the image covers [-0.5, size - 0.5]); false for NaN/Inf too.
inline bool onScreen(float x, float y, int width, int height) {
  return x >= -0.5f && y >= -0.5f && x <= float(width) - 0.5f && y <= float(height) - 0.5f;
}

// Bilinear weights at fractional position t: (1 - t, t) for the taps floor, floor + 1.
struct Footprint {
  int x0, y0;    // top-left tap (may be -1 or size - 1 + 1: clamped on read)
  float tx, ty;  // fractions in [0, 1)
};
inline Footprint footprintOf(float x, float y) {
  const float fx = std::floor(x), fy = std::floor(y);
  return {int(fx), int(fy), x - fx, y - fy};
}

// Bilinear fetch of the first 3 channels; out[3] = the carried channel of the
// nearest tap (never interpolated).
inline void fetchBilinear(const HistoryImage& h, float x, float y, float out[4]) {
  const Footprint f = footprintOf(x, y);
  const int xa = std::clamp(f.x0, 0, h.width - 1), xb = std::clamp(f.x0 + 1, 0, h.width - 1);
  const int ya = std::clamp(f.y0, 0, h.height - 1), yb = std::clamp(f.y0 + 1, 0, h.height - 1);
  const float* p00 = h.at(xa, ya);
  const float* p10 = h.at(xb, ya);
  const float* p01 = h.at(xa, yb);
  const float* p11 = h.at(xb, yb);
  for (int c = 0; c < 3; ++c) {
    const float top = p00[c] + (p10[c] - p00[c]) * f.tx;
    const float bottom = p01[c] + (p11[c] - p01[c]) * f.tx;
    out[c] = top + (bottom - top) * f.ty;
  }
  const float* nearest = h.at(f.tx < 0.5f ? xa : xb, f.ty < 0.5f ? ya : yb);
  out[3] = nearest[3];
}

// Catmull-Rom (cubic convolution, Keys 1981 with a = -0.5) weights of the taps
// floor - 1 .. floor + 2 at fraction t. They sum to 1; w0 and w3 are <= 0.
inline void catmullRomWeights(float t, float w[4]) {
  w[0] = t * (-0.5f + t * (1.0f - 0.5f * t));
  w[1] = 1.0f + t * t * (-2.5f + 1.5f * t);
  w[2] = t * (0.5f + t * (2.0f - 1.5f * t));
  w[3] = t * t * (-0.5f + 0.5f * t);
}

// Catmull-Rom fetch (16 taps, separable) of the first 3 channels. Negative-lobe
// clamping: the result is clamped per channel to the range of the 4 central
// (bilinear) taps, so the sharpening lobes cannot ring past the local colours
// (no overshoot, no negative colour from positive history). out[3] = the
// carried channel of the nearest tap.
inline void fetchCatmullRom(const HistoryImage& h, float x, float y, float out[4]) {
  const Footprint f = footprintOf(x, y);
  float wx[4], wy[4];
  catmullRomWeights(f.tx, wx);
  catmullRomWeights(f.ty, wy);
  int xs[4], ys[4];
  for (int i = 0; i < 4; ++i) {
    xs[i] = std::clamp(f.x0 - 1 + i, 0, h.width - 1);
    ys[i] = std::clamp(f.y0 - 1 + i, 0, h.height - 1);
  }
  float acc[3] = {0.0f, 0.0f, 0.0f};
  float lo[3], hi[3];
  const float* c11 = h.at(xs[1], ys[1]);
  for (int c = 0; c < 3; ++c) lo[c] = hi[c] = c11[c];
  for (int j = 0; j < 4; ++j) {
    float row[3] = {0.0f, 0.0f, 0.0f};
    for (int i = 0; i < 4; ++i) {
      const float* p = h.at(xs[i], ys[j]);
      for (int c = 0; c < 3; ++c) row[c] += wx[i] * p[c];
      if ((i == 1 || i == 2) && (j == 1 || j == 2))
        for (int c = 0; c < 3; ++c) {
          lo[c] = std::min(lo[c], p[c]);
          hi[c] = std::max(hi[c], p[c]);
        }
    }
    for (int c = 0; c < 3; ++c) acc[c] += wy[j] * row[c];
  }
  for (int c = 0; c < 3; ++c) out[c] = std::clamp(acc[c], lo[c], hi[c]);
  const float* nearest = h.at(f.tx < 0.5f ? xs[1] : xs[2], f.ty < 0.5f ? ys[1] : ys[2]);
  out[3] = nearest[3];
}

}  // namespace crisp::temporal
