// SPDX-License-Identifier: Apache-2.0
// Velocity selection and depth tests for reprojection (seed 000 §3.6.3: "en la
// vecindad 3x3 buscamos la velocidad del pixel con la profundidad mas cercana
// a la camara"; seed 004 "TAA steps" 2-4).
#pragma once

#include <cmath>

#include "core/conventions.h"

namespace crisp::temporal {

// Depth as the temporal filters use it: non-finite and far values read as
// background (conventions.h), so comparisons never see NaN.
inline float sanitizeDepth(float d) { return isBackgroundDepth(d) || std::isnan(d) ? kBackgroundDepth : d; }

// depth9: sanitised depths of the 3x3 block in row order (index 4 = centre).
// Returns the index of the closest (smallest) depth; the centre wins ties,
// then the first in row order, so the choice is deterministic.
inline int closestDepthTap(const float depth9[9]) {
  // Branch-free (selects, not jumps: depth edges are unpredictable); the
  // running best depth is carried instead of re-read.
  int best = 4;
  float bestDepth = depth9[4];
  for (int i = 0; i < 9; ++i) {
    const bool closer = depth9[i] < bestDepth;
    best = closer ? i : best;
    bestDepth = closer ? depth9[i] : bestDepth;
  }
  return best;
}

// Two depths belong to the same surface when they differ by at most
// `tolerance` times the nearer one (relative, as depth precision is).
// Background matches background.
inline bool sameSurfaceDepth(float a, float b, float tolerance) {
  return std::fabs(a - b) <= tolerance * std::fmin(a, b);
}

// A motion vector usable for reprojection: finite.
inline bool finiteMotion(float mx, float my) { return std::isfinite(mx) && std::isfinite(my); }

}  // namespace crisp::temporal
