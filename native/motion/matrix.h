// SPDX-License-Identifier: Apache-2.0
// 4x4 double matrices laid out as Blender's mathutils.Matrix (and the JSON
// sidecars): m[row][col], acting on column vectors, p' = M * p. Double so a
// chain of five matrices per object costs no precision that matters in pixels.
#pragma once

#include <algorithm>
#include <array>
#include <cmath>
#include <utility>

namespace crisp {

struct Vec4d {
  double x = 0, y = 0, z = 0, w = 0;
};

struct Mat4 {
  std::array<std::array<double, 4>, 4> m{};

  static Mat4 identity() {
    Mat4 r;
    for (int i = 0; i < 4; ++i) r.m[i][i] = 1.0;
    return r;
  }
  Mat4 operator*(const Mat4& b) const {
    Mat4 r;
    for (int i = 0; i < 4; ++i)
      for (int j = 0; j < 4; ++j) {
        double s = 0.0;
        for (int k = 0; k < 4; ++k) s += m[i][k] * b.m[k][j];
        r.m[i][j] = s;
      }
    return r;
  }
  Vec4d operator*(const Vec4d& p) const {
    auto row = [&](int i) { return m[i][0] * p.x + m[i][1] * p.y + m[i][2] * p.z + m[i][3] * p.w; };
    return {row(0), row(1), row(2), row(3)};
  }
  bool operator==(const Mat4& b) const { return m == b.m; }
  bool finite() const {
    for (const auto& r : m)
      for (double v : r)
        if (!std::isfinite(v)) return false;
    return true;
  }
};

// Gauss-Jordan with partial pivoting. Returns false (out untouched) when the
// matrix is singular or not finite.
inline bool invert(const Mat4& in, Mat4& out) {
  if (!in.finite()) return false;
  Mat4 a = in, inv = Mat4::identity();
  double scale = 0.0;
  for (const auto& r : in.m)
    for (double v : r) scale = std::max(scale, std::fabs(v));
  if (scale == 0.0) return false;
  for (int c = 0; c < 4; ++c) {
    int pivot = c;
    for (int r = c + 1; r < 4; ++r)
      if (std::fabs(a.m[r][c]) > std::fabs(a.m[pivot][c])) pivot = r;
    if (std::fabs(a.m[pivot][c]) <= 1e-12 * scale) return false;
    std::swap(a.m[c], a.m[pivot]);
    std::swap(inv.m[c], inv.m[pivot]);
    const double d = 1.0 / a.m[c][c];
    for (int k = 0; k < 4; ++k) {
      a.m[c][k] *= d;
      inv.m[c][k] *= d;
    }
    for (int r = 0; r < 4; ++r) {
      if (r == c || a.m[r][c] == 0.0) continue;
      const double f = a.m[r][c];
      for (int k = 0; k < 4; ++k) {
        a.m[r][k] -= f * a.m[c][k];
        inv.m[r][k] -= f * inv.m[c][k];
      }
    }
  }
  out = inv;
  return true;
}

}  // namespace crisp
