// SPDX-License-Identifier: Apache-2.0
// crisp render --scene SCENE -o OUTDIR [...]: runs headless Blender with the
// add-on's batch driver (addon/crisp/batch.py), which renders 1-sample frames
// with exactly the passes the method needs, filters them through libcrisp and
// writes OUTDIR/{input,filtered,reference}/ and OUTDIR/run.json. A farm
// chunk (--preroll, --shot, --resume) is handled by batch.py as well. What the
// command line leaves out (method, jitter, input codec, parameters) comes from
// the .blend's Crisp panel when the file set it (batch.py panel_settings).
#include <algorithm>
#include <cstdio>
#include <cstdlib>
#include <string>
#include <vector>

#include "cli/commands.h"
#include "core/error.h"

namespace crisp::cli {

namespace {

// The lines of the driver's log that --quiet keeps: where a temporal method's
// history starts over (addon/crisp/pipeline.py: at a cut or a gap, "frame N:
// temporal history restarts (...)"; a resume without pre-roll, "note: ...'s
// history starts again at frame N"), which changes the output and which
// docs/farm.md tells farm users to look for. Progress and notes are dropped.
std::string historyLines(const std::string& output) {
  std::string out, line;
  for (std::size_t begin = 0; begin < output.size();) {
    std::size_t end = output.find('\n', begin);
    if (end == std::string::npos) end = output.size();
    line = output.substr(begin, end - begin);
    if (line.find("temporal history restarts") != std::string::npos ||
        line.find("history starts again at frame") != std::string::npos)
      out += "render: " + line + "\n";
    begin = end + 1;
  }
  return out;
}

// --input-codec NAME for the driver, in lower case, refused here as batch.py
// would refuse it once Blender has started (render.INPUT_CODECS: lossless only,
// so the filters read the values rendered).
void appendInputCodecOption(const ParsedArgs& args, std::vector<std::string>& cmd) {
  if (!args.has("input-codec")) return;
  const std::string codec = lowerCase(args.get("input-codec"));
  if (codec != "none" && codec != "piz" && codec != "zip")
    throw UsageError("--input-codec: unknown codec '" + args.get("input-codec") +
                     "' (known: none, piz, zip; lossless, so the filters read the values rendered)");
  cmd.push_back("--input-codec");
  cmd.push_back(codec);
}

}  // namespace

int runRender(const ParsedArgs& args) {
  {
    // The method and its --set values, checked here as crisp filter checks them: a mistake is
    // said before Blender starts (and --plan, which filters nothing, says it too). Without --method a
    // .blend's Crisp panel may name the method (batch.py panel_settings), which only Blender reads:
    // --set is then checked there, against the method the run takes, before anything renders. A
    // bundled scene's panel is never set, and --no-panel ignores it: the method is the command line's
    // or fxaa, checked here. With --method and a panel, each --set is checked alone (name, type,
    // range): the panel's other parameters may make a pair valid that the library's defaults would not
    // (--set feedbackMin=0.9 with the panel's feedbackMax 0.95), so the rules between parameters are
    // batch.py's to check, with the values the run takes.
    Context context;
    const bool panel = readsScenePanel(args);
    if (!panel || args.has("method"))
      configuredFilter(context, args.getOr("method", "fxaa"), args, /*betweenParams=*/!panel);
    else
      settingsOf(args);  // KEY=VALUE
  }
  // So are the options batch.py would refuse once Blender has started (its limits).
  checkBlenderFrameRangeOption(args, "frames");
  checkBlenderFrameRangeOption(args, "shot");
  checkResolutionOption(args);
  parseIntOption(args, "preroll", 0, 0, 1000000);
  parseIntOption(args, "samples", 1, 1, 65536);
  parseIntOption(args, "reference-samples", 0, 0, 65536);
  parseIntOption(args, "threads", 0, 0, 1024);
  std::vector<std::string> cmd = blenderDriverCommand(args, "batch.py");
  cmd.push_back("-o");
  cmd.push_back(blenderOutputFolder(args).string());
  // --opt=VALUE as one argument: a frame range "-5-3" alone would read as an option to batch.py's argparse.
  for (const char* opt :
       {"frames", "preroll", "shot", "method", "samples", "reference-samples", "resolution", "threads"})
    if (args.has(opt)) cmd.push_back(std::string("--") + opt + "=" + args.get(opt));
  for (const std::string& kv : args.all("set")) {
    cmd.push_back("--set");
    cmd.push_back(kv);
  }
  appendJitterOption(args, cmd);
  appendInputCodecOption(args, cmd);
  if (args.has("plan")) cmd.push_back("--plan-only");
  if (args.has("resume")) cmd.push_back("--resume");
  if (args.has("no-panel")) cmd.push_back("--no-panel");
  appendLibraryOption(cmd);

  // --quiet: Blender's and the driver's output (progress, EGL's notes) is read here and dropped,
  // except where a temporal history starts over (historyLines, said once Blender has ended) and the
  // lines that report an error when Blender fails (Blender prints "Error: ..." on stdout, e.g. for
  // an unreadable .blend). --plan's output is what was asked for: kept.
  const bool capture = args.has("quiet") && !args.has("plan");
  const BlenderRun run = runBlender(cmd, capture ? BlenderOutput::Captured : BlenderOutput::Terminal);
  if (!run.started) return 1;  // said by runBlender
  if (capture) std::fprintf(stderr, "%s", historyLines(run.output).c_str());
  if (capture && (run.signal != 0 || run.exitCode != 0)) {
    std::string errors = blenderErrorLines(run.output);
    if (errors.empty())  // none recognised: the end of what it printed
      errors = run.output.substr(run.output.size() - std::min<std::size_t>(run.output.size(), 2000));
    std::fprintf(stderr, "%s", errors.c_str());
  }
  if (run.signal != 0) {
    std::fprintf(stderr, "crisp: error: Blender was killed by signal %d\n", run.signal);
    return 1;
  }
  // batch.py: 2 bad input, 3 library, 4 render failure, 5 a parameter refused (1 here, as when this
  // side refuses a --set); Blender itself exits 1 on a Python error.
  return run.exitCode == 0 ? 0 : (run.exitCode == 2 ? 2 : 1);
}

}  // namespace crisp::cli
