// SPDX-License-Identifier: Apache-2.0
// crisp: command-line entry. Exit codes: 0 ok, 1 error, 2 usage error.
#include <cstdio>
#include <string>
#include <vector>

#include "cli/commands.h"
#include "core/error.h"
#include "crisp/crisp.h"
#include "io/temporary_file.h"

using namespace crisp;
using namespace crisp::cli;

static int runHelp(const ParsedArgs& args) {
  if (args.positional.empty()) {
    std::fputs(helpText().c_str(), stdout);
    std::printf("\nMethods: %s\n", filterTypesJoined());
    return 0;
  }
  const std::string& topic = args.positional.front();
  std::string text = helpText(topic);
  if (text.empty()) {
    if (!isFilterType(topic)) {
      std::string commandNames;
      for (const CommandSpec& c : commands()) commandNames += (commandNames.empty() ? "" : ",") + std::string(c.name);
      throw UsageError("help: '" + topic + "' is neither a command (" + commandNames + ") nor a method (" +
                       filterTypesJoined() + ")");
    }
    Context context;
    text = createFilter(context, topic)->doc();
  }
  std::fputs(text.c_str(), stdout);
  return 0;
}

int main(int argc, char** argv) {
  removeTemporaryFilesOnSignals();  // Ctrl-C leaves no half-written ".name.tmp-*" behind
  std::vector<std::string> args(argv + 1, argv + argc);
  try {
    ParsedArgs a = parseArgs(args);
    if (a.has("help")) {
      std::fputs(helpText(a.command).c_str(), stdout);
      return 0;
    }
    checkPositionals(a);
    if (a.command == "help") return runHelp(a);
    if (a.command == "version") {
      std::printf("crisp %d.%d.%d\n", CRISP_VERSION_MAJOR, CRISP_VERSION_MINOR, CRISP_VERSION_PATCH);
      return 0;
    }
    if (a.command == "filter") return runFilter(a);
    if (a.command == "compare") return runCompare(a);
    if (a.command == "info") return runInfo(a);
    if (a.command == "synth") return runSynth(a);
    if (a.command == "render") return runRender(a);
    if (a.command == "eval") return runEval(a);
    if (a.command == "bench") return runBench(a, argv[0]);
    throw UsageError("unknown command '" + a.command + "'");
  } catch (const UsageError& e) {
    std::fprintf(stderr, "crisp: %s\n%s", e.what(), e.pointsToHelp ? "Run 'crisp help' for usage.\n" : "");
    return 2;
  } catch (const Exception& e) {
    std::fprintf(stderr, "crisp: error: %s\n", e.what());
    return 1;
  } catch (const std::exception& e) {
    std::fprintf(stderr, "crisp: error: %s\n", e.what());
    return 1;
  }
}
