// SPDX-License-Identifier: Apache-2.0
// Analytic test scenes whose right answer is known: shapes over a background,
// evaluated in continuous pixel coordinates (x right, y down, pixel (i,j)
// covers [i,i+1) x [j,j+1)). "1-sample" images sample each pixel centre (plus
// an optional jitter); references box-filter each pixel with n x n stratified
// samples (16 x 16 = coverage exact to 1/256).
#pragma once

#include <vector>

#include "core/image.h"

namespace crisp::synth {

struct Shape {
  enum Kind { HalfPlane, Strip, Disk } kind;
  // HalfPlane: point (px,py) on the edge, edge direction angle (deg, measured
  //   counter-clockwise from +x with y UP, i.e. as seen on screen); the side to
  //   the left of the direction is inside.
  // Strip: centre line through (px,py) at angle, full width `size`.
  // Disk: centre (px,py), radius `size`.
  float px, py, angleDeg, size;
  float rgb[3];
  bool contains(float x, float y) const;
};

struct Scene {
  float background[3] = {0.0f, 0.0f, 0.0f};
  std::vector<Shape> shapes;  // painted in order: later shapes cover earlier
  void eval(float x, float y, float out[3]) const;
};

// One straight edge at angleDeg through (cx + offset*normal): dark below-right,
// light above-left; colours are linear.
Scene edgeScene(int width, int height, float angleDeg, float offset = 0.0f, float dark = 0.05f,
                float light = 0.8f);
// A chart of edges at many angles, thin lines (0.3..1.5 px) and disks, in
// several colours: the standard spatial-AA test image.
Scene testChart(int width, int height);

// RGBA linear image sampled once per pixel at centre + (jx, jy) (y down).
Image renderCentre(const Scene& scene, int width, int height, float jx = 0.0f, float jy = 0.0f);
// RGBA linear image, n x n stratified box filter per pixel.
Image renderSupersampled(const Scene& scene, int width, int height, int n = 16);
// 1-channel mask: 1 where the pixel's n x n sub-samples do not all agree
// (the pixel is cut by an edge), else 0.
Image edgePixels(const Scene& scene, int width, int height, int n = 16);

}  // namespace crisp::synth
