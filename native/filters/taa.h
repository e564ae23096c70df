// SPDX-License-Identifier: Apache-2.0
// TAA baseline (seed 000 chapter III; METHODS.md "TAA baseline"): the kernel
// and its history, drivable by tests and benchmarks without the Filter
// interface. The filter "taa" (taa.cpp) wraps it.
//
// History kept between frames (bytesKeptBetweenFrames): two RGBA float
// images (ping-pong: the reprojected fetch reads neighbours of the pixel being
// written) holding the accumulated colour in the clip space plus a signed
// sample weight, and, only when the filter is committed with depth, two float
// depth planes (this frame's and the previous frame's), a 1-byte
// history-state plane (feedback since reset, frames since reset) and a
// 4-byte plane of the hold's windows (temporal/hold_release.h). Scratch
// (bytesScratch): per row band of the fast path, a ring of five staged rows
// as planes (colour in the clip space, motion x and y; the output's alpha is
// read from the input), five depth rows and the row's closest-depth taps; the
// current frame is staged on the fly (core/row_stage.h), never as a whole
// image. The per-pixel core is written once against temporal/lanes.h and run
// on one pixel (the scalar reference) or a lane group (the fast path), so
// both give the same bits; the fast row loop has an SSE2 (4 lanes), an AVX2
// (8) and an AVX-512 (16) copy (temporal/isa.h; the AVX-512 one is a unit of
// its own, filters/taa_rows.h).
#pragma once

#include <atomic>
#include <cstddef>
#include <cstdint>
#include <vector>

#include "core/aligned_vector.h"
#include "core/image.h"
#include "core/params.h"
#include "temporal/hold_release.h"
#include "temporal/jitter.h"

namespace crisp::taa {

enum class HistoryFilter { CatmullRom, Bilinear };
enum class ClipSpace { YCoCg, Rgb };
enum class JitterWeighting { None, BlackmanHarris };

struct Settings {
  float jitterX = 0.0f;  // this frame's sample offset, pixels, x right
  float jitterY = 0.0f;  // pixels, y DOWN (library convention; Blender's y up negated)
  JitterWeighting weighting = JitterWeighting::None;
  float filterSize = 1.5f;  // width of the Blackman-Harris pixel filter for weighting (EEVEE's filter_size)
  HistoryFilter historyFilter = HistoryFilter::CatmullRom;
  ClipSpace clipSpace = ClipSpace::Rgb;  // taa.cpp "Deliberate choices"
  float feedbackMin = 0.7f;   // history weight for a large luma difference (seed 000: 0.88)
  float feedbackMax = 0.85f;  // history weight for equal lumas (seed 000: 0.97)
  float sharpen = 0.0f;       // 0 = off, 1 = the full [0,-1,0;-1,5,-1;0,-1,0] kernel (eq. 3.1)
  bool staticAccumulation = true;
  int maxSamples = 128;       // cap of the running average's sample count (weighted units)
  float varianceClip = 1.0f;  // taa.cpp "Deliberate choices": the feedback box within mean +- gamma sigma; 0 = off
  float resampleDamping = 0.3f;  // taa.cpp "Deliberate choices": history weight lowered at sub-pixel motion
  int holdPeriod = 16;        // taa.cpp "Hold": the jitter sequence's period in frames; 0 = no hold
  float holdRelease = 0.002f;  // taa.cpp "Hold": a still pixel whose input changes by this much restarts; 1 = never
  bool staticClip = true;     // clip history in static pixels too (rejects cuts, fireflies, light changes)
  float depthTolerance = 0.05f;  // relative depth difference still the same surface
  temporal::UnjitterMode unjitter = temporal::UnjitterMode::BlackmanHarris;  // taa.cpp "Jitter"
  // Steering by a per-pixel aliasedValue plane (Inputs::aliasedValue; seed 000
  // §4.3.4, used by taa-improved): the moving path's box is
  // mix(cross, 3x3, a) (eq. 4.15) instead of the rounded box, and/or shrunk
  // toward the current colour by a (eq. 4.16). Ignored without a plane.
  bool aliasedNeighbourhood = true;
  bool aliasedBoxSize = true;
};

struct Inputs {
  ImageView color;   // required, 3-4 float channels
  ImageView motion;  // optional (ptr null = static scene): 2-4 channels, pixels, previous - current, y down
  ImageView depth;   // optional: planar depth, channel 0
  ImageView output;  // required, 3-4 channels
  // optional: aliasedValue in [0, 1] per pixel, packed width x height floats
  // (taa-improved). Null: the baseline's rounded box.
  const float* aliasedValue = nullptr;
};

// The "taa" parameter table and its reading into Settings (shared with
// taa-improved, which adds its own parameters). filterName names errors.
std::vector<ParamSpec> parameterSpecs();
void readSettings(const ParamSet& p, const char* filterName, Settings& settings);

class Kernel {
 public:
  // withDepth: keep depth planes (needed to run with depth; without, runs
  // given depth throw). Same size: keeps the history, also when depth
  // appears or goes.
  void allocate(int width, int height, bool withDepth = true);
  // Forgets the history: the next frame is a first frame (bootstrap).
  void reset();
  // One frame. reference: the scalar path (one thread, clamp-to-edge on every
  // tap); otherwise row bands on numThreads threads with unclamped interior
  // taps. Both give bit-identical outputs and histories.
  void run(const Inputs& in, const Settings& s, bool reference, int numThreads);

