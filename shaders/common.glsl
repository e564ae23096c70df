// SPDX-License-Identifier: Apache-2.0
// Helpers shared by the Crisp GLSL filters (shaders/*.glsl). Mirrors of
// native/core/color.h and core/conventions.h.
//
// Addressing, for every filter: one fragment = one pixel; (x, y) are integer
// texel indices, x = column, y = texture row. Every fetch is texelFetch with
// explicit clamp-to-edge (fetchClamped), never the sampler's filtering, so a
// "bilinear" tap is the same two lerps the C++ code does, in the same order
// (hardware filtering would quantise the weights, e.g. to 8 bits on llvmpipe).
// Row 0 of a texture is the library's row 0 (the parity test uploads rows
// top-down); in the viewport, row 0 is the BOTTOM of the screen, so the
// viewport sees a vertically mirrored picture: every filter here is defined
// in pixel coordinates and mirrors with it, except the y sign of taa's jitter
// (only used for the optional Blackman-Harris weight; symmetric anyway).
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
// driver's exp2(log2()) (C++: std::pow, or REPAIR's table within 3e-6).
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
