// SPDX-License-Identifier: Apache-2.0
// A perceptual LDR error in the spirit of FLIP, written from the description in
// P. Andersson, J. Nilsson, T. Akenine-Moeller, M. Oskarsson, K. Aastroem,
// M. D. Fairchild, "FLIP: A Difference Evaluator for Alternating Images",
// Proc. ACM Comput. Graph. Interact. Tech. 3(2), 2020 (HPG 2020). No code of
// the authors' was used; the constants below are the paper's published values.
//
// Per pixel, for reference r and test t (both sRGB-encoded in [0,1]):
//
// Colour pipeline (paper: "colour pipeline")
//  1. sRGB -> linear RGB (IEC 61966-2-1) -> CIE XYZ (sRGB primaries, D65) ->
//     the linearised opponent space YyCxCz of CIELAB (Flohr/Johnson-Fairchild):
//       Yy = 116 Y/Yn - 16, Cx = 500 (X/Xn - Y/Yn), Cz = 200 (Y/Yn - Z/Zn).
//  2. Each channel is filtered by the spatial counterpart of its contrast
//     sensitivity function, modelled as a sum of Gaussians in frequency,
//       S(f) = a1 exp(-b1 f^2) + a2 exp(-b2 f^2)            (f in cycles/degree),
//     whose spatial kernel is
//       s(x) = a1 sqrt(pi/b1) exp(-pi^2 x^2 / b1) + a2 sqrt(pi/b2) exp(-pi^2 x^2 / b2)
//     with x the distance in degrees (= pixels / pixelsPerDegree), evaluated on
//     the 2-D grid and normalised to sum 1. Paper's values (b in deg^2):
//       achromatic  a1 = 1,    b1 = 0.0047, a2 = 0
//       red-green   a1 = 1,    b1 = 0.0053, a2 = 0
//       blue-yellow a1 = 34.1, b1 = 0.04,   a2 = 13.5, b2 = 0.025
//     Each Gaussian term exp(-pi^2 x^2 / b) has sigma = sqrt(b / (2 pi^2)) deg.
//  3. Filtered YyCxCz -> XYZ -> linear RGB, clamped to [0,1] (filtering can leave
//     the gamut), -> CIELAB L*a*b*.
//  4. Hunt effect: a* and b* scaled by 0.01 L* (chroma looks weaker when dark).
//  5. HyAB distance (Abasi, Tehran & Fairchild 2019): |dL*| + sqrt(da*^2 + db*^2).
//  6. Compressed: dE_c = HyAB^qc, qc = 0.7; cmax = the compressed HyAB between
//     Hunt-adjusted pure green (0,1,0) and pure blue (0,0,1), the largest such
//     difference in the [0,1] RGB cube. Mapped to [0,1] with pc = 0.4,
//     pt = 0.95: errors below pc*cmax map linearly onto [0, pt], the rest
//     (large, equally obvious errors) are compressed into [pt, 1].
//
// Feature pipeline (paper: "feature pipeline")
//  7. On the achromatic channel Y/Yn = (Yy + 16) / 116 in [0,1] of the unfiltered
//     images: edges = |gradient| from first-derivative-of-Gaussian kernels,
//     points = |(d2/dx2, d2/dy2)| from second-derivative-of-Gaussian kernels,
//     sigma = 0.5 * w * pixelsPerDegree pixels with w = 0.082 deg, radius
//     ceil(3 sigma). Kernels normalised so their positive weights sum to 1 and
//     their negative weights to -1 (so a unit step gives a response of 1).
//  8. dE_f = ( max(|edge_r - edge_t|, |point_r - point_t|) / sqrt(2) )^qf, qf = 0.5.
//
// Final (paper's combination): e = dE_c ^ (1 - dE_f), in [0,1].
//
// Simplifications / choices of ours, none changing the model's intent:
//  * Each CSF Gaussian term gets its own radius ceil(3 sigma) (the paper sizes
//    all three filters by the widest one); the truncated 2-D kernel is still
//    normalised to sum 1, and each term is applied separably (exact: a sum of
//    separable Gaussians). Weights below exp(-4.5) of the peak are dropped.
//  * Borders mirror (convolve.h), as the SSIM code does.
//  * The kernels are applied as correlations: sign of the derivative responses
//    is irrelevant, only magnitudes are used.
//  * Arithmetic in float (the map is perceptual; means are taken in double by
//    the caller), final value clamped to [0,1] for safety. sRGB decoding and
//    the CIELAB cube roots are tabulated (power_table.h, ~1e-7 absolute).
#include "metrics/flip.h"

