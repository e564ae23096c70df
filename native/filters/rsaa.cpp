// SPDX-License-Identifier: Apache-2.0
// "rsaa": resampling anti-aliasing (seed 003: Svoboda 2016 after Reshetov,
// HPG 2012). See filters/rsaa.h for the steps, rsaa/sadp.h (eq. 2.1, 4.4.1),
// rsaa/cluster.h (Algorithm 1, 2.3.3, 4.4.3) and rsaa/table_generator.h
// (2.3.2) for the parts.
//
// Fast path: most pixels lie inside one polygon. For those the only work is
// the "does any sample differ" test. With AVX2 and packed float4 sub-samples
// it runs on 8 consecutive pixels at once, one sub-sample after the other
// (anyDiffers8: the centre's geometry once per 8 pixels, no per-pixel
// broadcasts); else per pixel on its 8 samples (differs8, AVX2) or 4 at a
// time (differs4, SSE). Every SIMD lane computes exactly the scalar
// expressions of rsaa::makeGeo / rsaa::differs (same operations, same order,
// -ffp-contract=off), so all paths agree bit for bit; every pixel with a
// differing sample goes through the same scalar resolve(). textureAA = fxaa
// runs the FXAA kernel first and guards each row inside the row pass.
#include "filters/rsaa.h"

#include <algorithm>
#include <atomic>
#include <cmath>
#include <cstring>
#include <string>

#include "core/color.h"
#include "core/cpu.h"
#include "core/error.h"
#include "core/filter.h"
#include "core/parallel.h"
#include "rsaa/offset_table.h"

#if defined(__SSE2__)
#include <emmintrin.h>
#endif
#if defined(__x86_64__) && (defined(__GNUC__) || defined(__clang__))
#include <immintrin.h>
#define CRISP_RSAA_AVX2 1
#endif

