// SPDX-License-Identifier: Apache-2.0
// Neighbourhood colour statistics for history rejection (seed 000 §3.6.3,
// Fig. 3.7; Pedersen/INSIDE 2016): min, max and average over the 3x3 block and
// over the 5-tap cross, and their "rounded" mix (the mean of the two), plus
// clipping toward the box centre (seed 000 §3.6.4, Fig. 3.9: clip, not clamp).
#pragma once

#include <algorithm>
#include <cmath>

#include "temporal/color_space.h"
#include "temporal/lanes.h"
#include "temporal/vec4.h"

namespace crisp::temporal {

struct ColorBox {
  Float3 min, max, avg;
};

// Tap order of the 3x3 block, row by row: index 4 is the centre; the cross
// is {1, 3, 4, 5, 7}.
constexpr int kCrossTaps[5] = {1, 3, 4, 5, 7};

// taps[9]: the 3x3 block in row order (any colour space). Sums run in tap
// order so results are reproducible.
inline void neighbourhoodBoxes(const Float3 taps[9], ColorBox& box3x3, ColorBox& cross) {
  for (int c = 0; c < 3; ++c) {
    float lo = taps[0][c], hi = taps[0][c], sum = taps[0][c];
    for (int i = 1; i < 9; ++i) {
      lo = std::min(lo, taps[i][c]);
      hi = std::max(hi, taps[i][c]);
      sum += taps[i][c];
    }
    box3x3.min[c] = lo;
    box3x3.max[c] = hi;
    box3x3.avg[c] = sum * (1.0f / 9.0f);
    float clo = taps[1][c], chi = taps[1][c], csum = taps[1][c];
    for (int k = 1; k < 5; ++k) {
      const float t = taps[kCrossTaps[k]][c];
      clo = std::min(clo, t);
      chi = std::max(chi, t);
      csum += t;
    }
    cross.min[c] = clo;
    cross.max[c] = chi;
    cross.avg[c] = csum * 0.2f;
  }
}

// The "rounded" box: the average of the 3x3 and cross statistics, which trims
// the corners the diagonal taps add (Pedersen 2016; seed 000 §3.6.3: "los
// promediamos").
inline ColorBox roundedBox(const ColorBox& box3x3, const ColorBox& cross) {
  ColorBox r;
  for (int c = 0; c < 3; ++c) {
    r.min[c] = 0.5f * (box3x3.min[c] + cross.min[c]);
    r.max[c] = 0.5f * (box3x3.max[c] + cross.max[c]);
    r.avg[c] = 0.5f * (box3x3.avg[c] + cross.avg[c]);
  }
  return r;
}

// Smallest box half-extent used by clipping: keeps the ray/box division finite
// on a flat neighbourhood (min == max) without moving a point that is inside.
constexpr float kClipEpsilon = 1e-7f;

struct ClipResult {
  Float3 color;
  float excess;  // max over channels of |p - centre| / half-extent: > 1 = was outside
};

// Clips `p` toward the centre of [min, max] along the ray from the centre:
// the point where that segment leaves the box, or p itself if it is inside.
// Unlike a per-channel clamp, the hue of the clipped colour stays on the line
// to the centre (seed 000 Fig. 3.9).
inline ClipResult clipTowardCentre(const Float3& p, const Float3& min, const Float3& max) {
  Float3 centre, offset;
  float excess = 0.0f;
  for (int c = 0; c < 3; ++c) {
    centre[c] = 0.5f * (max[c] + min[c]);
    const float half = 0.5f * (max[c] - min[c]) + kClipEpsilon;
    offset[c] = p[c] - centre[c];
    excess = std::max(excess, std::fabs(offset[c]) / half);
  }
  if (!(excess > 1.0f)) return {p, excess};
  const float scale = 1.0f / excess;
  Float3 out;
  for (int c = 0; c < 3; ++c) out[c] = centre[c] + offset[c] * scale;
  return {out, excess};
}

// ---- 4-lane versions (RGBA in one Vec4; lane 3 rides along) ----------------
// Same definitions as above, lane-wise; the kernels use these.
struct ColorBox4 {
  Vec4 min, max, avg;
};

inline void neighbourhoodBoxes4(const Vec4 taps[9], ColorBox4& box3x3, ColorBox4& cross) {
  Vec4 lo = taps[0], hi = taps[0], sum = taps[0];
  for (int i = 1; i < 9; ++i) {
    lo = vmin(lo, taps[i]);
    hi = vmax(hi, taps[i]);
    sum += taps[i];
  }
  box3x3 = {lo, hi, sum * (1.0f / 9.0f)};
  Vec4 clo = taps[1], chi = taps[1], csum = taps[1];
  for (int k = 1; k < 5; ++k) {
    const Vec4 t = taps[kCrossTaps[k]];
    clo = vmin(clo, t);
    chi = vmax(chi, t);
    csum += t;
  }
  cross = {clo, chi, csum * 0.2f};
}

// Min and max only (the clip box), 3x3 and cross, reduced column first:
// column k of the 3x3 (taps k, 3+k, 6+k, top down), then the three columns
// left to right; the cross is min(left tap, centre column, right tap). This
// is the order a sliding-window fast path (shared column reductions) can
// reproduce exactly. min/max are exact, so it equals neighbourhoodBoxes4's
// min/max except for which of two equal values (+0 / -0) is returned.
struct MinMax4 {
  Vec4 min, max;
};
struct ColumnReduction4 {
  Vec4 min, max;
};
inline ColumnReduction4 reduceColumn4(Vec4 top, Vec4 middle, Vec4 bottom) {
  return {vmin(vmin(top, middle), bottom), vmax(vmax(top, middle), bottom)};
}
// left/centre/right: column reductions; west/east: the centre row's taps left and right.
inline void boxesFromColumns4(const ColumnReduction4& left, const ColumnReduction4& centre,
                              const ColumnReduction4& right, Vec4 west, Vec4 east, MinMax4& box3x3, MinMax4& cross) {
  box3x3 = {vmin(vmin(left.min, centre.min), right.min), vmax(vmax(left.max, centre.max), right.max)};
  cross = {vmin(vmin(west, centre.min), east), vmax(vmax(west, centre.max), east)};
}
inline void columnFirstBoxes4(const Vec4 taps[9], MinMax4& box3x3, MinMax4& cross) {
  boxesFromColumns4(reduceColumn4(taps[0], taps[3], taps[6]), reduceColumn4(taps[1], taps[4], taps[7]),
                    reduceColumn4(taps[2], taps[5], taps[8]), taps[3], taps[5], box3x3, cross);
}

inline ColorBox4 roundedBox4(const ColorBox4& a, const ColorBox4& b) {
  return {0.5f * (a.min + b.min), 0.5f * (a.max + b.max), 0.5f * (a.avg + b.avg)};
}

// The two largest and two smallest values per lane of a set of taps (a value
// present twice is both; taps repeated by clamp-to-edge count as often as
// they are read). Exact: the result does not depend on the order of the taps.
struct TwoExtremes4 {
  Vec4 max1, max2, min1, min2;
};
inline TwoExtremes4 twoExtremesOf(Vec4 a, Vec4 b) { return {vmax(a, b), vmin(a, b), vmin(a, b), vmax(a, b)}; }
inline void addTap(TwoExtremes4& e, Vec4 v) {
  e.max2 = vmax(e.max2, vmin(e.max1, v));
  e.max1 = vmax(e.max1, v);
  e.min2 = vmin(e.min2, vmax(e.min1, v));
  e.min1 = vmin(e.min1, v);
}
inline void mergeExtremes(TwoExtremes4& e, const TwoExtremes4& o) {
  e.max2 = vmax(vmin(e.max1, o.max1), vmax(e.max2, o.max2));
  e.max1 = vmax(e.max1, o.max1);
  e.min2 = vmin(vmax(e.min1, o.min1), vmin(e.min2, o.min2));
  e.min1 = vmin(e.min1, o.min1);
}

// The static test's footprint box (taa.cpp "Deliberate choices", phlm.cpp
// "Box"): the 3x3 box united with the 5x5 box of the second-largest /
// second-smallest values (per lane). The 5x5 covers the jitter's footprint; a
// colour must show in two of its 25 samples to widen the box, so one firefly
// nearby cannot make a firefly in the history pass.
inline MinMax4 footprintBox(const MinMax4& box3x3, const TwoExtremes4& e) {
  return {vmin(box3x3.min, e.min2), vmax(box3x3.max, e.max2)};
}

// The unjittered current colour (temporal/jitter.h Unjitter): the 3x3 taps
// (row order) weighted by `weights`, summed centre first, then the others in
// row order, so every path that calls it gets the same bits.
// T: Vec4 (a pixel's RGBA) or any lane type of one channel (lanes.h Vec8).
// W: float, or T with the weights broadcast once per row (same products).
template <class T, class W>
CRISP_LANES_INLINE T unjitteredMix(const T taps[9], const W weights[9]) {
  T sum = taps[4] * weights[4];
  for (int i = 0; i < 9; ++i)
    if (i != 4) sum = sum + taps[i] * weights[i];
  return sum;
}

// clipTowardCentre on lanes 0-2; lane 3 of the result is p's. *excess as above.
inline Vec4 clipTowardCentre4(Vec4 p, Vec4 min, Vec4 max, float* excess) {
  const Vec4 centre = 0.5f * (max + min);
  const Vec4 half = 0.5f * (max - min) + kClipEpsilon;
  const Vec4 offset = p - centre;
  const Vec4 ratio = vabs(offset) / half;
  const float e = std::max(std::max(ratio[0], ratio[1]), ratio[2]);
  *excess = e;
  if (!(e > 1.0f)) return p;
  Vec4 out = centre + offset * (1.0f / e);
  out[3] = p[3];
  return out;
}

}  // namespace crisp::temporal
