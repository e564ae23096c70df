// SPDX-License-Identifier: Apache-2.0
// The Blender command line shared by `crisp render` and `crisp eval`: find the
// add-on's driver script and turn --scene into a .blend to open or a bundled
// test scene to build.
#include <cstdlib>
#include <filesystem>
#include <sstream>
#include <string>

#include "cli/commands.h"
#include "core/error.h"

namespace crisp::cli {

namespace fs = std::filesystem;

namespace {

// The add-on folder holding crisp/<script>: $CRISP_ADDON_DIR, else the source
// tree this CLI was built from, else <prefix>/share/crisp/addon.
fs::path addonDir(const std::string& script) {
  if (const char* env = std::getenv("CRISP_ADDON_DIR")) return env;
  for (fs::path p : {fs::path(CRISP_SOURCE_DIR) / "addon", fs::path(executableDir()) / ".." / "share" / "crisp" / "addon"})
    if (fs::exists(p / "crisp" / script)) return p;
  fail(CRISP_ERROR_IO, "cannot find the add-on's driver (addon/crisp/" + script + "); set CRISP_ADDON_DIR");
}

std::string bundledScenes(const fs::path& dir) {
  std::string names;
  std::error_code ec;
  for (const auto& e : fs::directory_iterator(dir, ec)) {
    std::string stem = e.path().stem().string();
    if (e.path().extension() == ".py" && stem != "common") names += (names.empty() ? "" : ", ") + stem;
  }
  return names;
}

}  // namespace

std::vector<std::string> blenderDriverCommand(const ParsedArgs& args, const std::string& script) {
  const std::string scene = args.get("scene");
  const fs::path addon = addonDir(script);
  const fs::path scenes = addon.parent_path() / "test_scenes";
  std::vector<std::string> cmd = {args.getOr("blender", "blender"), "-b"};
  std::string sceneScript;
  if (fs::path(scene).extension() == ".blend") {
    if (!fs::is_regular_file(scene)) fail(CRISP_ERROR_IO, "scene file '" + scene + "' does not exist");
    cmd.push_back(fs::absolute(scene).string());
  } else if (fs::is_regular_file(scenes / (scene + ".py"))) {
    sceneScript = scene;
  } else {
    throw UsageError("--scene '" + scene + "' is neither a .blend file nor a bundled test scene (" +
                     bundledScenes(scenes) + ")");
  }
  for (const char* a : {"--factory-startup", "--python-exit-code", "1", "--python"}) cmd.push_back(a);
  cmd.push_back((addon / "crisp" / script).string());
  cmd.push_back("--");
  if (!sceneScript.empty()) {
    cmd.push_back("--scene-script");
    cmd.push_back(sceneScript);
  }
  return cmd;
}

void appendJitterOption(const ParsedArgs& args, std::vector<std::string>& cmd) {
  if (!args.has("jitter")) return;
  const std::string dist = args.get("jitter");
  if (dist != "blackman-harris" && dist != "uniform")
    throw UsageError("--jitter: unknown distribution '" + dist + "' (known: blackman-harris, uniform)");
  cmd.push_back("--jitter");
  cmd.push_back(dist);
}

std::string blenderErrorLines(const std::string& output) {
  std::istringstream in(output);
  std::string line, out;
  while (std::getline(in, line))
    if (line.find("crisp: error") != std::string::npos || line.find("Error") != std::string::npos ||
        line.find("Traceback") != std::string::npos)
      if (line.find("EGL") == std::string::npos) out += "  " + line + "\n";
  return out;
}

}  // namespace crisp::cli
