// SPDX-License-Identifier: Apache-2.0
#include "cli/stop_notice.h"

#include <unistd.h>

#include <algorithm>
#include <atomic>
#include <cstring>

namespace crisp::cli {

namespace {

// What the handler reads. Each step's line goes into the buffer the handler is not pointed at, then the
// index flips (lock-free): a stop on any thread reads a whole line. write(2) is async-signal-safe.
StopHandlers stopHandlers;
char stopHead[64];  // "\n<who>: stopped by "
std::size_t stopHeadLength = 0;
struct Line {
  char text[1024];  // " <step>\n"
  std::size_t length = 0;
};
Line stopLines[2];
std::atomic<int> stopCurrent{0};
static_assert(std::atomic<int>::is_always_lock_free);
bool stopOnTerminal = false;

void writeAll(const char* text, std::size_t n) {
  while (n > 0) {
    const ssize_t w = ::write(STDERR_FILENO, text, n);
    if (w <= 0) return;  // stderr closed, or a pipe whose reader is gone (SIGPIPE is ignored meanwhile)
    text += w;
    n -= std::size_t(w);
  }
}

extern "C" void sayStopAndPassOn(int sig) {
  // A pipe whose reader went first (`| tee log`, Ctrl-C to both) must not end crisp by SIGPIPE before
  // the previous handler removes its temporary files.
  struct sigaction ignore {}, pipeBefore {};
  ignore.sa_handler = SIG_IGN;
  sigemptyset(&ignore.sa_mask);
  const bool pipeSaved = ::sigaction(SIGPIPE, &ignore, &pipeBefore) == 0;
  const char* name = sig == SIGINT ? "Ctrl-C (SIGINT)" : sig == SIGTERM ? "SIGTERM" : "SIGHUP";
  // On a terminal, a new line first: a progress bar may hold the last one.
  writeAll(stopHead + (stopOnTerminal ? 0 : 1), stopHeadLength - (stopOnTerminal ? 0 : 1));
  writeAll(name, std::strlen(name));
  const Line& line = stopLines[stopCurrent.load()];
  writeAll(line.text, line.length);
  if (pipeSaved) ::sigaction(SIGPIPE, &pipeBefore, nullptr);
  // Every previous handler back (a second stop signal is not said again); this one takes the signal once
  // this handler returns (the stop signals are blocked until then).
  stopHandlers.restore();
  ::raise(sig);
}

void copyText(char* to, std::size_t size, std::size_t& length, const std::string& text) {
  length = std::min(text.size(), size);
  std::memcpy(to, text.data(), length);
}

}  // namespace

StopNotice::StopNotice(const std::string& who) {
  const std::string head = "\n" + who + ": stopped by ";
  copyText(stopHead, sizeof stopHead, stopHeadLength, head);
  for (Line& line : stopLines) copyText(line.text, sizeof line.text, line.length, "\n");  // until a step
  stopOnTerminal = ::isatty(STDERR_FILENO) != 0;
  stopHandlers.install(sayStopAndPassOn, true);  // one stop at a time: a second waits for the first to end crisp
}

StopNotice::~StopNotice() { restore(); }

void StopNotice::step(const std::string& text) {
  const std::string line = " " + text.substr(0, sizeof stopLines[0].text - 2) + "\n";
  const int next = 1 - stopCurrent.load();
  copyText(stopLines[next].text, sizeof stopLines[next].text, stopLines[next].length, line);
  stopCurrent.store(next);
}

sigset_t StopNotice::hold() {
  sigset_t block, old;
  sigemptyset(&block);
  for (int sig : kStopSignals) sigaddset(&block, sig);
  ::sigprocmask(SIG_BLOCK, &block, &old);
  return old;
}

void StopNotice::release(const sigset_t& old) { ::sigprocmask(SIG_SETMASK, &old, nullptr); }

void StopNotice::restore() { stopHandlers.restore(); }

}  // namespace crisp::cli
