// SPDX-License-Identifier: Apache-2.0
// PHLM, pixel history linear models (seed 002; METHODS.md "PHLM"): the kernel
// and its per-pixel state, drivable by tests and benchmarks without the
// Filter interface, templated on the scalar type: Kernel<float> is the
// product (the "phlm" filter, phlm.cpp), Kernel<double> the test oracle.
// The stabilised RLS math is in phlm_rls.h.
//
// State kept between frames (bytesKeptBetweenFrames), allocated in
// allocate() (the filter's onCommit), never in run():
//  * one record of kRecord = 25 scalars per pixel (rows padded to a multiple
//    of kBlock = 8 pixels; recordIndex below): beta (12), the UD factors
//    of P (10), the temporal feature z (3); two such buffers (ping-pong) when
//    motion is given, because a pixel reads the model of another pixel; one
//    when the scene is static (no motion image: updated in place, no
//    reprojection work). float: 100 bytes per pixel per buffer.
//  * with motion: the intercepts beta[0] of both record buffers again, as
//    three planes of padded rows each (phlm.cpp "Model fetch": the
//    Catmull-Rom fetch reads them), 24 bytes per pixel in float.
//  * with depth: two float depth planes (this frame's and the previous one).
//  * with motion: one byte per pixel, set when the pixel's model moved, saw
//    motion in its 5x5 or was box-corrected since its reset (it then keeps
//    the 3x3 box; phlm.cpp "Box").
//  * one byte per pixel: the samples in the pixel's still model since its
//    reset or last box correction (phlm.cpp "Hold").
//  * four bytes per pixel: the hold's windows of the pixel's input
//    (temporal/hold_release.h; phlm.cpp "Hold").
// So at 1920x1080 (float): 218 MB static, 477 MB with motion, 494 MB with
// motion and depth (test Phlm.MemoryKeptBetweenFrames, bench counter kept_MB).
// Scratch (bytesScratch): the staged, sanitised frame (RGB + tonemapped
// luminance, float) and two counters per row.
#pragma once

#include <array>
#include <algorithm>
#include <cstddef>
#include <cstdint>
#include <vector>

#include "core/aligned_vector.h"
#include "core/image.h"
#include "filters/phlm_rls.h"
#include "temporal/hold_release.h"
#include "temporal/jitter.h"

namespace crisp::phlm {

enum class JitterWeighting { None, BlackmanHarris };
// How a moving pixel's beta is reprojected (P, U/D: always nearest; phlm.cpp "Model fetch"):
// CatmullRom = the intercepts by Catmull-Rom clamped to the central 2x2, the
// slopes bilinear; Bilinear = all of beta bilinear; Nearest.
enum class ModelFetch { CatmullRom, Bilinear, Nearest };

// The records are stored in blocks of kBlock pixels of a row, each block the
// kRecord scalars as planes of kBlock lanes (scalar j of the block's pixel i at
// j * kBlock + i): the layout of phlm.cpp's 8-lane batch, which loads and
// stores a block's model as whole vectors. Rows are padded to whole blocks.
constexpr int kBlock = 8;
// A pixel as an index into the padded rows of the records (blocksPerRow *
// kBlock pixels a row).
inline std::size_t paddedPixel(int blocksPerRow, int x, int y) {
  return std::size_t(y) * std::size_t(blocksPerRow) * kBlock + std::size_t(x);
}
// Where scalar 0 of a padded pixel's record is; scalar j at + j * kBlock.
inline std::size_t recordIndexOf(std::size_t paddedPixel) {
  return paddedPixel / kBlock * (kRecord * kBlock) + paddedPixel % kBlock;
}
// The same for pixel (x, y).
inline std::size_t recordIndex(int blocksPerRow, int x, int y) {
  return recordIndexOf(paddedPixel(blocksPerRow, x, y));
}

// Row y of intercept c (0-2) in the intercept planes kept with motion
// (phlm.cpp "Model fetch"): the three intercepts' rows of a pixel row follow
// each other (padded rows of blocksPerRow blocks), so a 4x4 footprint's taps
// lie in one window of memory.
template <class T>
inline T* interceptRow(T* intercepts, int blocksPerRow, int c, int y) {
  return intercepts + (std::size_t(y) * 3 + std::size_t(c)) * std::size_t(blocksPerRow) * kBlock;
}

struct Settings {
  float jitterX = 0.0f;  // this frame's sample offset, pixels, x right
  float jitterY = 0.0f;  // pixels, y DOWN (library convention)
  JitterWeighting weighting = JitterWeighting::None;
  float filterSize = 1.5f;       // Blackman-Harris width for the weighting
  double lambda = 0.998;         // forgetting factor (eqs. 6-7)
  double lambdaMoving = 0.7;     // forgetting factor of moving pixels (phlm.cpp header, "Forgetting")
  int holdPeriod = 16;           // still models with this many samples are held (phlm.cpp, "Hold"); 0: off
  float holdRelease = 0.002f;    // a still model whose input changes by this much restarts (phlm.cpp, "Hold"); 1: never
  double resampleDamping = 0.25;  // moving pixels forget with lambdaMoving (1 - beta s) (phlm.cpp, "Forgetting")
  double initialCovariance = 1000.0;  // p0: intercept variance at init/reset (§6) and its bound
  double slopeCovariance = 1.0;       // ps: slope variances at init/reset and their bound (§6 has 1000)
  double featureA = 0.125;       // a of phi (§5.1)
  double featureB = 0.25;        // b of phi (§5.1)
  double featureAlphaMin = 0.05;  // floor of the feature's current-frame weight (this file)
  float depthTolerance = 0.05f;  // relative depth difference still the same surface
  ModelFetch modelFetch = ModelFetch::CatmullRom;
  double boxResetCovariance = 1000.0;  // intercept variance after a box correction (P scaled from P0)
  bool footprintBox = true;  // still pixels: correct/clamp against the footprint box (phlm.cpp header)
  temporal::UnjitterMode unjitter = temporal::UnjitterMode::BlackmanHarris;  // phlm.cpp header, "Jitter"
};

struct Inputs {
  ImageView color;   // required, 3-4 float channels
  ImageView motion;  // optional: pixels, previous - current, y down; null = static scene
  ImageView depth;   // optional: planar depth, channel 0
  ImageView output;  // required, 3-4 channels
};

// Per-frame counts (diagnostics and tests).
struct FrameStats {
  // Off-screen, non-finite motion, disocclusion, first frame; none where
  // nothing moved (test_phlm_stability.cpp asserts it).
  long reprojectionResets = 0;
  long boxResets = 0;           // prediction outside the 3x3 box (Algorithm 1 line 16)
  long releases = 0;            // still models restarted by the hold's release (phlm.cpp "Hold"; not in the above)
  // Safety nets that fired: a non-finite prediction, a beta that overflowed
  // (the model restarts), an output not finite before its sanitise. Inputs
  // are sanitised first and P is bounded, so this stays 0 unless the kernel
  // is wrong; the stability tests assert it.
  long guards = 0;
};

template <class T>
class Kernel {
 public:
  // withMotion: allocate the second model buffer (reprojection). withDepth:
  // the depth planes. A call with the same size keeps the history (a buffer
  // added for motion starts as a copy of the current one).
  void allocate(int width, int height, bool withMotion, bool withDepth);
  // Forgets the history: the next frame is a first frame.
  void reset();
  // One frame. reference: the reference path (one thread, clamp-to-edge on
  // every tap, the baseline instruction set); otherwise row bands on
  // numThreads threads with unclamped interior taps (and the AVX2 copy where
  // the CPU has it). Both give bit-identical outputs and states.
  void run(const Inputs& in, const Settings& s, bool reference, int numThreads);

