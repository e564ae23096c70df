// SPDX-License-Identifier: Apache-2.0
// Temporal error of METHODS.md (Metrics): see temporal_error.h.
#include "metrics/temporal_error.h"

#include <algorithm>
#include <cmath>
#include <string>
#include <vector>

#include "core/conventions.h"
#include "core/error.h"
#include "core/parallel.h"
#include "metrics/metrics.h"

namespace crisp {

namespace {

void checkSame(const Image& a, const Image& b, const char* nameB, int minChannels, int maxChannels) {
  if (b.width != a.width || b.height != a.height)
    invalidData(std::string("temporal error: ") + nameB + " is " + std::to_string(b.width) + "x" +
                std::to_string(b.height) + ", the current output " + std::to_string(a.width) + "x" +
                std::to_string(a.height));
  if (b.channels < minChannels || b.channels > maxChannels)
    invalidData(std::string("temporal error: ") + nameB + " has " + std::to_string(b.channels) + " channels, expected " +
                std::to_string(minChannels) + (minChannels == maxChannels ? "" : "-" + std::to_string(maxChannels)));
}

// Bilinear read of channel c at (x, y) in pixel-centre coordinates, clamped to the border.
inline float bilinear(const Image& img, float x, float y, int c) {
  x = std::fmin(std::fmax(x, 0.0f), float(img.width - 1));
  y = std::fmin(std::fmax(y, 0.0f), float(img.height - 1));
  int x0 = int(x), y0 = int(y);
  int x1 = x0 + 1 < img.width ? x0 + 1 : x0, y1 = y0 + 1 < img.height ? y0 + 1 : y0;
  float fx = x - float(x0), fy = y - float(y0);
  float top = img.at(x0, y0)[c] * (1 - fx) + img.at(x1, y0)[c] * fx;
  float bottom = img.at(x0, y1)[c] * (1 - fx) + img.at(x1, y1)[c] * fx;
  return top * (1 - fy) + bottom * fy;
}

inline bool inside(const Image& img, float x, float y) {
  return x >= -0.5f && y >= -0.5f && x <= float(img.width) - 0.5f && y <= float(img.height) - 0.5f;
}

}  // namespace

Image warpPrevious(const Image& previous, const Image& motion, Image* valid, int numThreads) {
  checkSame(previous, motion, "motion", 2, 4);
  Image out(previous.width, previous.height, previous.channels);
  if (valid) *valid = Image(previous.width, previous.height, 1);
  parallelRows(previous.width, previous.height, numThreads, [&](int y0, int y1) {
    for (int y = y0; y < y1; ++y)
      for (int x = 0; x < previous.width; ++x) {
        const float* m = motion.at(x, y);
        float px = float(x) + m[0], py = float(y) + m[1];
        if (!std::isfinite(px) || !std::isfinite(py)) px = float(x), py = float(y);
        for (int c = 0; c < previous.channels; ++c) out.at(x, y)[c] = bilinear(previous, px, py, c);
        if (valid) valid->at(x, y)[0] = inside(previous, px, py) ? 1.0f : 0.0f;
      }
  });
  return out;
}

Image disocclusionMask(const Image* motion, const Image* ids, const Image* idsPrevious, const Image* depth,
                       const Image* depthPrevious, float depthTolerance, int numThreads) {
  const Image* size = ids ? ids : depth ? depth : motion;
  if (!size) invalidArgument("disocclusionMask needs IDs, depth or motion");
  int w = size->width, h = size->height;
  bool useIds = ids && idsPrevious, useDepth = depth && depthPrevious;
  if (useIds) checkSame(*ids, *idsPrevious, "previous IDs", 1, 1);
  if (useDepth) checkSame(*depth, *depthPrevious, "previous depth", 1, 4);
  if (motion && (motion->width != w || motion->height != h)) invalidData("disocclusionMask: motion size differs");
  Image mask(w, h, 1);
  parallelRows(w, h, numThreads, [&](int y0, int y1) {
    for (int y = y0; y < y1; ++y)
      for (int x = 0; x < w; ++x) {
        float px = float(x), py = float(y);
        if (motion) px += motion->at(x, y)[0], py += motion->at(x, y)[1];
        if (!std::isfinite(px) || !std::isfinite(py) || px < -0.5f || py < -0.5f || px > w - 0.5f || py > h - 0.5f)
          continue;  // left the picture: disoccluded
        int nx = std::min(std::max(int(std::lround(px)), 0), w - 1), ny = std::min(std::max(int(std::lround(py)), 0), h - 1);
        bool ok = true;
        if (useIds) ok = ids->uintAt(x, y) == idsPrevious->uintAt(nx, ny);
        if (ok && useDepth) {
          float d = depth->at(x, y)[0], dp = depthPrevious->at(nx, ny)[0];
          bool bg = isBackgroundDepth(d), bgp = isBackgroundDepth(dp);
          ok = bg == bgp && (bg || std::fabs(d - dp) <= depthTolerance * std::fmax(std::fabs(d), 1e-6f));
        }
        mask.at(x, y)[0] = ok ? 1.0f : 0.0f;
      }
  });
  return mask;
}

TemporalError temporalError(const Image& out, const Image& outPrevious, const Image& reference,
                            const Image& referencePrevious, const Image* motion, const Image* mask, int numThreads,
                            Image* map) {
  checkSame(out, out, "current output", 3, 4);
  checkSame(out, outPrevious, "previous output", 3, 4);
  checkSame(out, reference, "reference", 3, 4);
  checkSame(out, referencePrevious, "previous reference", 3, 4);
  if (motion) checkSame(out, *motion, "motion", 2, 4);
  if (mask) checkSame(out, *mask, "mask", 1, 1);
  // Same display encoding as compareImages (metrics.h), so TE is in RMSE units.
  Image o = displayEncode(out, numThreads), op = displayEncode(outPrevious, numThreads);
  Image r = displayEncode(reference, numThreads), rp = displayEncode(referencePrevious, numThreads);
  Image inside;
  if (map) *map = Image(out.width, out.height, 1);
  if (motion) {
    op = warpPrevious(op, *motion, &inside, numThreads);
    rp = warpPrevious(rp, *motion, nullptr, numThreads);
  }
  // Per-row sums in double, added in row order: the same figure for any thread count.
  std::vector<double> rowSum(std::size_t(out.height), 0.0);
  std::vector<long> rowCount(std::size_t(out.height), 0);
  parallelRows(out.width, out.height, numThreads, [&](int y0, int y1) {
    for (int y = y0; y < y1; ++y) {
      double s = 0;
      long n = 0;
      for (int x = 0; x < out.width; ++x) {
        if (motion && inside.at(x, y)[0] <= 0) continue;
        if (mask && !(mask->at(x, y)[0] > 0)) continue;
        double pixel = 0;
        for (int c = 0; c < 3; ++c)
          pixel += std::fabs(double(o.at(x, y)[c] - op.at(x, y)[c]) - double(r.at(x, y)[c] - rp.at(x, y)[c]));
        s += pixel;
        if (map) map->at(x, y)[0] = float(pixel / 3.0);
        ++n;
      }
      rowSum[std::size_t(y)] = s;
      rowCount[std::size_t(y)] = n;
    }
  });
  TemporalError te;
  double total = 0;
  for (int y = 0; y < out.height; ++y) total += rowSum[std::size_t(y)], te.pixels += rowCount[std::size_t(y)];
  te.value = te.pixels ? total / (3.0 * double(te.pixels)) : 0.0;
  return te;
}

}  // namespace crisp
