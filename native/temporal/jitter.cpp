// SPDX-License-Identifier: Apache-2.0
#include "temporal/jitter.h"

#include <algorithm>
#include <cmath>

namespace crisp::temporal {

namespace {
constexpr double kPi = 3.14159265358979323846;
constexpr double kA0 = 0.35875, kA1 = 0.48829, kA2 = 0.14128, kA3 = 0.01168;
}  // namespace

double radicalInverse(unsigned index, unsigned base) {
  // Seed 004's generator: digits of index in `base`, mirrored about the point.
  double result = 0.0, fraction = 1.0 / base;
  while (index > 0) {
    result += double(index % base) * fraction;
    index /= base;
    fraction /= base;
  }
  return result;
}

double blackmanHarrisWindow(double t) {
  if (t <= 0.0 || t >= 1.0) return 0.0;
  const double a = 2.0 * kPi * t;
  return kA0 - kA1 * std::cos(a) + kA2 * std::cos(2.0 * a) - kA3 * std::cos(3.0 * a);
}

double blackmanHarrisCdf(double t) {
  t = std::clamp(t, 0.0, 1.0);
  const double a = 2.0 * kPi * t;
  // Integral of the window from 0 to t; the total over [0, 1] is a0.
  const double integral = kA0 * t - kA1 * std::sin(a) / (2.0 * kPi) + kA2 * std::sin(2.0 * a) / (4.0 * kPi) -
                          kA3 * std::sin(3.0 * a) / (6.0 * kPi);
  return integral / kA0;
}

double blackmanHarrisInverse(double u, double width) {
  u = std::clamp(u, 0.0, 1.0);
  double lo = 0.0, hi = 1.0;
  for (int i = 0; i < 60; ++i) {
    const double mid = 0.5 * (lo + hi);
    (blackmanHarrisCdf(mid) < u ? lo : hi) = mid;
  }
  return (0.5 * (lo + hi) - 0.5) * width;
}

Jitter jitterForFrame(int frame, JitterDistribution distribution, float filterSize, int period) {
  if (period < 1) period = 1;
  const int m = ((frame % period) + period) % period;
  const unsigned index = unsigned(m) + 1u;
  const double u = radicalInverse(index, 2), v = radicalInverse(index, 3);
  double x, yUp;
  if (distribution == JitterDistribution::Uniform) {
    x = u - 0.5;
    yUp = v - 0.5;
  } else if (filterSize <= 1e-6f) {
    x = yUp = 0.0;
  } else {
    x = blackmanHarrisInverse(u, 2.0 * filterSize);
    yUp = blackmanHarrisInverse(v, 2.0 * filterSize);
  }
  return Jitter{float(x), float(-yUp)};
}

float blackmanHarrisWeight(float x, float y, float filterSize) {
  if (!(filterSize > 0.0f)) return 1.0f;
  const double width = 2.0 * double(filterSize);  // the window spans [-filterSize, filterSize]
  const double tx = double(x) / width + 0.5, ty = double(y) / width + 0.5;
  return float(blackmanHarrisWindow(tx) * blackmanHarrisWindow(ty) / (kA0 * kA0));
}

std::vector<ParamSpec> jitterParamSpecs(const char* weightMeaning, const char* weightSource) {
  return {
      {"jitterX", ParamType::Float, 0.0, -4.0, 4.0, nullptr,
       "this frame's sub-pixel sample offset in pixels, x right (set per frame from the sidecar's jitter; the "
       "image is never resampled, see unjitter)",
       "seed 000 §3.6.1 and appendix B; seed 002 §5.2; seed 004 Halton"},
      {"jitterY", ParamType::Float, 0.0, -4.0, 4.0, nullptr,
       "this frame's sample offset in pixels, y DOWN (the library convention: negate the sidecar's / Blender's "
       "y-up value)",
       "seed 000 §3.6.1 and appendix B; seed 002 §5.2"},
      {"jitterWeighting", ParamType::String, 0, 0, 0, "none|blackman-harris", weightMeaning, weightSource},
      {"filterSize", ParamType::Float, 1.5, 0.01, 4.0, nullptr,
       "EEVEE's filter_size: the Blackman-Harris pixel filter of jitterWeighting spans [-filterSize, filterSize] px",
       "BLENDER.md Sampling and jitter"},
      {"unjitter", ParamType::String, 0, 0, 0, "blackman-harris|nearest|none",
       "current colour of every pixel: blackman-harris = this frame's 3x3 around the sample nearest the pixel "
       "centre, weighted by the pixel filter at the unjittered centre (converges to EEVEE's filtered pixel for "
       "EEVEE's jitter); nearest = that sample; none = the pixel's own jittered sample (jumps by up to "
       "+-filterSize px from frame to frame; exact accumulation, also for uniform jitter and a box filter)",
       "METHODS.md TAA baseline (unjittered current colour); Karis 2014"},
  };
}

UnjitterMode parseUnjitterMode(const std::string& name) {
  return name == "none" ? UnjitterMode::None : name == "nearest" ? UnjitterMode::Nearest : UnjitterMode::BlackmanHarris;
}

Unjitter unjitterFor(UnjitterMode mode, float jitterX, float jitterY, float filterSize) {
  Unjitter u;
  if (mode == UnjitterMode::None) return u;
  u.enabled = true;
  u.shiftX = std::clamp(int(std::lround(jitterX)), -2, 2);
  u.shiftY = std::clamp(int(std::lround(jitterY)), -2, 2);
  const float dx = jitterX - float(u.shiftX), dy = jitterY - float(u.shiftY);
  float sum = 0.0f;
  for (int i = 0; i < 9; ++i) {
    u.weights[i] = mode == UnjitterMode::BlackmanHarris
                       ? blackmanHarrisWeight(float(i % 3 - 1) + dx, float(i / 3 - 1) + dy, filterSize)
                       : 0.0f;
    sum += u.weights[i];
  }
  if (!(sum > 0.0f)) {  // nearest, or a filter too narrow to reach any tap
    std::fill(u.weights, u.weights + 9, 0.0f);
    u.weights[4] = sum = 1.0f;
  }
  for (float& w : u.weights) w /= sum;
  return u;
}

}  // namespace crisp::temporal
