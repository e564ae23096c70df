// SPDX-License-Identifier: Apache-2.0
// Release of held still pixels (taa.cpp and phlm.cpp "Hold").
//
// A held pixel keeps its converged value while its input repeats with the
// jitter's period P; a change that leaves that value inside the pixel's box
// would otherwise never be taken in (docs/temporal_figures.md, "Weakness
// of the hold"), and a still pixel that keeps averaging (taa after a
// feedback blend; phlm forgetting with lambda = 0.998) takes it in only over
// hundreds of frames. Each pixel sums its input over windows of P frames, as
// tonemapped luminance l = Y / (1 + Y) quantised to 0..255: a periodic input
// gives every window the same sum, exactly (integers, so every path and the
// GLSL preview get the same ones). A window that differs from the baseline
// (the last window that matched) by more than `limit` marks the pixel
// pending; if the next window differs too, a still pixel that averages or
// learns (held or not) is released: restarted from this frame's colour, as at
// a reset, and it averages its new input until it holds again. A window that
// matches clears the mark and becomes the baseline, so a one-frame event (a
// firefly) never releases anything. Windows are aligned on the kernel's frame
// count (frames since its reset; holdWindowEnds); a pixel that restarted, or
// did not stand still, has no complete window until the next boundary, and no
// baseline until the one after. So a change is taken in P to 2P frames after
// it began, up to 3P when the part of it in its first window stays within the
// limit (before the release, never; with holdPeriod 0 there is no hold and no
// release).
//
// limit = holdRelease x 255 x P: holdRelease is the change of a window's mean
// tonemapped luminance that counts; 1 never releases (a mean changes by at
// most 1), 0 releases on any change.
//
// State: one 32-bit word per pixel, read and written in place: bits 0-14 the
// running window's sum (at most 127 x 255 = 32385), bit 15 set while it has
// none (the pixel restarted during the window), bits 16-30 the baseline
// (0x7fff: none), bit 31 pending.
#pragma once

#include <algorithm>
#include <cstddef>
#include <cstdint>
#include <cstring>
#include <limits>
#include <vector>

#include "temporal/lanes.h"

namespace crisp::temporal {

constexpr std::uint32_t kHoldWindowNone = 0x7fff8000u;  // no sum, no baseline, not pending
constexpr int kHoldPeriodMax = 127;                       // so a window's sum fits in 15 bits

// Does the frame that follows `framesBefore` frames since the kernel's reset
// close a window of `period` frames?
inline bool holdWindowEnds(long framesBefore, int period) { return period > 0 && (framesBefore + 1) % period == 0; }

// The integer limit on |window - baseline| (see above), for holdRelease
// clamped to [0, 1] (NaN: 1, never) and 0 < period <= kHoldPeriodMax. The
// GLSL preview gets it from here (gpu_filters.py computes it in float32 too).
inline int holdWindowLimit(float holdRelease, int period) {
  float release = holdRelease > 1.0f ? 1.0f : holdRelease;
  if (!(release >= 0.0f)) release = release < 0.0f ? 0.0f : 1.0f;  // NaN: never
  return int(release * 255.0f * float(period));
}

// An already tonemapped luminance in [0, 1) quantised to 0..255.
template <class T>
CRISP_LANES_INLINE IntOf<T> holdLumaOfTonemapped(T l) {
  const T t = l * 255.0f + 0.5f;
  using M = MaskOfT<T>;
  return truncOf(M(M(t > 0.0f) & M(t < 256.0f)) ? t : lanesOf<T>(0.0f));
}
// Tonemapped linear luminance quantised to 0..255 (NaN -> 0).
template <class T>
CRISP_LANES_INLINE IntOf<T> holdLumaOfLinear(T luminance) {
  const T y = maxOf(luminance, lanesOf<T>(0.0f));
  return holdLumaOfTonemapped<T>(1.0f - 1.0f / (1.0f + y));
}

// A kernel's windows: one word per pixel, kept between frames.
struct HoldWindows {
  std::vector<std::uint32_t> words;
  int period = 0;  // the holdPeriod they were kept for (another restarts them)
  void allocate(std::size_t pixels) {
    words.assign(pixels, kHoldWindowNone);
    period = 0;
  }
  std::size_t bytes() const { return words.size() * sizeof(std::uint32_t); }
};
// What one frame's pixels need of them.
struct HoldWindowFrame {
  std::uint32_t* words = nullptr;  // read and written in place; null without a hold
  bool windowEnd = false;          // this frame closes a window (holdWindowEnds)
  int limit = 0;                   // holdWindowLimit
};
// Sets up a frame after `framesBefore` frames since the kernel's reset; a
// new period restarts every pixel's windows.
inline HoldWindowFrame holdWindowFrame(HoldWindows& windows, long framesBefore, int period, float holdRelease) {
  if (period != windows.period) {
    std::fill(windows.words.begin(), windows.words.end(), kHoldWindowNone);
    windows.period = period;
  }
  HoldWindowFrame f;
  if (period <= 0 || period > kHoldPeriodMax) return f;  // no hold (the parameter tables keep P in range)
  f.words = windows.words.data();
  f.windowEnd = holdWindowEnds(framesBefore, period);
  f.limit = holdWindowLimit(holdRelease, period);
  return f;
}

// The word of a pixel whose windows restart this frame.
constexpr std::uint32_t holdWindowRestarted(bool windowEnd) { return windowEnd ? 0x7fff0000u : kHoldWindowNone; }

// One frame of one pixel's windows (lanes: several pixels). still: the pixel
// averaged or learned in place this frame as a still pixel (held or not),
// without a reset, so it may be released; else its windows restart. Returns
// the new word; `released` gets the lanes to restart.
template <class T>
CRISP_LANES_INLINE IntOf<T> stepHoldWindow(IntOf<T> word, IntOf<T> luma, MaskOfT<T> still,
                                           bool windowEnd, int limit, MaskOfT<T>& released) {
  using Int = IntOf<T>;
  using M = MaskOfT<T>;
  const Int noBaseline = Int{} + 0x7fff0000;
  Int sum = (word & 0xffff) + luma;  // bit 15 kept: none
  Int baseline = word & 0x7fff0000;
  M pending = M(word < 0);
  released = M{};
  if (windowEnd) {
    const M hasSum = M((sum & 0x8000) == 0);
    const M complete = M(hasSum & M(baseline != noBaseline));
    const Int diff = (sum & 0x7fff) - (baseline >> 16);
    const M differs = M(complete & M(M(diff > limit) | M(diff < -limit)));
    released = M(M(still & differs) & pending);
    const M wait = M(M(still & differs) & notOf(pending));
    baseline = wait ? baseline : (hasSum ? Int(sum << 16) : noBaseline);
    pending = wait;
    sum = Int{};
  }
  const M restart = M(notOf(still) | released);
  const Int next = Int(pending ? Int{} + std::numeric_limits<int>::min() : Int{}) | baseline | sum;
  return restart ? Int{} + int(holdWindowRestarted(windowEnd)) : next;
}

// The words of a lane group.
template <class T>
CRISP_LANES_INLINE IntOf<T> loadHoldWords(const std::uint32_t* p) {
  IntOf<T> v;
  std::memcpy(&v, p, sizeof v);
  return v;
}
template <class T>
CRISP_LANES_INLINE void storeHoldWords(std::uint32_t* p, IntOf<T> v) {
  std::memcpy(p, &v, sizeof v);
}

}  // namespace crisp::temporal
