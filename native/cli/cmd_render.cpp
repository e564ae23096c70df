// SPDX-License-Identifier: Apache-2.0
// crisp render --scene SCENE -o OUTDIR [...]: runs headless Blender with the
// add-on's batch driver (addon/crisp/batch.py), which renders 1-sample frames
// with exactly the passes the method needs, filters them through libcrisp and
// writes OUTDIR/{input,filtered,reference}/ and OUTDIR/run.json. A farm
// chunk (--preroll, --shot, --resume) is handled by batch.py as well.
#include <fcntl.h>
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

int runRender(const ParsedArgs& args) {
  if (!args.positional.empty()) throw UsageError("unexpected argument '" + args.positional.front() + "'");
  const bool quiet = args.has("quiet");
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
  std::fflush(stdout);
  pid_t pid = fork();
  if (pid < 0) ioError("cannot start Blender (fork failed)");
  if (pid == 0) {
    // --quiet: Blender's and the driver's progress (stdout) is dropped; errors (stderr) still show.
    // --plan's output is what was asked for: kept.
    if (quiet && !args.has("plan")) {
      const int devNull = open("/dev/null", O_WRONLY);
      if (devNull >= 0) dup2(devNull, STDOUT_FILENO);
    }
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
