// SPDX-License-Identifier: Apache-2.0
// RSAA: resampling anti-aliasing from 8 geometric sub-samples per pixel
// (seed 003 = Svoboda 2016, after Reshetov, HPG 2012; chapters 2.3 and 4.4).
// A kernel that tests and benchmarks drive without the Filter interface.
//
// Per pixel:
//  1. positions of the centre and the 8 sub-samples from planar depth and the
//     camera (rsaa/sadp.h), normals rotated to view space;
//  2. SADP of each sample against the centre (eq. 2.1); a pixel none of
//     whose samples reaches the threshold keeps its colour (2.3.1, 2.3.4);
//  3. otherwise the two-cluster split of Algorithm 1 gives the 8-bit mask,
//     optionally verified (2.3.3 / 4.4.3, rsaa/cluster.h);
//  4. the mask indexes the generated offset table (rsaa/offset_table.h) and
//     the colour is fetched bilinearly at the pixel centre + offset (2.3,
//     4.4.2), clamp-to-edge.
//  5. textureAA = fxaa (a product extension beyond seed 003, like MSAA combined
//     with a post-process AA): pixels RSAA does not resolve from geometry take
//     the library's FXAA (filters/fxaa.h) result, unless FXAA could have
//     blended them across a geometric edge (see Kernel::guardRows); those
//     keep their colour.
// Conventions (core/conventions.h): rows top-down, offsets in pixels, y down.
#pragma once

#include <cstdint>
#include <vector>

#include "core/image.h"
#include "filters/fxaa.h"
#include "rsaa/cluster.h"
#include "rsaa/sadp.h"
#include "rsaa/subsample_record.h"

namespace crisp::rsaa {

// What handles the pixels geometry does not resolve (texture and shading
// edges, which SADP cannot see): nothing (the thesis' RSAA) or FXAA.
enum class TextureAA { None, Fxaa };

struct Settings {
  float threshold = 0.2f;  // SADP at and above which a sample is on another polygon
  Verification verification = Verification::Halve;
  Camera camera;
  // The kernel defaults to the thesis' algorithm; the filter's parameter
  // textureAA defaults to fxaa.
  TextureAA textureAA = TextureAA::None;
  fxaa::Settings fxaa;  // FXAA's own defaults
};

// The images of one frame, all the same size.
struct Inputs {
  ImageView color;   // 3/4 channels, linear
  ImageView depth;   // channel 0: planar depth (background >= kFarDepth)
  ImageView normal;  // channels 0-2: world normal at the pixel centre
  // The sub-samples: either `packed` (Format::RsaaSubsamples, one 80-byte
  // record per pixel, rsaa/subsample_record.h; used when set) or the 8 images
  // `sub` (4 channels: world normal xyz, planar depth of sub-sample k).
  ImageView packed;
  ImageView sub[kSamples];
};

// The fast path tests 8 pixels (one sub-sample each) or 8 sub-samples of one
// pixel per AVX2 step where the CPU has AVX2, else 4 sub-samples per SSE
// step; all bit-identical to the scalar reference. Tests force the SSE path
// with 4 (0 = choose by CPU). Not for concurrent use.
void setSimdLanesForTesting(int lanes);

class Kernel {
 public:
  // Allocates every buffer and the per-row/column ray terms (from
  // Filter::onCommit; never in run()). The pattern is the shipped table's.
  void allocate(int width, int height, const Settings& settings);
  // reference = true: scalar path, one thread. false: rows in parallel with
  // the SIMD test for the pixels that need no RSAA. Bit-identical output.
  // output may be the colour buffer.
  void run(const Inputs& in, const ImageView& output, bool reference, int numThreads);

  // Results of the last run, for tests and reports.
  const Image& staged() const { return staged_; }  // sanitised RGBA input (only when output overlaps colour)
  // Per pixel (row-major): the mask used (bit k = sample k on the centre's
  // polygon, after verification); 255 where the pixel kept its colour.
  const std::vector<std::uint8_t>& masks() const { return masks_; }
  // Pixels whose offset was halved by Verification::Halve in the last run.
  const std::vector<std::uint8_t>& halved() const { return halved_; }
  // Per pixel: 1 = some sub-sample is on another polygon (RSAA's own edge
  // classification; these pixels get RSAA's result).
  const std::vector<std::uint8_t>& geometric() const { return geometric_; }
  // Per pixel, textureAA = fxaa: 1 = the output is FXAA's colour (FXAA changed
  // it and no geometric edge is near); 0 otherwise.
  const std::vector<std::uint8_t>& textured() const { return textured_; }
  long resolvedCount() const;  // pixels whose colour was resampled
  const Settings& settings() const { return settings_; }

 private:
  struct Ray {
    float ux, uy;
  };
  Geo centreGeo(const Inputs& in, int x, int y) const;
  Geo subGeo(const Inputs& in, int k, int x, int y) const;
  // Steps 3-4 for a pixel with at least one differing sample, from the SADP
  // of each sample against the centre (s[k] = rsaa::sadp(centre, sample k)).
  void resolve(const Inputs& in, int x, int y, const Geo& centre, const float s[kSamples], float out[4]);
  void runRows(const Inputs& in, const ImageView& output, int y0, int y1, bool simd);
  // textureAA = fxaa, after runRows on the whole image: restores the colour
  // of every pixel FXAA must not touch.
  // simd (after fxaa::runFast): visit only the pixels FXAA's contrast check
  // passed (its flags, 8 at a time), not every pixel's colour (same result).
  void guardRows(const Inputs& in, const ImageView& output, int y0, int y1, bool simd);
  // guardRows for one non-geometric pixel whose output FXAA changed: keeps
  // FXAA's colour (textured) or restores the sanitised colour.
  void guardChanged(const Inputs& in, const ImageView& output, int x, int y);
  void stage(const ImageView& color, int y0, int y1);
  void fetch(float fx, float fy, float out[4]) const;
  void texel(int x, int y, float out[4]) const;

  int width_ = 0, height_ = 0;
  Settings settings_;
  // settings_.camera with the rotation scaled by 1 / kSnormScale: turns the
  // packed records' int16 normals into view space in one step.
  Camera packedCamera_;
  float threshold2_ = 0.0f;
  PatternGeometry geometry_{};
  std::vector<float> colUx_, rowUy_;
  float dux_[kSamples] = {}, duy_[kSamples] = {};
  Image staged_;
  const ImageView* direct_ = nullptr;  // the input colour during run() when the output does not overlap it
  bool simdFetch_ = false;             // fetch() in SSE (fast path; the reference stays scalar)
  std::vector<std::uint8_t> masks_, halved_, geometric_, textured_;
  std::vector<std::uint8_t> rowGuarded_;  // per row: guarded inside runRows (fast path)
  std::vector<std::uint8_t> chunkBits_;   // per row and 8-pixel chunk: the SIMD test's bits (fast path)
  fxaa::Workspace fxaa_;
};

}  // namespace crisp::rsaa
