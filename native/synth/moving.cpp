// SPDX-License-Identifier: Apache-2.0
#include "synth/moving.h"

#include <cmath>

#include "core/conventions.h"

namespace crisp::synth {

namespace {

// The shape hit at (x, y) in frame t (topmost), or null for the background.
const MovingShape* hitAt(const SceneState& s, int t, float x, float y) {
  const MovingShape* hit = nullptr;
  for (const MovingShape& m : s.shapes)
    if (m.shape.contains(x - float(t) * m.vx, y - float(t) * m.vy)) hit = &m;
  return hit;
}

void colourAt(const SceneState& s, int t, float x, float y, float out[3]) {
  const MovingShape* m = hitAt(s, t, x, y);
  const float* c = m ? m->shape.rgb : s.background;
  out[0] = c[0];
  out[1] = c[1];
  out[2] = c[2];
}

MovingShape still(Shape shape, float depth, std::uint32_t id) {
  MovingShape m;
  m.shape = shape;
  m.depth = depth;
  m.id = id;
  return m;
}

}  // namespace

Scene Sequence::sceneAt(int frame) const {
  const SceneState& s = stateAt(frame);
  Scene scene;
  for (int c = 0; c < 3; ++c) scene.background[c] = s.background[c];
  for (const MovingShape& m : s.shapes) {
    Shape moved = m.shape;
    moved.px += float(frame) * m.vx;
    moved.py += float(frame) * m.vy;
    scene.shapes.push_back(moved);
  }
  return scene;
}

FrameData renderFrame(const Sequence& seq, int width, int height, int frame, const FrameOptions& options) {
  FrameData f;
  f.frame = frame;
  if (options.jitter == JitterKind::Uniform)
    f.jitter = temporal::jitterForFrame(frame, temporal::JitterDistribution::Uniform, 1.0f, options.period);
  else if (options.jitter == JitterKind::BlackmanHarris)
    f.jitter =
        temporal::jitterForFrame(frame, temporal::JitterDistribution::BlackmanHarris, options.filterSize, options.period);
  const SceneState& s = seq.stateAt(frame);
  f.color = Image(width, height, 4, 1.0f);
  f.motion = Image(width, height, 2);
  f.depth = Image(width, height, 1);
  f.id = Image::uintImage(width, height);
  for (int y = 0; y < height; ++y)
    for (int x = 0; x < width; ++x) {
      const float sx = float(x) + 0.5f + f.jitter.x, sy = float(y) + 0.5f + f.jitter.y;
      const MovingShape* m = hitAt(s, frame, sx, sy);
      const float* c = m ? m->shape.rgb : s.background;
      float* p = f.color.at(x, y);
      p[0] = c[0];
      p[1] = c[1];
      p[2] = c[2];
      // previous - current: the surface point was at p - v one frame earlier.
      float* mv = f.motion.at(x, y);
      mv[0] = m ? -m->vx : -s.backgroundVx;
      mv[1] = m ? -m->vy : -s.backgroundVy;
      *f.depth.at(x, y) = m ? m->depth : kBackgroundDepth;
      f.id.setUint(x, y, m ? m->id : 0u);
    }
  if (options.reference == ReferenceKind::Box) {
    f.reference = renderSupersampled(seq.sceneAt(frame), width, height, options.referenceSamples);
  } else if (options.reference == ReferenceKind::BlackmanHarris) {
    // n x n stratified points over the filter's support, weighted by the window.
    const int n = options.referenceSamples;
    const float w = 2.0f * options.filterSize;  // window spans [-filterSize, filterSize]
    std::vector<float> offsets(n), weights(n);
    double total = 0.0;
    for (int i = 0; i < n; ++i) {
      offsets[i] = ((float(i) + 0.5f) / float(n) - 0.5f) * w;
      weights[i] = float(temporal::blackmanHarrisWindow((double(i) + 0.5) / n));
      total += weights[i];
    }
    const double norm = 1.0 / (total * total);
    f.reference = Image(width, height, 4, 1.0f);
    for (int y = 0; y < height; ++y)
      for (int x = 0; x < width; ++x) {
        double acc[3] = {0, 0, 0};
        for (int j = 0; j < n; ++j)
          for (int i = 0; i < n; ++i) {
            float c[3];
            colourAt(s, frame, float(x) + 0.5f + offsets[i], float(y) + 0.5f + offsets[j], c);
            const double wt = double(weights[i]) * weights[j];
            for (int k = 0; k < 3; ++k) acc[k] += wt * c[k];
          }
        float* p = f.reference.at(x, y);
        for (int k = 0; k < 3; ++k) p[k] = float(acc[k] * norm);
      }
  }
  return f;
}

Sequence staticChartSequence(int width, int height) {
  Sequence seq;
  const Scene chart = testChart(width, height);
  for (int c = 0; c < 3; ++c) seq.before.background[c] = chart.background[c];
  std::uint32_t id = 1;
  float depth = 20.0f;
  for (const Shape& s : chart.shapes) {
    seq.before.shapes.push_back(still(s, depth, id++));
    depth -= 0.1f;
  }
  return seq;
}

Sequence movingEdgeSequence(int width, int height, float angleDeg, float vx, float vy) {
  Sequence seq;
  const Scene e = edgeScene(width, height, angleDeg);
  for (int c = 0; c < 3; ++c) seq.before.background[c] = e.background[c];
  MovingShape m = still(e.shapes[0], 10.0f, 1);
  m.vx = vx;
  m.vy = vy;
  seq.before.shapes.push_back(m);
  return seq;
}

Sequence ghostingSequence(int width, int height, float radius, float vx, float vy) {
  Sequence seq;
  seq.before.background[0] = 0.03f;
  seq.before.background[1] = 0.04f;
  seq.before.background[2] = 0.06f;
  const float W = float(width), H = float(height);
  seq.before.shapes.push_back(still(Shape{Shape::Disk, 0.3f * W, 0.25f * H, 0, 0.12f * H, {0.1f, 0.5f, 0.1f}}, 20.0f, 2));
  seq.before.shapes.push_back(still(Shape{Shape::Disk, 0.7f * W, 0.78f * H, 0, 0.1f * H, {0.6f, 0.1f, 0.1f}}, 19.0f, 3));
  MovingShape ball = still(Shape{Shape::Disk, -radius, 0.5f * H, 0, radius, {0.9f, 0.85f, 0.8f}}, 8.0f, 1);
  ball.vx = vx;
  ball.vy = vy;
  seq.before.shapes.push_back(ball);
  return seq;
}

Sequence cameraCutSequence(int width, int height, int cutFrame) {
  Sequence seq = staticChartSequence(width, height);
  seq.cutFrame = cutFrame;
  seq.after.background[0] = 0.7f;
  seq.after.background[1] = 0.6f;
  seq.after.background[2] = 0.4f;
  const float W = float(width), H = float(height);
  seq.after.shapes.push_back(still(Shape{Shape::Disk, 0.5f * W, 0.5f * H, 0, 0.3f * H, {0.05f, 0.1f, 0.3f}}, 5.0f, 7));
  seq.after.shapes.push_back(still(Shape{Shape::Strip, 0.5f * W, 0.5f * H, 30.0f, 2.0f, {0.9f, 0.9f, 0.2f}}, 4.0f, 8));
  return seq;
}

Sequence disocclusionSequence(int width, int height, float vx) {
  Sequence seq;
  seq.before.background[0] = seq.before.background[1] = seq.before.background[2] = 0.1f;
  const float W = float(width), H = float(height);
  // Static stripes (far), every 6 px, slightly slanted so they alias.
  int id = 10;
  for (float x = 3.0f; x < W; x += 6.0f)
    seq.before.shapes.push_back(
        still(Shape{Shape::Strip, x, 0.5f * H, 85.0f, 2.0f, {0.7f, 0.7f, 0.75f}}, 30.0f, std::uint32_t(id++)));
  // The near bar, moving right.
  MovingShape bar = still(Shape{Shape::Strip, 0.25f * W, 0.5f * H, 90.0f, 0.2f * W, {0.8f, 0.3f, 0.1f}}, 5.0f, 1);
  bar.vx = vx;
  seq.before.shapes.push_back(bar);
  return seq;
}

}  // namespace crisp::synth
