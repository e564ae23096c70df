// SPDX-License-Identifier: Apache-2.0
// The one in-memory convention of every buffer in Crisp. Readers convert to
// it; filters and metrics assume it; tests check it with asymmetric images.
//
//  * Rows top-down: row 0 is the top of the picture (as stored in EXR/PNG);
//    x grows to the right. Blender's Image.pixels is bottom-up: the add-on
//    flips it before calling the library.
//  * Colour ("color", "albedo", "output"): linear, scene-referred RGB(A) float.
//    Non-finite input values are sanitised on entry (see sanitizeColor).
//  * Depth ("depth"): planar view depth, distance along the camera axis, in
//    scene units. Background is kBackgroundDepth; any depth >= kFarDepth
//    (Blender 3.x writes half-float 65504, later versions 1e10) reads as
//    background.
//  * Normal ("normal"): world-space unit normal, XYZ.
//  * Motion ("motion"): 2 or 4 floats in PIXELS, y DOWN (row direction):
//    (x,y) = previous - current, (z,w) = current - next. So pixel p of this
//    frame was at p + motion.xy in the previous frame. Blender's Vector pass
//    is y UP; readers negate its y and w components.
//  * Object ID ("id"): 32-bit Cryptomatte hash of the object name
//    (CryptoObject00.r bit pattern), 0 = background. Compared exactly, never
//    interpolated. Kept as uint32 in memory.
#pragma once

#include <cstdint>

namespace crisp {

constexpr float kBackgroundDepth = 1e10f;
// Half-float max: Blender 3.x EEVEE stores depth in half floats, so its 1e10
// background reads as 65504.
constexpr float kFarDepth = 65504.0f;
// Largest colour magnitude kept; +Inf maps here (the half-float maximum).
constexpr float kMaxColor = 65504.0f;

inline bool isBackgroundDepth(float d) { return !(d < kFarDepth); }  // NaN too

}  // namespace crisp
