// SPDX-License-Identifier: Apache-2.0
#include "io/temporary_file.h"

#include <signal.h>
#include <unistd.h>

#include <algorithm>
#include <atomic>
#include <cctype>
#include <chrono>
#include <cerrno>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <string>
#include <vector>

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
constexpr int kFolderSlots = 16;
Slot folderSlots[kFolderSlots];  // removeFolderOnSignals's

int registerPath(const std::string& path, Slot* slotList = slots, int count = kSlots) {
  if (path.size() >= kPathBytes) return -1;
  for (int i = 0; i < count; ++i) {
    int expected = kFree;
    if (slotList[i].state.compare_exchange_strong(expected, kFilling)) {
      std::memcpy(slotList[i].path, path.c_str(), path.size() + 1);
      slotList[i].state.store(kReady);
      return i;
    }
  }
  return -1;
}

// This host's name as temporary names hold it: at most 64 bytes of [A-Za-z0-9_.-] (others become _).
const std::string& hostTag() {
  static const std::string tag = [] {
    char host[256] = {};
    if (::gethostname(host, sizeof host - 1) != 0 || !host[0]) return std::string("host");
    std::string t;
    for (const char* c = host; *c && t.size() < 64; ++c)
      t += (std::isalnum(static_cast<unsigned char>(*c)) || *c == '_' || *c == '.' || *c == '-') ? *c : '_';
    return t;
  }();
  return tag;
}

bool allDigits(const std::string& s) {
  return !s.empty() && s.size() < 12 &&
         std::all_of(s.begin(), s.end(), [](char c) { return c >= '0' && c <= '9'; });
}

// The process id in a name this code makes on this host, ".<name>.tmp-<host>-<pid>-<n>[.<ext>]"
// (<ext> without a dot), or 0 for any other name.
long pidOfOwnTemporary(const std::string& name) {
  const std::string marker = ".tmp-" + hostTag() + "-";
  const std::size_t at = name.rfind(marker);
  if (name.size() < 2 || name[0] != '.' || at == std::string::npos || at == 0) return 0;
  const std::string rest = name.substr(at + marker.size());  // "<pid>-<n>[.<ext>]"
  const std::size_t dash = rest.find('-');
  if (dash == std::string::npos) return 0;
  const std::size_t dot = rest.find('.', dash);
  const std::string pid = rest.substr(0, dash), n = rest.substr(dash + 1, dot == std::string::npos ? dot : dot - dash - 1);
  if (!allDigits(pid) || !allDigits(n)) return 0;
  if (dot != std::string::npos && (dot + 1 == rest.size() || rest.find('.', dot + 1) != std::string::npos)) return 0;
  return std::stol(pid);
}

// Only async-signal-safe calls: unlink, rmdir, signal, raise. rmdir removes
// only an empty folder: one that holds anything stays, and its parents too.
extern "C" void removeAndReraise(int sig) {
  for (Slot& s : slots)
    if (s.state.load() == kReady) ::unlink(s.path);
  // A folder before its parent: passes until one removes nothing (a slot's number need not follow
  // the order the folders were given in once slots have been freed and taken again).
  for (bool removed = true; removed;) {
    removed = false;
    for (int i = kFolderSlots - 1; i >= 0; --i)
      if (folderSlots[i].state.load() == kReady && ::rmdir(folderSlots[i].path) == 0) removed = true;
  }
  ::signal(sig, SIG_DFL);
  ::raise(sig);
}

}  // namespace

TemporaryFile::TemporaryFile(const std::string& target) : target_(target) {
  static std::atomic<unsigned> counter{0};
  const std::filesystem::path p(target);
  const std::string name = "." + p.stem().string().substr(0, 64) + ".tmp-" + hostTag() + "-" +
                           std::to_string(long(::getpid())) + "-" + std::to_string(counter.fetch_add(1)) +
                           p.extension().string();
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

int removeFolderOnSignals(const std::string& folder) { return registerPath(folder, folderSlots, kFolderSlots); }

void keepFolderOnSignals(int slot) {
  if (slot >= 0 && slot < kFolderSlots) folderSlots[slot].state.store(kFree);
}

std::vector<std::string> removeStaleTemporaryFiles(const std::string& folder) {
  namespace fs = std::filesystem;
  std::vector<std::string> removed;
  std::error_code ec;
  const auto now = fs::file_time_type::clock::now();
  for (fs::directory_iterator it(folder, ec), end; !ec && it != end; it.increment(ec)) {
    const std::string name = it->path().filename().string();
    const long pid = pidOfOwnTemporary(name);
    if (pid <= 0 || pid == long(::getpid())) continue;
    if (::kill(pid_t(pid), 0) == 0 || errno != ESRCH) continue;  // still running (or not ours to ask)
    std::error_code e;
    if (!it->is_regular_file(e) || e) continue;
    const auto modified = fs::last_write_time(it->path(), e);
    if (e || now - modified < std::chrono::minutes(1)) continue;
    if (fs::remove(it->path(), e)) removed.push_back(name);
  }
  return removed;
}

}  // namespace crisp
