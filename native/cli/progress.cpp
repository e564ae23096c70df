// SPDX-License-Identifier: Apache-2.0
#include "cli/progress.h"

#include <unistd.h>

#include <cstdio>

namespace crisp::cli {

Progress::Progress(std::string label, int total, bool quiet)
    : label_(std::move(label)), total_(total), quiet_(quiet), tty_(isatty(fileno(stderr)) != 0),
      start_(std::chrono::steady_clock::now()) {}

Progress::~Progress() { finish(); }

void Progress::step(const std::string& item) {
  ++done_;
  if (quiet_) return;
  double elapsed = std::chrono::duration<double>(std::chrono::steady_clock::now() - start_).count();
  double left = done_ > 0 ? elapsed / done_ * (total_ - done_) : 0.0;
  if (tty_) {
    const int width = 30;
    int filled = total_ > 0 ? done_ * width / total_ : width;
    std::fprintf(stderr, "\r%s [%s%s] %d/%d %.1fs left  %-30.30s", label_.c_str(), std::string(filled, '#').c_str(),
                 std::string(width - filled, '.').c_str(), done_, total_, left, item.c_str());
  } else {
    std::fprintf(stderr, "%s %d/%d %s (%.2fs, %.1fs left)\n", label_.c_str(), done_, total_, item.c_str(), elapsed, left);
  }
  std::fflush(stderr);
}

void Progress::finish() {
  if (finished_) return;
  finished_ = true;
  if (!quiet_ && tty_ && done_ > 0) std::fprintf(stderr, "\n");
}

}  // namespace crisp::cli