namespace crisp::rsaa {

void Kernel::allocate(int width, int height, const Settings& settings) {
  width_ = width;
  height_ = height;
  settings_ = settings;
  threshold2_ = settings.threshold * settings.threshold;
  packedCamera_ = settings.camera;
  for (auto& row : packedCamera_.view)
    for (float& v : row) v /= kSnormScale;
  geometry_ = patternGeometry(kTablePattern);
  colUx_.resize(std::size_t(width));
  rowUy_.resize(std::size_t(height));
  const Camera& c = settings.camera;
  for (int x = 0; x < width; ++x) colUx_[std::size_t(x)] = float(rayUx(x + 0.5, width, c));
  for (int y = 0; y < height; ++y) rowUy_[std::size_t(y)] = float(rayUy(y + 0.5, height, c));
  // A sub-sample's ray terms are the centre's plus a constant step; the
  // step is the ray-term difference of the offset (the ray terms are affine).
  for (int k = 0; k < kSamples; ++k) {
    dux_[k] = float(rayUx(0.5 + kTablePattern.x[k], width, c) - rayUx(0.5, width, c));
    duy_[k] = float(rayUy(0.5 + kTablePattern.y[k], height, c) - rayUy(0.5, height, c));
  }
  staged_ = Image(width, height, 4);
  const std::size_t n = std::size_t(width) * std::size_t(height);
  masks_.assign(n, 255);
  halved_.assign(n, 0);
  geometric_.assign(n, 0);
  textured_.assign(n, 0);
  rowGuarded_.assign(std::size_t(height), 0);
  chunkBits_.assign(std::size_t(height) * std::size_t(width / 8), 0);
  if (settings.textureAA == TextureAA::Fxaa) fxaa_.allocate(width, height);
}

long Kernel::resolvedCount() const {
  long n = 0;
  for (std::uint8_t m : masks_) n += m != 255;
  return n;
}

Geo Kernel::centreGeo(const Inputs& in, int x, int y) const {
  const float d = in.depth.pixel(x, y)[0];
  const float* n = in.normal.pixel(x, y);
  if (in.packed.valid())  // at the records' precision, so flat faces match their samples exactly
    return makeGeo(d, snormCentre(n[0]), snormCentre(n[1]), snormCentre(n[2]), colUx_[std::size_t(x)],
                   rowUy_[std::size_t(y)], packedCamera_);
  return makeGeo(d, n[0], n[1], n[2], colUx_[std::size_t(x)], rowUy_[std::size_t(y)], settings_.camera);
}

Geo Kernel::subGeo(const Inputs& in, int k, int x, int y) const {
  if (in.packed.valid()) {  // the int16 normal as float (exact); packedCamera_ holds the 1/32767
    const SubsampleRecord* r = subsampleRecord(in.packed, x, y);
    return makeGeo(r->depth[k], float(r->nx[k]), float(r->ny[k]), float(r->nz[k]),
                   colUx_[std::size_t(x)] + dux_[k], rowUy_[std::size_t(y)] + duy_[k], packedCamera_);
  }
  const float* s = in.sub[k].pixel(x, y);
  return makeGeo(s[3], s[0], s[1], s[2], colUx_[std::size_t(x)] + dux_[k], rowUy_[std::size_t(y)] + duy_[k],
                 settings_.camera);
}

void Kernel::stage(const ImageView& color, int y0, int y1) {
  const int c = color.channels();
  for (int y = y0; y < y1; ++y) {
    float* dst = staged_.at(0, y);
    for (int x = 0; x < width_; ++x, dst += 4) {
      const float* p = color.pixel(x, y);
      dst[0] = sanitizeColor(p[0]);
      dst[1] = sanitizeColor(c > 1 ? p[1] : p[0]);
      dst[2] = sanitizeColor(c > 2 ? p[2] : p[0]);
      dst[3] = c > 3 ? sanitizeColor(p[3]) : 1.0f;
    }
  }
}

// The sanitised RGBA colour of pixel (x, y): from the input itself when the
// output does not overlap it (no staging pass: a third less memory traffic),
// else from the staged copy. Both give the same values (stage() applies the
// same expressions).
void Kernel::texel(int x, int y, float out[4]) const {
  if (!direct_) {
    const float* p = staged_.at(x, y);
    for (int k = 0; k < 4; ++k) out[k] = p[k];
    return;
  }
  const int c = direct_->channels();
  const float* p = direct_->pixel(x, y);
  out[0] = sanitizeColor(p[0]);
  out[1] = sanitizeColor(c > 1 ? p[1] : p[0]);
  out[2] = sanitizeColor(c > 2 ? p[2] : p[0]);
  out[3] = c > 3 ? sanitizeColor(p[3]) : 1.0f;
}

// Bilinear fetch of the staged colour at pixel-index position (fx, fy)
// (pixel (i, j)'s centre is at (i, j)), clamp-to-edge.
void Kernel::fetch(float fx, float fy, float out[4]) const {
  const float x0f = std::floor(fx), y0f = std::floor(fy);
  const float tx = fx - x0f, ty = fy - y0f;
  const int x0 = int(x0f), y0 = int(y0f);
  const int xa = std::clamp(x0, 0, width_ - 1), xb = std::clamp(x0 + 1, 0, width_ - 1);
  const int ya = std::clamp(y0, 0, height_ - 1), yb = std::clamp(y0 + 1, 0, height_ - 1);
#if defined(__SSE2__)
  // Packed RGBA texels (the staged copy, or a 4-channel input): the four
  // sanitised texels and the blend in SSE, lane by lane the scalar code below.
  const ImageView* packedSource = !direct_ ? nullptr
                                  : direct_->channels() == 4 && direct_->pixelStride == 16 ? direct_
                                                                                          : nullptr;
  if (simdFetch_ && (!direct_ || packedSource)) {
    const auto load = [&](int x, int y) {
      const __m128 v = _mm_loadu_ps(packedSource ? packedSource->pixel(x, y) : staged_.at(x, y));
      if (!packedSource) return v;  // staged: already sanitised
      // sanitizeColor: NaN -> 0, then clamp (max/min give std::clamp's values for finite bounds).
      const __m128 finiteOrInf = _mm_and_ps(v, _mm_cmpord_ps(v, v));
      return _mm_min_ps(_mm_max_ps(finiteOrInf, _mm_set1_ps(-kMaxColor)), _mm_set1_ps(kMaxColor));
    };
    const __m128 wx0 = _mm_set1_ps(1.0f - tx), wx1 = _mm_set1_ps(tx);
    const __m128 top = _mm_add_ps(_mm_mul_ps(wx0, load(xa, ya)), _mm_mul_ps(wx1, load(xb, ya)));
    const __m128 bottom = _mm_add_ps(_mm_mul_ps(wx0, load(xa, yb)), _mm_mul_ps(wx1, load(xb, yb)));
    _mm_storeu_ps(out, _mm_add_ps(_mm_mul_ps(_mm_set1_ps(1.0f - ty), top), _mm_mul_ps(_mm_set1_ps(ty), bottom)));
    return;
  }
#endif
  float c00[4], c10[4], c01[4], c11[4];
  texel(xa, ya, c00);
  texel(xb, ya, c10);
  texel(xa, yb, c01);
  texel(xb, yb, c11);
  for (int k = 0; k < 4; ++k) {
    const float top = (1.0f - tx) * c00[k] + tx * c10[k];
    const float bottom = (1.0f - tx) * c01[k] + tx * c11[k];
    out[k] = (1.0f - ty) * top + ty * bottom;
  }
}

void Kernel::resolve(const Inputs& in, int x, int y, const Geo& centre, const float s[kSamples], float out[4]) {
  int mask = splitMask(s, settings_.threshold);  // Algorithm 1
  const auto neighbour = [&](int k, Geo& g) {
    const int nx = x + geometry_.neighbourDx[k], ny = y + geometry_.neighbourDy[k];
    if (nx < 0 || ny < 0 || nx >= width_ || ny >= height_) return false;
    g = centreGeo(in, nx, ny);
    return true;
  };
  if (settings_.verification == Verification::Reassign) {
    for (int k = 0; k < kSamples; ++k) {
      if (mask & (1 << k)) continue;
      Geo n;
      if (neighbour(k, n) && !(sadp(subGeo(in, k, x, y), n) < s[k])) mask |= 1 << k;
    }
  }
  float ox = kOffsetTable[mask][0], oy = kOffsetTable[mask][1];
  bool halved = false;
  if (settings_.verification == Verification::Halve && mask != 255) {
    int f = -1;
    for (int i = 0; i < kSamples && f < 0; ++i)
      if (!(mask & (1 << geometry_.byDistance[i]))) f = geometry_.byDistance[i];
    Geo n;
    if (neighbour(f, n) && sadp(centre, n) >= 2.0f * s[f]) {
      ox *= 0.5f;
      oy *= 0.5f;
      halved = true;
    }
  }
  const std::size_t i = std::size_t(y) * std::size_t(width_) + std::size_t(x);
  masks_[i] = std::uint8_t(mask);
  halved_[i] = halved;
  fetch(float(x) + ox, float(y) + oy, out);
}

namespace {

#if defined(__SSE2__)
inline __m128 absPs(__m128 v) { return _mm_andnot_ps(_mm_set1_ps(-0.0f), v); }

// Lane-wise rsaa::differs(centre, sample) for 4 sub-samples given as their
// float4 pixels (nx, ny, nz, depth); returns a 4-bit lane mask.
template <bool Ortho>
inline int differs4(const float* s0, const float* s1, const float* s2, const float* s3, const Geo& c,
                    float ux, float uy, __m128 dux, __m128 duy, const Camera& cam, float threshold2) {
  __m128 nx = _mm_loadu_ps(s0), ny = _mm_loadu_ps(s1), nz = _mm_loadu_ps(s2), d = _mm_loadu_ps(s3);
  _MM_TRANSPOSE4_PS(nx, ny, nz, d);
  const __m128 bg = _mm_cmpnlt_ps(d, _mm_set1_ps(kFarDepth));
  if (c.background) return ~_mm_movemask_ps(bg) & 0xF;  // geometry differs from background
  const __m128 sux = _mm_add_ps(_mm_set1_ps(ux), dux);
  const __m128 suy = _mm_add_ps(_mm_set1_ps(uy), duy);
  const __m128 px = Ortho ? sux : _mm_mul_ps(sux, d);
  const __m128 py = Ortho ? suy : _mm_mul_ps(suy, d);
  const __m128 pz = _mm_xor_ps(d, _mm_set1_ps(-0.0f));
  const auto rot = [&](int r) {
    return _mm_add_ps(_mm_add_ps(_mm_mul_ps(_mm_set1_ps(cam.view[r][0]), nx), _mm_mul_ps(_mm_set1_ps(cam.view[r][1]), ny)),
                      _mm_mul_ps(_mm_set1_ps(cam.view[r][2]), nz));
  };
  const __m128 snx = rot(0), sny = rot(1), snz = rot(2);
  const __m128 rx = _mm_sub_ps(px, _mm_set1_ps(c.px));
  const __m128 ry = _mm_sub_ps(py, _mm_set1_ps(c.py));
  const __m128 rz = _mm_sub_ps(pz, _mm_set1_ps(c.pz));
  const __m128 r2 = _mm_add_ps(_mm_add_ps(_mm_mul_ps(rx, rx), _mm_mul_ps(ry, ry)), _mm_mul_ps(rz, rz));
  const __m128 apart = _mm_cmpgt_ps(r2, _mm_set1_ps(kSamePoint2 * (c.pz * c.pz)));
  const __m128 da = _mm_add_ps(_mm_add_ps(_mm_mul_ps(_mm_set1_ps(c.nx), rx), _mm_mul_ps(_mm_set1_ps(c.ny), ry)),
                               _mm_mul_ps(_mm_set1_ps(c.nz), rz));
  const __m128 db = _mm_add_ps(_mm_add_ps(_mm_mul_ps(snx, rx), _mm_mul_ps(sny, ry)), _mm_mul_ps(snz, rz));
  // rsaa::certainDot lane by lane: the sample's view-ray terms and depth tolerance.
  const __m128 zero = _mm_setzero_ps();
  const __m128 svx = Ortho ? zero : sux, svy = Ortho ? zero : suy;
  const __m128 power = _mm_and_ps(d, _mm_castsi128_ps(_mm_set1_epi32(0x7F800000)));
  const __m128 ulp = _mm_max_ps(_mm_set1_ps(5.9604645e-8f), _mm_mul_ps(power, _mm_set1_ps(0.0009765625f)));
  const __m128 stol = _mm_mul_ps(_mm_set1_ps(cam.depthUlps), ulp);
  const auto slack = [&](__m128 nx_, __m128 ny_, __m128 nz_, __m128 vx, __m128 vy, __m128 tol) {
    return _mm_mul_ps(absPs(_mm_sub_ps(_mm_add_ps(_mm_mul_ps(nx_, vx), _mm_mul_ps(ny_, vy)), nz_)), tol);
  };
  const __m128 cnx = _mm_set1_ps(c.nx), cny = _mm_set1_ps(c.ny), cnz = _mm_set1_ps(c.nz);
  const __m128 cvx = _mm_set1_ps(c.vx), cvy = _mm_set1_ps(c.vy), ctol = _mm_set1_ps(c.tolerance);
  const __m128 slackA = _mm_add_ps(slack(cnx, cny, cnz, cvx, cvy, ctol), slack(cnx, cny, cnz, svx, svy, stol));
  const __m128 slackB = _mm_add_ps(slack(snx, sny, snz, cvx, cvy, ctol), slack(snx, sny, snz, svx, svy, stol));
  const __m128 ea = _mm_max_ps(zero, _mm_sub_ps(absPs(da), slackA));
  const __m128 eb = _mm_max_ps(zero, _mm_sub_ps(absPs(db), slackB));
  const __m128 dn = _mm_add_ps(ea, eb);
  const __m128 far = _mm_cmpnlt_ps(_mm_mul_ps(dn, dn), _mm_mul_ps(_mm_set1_ps(threshold2), r2));
  return _mm_movemask_ps(_mm_or_ps(bg, _mm_and_ps(apart, far)));
}
#endif

#if defined(CRISP_RSAA_AVX2)
// AVX2 (chosen at run time on CPUs that have it): rsaa::differs in 8 lanes,
// either 8 sub-samples of one pixel (differs8) or one sub-sample of 8
// consecutive pixels (anyDiffers8). Lane by lane the same operations in the
// same order as rsaa::makeGeo / rsaa::differs; no FMA (-ffp-contract=off and
// no fmadd intrinsics), so results are bit-identical to the scalar path.
#define CRISP_AVX2 __attribute__((target("avx2")))
CRISP_AVX2 inline __m256 abs8(__m256 v) { return _mm256_andnot_ps(_mm256_set1_ps(-0.0f), v); }
CRISP_AVX2 inline __m256 set8(float v) { return _mm256_set1_ps(v); }
// Two float4 pixels in the low and high halves.
CRISP_AVX2 inline __m256 pair8(const float* lo, const float* hi) {
  return _mm256_insertf128_ps(_mm256_castps128_ps256(_mm_loadu_ps(lo)), _mm_loadu_ps(hi), 1);
}
// |(nx vx + ny vy) - nz| tolerance (rsaa::dotSlack).
CRISP_AVX2 inline __m256 slack8(__m256 nx, __m256 ny, __m256 nz, __m256 vx, __m256 vy, __m256 tol) {
  return _mm256_mul_ps(abs8(_mm256_sub_ps(_mm256_add_ps(_mm256_mul_ps(nx, vx), _mm256_mul_ps(ny, vy)), nz)), tol);
}
CRISP_AVX2 inline __m256 dot8(__m256 ax, __m256 ay, __m256 az, __m256 bx, __m256 by, __m256 bz) {
  return _mm256_add_ps(_mm256_add_ps(_mm256_mul_ps(ax, bx), _mm256_mul_ps(ay, by)), _mm256_mul_ps(az, bz));
}
// The rotation of rsaa::makeGeo: world normal -> view space, row r.
CRISP_AVX2 inline __m256 rotate8(const Camera& cam, int r, __m256 x, __m256 y, __m256 z) {
  return dot8(set8(cam.view[r][0]), set8(cam.view[r][1]), set8(cam.view[r][2]), x, y, z);
}
// halfUlp(d) x depthUlps (rsaa::makeGeo's tolerance).
CRISP_AVX2 inline __m256 tolerance8(__m256 d, const Camera& cam) {
  const __m256 power = _mm256_and_ps(d, _mm256_castsi256_ps(_mm256_set1_epi32(0x7F800000)));
  const __m256 ulp = _mm256_max_ps(set8(5.9604645e-8f), _mm256_mul_ps(power, set8(0.0009765625f)));
  return _mm256_mul_ps(set8(cam.depthUlps), ulp);
}

// The centre side of rsaa::differs in 8 lanes.
struct Centre8 {
  __m256 px, py, pz, nx, ny, nz, vx, vy, tol, bg, samePoint, selfSlack;
};

CRISP_AVX2 inline void finishCentre8(Centre8& c) {
  c.samePoint = _mm256_mul_ps(set8(kSamePoint2), _mm256_mul_ps(c.pz, c.pz));
  c.selfSlack = slack8(c.nx, c.ny, c.nz, c.vx, c.vy, c.tol);  // dotSlack(centre normal, centre)
}

// makeGeo for 8 centres from their depth, world normal and ray terms. Lanes
// whose depth is background hold garbage; bg marks them (differsLanes ignores them).
template <bool Ortho>
CRISP_AVX2 inline Centre8 centre8(__m256 d, __m256 wx, __m256 wy, __m256 wz, __m256 ux, __m256 uy, const Camera& cam) {
  Centre8 c;
  c.bg = _mm256_cmp_ps(d, set8(kFarDepth), _CMP_NLT_UQ);
  c.px = Ortho ? ux : _mm256_mul_ps(ux, d);
  c.py = Ortho ? uy : _mm256_mul_ps(uy, d);
  c.pz = _mm256_xor_ps(d, set8(-0.0f));
  c.vx = Ortho ? _mm256_setzero_ps() : ux;
  c.vy = Ortho ? _mm256_setzero_ps() : uy;
  c.tol = tolerance8(d, cam);
  c.nx = rotate8(cam, 0, wx, wy, wz);
  c.ny = rotate8(cam, 1, wx, wy, wz);
  c.nz = rotate8(cam, 2, wx, wy, wz);
  finishCentre8(c);
  return c;
}

// One scalar centre in all 8 lanes.
CRISP_AVX2 inline Centre8 broadcastCentre8(const Geo& g) {
  Centre8 c;
  c.bg = _mm256_castsi256_ps(_mm256_set1_epi32(g.background ? -1 : 0));
  c.px = set8(g.px), c.py = set8(g.py), c.pz = set8(g.pz);
  c.nx = set8(g.nx), c.ny = set8(g.ny), c.nz = set8(g.nz);
  c.vx = set8(g.vx), c.vy = set8(g.vy), c.tol = set8(g.tolerance);
  finishCentre8(c);
  return c;
}

// 8 float4 pixels (lane j = p[j]: world normal xyz, depth) as 4 vectors.
CRISP_AVX2 inline void load8x4(const float* const* p, __m256& nx, __m256& ny, __m256& nz, __m256& d) {
  const __m256 r0 = pair8(p[0], p[4]), r1 = pair8(p[1], p[5]), r2 = pair8(p[2], p[6]), r3 = pair8(p[3], p[7]);
  const __m256 t0 = _mm256_unpacklo_ps(r0, r1), t1 = _mm256_unpackhi_ps(r0, r1);
  const __m256 t2 = _mm256_unpacklo_ps(r2, r3), t3 = _mm256_unpackhi_ps(r2, r3);
  // Lanes 0-3 = p[0..3], lanes 4-7 = p[4..7].
  nx = _mm256_shuffle_ps(t0, t2, _MM_SHUFFLE(1, 0, 1, 0));
  ny = _mm256_shuffle_ps(t0, t2, _MM_SHUFFLE(3, 2, 3, 2));
  nz = _mm256_shuffle_ps(t1, t3, _MM_SHUFFLE(1, 0, 1, 0));
  d = _mm256_shuffle_ps(t1, t3, _MM_SHUFFLE(3, 2, 3, 2));
}

// The sample side of rsaa::differs up to r: background mask, r = p2 - p1,
// |r|^2 and "apart" (not the same point).
struct SampleR8 {
  __m256 bg, rx, ry, rz, r2, apart;
};

template <bool Ortho>
CRISP_AVX2 inline SampleR8 sampleR8(__m256 d, const Centre8& c, __m256 sux, __m256 suy) {
  SampleR8 s;
  s.bg = _mm256_cmp_ps(d, set8(kFarDepth), _CMP_NLT_UQ);
  const __m256 px = Ortho ? sux : _mm256_mul_ps(sux, d);
  const __m256 py = Ortho ? suy : _mm256_mul_ps(suy, d);
  const __m256 pz = _mm256_xor_ps(d, set8(-0.0f));
  s.rx = _mm256_sub_ps(px, c.px);
  s.ry = _mm256_sub_ps(py, c.py);
  s.rz = _mm256_sub_ps(pz, c.pz);
  s.r2 = dot8(s.rx, s.ry, s.rz, s.rx, s.ry, s.rz);
  s.apart = _mm256_cmp_ps(s.r2, c.samePoint, _CMP_GT_OQ);
  return s;
}

// The end of rsaa::differs: dn^2 >= T^2 |r|^2 (NaN: different). A background
// centre differs iff the sample is geometry; else background sample, or
// apart and far.
CRISP_AVX2 inline __m256 differsResult8(const Centre8& c, const SampleR8& s, __m256 dn, __m256 threshold2) {
  const __m256 far = _mm256_cmp_ps(_mm256_mul_ps(dn, dn), _mm256_mul_ps(threshold2, s.r2), _CMP_NLT_UQ);
  return _mm256_or_ps(_mm256_xor_ps(c.bg, s.bg), _mm256_andnot_ps(c.bg, _mm256_and_ps(s.apart, far)));
}

// rsaa::differs(centre, sample) lane by lane for samples given as their
// float4s (lane j = p[j]) with ray terms sux, suy; all-ones lanes differ.
// The samples' world normals (nx, ny, nz; cam.view rotates them to view
// space) and depths d given in lanes.
// The SADP numerator of 8 samples against their centres, lane by lane:
// e_a + e_b, each |n . r| less rsaa::certainDot's slack (the sample's
// view-ray terms and depth tolerance), clipped at 0. Sample normals (nx, ny,
// nz) are rotated by cam first.
template <bool Ortho>
CRISP_AVX2 inline __m256 sadpNumerator8(__m256 nx, __m256 ny, __m256 nz, __m256 d, const Centre8& c,
                                        const SampleR8& s, __m256 sux, __m256 suy, const Camera& cam) {
  const __m256 snx = rotate8(cam, 0, nx, ny, nz), sny = rotate8(cam, 1, nx, ny, nz), snz = rotate8(cam, 2, nx, ny, nz);
  const __m256 da = dot8(c.nx, c.ny, c.nz, s.rx, s.ry, s.rz);
  const __m256 db = dot8(snx, sny, snz, s.rx, s.ry, s.rz);
  const __m256 zero = _mm256_setzero_ps();
  const __m256 svx = Ortho ? zero : sux, svy = Ortho ? zero : suy;
  const __m256 stol = tolerance8(d, cam);
  const __m256 slackA = _mm256_add_ps(c.selfSlack, slack8(c.nx, c.ny, c.nz, svx, svy, stol));
  const __m256 slackB = _mm256_add_ps(slack8(snx, sny, snz, c.vx, c.vy, c.tol), slack8(snx, sny, snz, svx, svy, stol));
  const __m256 ea = _mm256_max_ps(zero, _mm256_sub_ps(abs8(da), slackA));
  const __m256 eb = _mm256_max_ps(zero, _mm256_sub_ps(abs8(db), slackB));
  return _mm256_add_ps(ea, eb);
}

template <bool Ortho>
CRISP_AVX2 inline __m256 differsLanes(__m256 nx, __m256 ny, __m256 nz, __m256 d, const Centre8& c, __m256 sux,
                                      __m256 suy, const Camera& cam, __m256 threshold2) {
  const SampleR8 s = sampleR8<Ortho>(d, c, sux, suy);
  return differsResult8(c, s, sadpNumerator8<Ortho>(nx, ny, nz, d, c, s, sux, suy, cam), threshold2);
}

// differsLanes where every lane's sample normal equals its centre's (after
// the same rotation): then db = da and slackB = slackA bit for bit (the same
// operations on the same operands), so eb = ea and dn = ea + ea; the
// rotation, db and slackB are skipped. Same result bits as differsLanes.
// Two more exact rewrites save an operation each: r's z is formed as
// d - dCentre (cd), which is -((-d) - (-dCentre)) exactly (rounding to
// nearest is symmetric) or +0 where both are +0, so |r|^2 is unchanged and da
// = (nx rx + ny ry) - nz rz' differs at most in the sign of a zero, and da is
// used only through |da|; with no background centre among the lanes
// (BgCentres false) differsResult8 is s.bg | (apart & far).
template <bool Ortho, bool BgCentres>
CRISP_AVX2 inline __m256 sameNormalStep8(__m256 d, const Centre8& c, __m256 cd, __m256 sux, __m256 suy,
                                         const Camera& cam, __m256 threshold2) {
  const __m256 bg = _mm256_cmp_ps(d, set8(kFarDepth), _CMP_NLT_UQ);
  const __m256 rx = _mm256_sub_ps(Ortho ? sux : _mm256_mul_ps(sux, d), c.px);
  const __m256 ry = _mm256_sub_ps(Ortho ? suy : _mm256_mul_ps(suy, d), c.py);
  const __m256 rz = _mm256_sub_ps(d, cd);  // = -(pz - c.pz), see above
  const __m256 r2 = dot8(rx, ry, rz, rx, ry, rz);
  const __m256 apart = _mm256_cmp_ps(r2, c.samePoint, _CMP_GT_OQ);
  const __m256 da = _mm256_sub_ps(_mm256_add_ps(_mm256_mul_ps(c.nx, rx), _mm256_mul_ps(c.ny, ry)),
                                  _mm256_mul_ps(c.nz, rz));
  const __m256 zero = _mm256_setzero_ps();
  const __m256 svx = Ortho ? zero : sux, svy = Ortho ? zero : suy;
  const __m256 slackA = _mm256_add_ps(c.selfSlack, slack8(c.nx, c.ny, c.nz, svx, svy, tolerance8(d, cam)));
  const __m256 ea = _mm256_max_ps(zero, _mm256_sub_ps(abs8(da), slackA));
  const __m256 dn = _mm256_add_ps(ea, ea);
  const __m256 far = _mm256_cmp_ps(_mm256_mul_ps(dn, dn), _mm256_mul_ps(threshold2, r2), _CMP_NLT_UQ);
  const __m256 near = _mm256_and_ps(apart, far);
  return BgCentres ? _mm256_or_ps(_mm256_xor_ps(c.bg, bg), _mm256_andnot_ps(c.bg, near)) : _mm256_or_ps(bg, near);
}

// The same for samples given as their float4s (lane j = p[j]).
template <bool Ortho>
CRISP_AVX2 inline __m256 differsLanes(const float* const* p, const Centre8& c, __m256 sux, __m256 suy,
                                      const Camera& cam, __m256 threshold2) {
  __m256 nx, ny, nz, d;
  load8x4(p, nx, ny, nz, d);
  return differsLanes<Ortho>(nx, ny, nz, d, c, sux, suy, cam, threshold2);
}

// All 8 sub-samples of one pixel (lane k = sample k, float4 at p[k]) against its centre.
template <bool Ortho>
CRISP_AVX2 int differs8(const float* const* p, const Geo& c, float ux, float uy, const float* dux, const float* duy,
                        const Camera& cam, float threshold2) {
  const __m256 sux = _mm256_add_ps(set8(ux), _mm256_loadu_ps(dux));
  const __m256 suy = _mm256_add_ps(set8(uy), _mm256_loadu_ps(duy));
  return _mm256_movemask_ps(differsLanes<Ortho>(p, broadcastCentre8(c), sux, suy, cam, set8(threshold2)));
}

// rsaa::snormCentre in 8 lanes: clamp (max/min: NaN -> -1), scale, round to
// nearest even, + 0.
CRISP_AVX2 inline __m256 snormCentre8(__m256 c) {
  const __m256 t = _mm256_min_ps(_mm256_max_ps(c, set8(-1.0f)), set8(1.0f));
  return _mm256_add_ps(_mm256_round_ps(_mm256_mul_ps(t, set8(kSnormScale)), _MM_FROUND_CUR_DIRECTION),
                       _mm256_setzero_ps());
}

// The centres of pixels x..x+7 of row y (centreGeo in 8 lanes).
template <bool Ortho>
// quantised (packed records): the normals at the records' precision
// (snormCentre in 8 lanes), cam then being the packed camera; the
// quantised normals are returned in q[3] for the same-normal test.
CRISP_AVX2 inline Centre8 loadCentres8(const Inputs& in, int x, int y, __m256 ux, float uy, const Camera& cam,
                                       __m256* q = nullptr) {
  __m256 d, wx, wy, wz;
  if (in.depth.pixelStride == 4) {
    d = _mm256_loadu_ps(in.depth.pixel(x, y));
  } else {
    alignas(32) float g[8];
    for (int j = 0; j < 8; ++j) g[j] = in.depth.pixel(x + j, y)[0];
    d = _mm256_load_ps(g);
  }
  if (in.normal.pixelStride == 12) {
    // 8 packed xyz normals (24 floats) to x, y, z lanes: blends pick each
    // component's 8 values from the 3 loads, a permutation puts them in order.
    const float* n = in.normal.pixel(x, y);
    const __m256 m0 = _mm256_loadu_ps(n), m1 = _mm256_loadu_ps(n + 8), m2 = _mm256_loadu_ps(n + 16);
    wx = _mm256_permutevar8x32_ps(_mm256_blend_ps(_mm256_blend_ps(m0, m1, 0x92), m2, 0x24),
                                  _mm256_setr_epi32(0, 3, 6, 1, 4, 7, 2, 5));
    wy = _mm256_permutevar8x32_ps(_mm256_blend_ps(_mm256_blend_ps(m0, m1, 0x24), m2, 0x49),
                                  _mm256_setr_epi32(1, 4, 7, 2, 5, 0, 3, 6));
    wz = _mm256_permutevar8x32_ps(_mm256_blend_ps(_mm256_blend_ps(m0, m1, 0x49), m2, 0x92),
                                  _mm256_setr_epi32(2, 5, 0, 3, 6, 1, 4, 7));
  } else {
    alignas(32) float gx[8], gy[8], gz[8];
    for (int j = 0; j < 8; ++j) {
      const float* n = in.normal.pixel(x + j, y);
      gx[j] = n[0], gy[j] = n[1], gz[j] = n[2];
    }
    wx = _mm256_load_ps(gx), wy = _mm256_load_ps(gy), wz = _mm256_load_ps(gz);
  }
  if (q) {
    // snormCentre: clamp as max/min do (NaN -> -1), scale, round to nearest
    // even, + 0 (no -0).
    wx = q[0] = snormCentre8(wx), wy = q[1] = snormCentre8(wy), wz = q[2] = snormCentre8(wz);
  }
  return centre8<Ortho>(d, wx, wy, wz, ux, set8(uy), cam);
}

// rsaa::differs of any sample, as an 8-bit lane mask, for pixels x..x+7 of
// row y, sub-samples in the 8 float4 images.
template <bool Ortho>
CRISP_AVX2 int anyDiffers8(const Inputs& in, int x, int y, const float* colUx, float uy, const float* dux,
                           const float* duy, const Camera& cam, float threshold2) {
  const __m256 ux = _mm256_loadu_ps(colUx + x);
  const Centre8 c = loadCentres8<Ortho>(in, x, y, ux, uy, cam);
  const __m256 t2 = set8(threshold2);
  __m256 any = _mm256_setzero_ps();
  for (int k = 0; k < kSamples; ++k) {
    const float* row = in.sub[k].pixel(x, y);  // packed float4
    const float* p[8] = {row, row + 4, row + 8, row + 12, row + 16, row + 20, row + 24, row + 28};
    any = _mm256_or_ps(any, differsLanes<Ortho>(p, c, _mm256_add_ps(ux, set8(dux[k])), set8(uy + duy[k]), cam, t2));
  }
  return _mm256_movemask_ps(any);
}

// Transposes 8 rows of 8 floats (row j = lane j of the result's vectors).
CRISP_AVX2 inline void transpose8x8(__m256 r[8]) {
  __m256 t[8], s[8];
  for (int i = 0; i < 8; i += 2) {
    t[i] = _mm256_unpacklo_ps(r[i], r[i + 1]);
    t[i + 1] = _mm256_unpackhi_ps(r[i], r[i + 1]);
  }
  for (int h = 0; h < 8; h += 4) {
    s[h] = _mm256_shuffle_ps(t[h], t[h + 2], _MM_SHUFFLE(1, 0, 1, 0));
    s[h + 1] = _mm256_shuffle_ps(t[h], t[h + 2], _MM_SHUFFLE(3, 2, 3, 2));
    s[h + 2] = _mm256_shuffle_ps(t[h + 1], t[h + 3], _MM_SHUFFLE(1, 0, 1, 0));
    s[h + 3] = _mm256_shuffle_ps(t[h + 1], t[h + 3], _MM_SHUFFLE(3, 2, 3, 2));
  }
  for (int k = 0; k < 4; ++k) {
    r[k] = _mm256_permute2f128_ps(s[k], s[k + 4], 0x20);
    r[k + 4] = _mm256_permute2f128_ps(s[k], s[k + 4], 0x31);
  }
}

// Transposes 8 rows of 8 int16 (row j = element j of the result; a[k]
// then holds element k of the 8 rows), in each 128-bit half of a[] (AVX2)
// or in one 128-bit vector (SSE2).
#define CRISP_RSAA_TRANSPOSE8X8_I16(V, a, lo16, hi16, lo32, hi32, lo64, hi64) \
  do {                                                                      \
    V s_[8], t_[8];                                                         \
    for (int i_ = 0; i_ < 8; i_ += 2) {                                     \
      s_[i_] = lo16(a[i_], a[i_ + 1]);     /* elements 0-3 of rows i, i+1 */ \
      s_[i_ + 1] = hi16(a[i_], a[i_ + 1]); /* elements 4-7 */               \
    }                                                                       \
    for (int h_ = 0; h_ < 8; h_ += 4) {                                     \
      t_[h_] = lo32(s_[h_], s_[h_ + 2]);         /* rows h..h+3: 0, 1 */    \
      t_[h_ + 1] = hi32(s_[h_], s_[h_ + 2]);     /* 2, 3 */                 \
      t_[h_ + 2] = lo32(s_[h_ + 1], s_[h_ + 3]); /* 4, 5 */                 \
      t_[h_ + 3] = hi32(s_[h_ + 1], s_[h_ + 3]); /* 6, 7 */                 \
    }                                                                       \
    for (int e_ = 0; e_ < 4; ++e_) {                                        \
      a[2 * e_] = lo64(t_[e_], t_[e_ + 4]);                                 \
      a[2 * e_ + 1] = hi64(t_[e_], t_[e_ + 4]);                             \
    }                                                                       \
  } while (0)

CRISP_AVX2 inline __m256 int16ToFloat8(__m128i v) { return _mm256_cvtepi32_ps(_mm256_cvtepi16_epi32(v)); }

// vpshufb controls of sameNormals8: for pixel j = 0..3, kPickXY[j] takes
// int16 word j into every word of the low 128 bits and word 4 + j into the
// high 128 bits; kPickZ[j] word j into both.
struct alignas(32) WordPick {
  std::uint8_t byte[32];
};
constexpr WordPick pickWords(int lo, int hi) {
  WordPick p{};
  for (int i = 0; i < 16; i += 2) {
    p.byte[i] = std::uint8_t(2 * lo), p.byte[i + 1] = std::uint8_t(2 * lo + 1);
    p.byte[16 + i] = std::uint8_t(2 * hi), p.byte[17 + i] = std::uint8_t(2 * hi + 1);
  }
  return p;
}
constexpr WordPick kPickXY[4] = {pickWords(0, 4), pickWords(1, 5), pickWords(2, 6), pickWords(3, 7)};
constexpr WordPick kPickZ[4] = {pickWords(0, 0), pickWords(1, 1), pickWords(2, 2), pickWords(3, 3)};

CRISP_AVX2 inline __m256i loadPick(const WordPick& p) {
  return _mm256_load_si256(reinterpret_cast<const __m256i*>(p.byte));
}

// True when every sample normal of the 8 records rec[0..7] equals its pixel's
// centre normal at the records' precision (q: snormCentre of the 8 centres,
// integer floats), i.e. when every sample step of anyDiffersPacked8 can take
// sameNormalStep8. Compared as int16 in the records' own layout (no
// transpose): per pixel j, its centre's x and y words spread over 8 words
// each against the record's nx|ny, its z word against nz.
CRISP_AVX2 inline bool sameNormals8(const SubsampleRecord* rec, const __m256 q[3]) {
  // Per 128-bit half h (pixels 4h..4h+3): xy = x[4h..4h+3], y[4h..4h+3];
  // z = z[4h..4h+3] twice (the values are integers within int16).
  const __m256i xy = _mm256_packs_epi32(_mm256_cvtps_epi32(q[0]), _mm256_cvtps_epi32(q[1]));
  const __m256i zi = _mm256_cvtps_epi32(q[2]);
  const __m256i z = _mm256_packs_epi32(zi, zi);
  const __m256i xyLo = _mm256_permute2x128_si256(xy, xy, 0x00), xyHi = _mm256_permute2x128_si256(xy, xy, 0x11);
  __m256i eq = _mm256_set1_epi32(-1);
  for (int j = 0; j < 4; ++j) {
    const __m256i pickXY = loadPick(kPickXY[j]);
    const __m256i nxy = _mm256_loadu_si256(reinterpret_cast<const __m256i*>(rec[j].nx));  // nx[8] then ny[8]
    const __m256i nxy4 = _mm256_loadu_si256(reinterpret_cast<const __m256i*>(rec[j + 4].nx));
    const __m256i nz = _mm256_loadu2_m128i(reinterpret_cast<const __m128i*>(rec[j + 4].nz),
                                           reinterpret_cast<const __m128i*>(rec[j].nz));
    eq = _mm256_and_si256(eq, _mm256_cmpeq_epi16(nxy, _mm256_shuffle_epi8(xyLo, pickXY)));
    eq = _mm256_and_si256(eq, _mm256_cmpeq_epi16(nxy4, _mm256_shuffle_epi8(xyHi, pickXY)));
    eq = _mm256_and_si256(eq, _mm256_cmpeq_epi16(nz, _mm256_shuffle_epi8(z, loadPick(kPickZ[j]))));
  }
  return _mm256_testc_si256(eq, _mm256_set1_epi32(-1)) != 0;
}

// The sample steps of anyDiffersPacked8 where some sample normal differs from
// its centre's: the 8 records' nx|ny and nz fields are transposed to one
// vector per sample (lane j = pixel x + j) and converted exactly; per step,
// sameNormalStep8 where all 8 lanes' normals equal their centres', else
// differsLanes. Out of line, so that its loads and transposes stay off the
// flat-face path.
template <bool Ortho>
CRISP_AVX2 __attribute__((noinline)) __m256 mixedNormalSteps8(const SubsampleRecord* rec, const __m256 d[8],
                                                              const Centre8& c, const __m256 q[3], __m256 ux,
                                                              const float* dux, const float* suy,
                                                              const Camera& packedCam, __m256 t2) {
  __m256i nxy[8];
  __m128i nz[8];
  for (int j = 0; j < 8; ++j) {
    nxy[j] = _mm256_loadu_si256(reinterpret_cast<const __m256i*>(rec[j].nx));  // nx[8] then ny[8]
    nz[j] = _mm_loadu_si128(reinterpret_cast<const __m128i*>(rec[j].nz));
  }
  CRISP_RSAA_TRANSPOSE8X8_I16(__m256i, nxy, _mm256_unpacklo_epi16, _mm256_unpackhi_epi16, _mm256_unpacklo_epi32,
                              _mm256_unpackhi_epi32, _mm256_unpacklo_epi64, _mm256_unpackhi_epi64);
  CRISP_RSAA_TRANSPOSE8X8_I16(__m128i, nz, _mm_unpacklo_epi16, _mm_unpackhi_epi16, _mm_unpacklo_epi32,
                              _mm_unpackhi_epi32, _mm_unpacklo_epi64, _mm_unpackhi_epi64);
  const __m256 cd = _mm256_xor_ps(c.pz, set8(-0.0f));
  __m256 any = _mm256_setzero_ps();
  for (int k = 0; k < kSamples; ++k) {
    const __m256 wx = int16ToFloat8(_mm256_castsi256_si128(nxy[k]));
    const __m256 wy = int16ToFloat8(_mm256_extracti128_si256(nxy[k], 1));
    const __m256 wz = int16ToFloat8(nz[k]);
    const __m256 sux = _mm256_add_ps(ux, set8(dux[k])), sy = set8(suy[k]);
    // This step's 8 sample normals equal to their centres' (as integers)?
    const __m256 same = _mm256_and_ps(_mm256_and_ps(_mm256_cmp_ps(wx, q[0], _CMP_EQ_OQ), _mm256_cmp_ps(wy, q[1], _CMP_EQ_OQ)),
                                      _mm256_cmp_ps(wz, q[2], _CMP_EQ_OQ));
    any = _mm256_or_ps(any, _mm256_movemask_ps(same) == 0xFF
                                ? sameNormalStep8<Ortho, true>(d[k], c, cd, sux, sy, packedCam, t2)
                                : differsLanes<Ortho>(wx, wy, wz, d[k], c, sux, sy, packedCam, t2));
  }
  return any;
}

// anyDiffers8 for packed records (rsaa/subsample_record.h): the 8 records'
// depth fields are transposed to one vector per sample (lane j = pixel x +
// j). Where all 8 centres are background a sample differs iff it is
// geometry; where all sample normals equal their centres' (a flat face,
// sameNormals8) no normal is decoded; else mixedNormalSteps8. packedCam
// rotates the int16 normals with the 1/32767 scale folded in (as subGeo
// does); suy[k] = uy + duy[k], the ray terms of sample k's row.
template <bool Ortho>
CRISP_AVX2 inline __attribute__((always_inline)) int anyDiffersPacked8(const Inputs& in, int x, int y,
                                                                       const float* colUx, float uy, const float* dux,
                                                                       const float* suy, const Camera& packedCam,
                                                                       float threshold2) {
  const __m256 ux = _mm256_loadu_ps(colUx + x);
  __m256 q[3];
  const Centre8 c = loadCentres8<Ortho>(in, x, y, ux, uy, packedCam, q);
  const SubsampleRecord* rec = subsampleRecord(in.packed, x, y);
  __m256 d[8];
  for (int j = 0; j < 8; ++j) d[j] = _mm256_loadu_ps(rec[j].depth);
  transpose8x8(d);
  const int bgCentres = _mm256_movemask_ps(c.bg);
  __m256 any = _mm256_setzero_ps();
  if (bgCentres == 0xFF) {  // differsResult8 with every c.bg set: the sample is not background
    for (int k = 0; k < kSamples; ++k) any = _mm256_or_ps(any, _mm256_cmp_ps(d[k], set8(kFarDepth), _CMP_LT_OQ));
    return _mm256_movemask_ps(any);
  }
  const __m256 t2 = set8(threshold2);
  if (!sameNormals8(rec, q))
    return _mm256_movemask_ps(mixedNormalSteps8<Ortho>(rec, d, c, q, ux, dux, suy, packedCam, t2));
  const __m256 cd = _mm256_xor_ps(c.pz, set8(-0.0f));
  if (bgCentres)
    for (int k = 0; k < kSamples; ++k)
      any = _mm256_or_ps(any, sameNormalStep8<Ortho, true>(d[k], c, cd, _mm256_add_ps(ux, set8(dux[k])),
                                                           set8(suy[k]), packedCam, t2));
  else
    for (int k = 0; k < kSamples; ++k)
      any = _mm256_or_ps(any, sameNormalStep8<Ortho, false>(d[k], c, cd, _mm256_add_ps(ux, set8(dux[k])),
                                                            set8(suy[k]), packedCam, t2));
  return _mm256_movemask_ps(any);
}

// rsaa::sadp(centre, sample k) for the 8 samples of one pixel, lane k =
// sample k (world normals wx, wy, wz, which cam rotates; depths d; ray terms
// sux, suy): the operations of sadp in its order, the square root and the
// division correctly rounded as the scalar ones, so the same bits.
template <bool Ortho>
CRISP_AVX2 inline __m256 sadpLanes(__m256 wx, __m256 wy, __m256 wz, __m256 d, const Geo& centre, __m256 sux,
                                   __m256 suy, const Camera& cam) {
  const Centre8 c = broadcastCentre8(centre);
  const SampleR8 s = sampleR8<Ortho>(d, c, sux, suy);
  __m256 v = _mm256_div_ps(sadpNumerator8<Ortho>(wx, wy, wz, d, c, s, sux, suy, cam), _mm256_sqrt_ps(s.r2));
  v = _mm256_blendv_ps(set8(kDifferentSadp), v, _mm256_cmp_ps(v, v, _CMP_ORD_Q));  // NaN: different
  v = _mm256_and_ps(v, s.apart);  // coincident points: 0
  // Background on either side: 0 for two background points, else different.
  const __m256 bgValue = _mm256_and_ps(_mm256_xor_ps(c.bg, s.bg), set8(kDifferentSadp));
  return _mm256_blendv_ps(v, bgValue, _mm256_or_ps(c.bg, s.bg));
}

// SADP of the 8 samples of pixel (x, y) against its centre into s[], from
// the packed record (int16 normals, packedCam) or the 8 float4 images (cam).
// The samples' ray terms are the centre's (ux, uy) plus the pattern's steps
// (dux, duy), added as subGeo adds them.
template <bool Ortho>
CRISP_AVX2 void pixelSadp8(const Inputs& in, int x, int y, const Geo& centre, float ux, float uy, const float* dux,
                           const float* duy, const Camera& cam, const Camera& packedCam, float s[kSamples]) {
  const __m256 sux = _mm256_add_ps(set8(ux), _mm256_loadu_ps(dux)), suy = _mm256_add_ps(set8(uy), _mm256_loadu_ps(duy));
  __m256 v;
  if (in.packed.valid()) {
    const SubsampleRecord* r = subsampleRecord(in.packed, x, y);
    v = sadpLanes<Ortho>(int16ToFloat8(_mm_loadu_si128(reinterpret_cast<const __m128i*>(r->nx))),
                         int16ToFloat8(_mm_loadu_si128(reinterpret_cast<const __m128i*>(r->ny))),
                         int16ToFloat8(_mm_loadu_si128(reinterpret_cast<const __m128i*>(r->nz))),
                         _mm256_loadu_ps(r->depth), centre, sux, suy, packedCam);
  } else {
    const float* p[kSamples];
    for (int k = 0; k < kSamples; ++k) p[k] = in.sub[k].pixel(x, y);
    __m256 wx, wy, wz, d;
    load8x4(p, wx, wy, wz, d);
    v = sadpLanes<Ortho>(wx, wy, wz, d, centre, sux, suy, cam);
  }
  _mm256_storeu_ps(s, v);
}

// anyDiffersPacked8 for the chunks x = 8 c, c < chunks, of row y into
// bits[c]: one call per row, so that what the chunks share (the camera's
// broadcasts, the images' addresses) is set up once.
template <bool Ortho>
CRISP_AVX2 void anyDiffersPackedRow(const Inputs& in, int y, int chunks, const float* colUx, float uy,
                                    const float* dux, const float* suy, const Camera& packedCam, float threshold2,
                                    std::uint8_t* bits) {
  constexpr int kAhead = 4;  // chunks
  for (int c = 0; c < chunks; ++c) {
    if (c + kAhead < chunks) {
      const char* next = reinterpret_cast<const char*>(subsampleRecord(in.packed, 8 * (c + kAhead), y));
      for (int line = 0; line < 8 * int(sizeof(SubsampleRecord)); line += 64) _mm_prefetch(next + line, _MM_HINT_T0);
    }
    bits[c] = std::uint8_t(anyDiffersPacked8<Ortho>(in, 8 * c, y, colUx, uy, dux, suy, packedCam, threshold2));
  }
}

// sanitizeColor in 8 lanes: NaN -> 0, then clamp to +-kMaxColor, as
// std::clamp does (the bounds are finite, so max/min give the same values).
CRISP_AVX2 inline __m256 sanitize8(__m256 v) {
  const __m256 finiteOrInf = _mm256_and_ps(v, _mm256_cmp_ps(v, v, _CMP_ORD_Q));
  return _mm256_min_ps(_mm256_max_ps(finiteOrInf, set8(-kMaxColor)), set8(kMaxColor));
}

// sanitizeColor of 8 packed RGBA pixels (32 floats) from src to dst.
CRISP_AVX2 inline void sanitizeCopy8(const float* src, float* dst) {
  for (int j = 0; j < 32; j += 8) _mm256_storeu_ps(dst + j, sanitize8(_mm256_loadu_ps(src + j)));
}

#endif

std::atomic<int> gSimdLanes{0};  // setSimdLanesForTesting

bool useAvx2() {
#if defined(CRISP_RSAA_AVX2)
  const int lanes = gSimdLanes.load(std::memory_order_relaxed);
  return cpuHasAvx2() && lanes != 4;
#else
  return false;
#endif
}

}  // namespace

void setSimdLanesForTesting(int lanes) { gSimdLanes.store(lanes, std::memory_order_relaxed); }

void Kernel::runRows(const Inputs& in, const ImageView& output, int y0, int y1, bool simd) {
  const int outChannels = output.channels();
  Geo subs[kSamples];
  float colour[4];
#if defined(__SSE2__)
  const __m128 dux0 = _mm_setr_ps(dux_[0], dux_[1], dux_[2], dux_[3]);
  const __m128 dux1 = _mm_setr_ps(dux_[4], dux_[5], dux_[6], dux_[7]);
  const __m128 duy0 = _mm_setr_ps(duy_[0], duy_[1], duy_[2], duy_[3]);
  const __m128 duy1 = _mm_setr_ps(duy_[4], duy_[5], duy_[6], duy_[7]);
#else
  simd = false;
#endif
  const Camera& cam = settings_.camera;
  const bool textureFxaa = settings_.textureAA == TextureAA::Fxaa;
  const bool packed = in.packed.valid();
#if defined(CRISP_RSAA_AVX2)
  const bool avx2 = simd && useAvx2();
#endif
  // The per-pixel SIMD tests read float4 images; records elsewhere go through subGeo.
  const bool pixelSimd = simd && !packed;
#if defined(CRISP_RSAA_AVX2)
  // 8 pixels at a time where the sub-samples are packed records or packed
  // float4 images (as the library's frames and the C API's usual images are).
  bool chunks = avx2;
  if (packed)
    chunks = chunks && in.packed.pixelStride == sizeof(SubsampleRecord);
  else
    for (int k = 0; k < kSamples; ++k) chunks = chunks && in.sub[k].pixelStride == 16;
#endif
  for (int y = y0; y < y1; ++y) {
    int x = 0;
#if defined(CRISP_RSAA_AVX2)
    if (chunks) {
      const float uy = rowUy_[std::size_t(y)];
      float suy[kSamples];  // the sample rows' ray terms, as subGeo forms them
      for (int k = 0; k < kSamples; ++k) suy[k] = uy + duy_[k];
      std::uint8_t* rowBits = chunkBits_.data() + std::size_t(y) * std::size_t(width_ / 8);  // empty below 8 px wide
      if (packed) {  // the whole row's test first
        if (cam.orthographic)
          anyDiffersPackedRow<true>(in, y, width_ / 8, colUx_.data(), uy, dux_, suy, packedCamera_, threshold2_, rowBits);
        else
          anyDiffersPackedRow<false>(in, y, width_ / 8, colUx_.data(), uy, dux_, suy, packedCamera_, threshold2_,
                                     rowBits);
      }
      for (; x + 8 <= width_; x += 8) {
        const int bits =
            packed ? rowBits[x / 8]
                   : (cam.orthographic ? anyDiffers8<true>(in, x, y, colUx_.data(), uy, dux_, duy_, cam, threshold2_)
                                       : anyDiffers8<false>(in, x, y, colUx_.data(), uy, dux_, duy_, cam, threshold2_));
        const std::size_t i0 = std::size_t(y) * std::size_t(width_) + std::size_t(x);
        if (bits == 0) {  // most chunks: all 8 pixels inside one polygon
          std::memset(&geometric_[i0], 0, 8);
          std::memset(&halved_[i0], 0, 8);
          std::memset(&masks_[i0], 255, 8);
          if (textureFxaa) continue;
          const float* src = direct_ ? (direct_->pixelStride == 16 && direct_->channels() == 4 ? direct_->pixel(x, y)
                                                                                                 : nullptr)
                                     : staged_.at(x, y);
          if (src && outChannels == 4 && output.pixelStride == 16) {
            sanitizeCopy8(src, output.pixel(x, y));
            continue;
          }
        }
        for (int j = 0; j < 8; ++j) {
          const int xj = x + j;
          const std::size_t i = std::size_t(y) * std::size_t(width_) + std::size_t(xj);
          const bool any = (bits >> j) & 1;
          geometric_[i] = any;
          if (any) {  // the 8 SADPs in one AVX2 step, then resolve
            const Geo centre = centreGeo(in, xj, y);
            const float ux = colUx_[std::size_t(xj)], uy = rowUy_[std::size_t(y)];
            float s[kSamples];
            if (cam.orthographic)
              pixelSadp8<true>(in, xj, y, centre, ux, uy, dux_, duy_, cam, packedCamera_, s);
            else
              pixelSadp8<false>(in, xj, y, centre, ux, uy, dux_, duy_, cam, packedCamera_, s);
            resolve(in, xj, y, centre, s, colour);
          } else {
            masks_[i] = 255;
            halved_[i] = 0;
            if (textureFxaa) continue;
            texel(xj, y, colour);
          }
          float* o = output.pixel(xj, y);
          for (int c = 0; c < outChannels; ++c) o[c] = colour[c];
        }
      }
    }
#endif
    for (; x < width_; ++x) {
      const Geo centre = centreGeo(in, x, y);
      bool any = false;
#if defined(__SSE2__)
      if (pixelSimd) {
        const float ux = colUx_[std::size_t(x)], uy = rowUy_[std::size_t(y)];
        const float* p[kSamples];
        for (int k = 0; k < kSamples; ++k) p[k] = in.sub[k].pixel(x, y);
        int bits;
#if defined(CRISP_RSAA_AVX2)
        if (avx2)
          bits = cam.orthographic ? differs8<true>(p, centre, ux, uy, dux_, duy_, cam, threshold2_)
                                  : differs8<false>(p, centre, ux, uy, dux_, duy_, cam, threshold2_);
        else
#endif
          bits = cam.orthographic
                     ? differs4<true>(p[0], p[1], p[2], p[3], centre, ux, uy, dux0, duy0, cam, threshold2_) |
                           differs4<true>(p[4], p[5], p[6], p[7], centre, ux, uy, dux1, duy1, cam, threshold2_)
                     : differs4<false>(p[0], p[1], p[2], p[3], centre, ux, uy, dux0, duy0, cam, threshold2_) |
                           differs4<false>(p[4], p[5], p[6], p[7], centre, ux, uy, dux1, duy1, cam, threshold2_);
        any = bits != 0;
        if (any)
          for (int k = 0; k < kSamples; ++k) subs[k] = subGeo(in, k, x, y);
      }
#endif
      if (!pixelSimd) {
        for (int k = 0; k < kSamples; ++k) {
          subs[k] = subGeo(in, k, x, y);
          any = any || differs(centre, subs[k], threshold2_);
        }
      }
      const std::size_t i = std::size_t(y) * std::size_t(width_) + std::size_t(x);
      geometric_[i] = any;
      if (any) {
        float s[kSamples];
        for (int k = 0; k < kSamples; ++k) s[k] = sadp(centre, subs[k]);
        resolve(in, x, y, centre, s, colour);
      } else {
        masks_[i] = 255;
        halved_[i] = 0;
        if (textureFxaa) continue;  // the output holds FXAA's colour; guardRows decides
        texel(x, y, colour);
      }
      float* o = output.pixel(x, y);
      for (int k = 0; k < outChannels; ++k) o[k] = colour[k];
    }
    // textureAA = fxaa, fast path: guard the row above while its rows are in
    // cache, once its neighbours above and below are classified (both in this
    // band); run() guards the first and last row of each band afterwards.
    if (textureFxaa && simd) {
      rowGuarded_[std::size_t(y)] = 0;
      if (y - 1 > y0) {
        guardRows(in, output, y - 1, y, true);
        rowGuarded_[std::size_t(y - 1)] = 1;
      }
    }
  }
}

// FXAA may move a pixel's colour towards one of its 4 neighbours (its final
// bilinear fetch is at most one pixel across the edge it found). A pixel keeps
// FXAA's colour only when that cannot mix two surfaces:
//  * no pixel of its 3x3 neighbourhood is geometric (RSAA's classification:
//    some sub-sample on another polygon), and
//  * its centre and each 4-neighbour's centre are one surface (rsaa::differs
//    on the two centres), which catches an edge that passes between two
//    centres in the strip the sub-samples (|offset| <= 0.375 px) do not see.
// The second test runs only where FXAA changed the colour (a few % of pixels).
void Kernel::guardRows(const Inputs& in, const ImageView& output, int y0, int y1, bool simd) {
  const int outChannels = output.channels();
  // Fast path (after fxaa::runFast): only pixels that passed FXAA's contrast
  // check can have changed, so the others (most of the image) are skipped by
  // their flag bytes, 8 at a time, without reading colour or output.
  const std::uint8_t* searched = simd ? fxaa_.searchFlags() : nullptr;
  for (int y = y0; y < y1; ++y)
    for (int x = 0; x < width_; ++x) {
      const std::size_t i = std::size_t(y) * std::size_t(width_) + std::size_t(x);
      if (searched && x % 8 == 0 && x + 8 <= width_ && fxaa::noneOf8(searched + i)) {
        std::memset(&textured_[i], 0, 8);
        x += 7;
        continue;
      }
      textured_[i] = 0;
      if ((searched && !searched[i]) || geometric_[i]) continue;  // FXAA left it alone, or RSAA's result
      float colour[4];
      texel(x, y, colour);
      const float* o = output.pixel(x, y);
      bool changed = false;
      for (int k = 0; k < outChannels; ++k) changed = changed || o[k] != colour[k];
      if (changed) guardChanged(in, output, x, y);
    }
}

void Kernel::guardChanged(const Inputs& in, const ImageView& output, int x, int y) {
  static constexpr int kNeighbour4[4][2] = {{-1, 0}, {1, 0}, {0, -1}, {0, 1}};
  bool guarded = false;
  for (int yy = std::max(y - 1, 0); yy <= std::min(y + 1, height_ - 1) && !guarded; ++yy)
    for (int xx = std::max(x - 1, 0); xx <= std::min(x + 1, width_ - 1); ++xx)
      guarded = guarded || geometric_[std::size_t(yy) * std::size_t(width_) + std::size_t(xx)];
  if (!guarded) {
    const Geo centre = centreGeo(in, x, y);
    for (const auto& d : kNeighbour4) {
      const int nx = x + d[0], ny = y + d[1];
      if (nx < 0 || ny < 0 || nx >= width_ || ny >= height_) continue;
      if (differs(centre, centreGeo(in, nx, ny), threshold2_)) {
        guarded = true;
        break;
      }
    }
  }
  if (guarded) {
    float colour[4];
    texel(x, y, colour);
    float* o = output.pixel(x, y);
    for (int k = 0; k < output.channels(); ++k) o[k] = colour[k];
  } else {
    textured_[std::size_t(y) * std::size_t(width_) + std::size_t(x)] = 1;
  }
}

void Kernel::run(const Inputs& in, const ImageView& output, bool reference, int numThreads) {
  if (in.color.width != width_ || in.color.height != height_ || output.width != width_ || output.height != height_)
    invalidArgument("rsaa: images are " + std::to_string(in.color.width) + "x" + std::to_string(in.color.height) +
                    " but the kernel was allocated for " + std::to_string(width_) + "x" + std::to_string(height_));
  // Staging is needed only when the output overwrites colour that later pixels still fetch.
  direct_ = viewsOverlap(in.color, output) ? nullptr : &in.color;
  simdFetch_ = !reference;
  const auto rows = [&](auto&& body) {
    if (reference)
      body(0, height_);
    else
      parallelRows(width_, height_, numThreads, body);
  };
  // The staged colour must be complete before any pixel fetches neighbours.
  if (!direct_) rows([&](int y0, int y1) { stage(in.color, y0, y1); });
  const bool textureFxaa = settings_.textureAA == TextureAA::Fxaa;
  if (textureFxaa) {
    // FXAA of the whole (sanitised) colour into the output; runRows then
    // overwrites the geometric pixels and guardRows the ones FXAA must not touch.
    const ImageView source = direct_ ? in.color : staged_.view();
    if (reference)
      fxaa::runReference(source, output, settings_.fxaa, fxaa_);
    else
      fxaa::runFast(source, output, settings_.fxaa, fxaa_, numThreads);
  }
  rows([&](int y0, int y1) { runRows(in, output, y0, y1, !reference); });
  if (textureFxaa) {
    if (reference)
      guardRows(in, output, 0, height_, false);
    else  // the rows runRows could not guard (first and last of its bands)
      parallelRows(width_, height_, numThreads, [&](int y0, int y1) {
        for (int y = y0; y < y1; ++y)
          if (!rowGuarded_[std::size_t(y)]) guardRows(in, output, y, y + 1, true);
      });
  }
  direct_ = nullptr;
}

}  // namespace crisp::rsaa

