// SPDX-License-Identifier: Apache-2.0
// crisp filter --method NAME [--set K=V]... INPUT... -o OUTDIR [--png] [--exr-depth 16|32] [--exr-codec NAME]
//              [--frames A-B [--preroll N]] [--resume]
// Inputs are filtered in the order given (temporal methods keep history
// between them) and each result goes to OUTDIR/<input name>.exr. Methods that
// read motion get it reconstructed for inputs with add-on sidecars and no
// motion pass (addReconstructedMotion). A chunk (--frames, positions among the
// inputs, 1-based) writes only its own frames; --preroll filters N earlier
// inputs first to warm a temporal method's history (frame_range.h; a spatial
// method reads none of them). Decisions about the whole sequence (motion
// rebuilt or not, output names) still look at every input, so every chunk of
// one sequence makes the same ones.
#include <algorithm>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <future>
#include <set>
#include <vector>

#include <nlohmann/json.hpp>
#include <OpenImageIO/thread.h>

#include "cli/commands.h"
#include "cli/frame_range.h"
#include "cli/output_stamps.h"
#include "cli/progress.h"
#include "cli/stop_notice.h"
#include "core/error.h"
#include "core/filter.h"
#include "io/sidecar.h"
#include "io/subsamples.h"
#include "io/temporary_file.h"
#include "motion/reconstruct.h"

namespace crisp::cli {

namespace fs = std::filesystem;

namespace {

// Which inputs have an add-on sidecar (frame_NNNN.json beside them), looked
// at once per run.
struct Sidecars {
  std::vector<std::string> paths;  // every input's sidecar path
  std::size_t with = 0;            // how many of them exist
  std::string firstWithout;        // the first that does not, or ""

