// SPDX-License-Identifier: Apache-2.0
// FXAA 3.11 quality path, preset 12: the GLSL twin of native/filters/fxaa.cpp
// (and fxaa.h). Same function names, parameter names and defaults, same
// arithmetic in the same order; read the two side by side. The algorithm and
// its sources are described in fxaa.cpp's header (T. Lottes, "FXAA", 2009/2011).
//
// Two passes (gpu_filters.py builds them with gpu.shader.create_from_info;
// both declare the samplers and push constants of the whole file):
//  1. fxaaLumaPass   sampler colorImage (RGBA32F)          -> out float lumaOut (R32F)
//     = the luma plane of runReference (fxaa.h perceptualLuma of the
//       sanitised colour);
//  2. fxaaResolvePass samplers colorImage, lumaImage;
//     push constants edgeThreshold, edgeThresholdMin, subpix, rowsUp -> out vec4 fragColor
//     = blendFor + resolve of fxaa.cpp, clamp-to-edge fetches (runReference's
//       ClampedLuma), i.e. the reference path; the C++ fast path is
//       bit-identical to it.
//
// Parameters (fxaa.cpp table): edgeThreshold 0.166, edgeThresholdMin 0.0833,
// subpix 0.75; rowsUp (not a library parameter): common.glsl "Row order".
// Known differences from the C++ kernel (besides common.glsl's):
//  * sqrt in perceptualLuma is the driver's; a luma one ulp off can flip the
//    contrast check or a search end exactly at a threshold (rare, local).
//  * The colour fetch of step 7 is an explicit lerp of two texelFetch taps,
//    as in fxaa.cpp resolve() (not the sampler's bilinear filtering).

// Defaults of fxaa::Settings (fxaa.h), for readers; the values in use come
// from the push constants of the same names.
const float kDefaultEdgeThreshold = 0.166;
const float kDefaultEdgeThresholdMin = 0.0833;
const float kDefaultSubpix = 0.75;

// fxaa.h kSearchSteps (quality preset 12).
const int kSearchStepCount = 5;
const float kSearchSteps[5] = float[5](1.0, 1.5, 2.0, 4.0, 12.0);

// fxaa.cpp toneLuma / fxaa.h perceptualLuma: Rec. 709 Y clamped at 0, Y/(1+Y), sqrt.
float toneLuma(float luminance) {
  float y = 0.5 * (luminance + abs(luminance));
  return sqrt(y / (1.0 + y));
}
float perceptualLuma(float r, float g, float b) { return toneLuma(luminance709(r, g, b)); }

// fxaa.cpp ClampedLuma::at; (x, y) is the library's pixel (common.glsl "Row order").
float lumaAt(int x, int y) { return fetchPicture(lumaImage, x, y, rowsUp).r; }

float lerpf(float a, float b, float t) { return a + (b - a) * t; }
float maxOf(float a, float b) { return a < b ? b : a; }
float minOf(float a, float b) { return b < a ? b : a; }

// fxaa.cpp lowContrast: step 1, true when the pixel needs no anti-aliasing.
bool lowContrast(float m, float n, float s, float w, float e, float threshold, float thresholdMin) {
  float hi = maxOf(maxOf(maxOf(n, s), maxOf(w, e)), m);
  float lo = minOf(minOf(minOf(n, s), minOf(w, e)), m);
  float range = hi - lo;
  return (range < maxOf(thresholdMin, hi * threshold)) || (range <= 0.0);
}

// fxaa.cpp lookBetween<kHorizontal>: bilinear luma on the line half-way
// between rows (horizontal) or columns `low` and `low + 1`.
float lookBetween(bool horizontal, int low, float position) {
  int i = int(position);
  if (float(i) > position) --i;  // floor
  float t = position - float(i);
  if (horizontal) {
    float top = lerpf(lumaAt(i, low), lumaAt(i + 1, low), t);
    float bottom = lerpf(lumaAt(i, low + 1), lumaAt(i + 1, low + 1), t);
    return lerpf(top, bottom, 0.5);
  }
  float top = lerpf(lumaAt(low, i), lumaAt(low + 1, i), 0.5);
  float bottom = lerpf(lumaAt(low, i + 1), lumaAt(low + 1, i + 1), 0.5);
  return lerpf(top, bottom, t);
}

// fxaa.cpp Span / searchSpan: step 5, end-of-edge search both ways.
struct Span {
  float distNeg, distPos, endNeg, endPos;
};
Span searchSpan(bool horizontal, int acrossLow, int along, float edgeLuma, float endThreshold) {
  float centre = float(along);
  Span s = Span(kSearchSteps[0], kSearchSteps[0], 0.0, 0.0);
  s.endNeg = lookBetween(horizontal, acrossLow, centre - s.distNeg) - edgeLuma;
  s.endPos = lookBetween(horizontal, acrossLow, centre + s.distPos) - edgeLuma;
  bool doneNeg = abs(s.endNeg) >= endThreshold, donePos = abs(s.endPos) >= endThreshold;
  for (int k = 1; k < kSearchStepCount && !(doneNeg && donePos); ++k) {
    if (!doneNeg) s.distNeg += kSearchSteps[k];
    if (!donePos) s.distPos += kSearchSteps[k];
    if (k == kSearchStepCount - 1) break;  // the last step is taken without a look
    if (!doneNeg) {
      s.endNeg = lookBetween(horizontal, acrossLow, centre - s.distNeg) - edgeLuma;
      doneNeg = abs(s.endNeg) >= endThreshold;
    }
    if (!donePos) {
      s.endPos = lookBetween(horizontal, acrossLow, centre + s.distPos) - edgeLuma;
      donePos = abs(s.endPos) >= endThreshold;
    }
  }
  return s;
}

