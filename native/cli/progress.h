// SPDX-License-Identifier: Apache-2.0
// Progress on long runs: a bar on a terminal, plain lines otherwise.
#pragma once

#include <chrono>
#include <string>

namespace crisp::cli {

class Progress {
 public:
  Progress(std::string label, int total, bool quiet);
  ~Progress();
  void step(const std::string& item);  // call after finishing one item
  void finish();

 private:
  std::string label_;
  int total_;
  int done_ = 0;
  bool quiet_;
  bool tty_;
  bool finished_ = false;
  std::chrono::steady_clock::time_point start_;
};

}  // namespace crisp::cli
