// SPDX-License-Identifier: Apache-2.0
#include "io/temporary_file.h"

#include <signal.h>
#include <unistd.h>

#include <atomic>
#include <cerrno>
#include <cstdio>
#include <cstring>
#include <filesystem>

#include "core/error.h"

namespace crisp {

namespace {

// The temporary files being written, for the signal handler: fixed slots (no
// allocation, no lock), each holding its path once `state` is kReady. A write
// beyond kSlots concurrent ones is still removed on errors, not on signals.
constexpr int kSlots = 64;
constexpr std::size_t kPathBytes = 4096;
enum : int { kFree = 0, kFilling = 1, kReady = 2 };
struct Slot {
  std::atomic<int> state{kFree};
  char path[kPathBytes];
};
Slot slots[kSlots];

int registerPath(const std::string& path) {
  if (path.size() >= kPathBytes) return -1;
  for (int i = 0; i < kSlots; ++i) {
    int expected = kFree;
    if (slots[i].state.compare_exchange_strong(expected, kFilling)) {
      std::memcpy(slots[i].path, path.c_str(), path.size() + 1);
      slots[i].state.store(kReady);
      return i;
    }
  }
  return -1;
}

// Only async-signal-safe calls: unlink, signal, raise.
extern "C" void removeAndReraise(int sig) {
  for (Slot& s : slots)
    if (s.state.load() == kReady) ::unlink(s.path);
  ::signal(sig, SIG_DFL);
  ::raise(sig);
}

}  // namespace

TemporaryFile::TemporaryFile(const std::string& target) : target_(target) {
  static std::atomic<unsigned> counter{0};
  const std::filesystem::path p(target);
  const std::string name = "." + p.stem().string().substr(0, 64) + ".tmp-" + std::to_string(long(::getpid())) + "-" +
                           std::to_string(counter.fetch_add(1)) + p.extension().string();
  path_ = (p.parent_path() / name).string();
  slot_ = registerPath(path_);
}

TemporaryFile::~TemporaryFile() {
  if (!committed_) std::remove(path_.c_str());
  if (slot_ >= 0) slots[slot_].state.store(kFree);  // after the remove: a signal in between finds nothing left
}

void TemporaryFile::commit() {
  if (std::rename(path_.c_str(), target_.c_str()) != 0)
    ioError("cannot write '" + target_ + "': renaming the temporary file into place failed: " + std::strerror(errno));
  committed_ = true;
}

void removeTemporaryFilesOnSignals() {
  for (int sig : {SIGINT, SIGTERM, SIGHUP}) {
    struct sigaction action {};
    action.sa_handler = removeAndReraise;
    sigemptyset(&action.sa_mask);
    // A signal the shell told us to ignore (nohup, a background job's SIGINT) stays ignored.
    struct sigaction old {};
    if (::sigaction(sig, nullptr, &old) == 0 && old.sa_handler == SIG_IGN) continue;
    ::sigaction(sig, &action, nullptr);
  }
}

}  // namespace crisp
