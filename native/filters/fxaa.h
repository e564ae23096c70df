// SPDX-License-Identifier: Apache-2.0
// FXAA 3.11, "quality" path (T. Lottes, "FXAA", NVIDIA whitepaper, 2009/2011,
// and the description of version 3.11's quality algorithm), written from that
// description. The filter "fxaa" (fxaa.cpp) is a thin wrapper over the kernels
// declared here; tests and benchmarks call them directly.
//
// Two paths, bit-identical by construction and by test:
//  * runReference: single thread, unpadded luma plane, clamp-to-edge on every
//    fetch. The source of truth.
//  * runFast: rows in parallel (crisp::parallelRows). Pass 1 writes the
//    sanitised colour to the output and the luma plane in one sweep (SSE2 for
//    packed RGBA, with non-temporal stores for frames of 8 MiB and more;
//    compiler-vectorised loops for packed RGB), the plane padded by
//    clamp-to-edge copies so no luma fetch needs a clamp, and runs the
//    vectorised contrast check on rows whose neighbours it has just made.
//    Pass 2 runs the per-pixel search only on pixels that passed the check,
//    with unclamped colour fetches away from the first/last row/column.
// Both evaluate the same per-pixel arithmetic (fxaa.cpp) in the same order
// (the library builds with -ffp-contract=off), so only addressing and
// scheduling differ.
#pragma once

#include <cstdint>
#include <cstring>
#include <vector>

#include "core/conventions.h"
#include "core/image.h"

namespace crisp::fxaa {

struct Settings {
  // Early exit when the local luma range (centre + 4 neighbours) is below
  // max(edgeThresholdMin, edgeThreshold * local max luma) (whitepaper:
  // "local contrast check"; FXAA_QUALITY__EDGE_THRESHOLD(_MIN)).
  float edgeThreshold = 0.166f;
  float edgeThresholdMin = 0.0833f;
  // Amount of sub-pixel aliasing removal (FXAA_QUALITY__SUBPIX): scales the
  // blend derived from the 3x3 low-pass.
  float subpix = 0.75f;
};

// Quality preset 12 (the default preset of FXAA 3.11): distances, in pixels,
// of the successive steps of the end-of-edge search on each side. The first
// entry is the first look; every later step moves a side that has not found
// its end yet and looks again, except the last, which is taken blind (the
// search assumes the edge ends there).
inline constexpr float kSearchSteps[] = {1.0f, 1.5f, 2.0f, 4.0f, 12.0f};
inline constexpr int kSearchStepCount = int(sizeof(kSearchSteps) / sizeof(kSearchSteps[0]));
// Furthest any luma fetch lands from the centre along the edge: all steps but
// the last (1 + 1.5 + 2 + 4 = 8.5 px), plus one texel for the bilinear tap.
inline constexpr int kLumaPad = 10;

// Perceptual luma used by every decision: Rec. 709 luminance Y of the linear
// colour (negative clamped to 0), tone-mapped to [0,1) by Y/(1+Y) so HDR
// values stay bounded, then square-rooted (gamma 2), which brings it close to
// the display-encoded luma FXAA's thresholds were tuned for (Y = 0.18 -> 0.39,
// sRGB gives 0.46; Y = 0.05 -> 0.22, sRGB 0.25). Inputs must be finite.
float perceptualLuma(float r, float g, float b);

// Same result as crisp::sanitizeColor (core/color.h) for every input (tested),
// written as selects so the row loops vectorise: NaN -> 0, clamp to
// +-kMaxColor. Every colour read of both paths goes through it.
inline float sanitize(float v) {
  v = v != v ? 0.0f : v;
  v = v < -kMaxColor ? -kMaxColor : v;
  return v > kMaxColor ? kMaxColor : v;
}

// True when the 8 contrast flags from `flags` (Workspace::searchFlags) are all
// 0: the scans of those flags skip 8 pixels at a time with it.
inline bool noneOf8(const std::uint8_t* flags) {
  std::uint64_t eight;
  std::memcpy(&eight, flags, 8);
  return eight == 0;
}

// Buffers of both paths, allocated once for a frame size (Filter::onCommit);
// the kernels never allocate.
class Workspace {
 public:
  void allocate(int width, int height);
  int width() const { return width_; }
  int height() const { return height_; }
  // Pixels that passed the contrast check in the last runFast (for benchmarks).
  std::size_t searchedPixels() const;
  // After runFast: one byte per pixel, row-major, 1 where the pixel passed the
  // contrast check. Only those pixels can differ from the sanitised colour
  // (rsaa's guard reads these instead of comparing every pixel).
  const std::uint8_t* searchFlags() const { return needsSearch_.data(); }

 private:
  friend struct Access;
  int width_ = 0;
  int height_ = 0;
  std::vector<float> luma_;        // reference: width x height
  std::vector<float> paddedLuma_;  // fast: (width + 2 pad) x (height + 2 pad)
  std::vector<std::uint8_t> needsSearch_;  // fast: per pixel, passed the contrast check
  std::vector<std::uint8_t> rowChecked_;   // fast: per row, contrast check done in pass 1
  std::vector<float> staging_;     // packed RGBA copy of colour, used when output overlaps it
};

// Filters `color` (3 or 4 float channels, any strides) into `output` (3 or 4
// channels, same size; may be the same memory as `color`). Alpha passes
// through (1 when colour has 3 channels). Non-finite input is sanitised
// (core/color.h sanitizeColor) before anything else. Throws
// crisp::Exception(INVALID_ARGUMENT) on size mismatch with the workspace.
void runReference(const ImageView& color, const ImageView& output, const Settings& settings, Workspace& workspace);
// numThreads: 0 = all cores.
void runFast(const ImageView& color, const ImageView& output, const Settings& settings, Workspace& workspace,
             int numThreads);

}  // namespace crisp::fxaa