  explicit Sidecars(const std::vector<std::string>& inputs) {
    std::error_code ec;
    for (const std::string& in : inputs) {
      paths.push_back(sidecarPathFor(in));
      if (fs::is_regular_file(paths.back(), ec))
        ++with;
      else if (firstWithout.empty())
        firstWithout = paths.back();
    }
  }
  bool all() const { return with == paths.size(); }
};

// Whether motion should be rebuilt for this run: the method reads "motion",
// every input has an add-on sidecar (frame_NNNN.json) and something moves over
// the inputs. A still sequence gets no motion pass at all, as the pass plan
// decides, so temporal filters take their static path.
bool rebuildsMotion(const Filter& filter, const Sidecars& sidecars) {
  return readsMotion(filter) && sidecars.all() && !sequenceIsStill(sidecars.paths);
}

// What the inputs' sidecars decide over --set, and what a sequence where
// only some inputs have one loses, said before the run: a jitter set applies
// to the inputs without a sidecar only (rsaa's camera, which every sidecar
// gives, is refused by configuredFilter).
void checkSidecarSettings(const Filter& filter, const ParsedArgs& args, const Sidecars& sidecars) {
  const std::vector<std::string>& inputs = args.positional;
  const std::size_t with = sidecars.with;
  const bool takesJitter = keepsHistory(filter);
  std::set<std::string> warned;  // a key set twice is said once
  for (const auto& [key, value] : settingsOf(args))
    if (takesJitter && (key == "jitterX" || key == "jitterY") && with > 0 && warned.insert(key).second)
      std::fprintf(stderr,
                   "filter: warning: --set %s applies only to inputs without a sidecar; %zu of %zu inputs have one, "
                   "and take the jitter it gives\n",
                   key.c_str(), with, inputs.size());
  const bool motion = readsMotion(filter);
  if (with == 0 || sidecars.all() || !(takesJitter || motion)) return;
  std::string what;
  if (takesJitter) what = "they are filtered as unjittered (or with the jitter --set gives)";
  if (motion)
    what += std::string(what.empty() ? "" : ", and ") +
            "motion is rebuilt from the sidecars for no input, so inputs without a motion pass are filtered as if "
            "nothing moved";
  std::fprintf(stderr, "filter: warning: %zu of %zu inputs come without a sidecar (the first: '%s'): %s\n",
               inputs.size() - with, inputs.size(), sidecars.firstWithout.c_str(), what.c_str());
}

// A sidecar's "history", which the add-on writes where the image changes with nothing moving (a still
// pixel's average would keep the old image): null where it gives none, or keeps the still average.
nlohmann::json sidecarHistory(const std::string& path) {
  std::ifstream in(path);
  const nlohmann::json side = nlohmann::json::parse(in, nullptr, false);
  if (!side.is_object() || !side.contains("history")) return nullptr;  // unreadable: readSidecar names it
  const nlohmann::json& history = side["history"];
  const std::string where = "sidecar '" + path + "' history";
  if (!history.is_object() || !history.contains("still_average") || !history["still_average"].is_boolean())
    invalidData(where + ": expected an object with still_average true or false");
  if (history.contains("note") && !history["note"].is_string()) invalidData(where + ".note: expected text");
  return history["still_average"].get<bool>() ? nlohmann::json() : history;
}

// What the renders' plan asks of a temporal filter, from the first input's sidecar ("history"), set as
// crisp render sets it (pipeline.with_plan_params) for each parameter --set leaves out: a value, or the
// name of another parameter whose value it takes (phlm's lambda = lambdaMoving). Said also under --quiet,
// as crisp eval says it: it changes what the run makes. Sidecars that disagree (inputs of an older build,
// kept by a resume) are named: the first input's plan is taken for every frame.
void applyPlanParams(Filter& filter, const ParsedArgs& args, const Sidecars& sidecars) {
  if (!keepsHistory(filter)) return;
  nlohmann::json history;
  std::string first, other;
  for (const std::string& path : sidecars.paths) {
    std::error_code ec;
    if (!fs::is_regular_file(path, ec)) continue;
    const nlohmann::json h = sidecarHistory(path);
    if (first.empty()) {
      first = path;
      history = h;
    } else if (other.empty() && h.is_null() != history.is_null()) {
      other = path;
    }
  }
  if (!other.empty()) {
    const char* averages = "keeps the still average";
    const char* blends = "blends still pixels as moving ones";
    std::fprintf(stderr,
                 "filter: warning: the inputs' sidecars disagree on the renders' plan: '%s' %s, '%s' %s (frames of "
                 "another build or plan); the first input's is taken for every frame\n",
                 first.c_str(), history.is_null() ? averages : blends, other.c_str(),
                 history.is_null() ? blends : averages);
  }
  if (history.is_null()) return;
  const std::string where = "sidecar '" + first + "' history";
  const nlohmann::json table = history.value("params", nlohmann::json::object());
  const nlohmann::json params = table.is_object() ? table.value(filter.type(), nlohmann::json::object()) : nullptr;
  if (!params.is_object()) invalidData(where + ".params: expected an object of parameters per method");
  const std::string note = history.value("note", std::string("their sidecars"));
  std::set<std::string> given;
  for (const auto& [key, value] : settingsOf(args)) given.insert(key);
  for (const auto& [key, value] : params.items()) {
    if (given.count(key)) continue;
    const std::string at = where + ".params." + filter.type() + "." + key;
    // A parameter's name: its value (canonicalParamText gives "" for a name the filter lacks).
    std::string text = value.is_string() ? canonicalParamText(filter, value.get<std::string>()) : std::string();
    if (value.is_boolean() || value.is_number()) text = value.dump();
    if (text.empty())
      invalidData(at + ": expected a value or the name of a parameter of " + filter.type() + ", got " + value.dump());
    try {
      filter.params().setFromText(key, text);
    } catch (const Exception& e) {
      throw Exception(e.code(), at + ": " + e.what());
    }
    std::fprintf(stderr, "filter: %s runs with %s=%s, as the renders' plan asks (%s; --set %s=... to choose)\n",
                 filter.type(), key.c_str(), canonicalParamText(filter, key).c_str(), note.c_str(), key.c_str());
  }
}

// Non-finite colour is read as the library reads it (NaN -> 0, +-Inf ->
// +-65504, conventions.h), which hides a broken render, and a brighter value
// is clamped to 65504, which dims a light's edges: say so, per file.
void warnSanitisedColour(const Frame& frame) {
  const long count = frame.nonFiniteColour, clamped = frame.clampedColour;
  if (count > 0)
    std::fprintf(stderr, "filter: warning: '%s': %ld non-finite colour value%s, read as 0 (NaN) or +-65504 (Inf)\n",
                 frame.path.c_str(), count, count == 1 ? "" : "s");
  if (clamped > 0)
    std::fprintf(stderr, "filter: warning: '%s': %ld colour value%s beyond +-65504, read as +-65504\n",
                 frame.path.c_str(), clamped, clamped == 1 ? "" : "s");
}

// One view layer of a multilayer EXR is filtered; the others (a second view layer of the scene)
// are in no output: said once per run, at the first input holding any, as a sequence's frames
// hold the same layers.
void warnLayersNotRead(const Frame& frame, bool& warned) {
  if (warned || frame.layersNotRead.empty()) return;
  warned = true;
  std::string list;
  for (const std::string& l : frame.layersNotRead) list += (list.empty() ? "" : ", ") + l;
  std::fprintf(stderr, "filter: warning: '%s' holds other view layers than '%s', which is filtered: %s, in no output\n",
               frame.path.c_str(), frame.layer.c_str(), list.c_str());
}

// An input without a motion pass gets motion reconstructed from its depth and
// the sidecar of the previous input in the order given; index 0 gets zero
// motion (the caller passes 0 at a cut or gap too). Only xy, the motion to the
// previous frame, which is all the filters read: zw stays 0, as in the
// add-on's frames, and no output depends on the input after it.
void addReconstructedMotion(Frame& frame, const std::vector<std::string>& inputs, std::size_t index,
                            int numThreads) {
  if (frame.has("motion")) return;
  if (index == 0) {
    frame.passes["motion"] = Image(frame.width, frame.height, 4, 0.0f);
    return;
  }
  reconstructFrameMotion(frame, sidecarPathFor(inputs[index - 1]), std::string(), numThreads);
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
    if (pngMatchesRecord(pngPath, recordPath) && fs::remove(pngPath, ec)) {
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

// Writes a frame's EXR (in the input's windows) and, with `png`, its PNG. With more than one thread
// the PNG (a single zlib stream) is written on a thread of OIIO's pool while OpenEXR's threads write
// the EXR (1920x1080 taa with --png, 8 frames: 515 -> 435 ms a frame). Both have ended when it returns or
// throws, the EXR's error first.
void writeOutputs(const std::string& base, const Image& output, const FrameWindows& windows, const ExrStorage& exr,
                  bool png, int numThreads) {
  if (!png || numThreads == 1 || OIIO::default_thread_pool()->size() < 1) {
    writeImage(base + ".exr", output.view(), windows, exr);
    if (png) writeImage(base + ".png", output);
    return;
  }
  std::future<void> pngWritten = OIIO::default_thread_pool()->push([&](int) { writeImage(base + ".png", output); });
  try {
    writeImage(base + ".exr", output.view(), windows, exr);
  } catch (...) {
    pngWritten.wait();  // it reads `output`
    throw;
  }
  pngWritten.get();  // the PNG's error, if any
}

// --exr-depth and --exr-codec, checked before anything is read or written.
ExrStorage exrStorageOf(const ParsedArgs& args) {
  ExrStorage exr;
  const std::string depth = args.has("exr-depth") ? args.get("exr-depth") : "32";
  if (depth != "16" && depth != "32") throw UsageError("--exr-depth expects 16 or 32, got '" + depth + "'");
  exr.half = depth == "16";
  if (args.has("exr-codec")) exr.compression = lowerCase(args.get("exr-codec"));  // Blender's names: ZIP, DWAA
  try {
    checkExrStorage(exr);
  } catch (const Exception& e) {
    throw UsageError(std::string("--exr-codec: ") + e.what());
  }
  return exr;
}

}  // namespace

int runFilter(const ParsedArgs& args) {
  if (args.positional.empty()) throw UsageError("'filter' needs at least one INPUT file");
  const std::string outDir = args.get("output");
  const bool png = args.has("png");
  const bool quiet = args.has("quiet");
  const ExrStorage exr = exrStorageOf(args);

  Context context;
  context.setInt("numThreads", parseIntOption(args, "threads", 0, 0, 1024));
  std::unique_ptr<Filter> filter = configuredFilter(context, args.get("method"), args);

  const Sidecars sidecars(args.positional);
  checkSidecarSettings(*filter, args, sidecars);
  applyPlanParams(*filter, args, sidecars);

  // The chunk to write (default: every input) and its pre-roll, checked before anything is written.
  const int count = int(args.positional.size());
  const FrameRange chunk =
      args.has("frames") ? parseFrameRange("frames", args.get("frames"), 1) : FrameRange{1, count};
  if (chunk.last > count)
    throw UsageError("--frames " + args.get("frames") + " reaches past the last input (" + std::to_string(count) +
                     " given; frames are 1-based positions among the inputs)");
  const int preroll = parseIntOption(args, "preroll", 0, 0, 1000000);
  // Without a chunk every input is written from the first, before which there is nothing to warm
  // (a resume re-reads a temporal history from there too): a --preroll would change nothing.
  if (args.has("preroll") && !args.has("frames"))
    throw UsageError("--preroll needs --frames A-B: it filters the N inputs before the chunk --frames picks, and "
                     "without --frames every input is written from the first");

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
    for (const std::string ext : {".exr", ".png"})
      if ((png || ext == ".exr") &&  // a PNG is written only with --png
          inputs.count(fs::weakly_canonical(joinPath(outDir, fileStem(in) + ext), ec)))
        throw UsageError("output for '" + in + "' would overwrite an input file; choose another -o folder");
  }
  // A stop signal (Ctrl-C, a farm cancelling its task) says where the run was, also under --quiet:
  // a farm's log then tells a cancelled task from a failed one.
  StopNotice stopNotice("filter");
  stopNotice.step("before its first input: no output is written");
  const RunFolder folder(outDir);
  // A folder in an output's place (named like it) would fail the run only when it reaches that frame.
  for (int position = chunk.first; position <= chunk.last; ++position) {
    const std::string base = joinPath(outDir, fileStem(args.positional[std::size_t(position - 1)]));
    checkOutputFile(base + ".exr");
    if (png) checkOutputFile(base + ".png");
  }

  // What each output was made from, which a resume compares (output_stamps.h).
  const bool rebuildMotion = rebuildsMotion(*filter, sidecars);
  nlohmann::json settings = {{"method", args.get("method")},
                             {"params", nlohmann::json::object()},
                             {"motion_from_sidecars", rebuildMotion},
                             {"exr", {{"depth", exr.half ? 16 : 32}, {"codec", exr.compression}}},
                             {"build", buildStamp()}};
  for (const auto& [key, value] : settingsOf(args)) settings["params"][key] = canonicalParamText(*filter, key);
  const bool temporal = keepsHistory(*filter);
  const int historyFirst = std::max(1, chunk.first - preroll);  // where the chunk's history starts
  OutputStamps stamps(outDir, args.positional, settings, temporal, historyFirst, png, readsSubsamples(*filter));
  // An EXR (or, with --png, a PNG) beside its input under the output's name (-o the inputs' folder,
  // inputs of another format: frame_0001.tif beside Blender's frame_0001.exr) that this command did not
  // write is another file of that frame, which the output would replace.
  for (int position = chunk.first; position <= chunk.last; ++position) {
    const std::string& in = args.positional[std::size_t(position - 1)];
    std::error_code ec;
    if (!fs::equivalent(fs::absolute(outDir, ec), fs::absolute(in, ec).parent_path(), ec)) continue;
    const std::string base = joinPath(outDir, fileStem(in));
    const bool exr = fs::is_regular_file(base + ".exr", ec) && !stamps.wroteOutput(position);
    const bool pngMine = !png || !fs::is_regular_file(base + ".png", ec) ||
                         pngMatchesRecord(base + ".png", stamps.pngRecordOf(position));
    if (exr || !pngMine)
      throw UsageError("output '" + base + (exr ? ".exr" : ".png") + "' would replace a file beside the input '" +
                       in + "' that crisp filter did not write (another file of that frame); choose another -o "
                       "folder");
  }
  const bool resume = args.has("resume");
  if (temporal && resume) {
    // Where the history will start over (a cut, a gap), as the run below
    // finds it: the planned digests restart there, so a changed input before
    // a cut leaves the outputs after it complete. A sidecar that cannot be
    // read stops the resume here, naming it, as the run would.
    std::vector<int> breaks;
    ShotPosition planned;
    for (int position = historyFirst; position <= chunk.last; ++position)
      if (!historyBreak(*filter, args.positional[std::size_t(position - 1)], planned).empty())
        breaks.push_back(position);
    stamps.plannedBreaks(breaks);
  }
  auto isComplete = [&](int position) {
    const std::string why = stamps.whyRemake(position);
    if (why.empty()) return true;
    std::fprintf(stderr, "filter: '%s' %s; making it again\n",
                 joinPath(outDir, fileStem(args.positional[std::size_t(position - 1)])).c_str(), why.c_str());
    return false;
  };
  // Temporary files of an earlier run on this host that was killed mid-write.
  for (const std::string& dir : {outDir, stamps.folder()}) {
    const std::vector<std::string> stale = removeStaleTemporaryFiles(dir);
    if (!stale.empty() && !quiet)
      std::fprintf(stderr, "filter: removed %zu temporary file(s) an interrupted run left in '%s' (first: '%s')\n",
                   stale.size(), dir.c_str(), stale[0].c_str());
  }
  // Pre-roll warms a temporal history; a spatial method has none, so it reads no
  // frame before the chunk (as the add-on's render renders none).
  ChunkRun run = planChunk(chunk, temporal ? preroll : 0, 1, resume, isComplete);
  if (run.nothingToDo()) {
    if (!quiet)
      std::printf("filter: every output of frames %d-%d exists; nothing to do\n", chunk.first, chunk.last);
    return 0;
  }
  // A temporal filter reads from where the chunk's history starts, also when it resumes later in
  // the chunk, so what it writes is what an uninterrupted run writes (and what the stamps say).
  if (temporal) run.start = std::min(run.start, historyFirst);

  StalePngs stalePngs;
  stamps.checkFolder();  // a file in the stamps' way fails the run before the first output, not after it
  Image output;
  Progress progress("filter " + std::string(filter->type()), run.last - run.start + 1, quiet);
  ShotPosition shot;
  shot.filterSizeGiven = settings["params"].contains("filterSize");  // else each sidecar's Film > Filter Size
  std::set<std::string> optionalBound;  // the optional passes bound for the frame before
  bool layersWarned = false;
  for (std::size_t i = std::size_t(run.start - 1); i < std::size_t(run.last); ++i) {
    const std::string& in = args.positional[i];
    const bool write = int(i) + 1 >= run.first;
    stopNotice.step(write ? "while it filtered '" + in + "' (input " + std::to_string(i + 1) + " of " +
                                std::to_string(chunk.first) + "-" + std::to_string(chunk.last) +
                                "): the outputs before it are whole, and the same command with --resume goes on "
                                "from them"
                          : "while it read the pre-roll ('" + in + "'): no output is written yet");
    // A spatial method's outputs stand alone: its resume keeps every complete
    // output, also after the first one it makes again (planChunk asked up to it).
    // (Not with motion rebuilt from the sidecars, which reads the inputs beside it; no spatial
    // method reads motion today.)
    if (resume && !temporal && !rebuildMotion && int(i) + 1 > run.first && isComplete(int(i) + 1)) {
      progress.step(fileStem(in) + " (kept)");
      continue;
    }
    stamps.reading(int(i) + 1);
    Frame frame = readFrame(in);
    warnSanitisedColour(frame);
    warnLayersNotRead(frame, layersWarned);
    // A gap in the frame numbers or a cut to another camera: the history starts over, and the
    // frame gets zero motion as a first frame does. Said also under --quiet, which hides progress
    // and notes, not what changes the output (docs/farm.md tells farm users to look for this line).
    const std::string cut = historyBreak(*filter, in, shot);
    if (!cut.empty()) {
      filter->reset();
      stamps.historyStartsOver(int(i) + 1);
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
      if (output.width != 0) {  // a temporal method's history starts over; a spatial one has none to lose
        const std::string consequence = temporal ? std::string(": ") + filter->type() + " starts over at the new size" : "";
        std::fprintf(stderr, "filter: warning: '%s' is %dx%d, the frames before it %dx%d%s\n", in.c_str(),
                     frame.width, frame.height, output.width, output.height, consequence.c_str());
      }
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
    const std::string pngRecord = stamps.pngRecordOf(int(i) + 1);
    stamps.removeStamp(int(i) + 1);
    writeOutputs(base, output, frame.windows, exr, png, context.numThreads());
    stamps.makeFolder();  // for the PNG's record
    if (png) {
      writeTextFile(pngRecord, pngStampOf(base + ".png"));
    } else {
      stalePngs.check(base + ".png", pngRecord);
    }
    stamps.writeStamp(int(i) + 1);
    progress.step(fileStem(in));
  }
  stalePngs.report(quiet);
  return 0;
}

}  // namespace crisp::cli