  std::size_t bytesKeptBetweenFrames() const;
  std::size_t bytesScratch() const;
  int framesSinceReset() const { return frames_; }
  ClipSpace historySpace() const { return historySpace_; }
  // Pixels of the last run whose non-finite guard fired (a blend that was not
  // finite, reset to the current colour). Inputs are sanitised first, so
  // this stays 0 unless the kernel is wrong; the stability tests assert it.
  long guardsLastFrame() const { return guards_.load(std::memory_order_relaxed); }
  // Pixels of the last run whose history started over at the current colour:
  // no usable history (the first frame, an off-screen, non-finite or
  // disoccluded reprojection, a zero sample weight) or the guard above.
  // Counted per row. Where nothing moved (zero or no motion, the same depth)
  // no pixel has a reason to start over after the first frame; the stability
  // tests assert that, and that the count is live where things move.
  long resetsLastFrame() const { return resets_.load(std::memory_order_relaxed); }
  // Still pixels of the last run released from the hold (taa.cpp "Hold"):
  // their input changed for two windows running. Not in resetsLastFrame.
  long releasesLastFrame() const { return releases_.load(std::memory_order_relaxed); }
  // Some input alpha of the last run was not 1 (sanitised; an RGB input's is
  // 1), seen as the output's alpha was written: filters/temporal_alpha.h.
  bool alphaBelowOneLastFrame() const { return alphaBelowOne_.load(std::memory_order_relaxed); }
  // The largest accumulated sample weight W (Kernel::history_'s fourth plane,
  // either sign) over the pixels after the last run; 0 without history. The
  // running average caps it at Settings::maxSamples (taa.cpp "Static-scene
  // accumulation"). Scans the plane on each call: for tests and diagnostics.
  float largestSampleWeight() const;
  // The previous frame's sanitised depth plane (width x height), or null when
  // the previous frame had none or there is no history. Valid until run().
  const float* previousDepth() const {
    return frames_ > 0 && previousDepthValid_ && !depth_[current_].empty() ? depth_[current_].data() : nullptr;
  }
  // The plane the next run() writes its sanitised depth into (width x height),
  // or null without depth planes. A caller may stage this frame's depth into
  // it before run() (taa-improved does, to read it in its own passes); run()
  // overwrites it with the same values.
  float* nextDepthPlane() { return depth_[1 - current_].empty() ? nullptr : depth_[1 - current_].data(); }

 private:
  int width_ = 0, height_ = 0;
  int bands_ = 0;                  // row bands of the fast path
  std::vector<float> bandScratch_;  // bands_ x scratchFloatsPerBand()
  std::size_t scratchFloatsPerBand() const;
  // The history written by the last run and the one before, each width x
  // height x 4 floats as four planes (not interleaved, so eight pixels' taps
  // are one load): colour in the clip space of that run, then the signed
  // sample weight (negative: the pixel was moving). Cache-line aligned: the
  // AVX-512 rows stream them (Frame::streamHistory).
  AlignedVector<float> history_[2];
  // One byte per pixel, read and written in place (each pixel touches only
  // its own entry). Bit 0: the history went through the feedback path
  // (moving, or static history rejected) since its last reset; such history
  // is tested against the 3x3 box only, the rest against the footprint box.
  // Bits 1-7: frames since that reset, saturating at 127 (taa.cpp "Hold").
  std::vector<std::uint8_t> historyState_;
  // Per pixel, in place, its input's windows of holdPeriod frames
  // (temporal/hold_release.h).
  temporal::HoldWindows holdWindows_;
  std::vector<float> depth_[2];
  std::vector<int> sourceColumn_;  // per frame: the input column of each staged plane index (taa.cpp)
  int current_ = 0;           // index of the history written last
  int frames_ = 0;            // frames since reset; 0 = no history
  bool previousDepthValid_ = false;
  ClipSpace historySpace_ = ClipSpace::YCoCg;
  std::atomic<long> guards_{0};
  std::atomic<long> resets_{0};
  std::atomic<long> releases_{0};
  std::atomic<bool> alphaBelowOne_{false};
};

}  // namespace crisp::taa
