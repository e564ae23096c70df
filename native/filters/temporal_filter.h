// SPDX-License-Identifier: Apache-2.0
// What the filters of the three temporal methods (taa, taa-improved, phlm)
// share around their kernels: the images they take, the inputs read apart
// from the output, and the kernel and the alpha (temporal_alpha.h) reset and
// sized together. Each method's own file keeps its parameters and its run.
#pragma once

#include <utility>
#include <vector>

#include "core/filter.h"
#include "filters/temporal_alpha.h"

namespace crisp {

// The image roles of a temporal method, in the order the info table lists
// them: colour, motion and depth (depth's use is the method's), the method's
// own `extra` roles, output.
inline std::vector<ImageRole> temporalImageRoles(const char* depthMeaning, std::vector<ImageRole> extra = {}) {
  std::vector<ImageRole> roles = {
      {"color", true, 3, 4, false, "linear RGB(A) colour, 1 jittered sample per pixel"},
      {"motion", false, 2, 4, false,
       "motion vectors in pixels, previous - current, y down (absent: static scene, no reprojection)"},
      {"depth", false, 1, 4, false, depthMeaning}};
  for (ImageRole& r : extra) roles.push_back(r);
  roles.push_back({"output", true, 3, 4, false,
                   "anti-aliased linear colour; alpha anti-aliased as well when below 1 (temporal_alpha.h)"});
  return roles;
}

// The depth role's use for taa and phlm.
inline constexpr const char* kTemporalDepthMeaning = "planar depth (channel 0): closest-depth velocity, disocclusion";

template <class Kernel>
class TemporalFilter : public Filter {
 public:
  TemporalFilter(Context& c, std::vector<ParamSpec> params, std::vector<ImageRole> roles)
      : Filter(c, std::move(params), std::move(roles)) {}
  void reset() override {
    kernel_.reset();
    alpha_.reset();
  }

 protected:
  // Colour, motion and depth as the kernel reads them (inputApartFromOutput:
  // an input the output overwrites is copied first), and the output.
  template <class Inputs>
  void readCommonInputs(Inputs& in) {
    in.color = inputApartFromOutput("color");
    if (hasImage("motion")) in.motion = inputApartFromOutput("motion");
    if (hasImage("depth")) in.depth = inputApartFromOutput("depth");
    in.output = image("output");
  }
  // The alpha's kernel sized with the colour's (a new size starts both over).
  void allocateAlpha() { alpha_.allocate(width(), height(), hasImage("depth")); }

  Kernel kernel_;
  TemporalAlpha alpha_;
  bool reference_ = false;  // the "reference" parameter: the scalar path
};

}  // namespace crisp
