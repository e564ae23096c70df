// SPDX-License-Identifier: Apache-2.0
#include <unistd.h>

#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <sstream>

#include "cli/commands.h"
#include "core/error.h"
#include "io/sidecar.h"
#include "io/subsamples.h"

namespace crisp::cli {

namespace fs = std::filesystem;

void writeTextFile(const std::string& path, const std::string& text) {
  fs::path target(path);
  fs::path tmp = target.parent_path() / ("." + target.filename().string() + ".tmp-" + std::to_string(getpid()));
  {
    std::ofstream out(tmp, std::ios::binary | std::ios::trunc);
    if (!out) ioError("cannot write '" + path + "': cannot create a file in its folder");
    out << text;
    out.flush();
    if (!out) {
      out.close();
      std::error_code ec;
      fs::remove(tmp, ec);
      ioError("cannot write '" + path + "': write failed (disk full?)");
    }
  }
  std::error_code ec;
  fs::rename(tmp, target, ec);
  if (ec) {
    fs::remove(tmp, ec);
    ioError("cannot write '" + path + "': " + ec.message());
  }
}

void makeDirectories(const std::string& path) {
  std::error_code ec;
  fs::create_directories(path, ec);
  if (ec || !fs::is_directory(path)) ioError("cannot create output folder '" + path + "'" + (ec ? ": " + ec.message() : ""));
  if (access(path.c_str(), W_OK) != 0) ioError("output folder '" + path + "' is not writable");
}

std::string executableDir() {
  std::error_code ec;
  fs::path self = fs::read_symlink("/proc/self/exe", ec);
  return ec ? std::string(".") : self.parent_path().string();
}

std::string fileStem(const std::string& path) { return fs::path(path).stem().string(); }

std::string joinPath(const std::string& dir, const std::string& name) { return (fs::path(dir) / name).string(); }

std::string jsonNumber(double v) {
  if (!std::isfinite(v)) return "null";
  char buf[32];
  std::snprintf(buf, sizeof buf, "%.10g", v);
  return buf;
}

void bindFrame(Filter& filter, const Frame& frame) {
  // The callers own the frame (a local from readFrame); the sub-samples are
  // added to it so they live as long as the frame the filter is bound to.
  if (readsSubsamples(filter)) attachRsaaInputs(filter, const_cast<Frame&>(frame));
  for (const ImageRole& role : filter.roles()) {
    std::string name = role.name;
    if (name == "output") continue;
    if (frame.has(name)) {
      filter.setImage(name, frame.pass(name).view());
    } else if (role.required) {
      invalidData("'" + frame.path + "' has no '" + name + "' pass, which method '" + filter.type() + "' needs (" +
                  role.meaning + ")");
    } else if (filter.hasImage(name)) {
      filter.unsetImage(name);
    }
  }
}

}  // namespace crisp::cli
