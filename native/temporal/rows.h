// SPDX-License-Identifier: Apache-2.0
// Row loops shared by the temporal kernels (taa, taa-improved, phlm).
#pragma once

#include <type_traits>

namespace crisp::temporal {

// Calls fn(clamp, x, y) for every pixel of rows [y0, y1) of a width x height
// image, clamp = std::true_type where a 3x3 stencil at (x, y) may leave the
// image (border pixels; everywhere when clampAll, the reference paths) and
// std::false_type inside, so interior pixels read their taps without clamps
// (the same taps, so the same bits). Always inlined, so a row loop compiled
// for AVX2 (temporal/isa.h) keeps its pixel code in that copy.
template <class Fn>
__attribute__((always_inline)) inline void rowsWithBorder(int width, int height, int y0, int y1, bool clampAll, Fn&& fn) {
  for (int y = y0; y < y1; ++y) {
    if (clampAll || y == 0 || y == height - 1 || width < 3) {
      for (int x = 0; x < width; ++x) fn(std::true_type{}, x, y);
    } else {
      fn(std::true_type{}, 0, y);
      for (int x = 1; x < width - 1; ++x) fn(std::false_type{}, x, y);
      fn(std::true_type{}, width - 1, y);
    }
  }
}

}  // namespace crisp::temporal
