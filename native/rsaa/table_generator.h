// SPDX-License-Identifier: Apache-2.0
// The RSAA resampling-offset table generator (seed 003, section 2.3.2, after
// Reshetov 2012). For every 8-bit mask of "sample lies on the centre's
// polygon" bits it finds the offset (ox, oy) (pixels, y down, each in
// [-1, 1]) from which a bilinear fetch of the 1-sample colour image best
// reconstructs pixels cut by random straight edges that produce that mask.
//
// Model, per random configuration:
//  * One line (or two) crosses the pixel [-0.5, 0.5]^2. Region A is the part
//    of the plane on the centre's side of every line (the "polygon" of the
//    centre); everything else is B (another polygon). Bit k of the mask is
//    1 iff sample k lies in A.
//  * The exact colour of the pixel is A + cov_B (B - A), cov_B = area of B
//    inside the pixel (polygon clipping, exact).
//  * The 1-sample colour image holds, at each pixel centre, the colour of the
//    region that centre lies in (the edges are straight, so they continue
//    into the neighbours). A bilinear fetch at offset (ox, oy) then gives
//    A + f_B(ox, oy) (B - A), with f_B the bilinear weight of the fetched
//    neighbours whose centres lie in B.
//  * The table entry of a mask minimises sum (f_B - cov_B)^2 over the
//    configurations producing that mask (least squares = "the average
//    offset that best reconstructs" them). In each quadrant (signs of ox,
//    oy) f_B is bilinear in (|ox|, |oy|), so the sum is a biquadratic whose
//    10 coefficients are accumulated once; it is minimised per quadrant by a
//    4097-point scan in |oy| with the exact minimiser in |ox| at each point,
//    then refined by alternating exact 1-D minimisation.
//  * Which configurations count (2.3.2): if any one-line configuration gives
//    the mask, only one-line configurations are used; else the two-line
//    ones; if neither gives it, the offset points from the centre to the
//    farthest B sample with length (number of B samples) / 8, the "covered
//    area" estimate. Mask 255 (no B sample) is (0, 0).
//
// Random lines: direction uniform on the circle (a rejection-sampled point
// of the unit disk, normalised: no trigonometry, so the result is the same
// on every IEEE-754 platform), signed distance from the centre uniform in
// [0, sqrt(1/2)] (the lines that can reach the pixel). The generator is
// std::mt19937 with a fixed seed; doubles are built from its raw 32-bit
// outputs (std::uniform_real_distribution is implementation-defined).
#pragma once

#include <cstdint>
#include <string>

#include "rsaa/offset_table.h"
#include "rsaa/pattern.h"

namespace crisp::rsaa {

constexpr std::uint32_t kDefaultTableSeed = 20120625u;  // HPG 2012, Reshetov
constexpr long kDefaultTableConfigurations = 1000000;   // per family (one line, two lines)

enum class OffsetSource : int { OneLine = 0, TwoLines = 1, Fallback = 2, Centre = 3 };
const char* offsetSourceName(OffsetSource s);

struct GeneratorOptions {
  Pattern pattern = kDefaultPattern;
  std::uint32_t seed = kDefaultTableSeed;
  long configurations = kDefaultTableConfigurations;  // of each family
};

struct GeneratedTable {
  GeneratorOptions options;
  float offset[kMasks][2] = {};  // (ox, oy), pixels, y down
  OffsetSource source[kMasks] = {};
  long count[kMasks] = {};       // configurations of the chosen family behind each entry
  double rmsError[kMasks] = {};  // sqrt(mean (f_B - cov_B)^2) at the chosen offset; 0 when count is 0
  double meanCoverageB[kMasks] = {};
};

// Runs the generator (about a second for 10^6 configurations per family).
// Throws crisp::Exception (invalid argument) for a non-positive count or a
// non-finite pattern point outside the pixel.
GeneratedTable generateOffsetTable(const GeneratorOptions& options);

// The C++ source of native/rsaa/offset_table.cpp for a generated table:
// the table as float literals that round-trip exactly, with the pattern,
// seed, count and per-mask provenance in the text.
std::string offsetTableSource(const GeneratedTable& table);

}  // namespace crisp::rsaa
