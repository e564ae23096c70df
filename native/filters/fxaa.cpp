// SPDX-License-Identifier: Apache-2.0
// "fxaa": FXAA 3.11 quality path, preset 12 (see fxaa.h), written from Lottes'
// published description of the algorithm. Per pixel:
//   1. local contrast check on the centre and its 4 neighbours (early exit);
//   2. sub-pixel aliasing amount from the 3x3 low-pass vs the centre;
//   3. edge orientation from second differences over the 3x3 block;
//   4. the side of the edge with the steeper luma step;
//   5. end-of-edge search in both directions along the edge, on the luma
//      mid-way between the two rows (columns) either side of the edge;
//   6. blend offset from the nearer end's position on the span, kept only if
//      that end bends the right way; final offset = max(edge, sub-pixel);
//   7. one bilinear colour fetch moved by that offset across the edge.
//
// Parameters (also `crisp help fxaa` / crispGetFilterDoc):
// | name | type | default | range | meaning | source |
// |---|---|---|---|---|---|
// | edgeThreshold | float | 0.166 | [0, 1] | min local luma range, relative to the local max luma | FXAA 3.11 QUALITY_EDGE_THRESHOLD |
// | edgeThresholdMin | float | 0.0833 | [0, 1] | min local luma range, absolute (skips dark areas) | FXAA 3.11 QUALITY_EDGE_THRESHOLD_MIN |
// | subpix | float | 0.75 | [0, 1] | sub-pixel aliasing removal (0 off, 1 softest) | FXAA 3.11 QUALITY_SUBPIX |
// | reference | bool | false | - | run the scalar reference path (single thread, clamped fetches) | this file |
//
// Deviations from the shader, on purpose: luma is computed here from linear
// colour (fxaa.h perceptualLuma) into a plane, instead of read from an alpha
// channel written by an earlier pass; alpha passes through instead of holding
// luma; images are addressed in pixel units (centre of pixel i at i) with
// clamp-to-edge borders, as a texture sampler with clamp addressing would.
#include "filters/fxaa.h"

#include <algorithm>
#include <cmath>
#include <cstring>
#if defined(__SSE2__)
#include <emmintrin.h>
#endif

#include "core/color.h"
#include "core/error.h"
#include "core/filter.h"
#include "core/parallel.h"

