// SPDX-License-Identifier: Apache-2.0
// Headless Blender for `crisp render` and `crisp eval`: the command line (find
// the add-on's driver script, turn --scene into a .blend to open or a bundled
// test scene to build), the one process launcher both use, and the lines of
// its output that say what went wrong.
#include <fcntl.h>
#include <poll.h>
#include <sys/prctl.h>
#include <sys/wait.h>
#include <unistd.h>

#include <algorithm>
#include <cerrno>
#include <chrono>
#include <csignal>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <sstream>
#include <string>

#include "cli/commands.h"
#include "cli/stop_notice.h"
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

// The modules a Python script's import statements name ("import a, b", "from a import b"), indented too.
std::vector<std::string> importedModules(const fs::path& script) {
  std::vector<std::string> out;
  std::ifstream in(script);
  std::string line;
  while (std::getline(in, line)) {
    std::istringstream words(line);
    std::string keyword, names;
    words >> keyword;
    if (keyword != "import" && keyword != "from") continue;
    std::getline(words, names);
    if (keyword == "from") names = names.substr(0, names.find(" import"));
    std::istringstream list(names);
    std::string name;
    while (std::getline(list, name, ',')) {
      std::istringstream one(name);
      std::string module;
      one >> module;  // "a as b" -> "a"
      if (!module.empty()) out.push_back(module);
    }
  }
  return out;
}

}  // namespace