// fxaa.cpp Blend / blendFor: steps 1-6.
struct Blend {
  bool horizontalEdge;
  float offset;
};
Blend blendFor(int x, int y) {
  Blend outBlend = Blend(true, 0.0);
  float m = lumaAt(x, y);
  float n = lumaAt(x, y - 1), s = lumaAt(x, y + 1);
  float w = lumaAt(x - 1, y), e = lumaAt(x + 1, y);
  if (lowContrast(m, n, s, w, e, edgeThreshold, edgeThresholdMin)) return outBlend;
  float range = maxOf(maxOf(maxOf(n, s), maxOf(w, e)), m) - minOf(minOf(minOf(n, s), minOf(w, e)), m);
  float nw = lumaAt(x - 1, y - 1), ne = lumaAt(x + 1, y - 1);
  float sw = lumaAt(x - 1, y + 1), se = lumaAt(x + 1, y + 1);

  // Step 2: sub-pixel aliasing.
  float lowpass = (2.0 * (n + s + w + e) + (nw + ne + sw + se)) * (1.0 / 12.0);
  float subpixContrast = min(abs(lowpass - m) / range, 1.0);
  float eased = (3.0 - 2.0 * subpixContrast) * subpixContrast * subpixContrast;
  float subpixBlend = eased * eased * subpix;

  // Step 3: orientation.
  float acrossRows = abs(nw + sw - 2.0 * w) + 2.0 * abs(n + s - 2.0 * m) + abs(ne + se - 2.0 * e);
  float acrossColumns = abs(nw + ne - 2.0 * n) + 2.0 * abs(w + e - 2.0 * m) + abs(sw + se - 2.0 * s);
  bool horizontal = acrossRows >= acrossColumns;
  outBlend.horizontalEdge = horizontal;

  // Step 4: which side of the centre the edge lies on.
  float before = horizontal ? n : w;
  float after = horizontal ? s : e;
  float stepBefore = abs(before - m), stepAfter = abs(after - m);
  bool towardBefore = stepBefore >= stepAfter;
  float side = towardBefore ? -1.0 : 1.0;
  float gradient = max(stepBefore, stepAfter);
  float edgeLuma = 0.5 * (m + (towardBefore ? before : after));
  float endThreshold = 0.25 * gradient;
  bool centreBelowEdge = m - edgeLuma < 0.0;

  // Step 5.
  int acrossLow = (horizontal ? y : x) - (towardBefore ? 1 : 0);
  Span span = horizontal ? searchSpan(true, acrossLow, x, edgeLuma, endThreshold)
                         : searchSpan(false, acrossLow, y, edgeLuma, endThreshold);

  // Step 6.
  bool negNearer = span.distNeg < span.distPos;
  float nearest = min(span.distNeg, span.distPos);
  float endLuma = negNearer ? span.endNeg : span.endPos;
  bool goodSpan = (endLuma < 0.0) != centreBelowEdge;
  float edgeBlend = goodSpan ? 0.5 - nearest / (span.distNeg + span.distPos) : 0.0;
  outBlend.offset = side * max(edgeBlend, subpixBlend);
  return outBlend;
}

// fxaa.cpp ColorSource::rgba (sanitised read).
vec4 colorAt(int x, int y) { return sanitizeColor4(fetchPicture(colorImage, x, y, rowsUp)); }

// fxaa.cpp resolve<kClamp = true>: step 7.
vec4 resolve(int x, int y, Blend blend) {
  if (blend.offset == 0.0) return colorAt(x, y);
  float pos = float(blend.horizontalEdge ? y : x) + blend.offset;
  float p0f = floor(pos);
  float t = pos - p0f;
  int p0 = int(p0f);
  int p1 = t == 0.0 ? p0 : p0 + 1;
  vec4 a = blend.horizontalEdge ? colorAt(x, p0) : colorAt(p0, y);
  vec4 b = blend.horizontalEdge ? colorAt(x, p1) : colorAt(p1, y);
  vec4 outColor;
  outColor.r = lerpf(a.r, b.r, t);
  outColor.g = lerpf(a.g, b.g, t);
  outColor.b = lerpf(a.b, b.b, t);
  outColor.a = colorAt(x, y).a;  // alpha stays the centre's
  return outColor;
}

// Entry points: gpu_filters.py defines exactly one of the pass macros (each
// pass declares its own output) and appends main() calling the entry.
#ifdef FXAA_LUMA_PASS
void fxaaLumaPass() {
  vec4 c = sanitizeColor4(texelFetch(colorImage, fragmentPixel(), 0));
  lumaOut = perceptualLuma(c.r, c.g, c.b);
}
#endif

#ifdef FXAA_RESOLVE_PASS
void fxaaResolvePass() {
  ivec2 p = picturePixel(fragmentPixel(), textureSize(colorImage, 0).y, rowsUp);
  fragColor = resolve(p.x, p.y, blendFor(p.x, p.y));
}
#endif
