// SPDX-License-Identifier: Apache-2.0
// REPAIR rotated spatial filtering (seed 001): the GLSL twin of
// native/filters/repair.cpp (and repair.h). Same function names, parameter
// names and defaults; the thesis equations are cited in repair.cpp.
//
// Passes (gpu_filters.py; every pass declares all samplers and push constants
// of this file, and exactly one pass macro):
//  1. REPAIR_GREY_PASS      colorImage          -> float greyOut      (greyOf, step 1)
//  2. REPAIR_GRADIENT_PASS  greyImage           -> float gradientOut  (sobelMagnitude, step 2)
//  3. REPAIR_STATS_PASS     gradientImage       -> vec4 statsOut      (rowStats over a 4x4 block)
//  4. REPAIR_REDUCE_PASS    statsImage          -> vec4 statsOut      (sums of 4x4 blocks), repeated
//                           until the target is 1x1: (count, sum, sumSquares, 0) of the whole image
//  5. REPAIR_RESOLVE_PASS   colorImage, gradientImage, statsImage (1x1);
//                           push constants kappa, patchSize, mask, angleEstimator -> vec4 fragColor
//                           (combineRowStats, then fitPatch / edgeDirection / smoothAt per edge pixel)
// The global threshold of step 3 (mu + kappa sigma over the non-black gradient
// values) is a reduction: done on the GPU as a multi-pass 4x4 -> 1 tree
// (GLSL 3.3 has no compute shaders or atomics on float), never read back.
//
// Parameters (repair.cpp table): kappa 0 (float), patchSize 5 (odd, 3..15),
// mask 0 = gauss5 / 1 = box3, angleEstimator 0 = regression / 1 = thesis;
// rowsUp (not a library parameter, read by the gradient and resolve passes):
// common.glsl "Row order".
//
// Known differences from the C++ kernel (besides common.glsl's):
//  * step 1: sRGB encoding with pow() (C++: repair.cpp srgbEncodeT, a
//    log2/exp2 polynomial within 3.1e-7 of the exact curve);
//  * step 3: sums in float over a 4x4 tree (C++: double, row by row), and
//    T = mu + kappa sigma in float (C++: double, then rounded to float). A
//    pixel whose gradient lies within a few ulp of T can be an edge on one
//    side and not on the other: a local, full-size difference at that pixel;
//  * step 4: edgeDirection's spread squares (double in C++) and the thesis
//    estimator's atan (double in C++) are float here.

const float kDefaultKappa = 0.0;
const int kDefaultPatchSize = 5;
const int kMaxPatchSize = 15;  // repair.h

// ---------------------------------------------------------------- step 1 --
// repair.cpp greyOf: Y of YIQ (eq. 2.1) of the display-encoded colour.
float greyOf(float r, float g, float b) { return 0.299 * srgbEncode(r) + 0.587 * srgbEncode(g) + 0.114 * srgbEncode(b); }

// ---------------------------------------------------------------- step 2 --
// repair.cpp sobelMagnitude (Fig. 2.9, eq. 2.2); n[row][col], rows y.
float sobelMagnitude(float n[9]) {
  float gx = (n[2] + 2.0 * n[5] + n[8]) - (n[0] + 2.0 * n[3] + n[6]);
  float gy = (n[6] + 2.0 * n[7] + n[8]) - (n[0] + 2.0 * n[1] + n[2]);
  return sqrt(gx * gx + gy * gy);
}

// ---------------------------------------------------------------- step 3 --
// repair.h kBlackGradient: gradients below it are black (not counted, never
// edges), so the float rounding of flat areas, which differs from the C++'s,
// does not move T.
const float kBlackGradient = 1e-5;

// repair.h edgeValue (Algorithm 1, lines 4-10).
float edgeValue(float z, float threshold) { return z >= threshold ? z : 0.0; }

// repair.cpp combineRowStats, from the reduced (count, sum, sumSquares).
// Returns T; no non-black gradient -> +inf-like (nothing is an edge).
float thresholdOf(vec4 stats, float kappaValue) {
  if (stats.x == 0.0) return 3.0e38;
  float mean = stats.y / stats.x;
  float variance = max(0.0, stats.z / stats.x - mean * mean);
  return max(mean + kappaValue * sqrt(variance), kBlackGradient);  // eq. 3.1 (Algorithm 2's sign flip fixed)
}

// ---------------------------------------------------------------- step 4 --
// repair.cpp regressionSlope (eq. 2.4-2.5).
float regressionSlope(float xs[kMaxPatchSize], float ys[kMaxPatchSize], int count) {
  if (count < 2) return 0.0;
  float mx = 0.0, my = 0.0;
  for (int i = 0; i < count; ++i) {
    mx += xs[i];
    my += ys[i];
  }
  mx /= float(count);
  my /= float(count);
  float sxy = 0.0, sxx = 0.0;
  for (int i = 0; i < count; ++i) {
    sxy += (ys[i] - my) * (xs[i] - mx);
    sxx += (xs[i] - mx) * (xs[i] - mx);
  }
  return sxx > 0.0 ? sxy / sxx : 0.0;
}

