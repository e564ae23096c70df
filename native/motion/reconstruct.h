// SPDX-License-Identifier: Apache-2.0
// Motion vectors reconstructed from a 1-sample render's depth, its Cryptomatte
// object IDs and the JSON sidecars of this frame and its neighbours (issue 3
// item 4): for renderers without a Vector pass (EEVEE 3.x).
//
// Per pixel of the CURRENT frame: the render sampled the scene at the pixel
// centre moved by the frame's jitter, i.e. exactly at the pixel centre of the
// JITTERED projection, so the point is unprojected with that projection and
// the planar depth (conventions.h). It is moved by its object's transform
// change (world_prev * inverse(world_cur), object found by the ID pass; id 0
// or unknown: a static world point), projected with the PREVIOUS frame's
// UNJITTERED camera, and compared with its own projection through the
// current UNJITTERED camera, so no frame's jitter reaches the vector:
//   motion.xy = previous - current, motion.zw = current - next,
// in pixels, y DOWN (conventions.h), as Blender's Vector pass with y negated.
//
// Exact for rigid motion (objects whose world matrix describes all their
// movement: translation, rotation, scale, parenting, constraints). Not covered:
// deforming meshes (armatures, shape keys, simulations, modifiers), texture or
// UV animation, and changes of lens/shift over time other than through the
// projection matrices. The background (depth at infinity) is a direction: a
// perspective camera's rotation moves it, its translation does not; under an
// orthographic camera it gets motion 0.
#pragma once

#include <cstdint>
#include <string>

#include "core/image.h"
#include "io/frame.h"
#include "io/sidecar.h"

namespace crisp {

// Bits of the per-pixel "motion_flags" pass (Format::UInt).
enum MotionFlag : std::uint32_t {
  kMotionPreviousValid = 1u << 0,   // motion.xy was reconstructed
  kMotionNextValid = 1u << 1,       // motion.zw was reconstructed (a next sidecar was given)
  kMotionBackground = 1u << 2,      // depth reads as background: moved as a direction (its pairs' valid
                                    // bits say where it was), or 0 under an orthographic camera
  kMotionInvalidPoint = 1u << 3,    // depth <= 0/NaN, the point is on or behind the previous or
                                    // next camera's plane, or the maths was not finite: that pair 0
  kMotionUnknownObject = 1u << 4,   // ID not in this frame's sidecar: moved as a static world point
  kMotionUnmatchedObject = 1u << 5  // object absent from the previous/next sidecar: that pair 0
};

struct FrameMotion {
  Image motion;  // 4 floats per pixel, pixels, y down; 0 where a pair is invalid
  Image flags;   // Format::UInt, MotionFlag bits
};

// depth: 1 float per pixel, the size of current's resolution. ids: the "id"
// pass (Format::UInt) or nullptr; without it, every non-background pixel
// belongs to the only object of the sidecar if there is exactly one, and
// otherwise to none (static) - refused with CRISP_ERROR_INVALID_DATA if any
// object of the sidecars moves, since pixels cannot be matched to it. next may
// be nullptr (zw = 0, kMotionNextValid clear). frameLabel names the frame in
// messages. Threads via parallelRows (0 = all cores). path: Fast (four pixels
// at a time, the AVX2 copy where the CPU has it, temporal::useAvx2) or the
// scalar Reference, one pixel at a time; both give the same bits.
enum class MotionPath { Fast, Reference };
FrameMotion reconstructMotion(const Image& depth, const Image* ids, const Sidecar& current, const Sidecar& previous,
                              const Sidecar* next, const std::string& frameLabel, int numThreads,
                              MotionPath path = MotionPath::Fast);

// Reads frame.path's own sidecar (sidecarPathFor), the previous one and, if
// nextSidecarPath is not empty, the next one; adds or replaces the frame's
// "motion" (Float4) and "motion_flags" (UInt) passes. Needs the "depth" pass.
void reconstructFrameMotion(Frame& frame, const std::string& previousSidecarPath, const std::string& nextSidecarPath,
                            int numThreads);

}  // namespace crisp
