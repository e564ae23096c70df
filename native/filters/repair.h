// SPDX-License-Identifier: Apache-2.0
// REPAIR anti-aliasing (rotated spatial filtering; seed 001 = the REPAIR
// thesis, chapter 3 and Algorithms 1-4), as step functions and a kernel that
// tests and benchmarks can drive without the Filter interface.
//
// Conventions (see core/conventions.h):
//  * Images are rows top-down. Patch/pixel offsets are (column, row) = (x, y)
//    with y DOWN.
//  * Edge angles theta are reported as seen on screen: counter-clockwise from
//    +x with y UP, in [0, 180) degrees (the convention of synth::edgeScene).
//    An edge direction is kept as the unit vector (cos theta, sin theta).
#pragma once

#include <cstddef>
#include <cstdint>
#include <vector>

#include "core/image.h"

namespace crisp::repair {

enum class MaskKind { Gauss5, Box3 };
// Regression: the thesis' two regressions (eq. 3.2-3.3) combined into a
//   correct angle (our deliberate deviation from eq. 3.6, see repair.cpp).
// Thesis: the literal tan(theta) = beta1 / alpha1 of eq. 3.6, for the record.
enum class AngleEstimator { Regression, Thesis };

struct Settings {
  float kappa = 0.0f;   // threshold weight of eq. 3.1 (T = mu + kappa sigma); see the parameter table
  int patchSize = 5;    // n of the n x n slope patch (odd, 3..15)
  MaskKind mask = MaskKind::Gauss5;
  AngleEstimator estimator = AngleEstimator::Regression;
};

constexpr int kMaxPatchSize = 15;

// ---- Step 1: grey image (eq. 2.1, Y row of YIQ) ---------------------------
// Display encoding used for the grey image: sRGB encoding of the linear value
// clamped to [0, 1] (NaN -> 0), computed without pow() or tables so that the
// fast path vectorises it (see repair.cpp for the identities used). It
// differs from the exact curve by < 3.1e-7 and from crisp::srgbEncode
// (core/color.h) by < 1e-6 (tested), far below one 8-bit display step (1/255).
// Both paths use it, so they stay bit-identical.
float srgbEncodeFast(float linear);
// Y = 0.299 R' + 0.587 G' + 0.114 B' of the display-encoded colour.
float greyOf(float r, float g, float b);

// ---- Step 2: Sobel gradient magnitude (Fig. 2.9, eq. 2.2) -----------------
// z = sqrt(gx^2 + gy^2) over the 3 x 3 neighbourhood n[row][col] (y down).
float sobelMagnitude(const float n[3][3]);

// ---- Step 3: threshold (eq. 3.1 with the definition of sigma) ------------
// Gradient values below kBlackGradient are black: eq. 3.1 counts the
// non-black pixels only, and they are never edges. Not exactly zero: float
// rounding of the grey image (greys in [0, 1]) leaves Sobel values up to
// ~1e-6 in flat areas, and which of them round to exactly 0 differs between
// this code and the GPU's (shaders/repair.glsl), which moved T by 0.6 % on a
// viewport image and made ~200 pixels edges on one side only. One 8-bit
// display step of grey is 1/255 = 3.9e-3.
constexpr float kBlackGradient = 1e-5f;
// Statistics of the non-black gradient values, accumulated in double: each
// row in a fixed order (eight running sums over x mod 8, then the tail), then
// the row sums top to bottom, so the result does not depend on the number of
// threads or on the path.
struct RowStats {
  double count = 0, sum = 0, sumSquares = 0;
};
struct ThresholdStats {
  long count = 0;          // non-black gradient pixels
  double mean = 0;         // mu
  double sigma = 0;        // population standard deviation
  double threshold = 0;    // T = max(mu + kappa sigma, kBlackGradient)
};
RowStats rowStats(const float* gradientRow, int width);
ThresholdStats combineRowStats(const RowStats* rows, int height, float kappa);
// A gradient value after thresholding (Algorithm 1, lines 4-10): values below
// T are not edges (0). A pixel is an edge pixel iff edgeValue(z, T) > 0.
inline float edgeValue(float z, float threshold) { return z >= threshold ? z : 0.0f; }

// ---- Step 4: slope angle (eq. 3.2-3.6, Algorithm 3) -----------------------
struct SlopeFit {
  float alpha1 = 0;      // slope of the column means w_i over x_i (dy/dx, y down)
  float beta1 = 0;       // slope of the row means h_i over x_i (dx/dy, y down)
  float columnSpread = 0;  // sum of z (j - w_i)^2: how far each column spreads about its mean
  float rowSpread = 0;     // the same for the rows
};
// patch: n x n thresholded gradient values, patch[row * n + col], y down.
SlopeFit fitPatch(const float* patch, int n);
struct Direction {
  float cosTheta = 1, sinTheta = 0;  // unit vector, screen convention, theta in [0, 180)
};
Direction edgeDirection(const SlopeFit& fit, AngleEstimator estimator);
float directionDegrees(const Direction& d);  // theta in [0, 180)

// ---- Step 5: rotated smoothing mask (eq. 3.7 and bilinear eq. 3.8-3.9) ----
struct Mask {
  int radius = 0;        // taps are (w, h) in [-radius, radius]^2
  float weights[25] = {};  // row-major (2 radius + 1)^2, sum 1
};
const Mask& maskFor(MaskKind kind);
// Mask-weighted sum of bilinear samples of the packed RGBA image at the
// rotated tap offsets around pixel (x, y), with clamp-to-edge addressing.
void smoothPixel(const Image& rgba, int x, int y, const Direction& d, const Mask& mask, float out[4]);

// ---- The whole filter -----------------------------------------------------
// Instruction set of the fast path's row loops (grey, sanitise, Sobel,
// statistics). Auto: AVX2 when the CPU has it, else the x86-64 baseline
// (SSE2). Every choice gives the same bits (tested).
enum class RowIsa { Auto, Baseline };
const char* rowIsaName(RowIsa isa);  // "avx2" or "sse2": what `isa` runs here

class Kernel {
 public:
  // Allocates every buffer (called from Filter::onCommit, never in run()).
  void allocate(int width, int height);
  // Runs REPAIR from `color` (3/4 channels, any strides) to `output` (3/4
  // channels, same size; may be the same memory as `color`). The alpha is the
  // input's (sanitised; 1 for 3 channels): only the colour is smoothed.
  // reference = true: the scalar reference path (single thread, clamp-to-edge
  // addressing everywhere). false: the fast path (rows in parallel, edge
  // pixels found from the gradient rows, no clamping in the interior). Both
  // give bit-identical output.
  void run(const ImageView& color, const ImageView& output, const Settings& settings, bool reference,
           int numThreads);

