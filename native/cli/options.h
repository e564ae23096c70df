// SPDX-License-Identifier: Apache-2.0
// The CLI's options come from one table (options.cpp) that both parses the
// command line and prints --help, so the two can never disagree.
#pragma once

#include <map>
#include <stdexcept>
#include <string>
#include <vector>

namespace crisp::cli {

struct OptionSpec {
  const char* command;    // subcommand this option belongs to ("*" = all)
  const char* name;       // long name without dashes
  char shortName;         // 0 = none
  const char* valueName;  // nullptr = a flag without value
  bool multi;             // takes several values (until the next option)
  bool required;
  const char* help;
};

struct CommandSpec {
  const char* name;
  const char* usage;  // positional part of the usage line
  const char* summary;
};

const std::vector<CommandSpec>& commands();
const std::vector<OptionSpec>& options();

struct ParsedArgs {
  std::string command;
  std::map<std::string, std::vector<std::string>> values;  // option -> values ("" for flags)
  std::vector<std::string> positional;
  bool has(const std::string& name) const { return values.count(name) != 0; }
  const std::string& get(const std::string& name) const { return values.at(name).front(); }
  std::string getOr(const std::string& name, const std::string& fallback) const {
    return has(name) ? get(name) : fallback;
  }
  const std::vector<std::string>& all(const std::string& name) const;
};

// Throws UsageError with a message naming the offending argument.
struct UsageError : std::runtime_error {
  // pointsToHelp: the message ends with "Run 'crisp help'", unless it already says what to do instead.
  explicit UsageError(const std::string& what, bool pointsToHelp = true)
      : std::runtime_error(what), pointsToHelp(pointsToHelp) {}
  bool pointsToHelp;
};
ParsedArgs parseArgs(const std::vector<std::string>& args);
// The positional arguments against the command's usage (CommandSpec::usage): none where it is
// empty, at most one where it names one ("[COMMAND|METHOD]"), any number where it holds "...";
// UsageError naming the first one too many.
void checkPositionals(const ParsedArgs& args);
std::string helpText(const std::string& command = "");

int parseIntOption(const ParsedArgs& a, const std::string& name, int fallback, int lo, int hi);

// text with its ASCII letters in lower case (option values given in Blender's upper case: ZIP, PIZ).
std::string lowerCase(std::string text);

// The options crisp render and eval pass on to the Blender driver (batch.py,
// batch_eval.py), checked as the driver checks them, so that a mistake is said
// before Blender starts: --resolution WxH, and the frame ranges "A-B" or "A"
// named (Blender frame numbers, which may be negative).
void checkResolutionOption(const ParsedArgs& a);
// A --resolution value as "WxH" however it was spelled (64X36, 064x36, " 64x36" are 64x36); text that
// checkResolutionOption refuses is returned as it is.
std::string canonicalResolution(const std::string& text);
void checkBlenderFrameRangeOption(const ParsedArgs& a, const std::string& name);

}  // namespace crisp::cli
