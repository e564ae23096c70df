// SPDX-License-Identifier: Apache-2.0
// Errors inside the library are exceptions carrying a CrispError code; the C
// boundary (api/api.cpp) turns them into the per-thread error state.
#pragma once

#include <stdexcept>
#include <string>

#include "crisp/crisp.h"

namespace crisp {

class Exception : public std::runtime_error {
 public:
  Exception(CrispError code, const std::string& message) : std::runtime_error(message), code_(code) {}
  CrispError code() const { return code_; }

 private:
  CrispError code_;
};

[[noreturn]] inline void fail(CrispError code, const std::string& message) { throw Exception(code, message); }
[[noreturn]] inline void invalidArgument(const std::string& message) { fail(CRISP_ERROR_INVALID_ARGUMENT, message); }
[[noreturn]] inline void invalidData(const std::string& message) { fail(CRISP_ERROR_INVALID_DATA, message); }
[[noreturn]] inline void ioError(const std::string& message) { fail(CRISP_ERROR_IO, message); }

}  // namespace crisp
