// SPDX-License-Identifier: Apache-2.0
// Helpers shared by the Crisp GLSL filters (shaders/*.glsl). Mirrors of
// native/core/color.h and core/conventions.h.
//
// Addressing, for every filter: one fragment = one pixel; (x, y) are integer
// pixel indices, x = column, y = row: the texture's row (taa) or the
// library's (fxaa, repair; see "Row order"). Every fetch is texelFetch with
// explicit clamp-to-edge (fetchClamped, fetchPicture), never the sampler's
// filtering, so a "bilinear" tap is the same two lerps the C++ code does, in
// the same order (hardware filtering would quantise the weights, e.g. to 8
// bits on llvmpipe).
//
// Row order: the library's row 0 is the top of the picture
// (core/conventions.h). A texture may hold it either way: the parity test
// uploads rows top-down, the viewport's offscreen has row 0 at the BOTTOM.
//  * fxaa and repair work in the library's pixel coordinates whichever way
//    the texture holds the rows: each fragment filters pixel
//    picturePixel(fragment) and reads its neighbours with fetchPicture, so
//    rowsUp (a push constant, 1: row 0 is the bottom) gives the library's
//    arithmetic in the library's order. A mirrored computation would not
//    match: FXAA breaks ties toward the row above and the lower search end,
//    and an exact tie between its two second-difference sums (a dark pixel
//    in a brighter ring) is then decided by the sums' rounding; REPAIR's
//    thesis estimator keeps tan theta = beta1 / alpha1 when the rows are
//    reversed (both slopes change sign), so it does not mirror with the
//    picture (its regression estimator does, up to rounding).
//  * taa works in texel coordinates and is symmetric in y up to rounding:
//    its jitterY (and motion's y) are along the texture's rows, i.e. the
//    library's values for a top-down texture and their negation for a
//    bottom-up one (the viewport passes its y-up jitter as is). The unjitter
//    shift and 3x3 weights and the Blackman-Harris weight then mirror with
//    the picture.
//
// Known numeric differences against the C++ kernels, for all filters:
//  * GLSL does not promise IEEE rounding: the compiler may contract a * b + c
//    into an fma (the library builds with -ffp-contract=off), and sqrt, pow,
//    atan are the driver's approximations (llvmpipe: within a few ulp).
//  * Everything is float; where the C++ code uses double (REPAIR's
//    statistics and angle weights, taa's Blackman-Harris weight) it is stated
//    beside the function.
//  * NaN: isnan() is honoured by Mesa; a driver compiling with "fast math"
//    could fold it away.

const float kMaxColor = 65504.0;  // core/conventions.h kMaxColor

// core/color.h sanitizeColor: NaN -> 0, +-Inf -> +-kMaxColor.
float sanitizeColor(float v) { return isnan(v) ? 0.0 : clamp(v, -kMaxColor, kMaxColor); }
vec4 sanitizeColor4(vec4 c) {
  return vec4(sanitizeColor(c.r), sanitizeColor(c.g), sanitizeColor(c.b), sanitizeColor(c.a));
}

// core/color.h luminance709.
float luminance709(float r, float g, float b) { return 0.2126 * r + 0.7152 * g + 0.0722 * b; }

// core/color.h srgbEncode / srgbDecode (IEC 61966-2-1). pow() here is the
// driver's exp2(log2()) (C++: std::pow, or REPAIR's polynomial within 3.1e-7).
float srgbEncode(float linear) {
  float v = isnan(linear) ? 0.0 : clamp(linear, 0.0, 1.0);
  if (v >= 1.0) return 1.0;
  return v <= 0.0031308 ? 12.92 * v : 1.055 * pow(v, 1.0 / 2.4) - 0.055;
}
float srgbDecode(float encoded) {
  float v = clamp(encoded, 0.0, 1.0);
  return v <= 0.04045 ? v / 12.92 : pow((v + 0.055) / 1.055, 2.4);
}

// std::isfinite.
bool finiteValue(float v) { return !(isnan(v) || isinf(v)); }

int clampIndex(int v, int n) { return v < 0 ? 0 : (v >= n ? n - 1 : v); }

// texelFetch with clamp-to-edge addressing (the C++ reference's std::clamp).
vec4 fetchClamped(sampler2D image, int x, int y) {
  ivec2 size = textureSize(image, 0);
  return texelFetch(image, ivec2(clampIndex(x, size.x), clampIndex(y, size.y)), 0);
}

ivec2 fragmentPixel() { return ivec2(gl_FragCoord.xy); }

// The library's pixel (row 0 at the top) held by texel p of a texture of the
// given height, and back (the map is its own inverse): rowsUp = 1 when the
// texture's row 0 is the bottom of the picture.
ivec2 picturePixel(ivec2 p, int height, int rowsUp) { return rowsUp != 0 ? ivec2(p.x, height - 1 - p.y) : p; }

// fetchClamped at the library's pixel (x, y): clamped there, then mapped.
vec4 fetchPicture(sampler2D image, int x, int y, int rowsUp) {
  ivec2 size = textureSize(image, 0);
  return texelFetch(image, picturePixel(ivec2(clampIndex(x, size.x), clampIndex(y, size.y)), size.y, rowsUp), 0);
}
