// SPDX-License-Identifier: Apache-2.0
// Sub-pixel jitter for temporal filters: the Halton(2,3) sequence (seed 004,
// "Halton sequence generator"; seed 000 §3.6.1 and appendix B) and the
// Blackman-Harris distribution EEVEE 3.x gives its own samples (BLENDER.md,
// "Sampling and jitter"), so a temporal filter fed frames jittered this way
// converges to EEVEE's many-sample reference (METHODS.md, "Jitter and
// references").
//
// EEVEE's filter_size s is the window's HALF width: EEVEE 3.x maps its Halton
// points through a Blackman-Harris inverse CDF spread over [-s, s] pixels
// (eevee_temporal_sampling.c: table scaled to [-2, 2], times filter_size, then
// applied as an NDC translation, i.e. halved in pixels). Measured: the mean of
// eight 1-sample renders jittered over [-s, s] matches EEVEE's 8-sample render
// to 31.6 dB, over [-s/2, s/2] to 23.6 dB (still_life 240x135).
//
// Convention: offsets are in PIXELS in the library's convention (x right,
// y DOWN, conventions.h): the sample of pixel (i, j) sits at
// (i + 0.5 + x, j + 0.5 + y). Blender's camera shift and the add-on's sidecar
// use y UP: jitterForFrame() returns y already negated, so its (x, y) is what
// the taa filter's jitterX / jitterY expect.
#pragma once

#include <algorithm>
#include <string>
#include <vector>

#include "core/params.h"

namespace crisp::temporal {

// The per-frame jitter parameters every temporal filter takes: jitterX,
// jitterY, jitterWeighting, filterSize, unjitter. weightMeaning and weightSource say what
// the Blackman-Harris sample weight does in that filter; pass string literals
// (the specs keep the pointers).
std::vector<ParamSpec> jitterParamSpecs(const char* weightMeaning, const char* weightSource);


// Radical inverse of index in base (index >= 1 gives a value in (0, 1)).
double radicalInverse(unsigned index, unsigned base);

// The 4-term Blackman-Harris window (Harris 1978: a0..a3 = 0.35875, 0.48829,
// 0.14128, 0.01168) on t in [0, 1] (0 at both ends, peak 1 at t = 0.5).
double blackmanHarrisWindow(double t);
// Its integral over [0, t], normalised to 1 at t = 1 (closed form).
double blackmanHarrisCdf(double t);
// Inverse of blackmanHarrisCdf, mapped to a pixel offset in [-width/2, width/2]
// (bisection in double precision: exact to ~1e-12 px, monotonic).
double blackmanHarrisInverse(double u, double width);

enum class JitterDistribution { Uniform, BlackmanHarris };

struct Jitter {
  float x = 0.0f;  // pixels, x right
  float y = 0.0f;  // pixels, y DOWN
};

// Jitter of frame `frame` as the add-on draws it (addon/crisp/render.py
// jitter_offset): Halton(2,3) point number (frame mod period) + 1; Uniform =
// the point minus 0.5 (inside the pixel); BlackmanHarris = each coordinate
// through the inverse CDF of a window spanning [-filterSize, filterSize]
// (EEVEE's filter_size, default 1.5). y is returned in the library convention
// (y down).
// The add-on integrates the CDF with a 1024-step trapezoid table; the closed
// form here should differ from it only by that table's interpolation error
// (expected ~1e-6 px; not yet cross-checked against the add-on by a test).
Jitter jitterForFrame(int frame, JitterDistribution distribution, float filterSize = 1.5f, int period = 16);

// Relative weight of a sample at offset (x, y) under EEVEE's separable
// Blackman-Harris pixel filter of size filterSize (support [-filterSize,
// filterSize]^2), normalised so that its mean over uniform offsets on that
// support is 1 (0 outside). Used
// to weight uniformly jittered samples so their weighted average converges to
// the Blackman-Harris-filtered image.
float blackmanHarrisWeight(float x, float y, float filterSize);

// The unjittered current colour of a pixel (parameter `unjitter`;
// METHODS.md "unjittered current colour"; Karis 2014). With jitter j the
// sample of pixel p sits at p + j; the sample nearest p's centre is that of
// pixel p - shift, shift = round(j) (halves away from zero) clamped to +-2, so
// |j - shift| <= 0.5 for |j| <= 2.5. Tap i (row order) of the 3x3 around it
// sits at (i % 3 - 1, i / 3 - 1) + j - shift from p's centre and is weighted by
// the Blackman-Harris pixel filter there (weights normalised; nearest: the
// centre tap alone). Averaged over jitter phases the weighted taps again give
// the filtered pixel, without the frame-to-frame jumps of p's own sample.
enum class UnjitterMode { None, Nearest, BlackmanHarris };
UnjitterMode parseUnjitterMode(const std::string& name);  // the parameter's values
struct Unjitter {
  bool enabled = false;
  int shiftX = 0, shiftY = 0;
  float weights[9] = {0, 0, 0, 0, 1, 0, 0, 0, 0};
};
Unjitter unjitterFor(UnjitterMode mode, float jitterX, float jitterY, float filterSize);

// The input index that index q of the shifted image reads: clamped to the
// image, shifted, clamped again (how the fast paths stage a shifted,
// edge-padded row; the reference paths read the same taps).
inline int shiftedSource(int q, int size, int shift) {
  const int c = q < 0 ? 0 : (q >= size ? size - 1 : q);
  const int s = c - shift;
  return s < 0 ? 0 : (s >= size ? size - 1 : s);
}

// A row of the shifted image padded by `pad` pixels each side (1 unless
// given): index k holds shiftedSource(k - pad, width, shiftX). The indices
// [lo, hi) whose source is not clamped: column k - pad - shiftX there (a copy
// of a run of the input); the rest are copies of column 0 or width - 1.
struct UnclampedRun {
  int lo, hi;
};
inline UnclampedRun unclampedRun(int width, int shiftX, int pad = 1) {
  const int lo = std::max(pad, pad + shiftX), hi = std::min(width, width + shiftX) + pad;
  return {lo, std::max(lo, hi)};
}
// f(k) for the indices [0, n) outside the unclamped run.
template <class F>
inline void forEachClampedIndex(const UnclampedRun& run, int n, F&& f) {
  for (int k = 0; k < std::min(run.lo, n); ++k) f(k);
  for (int k = run.hi; k < n; ++k) f(k);
}

}  // namespace crisp::temporal
