// SPDX-License-Identifier: Apache-2.0
// Temporal error (METHODS.md, Metrics): how much a sequence's frame-to-frame
// change differs from the reference's, so flicker that PSNR cannot see counts:
//
//   TE_t = mean over valid pixels p and RGB channels of
//          | (out_t(p) - W(out_{t-1})(p)) - (ref_t(p) - W(ref_{t-1})(p)) |
//
// W warps the previous frame to the current one along the motion vectors
// (conventions.h: pixel p of frame t was at p + motion.xy in frame t-1), read
// with bilinear interpolation; without motion vectors W is the identity (a
// static scene). Valid = p + motion.xy lands inside the previous frame and the
// optional mask (e.g. disocclusionMask) is > 0 at p. Like every metric in
// metrics.h it compares DISPLAY-ENCODED values (linear RGB clamped to [0,1],
// sRGB-encoded), so it is in the same units as the RMSE behind PSNR.
#pragma once

#include "core/image.h"

namespace crisp {

struct TemporalError {
  double value = 0;  // the mean above; 0 when no pixel is valid
  long pixels = 0;   // valid pixels counted
};

// out, outPrevious, reference, referencePrevious: linear RGB(A), all the same
// size. motion: nullptr (identity) or 2/4 channels of that size. mask: nullptr
// or 1 channel of that size. map (optional): set to one channel of that size
// holding each valid pixel's term (the mean over RGB of the |...| above) and 0
// elsewhere, so its sum over valid pixels / pixels is the value. Throws
// CRISP_ERROR_INVALID_DATA naming the image whose size or channel count does
// not fit.
TemporalError temporalError(const Image& out, const Image& outPrevious, const Image& reference,
                            const Image& referencePrevious, const Image* motion = nullptr, const Image* mask = nullptr,
                            int numThreads = 0, Image* map = nullptr);

// Warps `previous` (any channel count) to the current frame: result(p) =
// previous(p + motion.xy(p)), bilinear, clamped at the borders. valid (if not
// nullptr) gets 1 channel: 1 where p + motion.xy is inside the image, else 0.
Image warpPrevious(const Image& previous, const Image& motion, Image* valid = nullptr, int numThreads = 0);

// Disocclusion test for TE's mask: 1 where the current pixel's surface was
// visible in the previous frame at p + motion.xy, judged by the object ID
// (ids: Format::UInt, exact match at the nearest pixel) and/or planar depth
// (relative difference at most depthTolerance). Either pair may be nullptr
// (not tested); motion nullptr means no motion.
Image disocclusionMask(const Image* motion, const Image* ids, const Image* idsPrevious, const Image* depth,
                       const Image* depthPrevious, float depthTolerance = 0.1f, int numThreads = 0);

}  // namespace crisp
