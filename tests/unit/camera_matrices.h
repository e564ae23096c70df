// SPDX-License-Identifier: Apache-2.0
// Camera and object matrices built the way Blender builds them, for the tests
// and benchmarks of motion reconstruction (motion/reconstruct.h): a move, a
// turn about Z, and the perspective projection of a camera with its jitter as
// lens shift.
#pragma once

#include <cmath>

#include "motion/matrix.h"

namespace crisp::test {

constexpr double kCameraNear = 0.1, kCameraFar = 100.0;

inline Mat4 translation(double x, double y, double z) {
  Mat4 m = Mat4::identity();
  m.m[0][3] = x;
  m.m[1][3] = y;
  m.m[2][3] = z;
  return m;
}

inline Mat4 rotationZ(double a) {
  Mat4 m = Mat4::identity();
  m.m[0][0] = std::cos(a);
  m.m[0][1] = -std::sin(a);
  m.m[1][0] = std::sin(a);
  m.m[1][1] = std::cos(a);
  return m;
}

// Blender's camera projection (sensor fit AUTO, square pixels) of a width x
// height render with focal scale s = 2 * lens / sensor on the wider axis;
// jitter (dx, dy) in pixels, x right, y up, as the add-on's lens shift:
// P[0][2] = 2 dx / width, P[1][2] = 2 dy / height.
inline Mat4 perspective(double s, int width, int height, double dx = 0, double dy = 0) {
  Mat4 p;
  p.m[0][0] = s;
  p.m[1][1] = s * width / height;
  p.m[0][2] = 2.0 * dx / width;
  p.m[1][2] = 2.0 * dy / height;
  p.m[2][2] = -(kCameraFar + kCameraNear) / (kCameraFar - kCameraNear);
  p.m[2][3] = -2.0 * kCameraFar * kCameraNear / (kCameraFar - kCameraNear);
  p.m[3][2] = -1.0;
  return p;
}

}  // namespace crisp::test
