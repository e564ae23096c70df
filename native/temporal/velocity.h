// SPDX-License-Identifier: Apache-2.0
// Velocity selection and depth tests for reprojection (seed 000 §3.6.3: "en la
// vecindad 3x3 buscamos la velocidad del pixel con la profundidad mas cercana
// a la camara"; seed 004 "TAA steps" 2-4).
#pragma once

#include <cmath>
#include <cstddef>
#include <cstdint>
#include <cstring>
#include <type_traits>

#include "core/conventions.h"
#include "core/row_stage.h"
#include "temporal/jitter.h"
#include "temporal/lanes.h"
#include "temporal/vec4.h"

namespace crisp::temporal {

// Depth as the temporal filters use it: non-finite and far values read as
// background (conventions.h), so comparisons never see NaN.
// (core/row_stage.h's sanitizedDepth, which stages whole rows.)
inline float sanitizeDepth(float d) { return sanitizedDepth(d); }

// depth9: sanitised depths of the 3x3 block in row order (index 4 = centre).
// Returns the index of the closest (smallest) depth; the centre wins ties,
// then the first in row order, so the choice is deterministic.
inline int closestDepthTap(const float depth9[9]) {
  // Integer selects (all ones or 0): GCC turns a float select of the index
  // into branches, which depth edges make unpredictable.
  int best = 4;
  float bestDepth = depth9[4];
#pragma GCC unroll 9
  for (int i = 0; i < 9; ++i) {
    const int closer = -int(depth9[i] < bestDepth);
    best = (i & closer) | (best & ~closer);
    bestDepth = depth9[i] < bestDepth ? depth9[i] : bestDepth;
  }
  return best;
}

// closestDepthTap for `width` consecutive pixels of a row, a lane group of T
// (lanes.h: Vec4, Vec8) at a time: up/middle/down are the depth rows above,
// at and below, padded by one pixel on each side (pixel x's 3x3 is columns
// x .. x + 2). The same comparisons in the same order per lane, so the same
// taps as closestDepthTap. tap receives int bits (memcpy), so a float scratch
// row can hold them.
template <class T = Vec4>
CRISP_LANES_INLINE void closestDepthTapsRow(const float* up, const float* middle, const float* down, int width,
                                            float* tap, float* tapDepth) {
  using Int = IntOf<T>;
  constexpr int kL = kLanesOf<T>;
  const float* rows[3] = {up, middle, down};
  int x = 0;
  for (; x + kL <= width; x += kL) {
    T bestDepth = loadLanes<T>(middle + x + 1);
    Int best = Int{} + 4;
    for (int i = 0; i < 9; ++i) {
      const T d = loadLanes<T>(rows[i / 3] + x + i % 3);
      const Int closer = d < bestDepth;
      best = closer ? Int{} + i : best;
      bestDepth = closer ? d : bestDepth;
    }
    std::memcpy(tap + x, &best, sizeof best);
    storeLanes(tapDepth + x, bestDepth);
  }
  for (; x < width; ++x) {
    const float depth9[9] = {up[x],     up[x + 1],     up[x + 2],   middle[x], middle[x + 1],
                             middle[x + 2], down[x], down[x + 1], down[x + 2]};
    const int best = closestDepthTap(depth9);
    std::memcpy(tap + x, &best, sizeof best);
    tapDepth[x] = depth9[best];
  }
}

// Two depths belong to the same surface when they differ by at most
// `tolerance` times the nearer one (relative, as depth precision is).
// Background matches background.
// fmin written as a select (GCC calls libm's fminf otherwise, a call per
// tap): the same value as std::fmin for every input, NaN included (the other
// operand wins); of +0 and -0 either may be returned, which the product and
// comparison below cannot tell apart.
// T: float, or Vec8 (lanes.h) for eight pixels at once.
template <class T>
CRISP_LANES_INLINE MaskOfT<T> sameSurfaceDepth(T a, T b, float tolerance) {
  using M = MaskOfT<T>;
  const T nearer = M(M(b < a) | M(a != a)) ? b : a;
  return fabsOf(a - b) <= tolerance * nearer;
}

// A motion vector usable for reprojection: finite.
inline bool finiteMotion(float mx, float my) { return std::isfinite(mx) && std::isfinite(my); }

// A pixel m of a motion image moves: either component is not zero (NaN moves).
inline bool movesAt(const float* m) { return m[0] != 0.0f || m[1] != 0.0f; }

// Nothing in the 5x5 around (x, y) of the image shifted by (shiftX, shiftY)
// (jitter.h shiftedSource) moves: only then may a still pixel's history be
// tested against the wider footprint box, so that a moving object's colour (a
// trail, or a first frame's mix next to it) cannot hide in it (taa.cpp,
// phlm.cpp). No motion image: a still scene.
inline bool stillFootprint(const ImageView& motion, int x, int y, int width, int height, int shiftX, int shiftY) {
  if (!motion.ptr) return true;
  for (int i = 0; i < 25; ++i)
    if (movesAt(motion.pixel(shiftedSource(x + i % 5 - 2, width, shiftX), shiftedSource(y + i / 5 - 2, height, shiftY))))
      return false;
  return true;
}

// A still silhouette under the jitter: the surface of the previous frame's
// sample at (x, y), depth d, is in this frame's 5x5 around (x, y) (of the
// image shifted by (shiftX, shiftY)) and does not move there. Then a failed
// depth test at a still pixel is the jitter flipping which surface the
// pixel's own sample hits, not a disocclusion (an object that moved on leaves
// with its non-zero motion or is gone from the 5x5), and the pixel keeps its
// history (taa.cpp reprojectLanes, phlm.cpp phlmPixel).
// depthAt(sx, sy): the sanitised depth of source pixel (sx, sy), from the
// filter's own depth source. Both paths of a filter ask it alike.
template <class DepthAt>
inline bool stillSurfaceNear(const ImageView& motion, int x, int y, int width, int height, int shiftX, int shiftY,
                             float d, float tolerance, DepthAt depthAt) {
  for (int i = 0; i < 25; ++i) {
    const int sx = shiftedSource(x + i % 5 - 2, width, shiftX), sy = shiftedSource(y + i / 5 - 2, height, shiftY);
    if (sameSurfaceDepth(depthAt(sx, sy), d, tolerance) && !movesAt(motion.pixel(sx, sy))) return true;
  }
  return false;
}

// stillFootprint a row at a time, in two steps. movingRow: 1 where pixel
// (x, y) of the motion image moves (the same test), for one row of a plane
// of flags made once per frame. stillFootprintRow: every pixel of row y of
// that plane (width x height flags) at once into out[0 .. width) (1 =
// still): each column of the shifted image is tested once over the 5 rows,
// then a window of 5 columns, instead of 25 motion taps per pixel.
// `columns` holds width + 4 bytes of scratch.
// A motion view whose pixels loadFirstTwoChannels (lanes.h) may read a lane
// group at a time: 2 or 4 floats apart, and the view's own (a 2- or
// 3-channel view may have a 16-byte stride, and its last pixel then ends 8
// or 4 bytes before the next would start).
inline bool motionLanesReadable(const ImageView& motion) {
  return (motion.pixelStride == 8 || motion.pixelStride == 16) &&
         std::size_t(motion.channels()) * sizeof(float) == motion.pixelStride;
}
// V (Vec4, Vec8) takes whole pixels of 2 or 4 packed floats a lane group at
// a time, de-interleaved by shuffles; the flags are the same.
template <class V = float>
CRISP_LANES_INLINE void movingRow(const ImageView& motion, int y, std::uint8_t* out) {
  int x = 0;
  if constexpr (!std::is_same_v<V, float>) {
    using M = MaskOfT<V>;
    constexpr int n = kLanesOf<V>;
    const int step = int(motion.pixelStride / sizeof(float));
    if (motionLanesReadable(motion))
      for (const float* m = motion.pixel(0, y); x + n <= motion.width; x += n, m += n * step) {
        V mx, my;
        loadFirstTwoChannels(m, step, mx, my);
        storeBytesOf<V>(out + x, M(M(mx != 0.0f) | M(my != 0.0f)) & 1);
      }
  }
  for (; x < motion.width; ++x) out[x] = movesAt(motion.pixel(x, y)) ? 1 : 0;
}
inline void stillFootprintRow(const std::uint8_t* moving, int y, int width, int height, int shiftX, int shiftY,
                              std::uint8_t* __restrict columns, std::uint8_t* __restrict out) {
  const std::uint8_t* __restrict r0 = moving + std::size_t(shiftedSource(y - 2, height, shiftY)) * width;
  const std::uint8_t* __restrict r1 = moving + std::size_t(shiftedSource(y - 1, height, shiftY)) * width;
  const std::uint8_t* __restrict r2 = moving + std::size_t(shiftedSource(y, height, shiftY)) * width;
  const std::uint8_t* __restrict r3 = moving + std::size_t(shiftedSource(y + 1, height, shiftY)) * width;
  const std::uint8_t* __restrict r4 = moving + std::size_t(shiftedSource(y + 2, height, shiftY)) * width;
  auto column = [&](int k, int c) { columns[k] = r0[c] | r1[c] | r2[c] | r3[c] | r4[c]; };
  // Column k is shifted column k - 2 (the row padded by 2 each side).
  const UnclampedRun run = unclampedRun(width, shiftX, 2);
  forEachClampedIndex(run, width + 4, [&](int k) { column(k, shiftedSource(k - 2, width, shiftX)); });
  for (int k = run.lo; k < run.hi; ++k) column(k, k - 2 - shiftX);
  for (int x = 0; x < width; ++x)
    out[x] = (columns[x] | columns[x + 1] | columns[x + 2] | columns[x + 3] | columns[x + 4]) ? 0 : 1;
}

}  // namespace crisp::temporal