struct SlopeFit {
  float alpha1, beta1, columnSpread, rowSpread;
};

// repair.cpp gatherPatch<true> + the patch indexing of fitPatch: thresholded
// gradient at patch (column i, row j) around (x, y), clamp-to-edge. Here and
// below (x, y) is the library's pixel (common.glsl "Row order").
float patchAt(int x, int y, int i, int j, int a, float threshold) {
  return edgeValue(fetchPicture(gradientImage, x + i - a, y + j - a, rowsUp).r, threshold);
}

// repair.cpp fitPatch (eq. 3.2-3.3), reading the patch from the texture.
SlopeFit fitPatch(int x, int y, int n, float threshold) {
  int a = (n - 1) / 2;
  float xs[kMaxPatchSize], w[kMaxPatchSize], h[kMaxPatchSize];
  float columnSpread = 0.0, rowSpread = 0.0;
  for (int i = 0; i < n; ++i) {
    xs[i] = float(i - a);
    float colSum = 0.0, colMoment = 0.0, colSecond = 0.0, rowSum = 0.0, rowMoment = 0.0, rowSecond = 0.0;
    for (int j = 0; j < n; ++j) {
      float fj = float(j - a);
      float zc = patchAt(x, y, i, j, a, threshold);  // patch[j * n + i]
      float zr = patchAt(x, y, j, i, a, threshold);  // patch[i * n + j]
      colSum += zc;
      colMoment += zc * fj;
      colSecond += zc * fj * fj;
      rowSum += zr;
      rowMoment += zr * fj;
      rowSecond += zr * fj * fj;
    }
    w[i] = colSum > 0.0 ? colMoment / colSum : 0.0;
    h[i] = rowSum > 0.0 ? rowMoment / rowSum : 0.0;
    columnSpread += max(0.0, colSecond - colMoment * w[i]);
    rowSpread += max(0.0, rowSecond - rowMoment * h[i]);
  }
  return SlopeFit(regressionSlope(xs, w, n), regressionSlope(xs, h, n), columnSpread, rowSpread);
}

// repair.h Direction: unit vector, screen convention, theta in [0, 180).
struct Direction {
  float cosTheta, sinTheta;
};

// repair.cpp screenDirection: image (y down) angle -> screen angle, folded.
Direction screenDirection(float cosImage, float sinImage) {
  Direction d = Direction(cosImage, -sinImage);
  if (d.sinTheta < 0.0 || (d.sinTheta == 0.0 && d.cosTheta < 0.0)) {
    d.cosTheta = -d.cosTheta;
    d.sinTheta = -d.sinTheta;
  }
  if (d.sinTheta == 0.0) d.sinTheta = 0.0;
  return d;
}

// repair.cpp edgeDirection (estimator 0 = Regression, 1 = Thesis).
Direction edgeDirection(SlopeFit fit, int estimator) {
  float alpha1 = fit.alpha1, beta1 = fit.beta1;
  if (!finiteValue(alpha1) || !finiteValue(beta1) || !finiteValue(fit.columnSpread) || !finiteValue(fit.rowSpread))
    return Direction(1.0, 0.0);
  if (estimator == 1) {
    float theta;  // C++: double
    if (alpha1 == 0.0)
      theta = beta1 == 0.0 ? 0.0 : 0.5 * 3.14159265358979;
    else
      theta = atan(beta1 / alpha1);
    return screenDirection(cos(theta), sin(theta));
  }
  float vcd = fit.columnSpread * fit.columnSpread, vrd = fit.rowSpread * fit.rowSpread;  // C++: double
  if (!(vcd + vrd > 0.0)) return Direction(1.0, 0.0);
  float wa = vrd / (vcd + vrd), wb = vcd / (vcd + vrd);
  float a2 = alpha1 * alpha1, b2 = beta1 * beta1;
  float c2 = wa * (1.0 - a2) / (1.0 + a2) + wb * (b2 - 1.0) / (1.0 + b2);
  float s2 = wa * 2.0 * alpha1 / (1.0 + a2) + wb * 2.0 * beta1 / (1.0 + b2);
  float r = sqrt(c2 * c2 + s2 * s2);
  if (!(r > 1e-6)) {
    return wa >= wb ? screenDirection(1.0 / sqrt(1.0 + a2), alpha1 / sqrt(1.0 + a2))
                    : screenDirection(beta1 / sqrt(1.0 + b2), 1.0 / sqrt(1.0 + b2));
  }
  float cosDouble = clamp(c2 / r, -1.0, 1.0);
  float cosImage = sqrt(0.5 * (1.0 + cosDouble));
  float sinImage = (s2 < 0.0 ? -1.0 : 1.0) * sqrt(0.5 * (1.0 - cosDouble));  // std::copysign
  return screenDirection(cosImage, sinImage);
}