  // For tests: force the baseline row loops on an AVX2 machine.
  void setRowIsa(RowIsa isa) { rowIsa_ = isa; }

  // Results of the last run, for tests and reports.
  const Image& staged() const { return staged_; }      // sanitised RGBA input
  const Image& grey() const { return grey_; }          // step 1 (reference path only: the fast path keeps 3 rows)
  const Image& gradient() const { return gradient_; }  // step 2 (before thresholding)
  const ThresholdStats& threshold() const { return stats_; }
  long edgeCount() const;  // pixels filtered in the last run
  // Step 4 at one pixel from the last run's gradient (clamp-to-edge patch).
  Direction directionAt(int x, int y, const Settings& settings) const;

 private:
  void runReference(const ImageView& color, const ImageView& output, const Settings& s);
  void runFast(const ImageView& color, const ImageView& output, const Settings& s, int numThreads);

  // Rows per band of the fast path's first pass (grey, Sobel, statistics).
  // Each band recomputes the 2 grey rows just outside it: 2/64 = 3% extra.
  static constexpr int kBandRows = 64;

  int width_ = 0, height_ = 0;
  Image staged_, grey_, gradient_;
  int bands_ = 0;
  std::vector<float> bandScratch_;  // per band: 3 grey rows + 1 RGBA row
  std::vector<char> bandSanitized_;  // per band: sanitising changed a value
  RowIsa rowIsa_ = RowIsa::Auto;
  std::vector<RowStats> rowStats_;
  std::vector<long> rowEdges_;
  ThresholdStats stats_;
};

}  // namespace crisp::repair
