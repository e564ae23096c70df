// SPDX-License-Identifier: Apache-2.0
#include "synth/synthetic.h"

#include <algorithm>
#include <cmath>

namespace crisp::synth {

namespace {
constexpr float kPi = 3.14159265358979323846f;

// Unit direction of the edge in y-DOWN pixel space (screen angle uses y up).
void direction(float angleDeg, float& dx, float& dy) {
  float a = angleDeg * kPi / 180.0f;
  dx = std::cos(a);
  dy = -std::sin(a);
}
}  // namespace

bool Shape::contains(float x, float y) const {
  float rx = x - px, ry = y - py;
  switch (kind) {
    case HalfPlane: {
      float dx, dy;
      direction(angleDeg, dx, dy);
      // Left of the direction as seen on screen (y up) = cross > 0 with y flipped.
      return (dx * (-ry) - (-dy) * rx) > 0.0f;
    }
    case Strip: {
      float dx, dy;
      direction(angleDeg, dx, dy);
      float dist = std::fabs(rx * (-dy) + ry * dx);  // distance to the centre line
      return dist < 0.5f * size;
    }
    case Disk: return rx * rx + ry * ry < size * size;
  }
  return false;
}

void Scene::eval(float x, float y, float out[3]) const {
  const float* c = background;
  for (const Shape& s : shapes)
    if (s.contains(x, y)) c = s.rgb;
  out[0] = c[0];
  out[1] = c[1];
  out[2] = c[2];
}

Scene edgeScene(int width, int height, float angleDeg, float offset, float dark, float light) {
  Scene s;
  s.background[0] = s.background[1] = s.background[2] = dark;
  float dx, dy;
  direction(angleDeg, dx, dy);
  // Normal pointing to the inside (left of the direction, on screen).
  float nx = dy, ny = -dx;
  Shape h{Shape::HalfPlane, 0.5f * width + offset * nx, 0.5f * height + offset * ny, angleDeg, 0.0f,
          {light, light, light}};
  s.shapes.push_back(h);
  return s;
}

Scene testChart(int width, int height) {
  Scene s;
  s.background[0] = 0.02f;
  s.background[1] = 0.03f;
  s.background[2] = 0.05f;
  const float W = float(width), H = float(height);
  // A fan of half-planes in the left half is hard to read; instead tile the
  // image with cells, each holding one feature.
  const int cols = 6, rows = 4;
  const float cw = W / cols, ch = H / rows;
  const float palette[6][3] = {{0.9f, 0.9f, 0.9f}, {0.8f, 0.1f, 0.05f}, {0.1f, 0.6f, 0.1f},
                               {0.1f, 0.2f, 0.9f}, {0.9f, 0.8f, 0.1f}, {0.6f, 0.6f, 0.6f}};
  int k = 0;
  for (int r = 0; r < rows; ++r)
    for (int c = 0; c < cols; ++c, ++k) {
      float cx = (c + 0.5f) * cw + 0.37f * (k % 3), cy = (r + 0.5f) * ch + 0.21f * (k % 4);
      const float* col = palette[k % 6];
      float angle = 7.0f + 13.0f * k;  // many distinct angles
      if (r < 2) {
        // A half-plane clipped to its cell by drawing a disk of the background
        // colour is not analytic-friendly; use a large disk whose boundary is
        // nearly straight inside the cell.
        float radius = 4.0f * std::max(cw, ch);
        float a = angle * kPi / 180.0f;
        Shape d{Shape::Disk, cx + radius * std::sin(a), cy + radius * std::cos(a), 0, radius, {col[0], col[1], col[2]}};
        s.shapes.push_back(d);
      } else if (r == 2) {
        Shape t{Shape::Strip, cx, cy, angle, 0.3f + 0.25f * c, {col[0], col[1], col[2]}};
        s.shapes.push_back(t);
      } else {
        Shape d{Shape::Disk, cx, cy, 0, 0.18f * std::min(cw, ch) * (1 + c % 3), {col[0], col[1], col[2]}};
        s.shapes.push_back(d);
      }
    }
  return s;
}

Image renderCentre(const Scene& scene, int width, int height, float jx, float jy) {
  Image im(width, height, 4, 1.0f);
  for (int y = 0; y < height; ++y)
    for (int x = 0; x < width; ++x) scene.eval(x + 0.5f + jx, y + 0.5f + jy, im.at(x, y));
  return im;
}

Image renderSupersampled(const Scene& scene, int width, int height, int n) {
  Image im(width, height, 4, 1.0f);
  const float inv = 1.0f / float(n * n);
  for (int y = 0; y < height; ++y)
    for (int x = 0; x < width; ++x) {
      double acc[3] = {0, 0, 0};
      for (int j = 0; j < n; ++j)
        for (int i = 0; i < n; ++i) {
          float c[3];
          scene.eval(x + (i + 0.5f) / n, y + (j + 0.5f) / n, c);
          acc[0] += c[0];
          acc[1] += c[1];
          acc[2] += c[2];
        }
      float* p = im.at(x, y);
      p[0] = float(acc[0] * inv);
      p[1] = float(acc[1] * inv);
      p[2] = float(acc[2] * inv);
    }
  return im;
}

Image edgePixels(const Scene& scene, int width, int height, int n) {
  Image m(width, height, 1, 0.0f);
  for (int y = 0; y < height; ++y)
    for (int x = 0; x < width; ++x) {
      float first[3];
      scene.eval(x + 0.5f / n, y + 0.5f / n, first);
      bool differ = false;
      for (int j = 0; j < n && !differ; ++j)
        for (int i = 0; i < n && !differ; ++i) {
          float c[3];
          scene.eval(x + (i + 0.5f) / n, y + (j + 0.5f) / n, c);
          differ = c[0] != first[0] || c[1] != first[1] || c[2] != first[2];
        }
      *m.at(x, y) = differ ? 1.0f : 0.0f;
    }
  return m;
}

}  // namespace crisp::synth
