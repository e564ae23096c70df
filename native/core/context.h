// SPDX-License-Identifier: Apache-2.0
#pragma once

#include <atomic>
#include <string>

namespace crisp {

// Shared settings for filters created from it. Reference-counted through the
// C API (crispRetainContext/crispReleaseContext).
class Context {
 public:
  void setInt(const std::string& name, int value);
  int getInt(const std::string& name) const;
  void commit() { committed_ = true; }
  bool committed() const { return committed_; }

  int numThreads() const { return numThreads_; }  // 0 = all cores
  int verbose() const { return verbose_; }

  std::atomic<int> refCount{1};

 private:
  int numThreads_ = 0;
  int verbose_ = 0;
  bool committed_ = false;
};

}  // namespace crisp
