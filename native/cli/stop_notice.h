// SPDX-License-Identifier: Apache-2.0
// What a stop signal (Ctrl-C, kill PID, a farm's SIGTERM, SIGHUP) says before it ends a long command:
// one line, "<who>: stopped by <SIGNAL> <step>", where the step says where the run was and what of it
// is kept. crisp then ends as before, by the handler it had (its temporary files removed, then the
// signal's default). One notice at a time.
#pragma once

#include <csignal>
#include <string>

namespace crisp::cli {

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