// ---------------------------------------------------------------- filter --

namespace crisp {
namespace {

// The parameter documentation (crisp help rsaa, crispGetFilterDoc).
std::vector<ParamSpec> rsaaParams() {
  return {
      {"threshold", ParamType::Float, 0.2, 0.0, 2.0, nullptr,
       "SADP at and above which a sub-sample counts as another polygon; a pixel none of whose 8 samples "
       "reaches it keeps its colour. SADP is about the crease angle in radians for two faces meeting at an "
       "edge (0.2 ~ 11 degrees) and ~2 across a depth jump; background vs geometry counts as 2",
       "eq. 2.1, section 2.3.1, Algorithm 1"},
      {"verification", ParamType::String, 0, 0, 0, "halve|reassign|none",
       "offset verification: halve = halve the offset when the neighbouring centre it leans to has SADP >= "
       "2x the farthest different sample's (4.4.3); reassign = a different sample must be more similar to "
       "the neighbouring centre in its direction than to its own (2.3.3); none = table offset as is",
       "sections 2.3.3, 4.4.3, figures 2.8, 5.5"},
      {"orthographic", ParamType::Bool, 0, 0, 1, nullptr,
       "orthographic camera (the sidecar's camera.projection[3][3] == 1); else perspective", "section 4.4.1"},
      {"proj00", ParamType::Float, 1.0, 1e-6, 1e6, nullptr,
       "camera.projection[0][0] (OpenGL-style, from the sidecar; cot(fov_x/2) for a perspective camera)",
       "section 4.4.1"},
      {"proj11", ParamType::Float, 1.0, 1e-6, 1e6, nullptr, "camera.projection[1][1]", "section 4.4.1"},
      {"proj02", ParamType::Float, 0.0, -1e6, 1e6, nullptr,
       "camera.projection[0][2] (lens shift incl. the frame's jitter; unused when orthographic)", "section 4.4.1"},
      {"proj12", ParamType::Float, 0.0, -1e6, 1e6, nullptr, "camera.projection[1][2]", "section 4.4.1"},
      {"view00", ParamType::Float, 1.0, -1e3, 1e3, nullptr,
       "camera.view[0][0]: view00..view22 are the rotation part of the world->view matrix, used to bring the "
       "world normals into the frame of the positions (identity by default: normals already in view space)",
       "section 4.4.1"},
      {"view01", ParamType::Float, 0.0, -1e3, 1e3, nullptr, "camera.view[0][1]", "section 4.4.1"},
      {"view02", ParamType::Float, 0.0, -1e3, 1e3, nullptr, "camera.view[0][2]", "section 4.4.1"},
      {"view10", ParamType::Float, 0.0, -1e3, 1e3, nullptr, "camera.view[1][0]", "section 4.4.1"},
      {"view11", ParamType::Float, 1.0, -1e3, 1e3, nullptr, "camera.view[1][1]", "section 4.4.1"},
      {"view12", ParamType::Float, 0.0, -1e3, 1e3, nullptr, "camera.view[1][2]", "section 4.4.1"},
      {"view20", ParamType::Float, 0.0, -1e3, 1e3, nullptr, "camera.view[2][0]", "section 4.4.1"},
      {"view21", ParamType::Float, 0.0, -1e3, 1e3, nullptr, "camera.view[2][1]", "section 4.4.1"},
      {"view22", ParamType::Float, 1.0, -1e3, 1e3, nullptr, "camera.view[2][2]", "section 4.4.1"},
      {"depthUlps", ParamType::Float, 1.0, 0.0, 64.0, nullptr,
       "depth precision in units in the last place of a half float at that depth: depth differences up to "
       "this are taken as 0 in SADP. Blender 3.4's EEVEE writes Depth as half floats, so two points of one "
       "plane a fraction of a pixel apart differ by up to ~1 ulp and would otherwise count as a step; 0 = "
       "exact (float) depths",
       "eq. 2.1 (input precision)"},
      {"textureAA", ParamType::String, 0, 0, 0, "fxaa|none",
       "what handles the pixels geometry does not resolve (texture, shading and shadow edges, which SADP cannot "
       "see): fxaa = the library's FXAA (filters/fxaa.h, its defaults) on every pixel that is not geometric, "
       "unless a geometric pixel is in its 3x3 neighbourhood or its centre and a 4-neighbour's centre differ "
       "(so FXAA never blends across a geometric edge); none = those pixels keep their colour (the thesis' RSAA)",
       "product extension beyond seed 003 (RSAA + post-process AA, like MSAA + FXAA); docs/rsaa.md"},
      {"reference", ParamType::Bool, 0, 0, 1, nullptr,
       "run the scalar reference path (one thread); bit-identical to the fast path", "section 4.4.2"},
  };
}

constexpr const char* kSubRoles[rsaa::kSamples] = {"sub0", "sub1", "sub2", "sub3", "sub4", "sub5", "sub6", "sub7"};

std::vector<ImageRole> rsaaRoles() {
  std::vector<ImageRole> roles = {
      {"color", true, 3, 4, false, "linear RGB(A) colour, 1 sample at the pixel centre"},
      {"depth", true, 1, 4, false, "planar view depth at the pixel centre (channel 0; background >= 65504)"},
      {"normal", true, 3, 4, false, "world-space normal at the pixel centre (xyz)"},
      {"output", true, 3, 4, false, "filtered colour, same size (may be the colour buffer)"},
  };
  roles.push_back({"subsamples", false, kRsaaSubsampleWords, kRsaaSubsampleWords, false,
                   "the 8 geometric sub-samples of each pixel in one 80-byte record (CRISP_FORMAT_RSAA_SUBSAMPLES: "
                   "float32 planar depth[8], int16 snorm world normal x[8], y[8], z[8], in the pattern's order; "
                   "crispAttachFrameSubsamples makes it); used instead of sub0..sub7 when set (62 % of their bytes)"});
  for (int k = 0; k < rsaa::kSamples; ++k)
    roles.push_back({kSubRoles[k], false, 4, 4, false,
                     "geometric sub-sample k (frame_NNNN_subK.exr) at the pattern's offset k: world normal xyz + "
                     "planar depth in w (pattern, x right / y down: (-0.375,0.125) (0.125,0.375) (0.375,-0.125) "
                     "(-0.125,-0.375) (-0.25,-0.25) (0.25,-0.25) (0.25,0.25) (-0.25,0.25) = the add-on's "
                     "RSAA_PATTERN with y negated); all 8 are needed unless 'subsamples' is set"});
  return roles;
}

class RsaaFilter final : public Filter {
 public:
  explicit RsaaFilter(Context& c) : Filter(c, rsaaParams(), rsaaRoles()) {}
  const char* type() const override { return "rsaa"; }

