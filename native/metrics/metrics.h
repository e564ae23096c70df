// SPDX-License-Identifier: Apache-2.0
// Image-quality metrics. Every metric compares DISPLAY-ENCODED values: each
// linear RGB channel clamped to [0,1] and sRGB-encoded (core/color.h; the
// metrics use a tabulated copy within 2.5e-7 of it), so the figures match what
// a viewer sees and what PNG output holds.
#pragma once

#include "core/image.h"

namespace crisp {

struct Metrics {
  double mse = 0;    // mean over pixels and RGB channels of squared difference
  double rmse = 0;   // sqrt(mse)
  double psnr = 0;   // 10 log10(1 / mse) dB (peak 1); capped at 100 dB for identical images
  double snr = 0;    // 10 log10(sum ref^2 / sum (ref - test)^2) dB; capped at 100 dB
  double ssim = 0;   // mean SSIM (Wang et al. 2004: 11x11 Gaussian sigma 1.5, K1 0.01, K2 0.03) of the luma
                     // Y = 0.299R' + 0.587G' + 0.114B' of the encoded values
  double flip = 0;   // mean perceptual LDR error in [0,1] (FLIP-style, flip.h)
  long pixels = 0;   // pixels counted (mask > 0)
};

struct MetricMaps {
  Image* error = nullptr;  // if set: 1 channel, per-pixel squared error averaged over RGB
  Image* ssim = nullptr;   // if set: 1 channel, per-pixel SSIM
  Image* flip = nullptr;   // if set: 1 channel, per-pixel perceptual error
};

// What to compute (all by default). The cheap figures (MSE, RMSE, PSNR, SNR)
// are always computed; a figure switched off stays 0.
struct CompareOptions {
  bool ssim = true;
  bool flip = true;
  float pixelsPerDegree = 67.0f;  // observer of the FLIP-style error (flip.h)
};

// reference and test: same size, 3 or 4 channels (alpha ignored). mask (optional,
// 1 channel, same size): only pixels with mask > 0 count. Throws
// CRISP_ERROR_INVALID_DATA on size/channel mismatch.
//
// Details (metrics.cpp):
//  * Every figure is a mean over the counted pixels; sums run in double, per
//    row then over rows in row order, so results are bit-identical for any
//    thread count.
//  * PSNR and SNR are capped at 100 dB (identical images); SNR is floored at
//    -100 dB (black reference, different test).
//  * SSIM: moments filtered over the whole image with the image mirrored at its
//    borders (scipy.ndimage 'reflect', as scikit-image filters), so there is an
//    SSIM value at every pixel and Metrics::ssim is the mean of that map over
//    the counted pixels. scikit-image's structural_similarity instead averages
//    only pixels at least 5 from the border (its "crop"); a mask that is 1 on
//    exactly those pixels reproduces its figure.
//  * Maps cover every pixel (the mask only selects which pixels are averaged),
//    so the mean of a map over the counted pixels is the scalar figure.
//  * A mask that selects no pixel is CRISP_ERROR_INVALID_DATA; a map asked for
//    a figure switched off in options is CRISP_ERROR_INVALID_ARGUMENT.
//  * Cost: the FLIP-style map is most of it (about 2/3 at 1080p); switch it off
//    in CompareOptions for quick figures. Scratch memory is ~75 bytes/pixel.
Metrics compareImages(const Image& reference, const Image& test, const Image* mask = nullptr,
                      const MetricMaps& maps = {}, int numThreads = 0);
Metrics compareImages(const Image& reference, const Image& test, const Image* mask, const MetricMaps& maps,
                      int numThreads, const CompareOptions& options);

// Display encoding used by every metric: RGB(A) linear -> 3-channel sRGB in [0,1].
Image displayEncode(const Image& linear, int numThreads = 0);

}  // namespace crisp
