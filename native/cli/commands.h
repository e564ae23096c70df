// SPDX-License-Identifier: Apache-2.0
// One function per subcommand; each returns the process exit code.
#pragma once

#include <cstdint>
#include <filesystem>
#include <functional>
#include <memory>
#include <optional>
#include <string>
#include <utility>
#include <vector>

#include "cli/options.h"
#include "core/filter.h"
#include "core/params.h"  // jsonQuote
#include "io/frame.h"
#include "io/sidecar.h"

namespace crisp::cli {

int runFilter(const ParsedArgs& args);
int runCompare(const ParsedArgs& args);
int runInfo(const ParsedArgs& args);
int runSynth(const ParsedArgs& args);
int runRender(const ParsedArgs& args);
int runEval(const ParsedArgs& args);
int runBench(const ParsedArgs& args, const char* argv0);

// Points every image role the filter declares at the frame's pass of that
// name, if the frame has it. Errors from commit name the file. With an add-on
// sidecar beside the frame it also adds what the sidecar holds for the filter:
// rsaa's sub-samples and camera (attached to the frame, so they live as long
// as it does) and a temporal filter's jitterX / jitterY and filterSize.
// Where a sequence is, for a temporal filter's history: the sidecar of the
// last frame it filtered, and that sidecar's path; and the jitter and filter
// size the filter had before the first frame (its defaults or --set), for
// frames without a sidecar. filterSizeGiven: --set (or the method's settings)
// gave filterSize, which then wins over the sidecars' Film > Filter Size.
struct ShotPosition {
  bool known = false;
  Sidecar sidecar;
  std::string path;
  bool jitterSaved = false;
  float jitterX = 0.0f, jitterY = 0.0f, filterSize = 0.0f;
  bool filterSizeGiven = false;
};
// The --set KEY=VALUE settings of args, blanks around KEY and VALUE trimmed
// (as batch.py strips them); a UsageError for one without KEY or '='.
std::vector<std::pair<std::string, std::string>> settingsOf(const ParsedArgs& args);
// A parameter's value as the filter holds it, in one spelling: --set 1e-3, 0.001 and +0.001 are one
// value, whose stamps a resume compares (params.h valueText: the fewest digits that read back as it).
std::string canonicalParamText(const Filter& filter, const std::string& name);
// The method's filter with the --set KEY=VALUE settings of args applied
// (throws naming a bad one, checkSettingsByCommit): what crisp filter runs,
// and what crisp render checks before it starts Blender. betweenParams false:
// each setting alone (name, type, range), not the rules between parameters
// that a commit checks (other values, a .blend's Crisp panel's, may complete them).
std::unique_ptr<Filter> configuredFilter(Context& context, const std::string& method, const ParsedArgs& args,
                                         bool betweenParams = true);
// Throws, as a commit does, when the method refuses the settings, also for a
// rule between parameters that only a commit checks (repair's odd patchSize,
// taa's feedbackMin <= feedbackMax): a probe filter is committed on 1x1 images.
void checkSettingsByCommit(Context& context, const std::string& method,
                           const std::vector<std::pair<std::string, std::string>>& settings);
// Binds the frame's passes and its jitter (from its sidecar, or the jitter
// saved in shot when it has none). shot: the position historyBreak just
// updated for this frame, whose sidecar is then not parsed again.
void bindFrame(Filter& filter, Frame& frame, ShotPosition& shot);
// Whether the filter has a "motion" image (the temporal methods): its frames need motion.
bool readsMotion(const Filter& filter);
// A temporal filter's history carries over only to the next frame of the same
// camera: for the frame at framePath, "" if it does (or it has no sidecar, or
// the filter keeps no history), else why not (io/sidecar.h shotBreak), and the
// caller restarts the history. Updates last.
std::string historyBreak(const Filter& filter, const std::string& framePath, ShotPosition& last);
// Whether the filter keeps history between frames (the temporal filters,
// which take a jitter): its output depends on the frames before.
bool keepsHistory(const Filter& filter);
// The filter's filterSize for a render whose Film > Filter Size was filmSize
// px (Blender's 0 is the library's smallest size), or nothing when the filter
// has no filterSize. Not checked against the largest: setFloat refuses that.
std::optional<float> filterSizeForFilm(const Filter& filter, double filmSize);
// The largest Film > Filter Size (px) filterSizeForFilm gives the filter a
// filterSize it takes (its table's largest), or nothing when it has none.
std::optional<double> largestFilmFilterSize(const Filter& filter);

// A file's size and modification time as "SIZE TIME", "" when it cannot be
// read: what tells a file apart from the one a run wrote or read before.
std::string sizeAndTime(const std::string& path);

// File helpers: text written through a temporary file renamed into place.
void writeTextFile(const std::string& path, const std::string& text);
void makeDirectories(const std::string& path);
// CRISP_ERROR_IO naming `path` when a file could not be put there at the end of a run (a folder in
// its place, or no folder to hold it): checked before the run does its work, not after it.
void checkOutputFile(const std::string& path);
// makeDirectories for one run: the folders it had to create are removed again
// at the end of the run (deepest first) if they are still empty, so that a
// run that fails before its first output, or is stopped by a signal
// (removeFolderOnSignals), leaves no empty output folder behind.
class RunFolder {
 public:
  explicit RunFolder(const std::string& path);
  ~RunFolder();
  RunFolder(const RunFolder&) = delete;
  RunFolder& operator=(const RunFolder&) = delete;

