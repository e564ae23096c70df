// SPDX-License-Identifier: Apache-2.0
// Files written under a temporary name beside their target, then renamed into
// place (rename(2) within one filesystem is atomic), so the target holds
// either its old content or the whole new one. The temporary file is removed
// on every exit that did not commit it: a thrown error (the destructor), and
// SIGINT / SIGTERM / SIGHUP once removeTemporaryFilesOnSignals() has run.
#pragma once

#include <string>
#include <vector>

namespace crisp {

class TemporaryFile {
 public:
  // ".<name>.tmp-<host>-<pid>-<n><ext>" beside target: same filesystem,
  // hidden, unique per host, process and call (a farm may share the folder),
  // the real extension last (OIIO picks the format from it); the name part
  // cut to 64 bytes and the host to 64 so a target name near NAME_MAX (255)
  // still gets a valid sibling.
  explicit TemporaryFile(const std::string& target);
  ~TemporaryFile();
  TemporaryFile(const TemporaryFile&) = delete;
  TemporaryFile& operator=(const TemporaryFile&) = delete;

  const std::string& path() const { return path_; }
  // Renames the temporary file to the target; an IO error naming the target
  // (the temporary file is then removed).
  void commit();

 private:
  std::string target_, path_;
  int slot_ = -1;  // in the signal handler's list, or -1
  bool committed_ = false;
};

// Installs handlers for SIGINT, SIGTERM and SIGHUP that remove the temporary
// files being written, and then the folders given to removeFolderOnSignals
// that are empty, then end the process by the same signal. For programs
// (the crisp command); a library must not take a host's signals.
void removeTemporaryFilesOnSignals();

// A folder a run makes, which those handlers remove (rmdir(2), a folder before
// its parent) if it exists and is empty then, so that a
// run stopped before its first output leaves no empty folder behind. Given
// before the folder is made. Returns the slot to hand to keepFolderOnSignals
// once the run is over (or the folder could not be made), or -1 (no slot
// free: kept).
int removeFolderOnSignals(const std::string& folder);
void keepFolderOnSignals(int slot);

// Removes from `folder` the temporary files (above) that a process of this
// host left behind when it was killed without a chance to clean up (kill -9,
// a crash, a power cut): those named with this host, whose process no longer
// runs, untouched for a minute (a process of another machine that shares the
// host name is then still safe). Returns their names; nothing else is touched.
std::vector<std::string> removeStaleTemporaryFiles(const std::string& folder);

}  // namespace crisp
