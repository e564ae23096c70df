// SPDX-License-Identifier: Apache-2.0
// MSE / RMSE / PSNR / SNR / SSIM on display-encoded values (metrics.h), plus
// the mean of the FLIP-style map (flip.cpp).
//
// SSIM follows Wang, Bovik, Sheikh, Simoncelli, "Image quality assessment:
// from error visibility to structural similarity", IEEE TIP 13(4), 2004:
//  * eq. (14)-(16): local means, standard deviations and covariance weighted by
//    an 11x11 circular-symmetric Gaussian, sigma 1.5, normalised to sum 1
//    (Sec. III-C). Here: separable, taps exp(-i^2/(2*1.5^2)), i in [-5, 5],
//    which is the same window; variances are E[x^2] - E[x]^2 (population, not
//    sample, covariance, as the paper).
//  * eq. (13): SSIM = (2 mx my + C1)(2 sxy + C2) / ((mx^2 + my^2 + C1)(sx^2 + sy^2 + C2)),
//    C1 = (K1 L)^2, C2 = (K2 L)^2, K1 = 0.01, K2 = 0.03 (Sec. III-B), L = 1
//    (encoded values are in [0,1]).
//  * Applied to the luma Y' = 0.299 R' + 0.587 G' + 0.114 B' (Rec. 601 weights
//    on the sRGB-encoded values), as the paper works on grey-scale images.
//  * Border: Wang's reference code evaluates valid windows only. We mirror the
//    image (scipy.ndimage 'reflect', see convolve.h) to get a value at every
//    pixel so maps and masks cover the whole frame; see metrics.h for how this
//    relates to scikit-image's figure.
#include "metrics/metrics.h"

#include <algorithm>
#include <cmath>
#include <string>
#include <vector>

#include "core/color.h"
#include "core/error.h"
#include "core/parallel.h"
#include "metrics/convolve.h"
#include "metrics/flip.h"
#include "metrics/power_table.h"

