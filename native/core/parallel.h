// SPDX-License-Identifier: Apache-2.0
// The one place kernels get threads from: OpenImageIO's pool, split in rows.
// Kernels never create threads themselves.
#pragma once

#include <cstdint>

#include <OpenImageIO/imagebufalgo_util.h>

namespace crisp {

// Calls fn(y0, y1) on disjoint row bands covering [0, height), on up to
// numThreads threads (0 = all). Small images run on the calling thread.
template <class Fn>
void parallelRows(int width, int height, int numThreads, Fn&& fn) {
  if (width <= 0 || height <= 0) return;
  OIIO::paropt opt(numThreads, OIIO::paropt::SplitDir::Y, 8192);
  OIIO::ImageBufAlgo::parallel_image(OIIO::ROI(0, width, 0, height), opt,
                                     [&](OIIO::ROI r) { fn(int(r.ybegin), int(r.yend)); });
}

// Calls fn(b, y0, y1) for each of `bands` bands of rows [0, height), band b
// covering [b h / bands, (b + 1) h / bands), on up to numThreads threads: for
// row loops whose bands own scratch (rings of rows) and restage a few rows
// beyond their edges. parallelRows hands out the bands as the rows of a
// virtual image 8192 wide, so every band is a task of its own.
template <class Fn>
void parallelBands(int height, int bands, int numThreads, Fn&& fn) {
  parallelRows(8192, bands, numThreads, [&](int b0, int b1) {
    for (int b = b0; b < b1; ++b)
      fn(b, int(std::int64_t(b) * height / bands), int(std::int64_t(b + 1) * height / bands));
  });
}

}  // namespace crisp
