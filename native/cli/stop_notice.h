// SPDX-License-Identifier: Apache-2.0
// The stop signals (Ctrl-C, kill PID, a farm's SIGTERM, SIGHUP): taking them over and giving them back
// (StopHandlers, also cli/blender.cpp's), and what one says before it ends a long command (StopNotice):
// one line, "<who>: stopped by <SIGNAL> <step>", where the step says where the run was and what of it
// is kept. crisp then ends as before, by the handler it had (its temporary files removed, then the
// signal's default). One notice at a time.
#pragma once

#include <csignal>
#include <iterator>
#include <string>

namespace crisp::cli {

// The signals that stop a run: Ctrl-C, kill PID or a farm cancelling its task, a closed terminal.
constexpr int kStopSignals[] = {SIGINT, SIGTERM, SIGHUP};

// The stop signals taken over by one handler, and the handlers they had before, to put back. A signal
// the shell made crisp ignore (nohup, a background job's SIGINT) stays ignored. restore() only calls
// sigaction: a signal handler may call it.
struct StopHandlers {
  struct sigaction previous[std::size(kStopSignals)] {};
  bool installed[std::size(kStopSignals)] = {};

  // oneAtATime: the other stop signals wait while the handler runs.
  void install(void (*handler)(int), bool oneAtATime) {
    for (std::size_t i = 0; i < std::size(kStopSignals); ++i) {
      struct sigaction action {};
      action.sa_handler = handler;
      sigemptyset(&action.sa_mask);
      if (oneAtATime)
        for (int sig : kStopSignals) sigaddset(&action.sa_mask, sig);
      installed[i] = ::sigaction(kStopSignals[i], nullptr, &previous[i]) == 0 &&
                     previous[i].sa_handler != SIG_IGN && ::sigaction(kStopSignals[i], &action, nullptr) == 0;
    }
  }
  void restore() const {
    for (std::size_t i = 0; i < std::size(kStopSignals); ++i)
      if (installed[i]) ::sigaction(kStopSignals[i], &previous[i], nullptr);
  }
};

class StopNotice {
 public:
  // who: the line's prefix ("crisp eval", "filter"). Signals the shell made crisp ignore stay ignored.
  explicit StopNotice(const std::string& who);
  ~StopNotice();
  StopNotice(const StopNotice&) = delete;
  StopNotice& operator=(const StopNotice&) = delete;

  // What a stop during the next step says after "stopped by SIGNAL ".
  void step(const std::string& text);

  // The stop signals blocked on this thread (they wait); returns the mask to release. Around a fork, so
  // that the child takes the previous handlers back (restore) before a stop can reach it.
  static sigset_t hold();
  static void release(const sigset_t& old);
  // The handlers crisp had before the notice.
  static void restore();
};

}  // namespace crisp::cli
