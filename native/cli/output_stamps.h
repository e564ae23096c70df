// SPDX-License-Identifier: Apache-2.0
// crisp filter's record of what each output was made from, which --resume
// compares with the inputs as they are now (docs/farm.md "Resume").
//
// Each output has a stamp, OUT/.crisp/<name>.json, written after it: the
// method, its --set parameters, the build (files.cpp buildStamp), whether
// motion was rebuilt from the sidecars (a decision over the whole sequence),
// its input ("input": inputIdentity: the input, its sidecar and, for rsaa,
// the sub-sample files the sidecar lists), the output EXR as written ("output"),
// and, for a filter that keeps history, the inputs its history went through
// ("history": a digest of the identities of the inputs from the chunk's first
// pre-roll frame, or from the last cut or gap after it where the history
// starts over (files.cpp historyBreak), to its own; at the chunk's first
// frame with motion rebuilt from the sidecars, also the sidecar before it).
// An output made otherwise, or by a build before these stamps, counts as
// missing; so does every output of a temporal filter after a changed input,
// whether that input is in the chunk or its pre-roll, up to the next cut or gap.
// A PNG written with --png has its own record, OUT/.crisp/<name>.png.stamp.
#pragma once

#include <cstdint>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

namespace crisp::cli {

// What this command knows of a PNG it wrote: its size and modification time,
// so that a PNG changed since, or never written by it, is told apart.
std::string pngStampOf(const std::string& pngPath);
// Whether the PNG at pngPath is the one its record (recordPath) describes:
// written by this command and unchanged since.
bool pngMatchesRecord(const std::string& pngPath, const std::string& recordPath);

class OutputStamps {
 public:
  // settings: the method, params, build and motion decision (recorded as
  // given); inputs: every input, in order; historyFirst: the 1-based position
  // where the chunk's history starts (temporal filters only); subsamples: the
  // method reads the geometric sub-sample files each sidecar lists (rsaa).
  OutputStamps(std::string outDir, const std::vector<std::string>& inputs, nlohmann::json settings, bool temporal,
               int historyFirst, bool png, bool subsamples);

  // The positions (1-based, ascending) where the history starts over, as
  // historyBreak finds them in the sidecars as they are now: the planned
  // digests (plannedHistory_) restart there. The constructor plans none; call
  // before whyRemake.
  void plannedBreaks(const std::vector<int>& breaks);
  // Why the outputs of input `position` (1-based) must be made again, from
  // the files as they are now; "" when they are complete and match.
  std::string whyRemake(int position) const;

  // Fails before the first output when a file is in the stamps' way.
  void checkFolder() const;
  // Whether the EXR at input `position`'s output name is one this command wrote and nobody changed
  // since (its stamp's "output"); false when there is none.
  bool wroteOutput(int position) const;
  // Before reading input `position`: records it as the read will see it (a
  // file replaced meanwhile is not stamped as read) and adds it to the
  // history digest. Inputs are read in order, from historyFirst on for a
  // temporal filter.
  void reading(int position);
  // After reading `position`: the filter's history started over there, so
  // the digest restarts with this input.
  void historyStartsOver(int position);
  // Before `position`'s outputs are replaced: its old stamp goes first, so a
  // run stopped between the outputs and the new stamp leaves no stamp under
  // the new pixels.
  void removeStamp(int position) const;
  // After `position`'s outputs are in place.
  void writeStamp(int position) const;
  // Makes the stamps' folder: after the first output is written (writeStamp does it too), so that a
  // run whose first output fails leaves no folder behind (RunFolder).
  void makeFolder() const;

  const std::string& folder() const { return dir_; }
  std::string pngRecordOf(int position) const;

 private:
  std::string base(int position) const;       // OUT/<stem>
  std::string stampPathOf(int position) const;  // OUT/.crisp/<stem>.json
  nlohmann::json stampOf(int position, const std::string& history, const std::string& output) const;
  std::uint64_t startDigest() const;  // the digest before input historyFirst_

  std::string outDir_, dir_;
  std::vector<std::string> inputs_, identity_;  // identity_ by position - 1
  std::vector<std::string> plannedHistory_;     // by position: the digest as the files are now
  nlohmann::json settings_;
  bool temporal_, png_, subsamples_;
  int historyFirst_;
  std::uint64_t history_;  // the digest of the inputs read so far
};

}  // namespace crisp::cli
