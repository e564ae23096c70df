// SPDX-License-Identifier: Apache-2.0
// crisp bench [ARGS...]: runs crisp_bench (Google Benchmark), built beside
// the CLI, with the given arguments (default: 5 repetitions, medians).
#include <unistd.h>

#include <filesystem>
#include <vector>

#include "cli/commands.h"
#include "core/error.h"

namespace crisp::cli {

int runBench(const ParsedArgs& args, const char* argv0) {
  namespace fs = std::filesystem;
  fs::path bench = fs::path(executableDir()) / "crisp_bench";
  if (!fs::exists(bench))
    fail(CRISP_ERROR_INVALID_OPERATION, "benchmark runner '" + bench.string() + "' is not built (configure with -DCRISP_BUILD_TESTS=ON)");
  std::vector<std::string> a = {bench.string()};
  if (args.positional.empty()) {
    a.push_back("--benchmark_repetitions=5");
    a.push_back("--benchmark_report_aggregates_only=true");
  }
  a.insert(a.end(), args.positional.begin(), args.positional.end());
  std::vector<char*> argv;
  for (auto& s : a) argv.push_back(s.data());
  argv.push_back(nullptr);
  execv(argv[0], argv.data());
  ioError("cannot run '" + bench.string() + "'");
}

}  // namespace crisp::cli
