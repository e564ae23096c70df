// SPDX-License-Identifier: Apache-2.0
// PLACEHOLDER until the real taa filter lands: copies colour to output.
#include "core/filter.h"

namespace crisp {
namespace {
class TaaFilter final : public Filter {
 public:
  explicit TaaFilter(Context& c)
      : Filter(c, {}, {{"color", true, 3, 4, false, "linear RGB(A) colour"}, {"output", true, 3, 4, false, "filtered colour"}}) {}
  const char* type() const override { return "taa"; }
 protected:
  void onCommit() override { staged_ = Image(width(), height(), 4); }
  void onExecute() override { stageColor(staged_); writeOutput(staged_); }
 private:
  Image staged_;
};
}  // namespace
std::unique_ptr<Filter> newTaaFilter(Context& c) { return std::make_unique<TaaFilter>(c); }
}  // namespace crisp
