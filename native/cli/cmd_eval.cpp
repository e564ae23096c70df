// SPDX-License-Identifier: Apache-2.0
// crisp eval --scene SCENE -o OUTDIR [...]: renders everything the evaluation
// needs in headless Blender (addon/crisp/batch_eval.py: EEVEE's sample curve,
// the methods' 1-sample inputs, the reference, Blender's SMAA), then runs the
// methods through the library, measures them and writes the report
// (native/eval/). Blender's own output goes to OUTDIR/logs/blender.log; its
// progress comes back on a pipe (runBlender, cli/blender.cpp). Finished frames are never redone.
#include <fcntl.h>
#include <sys/file.h>
#include <unistd.h>

#include <algorithm>
#include <cctype>
#include <cerrno>
#include <chrono>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <map>
#include <set>
#include <sstream>
#include <vector>

#include <nlohmann/json.hpp>

#include "cli/commands.h"
#include "cli/frame_range.h"
#include "core/error.h"
#include "core/filter.h"
#include "eval/eval.h"

namespace crisp::cli {

namespace fs = std::filesystem;

namespace {

std::vector<std::string> splitList(const std::string& text) {
  std::vector<std::string> out;
  std::stringstream s(text);
  std::string item;
  while (std::getline(s, item, ','))
    if (!item.empty()) out.push_back(item);
  return out;
}

// The exact command line of this process (/proc/self/cmdline), shell-quoted where needed.
std::string commandLine() {
  std::ifstream in("/proc/self/cmdline", std::ios::binary);
  std::string all((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>()), out, arg;
  auto flush = [&]() {
    bool plain = !arg.empty() && arg.find_first_not_of(
        "abcdefghijklmnopqrstuvwxyzABCDEFGHIJKLMNOPQRSTUVWXYZ0123456789-_./=,:+") == std::string::npos;
    std::string quoted = "'";
    for (char c : arg) quoted += c == '\'' ? std::string("'\\''") : std::string(1, c);  // ' ends, \' is one, ' reopens
    out += (out.empty() ? "" : " ") + (plain ? arg : quoted + "'");
    arg.clear();
  };
  for (char c : all) {
    if (c == '\0') flush();
    else arg += c;
  }
  if (!arg.empty()) flush();
  return out;
}

// Shows a progress line of batch_eval.py ("progress DONE TOTAL COST COST_TOTAL SECONDS_LEFT ITEM").
// Returns whether the line was progress (and so was shown).
bool showRenderProgress(const std::string& line, bool tty) {
  int done = 0, total = 0, consumed = 0;
  long cost = 0, costTotal = 0;
  double left = 0;
  if (std::sscanf(line.c_str(), "progress %d %d %ld %ld %lf %n", &done, &total, &cost, &costTotal, &left,
                  &consumed) < 5)
    return false;
  std::string item = line.substr(std::size_t(consumed));
  while (!item.empty() && (item.back() == '\n' || item.back() == '\r')) item.pop_back();
  const int width = 30;
  const int filled = costTotal > 0 ? int(cost * width / costTotal) : width;
  if (tty)
    std::fprintf(stderr, "\rrender [%s%s] %d/%d %.0fs left  %-40.40s", std::string(filled, '#').c_str(),
                 std::string(width - filled, '.').c_str(), done, total, left, item.c_str());
  else
    std::fprintf(stderr, "render %d/%d %s (%.0fs left)\n", done, total, item.c_str(), left);
  std::fflush(stderr);
  return true;
}

// The lines of Blender's log that say what went wrong.
std::string blenderErrors(const fs::path& log) {
  std::ifstream in(log);
  return blenderErrorLines(std::string(std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>()));
}

// A method spec (--methods' METHOD[:KEY=VALUE...], or the scene's panel's) checked as the library
// checks it, before anything renders; what names it in a message comes first ("--methods 'X'").
// Returns the method and all its parameters' values once set: two spellings of one setting
// ("taa:sharpen=0.50", "taa:sharpen=.5", a default given) give the same, another setting another.
std::string checkedMethodSpec(const std::string& m, const std::string& where) {
  eval::MethodSpec spec;
  try {
    spec = eval::parseMethodSpec(m);
  } catch (const std::invalid_argument& e) {
    throw UsageError(where + ": " + e.what());
  }
  if (spec.method == "blender-smaa")
    throw UsageError(where + ": blender-smaa takes no settings (Blender's Anti-Aliasing node, always measured, at "
                     "the threshold eval_renders.py sets)");
  if (!isFilterType(spec.method))
    throw UsageError(where + ": unknown method '" + spec.method + "' (known: " + filterTypesJoined() +
                     ", blender-smaa)");
  Context context;
  std::unique_ptr<Filter> probe = createFilter(context, spec.method);
  try {
    for (const auto& [key, value] : spec.params) probe->params().setFromText(key, value);
    checkSettingsByCommit(context, spec.method, spec.params);  // rules a commit checks (an odd patchSize)
  } catch (const Exception& e) {
    throw UsageError(where + ": " + e.what());
  }
  std::string setting = spec.method;
  const ParamSet& values = probe->params();
  for (const ParamSpec& p : values.specs()) {
    char number[32];
    if (p.type == ParamType::Float) std::snprintf(number, sizeof number, "%.9g", double(values.getFloat(p.name)));
    setting += std::string(" ") + p.name + "=" +
               (p.type == ParamType::Int      ? std::to_string(values.getInt(p.name))
                : p.type == ParamType::Float  ? std::string(number)
                : p.type == ParamType::Bool   ? std::string(values.getBool(p.name) ? "true" : "false")
                                              : values.getString(p.name));
  }
  return setting;
}

// The --scene's Crisp panel as batch_eval.py --read-panel reads it in Blender and has the library check
// it (batch.py panel_settings, check_panel_params), before anything renders: its record into panel.
// Returns 0, or the exit code once said: a value the library refuses exits 1 (2 for an unknown
// method), as crisp render does.
int readScenePanel(const ParsedArgs& args, nlohmann::json& panel) {
  std::vector<std::string> cmd = blenderDriverCommand(args, "batch_eval.py");
  cmd.push_back("--read-panel");
  appendJitterOption(args, cmd);  // a --jitter given leaves the panel's out of its record
  appendLibraryOption(cmd);
  const BlenderRun run = runBlender(cmd, BlenderOutput::Captured);
  if (!run.started) return 1;  // said by runBlender
  const std::string marker = "crisp-panel: ";
  std::istringstream lines(run.output);
  for (std::string line; std::getline(lines, line);)
    if (line.rfind(marker, 0) == 0) panel = nlohmann::json::parse(line.substr(marker.size()), nullptr, false);
  if (run.signal == 0 && run.exitCode == 0 && panel.is_object()) return 0;
  std::string errors = blenderErrorLines(run.output);
  if (errors.empty())  // none recognised: the end of what it printed
    errors = run.output.substr(run.output.size() - std::min<std::size_t>(run.output.size(), 2000));
  std::fprintf(stderr, "crisp: error: Blender failed reading the scene's Crisp panel (%s %d):\n%s",
               run.signal ? "signal" : "exit", run.signal ? run.signal : run.exitCode, errors.c_str());
  return run.signal == 0 && run.exitCode == 2 ? 2 : 1;  // batch_eval.py: 5 a refused value, 3 the library
}

// Whether a run into the folder rendered anything: an EXR anywhere under renders/ (not a hidden one, the
// temporary name of a render that did not finish).
bool holdsRenders(const fs::path& renders) {
  std::error_code ec;
  for (auto it = fs::recursive_directory_iterator(renders, ec); !ec && it != fs::recursive_directory_iterator();
       it.increment(ec))
    if (it->path().extension() == ".exr" && it->path().filename().string()[0] != '.') return true;
  return false;
}

// Held while a run uses its output folder: a second crisp eval into it would render the same frames again
// and rewrite the first's records (times.json, scene.json, the report) under it. An flock on the folder
// itself: nothing to leave behind, and released however crisp ends (kill -9 included; the method
// processes it forks hold it with it and end with it). Blender, which it execs, does not inherit it. A
// file system that keeps no locks (ENOLCK, some network mounts) runs unlocked, as before.
class FolderLock {
 public:
  explicit FolderLock(const fs::path& folder) : fd_(::open(folder.c_str(), O_RDONLY | O_DIRECTORY | O_CLOEXEC)) {
    if (fd_ < 0 || ::flock(fd_, LOCK_EX | LOCK_NB) == 0) return;
    const int err = errno;
    ::close(fd_);
    fd_ = -1;
    if (err == EWOULDBLOCK)
      throw UsageError("'" + folder.string() + "' is the output folder of another crisp eval still running; wait for "
                           "it to end or use another -o folder",
                       false);
  }
  ~FolderLock() {
    if (fd_ >= 0) ::close(fd_);
  }
  FolderLock(const FolderLock&) = delete;
  FolderLock& operator=(const FolderLock&) = delete;

 private:
  int fd_;
};

}  // namespace

int runEval(const ParsedArgs& args) {
  const std::string scene = args.get("scene");
  const fs::path outDir = blenderOutputFolder(args);
  const bool quiet = args.has("quiet");
  const int threads = parseIntOption(args, "threads", 0, 0, 1024);
  const int refSamples = parseIntOption(args, "reference-samples", 64, 1, 65536);

  // Methods: the library's, or the list given; "none" (the 1-sample frames) always comes first.
  std::vector<std::string> methods;
  std::vector<std::string> asked = args.has("methods") ? splitList(args.get("methods")) : filterTypes();
  if (asked.empty())  // an unset shell variable, say; `--methods none` asks for the baseline alone
    throw UsageError("--methods '" + args.get("methods") + "' names no method (e.g. fxaa,repair; none measures the "
                     "1-sample frames alone)");
  methods.push_back("none");
  std::vector<std::string> rendered = {"none"};  // library methods whose inputs Blender renders
  std::map<std::string, std::string> settingOf;  // method spec -> checkedMethodSpec's
  auto addRendered = [&](const std::string& m) {
    const std::string method = eval::parseMethodSpec(m).method;
    if (std::find(rendered.begin(), rendered.end(), method) == rendered.end()) rendered.push_back(method);
  };
  for (const std::string& m : asked) {
    if (m == "blender-smaa") continue;  // always measured
    // Bad parameters are refused now, before anything is rendered.
    settingOf[m] = checkedMethodSpec(m, "--methods '" + m + "'");
    // Another spelling of a setting listed before ("taa:sharpen=.5" after "taa:sharpen=0.5") would be a
    // second row of the same figures: measured once, under the first spelling. Only where both give the
    // same keys: a key left out takes what the scene's plan or Film > Filter Size sets ("taa" and
    // "taa:staticAccumulation=true" differ on a scene whose plan turns the average off).
    auto givenKeys = [](const std::string& spec) {
      std::set<std::string> keys;
      for (const auto& kv : eval::parseMethodSpec(spec).params) keys.insert(kv.first);
      return keys;
    };
    const auto same = std::find_if(methods.begin(), methods.end(), [&](const std::string& k) {
      return settingOf.count(k) && settingOf[k] == settingOf[m] && givenKeys(k) == givenKeys(m);
    });
    if (same != methods.end()) {
      if (*same != m)
        std::fprintf(stderr, "crisp eval: --methods '%s' is the setting of '%s': measured once, as '%s'\n",
                     m.c_str(), same->c_str(), same->c_str());
      continue;
    }
    methods.push_back(m);
    addRendered(m);
  }
  std::string curve = args.getOr("curve", "");
  if (curve.empty()) {  // 1, 2, 4, ... below the reference's count
    for (int s = 1; s < refSamples && s <= 16; s *= 2) curve += (curve.empty() ? "" : ",") + std::to_string(s);
    if (curve.empty()) curve = "1";
  }
  std::string notBelowReference;  // curve points the reference is no better than
  for (const std::string& c : splitList(curve)) {
    char* end = nullptr;
    long v = std::strtol(c.c_str(), &end, 10);
    if (*end || v < 1 || v > 65536) throw UsageError("--curve expects sample counts like 1,2,4,8; got '" + c + "'");
    if (v >= refSamples) notBelowReference += (notBelowReference.empty() ? "" : ", ") + std::to_string(v);
  }
  if (!notBelowReference.empty())
    std::fprintf(stderr,
                 "eval: warning: EEVEE at %s sample(s) is measured against a reference of %d, which is no better: its "
                 "error says nothing (the same count gives 100 dB); give --reference-samples above the curve's "
                 "largest count\n",
                 notBelowReference.c_str(), refSamples);

  // Checked here too: the folder's settings file is written before Blender starts, and a size Blender
  // then refused would lock the folder against the corrected command.
  checkResolutionOption(args);
  const int warmup = parseIntOption(args, "warmup", 0, 0, 1000000);
  if (args.has("frames")) {  // checked as crisp render checks it (checkBlenderFrameRangeOption), and its length
    const FrameRange range = parseFrameRange("frames", args.get("frames"), kBlenderLowestFrame);
    if (warmup > range.last - range.first)
      throw UsageError("--warmup " + std::to_string(warmup) + " leaves none of the frames " + args.get("frames") +
                       " to measure");
  }
  const char* filterSize = std::getenv("CRISP_EVAL_FILTER_SIZE");  // batch_eval.py reads it too
  std::optional<double> renderedSize;
  if (filterSize && *filterSize) {
    char* end = nullptr;
    const double v = std::strtod(filterSize, &end);
    if (*end || !(v >= 0.0 && v <= 100.0))
      throw UsageError(std::string("bad CRISP_EVAL_FILTER_SIZE '") + filterSize + "' (pixels, e.g. 0.5)");
    renderedSize = v;
  }
  // The .blend's Crisp panel (readScenePanel): the method and changed parameters it set are measured as
  // a row of their own (also when --methods leaves the method out: the panel's setting is what the scene
  // renders with, the row eval is run to compare), beside that method's defaults, or are the row
  // --methods gives for the same setting; its jitter is the renders' unless --jitter is given.
  nlohmann::json panel;  // null: nothing came from a panel
  std::string panelRow;
  if (readsScenePanel(args)) {
    if (const int code = readScenePanel(args, panel)) return code;
    const nlohmann::json from = panel.value("from_panel", nlohmann::json::object());
    if (from.value("method", false) || !from.value("params", nlohmann::json::object()).empty()) {
      std::string spec = panel.value("method", std::string());
      const nlohmann::json params = panel.value("params", nlohmann::json::object());
      for (const auto& [key, value] : params.items())
        spec += ":" + key + "=" + (value.is_string() ? value.get<std::string>() : value.dump());
      const std::string setting = checkedMethodSpec(
          spec, "the scene's Crisp panel (" + panel.value("file", std::string()) + ") as '" + spec + "'");
      for (const std::string& m : methods)
        if (panelRow.empty() && (m == spec || (settingOf.count(m) && settingOf[m] == setting))) panelRow = m;
      if (panelRow.empty()) {  // after the last row of its method, else last
        const std::string method = eval::parseMethodSpec(spec).method;
        auto at = methods.end();
        for (auto it = methods.begin(); it != methods.end(); ++it)
          if (eval::parseMethodSpec(*it).method == method) at = it + 1;
        methods.insert(at, spec);
        panelRow = spec;
      }
      addRendered(panelRow);
    }
    if (panel.value("line", std::string()).empty()) {
      panel = nullptr;
    } else {
      panel["row"] = panelRow.empty() ? nlohmann::json() : nlohmann::json(panelRow);
      if (!quiet)
        std::fprintf(stderr, "%s%s\n", panel["line"].get<std::string>().c_str(),
                     panelRow.empty() ? "" : ("; measured as '" + panelRow + "'").c_str());
    }
  }
  // A temporal method filters with the renders' filter size (their sidecars, files.cpp bindJitter)
  // unless its settings give one. CRISP_EVAL_FILTER_SIZE is checked here; the scene's own Film >
  // Filter Size is known only in Blender, and batch_eval.py refuses one above what the method takes
  // (--filter-size-max) before the first render: a size it refuses is refused now, not after every render.
  std::vector<std::string> sizeLimits;
  for (const std::string& m : methods) {
    if (m == "none") continue;
    const eval::MethodSpec spec = eval::parseMethodSpec(m);
    Context context;
    std::unique_ptr<Filter> probe = createFilter(context, spec.method);
    const std::optional<double> largest = largestFilmFilterSize(*probe);
    if (!largest || !keepsHistory(*probe) || spec.gives("filterSize")) continue;
    if (renderedSize) {
      try {
        probe->params().setFloat("filterSize", *filterSizeForFilm(*probe, *renderedSize));
      } catch (const Exception& e) {
        throw UsageError("CRISP_EVAL_FILTER_SIZE " + std::string(filterSize) + " (the renders' Film > Filter Size, " +
                         "which " + spec.method + " filters with): " + e.what() + "; give --methods '" +
                         spec.method + ":filterSize=...' to filter with another");
      }
    }
    sizeLimits.push_back("--filter-size-max=" + m + "=" + jsonNumber(*largest));
  }
  std::vector<std::string> cmd = blenderDriverCommand(args, "batch_eval.py");
  appendJitterOption(args, cmd);
  if (!panel.is_null() && panel["from_panel"].value("jitter", false))  // not given: readScenePanel passed --jitter
    cmd.insert(cmd.end(), {"--jitter", panel["jitter"].get<std::string>()});
  cmd.insert(cmd.end(), sizeLimits.begin(), sizeLimits.end());
  makeDirectories(outDir.string());
  const FolderLock lock(outDir);
  const fs::path renders = outDir / "renders", logs = outDir / "logs";
  makeDirectories(renders.string());
  makeDirectories(logs.string());
  // A resumed run reuses the renders it finds, so what changes a render and is not checked frame by
  // frame must match the first run's: the scene (its name or path, and what its .blend or script
  // holds: sceneFingerprint), its size and EEVEE's pixel filter (CRISP_EVAL_FILTER_SIZE,
  // batch_eval.py), which shapes the reference, the curve and the Blackman-Harris jitter. (A changed
  // --jitter renders the jittered set again: its sidecars say how it was drawn; which scene of the
  // file the renders are of, batch_eval.py checks against their record, as only Blender knows the
  // file's active scene.) Settings files of older builds lack the last two: the filter size was the
  // scene's; the contents are taken as they are now. Those of builds that hashed a --scene-name into
  // the contents are read as the key of the scene their renders record.
  const fs::path settings = outDir / "eval_settings.json";
  const nlohmann::json want = {{"scene", scene},
                               {"scene_contents", sceneFingerprint(args)},
                               {"resolution", canonicalResolution(args.getOr("resolution", ""))},
                               {"filter_size", filterSize ? filterSize : ""}};
  // Settings with no render beside them bind nothing: a run stopped before its first render (Ctrl-C,
  // kill -9, a lost machine) must not lock the folder against the corrected command.
  if (fs::exists(settings) && holdsRenders(renders)) {
    std::ifstream in(settings);
    nlohmann::json have = nlohmann::json::parse(in, nullptr, false);
    if (have.is_object() && !have.contains("filter_size")) have["filter_size"] = "";
    if (have.is_object() && !have.contains("scene_contents")) have["scene_contents"] = want["scene_contents"];
    if (have.is_object() && have["scene_contents"] != want["scene_contents"]) {
      std::ifstream recordFile(renders / "scene.json");
      const nlohmann::json record = nlohmann::json::parse(recordFile, nullptr, false);
      const std::string named = record.is_object() ? record.value("scene", std::string()) : std::string();
      if (!named.empty() && have["scene_contents"] == sceneFingerprint(args, named))
        have["scene_contents"] = want["scene_contents"];
    }
    if (have.is_object() && have.contains("resolution") && have["resolution"].is_string())  // spelled as then
      have["resolution"] = canonicalResolution(have["resolution"].get<std::string>());
    if (have != want) {
      std::string differences;
      for (const auto& [key, value] : want.items()) {
        const nlohmann::json there = have.is_object() && have.contains(key) ? have[key] : nlohmann::json();
        if (there != value)
          differences += (differences.empty() ? "" : ", ") + key + " " + there.dump() + " there, " + value.dump() +
                         " here";
      }
      throw UsageError("'" + outDir.string() + "' holds renders made with other settings (" + differences +
                           "); use another -o folder or delete it",
                       false);
    }
  }
  writeTextFile(settings.string(), want.dump() + "\n");

  cmd.push_back("-o");
  cmd.push_back(renders.string());
  std::string methodList;
  for (const std::string& m : rendered) methodList += (methodList.empty() ? "" : ",") + m;
  cmd.insert(cmd.end(), {"--methods", methodList, "--reference-samples", std::to_string(refSamples), "--curve", curve});
  // --frames=A-B as one argument: "-5-3" alone would read as an option to the driver's argparse.
  for (const char* opt : {"frames", "resolution", "warmup"})
    if (args.has(opt)) cmd.push_back(std::string("--") + opt + "=" + args.get(opt));

  const fs::path log = logs / "blender.log";
  if (!quiet) std::fprintf(stderr, "crisp eval: rendering in Blender (log: %s)\n", log.c_str());
  auto t0 = std::chrono::steady_clock::now();
  const bool tty = isatty(fileno(stderr)) != 0;
  bool barShown = false;  // a tty's progress bar ends the line it is on
  const BlenderRun run = runBlender(cmd, BlenderOutput::Logged, log.string(), [&](const std::string& line) {
    // How far a run a signal stopped came (batch_eval.py stop_line), said also with --quiet: crisp ends
    // by that signal next, which says nothing of the renders kept.
    if (line.rfind("stop ", 0) == 0) {
      std::fprintf(stderr, "%scrisp eval: %s (renders in %s)\n", barShown ? "\n" : "", line.substr(5).c_str(),
                   renders.c_str());
      barShown = false;
      return;
    }
    if (quiet) return;
    if (line.rfind("say ", 0) == 0) {  // a line for the user (batch_eval.py: which scene of the file it took)
      std::fprintf(stderr, "%s%s\n", barShown ? "\n" : "", line.substr(4).c_str());
      barShown = false;
    } else {
      barShown = showRenderProgress(line, tty) && tty;
    }
  });
  if (barShown) std::fprintf(stderr, "\n");
  const int code = run.signal ? 128 + run.signal : run.exitCode;
  double blenderSeconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  if (!run.started || code != 0) {
    // Nothing rendered (Blender could not start, or refused the scene or the arguments): no settings file
    // is left to look as if it did.
    std::error_code ec;
    if (!holdsRenders(renders)) fs::remove(settings, ec);
    if (!run.started) return 1;  // said by runBlender
    std::fprintf(stderr, "crisp: error: Blender failed (exit %d); from %s:\n%s", code, log.c_str(),
                 blenderErrors(log).c_str());
    return code == 2 ? 2 : 1;
  }

  eval::Options o;
  o.outDir = outDir.string();
  o.renderDir = renders.string();
  o.methods = methods;
  o.threads = threads;
  o.quiet = quiet;
  o.command = commandLine();
  o.blenderSeconds = blenderSeconds;
  o.warmup = warmup;
  o.panel = panel;
  int rc = eval::run(o);
  if (rc == 0) std::printf("report: %s\n", (outDir / "report.html").c_str());
  return rc;
}

}  // namespace crisp::cli