 protected:
  // 'subsamples' supersedes sub0..sub7: a stale set of them, of another size,
  // does not stop the commit.
  bool readsImage(const std::string& role) const override {
    if (!hasImage("subsamples")) return true;
    for (const char* sub : kSubRoles)
      if (role == sub) return false;
    return true;
  }
  void onCommit() override {
    const ParamSet& p = params();
    rsaa::Settings s;
    s.threshold = p.getFloat("threshold");
    const std::string& v = p.getString("verification");
    s.verification = v == "none" ? rsaa::Verification::None
                     : v == "reassign" ? rsaa::Verification::Reassign
                                       : rsaa::Verification::Halve;
    rsaa::Camera& cam = s.camera;
    cam.orthographic = p.getBool("orthographic");
    cam.proj00 = p.getFloat("proj00");
    cam.proj11 = p.getFloat("proj11");
    cam.proj02 = p.getFloat("proj02");
    cam.proj12 = p.getFloat("proj12");
    cam.depthUlps = p.getFloat("depthUlps");
    for (int r = 0; r < 3; ++r)
      for (int c = 0; c < 3; ++c) cam.view[r][c] = p.getFloat("view" + std::to_string(r) + std::to_string(c));
    s.textureAA = p.getString("textureAA") == "none" ? rsaa::TextureAA::None : rsaa::TextureAA::Fxaa;
    reference_ = p.getBool("reference");
    if (!hasImage("subsamples"))
      for (int k = 0; k < rsaa::kSamples; ++k)
        if (!hasImage(kSubRoles[k]))
          invalidData(std::string("filter 'rsaa': image '") + kSubRoles[k] +
                      "' is not set: rsaa needs the geometric sub-samples, either as 'subsamples' (one "
                      "CRISP_FORMAT_RSAA_SUBSAMPLES record per pixel) or as the 8 float4 images 'sub0'..'sub7'");
    kernel_.allocate(width(), height(), s);
  }
  void onExecute() override {
    rsaa::Inputs in;
    in.color = image("color");  // the kernel reads colour in place itself
    in.depth = inputApartFromOutput("depth");
    in.normal = inputApartFromOutput("normal");
    // The texture pass reads the sub-samples again after output rows are written.
    if (hasImage("subsamples"))
      in.packed = inputApartFromOutput("subsamples");
    else
      for (int k = 0; k < rsaa::kSamples; ++k) in.sub[k] = inputApartFromOutput(kSubRoles[k]);
    kernel_.run(in, image("output"), reference_, numThreads());
  }

 private:
  bool reference_ = false;
  rsaa::Kernel kernel_;
};

}  // namespace

std::unique_ptr<Filter> newRsaaFilter(Context& c) { return std::make_unique<RsaaFilter>(c); }

}  // namespace crisp
