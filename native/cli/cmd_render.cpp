// SPDX-License-Identifier: Apache-2.0
// crisp render --scene SCENE -o OUTDIR [...]: runs headless Blender with the
// add-on's batch driver (addon/crisp/batch.py), which renders 1-sample frames
// with exactly the passes the method needs, filters them through libcrisp and
// writes OUTDIR/{input,filtered,reference}/ and OUTDIR/run.json.
#include <sys/wait.h>
#include <unistd.h>

#include <cerrno>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <vector>

#include "cli/commands.h"
#include "core/error.h"

namespace crisp::cli {

namespace fs = std::filesystem;

namespace {

// The add-on folder: $CRISP_ADDON_DIR, else the source tree this CLI was
// built from, else <prefix>/share/crisp/addon beside an installed binary.
fs::path addonDir() {
  if (const char* env = std::getenv("CRISP_ADDON_DIR")) return env;
  for (fs::path p : {fs::path(CRISP_SOURCE_DIR) / "addon", fs::path(executableDir()) / ".." / "share" / "crisp" / "addon"})
    if (fs::exists(p / "crisp" / "batch.py")) return p;
  fail(CRISP_ERROR_IO, "cannot find the add-on's batch driver (addon/crisp/batch.py); set CRISP_ADDON_DIR");
}

fs::path sceneScriptsDir() { return addonDir().parent_path() / "test_scenes"; }

std::string bundledScenes() {
  std::string names;
  std::error_code ec;
  for (const auto& e : fs::directory_iterator(sceneScriptsDir(), ec)) {
    std::string stem = e.path().stem().string();
    if (e.path().extension() == ".py" && stem != "common") names += (names.empty() ? "" : ", ") + stem;
  }
  return names;
}

}  // namespace

int runRender(const ParsedArgs& args) {
  if (!args.positional.empty()) throw UsageError("unexpected argument '" + args.positional.front() + "'");
  const std::string scene = args.get("scene");
  const fs::path addon = addonDir();
  std::vector<std::string> cmd = {args.getOr("blender", "blender"), "-b"};
  std::string sceneScript;
  if (fs::path(scene).extension() == ".blend") {
    if (!fs::is_regular_file(scene)) fail(CRISP_ERROR_IO, "scene file '" + scene + "' does not exist");
    cmd.push_back(scene);
  } else if (fs::is_regular_file(sceneScriptsDir() / (scene + ".py"))) {
    sceneScript = scene;
  } else {
    throw UsageError("--scene '" + scene + "' is neither a .blend file nor a bundled test scene (" + bundledScenes() + ")");
  }
  for (const char* a : {"--factory-startup", "--python-exit-code", "1", "--python"}) cmd.push_back(a);
  cmd.push_back((addon / "crisp" / "batch.py").string());
  cmd.push_back("--");
  cmd.push_back("-o");
  cmd.push_back(args.get("output"));
  if (!sceneScript.empty()) {
    cmd.push_back("--scene-script");
    cmd.push_back(sceneScript);
  }
  for (const char* opt : {"frames", "method", "samples", "reference-samples", "resolution", "threads"})
    if (args.has(opt)) {
      cmd.push_back(std::string("--") + opt);
      cmd.push_back(args.get(opt));
    }
  for (const std::string& kv : args.all("set")) {
    cmd.push_back("--set");
    cmd.push_back(kv);
  }
  if (args.has("plan")) cmd.push_back("--plan-only");
  const fs::path library = fs::path(executableDir()) / ".." / "lib" / "libcrisp.so";
  if (fs::exists(library)) {
    cmd.push_back("--library");
    cmd.push_back(fs::canonical(library).string());
  }

  std::vector<char*> argv;
  for (auto& s : cmd) argv.push_back(s.data());
  argv.push_back(nullptr);
  std::fflush(stdout);
  pid_t pid = fork();
  if (pid < 0) ioError("cannot start Blender (fork failed)");
  if (pid == 0) {
    execvp(argv[0], argv.data());
    std::fprintf(stderr, "crisp: error: cannot run Blender '%s' (install it, or pass --blender PATH)\n", argv[0]);
    _exit(127);
  }
  int status = 0;
  while (waitpid(pid, &status, 0) < 0 && errno == EINTR) {
  }
  if (WIFEXITED(status)) {
    int code = WEXITSTATUS(status);
    if (code == 127) return 1;
    // batch.py: 2 bad input, 3 library, 4 render failure; Blender itself exits 1 on a Python error.
    return code == 0 ? 0 : (code == 2 ? 2 : 1);
  }
  std::fprintf(stderr, "crisp: error: Blender was killed by signal %d\n", WTERMSIG(status));
  return 1;
}

}  // namespace crisp::cli
