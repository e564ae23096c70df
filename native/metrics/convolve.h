// SPDX-License-Identifier: Apache-2.0
// Separable convolution helpers shared by SSIM (metrics.cpp) and the FLIP-style
// error (flip.cpp). Both filter "vertical first, per output row": a row band
// needs only its own small row buffers, and every output pixel is a fixed-order
// sum, so results do not depend on how rows are split between threads.
//
// Borders mirror with the edge pixel repeated (d c b a | a b c d | d c b a),
// i.e. scipy.ndimage / scikit-image mode 'reflect', so SSIM maps can be
// cross-checked against skimage.metrics.structural_similarity(full=True).
#pragma once

#include <algorithm>
#include <cmath>
#include <cstddef>
#include <vector>

namespace crisp::metrics_detail {

// Index i of a line of n samples, mirrored half-sample symmetrically; any i,
// any n >= 1 (the mirror repeats with period 2n, as scipy's 'reflect').
inline int reflectIndex(int i, int n) {
  const int period = 2 * n;
  i %= period;
  if (i < 0) i += period;
  return i < n ? i : period - 1 - i;
}

// A symmetric 1-D kernel of 2*radius+1 taps; taps[k] is offset k - radius.
template <class T>
struct Kernel {
  int radius = 0;
  std::vector<T> taps;
};

// Sampled Gaussian exp(-x^2 / (2 sigma^2)) on [-radius, radius], normalised to
// sum 1 (as scipy.ndimage.gaussian_filter1d builds its weights).
template <class T>
Kernel<T> gaussianKernel(double sigma, int radius) {
  Kernel<T> k;
  k.radius = radius;
  std::vector<double> w(std::size_t(2 * radius + 1));
  double sum = 0;
  for (int i = -radius; i <= radius; ++i) {
    w[std::size_t(i + radius)] = std::exp(-0.5 * double(i) * double(i) / (sigma * sigma));
    sum += w[std::size_t(i + radius)];
  }
  for (double v : w) k.taps.push_back(T(v / sum));
  return k;
}

// out[x] = sum_k taps[k] * plane[reflect(y + k - r)][x] over the whole row.
// plane is packed, `width` values per row.
template <class T>
void convolveColumn(const T* plane, int width, int height, int y, const Kernel<T>& kernel, T* out) {
  std::fill(out, out + width, T(0));
  for (int k = -kernel.radius; k <= kernel.radius; ++k) {
    const T* row = plane + std::size_t(reflectIndex(y + k, height)) * std::size_t(width);
    const T w = kernel.taps[std::size_t(k + kernel.radius)];
    for (int x = 0; x < width; ++x) out[x] += w * row[x];
  }
}

// Copies row[0..width) into padded[radius .. radius+width) with mirrored
// margins of `radius` samples on both sides (padded holds width + 2*radius).
template <class T>
void padRow(const T* row, int width, int radius, T* padded) {
  for (int i = -radius; i < width + radius; ++i) padded[i + radius] = row[reflectIndex(i, width)];
}

// out[x] = sum_k taps[k] * padded[x + k], padded made by padRow with a margin
// of at least kernel.radius; `margin` is the margin padRow used.
template <class T>
void convolveRow(const T* padded, int width, int margin, const Kernel<T>& kernel, T* out) {
  const T* base = padded + (margin - kernel.radius);
  std::fill(out, out + width, T(0));
  for (int k = 0; k <= 2 * kernel.radius; ++k) {
    const T w = kernel.taps[std::size_t(k)];
    const T* src = base + k;
    for (int x = 0; x < width; ++x) out[x] += w * src[x];
  }
}

}  // namespace crisp::metrics_detail