namespace crisp::fxaa {

// The furthest look of the search is the sum of all steps but the last
// (8.5 px for preset 12); its bilinear taps reach one texel further, rounded
// up. Across the edge, looks reach 1 px. The padded plane must cover both.
constexpr float furthestLook() {
  float sum = 0.0f;
  for (int k = 0; k + 1 < kSearchStepCount; ++k) sum += kSearchSteps[k];
  return sum;
}
static_assert(float(kLumaPad) >= furthestLook() + 1.0f, "kLumaPad must cover the furthest search look and its taps");

namespace {
// The tone curve of perceptualLuma on Rec. 709 luminance. 0.5 (Y + |Y|) is
// exactly max(Y, 0) for finite Y, written without a select so row loops
// vectorise.
inline float toneLuma(float luminance) {
  const float y = 0.5f * (luminance + std::fabs(luminance));
  return std::sqrt(y / (1.0f + y));
}
}  // namespace

float perceptualLuma(float r, float g, float b) { return toneLuma(luminance709(r, g, b)); }

struct Access {
  static std::vector<float>& luma(Workspace& w) { return w.luma_; }
  static std::vector<float>& paddedLuma(Workspace& w) { return w.paddedLuma_; }
  static std::vector<std::uint8_t>& needsSearch(Workspace& w) { return w.needsSearch_; }
  static std::vector<std::uint8_t>& rowChecked(Workspace& w) { return w.rowChecked_; }
  static std::vector<float>& staging(Workspace& w) { return w.staging_; }
};

void Workspace::allocate(int width, int height) {
  width_ = width;
  height_ = height;
  const std::size_t w = std::size_t(width), h = std::size_t(height), pad = std::size_t(kLumaPad);
  luma_.assign(w * h, 0.0f);
  paddedLuma_.assign((w + 2 * pad) * (h + 2 * pad), 0.0f);
  needsSearch_.assign(w * h, 0);
  rowChecked_.assign(h, 0);
  staging_.assign(w * h * 4, 0.0f);
}

std::size_t Workspace::searchedPixels() const {
  std::size_t n = 0;
  for (std::uint8_t f : needsSearch_) n += f;
  return n;
}

namespace {

// ---------------------------------------------------------------------------
// Shared per-pixel arithmetic. Both paths call exactly these functions.

inline float lerp(float a, float b, float t) { return a + (b - a) * t; }
// max/min as selects the vectoriser maps onto maxps/minps (no NaN reaches them).
inline float maxOf(float a, float b) { return a < b ? b : a; }
inline float minOf(float a, float b) { return b < a ? b : a; }

// Step 1, local contrast check. True when the pixel needs no anti-aliasing.
// Written branch-free so the fast path's row loop vectorises.
inline bool lowContrast(float m, float n, float s, float w, float e, float threshold, float thresholdMin) {
  const float hi = maxOf(maxOf(maxOf(n, s), maxOf(w, e)), m);
  const float lo = minOf(minOf(minOf(n, s), minOf(w, e)), m);
  const float range = hi - lo;
  // range <= 0 also catches edgeThresholdMin = 0 on a flat area (no 1/range later).
  return (range < maxOf(thresholdMin, hi * threshold)) | (range <= 0.0f);
}

// Where to fetch the colour of pixel (x, y): `offset` pixels across the edge
// (along y for a horizontal edge, along x for a vertical one); 0 = keep.
struct Blend {
  bool horizontalEdge = true;
  float offset = 0.0f;
};

// Bilinear luma on the line half-way between rows (kHorizontal) or columns
// `low` and `low + 1`, at `position` along it: the fetch of step 5, with the
// across weight 1/2 known; interpolates along x first, then y. Pixel centres
// are on integers.
template <bool kHorizontal, class Luma>
inline float lookBetween(const Luma& luma, int low, float position) {
  int i = int(position);
  if (float(i) > position) --i;  // floor (positions are small multiples of 1/2)
  const float t = position - float(i);
  if (kHorizontal) {
    const float top = lerp(luma.at(i, low), luma.at(i + 1, low), t);
    const float bottom = lerp(luma.at(i, low + 1), luma.at(i + 1, low + 1), t);
    return lerp(top, bottom, 0.5f);
  }
  const float top = lerp(luma.at(low, i), luma.at(low + 1, i), 0.5f);
  const float bottom = lerp(luma.at(low, i + 1), luma.at(low + 1, i + 1), 0.5f);
  return lerp(top, bottom, t);
}

// Step 5 result: distance searched on each side and the luma change (from
// the mid-edge value) seen at the last look on that side.
struct Span {
  float distNeg, distPos, endNeg, endPos;
};

// End-of-edge search in both directions from `along` (the pixel's x for a
// horizontal edge, y for a vertical one). A side stops when the averaged luma
// has moved by endThreshold from edgeLuma; each step of kSearchSteps moves
// the sides still going, and looks again except after the last step.
template <bool kHorizontal, class Luma>
inline Span searchSpan(const Luma& luma, int acrossLow, int along, float edgeLuma, float endThreshold) {
  const float centre = float(along);
  Span s{kSearchSteps[0], kSearchSteps[0], 0.0f, 0.0f};
  s.endNeg = lookBetween<kHorizontal>(luma, acrossLow, centre - s.distNeg) - edgeLuma;
  s.endPos = lookBetween<kHorizontal>(luma, acrossLow, centre + s.distPos) - edgeLuma;
  bool doneNeg = std::fabs(s.endNeg) >= endThreshold, donePos = std::fabs(s.endPos) >= endThreshold;
  for (int k = 1; k < kSearchStepCount && !(doneNeg && donePos); ++k) {
    if (!doneNeg) s.distNeg += kSearchSteps[k];
    if (!donePos) s.distPos += kSearchSteps[k];
    if (k == kSearchStepCount - 1) break;  // the last step is taken without a look
    if (!doneNeg) {
      s.endNeg = lookBetween<kHorizontal>(luma, acrossLow, centre - s.distNeg) - edgeLuma;
      doneNeg = std::fabs(s.endNeg) >= endThreshold;
    }
    if (!donePos) {
      s.endPos = lookBetween<kHorizontal>(luma, acrossLow, centre + s.distPos) - edgeLuma;
      donePos = std::fabs(s.endPos) >= endThreshold;
    }
  }
  return s;
}

template <class Luma>
inline Blend blendFor(const Luma& luma, int x, int y, const Settings& st) {
  Blend out;
  const float m = luma.at(x, y);
  const float n = luma.at(x, y - 1), s = luma.at(x, y + 1);
  const float w = luma.at(x - 1, y), e = luma.at(x + 1, y);
  if (lowContrast(m, n, s, w, e, st.edgeThreshold, st.edgeThresholdMin)) return out;
  const float range = maxOf(maxOf(maxOf(n, s), maxOf(w, e)), m) - minOf(minOf(minOf(n, s), minOf(w, e)), m);
  const float nw = luma.at(x - 1, y - 1), ne = luma.at(x + 1, y - 1);
  const float sw = luma.at(x - 1, y + 1), se = luma.at(x + 1, y + 1);

  // Step 2: sub-pixel aliasing. The 3x3 low-pass (weights 1 2 1 / 2 0 2 /
  // 1 2 1, sum 12) against the centre, relative to the local range, eased by
  // smoothstep, squared, and scaled by `subpix`.
  const float lowpass = (2.0f * (n + s + w + e) + (nw + ne + sw + se)) * (1.0f / 12.0f);
  const float subpixContrast = std::min(std::fabs(lowpass - m) / range, 1.0f);
  const float eased = (3.0f - 2.0f * subpixContrast) * subpixContrast * subpixContrast;
  const float subpixBlend = eased * eased * st.subpix;

  // Step 3: orientation. Vertical second differences down the three columns
  // (centre column weighted 2) measure a horizontal edge; horizontal second
  // differences along the three rows measure a vertical one.
  const float acrossRows = std::fabs(nw + sw - 2.0f * w) + 2.0f * std::fabs(n + s - 2.0f * m) +
                           std::fabs(ne + se - 2.0f * e);
  const float acrossColumns = std::fabs(nw + ne - 2.0f * n) + 2.0f * std::fabs(w + e - 2.0f * m) +
                              std::fabs(sw + se - 2.0f * s);
  const bool horizontal = acrossRows >= acrossColumns;
  out.horizontalEdge = horizontal;

  // Step 4: the neighbour across the edge with the larger luma step decides
  // on which side of the centre the edge lies (-1: up/left, +1: down/right).
  const float before = horizontal ? n : w;
  const float after = horizontal ? s : e;
  const float stepBefore = std::fabs(before - m), stepAfter = std::fabs(after - m);
  const bool towardBefore = stepBefore >= stepAfter;
  const float side = towardBefore ? -1.0f : 1.0f;
  const float gradient = std::max(stepBefore, stepAfter);
  // Luma half-way across the edge, and the change from it that ends the edge.
  const float edgeLuma = 0.5f * (m + (towardBefore ? before : after));
  const float endThreshold = 0.25f * gradient;
  const bool centreBelowEdge = m - edgeLuma < 0.0f;

  // Step 5: end-of-edge search, on the line half a pixel toward the edge,
  // where a bilinear fetch averages the two rows (columns) it separates.
  const int acrossLow = (horizontal ? y : x) - (towardBefore ? 1 : 0);
  const Span span = horizontal ? searchSpan<true>(luma, acrossLow, x, edgeLuma, endThreshold)
                               : searchSpan<false>(luma, acrossLow, y, edgeLuma, endThreshold);
  const float distNeg = span.distNeg, distPos = span.distPos, endNeg = span.endNeg, endPos = span.endPos;

  // Step 6: the nearer end decides. The span is a staircase step of length
  // distNeg + distPos; a pixel at distance d from its nearer end is covered
  // by 0.5 - d / span of the other side. Only blend when the luma at that end
  // crosses the mid-way value in the opposite sense to the centre (otherwise
  // this pixel is on the wrong side of the step).
  const bool negNearer = distNeg < distPos;
  const float nearest = std::min(distNeg, distPos);
  const float endLuma = negNearer ? endNeg : endPos;
  const bool goodSpan = (endLuma < 0.0f) != centreBelowEdge;
  const float edgeBlend = goodSpan ? 0.5f - nearest / (distNeg + distPos) : 0.0f;
  out.offset = side * std::max(edgeBlend, subpixBlend);
  return out;
}

// ---------------------------------------------------------------------------
// Addressing: the only thing the two paths do differently.

// Reference: unpadded plane, clamp-to-edge on every fetch.
struct ClampedLuma {
  const float* plane;
  int width, height;
  float at(int x, int y) const {
    x = std::clamp(x, 0, width - 1);
    y = std::clamp(y, 0, height - 1);
    return plane[std::size_t(y) * std::size_t(width) + std::size_t(x)];
  }
};

// Fast: plane padded by kLumaPad clamp-to-edge copies on every side; `origin`
// points at pixel (0, 0). Valid for -kLumaPad <= x < width + kLumaPad.
struct PaddedLuma {
  const float* origin;
  std::ptrdiff_t stride;
  float at(int x, int y) const { return origin[std::ptrdiff_t(y) * stride + x]; }
};

// Colour source: the input view, or the staging copy when output overlaps it.
// Values are sanitised on every read (idempotent on the staged copy).
struct ColorSource {
  const char* base;
  std::size_t pixelStride, rowStride;
  int channels;
  const float* pixel(int x, int y) const {
    return reinterpret_cast<const float*>(base + std::size_t(y) * rowStride + std::size_t(x) * pixelStride);
  }
  void rgba(int x, int y, float out[4]) const {
    const float* p = pixel(x, y);
    out[0] = sanitize(p[0]);
    out[1] = sanitize(p[1]);
    out[2] = sanitize(p[2]);
    out[3] = channels > 3 ? sanitize(p[3]) : 1.0f;
  }
};

// Step 7: the colour of (x, y) fetched `blend.offset` pixels across the edge.
// The fetch point is on a pixel-centre line, so the bilinear fetch reduces to
// a lerp between the two pixels either side of it; |offset| <= subpix <= 1,
// so for pixels off the border both lie inside the image.
template <bool kClamp>
inline void resolve(const ColorSource& src, int width, int height, int x, int y, const Blend& blend, float out[4]) {
  if (blend.offset == 0.0f) return src.rgba(x, y, out);
  const float pos = float(blend.horizontalEdge ? y : x) + blend.offset;
  const float p0f = std::floor(pos);
  const float t = pos - p0f;
  // |offset| reaches 1 when subpix = 1: the fetch lands on the neighbour's
  // centre (t = 0), and the pixel beyond it must not be read.
  int p0 = int(p0f), p1 = t == 0.0f ? p0 : p0 + 1;
  if (kClamp) {
    const int last = (blend.horizontalEdge ? height : width) - 1;
    p0 = std::clamp(p0, 0, last);
    p1 = std::clamp(p1, 0, last);
  }
  float a[4], b[4];
  if (blend.horizontalEdge) {
    src.rgba(x, p0, a);
    src.rgba(x, p1, b);
  } else {
    src.rgba(p0, y, a);
    src.rgba(p1, y, b);
  }
  for (int k = 0; k < 3; ++k) out[k] = lerp(a[k], b[k], t);
  out[3] = src.channels > 3 ? sanitize(src.pixel(x, y)[3]) : 1.0f;  // alpha stays the centre's
}

inline void store(const ImageView& output, int x, int y, const float rgba[4]) {
  float* p = output.pixel(x, y);
  const int c = output.channels();
  for (int k = 0; k < c; ++k) p[k] = rgba[k];
}

// ---------------------------------------------------------------------------
// Set-up shared by both paths.

void checkViews(const ImageView& color, const ImageView& output, const Workspace& ws) {
  if (ws.width() < 1 || ws.height() < 1) invalidArgument("fxaa: the workspace is not allocated (empty image?)");
  if (color.width != ws.width() || color.height != ws.height() || output.width != ws.width() ||
      output.height != ws.height())
    invalidArgument("fxaa: color " + std::to_string(color.width) + "x" + std::to_string(color.height) + " / output " +
                    std::to_string(output.width) + "x" + std::to_string(output.height) +
                    " do not match the workspace " + std::to_string(ws.width()) + "x" + std::to_string(ws.height()));
  if (color.channels() < 3 || color.channels() > 4 || output.channels() < 3 || output.channels() > 4 ||
      color.format == Format::UInt || output.format == Format::UInt)
    invalidArgument("fxaa: color and output need 3 or 4 float channels");
}

// Reads colour from the input, or from a sanitised packed copy when the
// output would overwrite pixels still to be read.
ColorSource colorSource(const ImageView& color, const ImageView& output, Workspace& ws, int numThreads) {
  if (!viewsOverlap(color, output))
    return {static_cast<const char*>(color.ptr), color.pixelStride, color.rowStride, color.channels()};
  std::vector<float>& staged = Access::staging(ws);
  const ColorSource in{static_cast<const char*>(color.ptr), color.pixelStride, color.rowStride, color.channels()};
  parallelRows(color.width, color.height, numThreads, [&](int y0, int y1) {
    for (int y = y0; y < y1; ++y)
      for (int x = 0; x < color.width; ++x) in.rgba(x, y, staged.data() + (std::size_t(y) * color.width + x) * 4);
  });
  return {reinterpret_cast<const char*>(staged.data()), 16, std::size_t(color.width) * 16, 4};
}

// toneLuma over a row. GCC keeps a scalar errno branch around sqrt (the
// library does not build with -fno-math-errno), which blocks vectorisation,
// so SSE2 (part of x86-64) is spelled out; IEEE sqrt/div/add/mul are exactly
// rounded, so lanes equal the scalar toneLuma bit for bit.
void toneLumaRow(float* luma, int width) {
  int x = 0;
#if defined(__SSE2__)
  const __m128 half = _mm_set1_ps(0.5f), one = _mm_set1_ps(1.0f);
  const __m128 absMask = _mm_castsi128_ps(_mm_set1_epi32(0x7fffffff));
  for (; x + 4 <= width; x += 4) {
    const __m128 l = _mm_loadu_ps(luma + x);
    const __m128 y = _mm_mul_ps(half, _mm_add_ps(l, _mm_and_ps(l, absMask)));
    _mm_storeu_ps(luma + x, _mm_sqrt_ps(_mm_div_ps(y, _mm_add_ps(one, y))));
  }
#endif
  for (; x < width; ++x) luma[x] = toneLuma(luma[x]);
}

// Pass 1 of the fast path for one row: the sanitised colour copied to the
// output (pixels FXAA leaves alone keep it), and the luma row computed from
// that copy. Packed RGBA -> RGBA and RGB -> RGB get loops the compiler
// vectorises; the luma is luminance709 then toneLuma, i.e. the same
// operations as perceptualLuma(rgba(...)) in the reference path.
template <int kChannels>
void copyAndLumaPacked(const float* in, float* out, int width, float* luma) {
  for (int i = 0; i < kChannels * width; ++i) out[i] = sanitize(in[i]);
  for (int x = 0; x < width; ++x) {
    const float* p = out + std::size_t(x) * kChannels;
    luma[x] = luminance709(p[0], p[1], p[2]);
  }
  toneLumaRow(luma, width);
}

#if defined(__SSE2__)
// Packed RGBA -> RGBA in SSE2, four pixels at a time: sanitise (the same
// selects as sanitize(): NaN -> +0 by mask, then max with -kMaxColor, min with
// kMaxColor, whose tie cases return equal values), store, transpose to planar
// R, G, B and compute luminance709 then toneLuma lane-wise in the same order
// as the scalar code. `stream` uses non-temporal stores so a frame larger
// than the caches is written without first being read (as memcpy does).
constexpr int kPrefetchPixels = 32;
void copyAndLumaRgbaSse2(const float* in, float* out, int width, float* luma, bool stream) {
  const __m128 hi = _mm_set1_ps(kMaxColor), lo = _mm_set1_ps(-kMaxColor);
  const __m128 wr = _mm_set1_ps(0.2126f), wg = _mm_set1_ps(0.7152f), wb = _mm_set1_ps(0.0722f);
  const __m128 half = _mm_set1_ps(0.5f), one = _mm_set1_ps(1.0f);
  const __m128 absMask = _mm_castsi128_ps(_mm_set1_epi32(0x7fffffff));
  int x = 0;
  for (; x + 4 <= width; x += 4) {
    // One cache line of input per step; fetched 32 pixels (8 lines) ahead, as
    // the hardware prefetcher did not keep up (perf: the step's last load).
    if (x + kPrefetchPixels < width)
      _mm_prefetch(reinterpret_cast<const char*>(in + 4 * (x + kPrefetchPixels)), _MM_HINT_T0);
    __m128 p[4];
    for (int k = 0; k < 4; ++k) {
      __m128 v = _mm_loadu_ps(in + 4 * (x + k));
      v = _mm_and_ps(v, _mm_cmpeq_ps(v, v));
      p[k] = _mm_min_ps(_mm_max_ps(v, lo), hi);
      if (stream)
        _mm_stream_ps(out + 4 * (x + k), p[k]);
      else
        _mm_storeu_ps(out + 4 * (x + k), p[k]);
    }
    _MM_TRANSPOSE4_PS(p[0], p[1], p[2], p[3]);  // now R, G, B, A of the four pixels
    const __m128 l = _mm_add_ps(_mm_add_ps(_mm_mul_ps(wr, p[0]), _mm_mul_ps(wg, p[1])), _mm_mul_ps(wb, p[2]));
    const __m128 y = _mm_mul_ps(half, _mm_add_ps(l, _mm_and_ps(l, absMask)));
    _mm_storeu_ps(luma + x, _mm_sqrt_ps(_mm_div_ps(y, _mm_add_ps(one, y))));
  }
  for (; x < width; ++x) {
    for (int k = 0; k < 4; ++k) out[4 * x + k] = sanitize(in[4 * x + k]);
    luma[x] = perceptualLuma(out[4 * x], out[4 * x + 1], out[4 * x + 2]);
  }
  if (stream) _mm_sfence();  // order the streamed stores before the pass ends
}
#endif

// Frames at least this large are written with non-temporal stores.
constexpr std::size_t kStreamBytes = std::size_t(8) << 20;

void copyAndLumaRow(const ColorSource& src, const ImageView& output, int y, int width, float* luma) {
  const int c = output.channels();
  if (src.channels == c && src.pixelStride == std::size_t(4 * c) && output.pixelStride == std::size_t(4 * c)) {
#if defined(__SSE2__)
    if (c == 4) {
      float* out = output.row(y);
      const bool stream = (reinterpret_cast<std::uintptr_t>(out) & 15) == 0 &&
                          std::size_t(output.height) * output.rowStride >= kStreamBytes;
      return copyAndLumaRgbaSse2(src.pixel(0, y), out, width, luma, stream);
    }
#endif
    if (c == 4) return copyAndLumaPacked<4>(src.pixel(0, y), output.row(y), width, luma);
    return copyAndLumaPacked<3>(src.pixel(0, y), output.row(y), width, luma);
  }
  for (int x = 0; x < width; ++x) {
    float rgba[4];
    src.rgba(x, y, rgba);
    store(output, x, y, rgba);
    luma[x] = perceptualLuma(rgba[0], rgba[1], rgba[2]);
  }
}

// Step 1 over a row of the padded luma plane: flags[x] = 1 where pixel x
// needs the rest of FXAA. Vectorised by the compiler.
void contrastRow(const float* origin, std::ptrdiff_t stride, int y, int width, const Settings& st,
                 std::uint8_t* __restrict flags) {
  const float* __restrict mid = origin + std::ptrdiff_t(y) * stride;
  const float* __restrict up = mid - stride;
  const float* __restrict down = mid + stride;
  const float threshold = st.edgeThreshold, thresholdMin = st.edgeThresholdMin;
  for (int x = 0; x < width; ++x)
    flags[x] = std::uint8_t(!lowContrast(mid[x], up[x], down[x], mid[x - 1], mid[x + 1], threshold, thresholdMin));
}

}  // namespace

// ---------------------------------------------------------------------------

void runReference(const ImageView& color, const ImageView& output, const Settings& settings, Workspace& ws) {
  checkViews(color, output, ws);
  const int width = ws.width(), height = ws.height();
  const ColorSource src = colorSource(color, output, ws, 1);
  std::vector<float>& plane = Access::luma(ws);
  for (int y = 0; y < height; ++y)
    for (int x = 0; x < width; ++x) {
      float rgba[4];
      src.rgba(x, y, rgba);
      plane[std::size_t(y) * width + x] = perceptualLuma(rgba[0], rgba[1], rgba[2]);
    }
  const ClampedLuma luma{plane.data(), width, height};
  for (int y = 0; y < height; ++y)
    for (int x = 0; x < width; ++x) {
      float rgba[4];
      resolve<true>(src, width, height, x, y, blendFor(luma, x, y, settings), rgba);
      store(output, x, y, rgba);
    }
}

void runFast(const ImageView& color, const ImageView& output, const Settings& settings, Workspace& ws,
             int numThreads) {
  checkViews(color, output, ws);
  const int width = ws.width(), height = ws.height();
  const ColorSource src = colorSource(color, output, ws, numThreads);
  const std::ptrdiff_t stride = std::ptrdiff_t(width) + 2 * kLumaPad;
  float* padded = Access::paddedLuma(ws).data();
  float* origin = padded + kLumaPad * stride + kLumaPad;

  // Pass 1: sanitised copy to the output, luma plane rows with their
  // left/right clamp-to-edge pads, and -- while its three luma rows are still
  // in cache -- the contrast check of each row whose neighbours are in the
  // same band ...
  std::uint8_t* needsSearch = Access::needsSearch(ws).data();
  std::uint8_t* rowChecked = Access::rowChecked(ws).data();
  const Settings st = settings;
  parallelRows(width, height, numThreads, [&](int y0, int y1) {
    for (int y = y0; y < y1; ++y) {
      float* row = origin + std::ptrdiff_t(y) * stride;
      copyAndLumaRow(src, output, y, width, row);
      std::fill(row - kLumaPad, row, row[0]);
      std::fill(row + width, row + width + kLumaPad, row[width - 1]);
      rowChecked[y] = 0;
      if (y - 2 >= y0) {
        contrastRow(origin, stride, y - 1, width, st, needsSearch + std::size_t(y - 1) * width);
        rowChecked[y - 1] = 1;
      }
    }
  });
  // ... then the top/bottom pads (copies of the first/last padded row).
  for (int p = 1; p <= kLumaPad; ++p) {
    std::memcpy(origin - kLumaPad - p * stride, origin - kLumaPad, sizeof(float) * std::size_t(stride));
    std::memcpy(origin - kLumaPad + std::ptrdiff_t(height - 1 + p) * stride,
                origin - kLumaPad + std::ptrdiff_t(height - 1) * stride, sizeof(float) * std::size_t(stride));
  }

  // Pass 2: the contrast check of the rows pass 1 could not do (first and
  // last of each band), then the full FXAA for the pixels that passed it
  // (pass 1 wrote the others).
  const PaddedLuma luma{origin, stride};
  parallelRows(width, height, numThreads, [&](int y0, int y1) {
    for (int y = y0; y < y1; ++y) {
      std::uint8_t* flags = needsSearch + std::size_t(y) * width;
      if (!rowChecked[y]) contrastRow(origin, stride, y, width, st, flags);
      const bool interiorRow = y > 0 && y < height - 1;
      for (int x = 0; x < width; ++x) {
        if (x + 8 <= width && noneOf8(flags + x)) {  // skip 8 flat pixels at a time
          x += 7;
          continue;
        }
        if (!flags[x]) continue;
        const Blend blend = blendFor(luma, x, y, st);
        float rgba[4];
        if (interiorRow && x > 0 && x < width - 1)
          resolve<false>(src, width, height, x, y, blend, rgba);
        else
          resolve<true>(src, width, height, x, y, blend, rgba);
        store(output, x, y, rgba);
      }
    }
  });
}

}  // namespace crisp::fxaa

