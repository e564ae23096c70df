// SPDX-License-Identifier: Apache-2.0
#include "core/context.h"

#include "core/error.h"

namespace crisp {

void Context::setInt(const std::string& name, int value) {
  if (name == "numThreads") {
    if (value < 0 || value > 1024) invalidArgument("context parameter 'numThreads' = " + std::to_string(value) + " is out of range [0, 1024]");
    numThreads_ = value;
  } else if (name == "verbose") {
    if (value < 0 || value > 2) invalidArgument("context parameter 'verbose' = " + std::to_string(value) + " is out of range [0, 2]");
    verbose_ = value;
  } else {
    invalidArgument("unknown context parameter '" + name + "' (known: numThreads, verbose)");
  }
}

int Context::getInt(const std::string& name) const {
  if (name == "numThreads") return numThreads_;
  if (name == "verbose") return verbose_;
  if (name == "version") return CRISP_VERSION;
  invalidArgument("unknown context parameter '" + name + "' (known: numThreads, verbose, version)");
}

}  // namespace crisp
