// SPDX-License-Identifier: Apache-2.0
// Chunked runs (issue 8): `--frames A-B --preroll N [--resume]`. A chunk
// writes frames A..B; the N frames before A (never before the sequence's
// first frame) only warm the temporal history. With --resume the chunk starts
// at its first frame whose output is missing, and the pre-roll is taken before
// that frame, so a resumed run warms its history exactly like a fresh chunk
// starting there would (crisp filter then reads a temporal method's chunk
// from its first pre-roll frame instead, cmd_filter.cpp). Header-only so the
// CLI's source list needs no change.
#pragma once

#include <algorithm>
#include <cerrno>
#include <cstdlib>
#include <functional>
#include <string>

#include "cli/options.h"

namespace crisp::cli {

constexpr int kBlenderLowestFrame = -1048574;  // Blender's MINAFRAME: crisp render and eval pass frames to it

struct FrameRange {
  int first = 0;
  int last = 0;  // inclusive
};

// The frames one run processes: [start, first) are pre-roll (filtered, not
// written), [first, last] are written. first > last: every output exists.
struct ChunkRun {
  int start = 0;
  int first = 0;
  int last = 0;
  bool nothingToDo() const { return first > last; }
};

namespace detail {
inline bool parseWholeNumber(const std::string& text, long& value) {
  if (text.empty()) return false;
  char* end = nullptr;
  errno = 0;
  value = std::strtol(text.c_str(), &end, 10);
  return *end == '\0' && errno == 0 && value > -1000000000L && value < 1000000000L;
}
}  // namespace detail

// "A-B" or "A" -> [A, B]; both >= lowest. Errors name the option and the text.
inline FrameRange parseFrameRange(const std::string& option, const std::string& text, int lowest) {
  const std::string expect = "--" + option + " expects A-B or A (whole numbers >= " + std::to_string(lowest) +
                             ", A <= B), got '" + text + "'";
  const std::size_t dash = text.find('-', 1);  // a leading '-' would be a sign
  long a = 0, b = 0;
  if (!detail::parseWholeNumber(text.substr(0, dash), a)) throw UsageError(expect);
  b = a;
  if (dash != std::string::npos && !detail::parseWholeNumber(text.substr(dash + 1), b)) throw UsageError(expect);
  if (a < lowest || b < a) throw UsageError(expect);
  return FrameRange{int(a), int(b)};
}

// chunk: the frames to write; sequenceFirst: the first frame of the whole
// sequence (pre-roll stops there, as a sequential run starts there);
// isComplete(f): whether frame f's outputs all exist (only asked with resume).
inline ChunkRun planChunk(FrameRange chunk, int preroll, int sequenceFirst, bool resume,
                          const std::function<bool(int)>& isComplete) {
  ChunkRun run;
  run.first = chunk.first;
  run.last = chunk.last;
  if (resume)
    while (run.first <= run.last && isComplete(run.first)) ++run.first;
  run.start = std::max(sequenceFirst, run.first - std::max(preroll, 0));
  return run;
}

}  // namespace crisp::cli