namespace crisp {

namespace {

using metrics_detail::convolveColumn;
using metrics_detail::convolveRow;
using metrics_detail::gaussianKernel;
using metrics_detail::Kernel;
using metrics_detail::padRow;

constexpr double kPeakValue = 1.0;   // encoded values lie in [0,1]
constexpr double kMaxDecibels = 100.0;  // PSNR/SNR of identical images
constexpr double kSsimK1 = 0.01, kSsimK2 = 0.03;  // Wang 2004, Sec. III-B
constexpr double kSsimSigma = 1.5;                 // Wang 2004, Sec. III-C
constexpr int kSsimRadius = 5;                     // 11x11 window

std::string describe(const Image& im) {
  return std::to_string(im.width) + "x" + std::to_string(im.height) + "x" + std::to_string(im.channels);
}

double decibels(double signal, double noise) {
  if (!(noise > 0)) return kMaxDecibels;
  if (!(signal > 0)) return -kMaxDecibels;
  return std::clamp(10.0 * std::log10(signal / noise), -kMaxDecibels, kMaxDecibels);
}

bool counted(const Image* mask, int x, int y) { return !mask || *mask->at(x, y) > 0.0f; }

// Per-row partial sums, reduced in row order afterwards (thread-count independent).
struct RowSums {
  std::vector<double> squaredError, referenceEnergy, ssim, flip;
  std::vector<long> pixels;
  explicit RowSums(int height)
      : squaredError(std::size_t(height), 0.0),
        referenceEnergy(std::size_t(height), 0.0),
        ssim(std::size_t(height), 0.0),
        flip(std::size_t(height), 0.0),
        pixels(std::size_t(height), 0) {}
};

double luma(const float* p) { return 0.299 * double(p[0]) + 0.587 * double(p[1]) + 0.114 * double(p[2]); }

// SSIM of every pixel of row band [y0, y1), written to ssimRow(y)[x].
// lumaRef/lumaTest: packed width x height planes.
template <class Sink>
void ssimRows(const std::vector<double>& lumaRef, const std::vector<double>& lumaTest, int width, int height,
              int y0, int y1, const Kernel<double>& window, Sink&& sink) {
  const int r = window.radius;
  const std::size_t w = std::size_t(width), padded = w + 2 * std::size_t(r);
  // Vertical pass output (5 moments), their padded copies, horizontal output.
  std::vector<double> col(5 * w), pad(5 * padded), mom(5 * w), ssim(w);
  const double c1 = (kSsimK1 * kPeakValue) * (kSsimK1 * kPeakValue);
  const double c2 = (kSsimK2 * kPeakValue) * (kSsimK2 * kPeakValue);
  for (int y = y0; y < y1; ++y) {
    double* mx = col.data();
    double* my = mx + w;
    double* mxx = my + w;
    double* myy = mxx + w;
    double* mxy = myy + w;
    convolveColumn(lumaRef.data(), width, height, y, window, mx);
    convolveColumn(lumaTest.data(), width, height, y, window, my);
    // Second moments: products per source row, then the same fixed-order sum.
    std::fill(mxx, mxx + 3 * w, 0.0);
    for (int k = -r; k <= r; ++k) {
      const std::size_t sy = std::size_t(metrics_detail::reflectIndex(y + k, height));
      const double* a = lumaRef.data() + sy * w;
      const double* b = lumaTest.data() + sy * w;
      const double wk = window.taps[std::size_t(k + r)];
      for (std::size_t x = 0; x < w; ++x) {
        mxx[x] += wk * (a[x] * a[x]);
        myy[x] += wk * (b[x] * b[x]);
        mxy[x] += wk * (a[x] * b[x]);
      }
    }
    for (int m = 0; m < 5; ++m) {
      padRow(col.data() + std::size_t(m) * w, width, r, pad.data() + std::size_t(m) * padded);
      convolveRow(pad.data() + std::size_t(m) * padded, width, r, window, mom.data() + std::size_t(m) * w);
    }
    const double* ux = mom.data();
    const double* uy = ux + w;
    const double* uxx = uy + w;
    const double* uyy = uxx + w;
    const double* uxy = uyy + w;
    for (std::size_t x = 0; x < w; ++x) {
      const double vx = uxx[x] - ux[x] * ux[x];
      const double vy = uyy[x] - uy[x] * uy[x];
      const double vxy = uxy[x] - ux[x] * uy[x];
      const double num = (2.0 * ux[x] * uy[x] + c1) * (2.0 * vxy + c2);
      const double den = (ux[x] * ux[x] + uy[x] * uy[x] + c1) * (vx + vy + c2);
      ssim[x] = num / den;
    }
    sink(y, ssim.data());
  }
}

}  // namespace

Image displayEncode(const Image& linear, int numThreads) {
  if (linear.channels != 3 && linear.channels != 4)
    invalidData("displayEncode: image is " + describe(linear) + ", expected 3 or 4 channels (RGB or RGBA)");
  if (linear.width <= 0 || linear.height <= 0) invalidData("displayEncode: image is empty");
  Image out(linear.width, linear.height, 3);
  // srgbEncode (core/color.h) to ~2e-7, tabulated: powf would dominate the cost of PSNR.
  const metrics_detail::PowerTable& table = metrics_detail::srgbEncodeTable();
  const int inChannels = linear.channels;
  parallelRows(linear.width, linear.height, numThreads, [&](int y0, int y1) {
    for (int y = y0; y < y1; ++y) {
      const float* in = linear.at(0, y);
      float* o = out.at(0, y);
      for (int x = 0; x < linear.width; ++x)
        for (int c = 0; c < 3; ++c)
          o[3 * x + c] = metrics_detail::fastSrgbEncode(in[inChannels * x + c], table);  // NaN -> 0, clamps
    }
  });
  return out;
}

Metrics compareImages(const Image& reference, const Image& test, const Image* mask, const MetricMaps& maps,
                      int numThreads) {
  return compareImages(reference, test, mask, maps, numThreads, CompareOptions{});
}

Metrics compareImages(const Image& reference, const Image& test, const Image* mask, const MetricMaps& maps,
                      int numThreads, const CompareOptions& options) {
  for (const Image* im : {&reference, &test})
    if ((im->channels != 3 && im->channels != 4) || im->format == Format::UInt)
      invalidData(std::string("compareImages: ") + (im == &reference ? "reference" : "test") + " image is " +
                  describe(*im) + ", expected 3 or 4 float channels (RGB or RGBA)");
  if (reference.width != test.width || reference.height != test.height || reference.channels != test.channels)
    invalidData("compareImages: reference is " + describe(reference) + " but test is " + describe(test) +
                " (width x height x channels must match)");
  if (reference.width <= 0 || reference.height <= 0) invalidData("compareImages: images are empty");
  if (mask && (mask->width != reference.width || mask->height != reference.height || mask->channels != 1))
    invalidData("compareImages: mask is " + describe(*mask) + " but the images are " + describe(reference) +
                " (the mask must be 1 channel of the same size)");
  if ((maps.ssim && !options.ssim) || (maps.flip && !options.flip))
    invalidArgument("compareImages: a map was requested for a metric that is switched off");

  const int width = reference.width, height = reference.height;
  const std::size_t w = std::size_t(width);
  const Image encRef = displayEncode(reference, numThreads);
  const Image encTest = displayEncode(test, numThreads);

  if (maps.error) *maps.error = Image(width, height, 1);
  if (maps.ssim) *maps.ssim = Image(width, height, 1);
  RowSums sums(height);

  // Pass 1: per-pixel squared error, reference energy, luma planes for SSIM.
  std::vector<double> lumaRef, lumaTest;
  if (options.ssim) {
    lumaRef.resize(w * std::size_t(height));
    lumaTest.resize(w * std::size_t(height));
  }
  parallelRows(width, height, numThreads, [&](int y0, int y1) {
    for (int y = y0; y < y1; ++y) {
      double sq = 0, energy = 0;
      long n = 0;
      for (int x = 0; x < width; ++x) {
        const float* a = encRef.at(x, y);
        const float* b = encTest.at(x, y);
        double pixelSq = 0, pixelEnergy = 0;
        for (int c = 0; c < 3; ++c) {
          const double d = double(a[c]) - double(b[c]);
          pixelSq += d * d;
          pixelEnergy += double(a[c]) * double(a[c]);
        }
        if (maps.error) *maps.error->at(x, y) = float(pixelSq / 3.0);
        if (options.ssim) {
          lumaRef[std::size_t(y) * w + std::size_t(x)] = luma(a);
          lumaTest[std::size_t(y) * w + std::size_t(x)] = luma(b);
        }
        if (counted(mask, x, y)) {
          sq += pixelSq;
          energy += pixelEnergy;
          ++n;
        }
      }
      sums.squaredError[std::size_t(y)] = sq;
      sums.referenceEnergy[std::size_t(y)] = energy;
      sums.pixels[std::size_t(y)] = n;
    }
  });

  Metrics m;
  for (int y = 0; y < height; ++y) m.pixels += sums.pixels[std::size_t(y)];
  if (m.pixels == 0) invalidData("compareImages: the mask selects no pixel (no value > 0)");

  // Pass 2: SSIM map (needs all luma rows, hence a second pass).
  if (options.ssim) {
    const Kernel<double> window = gaussianKernel<double>(kSsimSigma, kSsimRadius);
    parallelRows(width, height, numThreads, [&](int y0, int y1) {
      ssimRows(lumaRef, lumaTest, width, height, y0, y1, window, [&](int y, const double* ssim) {
        double s = 0;
        for (int x = 0; x < width; ++x) {
          if (maps.ssim) *maps.ssim->at(x, y) = float(ssim[x]);
          if (counted(mask, x, y)) s += ssim[x];
        }
        sums.ssim[std::size_t(y)] = s;
      });
    });
  }

  // FLIP-style map, averaged over the counted pixels.
  if (options.flip) {
    Image flipMap = flipErrorMap(encRef, encTest, options.pixelsPerDegree, numThreads);
    for (int y = 0; y < height; ++y) {
      double s = 0;
      for (int x = 0; x < width; ++x)
        if (counted(mask, x, y)) s += double(*flipMap.at(x, y));
      sums.flip[std::size_t(y)] = s;
    }
    if (maps.flip) *maps.flip = std::move(flipMap);
  }

  double sq = 0, energy = 0, ssim = 0, flip = 0;
  for (int y = 0; y < height; ++y) {
    sq += sums.squaredError[std::size_t(y)];
    energy += sums.referenceEnergy[std::size_t(y)];
    ssim += sums.ssim[std::size_t(y)];
    flip += sums.flip[std::size_t(y)];
  }
  const double n = double(m.pixels);
  m.mse = sq / (3.0 * n);
  m.rmse = std::sqrt(m.mse);
  m.psnr = decibels(kPeakValue * kPeakValue, m.mse);
  m.snr = decibels(energy, sq);
  m.ssim = options.ssim ? ssim / n : 0.0;
  m.flip = options.flip ? flip / n : 0.0;
  return m;
}

}  // namespace crisp
