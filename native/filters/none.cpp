// SPDX-License-Identifier: Apache-2.0
// "none": copies colour to output (after sanitising). The unfiltered baseline,
// and the simplest example of a filter.
#include "core/filter.h"

namespace crisp {
namespace {

class NoneFilter final : public Filter {
 public:
  explicit NoneFilter(Context& c)
      : Filter(c, {},
               {{"color", true, 3, 4, false, "linear RGB(A) colour"},
                {"output", true, 3, 4, false, "filtered colour, same size"}}) {}
  const char* type() const override { return "none"; }

 protected:
  void onCommit() override { staged_ = Image(width(), height(), 4); }
  void onExecute() override {
    stageColor(staged_);
    writeOutput(staged_);
  }

 private:
  Image staged_;
};

}  // namespace

std::unique_ptr<Filter> newNoneFilter(Context& c) { return std::make_unique<NoneFilter>(c); }

}  // namespace crisp