  std::size_t bytesKeptBetweenFrames() const;
  std::size_t bytesScratch() const;
  int framesSinceReset() const { return frames_; }
  const FrameStats& lastStats() const { return stats_; }
  // Some input alpha of the last run was not 1 (sanitised; an RGB input's is
  // 1), from the rows' staging: filters/temporal_alpha.h.
  bool alphaBelowOneLastFrame() const {
    return frames_ > 0 && std::find(alphaOne_.begin(), alphaOne_.end(), 0) != alphaOne_.end();
  }
  // The record (kRecord scalars, phlm_rls.h layout) of pixel (x, y) after the last run.
  std::array<T, kRecord> record(int x, int y) const {
    std::array<T, kRecord> r;
    const T* first = models_[current_].data() + recordIndex(blocksPerRow_, x, y);
    for (int j = 0; j < kRecord; ++j) r[std::size_t(j)] = first[std::size_t(j) * kBlock];
    return r;
  }
  // With motion: pixel (x, y)'s intercepts in the planes kept beside the
  // records (phlm.cpp "Model fetch"); they equal record(x, y)[0..2] after
  // every frame with motion.
  std::array<T, 3> planarIntercepts(int x, int y) const {
    std::array<T, 3> r;
    for (int c = 0; c < 3; ++c)
      r[std::size_t(c)] = interceptRow(intercepts_[current_].data(), blocksPerRow_, c, y)[x];
    return r;
  }
  int width() const { return width_; }
  int height() const { return height_; }

 private:
  int width_ = 0, height_ = 0, blocksPerRow_ = 0;
  bool withMotion_ = false, withDepth_ = false;
  Image staged_;
  AlignedVector<T> models_[2];  // aligned: written with streaming stores (phlm.cpp streamLanes)
  std::vector<float> depth_[2];
  temporal::HoldWindows holdWindows_;  // per pixel: its input's windows (temporal/hold_release.h)
  std::vector<std::uint8_t> stillSamples_;  // per pixel: samples in its still model since its reset or box correction (phlm.cpp "Hold")
  AlignedVector<T> intercepts_[2];  // with motion: the records' intercepts as planes, ping-pong (phlm.cpp "Model fetch")
  bool interceptsValid_ = false;   // intercepts_[current_] holds the current records' intercepts
  std::vector<std::uint8_t> narrowBox_;  // with motion: per pixel, its model keeps the 3x3 box (phlm.cpp "Box")
  std::vector<std::uint8_t> movingFlags_;  // with motion: this frame's temporal::movingRow flags (fast path)
  std::vector<FrameStats> rowStats_;  // this frame's counts, per row
  std::vector<std::uint8_t> alphaOne_;  // per row of this frame: every input alpha is 1 (or there is none)
  int current_ = 0;
  int frames_ = 0;
  bool previousDepthValid_ = false;
  FrameStats stats_;
};

extern template class Kernel<float>;
extern template class Kernel<double>;

}  // namespace crisp::phlm
