// SPDX-License-Identifier: Apache-2.0
// RSAA geometry: view-space positions of pixel-centre and sub-sample points
// from planar depth (seed 003, section 4.4.1, done per ray instead of with
// the inverse matrices) and the SADP similarity (eq. 2.1, section 2.3.1).
//
// Positions are view-space (camera looks down -z, y up), up to a translation
// that cancels in r = p2 - p1. World-space normals are rotated into view
// space by the upper 3x3 of the world->view matrix (Camera::view), so SADP
// sees both in one frame.
#pragma once

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <cstring>

#include "core/conventions.h"

namespace crisp::rsaa {

// SADP of a background/geometry pair: "different" (4.4.2), as large as SADP
// of unit normals gets (|n1.r| + |n2.r| <= 2 |r|).
constexpr float kDifferentSadp = 2.0f;
// |r|^2 <= kSamePoint2 * depth^2: the two points coincide (same surface
// point), SADP 0; guards the division by |r| (eq. 2.1).
constexpr float kSamePoint2 = 1e-12f;

// The camera as the Blender add-on's sidecar gives it: the OpenGL-style
// projection (camera.projection, jitter included) and the world->view
// matrix (camera.view). Only these terms matter for SADP.
struct Camera {
  bool orthographic = false;  // projection[3][3] == 1
  float proj00 = 1.0f, proj11 = 1.0f;  // focal terms (both non-zero)
  float proj02 = 0.0f, proj12 = 0.0f;  // lens shift (perspective)
  float view[3][3] = {{1, 0, 0}, {0, 1, 0}, {0, 0, 1}};  // rotation rows of world->view
  // Precision of the depth images, in units in the last place of a half
  // float at that depth (halfUlp): Blender 3.4's EEVEE writes its Depth pass
  // as half floats, so two points of one plane a fraction of a pixel apart
  // can differ by a whole ulp (0.004 at depth 5), which SADP would read as
  // a step. 0 = exact depths (synthetic input).
  float depthUlps = 0.0f;
};

// The spacing of half floats around depth d: 2^(floor(log2 d) - 10), at least
// 2^-24 (the smallest half subnormal step). Exact bit operations, so the SIMD
// path can repeat them.
inline float halfUlp(float d) {
  std::uint32_t bits;
  std::memcpy(&bits, &d, 4);
  bits &= 0x7F800000u;  // 2^floor(log2 |d|)
  float power;
  std::memcpy(&power, &bits, 4);
  return std::max(power * 0.0009765625f, 5.9604645e-8f);
}

// A point seen by the camera: view-space position and normal.
struct Geo {
  float px = 0, py = 0, pz = 0;
  float nx = 0, ny = 0, nz = 0;
  float vx = 0, vy = 0;  // view-ray terms: d(position)/d(depth) = (vx, vy, -1)
  float tolerance = 0;   // depth uncertainty: Camera::depthUlps x halfUlp(depth)
  bool background = true;
};

// The view-ray terms (ux, uy) of a point at continuous pixel position
// (pxl, pyl) (x right, y down, pixel (i, j) covers [i, i+1) x [j, j+1)):
// x_view = ux d, y_view = uy d, z_view = -d for planar depth d (perspective,
// from ndc = (P00 x + P02 z) / -z); x_view = ux, y_view = uy (orthographic,
// where the shift only translates).
inline double rayUx(double pxl, int width, const Camera& c) {
  const double ndc = 2.0 * pxl / width - 1.0;
  return c.orthographic ? ndc / c.proj00 : (ndc + c.proj02) / c.proj00;
}
inline double rayUy(double pyl, int height, const Camera& c) {
  const double ndc = 1.0 - 2.0 * pyl / height;
  return c.orthographic ? ndc / c.proj11 : (ndc + c.proj12) / c.proj11;
}

// Builds a Geo from depth, world normal and the point's ray terms. Every
// operation is written out in a fixed order: the SIMD path (filters/rsaa.cpp)
// repeats it lane by lane and must round the same way.
inline Geo makeGeo(float depth, float wx, float wy, float wz, float ux, float uy, const Camera& c) {
  Geo g;
  g.background = isBackgroundDepth(depth);
  if (g.background) return g;
  g.px = c.orthographic ? ux : ux * depth;
  g.py = c.orthographic ? uy : uy * depth;
  g.pz = -depth;
  g.vx = c.orthographic ? 0.0f : ux;
  g.vy = c.orthographic ? 0.0f : uy;
  g.tolerance = c.depthUlps * halfUlp(depth);
  g.nx = (c.view[0][0] * wx + c.view[0][1] * wy) + c.view[0][2] * wz;
  g.ny = (c.view[1][0] * wx + c.view[1][1] * wy) + c.view[1][2] * wz;
  g.nz = (c.view[2][0] * wx + c.view[2][1] * wy) + c.view[2][2] * wz;
  return g;
}

// How much a point's depth uncertainty can change n.r: the point moves along
// its view ray v = (ux, uy, -1) (perspective; (0, 0, -1) orthographic) by up
// to its tolerance, so n.p changes by up to |n.v| x tolerance.
inline float dotSlack(float nx, float ny, float nz, const Geo& p) {
  return std::fabs((nx * p.vx + ny * p.vy) - nz) * p.tolerance;
}

// |n.r| reduced by what the two points' depth uncertainties allow (never
// below 0): on one plane, stored half-float depths then give 0 as exact ones do.
inline float certainDot(float dot, float nx, float ny, float nz, const Geo& a, const Geo& b) {
  return std::max(std::fabs(dot) - (dotSlack(nx, ny, nz, a) + dotSlack(nx, ny, nz, b)), 0.0f);
}

// Eq. 2.1: sadp(n1, n2, r) = (|n1.r| + |n2.r|) / |r|, r = p2 - p1. 0 on one
// plane, growing with the angle between the normals and r. Background vs
// geometry = kDifferentSadp, background vs background = 0. Coincident points
// are 0; a non-finite result (non-finite normals) counts as different.
inline float sadp(const Geo& a, const Geo& b) {
  if (a.background || b.background) return a.background == b.background ? 0.0f : kDifferentSadp;
  const float rx = b.px - a.px, ry = b.py - a.py, rz = b.pz - a.pz;
  const float r2 = (rx * rx + ry * ry) + rz * rz;
  if (!(r2 > kSamePoint2 * (a.pz * a.pz))) return 0.0f;
  const float da = (a.nx * rx + a.ny * ry) + a.nz * rz;
  const float db = (b.nx * rx + b.ny * ry) + b.nz * rz;
  const float s = (certainDot(da, a.nx, a.ny, a.nz, a, b) + certainDot(db, b.nx, b.ny, b.nz, a, b)) / std::sqrt(r2);
  return s == s ? s : kDifferentSadp;
}

// sadp(a, b) >= threshold, decided without the square root or division:
// (|n1.r| + |n2.r|)^2 >= T^2 |r|^2 (threshold2 = T^2). Used to find the
// pixels that need RSAA at all (2.3.4: pixels whose samples all lie on the
// centre's polygon keep their colour). NaN counts as different.
inline bool differs(const Geo& a, const Geo& b, float threshold2) {
  if (a.background || b.background) return a.background != b.background;
  const float rx = b.px - a.px, ry = b.py - a.py, rz = b.pz - a.pz;
  const float r2 = (rx * rx + ry * ry) + rz * rz;
  if (!(r2 > kSamePoint2 * (a.pz * a.pz))) return false;
  const float da = (a.nx * rx + a.ny * ry) + a.nz * rz;
  const float db = (b.nx * rx + b.ny * ry) + b.nz * rz;
  const float dn = certainDot(da, a.nx, a.ny, a.nz, a, b) + certainDot(db, b.nx, b.ny, b.nz, a, b);
  return !(dn * dn < threshold2 * r2);
}

}  // namespace crisp::rsaa
