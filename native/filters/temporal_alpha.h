// SPDX-License-Identifier: Apache-2.0
// The alpha of the temporal methods' outputs (taa, taa-improved, phlm).
//
// A render with Film > Transparent carries coverage in alpha, and its one
// jittered sample per pixel makes that alpha as aliased as the colour: 0 or
// 1 along every silhouette against the empty background. The colour (which
// Blender premultiplies) is anti-aliased by the method; an alpha passed
// through would leave a jagged matte under a smooth edge, and a composite
// over a plate would show the stair steps again.
//
// So once a frame's input alpha is below 1 anywhere, the method's alpha is
// filtered too: taa's kernel (taa.h) over the alpha as a grey image, with
// the same motion, depth, jitter, pixel filter and hold as the colour, so it
// converges to the same filtered coverage EEVEE's many-sample alpha shows.
// taa-improved steers it by the colour's aliasedValue plane; phlm uses taa's
// kernel too, not a second set of linear models (a coverage signal has no use
// for them, and they would cost 250-500 MB more at 1080p). The input alpha
// is clamped to [0, 1] before (NaN counts as 0), the result after.
//
// Opaque renders cost nothing more (the methods' kernels note an alpha below
// 1 as they read the colour) and keep nothing; a transparent one keeps taa's
// history for alpha and the alpha as RGB in and out (93 + 50 MB at 1920x1080
// with depth, plus 4.5 MB of taa's scratch; made by the execute where alpha
// first shows up, crisp.h) and runs that kernel once more each frame (at
// 1080p on 2 threads 35 ms against 30 ms for taa's colour: taa's time more
// than doubles). Once alpha has shown up, it is filtered every frame until
// the filter resets, so its history never skips a frame.
#pragma once

#include <cstddef>
#include <memory>

#include "core/image.h"

namespace crisp {

namespace taa {
struct Settings;
class Kernel;
}  // namespace taa
namespace phlm {
struct Settings;
}  // namespace phlm

// (The filters hold one and include no more than this header: with taa.h
// and the settings' conversion compiled into phlm.cpp, phlm.fast.mt measured
// 2-3 ms slower at 1080p; the cause, likely code layout, was not traced.)
class TemporalAlpha {
 public:
  TemporalAlpha();
  ~TemporalAlpha();
  // Keeps the size; the history starts over when the size changes.
  void allocate(int width, int height, bool withDepth);
  void reset();
  // Filters this frame's alpha into output's fourth channel once alpha has
  // been below 1 since the last reset (this frame included) in a colour and
  // an output that both have one (alphaBelowOne: this frame's, as the
  // method's kernel saw it while reading the colour, so opaque frames are not
  // read again); otherwise leaves the output alone (the method passed the
  // input's alpha through). Once started, the history runs every frame: an
  // RGB colour counts as alpha 1 (as the colour kernel writes it), an RGB
  // output gets nothing but the history still runs. `base` is the method's
  // taa settings (jitter, pixel filter, hold); aliasedValue as taa::Inputs.
  void run(const ImageView& color, bool alphaBelowOne, const ImageView& motion, const ImageView& depth,
           const float* aliasedValue, const ImageView& output, const taa::Settings& base, bool reference,
           int numThreads);
  // The same for phlm: taa's settings from phlm's jitter, pixel filter,
  // unjitter, hold and depth tolerance, taa's defaults for the rest.
  void run(const ImageView& color, bool alphaBelowOne, const ImageView& motion, const ImageView& depth,
           const ImageView& output, const phlm::Settings& settings, bool reference, int numThreads);
  bool active() const { return active_; }
  // What it holds: nothing until alpha first shows up, then taa's history and
  // the two RGB images until the size changes (a reset keeps them).
  std::size_t bytesKeptBetweenFrames() const;
  // The alpha's kernel while active, else null (tests).
  const taa::Kernel* kernel() const { return active_ ? kernel_.get() : nullptr; }

 private:
  int width_ = 0, height_ = 0;
  bool withDepth_ = false;
  bool active_ = false;
  std::unique_ptr<taa::Kernel> kernel_;  // made when alpha first shows up
  Image grey_;      // this frame's alpha as RGB
  Image filtered_;  // the kernel's output
};

}  // namespace crisp
