// SPDX-License-Identifier: Apache-2.0
// Set-up shared by the single-frame tests (test_fxaa.cpp, test_repair.cpp,
// test_rsaa.cpp, test_flip.cpp, test_metrics.cpp, test_temporal_error.cpp): a synthetic scene with its
// reference and edge mask, the error over a mask computed here (so a test of
// a filter does not depend on metrics.cpp), and the error code of a call.
#pragma once

#include <cmath>
#include <functional>

#include "core/color.h"
#include "core/error.h"
#include "core/image.h"
#include "synth/synthetic.h"

namespace crisp::test {

// A scene rendered at width x height: 1 sample at the pixel centres, the
// 16x16 box-supersampled reference, and the edge pixels (16x16 sub-samples).
struct EdgeFrames {
  Image one, reference, edges;
};

inline EdgeFrames renderEdgeFrames(const synth::Scene& scene, int width, int height) {
  return {synth::renderCentre(scene, width, height), synth::renderSupersampled(scene, width, height, 16),
          synth::edgePixels(scene, width, height, 16)};
}

// A linear RGBA image (alpha 1) whose display-encoded values are
// encoded(x, y, c) (test_metrics.cpp, test_temporal_error.cpp).
inline Image fromEncoded(int w, int h, const std::function<float(int, int, int)>& encoded) {
  Image im(w, h, 4, 1.0f);
  for (int y = 0; y < h; ++y)
    for (int x = 0; x < w; ++x)
      for (int c = 0; c < 3; ++c) im.at(x, y)[c] = srgbDecode(encoded(x, y, c));
  return im;
}

// Squared error of display-encoded RGB (sRGB of clamped linear) over the
// pixels where mask > 0; adds the number of values summed to `count`.
inline double maskedSquaredError(const Image& reference, const Image& test, const Image& mask, long& count) {
  double squared = 0;
  for (int y = 0; y < reference.height; ++y)
    for (int x = 0; x < reference.width; ++x) {
      if (!(*mask.at(x, y) > 0)) continue;
      for (int k = 0; k < 3; ++k) {
        const double d = double(srgbEncode(reference.at(x, y)[k])) - double(srgbEncode(test.at(x, y)[k]));
        squared += d * d;
        ++count;
      }
    }
  return squared;
}

// PSNR (peak 1) of the same.
inline double maskedPsnr(const Image& reference, const Image& test, const Image& mask) {
  long count = 0;
  const double squared = maskedSquaredError(reference, test, mask, count);
  return 10.0 * std::log10(1.0 / (squared / double(count)));
}

// The code of the crisp::Exception `call` throws; CRISP_ERROR_NONE when it
// returns.
inline CrispError errorCode(const std::function<void()>& call) {
  try {
    call();
  } catch (const Exception& e) {
    return e.code();
  }
  return CRISP_ERROR_NONE;
}

}  // namespace crisp::test