#include <algorithm>
#include <cmath>
#include <string>
#include <vector>

#include "core/color.h"
#include "core/error.h"
#include "core/parallel.h"
#include "metrics/convolve.h"
#include "metrics/power_table.h"

namespace crisp {

namespace {

using metrics_detail::convolveColumn;
using metrics_detail::convolveRow;
using metrics_detail::Kernel;
using metrics_detail::padRow;

constexpr double kPi = 3.14159265358979323846;

// Contrast sensitivity sum-of-Gaussians parameters (paper's values, b in deg^2).
struct CsfTerm {
  double a, b;
};
struct Csf {
  CsfTerm terms[2];
};
constexpr Csf kCsfAchromatic{{{1.0, 0.0047}, {0.0, 1e-5}}};
constexpr Csf kCsfRedGreen{{{1.0, 0.0053}, {0.0, 1e-5}}};
constexpr Csf kCsfBlueYellow{{{34.1, 0.04}, {13.5, 0.025}}};

constexpr float kQc = 0.7f;   // colour-difference compression exponent
constexpr float kPc = 0.4f;   // fraction of cmax below which errors map linearly
constexpr float kPt = 0.95f;  // value those errors map onto
constexpr float kQf = 0.5f;   // feature-difference exponent
constexpr double kFeatureWidthDeg = 0.082;  // w, width of the detected features in degrees

// sRGB (IEC 61966-2-1) linear RGB -> XYZ, D65.
constexpr double kRgbToXyz[3][3] = {{0.4124564, 0.3575761, 0.1804375},
                                    {0.2126729, 0.7151522, 0.0721750},
                                    {0.0193339, 0.1191920, 0.9503041}};

struct ColorSpace {
  float rgbToXyz[3][3];
  float xyzToRgb[3][3];
  float white[3];  // XYZ of RGB (1,1,1): the reference white of CIELAB here
  float invWhite[3];
  const metrics_detail::PowerTable* cbrt = nullptr;
};

ColorSpace makeColorSpace() {
  ColorSpace cs;
  cs.cbrt = &metrics_detail::cbrtTable();
  const auto& m = kRgbToXyz;
  // Inverse by the adjugate (in double, then stored as float).
  const double det = m[0][0] * (m[1][1] * m[2][2] - m[1][2] * m[2][1]) -
                     m[0][1] * (m[1][0] * m[2][2] - m[1][2] * m[2][0]) +
                     m[0][2] * (m[1][0] * m[2][1] - m[1][1] * m[2][0]);
  double inv[3][3];
  inv[0][0] = (m[1][1] * m[2][2] - m[1][2] * m[2][1]) / det;
  inv[0][1] = (m[0][2] * m[2][1] - m[0][1] * m[2][2]) / det;
  inv[0][2] = (m[0][1] * m[1][2] - m[0][2] * m[1][1]) / det;
  inv[1][0] = (m[1][2] * m[2][0] - m[1][0] * m[2][2]) / det;
  inv[1][1] = (m[0][0] * m[2][2] - m[0][2] * m[2][0]) / det;
  inv[1][2] = (m[0][2] * m[1][0] - m[0][0] * m[1][2]) / det;
  inv[2][0] = (m[1][0] * m[2][1] - m[1][1] * m[2][0]) / det;
  inv[2][1] = (m[0][1] * m[2][0] - m[0][0] * m[2][1]) / det;
  inv[2][2] = (m[0][0] * m[1][1] - m[0][1] * m[1][0]) / det;
  for (int i = 0; i < 3; ++i) {
    cs.white[i] = float(m[i][0] + m[i][1] + m[i][2]);
    cs.invWhite[i] = float(1.0 / (m[i][0] + m[i][1] + m[i][2]));
    for (int j = 0; j < 3; ++j) {
      cs.rgbToXyz[i][j] = float(m[i][j]);
      cs.xyzToRgb[i][j] = float(inv[i][j]);
    }
  }
  return cs;
}

void multiply(const float m[3][3], const float in[3], float out[3]) {
  for (int i = 0; i < 3; ++i) out[i] = m[i][0] * in[0] + m[i][1] * in[1] + m[i][2] * in[2];
}

// CIELAB's cube-root with its linear toe (CIE 15).
float labF(float t, const metrics_detail::PowerTable& cbrt) {
  constexpr float delta = 6.0f / 29.0f;
  return t > delta * delta * delta ? metrics_detail::fastCbrt(t, cbrt) : t / (3.0f * delta * delta) + 4.0f / 29.0f;
}

// Linear RGB (already in [0,1]) -> Hunt-adjusted L*a*b* (steps 3-4).
void huntLab(const ColorSpace& cs, const float rgb[3], float lab[3]) {
  float xyz[3];
  multiply(cs.rgbToXyz, rgb, xyz);
  const float fx = labF(xyz[0] * cs.invWhite[0], *cs.cbrt), fy = labF(xyz[1] * cs.invWhite[1], *cs.cbrt),
              fz = labF(xyz[2] * cs.invWhite[2], *cs.cbrt);
  const float l = 116.0f * fy - 16.0f;
  lab[0] = l;
  lab[1] = 0.01f * l * (500.0f * (fx - fy));
  lab[2] = 0.01f * l * (200.0f * (fy - fz));
}

float hyab(const float p[3], const float q[3]) {
  const float da = p[1] - q[1], db = p[2] - q[2];
  return std::fabs(p[0] - q[0]) + std::sqrt(da * da + db * db);
}

// The CSF's spatial filter as a weighted sum of separable, normalised Gaussians.
struct CsfFilter {
  int terms = 0;
  float weight[2] = {0, 0};
  Kernel<float> kernel[2];
};

CsfFilter makeCsfFilter(const Csf& csf, double ppd) {
  CsfFilter f;
  double mass[2] = {0, 0}, total = 0;
  for (const CsfTerm& t : csf.terms) {
    if (!(t.a > 0)) continue;
    const double sigmaPx = std::sqrt(t.b / (2.0 * kPi * kPi)) * ppd;
    const int radius = std::max(1, int(std::ceil(3.0 * sigmaPx)));
    std::vector<double> g(std::size_t(2 * radius + 1));
    double sum = 0;
    for (int i = -radius; i <= radius; ++i) {
      const double xDeg = double(i) / ppd;
      g[std::size_t(i + radius)] = std::exp(-kPi * kPi * xDeg * xDeg / t.b);
      sum += g[std::size_t(i + radius)];
    }
    Kernel<float>& k = f.kernel[f.terms];
    k.radius = radius;
    for (double v : g) k.taps.push_back(float(v / sum));
    // The term's share of the 2-D kernel a sqrt(pi/b) g(x) g(y) summed over the grid.
    mass[f.terms] = t.a * std::sqrt(kPi / t.b) * sum * sum;
    total += mass[f.terms];
    ++f.terms;
  }
  for (int i = 0; i < f.terms; ++i) f.weight[i] = float(mass[i] / total);
  return f;
}

// Gaussian and its first and second derivatives for the feature detectors.
struct FeatureKernels {
  Kernel<float> gauss, first, second;
  int radius = 0;
};

FeatureKernels makeFeatureKernels(double ppd) {
  const double sigma = 0.5 * kFeatureWidthDeg * ppd;
  const int radius = std::max(1, int(std::ceil(3.0 * sigma)));
  std::vector<double> g, d1, d2;
  double sumG = 0, posD1 = 0, posD2 = 0, negD2 = 0;
  for (int i = -radius; i <= radius; ++i) {
    const double x = double(i);
    const double gi = std::exp(-x * x / (2.0 * sigma * sigma));
    g.push_back(gi);
    d1.push_back(-x / (sigma * sigma) * gi);
    d2.push_back((x * x / (sigma * sigma) - 1.0) / (sigma * sigma) * gi);
    sumG += gi;
    if (d1.back() > 0) posD1 += d1.back();
    if (d2.back() > 0) posD2 += d2.back(); else negD2 -= d2.back();
  }
  FeatureKernels k;
  k.radius = radius;
  for (Kernel<float>* kk : {&k.gauss, &k.first, &k.second}) kk->radius = radius;
  for (std::size_t i = 0; i < g.size(); ++i) {
    k.gauss.taps.push_back(float(g[i] / sumG));
    // At tiny sigma (ppd < ~0.6) the off-centre weights underflow to 0: no
    // detectable feature, zero kernels rather than 0/0.
    k.first.taps.push_back(posD1 > 0 ? float(d1[i] / posD1) : 0.0f);
    k.second.taps.push_back(posD2 > 0 && negD2 > 0 ? float(d2[i] > 0 ? d2[i] / posD2 : d2[i] / negD2) : 0.0f);
  }
  return k;
}

// Per-band scratch rows.
struct Scratch {
  std::vector<float> col, pad, tmp;
  explicit Scratch(int width, int maxRadius)
      : col(std::size_t(width)), pad(std::size_t(width) + 2 * std::size_t(maxRadius)), tmp(std::size_t(width)) {}
};

// out = CSF-filtered row y of plane.
void csfFilterRow(const float* plane, int width, int height, int y, const CsfFilter& f, Scratch& s, float* out) {
  std::fill(out, out + width, 0.0f);
  for (int t = 0; t < f.terms; ++t) {
    const Kernel<float>& k = f.kernel[t];
    convolveColumn(plane, width, height, y, k, s.col.data());
    padRow(s.col.data(), width, k.radius, s.pad.data());
    convolveRow(s.pad.data(), width, k.radius, k, s.tmp.data());
    const float w = f.weight[t];
    for (int x = 0; x < width; ++x) out[x] += w * s.tmp[std::size_t(x)];
  }
}

// edge and point magnitudes of row y of the achromatic plane.
void featureRow(const float* plane, int width, int height, int y, const FeatureKernels& k, Scratch& s,
                std::vector<float>& colG, std::vector<float>& padG, float* edge, float* point) {
  const int r = k.radius;
  float* tmp = s.tmp.data();
  // Vertical Gaussian, then horizontal first / second derivative: d/dx, d2/dx2.
  convolveColumn(plane, width, height, y, k.gauss, colG.data());
  padRow(colG.data(), width, r, padG.data());
  convolveRow(padG.data(), width, r, k.first, edge);    // edge = dx for now
  convolveRow(padG.data(), width, r, k.second, point);  // point = dxx for now
  // Vertical first derivative, horizontal Gaussian: d/dy.
  convolveColumn(plane, width, height, y, k.first, s.col.data());
  padRow(s.col.data(), width, r, s.pad.data());
  convolveRow(s.pad.data(), width, r, k.gauss, tmp);
  for (int x = 0; x < width; ++x) edge[x] = std::sqrt(edge[x] * edge[x] + tmp[x] * tmp[x]);
  // Vertical second derivative, horizontal Gaussian: d2/dy2.
  convolveColumn(plane, width, height, y, k.second, s.col.data());
  padRow(s.col.data(), width, r, s.pad.data());
  convolveRow(s.pad.data(), width, r, k.gauss, tmp);
  for (int x = 0; x < width; ++x) point[x] = std::sqrt(point[x] * point[x] + tmp[x] * tmp[x]);
}

std::string describe(const Image& im) {
  return std::to_string(im.width) + "x" + std::to_string(im.height) + "x" + std::to_string(im.channels);
}

}  // namespace

Image flipErrorMap(const Image& referenceSrgb, const Image& testSrgb, float pixelsPerDegree, int numThreads) {
  if (referenceSrgb.channels != 3 || testSrgb.channels != 3 || referenceSrgb.width != testSrgb.width ||
      referenceSrgb.height != testSrgb.height)
    invalidData("flipErrorMap: reference is " + describe(referenceSrgb) + " and test is " + describe(testSrgb) +
                "; both must be 3-channel sRGB of the same size");
  if (referenceSrgb.width <= 0 || referenceSrgb.height <= 0) invalidData("flipErrorMap: images are empty");
  if (!(pixelsPerDegree > 0.0f && pixelsPerDegree <= 1000.0f))
    invalidArgument("flipErrorMap: pixelsPerDegree " + std::to_string(pixelsPerDegree) + " is outside (0, 1000]");

  static const ColorSpace cs = makeColorSpace();
  const double ppd = pixelsPerDegree;
  const CsfFilter csf[3] = {makeCsfFilter(kCsfAchromatic, ppd), makeCsfFilter(kCsfRedGreen, ppd),
                            makeCsfFilter(kCsfBlueYellow, ppd)};
  const FeatureKernels features = makeFeatureKernels(ppd);
  int maxRadius = features.radius;
  for (const CsfFilter& f : csf)
    for (int t = 0; t < f.terms; ++t) maxRadius = std::max(maxRadius, f.kernel[t].radius);
  // ppd <= 1000 gives radii <= 136; convolve.h supports up to kMaxRadius.
  if (maxRadius > metrics_detail::kMaxRadius)
    invalidArgument("flipErrorMap: pixelsPerDegree " + std::to_string(pixelsPerDegree) + " needs too wide filters");

  // cmax: compressed HyAB between Hunt-adjusted green and blue (step 6).
  float cmax;
  {
    const float green[3] = {0, 1, 0}, blue[3] = {0, 0, 1};
    float labGreen[3], labBlue[3];
    huntLab(cs, green, labGreen);
    huntLab(cs, blue, labBlue);
    cmax = std::pow(hyab(labGreen, labBlue), kQc);
  }

  const int width = referenceSrgb.width, height = referenceSrgb.height;
  const std::size_t planeSize = std::size_t(width) * std::size_t(height);
  // Planes per image: Yy, Cx, Cz, achromatic Y/Yn.
  std::vector<float> planes(8 * planeSize);
  auto plane = [&](int image, int channel) { return planes.data() + std::size_t(image * 4 + channel) * planeSize; };

  // Step 1 (+ the achromatic input of step 7).
  const metrics_detail::PowerTable& decode = metrics_detail::srgbDecodeTable();
  parallelRows(width, height, numThreads, [&](int y0, int y1) {
    for (int image = 0; image < 2; ++image) {
      const Image& src = image == 0 ? referenceSrgb : testSrgb;
      float* yy = plane(image, 0);
      float* cx = plane(image, 1);
      float* cz = plane(image, 2);
      float* ach = plane(image, 3);
      for (int y = y0; y < y1; ++y)
        for (int x = 0; x < width; ++x) {
          const float* p = src.at(x, y);
          const float rgb[3] = {metrics_detail::fastSrgbDecode(p[0], decode),
                                metrics_detail::fastSrgbDecode(p[1], decode),
                                metrics_detail::fastSrgbDecode(p[2], decode)};
          float xyz[3];
          multiply(cs.rgbToXyz, rgb, xyz);
          const float xr = xyz[0] * cs.invWhite[0], yr = xyz[1] * cs.invWhite[1], zr = xyz[2] * cs.invWhite[2];
          const std::size_t i = std::size_t(y) * std::size_t(width) + std::size_t(x);
          yy[i] = 116.0f * yr - 16.0f;
          cx[i] = 500.0f * (xr - yr);
          cz[i] = 200.0f * (yr - zr);
          ach[i] = yr;
        }
    }
  });

  Image out(width, height, 1);
  const float linearScale = kPt / (kPc * cmax);
  const float invSqrt2 = float(1.0 / std::sqrt(2.0));
  parallelRows(width, height, numThreads, [&](int y0, int y1) {
    const std::size_t w = std::size_t(width);
    Scratch scratch(width, maxRadius);
    std::vector<float> colG(w), padG(w + 2 * std::size_t(maxRadius));
    std::vector<float> filtered(2 * 3 * w), edge(2 * w), point(2 * w);
    for (int y = y0; y < y1; ++y) {
      for (int image = 0; image < 2; ++image) {
        for (int c = 0; c < 3; ++c)
          csfFilterRow(plane(image, c), width, height, y, csf[c], scratch, filtered.data() + std::size_t(image * 3 + c) * w);
        featureRow(plane(image, 3), width, height, y, features, scratch, colG, padG, edge.data() + std::size_t(image) * w,
                   point.data() + std::size_t(image) * w);
      }
      float* o = out.at(0, y);
      for (std::size_t x = 0; x < w; ++x) {
        float lab[2][3];
        for (int image = 0; image < 2; ++image) {
          const float* f = filtered.data() + std::size_t(image * 3) * w;
          // Step 3: filtered YyCxCz -> XYZ -> linear RGB in [0,1] -> Hunt-adjusted Lab.
          const float yr = (f[x] + 16.0f) * (1.0f / 116.0f);
          const float xyz[3] = {(f[w + x] * (1.0f / 500.0f) + yr) * cs.white[0], yr * cs.white[1],
                                (yr - f[2 * w + x] * (1.0f / 200.0f)) * cs.white[2]};
          float rgb[3];
          multiply(cs.xyzToRgb, xyz, rgb);
          for (float& v : rgb) v = std::clamp(v, 0.0f, 1.0f);
          huntLab(cs, rgb, lab[image]);
        }
        // Steps 5-6.
        const float dc = std::pow(hyab(lab[0], lab[1]), kQc);
        const float colourError =
            dc < kPc * cmax ? linearScale * dc : kPt + (dc - kPc * cmax) / (cmax - kPc * cmax) * (1.0f - kPt);
        // Step 8.
        const float featureDiff =
            std::max(std::fabs(edge[x] - edge[w + x]), std::fabs(point[x] - point[w + x])) * invSqrt2;
        static_assert(kQf == 0.5f, "the feature exponent qf is applied as a square root");
        const float featureError = std::sqrt(std::min(featureDiff, 1.0f));
        o[x] = std::clamp(std::pow(colourError, 1.0f - featureError), 0.0f, 1.0f);
      }
    }
  });
  return out;
}

}  // namespace crisp
