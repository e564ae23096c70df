// SPDX-License-Identifier: Apache-2.0
#include "cli/output_stamps.h"

#include <unistd.h>

#include <cerrno>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <utility>

#include "cli/commands.h"
#include "core/error.h"
#include "io/sidecar.h"
#include "io/subsamples.h"

namespace crisp::cli {

namespace fs = std::filesystem;

namespace {

// What an output is made from, as its stamp records it: its input file and
// the input's sidecar (jitter, camera, shot position), each as size and
// modification time (files.cpp sizeAndTime; "" for a missing sidecar); for
// a method that reads geometric sub-samples (rsaa), also each sub-sample file
// the sidecar lists, so that a sub-sample rendered again remakes the output.
// A list that cannot be read is recorded as such (the filter then stops
// with the reason when it reads the frame).
std::string inputIdentity(const std::string& input, bool subsamples) {
  const std::string sidecar = sidecarPathFor(input);
  std::string identity = sizeAndTime(input) + " | " + sizeAndTime(sidecar);
  if (subsamples) {
    try {
      for (const SubsampleEntry& e : readSubsampleList(sidecar)) identity += " | " + sizeAndTime(e.file);
    } catch (const Exception&) {
      identity += " | no readable sub-sample list";
    }
  }
  return identity;
}

std::string readText(const std::string& path) {
  std::ifstream in(path);
  return std::string((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
}

std::string digestText(std::uint64_t digest) { return "fnv1a64:" + hex64(digest); }

}  // namespace

std::string pngStampOf(const std::string& pngPath) {
  const std::string stamp = sizeAndTime(pngPath);
  return stamp.empty() ? "" : stamp + "\n";
}

bool pngMatchesRecord(const std::string& pngPath, const std::string& recordPath) {
  const std::string stamp = pngStampOf(pngPath);
  return !stamp.empty() && readText(recordPath) == stamp;
}

OutputStamps::OutputStamps(std::string outDir, const std::vector<std::string>& inputs, nlohmann::json settings,
                           bool temporal, int historyFirst, bool png, bool subsamples)
    : outDir_(std::move(outDir)),
      dir_(joinPath(outDir_, ".crisp")),
      inputs_(inputs),
      plannedHistory_(inputs.size() + 1),
      settings_(std::move(settings)),
      temporal_(temporal),
      png_(png),
      subsamples_(subsamples),
      historyFirst_(historyFirst),
      history_(kFnv1a64Seed) {
  for (const std::string& in : inputs_) identity_.push_back(inputIdentity(in, subsamples_));
  plannedBreaks({});
}

// The digest before the chunk's first input: with motion rebuilt from the
// sidecars, that input's motion is rebuilt from the sidecar of the input
// before it (files.cpp), so the digest starts from that sidecar's identity.
// A break (historyStartsOver) starts from the bare seed: there the frame gets
// zero motion, so a chunk starting at a cut and a run across it differ, and
// their digests do too.
std::uint64_t OutputStamps::startDigest() const {
  std::uint64_t digest = kFnv1a64Seed;
  if (historyFirst_ > 1 && settings_.value("motion_from_sidecars", false))
    fnv1a64OfText("motion after " + sizeAndTime(sidecarPathFor(inputs_[std::size_t(historyFirst_ - 2)])) + "\n",
                  digest);
  return digest;
}

void OutputStamps::plannedBreaks(const std::vector<int>& breaks) {
  std::uint64_t digest = startDigest();
  auto next = breaks.begin();
  for (int position = historyFirst_; position <= int(inputs_.size()); ++position) {
    while (next != breaks.end() && *next < position) ++next;
    if (next != breaks.end() && *next == position) digest = kFnv1a64Seed;  // historyStartsOver's rule
    fnv1a64OfText(identity_[std::size_t(position - 1)] + "\n", digest);
    plannedHistory_[std::size_t(position)] = digestText(digest);
  }
}

std::string OutputStamps::base(int position) const {
  return joinPath(outDir_, fileStem(inputs_[std::size_t(position - 1)]));
}
std::string OutputStamps::stampPathOf(int position) const {
  return joinPath(dir_, fileStem(inputs_[std::size_t(position - 1)]) + ".json");
}
std::string OutputStamps::pngRecordOf(int position) const {
  return joinPath(dir_, fileStem(inputs_[std::size_t(position - 1)]) + ".png.stamp");
}

nlohmann::json OutputStamps::stampOf(int position, const std::string& history, const std::string& output) const {
  nlohmann::json stamp = settings_;
  stamp["input"] = identity_[std::size_t(position - 1)];
  stamp["output"] = output;
  if (temporal_) stamp["history"] = history;
  return stamp;
}

std::string OutputStamps::whyRemake(int position) const {
  const std::string& input = inputs_[std::size_t(position - 1)];
  const std::string out = base(position);
  std::error_code ec;
  if (!fs::is_regular_file(out + ".exr", ec)) return "is missing";
  if (png_ && !fs::is_regular_file(out + ".png", ec)) return "has no PNG";
  if (png_ && !pngMatchesRecord(out + ".png", pngRecordOf(position)))
    return "has a PNG this command did not write (or one changed since)";
  const std::string have = readText(stampPathOf(position));
  const nlohmann::json want = stampOf(position, plannedHistory_[std::size_t(position)], sizeAndTime(out + ".exr"));
  if (have == want.dump() + "\n") return "";
  if (have.empty()) return "has no stamp (a run stopped before stamping it, or another program wrote it)";
  const nlohmann::json had = nlohmann::json::parse(have, nullptr, false);
  if (!had.is_object() || had.value("method", nlohmann::json()) != settings_["method"] ||
      had.value("params", nlohmann::json()) != settings_["params"])
    return "was made with other settings (" + have.substr(0, have.size() - 1) + ")";
  if (!had.contains("input") || !had["input"].is_string() || !had.contains("output") || !had.contains("build") ||
      !had["build"].is_string())
    return "has a stamp from an older crisp, which did not record all it was made from";
  if (had["build"] != settings_["build"])
    return "was made by another build of crisp (" + had["build"].get<std::string>() + ")";
  if (had.value("exr", nlohmann::json()) != settings_.value("exr", nlohmann::json()))
    return "was written as another EXR (" + had.value("exr", nlohmann::json()).dump() + ", now " +
           settings_.value("exr", nlohmann::json()).dump() + ")";
  if (had.value("motion_from_sidecars", nlohmann::json()) != settings_["motion_from_sidecars"])
    return settings_["motion_from_sidecars"] == true
               ? "was made before the motion was rebuilt from the sidecars (every input has one now)"
               : "was made with motion rebuilt from the sidecars (not every input has one now, or the sequence is "
                 "still)";
  if (had["input"] != want["input"])
    return "was made from another version of '" + input + "' or its sidecar" +
           (subsamples_ ? " or sub-samples" : "");
  if (had["output"] != want["output"]) return "was replaced since this command wrote it";
  return "was made after other inputs before it than these (one changed since, another input list, or another "
         "--preroll; its history starts at '" + inputs_[std::size_t(historyFirst_ - 1)] +
         "' or at the last cut or gap after it)";
}

bool OutputStamps::wroteOutput(int position) const {
  const nlohmann::json had = nlohmann::json::parse(readText(stampPathOf(position)), nullptr, false);
  return had.is_object() && had.contains("output") && had["output"] == sizeAndTime(base(position) + ".exr");
}

void OutputStamps::checkFolder() const {
  std::error_code ec;
  if (fs::exists(dir_, ec) && !fs::is_directory(dir_, ec))
    ioError("cannot keep stamps in '" + dir_ + "': it is a file, not a folder");
  // One another user made (a farm's workers under other accounts): the first output would be written, and
  // the run would stop at its stamp, leaving an output without one.
  if (fs::is_directory(dir_, ec) && access(dir_.c_str(), W_OK | X_OK) != 0)
    ioError("cannot keep stamps in '" + dir_ + "': the folder is not writable (" + std::strerror(errno) + ")");
}

void OutputStamps::reading(int position) {
  identity_[std::size_t(position - 1)] = inputIdentity(inputs_[std::size_t(position - 1)], subsamples_);
  if (position == historyFirst_) history_ = startDigest();
  fnv1a64OfText(identity_[std::size_t(position - 1)] + "\n", history_);
}

void OutputStamps::historyStartsOver(int position) {
  history_ = kFnv1a64Seed;
  fnv1a64OfText(identity_[std::size_t(position - 1)] + "\n", history_);
}

void OutputStamps::removeStamp(int position) const {
  const std::string path = stampPathOf(position);
  std::error_code ec;
  fs::remove(path, ec);
  if (ec) ioError("cannot remove the old record '" + path + "': " + ec.message());
}

void OutputStamps::makeFolder() const { makeDirectories(dir_); }

void OutputStamps::writeStamp(int position) const {
  makeFolder();
  const nlohmann::json stamp = stampOf(position, digestText(history_), sizeAndTime(base(position) + ".exr"));
  writeTextFile(stampPathOf(position), stamp.dump() + "\n");
}

}  // namespace crisp::cli
