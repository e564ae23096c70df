// SPDX-License-Identifier: Apache-2.0
// crisp filter --method NAME [--set K=V]... INPUT... -o OUTDIR [--png]
//              [--frames A-B [--preroll N]] [--resume]
// Inputs are filtered in the order given (temporal methods keep history
// between them) and each result goes to OUTDIR/<input name>.exr. Methods that
// read motion get it reconstructed for inputs with add-on sidecars and no
// motion pass (addReconstructedMotion). A chunk (--frames, positions among the
// inputs, 1-based) writes only its own frames; --preroll filters N earlier
// inputs first to warm the history (frame_range.h). Decisions about the whole
// sequence (motion rebuilt or not, output names) still look at every input, so
// every chunk of one sequence makes the same ones.
#include <algorithm>
#include <cstdint>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <set>
#include <vector>

#include <nlohmann/json.hpp>

#include "cli/commands.h"
#include "cli/frame_range.h"
#include "cli/progress.h"
#include "core/error.h"
#include "core/filter.h"
#include "io/sidecar.h"
#include "motion/reconstruct.h"

namespace crisp::cli {

namespace fs = std::filesystem;

namespace {

// Removes an output's settings record; one that cannot be removed fails the run before the
// outputs are replaced.
void removeRecord(const std::string& path) {
  std::error_code ec;
  fs::remove(path, ec);
  if (ec) ioError("cannot remove the old record '" + path + "': " + ec.message());
}

// What an output is made from, as its stamp records it: its input file and
// the input's sidecar (jitter, camera, shot position), each as size and
// modification time (files.cpp sizeAndTime; "" for a missing sidecar).
std::string inputIdentity(const std::string& input) {
  return sizeAndTime(input) + " | " + sizeAndTime(sidecarPathFor(input));
}

// Whether motion should be rebuilt for this run: the method reads "motion",
// every input has an add-on sidecar (frame_NNNN.json) and something moves over
// the inputs. A still sequence gets no motion pass at all, as the pass plan
// decides, so temporal filters take their static path.
bool rebuildsMotion(const Filter& filter, const std::vector<std::string>& inputs) {
  const auto& roles = filter.roles();
  const bool readsMotion = std::any_of(roles.begin(), roles.end(),
                                       [](const ImageRole& r) { return std::strcmp(r.name, "motion") == 0; });
  if (!readsMotion) return false;
  std::vector<std::string> sidecars;
  std::error_code ec;
  for (const std::string& in : inputs) {
    sidecars.push_back(sidecarPathFor(in));
    if (!fs::is_regular_file(sidecars.back(), ec)) return false;
  }
  return !sequenceIsStill(sidecars);
}

// Non-finite colour is read as the library reads it (NaN -> 0, +-Inf ->
// +-65504, conventions.h), which hides a broken render: say so, per file.
void warnNonFiniteColour(const Frame& frame) {
  const long count = frame.nonFiniteColour;
  if (count > 0)
    std::fprintf(stderr, "filter: warning: '%s': %ld non-finite colour value%s, read as 0 (NaN) or +-65504 (Inf)\n",
                 frame.path.c_str(), count, count == 1 ? "" : "s");
}

// An input without a motion pass gets motion reconstructed from its depth and
// the sidecars of the previous input (and of the next one, for zw) in the
// order given; the first input gets zero motion.
void addReconstructedMotion(Frame& frame, const std::vector<std::string>& inputs, std::size_t index,
                            int numThreads) {
  if (frame.has("motion")) return;
  if (index == 0) {
    frame.passes["motion"] = Image(frame.width, frame.height, 4, 0.0f);
    return;
  }
  const std::string next = index + 1 < inputs.size() ? sidecarPathFor(inputs[index + 1]) : std::string();
  reconstructFrameMotion(frame, sidecarPathFor(inputs[index - 1]), next, numThreads);
}

// What this command knows of a PNG it wrote, in OUT/.crisp/<name>.png.stamp:
// its size and modification time, so that a PNG changed since, or never
// written by it, is told apart from its own.
std::string pngStampOf(const std::string& pngPath) {
  const std::string stamp = sizeAndTime(pngPath);
  return stamp.empty() ? "" : stamp + "\n";
}

// A PNG beside an output written without --png shows an earlier run's result.
// One this command wrote and nobody changed since is removed; any other is
// kept and named.
struct StalePngs {
  int removed = 0;
  std::vector<std::string> kept;