 private:
  std::vector<std::string> made_;  // deepest first
  std::vector<int> signalSlots_;   // removeFolderOnSignals's, in the order made
};
std::string fileStem(const std::string& path);
std::string joinPath(const std::string& dir, const std::string& name);
// FNV-1a (64 bits) over a file's bytes, continuing from hash (start from
// kFnv1a64Seed); false if it cannot be read. hex64: 16 hex digits.
constexpr std::uint64_t kFnv1a64Seed = 0xcbf29ce484222325ull;
bool fnv1a64OfFile(const std::string& path, std::uint64_t& hash);
void fnv1a64OfText(const std::string& text, std::uint64_t& hash);
// The build that runs: the library version and a hash (FNV-1a, 64 bits) of
// the running executable, which holds libcrisp (the CLI links it
// statically). Outputs stamped by another build are made again (crisp eval's
// method folders, crisp filter's outputs), so a result never comes from
// frames an older filter left behind.
const std::string& buildStamp();
std::string hex64(std::uint64_t v);
// The command line running addon/crisp/<script> in headless Blender on the
// --scene of args (a .blend to open, or a bundled test scene to build); it ends
// after "--" with the driver's scene arguments, callers append the rest.
std::vector<std::string> blenderDriverCommand(const ParsedArgs& args, const std::string& script);
// The -o folder of args as an absolute path: //NAME is NAME beside the --scene
// .blend, as Blender reads // (POSIX would take it for the root, while Blender,
// handed such a path, writes beside the .blend); a UsageError without a .blend.
std::filesystem::path blenderOutputFolder(const ParsedArgs& args);
// What the --scene of args is made of, as "fnv1a64:<hex>": the bytes of the
// .blend, or of the bundled scene's script, the test_scenes/common.py it
// imports and the other bundled scenes it imports (light_switch: still_life).
// Files the scene links or loads (textures, libraries) are not in it, nor
// which of the file's scenes is meant (only Blender knows the active one).
// olderBuildsSceneName: the key earlier builds wrote for that --scene-name.
std::string sceneFingerprint(const ParsedArgs& args, const std::string& olderBuildsSceneName = "");
// Whether the run reads the --scene's Crisp panel (addon/crisp/batch.py
// panel_settings): a .blend's, unless --no-panel (a bundled scene's is never set).
bool readsScenePanel(const ParsedArgs& args);
// Appends "--library PATH" for the driver when this build's libcrisp.so lies
// beside the executable (../lib), so Blender loads the library crisp was built with.
void appendLibraryOption(std::vector<std::string>& cmd);
// Appends "--jitter DIST" for the driver when args has --jitter; a distribution
// the add-on does not know (render.JITTER_DISTRIBUTIONS) is a UsageError.
void appendJitterOption(const ParsedArgs& args, std::vector<std::string>& cmd);
// The lines of Blender's output that report an error (the driver's "crisp:
// error", Blender's "Error: ...", Python tracebacks; not EGL's fallback
// notes), each indented, for a message after Blender failed.
std::string blenderErrorLines(const std::string& output);
// Where a Blender run's own output (its stdout and stderr) goes.
enum class BlenderOutput {
  Terminal,  // left on this process's terminal
  Captured,  // both streams read into BlenderRun::output
  Logged,    // both streams appended to the log file
};
struct BlenderRun {
  bool started = true;  // false: Blender could not be started (said on stderr; exitCode 127)
  int exitCode = 0;
  int signal = 0;       // non-zero: Blender was killed by it
  std::string output;  // BlenderOutput::Captured: what Blender printed
};
// Runs cmd (blenderDriverCommand's; cmd[0] looked up on PATH) and waits for it.
// With onProgress, "--progress-fd N" is appended and each line the driver
// writes to that pipe is handed over as it arrives.
BlenderRun runBlender(std::vector<std::string> cmd, BlenderOutput output, const std::string& log = {},
                      const std::function<void(const std::string&)>& onProgress = {});
// Folder of the running executable (/proc/self/exe).
std::string executableDir();

// Minimal JSON output.
std::string jsonNumber(double v);

}  // namespace crisp::cli
