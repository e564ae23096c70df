// SPDX-License-Identifier: Apache-2.0
// A perceptual LDR error in the spirit of NVIDIA's FLIP (Andersson et al.
// 2020), written from the paper's description (see flip.cpp for what is kept
// and what is simplified).
#pragma once

#include "core/image.h"

namespace crisp {

// reference and test: 3-channel display-encoded sRGB in [0,1], same size.
// Returns a 1-channel per-pixel error in [0,1]. pixelsPerDegree sets the
// observer (FLIP's default: 0.7 m from a 0.7 m wide 4K monitor = 67 ppd).
Image flipErrorMap(const Image& referenceSrgb, const Image& testSrgb, float pixelsPerDegree = 67.0f,
                   int numThreads = 0);

}  // namespace crisp