  void check(const std::string& pngPath, const std::string& recordPath) {
    std::error_code ec;
    if (!fs::is_regular_file(pngPath, ec)) return;
    std::ifstream in(recordPath);
    const std::string record((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
    if (!record.empty() && record == pngStampOf(pngPath) && fs::remove(pngPath, ec)) {
      fs::remove(recordPath, ec);
      ++removed;
    } else {
      kept.push_back(pngPath);
    }
  }

  void report(bool quiet) const {
    if (removed > 0 && !quiet)
      std::fprintf(stderr, "filter: removed %d PNG(s) an earlier run wrote: this run writes none, and they could "
                   "show another result than the EXR beside them (--png writes new ones)\n", removed);
    for (const std::string& p : kept)
      std::fprintf(stderr, "filter: warning: kept '%s' (not written by crisp filter, or changed since): it does not "
                   "show this run's result\n", p.c_str());
  }
};

}  // namespace

int runFilter(const ParsedArgs& args) {
  if (args.positional.empty()) throw UsageError("'filter' needs at least one INPUT file");
  const std::string outDir = args.get("output");
  const bool png = args.has("png");
  const bool quiet = args.has("quiet");

  Context context;
  context.setInt("numThreads", parseIntOption(args, "threads", 0, 0, 1024));
  std::unique_ptr<Filter> filter = createFilter(context, args.get("method"));
  for (const std::string& kv : args.all("set")) {
    auto eq = kv.find('=');
    if (eq == std::string::npos || eq == 0) throw UsageError("--set expects KEY=VALUE, got '" + kv + "'");
    filter->params().setFromText(kv.substr(0, eq), kv.substr(eq + 1));
  }

  // The chunk to write (default: every input) and its pre-roll, checked before anything is written.
  const int count = int(args.positional.size());
  const FrameRange chunk =
      args.has("frames") ? parseFrameRange("frames", args.get("frames"), 1) : FrameRange{1, count};
  if (chunk.last > count)
    throw UsageError("--frames " + args.get("frames") + " reaches past the last input (" + std::to_string(count) +
                     " given; frames are 1-based positions among the inputs)");
  const int preroll = parseIntOption(args, "preroll", 0, 0, 1000000);

  // Refuse before writing anything: outputs that would collide or overwrite an input.
  std::set<std::string> stems;
  std::set<fs::path> inputs;
  for (const std::string& in : args.positional) {
    checkReadable(in);
    if (!stems.insert(fileStem(in)).second)
      throw UsageError("two inputs are named '" + fileStem(in) + "': their outputs would overwrite each other");
    std::error_code ec;
    inputs.insert(fs::weakly_canonical(in, ec));
  }
  for (const std::string& in : args.positional) {
    std::error_code ec;
    for (const char* ext : {".exr", ".png"})
      if (inputs.count(fs::weakly_canonical(joinPath(outDir, fileStem(in) + ext), ec)))
        throw UsageError("output for '" + in + "' would overwrite an input file; choose another -o folder");
  }
  makeDirectories(outDir);

  // A resume keeps the outputs it finds that this method made with these parameters from these
  // inputs. Each output has a stamp (OUT/.crisp/<name>.json, written after it) of the method, its
  // --set parameters, the build (files.cpp buildStamp), whether motion was rebuilt from the
  // sidecars (a decision over the whole sequence), its input ("input": inputIdentity), the output
  // EXR as written ("output"), and, for a filter that keeps history, the inputs its history went
  // through ("history": a digest of the identities of the inputs from the chunk's first pre-roll
  // frame to its own). An output made otherwise, or by a build before these stamps, counts as
  // missing; so does every output of a temporal filter after a changed input, whether that input
  // is in the chunk or in its pre-roll.
  const bool rebuildMotion = rebuildsMotion(*filter, args.positional);
  nlohmann::json settings = {{"method", args.get("method")},
                             {"params", nlohmann::json::object()},
                             {"motion_from_sidecars", rebuildMotion},
                             {"build", buildStamp()}};
  for (const std::string& kv : args.all("set")) {
    const std::size_t eq = kv.find('=');
    settings["params"][kv.substr(0, eq)] = kv.substr(eq + 1);
  }
  const bool temporal = keepsHistory(*filter);
  const int historyFirst = std::max(1, chunk.first - preroll);  // where the chunk's history starts
  std::vector<std::string> identity;  // by position - 1; a frame read by this run gets what the read saw
  for (const std::string& in : args.positional) identity.push_back(inputIdentity(in));
  auto foldIdentity = [&](int position, std::uint64_t& digest) {
    fnv1a64OfText(identity[std::size_t(position - 1)] + "\n", digest);
  };
  std::vector<std::string> plannedHistory(std::size_t(count) + 1);  // by position, as the files are now
  {
    std::uint64_t digest = kFnv1a64Seed;
    for (int position = historyFirst; position <= count; ++position) {
      foldIdentity(position, digest);
      plannedHistory[std::size_t(position)] = "fnv1a64:" + hex64(digest);
    }
  }
  auto stampOf = [&](int position, const std::string& history, const std::string& output) {
    nlohmann::json stamp = settings;
    stamp["input"] = identity[std::size_t(position - 1)];
    stamp["output"] = output;
    if (temporal) stamp["history"] = history;
    return stamp;
  };
  const std::string stampDir = joinPath(outDir, ".crisp");
  auto stampPathOf = [&](const std::string& stem) { return joinPath(stampDir, stem + ".json"); };
  auto pngRecordOf = [&](const std::string& stem) { return joinPath(stampDir, stem + ".png.stamp"); };
  auto readText = [](const std::string& path) {
    std::ifstream in(path);
    return std::string((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
  };

  // Why position's outputs must be made again ("" when they are complete and match).
  auto whyRemake = [&](int position) -> std::string {
    const std::string& input = args.positional[std::size_t(position - 1)];
    const std::string stem = fileStem(input), base = joinPath(outDir, stem);
    std::error_code ec;
    if (!fs::is_regular_file(base + ".exr", ec)) return "is missing";
    if (png && !fs::is_regular_file(base + ".png", ec)) return "has no PNG";
    if (png && readText(pngRecordOf(stem)) != pngStampOf(base + ".png"))
      return "has a PNG this command did not write (or one changed since)";
    const std::string have = readText(stampPathOf(stem));
    const nlohmann::json want = stampOf(position, plannedHistory[std::size_t(position)], sizeAndTime(base + ".exr"));
    if (have == want.dump() + "\n") return "";
    const nlohmann::json had = nlohmann::json::parse(have, nullptr, false);
    if (have.empty()) return "has no stamp (a run stopped before stamping it, or another program wrote it)";
    if (!had.is_object() || had.value("method", nlohmann::json()) != settings["method"] ||
        had.value("params", nlohmann::json()) != settings["params"])
      return "was made with other settings (" + have.substr(0, have.size() - 1) + ")";
    if (!had.contains("input") || !had["input"].is_string() || !had.contains("output") || !had.contains("build"))
      return "has a stamp from an older crisp, which did not record all it was made from";
    if (had["build"] != settings["build"])
      return "was made by another build of crisp (" + had["build"].get<std::string>() + ")";
    if (had.value("motion_from_sidecars", nlohmann::json()) != settings["motion_from_sidecars"])
      return rebuildMotion ? "was made before the motion was rebuilt from the sidecars (every input has one now)"
                           : "was made with motion rebuilt from the sidecars (not every input has one now, or the "
                             "sequence is still)";
    if (had["input"] != want["input"]) return "was made from another version of '" + input + "' or its sidecar";
    if (had["output"] != want["output"]) return "was replaced since this command wrote it";
    return "was made after other inputs before it than these (one changed since, another input list, or another "
           "--preroll; its history starts at '" + args.positional[std::size_t(historyFirst - 1)] + "')";
  };
  auto isComplete = [&](int position) {
    const std::string why = whyRemake(position);
    if (why.empty()) return true;
    std::fprintf(stderr, "filter: '%s' %s; making it again\n",
                 joinPath(outDir, fileStem(args.positional[std::size_t(position - 1)])).c_str(), why.c_str());
    return false;
  };
  ChunkRun run = planChunk(chunk, preroll, 1, args.has("resume"), isComplete);
  if (run.nothingToDo()) {
    if (!quiet)
      std::printf("filter: every output of frames %d-%d exists; nothing to do\n", chunk.first, chunk.last);
    return 0;
  }
  // A temporal filter reads from where the chunk's history starts, also when it resumes later in
  // the chunk, so what it writes is what an uninterrupted run writes (and what the stamps say).
  if (temporal) run.start = std::min(run.start, historyFirst);

  StalePngs stalePngs;
  {  // a file in the stamps' way fails the run before the first output, not after it
    std::error_code ec;
    if (fs::exists(stampDir, ec) && !fs::is_directory(stampDir, ec))
      ioError("cannot keep stamps in '" + stampDir + "': it is a file, not a folder");
  }
  // The history digest of the frames read so far: plannedHistory's, with the identities this run's
  // reads saw (a temporal filter reads from historyFirst; a spatial one's stamps have none).
  std::uint64_t history = kFnv1a64Seed;
  Image output;
  Progress progress("filter " + std::string(filter->type()), run.last - run.start + 1, quiet);
  ShotPosition shot;
  std::set<std::string> optionalBound;  // the optional passes bound for the frame before
  for (std::size_t i = std::size_t(run.start - 1); i < std::size_t(run.last); ++i) {
    const std::string& in = args.positional[i];
    const bool write = int(i) + 1 >= run.first;
    identity[i] = inputIdentity(in);  // before the read: a file replaced meanwhile is not stamped as read
    foldIdentity(int(i) + 1, history);
    Frame frame = readFrame(in);
    warnNonFiniteColour(frame);
    // A gap in the frame numbers or a cut to another camera: the history starts over, and the
    // frame gets zero motion as a first frame does.
    const std::string cut = historyBreak(*filter, in, shot);
    if (!cut.empty()) {
      filter->reset();
      if (!quiet)
        std::fprintf(stderr, "filter: '%s': %s history starts over (%s)\n", in.c_str(), filter->type(), cut.c_str());
    }
    if (rebuildMotion) addReconstructedMotion(frame, args.positional, cut.empty() ? i : 0, context.numThreads());
    try {
      bindFrame(*filter, frame, shot);
    } catch (const Exception& e) {
      throw Exception(e.code(), "'" + in + "': " + e.what());
    }
    {
      // An optional pass the frame before had and this one lacks (motion,
      // depth, ...): the filter goes on without it, which changes its output
      // for several frames; more often a mixed-up folder than intended.
      std::set<std::string> bound;
      std::string missing;
      for (const ImageRole& role : filter->roles())
        if (!role.required && std::string(role.name) != "output" && filter->hasImage(role.name)) bound.insert(role.name);
      for (const std::string& name : optionalBound)
        if (!bound.count(name)) missing += std::string(missing.empty() ? "'" : ", '") + name + "'";
      if (!missing.empty())
        std::fprintf(stderr, "filter: warning: '%s' has no %s pass, which the frame before it had: %s goes on without\n",
                     in.c_str(), missing.c_str(), filter->type());
      optionalBound = std::move(bound);
    }
    if (output.width != frame.width || output.height != frame.height) {
      // A size change part-way is legitimate (a cut to another camera) but
      // more often mixed-up folders: carry on, and say so.
      if (output.width != 0)
        std::fprintf(stderr,
                     "filter: warning: '%s' is %dx%d, the frames before it %dx%d: %s starts over at the new size\n",
                     in.c_str(), frame.width, frame.height, output.width, output.height, filter->type());
      output = Image(frame.width, frame.height, 4);
    }
    filter->setImage("output", output.view());
    try {
      if (!filter->committed()) filter->commit();
      filter->execute();
    } catch (const Exception& e) {
      throw Exception(e.code(), "'" + in + "': " + e.what());
    }
    if (!write) {
      progress.step(fileStem(in) + " (pre-roll)");
      continue;
    }
    const std::string base = joinPath(outDir, fileStem(in));
    const std::string pngRecord = pngRecordOf(fileStem(in));
    makeDirectories(stampDir);
    // The old record goes first: a run stopped between the outputs and the new record must not
    // leave new pixels under the old settings, which --resume would keep.
    removeRecord(stampPathOf(fileStem(in)));
    writeImage(base + ".exr", output);
    if (png) {
      writeImage(base + ".png", output);
      writeTextFile(pngRecord, pngStampOf(base + ".png"));
    } else {
      stalePngs.check(base + ".png", pngRecord);
    }
    writeTextFile(stampPathOf(fileStem(in)),
                  stampOf(int(i) + 1, "fnv1a64:" + hex64(history), sizeAndTime(base + ".exr")).dump() + "\n");
    progress.step(fileStem(in));
  }
  stalePngs.report(quiet);
  return 0;
}

}  // namespace crisp::cli