// ---------------------------------------------------------------- step 5 --
// repair.cpp maskFor: binomial 5x5 / 256 (Fig. 2.5) or average 3x3 (Fig. 2.3).
int maskRadius(int kind) { return kind == 1 ? 1 : 2; }
float maskWeight(int kind, int w, int h) {
  if (kind == 1) return 1.0 / 9.0;
  const float b[5] = float[5](1.0, 4.0, 6.0, 4.0, 1.0);
  return b[h + 2] * b[w + 2] / 256.0;
}

// repair.cpp Source::fetch (sanitised).
vec4 stagedAt(int x, int y) { return sanitizeColor4(fetchPicture(colorImage, x, y, rowsUp)); }

// repair.cpp smoothAt<Clamp = true> (eq. 3.7-3.9, plain bilinear).
vec4 smoothAt(int x, int y, Direction d, int kind) {
  int r = maskRadius(kind);
  float c = d.cosTheta, s = d.sinTheta;
  vec4 acc = vec4(0.0);
  for (int h = -r; h <= r; ++h)
    for (int w = -r; w <= r; ++w) {
      float weight = maskWeight(kind, w, h);
      float px = float(x) + (float(w) * c + float(h) * s);
      float py = float(y) + (float(h) * c - float(w) * s);
      float fx0 = floor(px), fy0 = floor(py);
      float fx = px - fx0, fy = py - fy0;
      int x0 = int(fx0), y0 = int(fy0);
      vec4 pa = stagedAt(x0, y0), pb = stagedAt(x0 + 1, y0);
      vec4 pc = stagedAt(x0, y0 + 1), pd = stagedAt(x0 + 1, y0 + 1);
      for (int k = 0; k < 4; ++k) {
        float f1 = pa[k] + fx * (pb[k] - pa[k]);
        float f2 = pc[k] + fx * (pd[k] - pc[k]);
        acc[k] += weight * (f1 + fy * (f2 - f1));
      }
    }
  return acc;
}

// ---------------------------------------------------------------- passes --
#ifdef REPAIR_GREY_PASS
void repairGreyPass() {
  vec4 p = sanitizeColor4(texelFetch(colorImage, fragmentPixel(), 0));
  greyOut = greyOf(p.r, p.g, p.b);
}
#endif

#ifdef REPAIR_GRADIENT_PASS
void repairGradientPass() {
  ivec2 p = picturePixel(fragmentPixel(), textureSize(greyImage, 0).y, rowsUp);
  float n[9];
  for (int j = 0; j < 3; ++j)
    for (int i = 0; i < 3; ++i) n[j * 3 + i] = fetchPicture(greyImage, p.x + i - 1, p.y + j - 1, rowsUp).r;
  gradientOut = sobelMagnitude(n);
}
#endif

#ifdef REPAIR_STATS_PASS
// repair.cpp rowStats over the 4x4 block of gradient pixels this texel covers.
void repairStatsPass() {
  ivec2 base = fragmentPixel() * 4;
  ivec2 size = textureSize(gradientImage, 0);
  vec4 s = vec4(0.0);
  for (int j = 0; j < 4; ++j)
    for (int i = 0; i < 4; ++i) {
      ivec2 q = base + ivec2(i, j);
      if (q.x >= size.x || q.y >= size.y) continue;
      float z = texelFetch(gradientImage, q, 0).r;
      if (z >= kBlackGradient) s += vec4(1.0, z, z * z, 0.0);  // eq. 3.1 counts the non-black pixels only
    }
  statsOut = s;
}
#endif

#ifdef REPAIR_REDUCE_PASS
void repairReducePass() {
  ivec2 base = fragmentPixel() * 4;
  ivec2 size = textureSize(statsImage, 0);
  vec4 s = vec4(0.0);
  for (int j = 0; j < 4; ++j)
    for (int i = 0; i < 4; ++i) {
      ivec2 q = base + ivec2(i, j);
      if (q.x < size.x && q.y < size.y) s += texelFetch(statsImage, q, 0);
    }
  statsOut = s;
}
#endif

#ifdef REPAIR_RESOLVE_PASS
// repair.cpp Kernel::runReference, steps 4-5 for one pixel.
void repairResolvePass() {
  ivec2 p = picturePixel(fragmentPixel(), textureSize(colorImage, 0).y, rowsUp);
  float T = thresholdOf(texelFetch(statsImage, ivec2(0, 0), 0), kappa);
  if (edgeValue(texelFetch(gradientImage, fragmentPixel(), 0).r, T) > 0.0) {
    Direction d = edgeDirection(fitPatch(p.x, p.y, patchSize, T), angleEstimator);
    fragColor = vec4(smoothAt(p.x, p.y, d, mask).rgb, stagedAt(p.x, p.y).a);  // the alpha passes through
  } else {
    fragColor = stagedAt(p.x, p.y);
  }
}
#endif
