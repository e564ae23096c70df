// SPDX-License-Identifier: Apache-2.0
// The one place kernels get threads from: OpenImageIO's pool, split in rows.
// Kernels never create threads themselves.
#pragma once

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

}  // namespace crisp
