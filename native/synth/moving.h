// SPDX-License-Identifier: Apache-2.0
// Animated analytic sequences for the temporal filters, built on synthetic.h:
// shapes translating with a known velocity per frame, a camera cut, a
// disocclusion. Each frame yields what a jittered 1-sample renderer gives a
// temporal filter, exactly:
//  * color: RGBA, one sample per pixel at the pixel centre + this frame's
//    jitter (x right, y down);
//  * motion: 2 channels, pixels, previous - current, y down, of the surface
//    hit by that sample; jitter never included (conventions.h);
//  * depth: planar depth of that surface (background kBackgroundDepth);
//  * id: uint32 object id of that surface (0 = background);
//  * reference: RGBA, the frame (shapes at their position of this frame, no
//    motion blur) filtered per pixel with n x n stratified samples: a box over
//    the pixel (16 x 16 = coverage exact to 1/256), or a Blackman-Harris filter
//    of EEVEE's filter_size `filterSize` (support [-filterSize, filterSize],
//    temporal/jitter.h).
// The geometry passes come from the same jittered sample as the colour, as in
// a jittered render whose passes all share its one sample.
#pragma once

#include <cstdint>
#include <vector>

#include "core/image.h"
#include "synth/synthetic.h"
#include "temporal/jitter.h"

namespace crisp::synth {

struct MovingShape {
  Shape shape;              // geometry at frame 0
  float vx = 0.0f;          // pixels per frame, x right
  float vy = 0.0f;          // pixels per frame, y down
  float depth = 10.0f;      // planar depth; shapes later in the list must be nearer
  std::uint32_t id = 1;
};

struct SceneState {
  float background[3] = {0.0f, 0.0f, 0.0f};
  float backgroundVx = 0.0f, backgroundVy = 0.0f;  // motion reported for the (flat) background
  std::vector<MovingShape> shapes;                  // painted in order: later in front
};

struct Sequence {
  SceneState before;
  int cutFrame = -1;  // frames >= cutFrame show `after` (a camera cut); -1 = never
  SceneState after;
  const SceneState& stateAt(int frame) const { return cutFrame >= 0 && frame >= cutFrame ? after : before; }
  // The still picture of frame `frame` (shapes moved to their position).
  Scene sceneAt(int frame) const;
};

enum class JitterKind { None, Uniform, BlackmanHarris };
enum class ReferenceKind { None, Box, BlackmanHarris };

struct FrameOptions {
  JitterKind jitter = JitterKind::Uniform;
  float filterSize = 1.5f;  // EEVEE filter_size of the jitter and reference (half width of the window)
  int period = 16;           // Halton points cycled through
  ReferenceKind reference = ReferenceKind::Box;
  int referenceSamples = 16;  // n of the n x n reference samples
};

struct FrameData {
  int frame = 0;
  temporal::Jitter jitter;  // y down; pass as the filter's jitterX / jitterY
  Image color, motion, depth, id, reference;
};

FrameData renderFrame(const Sequence& seq, int width, int height, int frame, const FrameOptions& options = {});

// ---- sequences -------------------------------------------------------------
// testChart (thin lines, disks, edges) standing still.
Sequence staticChartSequence(int width, int height);
// One straight edge at angleDeg (dark/light as edgeScene) translating by (vx, vy) per frame.
Sequence movingEdgeSequence(int width, int height, float angleDeg, float vx, float vy);
// Seed 000's ghosting protocol: a light disk of `radius` crossing a dark
// background with two static disks, moving (vx, vy) per frame from the left.
Sequence ghostingSequence(int width, int height, float radius, float vx, float vy);
// A camera cut at `cutFrame`: the chart before, a different still scene after;
// the motion after the cut is zero (the worst case: history looks static).
Sequence cameraCutSequence(int width, int height, int cutFrame);
// Disocclusion: a vertical bar (near) sliding right over a static striped
// background (far), revealing background it hid.
Sequence disocclusionSequence(int width, int height, float vx);

}  // namespace crisp::synth
