// SPDX-License-Identifier: Apache-2.0
// The filters known by name. Each filter's file provides its factory.
#include <algorithm>
#include <functional>

#include "core/error.h"
#include "core/filter.h"

namespace crisp {

std::unique_ptr<Filter> newNoneFilter(Context&);
std::unique_ptr<Filter> newFxaaFilter(Context&);
std::unique_ptr<Filter> newRepairFilter(Context&);
std::unique_ptr<Filter> newTaaFilter(Context&);
std::unique_ptr<Filter> newTaaImprovedFilter(Context&);
std::unique_ptr<Filter> newPhlmFilter(Context&);
std::unique_ptr<Filter> newRsaaFilter(Context&);

namespace {
struct Entry {
  const char* name;
  std::unique_ptr<Filter> (*make)(Context&);
};
const Entry kFilters[] = {
    {"none", newNoneFilter},
    {"fxaa", newFxaaFilter},
    {"repair", newRepairFilter},
    {"taa", newTaaFilter},
    {"taa-improved", newTaaImprovedFilter},
    {"phlm", newPhlmFilter},
    {"rsaa", newRsaaFilter},
};
}  // namespace

const std::vector<std::string>& filterTypes() {
  static const std::vector<std::string> names = [] {
    std::vector<std::string> v;
    for (const Entry& e : kFilters) v.push_back(e.name);
    return v;
  }();
  return names;
}

const char* filterTypesJoined() {
  static const std::string joined = [] {
    std::string s;
    for (const auto& n : filterTypes()) s += (s.empty() ? "" : ",") + n;
    return s;
  }();
  return joined.c_str();
}

bool isFilterType(const std::string& name) {
  return std::find(filterTypes().begin(), filterTypes().end(), name) != filterTypes().end();
}

std::unique_ptr<Filter> createFilter(Context& context, const std::string& type) {
  for (const Entry& e : kFilters)
    if (type == e.name) {
      std::unique_ptr<Filter> f = e.make(context);
      f->params().setOwner("filter '" + type + "'");
      return f;
    }
  invalidArgument("unknown filter type '" + type + "' (known: " + filterTypesJoined() + ")");
}

}  // namespace crisp