std::vector<std::string> blenderDriverCommand(const ParsedArgs& args, const std::string& script) {
  const std::string scene = args.get("scene");
  const fs::path addon = addonDir(script);
  const fs::path scenes = addon.parent_path() / "test_scenes";
  std::vector<std::string> cmd = {args.getOr("blender", "blender"), "-b"};
  std::string sceneScript;
  const bool blend = fs::path(scene).extension() == ".blend";
  if (args.has("scene-name") && !blend)
    throw UsageError("--scene-name picks a scene of a .blend file; --scene '" + scene + "' is none");
  if (blend) {
    if (!fs::is_regular_file(scene)) fail(CRISP_ERROR_IO, "scene file '" + scene + "' does not exist");
    cmd.push_back(fs::absolute(scene).string());
    if (args.has("scene-name")) {  // Blender's own choice of the scene; the driver checks it took (batch.named_scene)
      cmd.push_back("-S");
      cmd.push_back(args.get("scene-name"));
    }
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
  if (args.has("scene-name")) {
    cmd.push_back("--scene-name");
    cmd.push_back(args.get("scene-name"));
  }
  return cmd;
}

fs::path blenderOutputFolder(const ParsedArgs& args) {
  const std::string out = args.get("output");
#ifndef _WIN32
  // Blender reads a backslash in a render's path as a folder separator: the renders would go elsewhere
  // (batch.py refuses it too, pipeline.check_output_dir; said here before anything is made). On
  // Windows it is the separator.
  if (out.find('\\') != std::string::npos)
    throw UsageError("-o '" + out + "' has a backslash in its path, which Blender reads as a folder separator: "
                     "choose a path without one");
#endif
  if (out.rfind("//", 0) != 0) return fs::absolute(out);
  const std::string scene = args.get("scene");
  if (fs::path(scene).extension() != ".blend")
    throw UsageError("-o '" + out + "' is relative to the .blend file, as Blender reads //, and --scene '" + scene +
                     "' is no .blend file: give a folder");
  return fs::absolute(scene).parent_path() / out.substr(2);
}

std::string sceneFingerprint(const ParsedArgs& args, const std::string& olderBuildsSceneName) {
  const std::string scene = args.get("scene");
  std::vector<fs::path> files;
  if (fs::path(scene).extension() == ".blend") {
    files = {scene};
  } else {
    const fs::path scenes = addonDir("batch.py").parent_path() / "test_scenes";
    files = {scenes / (scene + ".py"), scenes / "common.py"};
    // And the other bundled scenes it imports, through theirs (light_switch builds still_life's scene):
    // an edit of still_life.py changes light_switch too. A scene importing none hashes as before.
    for (std::size_t k = 0; k < files.size(); ++k)
      for (const std::string& module : importedModules(files[k])) {
        const fs::path f = scenes / (module + ".py");
        if (fs::is_regular_file(f) && std::find(files.begin(), files.end(), f) == files.end()) files.push_back(f);
      }
  }
  std::uint64_t hash = kFnv1a64Seed;
  for (const fs::path& f : files)
    if (!fnv1a64OfFile(f.string(), hash)) fail(CRISP_ERROR_IO, "cannot read the scene file '" + f.string() + "'");
  // Builds before this one hashed --scene-name in where it was given: the same scene chosen as the file's
  // active one had another key, and a folder was refused to the same scene named.
  if (!olderBuildsSceneName.empty()) fnv1a64OfText("\nscene-name\n" + olderBuildsSceneName, hash);
  return "fnv1a64:" + hex64(hash);
}

bool readsScenePanel(const ParsedArgs& args) {
  return !args.has("no-panel") && fs::path(args.get("scene")).extension() == ".blend";
}

void appendLibraryOption(std::vector<std::string>& cmd) {
  const fs::path library = fs::path(executableDir()) / ".." / "lib" / "libcrisp.so";
  if (!fs::exists(library)) return;
  cmd.push_back("--library");
  cmd.push_back(fs::canonical(library).string());
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

namespace {

// Appends what fd has ready to buffer; false once its writers are gone.
bool readSome(int fd, std::string& buffer) {
  char chunk[4096];
  for (;;) {
    const ssize_t n = read(fd, chunk, sizeof chunk);
    if (n > 0) {
      buffer.append(chunk, std::size_t(n));
      return true;
    }
    if (n < 0 && errno == EINTR) continue;
    return false;
  }
}

// Blender's pid while it runs, and the first stop signal crisp got meanwhile.
volatile sig_atomic_t blenderPid = 0;
volatile sig_atomic_t stopSignal = 0;

// Only async-signal-safe calls: kill.
extern "C" void passStopToBlender(int sig) {
  if (stopSignal == 0) stopSignal = sig;
  if (blenderPid > 0) ::kill(pid_t(blenderPid), sig);
}

// While Blender runs, a stop signal crisp gets (a farm cancelling its task,
// kill PID, Ctrl-C) goes on to Blender, whose driver stops after the frame
// it is on and records why, and crisp waits for it: otherwise Blender would
// go on alone, writing into the output folder. A signal the shell made crisp
// ignore (nohup) is left alone.
class StopSignalsToBlender {
 public:
  StopSignalsToBlender() {
    stopSignal = 0;
    blenderPid = 0;
    handlers_.install(passStopToBlender, false);
  }
  void started(pid_t pid) {
    blenderPid = pid;
    lastSent_ = std::chrono::steady_clock::now();
    if (stopSignal != 0) ::kill(pid, stopSignal);  // one that came before the pid was known
  }
  // A stop Blender has not acted on yet goes to it again, once a second: a single Ctrl-C only flags
  // Blender's render to stop (its second one ends Blender) until a driver takes the signals over, and
  // batch_eval.py never does; a signal that reached the child before exec was lost. Once batch.py
  // takes them, the repeats change nothing: its first signal stops the run, the others wait for that.
  void repeatStop() {
    if (stopSignal == 0 || blenderPid <= 0) return;
    const auto now = std::chrono::steady_clock::now();
    if (now - lastSent_ < std::chrono::seconds(1)) return;
    lastSent_ = now;
    ::kill(pid_t(blenderPid), stopSignal);
  }
  void ended() { blenderPid = 0; }  // reaped: its pid may be another process's now
  // After Blender ended: crisp's own handlers back and, if crisp was asked to
  // stop, it stops now by the same signal.
  ~StopSignalsToBlender() {
    blenderPid = 0;
    handlers_.restore();
    if (stopSignal != 0) ::raise(stopSignal);
  }
  StopSignalsToBlender(const StopSignalsToBlender&) = delete;
  StopSignalsToBlender& operator=(const StopSignalsToBlender&) = delete;

 private:
  StopHandlers handlers_;
  std::chrono::steady_clock::time_point lastSent_;  // when Blender was last sent the stop (about)
};

}  // namespace

BlenderRun runBlender(std::vector<std::string> cmd, BlenderOutput output, const std::string& log,
                      const std::function<void(const std::string&)>& onProgress) {
  // The pipes are close-on-exec: Blender keeps what the child dup2s, and the
  // progress pipe's write end, made inheritable there. The exec pipe tells
  // the parent whether Blender started: it closes empty on a successful exec,
  // or carries the child's errno (an exit status cannot tell: Blender, or a
  // wrapper script, may itself exit 127).
  int progress[2] = {-1, -1}, capture[2] = {-1, -1}, exec[2] = {-1, -1};
  auto closeAll = [&]() {
    for (int fd : {progress[0], progress[1], capture[0], capture[1], exec[0], exec[1]})
      if (fd >= 0) close(fd);
  };
  bool piped = pipe2(exec, O_CLOEXEC) == 0;
  if (piped && onProgress) piped = pipe2(progress, O_CLOEXEC) == 0;
  if (piped && output == BlenderOutput::Captured) piped = pipe2(capture, O_CLOEXEC) == 0;
  if (!piped) {
    closeAll();
    ioError("cannot start Blender (pipe failed)");
  }
  if (onProgress) {
    cmd.push_back("--progress-fd");
    cmd.push_back(std::to_string(progress[1]));
  }
  std::vector<char*> argv;
  for (auto& s : cmd) argv.push_back(s.data());
  argv.push_back(nullptr);
  std::fflush(stdout);
  std::fflush(stderr);
  StopSignalsToBlender stops;
  const pid_t parent = getpid();
  const pid_t pid = fork();
  if (pid < 0) {
    closeAll();
    ioError("cannot start Blender (fork failed)");
  }
  if (pid == 0) {
    // crisp killed outright (kill -9, the OOM killer): Blender gets SIGTERM rather than going on alone.
    prctl(PR_SET_PDEATHSIG, SIGTERM);
    if (getppid() != parent) _exit(127);  // crisp died before that
    int to = output == BlenderOutput::Captured ? capture[1] : -1;
    if (output == BlenderOutput::Logged) to = open(log.c_str(), O_WRONLY | O_CREAT | O_APPEND | O_CLOEXEC, 0644);
    if (to >= 0) {
      dup2(to, STDOUT_FILENO);
      dup2(to, STDERR_FILENO);
    }
    if (onProgress) fcntl(progress[1], F_SETFD, 0);
    execvp(argv[0], argv.data());
    const int error = errno;
    (void)!write(exec[1], &error, sizeof error);
    _exit(127);
  }
  stops.started(pid);
  close(exec[1]);
  exec[1] = -1;
  int execError = 0;
  ssize_t got;
  while ((got = read(exec[0], &execError, sizeof execError)) < 0 && errno == EINTR) {
  }
  if (got > 0) {  // exec failed: nothing else comes from the child
    closeAll();
    while (waitpid(pid, nullptr, 0) < 0 && errno == EINTR) {
    }
    stops.ended();
    std::fprintf(stderr, "crisp: error: cannot run Blender '%s': %s (install it, or pass --blender PATH)\n",
                 cmd[0].c_str(), std::strerror(execError));
    BlenderRun failed;
    failed.started = false;
    failed.exitCode = 127;
    return failed;
  }
  close(exec[0]);
  // Both pipes are read as they fill (Blender would block on a full one).
  BlenderRun run;
  if (onProgress) close(progress[1]);
  if (output == BlenderOutput::Captured) close(capture[1]);
  std::string lines;  // progress not yet ended by a newline
  std::vector<pollfd> reading;
  if (onProgress) reading.push_back({progress[0], POLLIN, 0});
  if (output == BlenderOutput::Captured) reading.push_back({capture[0], POLLIN, 0});
  while (!reading.empty()) {
    stops.repeatStop();
    if (poll(reading.data(), reading.size(), 250) < 0) {
      if (errno == EINTR) continue;
      for (const pollfd& p : reading) close(p.fd);  // not expected; Blender then gets SIGPIPE
      break;
    }
    for (std::size_t i = 0; i < reading.size();) {
      const bool isProgress = onProgress && reading[i].fd == progress[0];
      bool more = true;
      if (reading[i].revents & (POLLIN | POLLHUP | POLLERR))
        more = readSome(reading[i].fd, isProgress ? lines : run.output);
      if (isProgress)
        for (std::size_t end; (end = lines.find('\n')) != std::string::npos; lines.erase(0, end + 1))
          onProgress(lines.substr(0, end));
      if (more) {
        ++i;
        continue;
      }
      close(reading[i].fd);
      reading.erase(reading.begin() + std::ptrdiff_t(i));
    }
  }
  if (onProgress && !lines.empty()) onProgress(lines);
  int status = 0;
  for (pid_t got = 0; got == 0 || (got < 0 && errno == EINTR);) {
    stops.repeatStop();
    if ((got = waitpid(pid, &status, WNOHANG)) == 0) poll(nullptr, 0, 100);
  }
  stops.ended();
  if (WIFEXITED(status))
    run.exitCode = WEXITSTATUS(status);
  else
    run.signal = WTERMSIG(status);
  return run;
}

}  // namespace crisp::cli
