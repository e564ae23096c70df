// SPDX-License-Identifier: Apache-2.0
// PHLM's feature space (seed 002 §5.1; phlm.cpp "Deliberate choices"): the
// YCgCo luminance and the tonemap z = c / (1 + Y(c)) that bounds the temporal
// feature whatever the HDR range. Shared by the kernel (phlm.cpp) and its row
// staging (phlm_stage.cpp), which stages the tonemapped luminance Y / (1 + Y)
// of every input pixel; lumaYCgCo of a feature is that same value.
#pragma once

#include "filters/phlm_rls.h"

namespace crisp::phlm {

// YCgCo luminance (R + 2G + B) / 4 (§5.1); T the scalar, V T or lanes of T.
template <class T, class V>
CRISP_PHLM_INLINE V lumaYCgCo(const V c[3]) {
  return T(0.25) * c[0] + T(0.5) * c[1] + T(0.25) * c[2];
}

// The feature space: c / (1 + Y(c)) of the colour clamped to >= 0.
template <class T, class V>
CRISP_PHLM_INLINE void toFeature(const V c[3], V out[3]) {
  V p[3];
  for (int k = 0; k < 3; ++k) p[k] = c[k] < zeroOf<V>() ? zeroOf<V>() : c[k];  // std::max(c, 0)
  const V scale = oneOf<V>() / (oneOf<V>() + lumaYCgCo<T>(p));
  for (int k = 0; k < 3; ++k) out[k] = p[k] * scale;
}

}  // namespace crisp::phlm