// ---------------------------------------------------------------------------
// The filter.

namespace crisp {
namespace {

class FxaaFilter final : public Filter {
 public:
  explicit FxaaFilter(Context& c)
      : Filter(c,
               {{"edgeThreshold", ParamType::Float, 0.166, 0.0, 1.0, nullptr,
                 "minimum local range of perceptual luma sqrt(Y/(1+Y)) (Y: Rec. 709 luminance), relative to the local maximum, for a pixel to be filtered",
                 "FXAA 3.11 quality: local contrast check (QUALITY_EDGE_THRESHOLD)"},
                {"edgeThresholdMin", ParamType::Float, 0.0833, 0.0, 1.0, nullptr,
                 "minimum local luma range, absolute: dark areas below it are left alone",
                 "FXAA 3.11 quality: local contrast check (QUALITY_EDGE_THRESHOLD_MIN)"},
                {"subpix", ParamType::Float, 0.75, 0.0, 1.0, nullptr,
                 "amount of sub-pixel aliasing removal (0 off, 1 softest)",
                 "FXAA 3.11 quality: 3x3 low-pass sub-pixel test (QUALITY_SUBPIX)"},
                {"reference", ParamType::Bool, 0, 0, 1, nullptr,
                 "run the scalar reference path (single thread, clamped fetches) instead of the fast path",
                 "filters/fxaa.h (both paths are bit-identical)"}},
               {{"color", true, 3, 4, false, "linear RGB(A) colour"},
                {"output", true, 3, 4, false, "anti-aliased linear colour, same size; alpha passes through"}}) {}
  const char* type() const override { return "fxaa"; }

 protected:
  void onCommit() override { workspace_.allocate(width(), height()); }
  void onExecute() override {
    fxaa::Settings settings;
    settings.edgeThreshold = params().getFloat("edgeThreshold");
    settings.edgeThresholdMin = params().getFloat("edgeThresholdMin");
    settings.subpix = params().getFloat("subpix");
    if (params().getBool("reference"))
      fxaa::runReference(image("color"), image("output"), settings, workspace_);
    else
      fxaa::runFast(image("color"), image("output"), settings, workspace_, numThreads());
  }

 private:
  fxaa::Workspace workspace_;
};

}  // namespace

std::unique_ptr<Filter> newFxaaFilter(Context& c) { return std::make_unique<FxaaFilter>(c); }

}  // namespace crisp
