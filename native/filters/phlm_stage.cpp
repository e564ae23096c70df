// SPDX-License-Identifier: Apache-2.0
// PHLM's row staging (phlm_stage.h).
#include "filters/phlm_stage.h"

#include <cstddef>

#include "core/row_stage.h"
#include "filters/phlm_feature.h"
#include "temporal/lanes.h"
#include "temporal/velocity.h"

namespace crisp::phlm {

namespace {

// Lane groups of V (Vec4 or Vec8), then pixel by pixel: the same operations
// in every lane, so both copies give the same bits (the reference path runs
// the baseline one; the tests compare it with the AVX2 copy).
template <class V>
CRISP_PHLM_INLINE void stageRowBody(const StagedRow& r, int y) {
  using M = temporal::MaskOfT<V>;
  constexpr int n = temporal::kLanesOf<V>;
  const int w = r.color.width;
  float* d = r.staged + std::size_t(y) * w * 4;
  stageColorRow(r.color, y, d);  // sanitised RGBA (core/row_stage.h); lane 3 replaced below
  auto luma = [](auto red, auto green, auto blue) __attribute__((always_inline)) {
    using L = decltype(red);
    // std::max(v, 0) as selects; then Y / (1 + Y).
    const L c[3] = {red < L{} ? L{} : red, green < L{} ? L{} : green, blue < L{} ? L{} : blue};
    const L l = lumaYCgCo<float>(c);
    return l / (1.0f + l);
  };
  M alphaOne = M{} == M{};
  int x = 0;
  for (; x + n <= w; x += n) {
    V red, green, blue, alpha;
    temporal::loadInterleaved4(d + 4 * x, red, green, blue, alpha);
    alphaOne &= alpha == 1.0f;
    temporal::storeInterleaved4(d + 4 * x, red, green, blue, V(luma(red, green, blue)));
  }
  bool one = temporal::allOf(alphaOne);
  for (; x < w; ++x) {
    float* p = d + 4 * x;
    one &= p[3] == 1.0f;
    p[3] = luma(p[0], p[1], p[2]);
  }
  r.alphaOne[std::size_t(y)] = one;
  if (r.depthOut) stageDepthRow(r.depth, y, r.depthOut + std::size_t(y) * w);
  if (r.movingFlags) temporal::movingRow<V>(r.motion, y, r.movingFlags + std::size_t(y) * w);
}

}  // namespace

void stageRowBaseline(const StagedRow& r, int y) { stageRowBody<temporal::Vec4>(r, y); }
#ifdef CRISP_TEMPORAL_HAS_AVX2
CRISP_TEMPORAL_AVX2 void stageRowAvx2(const StagedRow& r, int y) { stageRowBody<temporal::Vec8>(r, y); }
#endif

}  // namespace crisp::phlm
