// SPDX-License-Identifier: Apache-2.0
// crisp render --scene SCENE -o OUTDIR [...]: runs headless Blender with the
// add-on's batch driver (addon/crisp/batch.py), which renders 1-sample frames
// with exactly the passes the method needs, filters them through libcrisp and
// writes OUTDIR/{input,filtered,reference}/ and OUTDIR/run.json. A farm
// chunk (--preroll, --shot, --resume) is handled by batch.py as well.
#include <fcntl.h>
#include <sys/wait.h>
#include <unistd.h>

#include <algorithm>
#include <cerrno>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <string>
#include <vector>

#include "cli/commands.h"
#include "core/error.h"

namespace crisp::cli {

namespace fs = std::filesystem;

int runRender(const ParsedArgs& args) {
  if (!args.positional.empty()) throw UsageError("unexpected argument '" + args.positional.front() + "'");
  std::vector<std::string> cmd = blenderDriverCommand(args, "batch.py");
  cmd.push_back("-o");
  cmd.push_back(args.get("output"));
  for (const char* opt :
       {"frames", "preroll", "shot", "method", "samples", "reference-samples", "resolution", "threads"})
    if (args.has(opt)) {
      cmd.push_back(std::string("--") + opt);
      cmd.push_back(args.get(opt));
    }
  for (const std::string& kv : args.all("set")) {
    cmd.push_back("--set");
    cmd.push_back(kv);
  }
  appendJitterOption(args, cmd);
  if (args.has("plan")) cmd.push_back("--plan-only");
  if (args.has("resume")) cmd.push_back("--resume");
  const fs::path library = fs::path(executableDir()) / ".." / "lib" / "libcrisp.so";
  if (fs::exists(library)) {
    cmd.push_back("--library");
    cmd.push_back(fs::canonical(library).string());
  }

  std::vector<char*> argv;
  for (auto& s : cmd) argv.push_back(s.data());
  argv.push_back(nullptr);
  // --quiet: Blender's and the driver's progress (their stdout) is read here and dropped, except the
  // lines that report an error when Blender fails (Blender prints "Error: ..." there, e.g. for an
  // unreadable .blend). stderr stays the terminal's. --plan's output is what was asked for: kept.
  const bool capture = args.has("quiet") && !args.has("plan");
  int fds[2] = {-1, -1};
  if (capture && pipe2(fds, O_CLOEXEC) != 0) ioError("cannot start Blender (pipe failed)");
  std::fflush(stdout);
  pid_t pid = fork();
  if (pid < 0) ioError("cannot start Blender (fork failed)");
  if (pid == 0) {
    if (capture) dup2(fds[1], STDOUT_FILENO);  // the copy is not close-on-exec; the pipe's own ends are
    execvp(argv[0], argv.data());
    std::fprintf(stderr, "crisp: error: cannot run Blender '%s' (install it, or pass --blender PATH)\n", argv[0]);
    _exit(127);
  }
  std::string output;
  if (capture) {
    close(fds[1]);
    char buffer[4096];
    for (;;) {
      const ssize_t n = read(fds[0], buffer, sizeof buffer);
      if (n > 0) output.append(buffer, std::size_t(n));
      else if (n == 0 || errno != EINTR) break;
    }
    close(fds[0]);
  }
  int status = 0;
  while (waitpid(pid, &status, 0) < 0 && errno == EINTR) {
  }
  if (capture && !(WIFEXITED(status) && WEXITSTATUS(status) == 0)) {
    std::string errors = blenderErrorLines(output);
    if (errors.empty())  // none recognised: the end of what it printed
      errors = output.substr(output.size() - std::min<std::size_t>(output.size(), 2000));
    std::fprintf(stderr, "%s", errors.c_str());
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
