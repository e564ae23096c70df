// SPDX-License-Identifier: Apache-2.0
// RSAA's geometric sub-sample pattern (seed 003, section 2.2.1 and 2.3): 8
// sample points per pixel at known offsets from the pixel centre.
//
// Library convention (core/conventions.h): offsets in pixels, x RIGHT, y DOWN.
// The Blender add-on (addon/crisp/render.py, RSAA_PATTERN) lists the same
// points with y UP, because camera shift moves the samples up; the library
// value is (x, -y) of the add-on's. test_rsaa_table.cpp checks the two agree.
#pragma once

namespace crisp::rsaa {

constexpr int kSamples = 8;

struct Pattern {
  float x[kSamples];
  float y[kSamples];
};

// The default pattern: two squares of four points, one rotated (the
// "rotated grid" of figure 2.4) on radius sqrt(10)/8 and one diagonal on
// radius sqrt(2)/4, so every straight line through the pixel separates some
// of them. Same order as the add-on's sub0..sub7 files.
constexpr Pattern kDefaultPattern = {
    {-0.375f, 0.125f, 0.375f, -0.125f, -0.25f, 0.25f, 0.25f, -0.25f},
    {0.125f, 0.375f, -0.125f, -0.375f, -0.25f, -0.25f, 0.25f, 0.25f},
};

}  // namespace crisp::rsaa
