// SPDX-License-Identifier: Apache-2.0
// RSAA clustering and offset verification (seed 003): the two-cluster split
// of Algorithm 1 (section 2.3.1), the 8-bit mask (section 2.3) and the two
// verification modes (sections 2.3.3 and 4.4.3).
#pragma once

#include <cstdint>

#include "rsaa/pattern.h"

namespace crisp::rsaa {

// Verification of the resampling offset.
//  * None: the mask's table offset as is.
//  * Reassign (2.3.3 second paragraph, 4.4.3 first): a "different" sample
//    stays different only if it is more similar to the centre of the
//    neighbouring pixel in its direction than to its own centre
//    (SADP(sample, neighbour) < SADP(sample, centre)); otherwise it joins
//    the centre's cluster. (METHODS.md words it the other way round; the
//    thesis' text and its figure 2.8 case need this direction.)
//  * Halve (2.3.3 third paragraph, 4.4.3 second): f = the different sample
//    farthest from the centre, N = the neighbouring centre in f's direction; the
//    offset is halved when SADP(centre, N) >= 2 SADP(centre, f), i.e. the
//    pixel the offset leans towards is far more unlike the centre than the
//    different sample is, so it does not show the sample's surface. 4.4.3
//    gives the factor 2; 2.3.3's "smaller than" reading would halve on every
//    ordinary edge (there SADP(centre, N) ~ SADP(centre, f)) and would not
//    fix figure 5.5 (polygon meets background), so we follow 4.4.3.
// Neighbours outside the image are not consulted (no change).
enum class Verification : int { None = 0, Reassign = 1, Halve = 2 };

// Algorithm 1: maxsim = max(0, SADP[i]); sample i is on the centre's polygon
// iff SADP[i] < maxsim / 2 + threshold / 2. Returns the mask (bit i = 1 on
// the centre's polygon). When no SADP reaches the threshold every bit is 1.
inline int splitMask(const float sadp[kSamples], float threshold) {
  float maxsim = 0.0f;
  for (int i = 0; i < kSamples; ++i)
    if (sadp[i] > maxsim) maxsim = sadp[i];
  const float split = 0.5f * maxsim + 0.5f * threshold;
  int mask = 0;
  for (int i = 0; i < kSamples; ++i)
    if (sadp[i] < split) mask |= 1 << i;
  return mask;
}

// Per-pattern constants of the verification modes.
struct PatternGeometry {
  int neighbourDx[kSamples];  // the neighbouring pixel in sample k's direction
  int neighbourDy[kSamples];
  int byDistance[kSamples];   // sample indices, farthest from the centre first
};

// The neighbouring pixel in the sample's direction: the direction from the
// centre to the sample quantised to the 8 neighbours (45-degree sectors).
// The thesis says "the nearest pixel"; for a sample on a diagonal the
// nearest centres are two edge neighbours, a tie that sends an axis-aligned
// edge's samples to the wrong side, so the diagonal neighbour is used there.
inline PatternGeometry patternGeometry(const Pattern& p) {
  PatternGeometry g{};
  for (int k = 0; k < kSamples; ++k) {
    const float ax = p.x[k] < 0 ? -p.x[k] : p.x[k], ay = p.y[k] < 0 ? -p.y[k] : p.y[k];
    // tan(22.5 deg) = 0.41421356: within 22.5 degrees of an axis -> that axis.
    const float t = 0.41421356f;
    g.neighbourDx[k] = ax > t * ay ? (p.x[k] > 0 ? 1 : -1) : 0;
    g.neighbourDy[k] = ay > t * ax ? (p.y[k] > 0 ? 1 : -1) : 0;
    if (g.neighbourDx[k] == 0 && g.neighbourDy[k] == 0) g.neighbourDx[k] = 1;  // a sample on the centre
    g.byDistance[k] = k;
  }
  // Stable insertion sort by decreasing distance (ties keep index order).
  for (int i = 1; i < kSamples; ++i) {
    const int k = g.byDistance[i];
    const float dk = p.x[k] * p.x[k] + p.y[k] * p.y[k];
    int j = i;
    for (; j > 0; --j) {
      const int m = g.byDistance[j - 1];
      if (p.x[m] * p.x[m] + p.y[m] * p.y[m] >= dk) break;
      g.byDistance[j] = m;
    }
    g.byDistance[j] = k;
  }
  return g;
}

}  // namespace crisp::rsaa
