// SPDX-License-Identifier: Apache-2.0
#include <unistd.h>

#include <algorithm>
#include <cerrno>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <sstream>
#include <vector>

#include "cli/commands.h"
#include "core/error.h"
#include "crisp/crisp.h"
#include "io/sidecar.h"
#include "io/temporary_file.h"
#include "io/subsamples.h"

namespace crisp::cli {

namespace fs = std::filesystem;

namespace {
void fnv1a64Bytes(const char* data, std::size_t n, std::uint64_t& hash) {
  for (std::size_t i = 0; i < n; ++i) {
    hash ^= static_cast<unsigned char>(data[i]);
    hash *= 0x100000001b3ull;
  }
}
}  // namespace

bool fnv1a64OfFile(const std::string& path, std::uint64_t& hash) {
  std::ifstream in(path, std::ios::binary);
  if (!in) return false;
  std::vector<char> chunk(1 << 20);
  while (in.read(chunk.data(), std::streamsize(chunk.size())) || in.gcount() > 0)
    fnv1a64Bytes(chunk.data(), std::size_t(in.gcount()), hash);
  return !in.bad();
}

void fnv1a64OfText(const std::string& text, std::uint64_t& hash) { fnv1a64Bytes(text.data(), text.size(), hash); }

const std::string& buildStamp() {
  static const std::string stamp = [] {
    std::string s = "crisp " + std::to_string(CRISP_VERSION_MAJOR) + "." + std::to_string(CRISP_VERSION_MINOR) + "." +
                    std::to_string(CRISP_VERSION_PATCH);
    std::uint64_t hash = kFnv1a64Seed;
    if (!fnv1a64OfFile("/proc/self/exe", hash)) return s + " (executable unreadable)";
    return s + " executable fnv1a64:" + hex64(hash);
  }();
  return stamp;
}

std::string hex64(std::uint64_t v) {
  char hex[17];
  std::snprintf(hex, sizeof hex, "%016llx", static_cast<unsigned long long>(v));
  return hex;
}

std::string sizeAndTime(const std::string& path) {
  std::error_code ec;
  const auto size = fs::file_size(path, ec);
  if (ec) return "";
  const auto time = fs::last_write_time(path, ec);
  if (ec) return "";
  return std::to_string(size) + " " + std::to_string(time.time_since_epoch().count());
}

void writeTextFile(const std::string& path, const std::string& text) {
  TemporaryFile tmp(path);
  std::FILE* out = std::fopen(tmp.path().c_str(), "wb");
  if (!out) ioError("cannot write '" + path + "': " + std::strerror(errno));
  const bool wrote = std::fwrite(text.data(), 1, text.size(), out) == text.size();
  const int writeErrno = errno;
  if (std::fclose(out) != 0 || !wrote)
    ioError("cannot write '" + path + "': " + std::strerror(wrote ? errno : writeErrno));
  tmp.commit();
}

void makeDirectories(const std::string& path) {
  std::error_code ec;
  fs::create_directories(path, ec);
  if (ec || !fs::is_directory(path)) ioError("cannot create output folder '" + path + "'" + (ec ? ": " + ec.message() : ""));
  if (access(path.c_str(), W_OK) != 0) ioError("output folder '" + path + "' is not writable");
}

void checkOutputFile(const std::string& path) {
  std::error_code ec;
  if (path.empty()) ioError("cannot write a file of an empty name");
  if (fs::is_directory(path, ec)) ioError("cannot write '" + path + "': it is a folder");
  const fs::path parent = fs::path(path).parent_path();
  if (!fs::is_directory(parent.empty() ? fs::path(".") : parent, ec))
    ioError("cannot write '" + path + "': its folder '" + parent.string() + "' does not exist");
}

namespace {
// Removes the folders in `dirs` (deepest first) while they are empty.
void removeEmptyFolders(const std::vector<std::string>& dirs) {
  std::error_code ec;
  for (const std::string& dir : dirs)
    if (!fs::remove(dir, ec)) break;  // not empty (or gone): neither it nor its parents are ours to remove
}
}  // namespace

RunFolder::RunFolder(const std::string& path) {
  // The path's folders are made one component at a time, as the system resolves it ("new/../x"
  // makes new, then x; ".." follows a symlink), and each one made is recorded, deepest first.
  // What exists, a symlink too (even a dangling one), is never recorded.
  std::error_code ec;
  fs::path prefix;
  for (const fs::path& part : fs::absolute(path, ec)) {
    if (ec || part.empty()) continue;  // the empty name after a trailing '/'
    prefix /= part;
    if (part == "." || part == ".." || fs::symlink_status(prefix, ec).type() != fs::file_type::not_found) {
      ec.clear();
      continue;
    }
    // Ctrl-C (or SIGTERM, SIGHUP) skips the destructor: the signal handler removes it instead,
    // handed over before it is made so that no signal finds it made and not handed over.
    const int slot = removeFolderOnSignals(prefix.string());
    if (!fs::create_directory(prefix, ec)) {  // makeDirectories below names the failure
      keepFolderOnSignals(slot);
      break;
    }
    made_.insert(made_.begin(), prefix.string());
    signalSlots_.push_back(slot);
  }
  try {
    makeDirectories(path);
  } catch (...) {
    removeEmptyFolders(made_);
    for (int slot : signalSlots_) keepFolderOnSignals(slot);
    throw;
  }
}

RunFolder::~RunFolder() {
  removeEmptyFolders(made_);
  for (int slot : signalSlots_) keepFolderOnSignals(slot);
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

namespace {

const ParamSpec* findParam(const Filter& f, const char* name) {
  for (const ParamSpec& s : f.params().specs())
    if (std::strcmp(s.name, name) == 0) return &s;
  return nullptr;
}
bool hasParam(const Filter& f, const char* name) { return findParam(f, name) != nullptr; }

}  // namespace

bool keepsHistory(const Filter& filter) { return hasParam(filter, "jitterX"); }

std::optional<float> filterSizeForFilm(const Filter& filter, double filmSize) {
  const ParamSpec* spec = findParam(filter, "filterSize");
  if (!spec) return std::nullopt;
  return std::max(float(filmSize), float(spec->minValue));
}

std::optional<double> largestFilmFilterSize(const Filter& filter) {
  const ParamSpec* spec = findParam(filter, "filterSize");
  if (!spec) return std::nullopt;
  return spec->maxValue;
}

namespace {

// This frame's sub-pixel jitter from its sidecar, for filters that take it
// (the sidecar's y is up, the library's down), parsed already when shot holds
// this frame's sidecar; without a sidecar, the jitter the filter had before
// the first frame (a frame of another renderer is not jittered, or --set says
// how). The same for filterSize, the pixel filter the unjitter assumes: the
// sidecar's Film > Filter Size, over which the add-on jittered the frame and
// EEVEE filters the reference (the add-on's pipeline.with_scene_filter_size),
// unless --set gave one; Blender's 0 is the library's smallest size.
// Re-commit only on a change.
void bindJitter(Filter& filter, const Frame& frame, ShotPosition& shot) {
  if (!hasParam(filter, "jitterX") || !hasParam(filter, "jitterY")) return;
  const bool sized = hasParam(filter, "filterSize");
  if (!shot.jitterSaved) {
    shot.jitterSaved = true;
    shot.jitterX = filter.params().getFloat("jitterX");
    shot.jitterY = filter.params().getFloat("jitterY");
    if (sized) shot.filterSize = filter.params().getFloat("filterSize");
  }
  const std::string side = sidecarPathFor(frame.path);
  Sidecar parsed;
  const Sidecar* s = nullptr;
  std::error_code ec;
  if (shot.known && shot.path == side) {
    s = &shot.sidecar;
  } else if (fs::is_regular_file(side, ec)) {
    parsed = readSidecar(side);
    s = &parsed;
  }
  // The jitter is in pixels of the sidecar's resolution: another frame size is another render's sidecar
  // (a moving shot's motion rebuild refused it; a still one took its jitter without a word).
  if (s && (s->width != frame.width || s->height != frame.height))
    invalidData("the frame is " + std::to_string(frame.width) + "x" + std::to_string(frame.height) +
                " but its sidecar '" + side + "' says " + std::to_string(s->width) + "x" + std::to_string(s->height) +
                " (render_settings.resolution), whose jitter it gives");
  const float x = s ? float(s->jitterX) : shot.jitterX, y = s ? float(-s->jitterY) : shot.jitterY;
  float size = shot.filterSize;
  if (sized && s && s->filterSize >= 0.0 && !shot.filterSizeGiven) size = *filterSizeForFilm(filter, s->filterSize);
  const bool jitterChanged = filter.params().getFloat("jitterX") != x || filter.params().getFloat("jitterY") != y;
  const bool sizeChanged = sized && filter.params().getFloat("filterSize") != size;
  if (!jitterChanged && !sizeChanged) return;
  const std::string from = s ? "sidecar '" + side + "'" : std::string("the shot");
  if (jitterChanged) {
    try {
      filter.params().setFloat("jitterX", x);
      filter.params().setFloat("jitterY", y);
    } catch (const Exception& e) {
      if (!s) throw;
      throw Exception(e.code(), "sidecar '" + side + "' gives jitter (" + jsonNumber(s->jitterX) + ", " +
                                    jsonNumber(s->jitterY) + ") px (y up): " + e.what());
    }
    filter.markDirty("jitterX and jitterY were set for " + from);
  }
  if (sizeChanged) {
    try {
      filter.params().setFloat("filterSize", size);
    } catch (const Exception& e) {
      if (!s) throw;
      throw Exception(e.code(), "sidecar '" + side + "' gives Film > Filter Size " + jsonNumber(s->filterSize) +
                                    " px (render_settings.filter_size): " + e.what());
    }
    filter.markDirty("filterSize was set for " + from);
  }
}

}  // namespace

std::string historyBreak(const Filter& filter, const std::string& framePath, ShotPosition& last) {
  if (!keepsHistory(filter)) return "";
  const std::string side = sidecarPathFor(framePath);
  std::error_code ec;
  if (!fs::is_regular_file(side, ec)) {
    // This frame's position is unknown: the next sidecar is not compared
    // with an older frame's (a chunk starting here could not do so either).
    last.known = false;
    return "";
  }
  Sidecar s = readSidecar(side);
  const std::string reason = last.known ? shotBreak(last.sidecar, s) : "";
  last.known = true;  // field by field: the jitter saved before the first frame stays
  last.sidecar = std::move(s);
  last.path = side;
  return reason;
}

std::vector<std::pair<std::string, std::string>> settingsOf(const ParsedArgs& args) {
  const auto trimmed = [](const std::string& t) {
    const auto b = t.find_first_not_of(" \t"), e = t.find_last_not_of(" \t");
    return b == std::string::npos ? std::string() : t.substr(b, e - b + 1);
  };
  std::vector<std::pair<std::string, std::string>> out;
  for (const std::string& kv : args.all("set")) {
    const auto eq = kv.find('=');
    const std::string key = trimmed(kv.substr(0, eq));
    if (eq == std::string::npos || key.empty()) throw UsageError("--set expects KEY=VALUE, got '" + kv + "'");
    out.emplace_back(key, trimmed(kv.substr(eq + 1)));
  }
  return out;
}

std::string canonicalParamText(const Filter& filter, const std::string& name) {
  const ParamSet& params = filter.params();
  const ParamSpec* spec = findParam(filter, name.c_str());
  if (!spec) return std::string();
  switch (spec->type) {
    case ParamType::Int: return std::to_string(params.getInt(name));
    case ParamType::Bool: return params.getBool(name) ? "true" : "false";
    case ParamType::String: return params.getString(name);
    case ParamType::Float: break;
  }
  return valueText(params.getFloat(name) + 0.0f, true);  // (-0 is 0)
}

std::unique_ptr<Filter> configuredFilter(Context& context, const std::string& method, const ParsedArgs& args,
                                         bool betweenParams) {
  if (!isFilterType(method))  // a mistyped option: a usage error, as in crisp eval
    throw UsageError("--method: unknown method '" + method + "' (known: " + filterTypesJoined() + ")");
  std::unique_ptr<Filter> filter = createFilter(context, method);
  for (const auto& [key, value] : settingsOf(args)) {
    if (readsSubsamples(*filter) && isRsaaCameraParam(key))
      throw UsageError("--set " + key + ": rsaa takes its camera from each frame's sidecar (the camera the frame "
                       "was rendered with), which replaces any value set here");
    filter->params().setFromText(key, value);
  }
  if (betweenParams) checkSettingsByCommit(context, method, settingsOf(args));
  return filter;
}

void checkSettingsByCommit(Context& context, const std::string& method,
                           const std::vector<std::pair<std::string, std::string>>& settings) {
  std::unique_ptr<Filter> probe = createFilter(context, method);
  for (const auto& [key, value] : settings) probe->params().setFromText(key, value);
  // 1x1 zero images bound to the images the filter requires, and rsaa's sub-sample record, as the
  // add-on's native.check_params binds them: a commit then checks what it checks between parameters.
  std::vector<std::vector<float>> buffers;
  for (const ImageRole& role : probe->roles()) {
    const bool subsamples = std::string(role.name) == "subsamples";
    if (!role.required && !subsamples) continue;
    const Format format = subsamples ? Format::RsaaSubsamples : role.isUint ? Format::UInt : Format(role.maxChannels);
    buffers.emplace_back(std::size_t(formatChannels(format)), 0.0f);
    probe->setImage(role.name, makeView(buffers.back().data(), format, 1, 1));
  }
  probe->commit();
}

bool readsMotion(const Filter& filter) {
  const auto& roles = filter.roles();
  return std::any_of(roles.begin(), roles.end(), [](const ImageRole& r) { return std::strcmp(r.name, "motion") == 0; });
}

void bindFrame(Filter& filter, Frame& frame, ShotPosition& shot) {
  if (readsSubsamples(filter)) attachRsaaInputs(filter, frame);
  bindJitter(filter, frame, shot);
  for (const ImageRole& role : filter.roles()) {
    std::string name = role.name;
    if (name == "output") continue;
    if (!frame.has(name) && frame.unusable.count(name)) frame.pass(name);  // throws, saying why
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
