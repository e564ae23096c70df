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
#include <cstring>
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

// Blocked loops: 2 x 16-byte vectors of outputs (8 floats / 4 doubles) are
// accumulated in registers across all taps, using GCC/Clang vector extensions
// (plain SSE2 on x86-64, NEON elsewhere). Each lane does exactly what the
// scalar tail does, in the same tap order, so results do not depend on where
// a row's blocks start (nor on -ffp-contract, which is off).
typedef float Float4 __attribute__((vector_size(16)));
typedef double Double2 __attribute__((vector_size(16)));
template <class T>
struct VecOf;
template <>
struct VecOf<float> {
  using type = Float4;
};
template <>
struct VecOf<double> {
  using type = Double2;
};
template <class T>
using Vec = typename VecOf<T>::type;
template <class T>
constexpr int kLanes = int(16 / sizeof(T));

template <class T>
inline Vec<T> loadVec(const T* p) {
  static_assert(sizeof(Vec<T>) == 16, "vector extension expected");
  Vec<T> v;
  std::memcpy(&v, p, sizeof v);
  return v;
}
template <class T>
inline void storeVec(T* p, Vec<T> v) {
  std::memcpy(p, &v, sizeof v);
}

// Largest radius the fixed-size row-pointer table below supports.
constexpr int kMaxRadius = 255;

// out[x] = sum_k taps[k] * plane[reflect(y + k - r)][x] over the whole row.
// plane is packed, `width` values per row.
template <class T>
void convolveColumn(const T* plane, int width, int height, int y, const Kernel<T>& kernel, T* out) {
  const int n = 2 * kernel.radius + 1;
  const T* rows[2 * kMaxRadius + 1];
  for (int k = 0; k < n; ++k)
    rows[k] = plane + std::size_t(reflectIndex(y + k - kernel.radius, height)) * std::size_t(width);
  const T* taps = kernel.taps.data();
  constexpr int L = kLanes<T>;
  int x = 0;
  for (; x + 2 * L <= width; x += 2 * L) {
    Vec<T> acc0 = {}, acc1 = {};
    for (int k = 0; k < n; ++k) {
      const T w = taps[k];
      acc0 += w * loadVec(rows[k] + x);
      acc1 += w * loadVec(rows[k] + x + L);
    }
    storeVec(out + x, acc0);
    storeVec(out + x + L, acc1);
  }
  for (; x < width; ++x) {
    T acc = 0;
    for (int k = 0; k < n; ++k) acc += taps[k] * rows[k][x];
    out[x] = acc;
  }
}

// Copies row[0..width) into padded[radius .. radius+width) with mirrored
// margins of `radius` samples on both sides (padded holds width + 2*radius).
template <class T>
void padRow(const T* row, int width, int radius, T* padded) {
  std::copy(row, row + width, padded + radius);
  for (int i = 1; i <= radius; ++i) {
    padded[radius - i] = row[reflectIndex(-i, width)];
    padded[radius + width - 1 + i] = row[reflectIndex(width - 1 + i, width)];
  }
}

// out[x] = sum_k taps[k] * padded[x + k], padded made by padRow with a margin
// of at least kernel.radius; `margin` is the margin padRow used.
template <class T>
void convolveRow(const T* padded, int width, int margin, const Kernel<T>& kernel, T* out) {
  const T* base = padded + (margin - kernel.radius);
  const int n = 2 * kernel.radius + 1;
  const T* taps = kernel.taps.data();
  constexpr int L = kLanes<T>;
  int x = 0;
  for (; x + 2 * L <= width; x += 2 * L) {
    Vec<T> acc0 = {}, acc1 = {};
    for (int k = 0; k < n; ++k) {
      const T w = taps[k];
      acc0 += w * loadVec(base + x + k);
      acc1 += w * loadVec(base + x + k + L);
    }
    storeVec(out + x, acc0);
    storeVec(out + x + L, acc1);
  }
  for (; x < width; ++x) {
    T acc = 0;
    for (int k = 0; k < n; ++k) acc += taps[k] * base[x + k];
    out[x] = acc;
  }
}

}  // namespace crisp::metrics_detail
