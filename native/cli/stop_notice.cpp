// SPDX-License-Identifier: Apache-2.0
#include "cli/stop_notice.h"

#include <unistd.h>

#include <algorithm>
#include <cstring>
#include <iterator>

namespace crisp::cli {

namespace {

// The handler reads only these: the line is made before each step with the signals blocked, and the
// handler writes it with write(2), which is async-signal-safe.
constexpr int kStopSignals[] = {SIGINT, SIGTERM, SIGHUP};
struct sigaction stopPrevious[std::size(kStopSignals)];
bool stopInstalled[std::size(kStopSignals)];
char stopHead[64];  // "\n<who>: stopped by "
std::size_t stopHeadLength = 0;
char stopLine[1024];  // " <step>\n"
std::size_t stopLength = 0;
bool stopOnTerminal = false;

void writeAll(const char* text, std::size_t n) {
  while (n > 0) {
    const ssize_t w = ::write(STDERR_FILENO, text, n);
    if (w <= 0) return;
    text += w;
    n -= std::size_t(w);
  }
}

extern "C" void sayStopAndPassOn(int sig) {
  const char* name = sig == SIGINT ? "Ctrl-C (SIGINT)" : sig == SIGTERM ? "SIGTERM" : "SIGHUP";
  // On a terminal, a new line first: a progress bar may hold the last one.
  writeAll(stopHead + (stopOnTerminal ? 0 : 1), stopHeadLength - (stopOnTerminal ? 0 : 1));
  writeAll(name, std::strlen(name));
  writeAll(stopLine, stopLength);
  // The previous handler takes it once this one returns (the stop signals are blocked until then).
  for (std::size_t i = 0; i < std::size(kStopSignals); ++i)
    if (kStopSignals[i] == sig) ::sigaction(sig, &stopPrevious[i], nullptr);
  ::raise(sig);
}

void copyText(char* to, std::size_t size, std::size_t& length, const std::string& text) {
  length = std::min(text.size(), size);
  std::memcpy(to, text.data(), length);
}

}  // namespace

StopNotice::StopNotice(const std::string& who) {
  const sigset_t held = hold();
  copyText(stopHead, sizeof stopHead, stopHeadLength, "\n" + who + ": stopped by ");
  stopLength = 0;
  release(held);
  stopOnTerminal = ::isatty(STDERR_FILENO) != 0;
  for (std::size_t i = 0; i < std::size(kStopSignals); ++i) {
    struct sigaction action {};
    action.sa_handler = sayStopAndPassOn;
    sigemptyset(&action.sa_mask);  // one stop at a time: a second signal waits for the first to end crisp
    for (int sig : kStopSignals) sigaddset(&action.sa_mask, sig);
    stopInstalled[i] = ::sigaction(kStopSignals[i], nullptr, &stopPrevious[i]) == 0 &&
                       stopPrevious[i].sa_handler != SIG_IGN && ::sigaction(kStopSignals[i], &action, nullptr) == 0;
  }
}

StopNotice::~StopNotice() { restore(); }

void StopNotice::step(const std::string& text) {
  const sigset_t held = hold();
  copyText(stopLine, sizeof stopLine, stopLength, " " + text.substr(0, sizeof stopLine - 2) + "\n");
  release(held);
}

sigset_t StopNotice::hold() {
  sigset_t block, old;
  sigemptyset(&block);
  for (int sig : kStopSignals) sigaddset(&block, sig);
  ::sigprocmask(SIG_BLOCK, &block, &old);
  return old;
}

void StopNotice::release(const sigset_t& old) { ::sigprocmask(SIG_SETMASK, &old, nullptr); }

void StopNotice::restore() {
  for (std::size_t i = 0; i < std::size(kStopSignals); ++i)
    if (stopInstalled[i]) ::sigaction(kStopSignals[i], &stopPrevious[i], nullptr);
}

}  // namespace crisp::cli
