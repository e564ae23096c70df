// SPDX-License-Identifier: Apache-2.0
#include "cli/options.h"

#include <algorithm>
#include <cctype>
#include <cstdio>
#include <cstdlib>
#include <stdexcept>
#include <sstream>

#include "cli/frame_range.h"
#include "core/image.h"

namespace crisp::cli {

const std::vector<CommandSpec>& commands() {
  static const std::vector<CommandSpec> c = {
      {"filter", "INPUT...", "filter each input in order, write OUTDIR/<input name>.exr"},
      {"compare", "", "compare test images with references: MSE, RMSE, PSNR, SNR, SSIM, perceptual error"},
      {"info", "FILE...", "list the passes in a file and, per method, the required ones that are missing"},
      {"render", "", "render 1-sample frames in Blender with the passes a method needs, filter them"},
      {"synth", "", "write the analytic test chart: 1-sample, 16x16 reference and edge mask"},
      {"eval", "", "render a scene, run every method, measure error against run time, write report.html"},
      {"bench", "[BENCHMARK ARGS...]", "run the benchmarks (crisp_bench, Google Benchmark)"},
      {"help", "[COMMAND|METHOD]", "show help for a command, or a method's parameter table"},
      {"version", "", "print the version"},
  };
  return c;
}

const std::vector<OptionSpec>& options() {
  static const std::vector<OptionSpec> o = {
      {"filter", "method", 'm', "NAME", false, true, "filter to run (see `crisp help`)"},
      {"filter", "set", 's', "KEY=VALUE", false, false, "set a filter parameter (repeatable)"},
      {"filter", "output", 'o', "OUTDIR", false, true, "output folder (created if missing)"},
      {"filter", "png", 0, nullptr, false, false, "also write a display-encoded PNG beside each EXR"},
      {"filter", "exr-depth", 0, "16|32", false, false, "bits per channel of the output EXRs, as Blender's Color Depth: 16 (half float) or 32 (default)"},
      {"filter", "exr-codec", 0, "NAME", false, false, "compression of the output EXRs, as Blender's Codec: none, zip (default), zips, piz, pxr24, rle, b44, b44a, dwaa, dwab"},
      {"filter", "frames", 0, "A-B", false, false, "write only inputs A..B (1-based positions among the inputs); a farm chunk"},
      {"filter", "preroll", 0, "N", false, false, "with --frames: first filter the N inputs before A without writing them (a temporal method's history; a spatial one skips them)"},
      {"filter", "resume", 0, nullptr, false, false, "start at the first input whose output is missing or stale (pre-roll before it; a temporal method re-reads from the chunk's first pre-roll frame)"},
      {"compare", "reference", 'r', "REF...", true, true, "reference images, paired in order with --test"},
      {"compare", "test", 't', "TEST...", true, true, "images to measure"},
      {"compare", "mask", 0, "MASK", false, false, "only count pixels where this image's first channel > 0"},
      {"compare", "json", 0, "FILE", false, false, "write per-frame and mean figures as JSON"},
      {"compare", "maps", 0, "DIR", false, false, "write per-pixel error, SSIM and perceptual-error maps, named by the test file (FOLDER_NAME where two share a name)"},
      {"render", "scene", 0, "SCENE", false, true, "a .blend file, or the name of a bundled test scene"},
      {"render", "scene-name", 0, "NAME", false, false, "the scene of a .blend to render (default: the one the file was saved with active)"},
      {"render", "frames", 0, "A-B", false, false, "frame range (default: the scene's)"},
      {"render", "preroll", 0, "N", false, false, "render and filter N frames before --frames first, write none of them"},
      {"render", "shot", 0, "A-B", false, false, "the whole shot a chunk belongs to: pre-roll stops at A, one pass plan for it (default: the scene's range)"},
      {"render", "resume", 0, nullptr, false, false, "start at the first frame whose input or filtered output is missing"},
      {"render", "method", 'm', "NAME", false, false, "filter to run on each frame (default: the .blend's Crisp panel's method if the file set it, else fxaa)"},
      {"render", "set", 's', "KEY=VALUE", false, false, "set a filter parameter (repeatable); over the .blend's Crisp panel's parameters of the method"},
      {"render", "no-panel", 0, nullptr, false, false, "ignore the .blend's Crisp panel: the command line and the library's defaults only"},
      {"render", "samples", 0, "N", false, false, "EEVEE samples of the input frames (default 1)"},
      {"render", "reference-samples", 0, "N", false, false, "also render reference frames with N samples"},
      {"render", "resolution", 0, "WxH", false, false, "override the render size"},
      {"render", "jitter", 0, "DIST", false, false, "sub-pixel jitter of the temporal methods' frames: blackman-harris (EEVEE's own pixel filter) or uniform (inside the pixel); default: the .blend's Crisp panel's if the file set it, else blackman-harris"},
      {"render", "input-codec", 0, "NAME", false, false, "OpenEXR codec of the renders kept in input/ and reference/: none (fastest), piz or zip (about 4.5x smaller, 0.1-0.2 s more a 1920x1080 frame); all lossless; default: the .blend's Crisp panel's if the file set it, else none"},
      {"render", "plan", 0, nullptr, false, false, "print the pass plan with the reason for each pass and write it to OUTDIR/run.json (not over a run's record); render nothing"},
      {"render", "blender", 0, "PATH", false, false, "Blender executable (default: blender on PATH)"},
      {"render", "output", 'o', "OUTDIR", false, true, "output folder: input/, filtered/, reference/, run.json"},
      {"synth", "output", 'o', "OUTDIR", false, true, "output folder (created if missing)"},
      {"eval", "scene", 0, "SCENE", false, true, "a .blend file, or the name of a bundled test scene (the main job uses still_life)"},
      {"eval", "scene-name", 0, "NAME", false, false, "the scene of a .blend to measure (default: the one the file was saved with active)"},
      {"eval", "frames", 0, "A-B", false, false, "frame range (default: the scene's)"},
      {"eval", "methods", 'm', "LIST", false, false, "comma-separated methods (default: every library method); none and blender-smaa are always measured; METHOD:KEY=VALUE[:KEY=VALUE...] measures a parameter setting beside the defaults (e.g. taa,taa:feedbackMin=0.8); a .blend whose Crisp panel set a method or changed its parameters adds that setting as a row of its own (unless the list has it; also when the list leaves its method out)"},
      {"eval", "no-panel", 0, nullptr, false, false, "ignore the .blend's Crisp panel: no row of its setting, and its jitter not used"},
      {"eval", "resolution", 0, "WxH", false, false, "override the render size"},
      {"eval", "warmup", 0, "N", false, false, "leave the first N frames out of the error means (a temporal method's warm-up; seed 000's static protocol: 15 of 16); they stay in the per-frame figures (default 0)"},
      {"eval", "reference-samples", 0, "N", false, false, "EEVEE samples of the reference (default 64; 256 for final figures)"},
      {"eval", "curve", 0, "LIST", false, false, "EEVEE sample counts of the curve, each below the reference's (default 1,2,4,... up to 16)"},
      {"eval", "jitter", 0, "DIST", false, false, "sub-pixel jitter of the temporal methods' input frames: blackman-harris (EEVEE's own pixel filter) or uniform (inside the pixel); default: the .blend's Crisp panel's if the file set it, else blackman-harris"},
      {"eval", "blender", 0, "PATH", false, false, "Blender executable (default: blender on PATH)"},
      {"eval", "output", 'o', "OUTDIR", false, true, "output folder: report.html, results.json/.csv, images/, renders/, methods/; rerun to resume"},
      {"synth", "size", 0, "WxH", false, false, "image size (default 320x180)"},
      {"*", "threads", 'j', "N", false, false, "worker threads (0 = all cores, default)"},
      {"*", "quiet", 'q', nullptr, false, false, "no progress output or notes (warnings, such as where a temporal history starts over, are still said)"},
      {"*", "help", 'h', nullptr, false, false, "show this help"},
  };
  return o;
}

const std::vector<std::string>& ParsedArgs::all(const std::string& name) const {
  static const std::vector<std::string> none;
  auto it = values.find(name);
  return it == values.end() ? none : it->second;
}

static const CommandSpec* findCommand(const std::string& command) {
  for (const CommandSpec& c : commands())
    if (command == c.name) return &c;
  return nullptr;
}

// Whether the command's positional arguments are files (filter's INPUT..., info's FILE...), which
// '--' lets begin with '-'.
static bool takesFiles(const std::string& command) {
  const CommandSpec* c = findCommand(command);
  return c && c->usage[0] != '\0' && c->usage[0] != '[';
}

void checkPositionals(const ParsedArgs& args) {
  const CommandSpec* c = findCommand(args.command);
  if (!c) return;  // an unknown command: main says so
  const std::string usage = c->usage;
  if (usage.find("...") != std::string::npos) return;
  if (usage.empty()) {
    if (!args.positional.empty()) throw UsageError("unexpected argument '" + args.positional.front() + "'");
  } else if (args.positional.size() > 1) {
    throw UsageError(std::string(c->name) + " takes one " + usage + "; unexpected argument '" + args.positional[1] + "'");
  }
}

static const OptionSpec* findOption(const std::string& command, const std::string& arg) {
  for (const OptionSpec& o : options()) {
    if (std::string(o.command) != command && std::string(o.command) != "*") continue;
    if (arg == std::string("--") + o.name) return &o;
    if (o.shortName && arg.size() == 2 && arg[0] == '-' && arg[1] == o.shortName) return &o;
  }
  return nullptr;
}

ParsedArgs parseArgs(const std::vector<std::string>& args) {
  ParsedArgs p;
  if (args.empty()) throw UsageError("no command given");
  p.command = args[0];
  if (p.command == "--help" || p.command == "-h") {
    p.command = "help";
    return p;
  }
  if (p.command == "--version") {
    p.command = "version";
    return p;
  }
  if (!findCommand(p.command)) throw UsageError("unknown command '" + p.command + "'");
  if (p.command == "bench") {  // everything after is for the benchmark runner
    p.positional.assign(args.begin() + 1, args.end());
    return p;
  }
  for (std::size_t i = 1; i < args.size(); ++i) {
    std::string arg = args[i];
    if (arg == "--") {  // the end of the options: what follows is positional, "-name.exr" too
      p.positional.insert(p.positional.end(), args.begin() + std::ptrdiff_t(i) + 1, args.end());
      break;
    }
    std::string inlineValue;
    bool hasInline = false;
    if (arg.rfind("--", 0) == 0 && arg.find('=') != std::string::npos) {
      inlineValue = arg.substr(arg.find('=') + 1);
      arg = arg.substr(0, arg.find('='));
      hasInline = true;
    }
    if (arg.size() > 1 && arg[0] == '-' && !(arg.size() > 1 && (std::isdigit(static_cast<unsigned char>(arg[1])) || arg[1] == '.'))) {
      const OptionSpec* o = findOption(p.command, arg);
      if (!o) {
        throw UsageError("unknown option '" + arg + "' for '" + p.command + "'" +
                         (takesFiles(p.command) ? " (a file whose name begins with '-' goes after '--')" : ""));
      }
      auto& vals = p.values[o->name];
      if (!o->valueName) {
        if (hasInline) throw UsageError("option '" + arg + "' takes no value");
        vals.push_back("");
        continue;
      }
      if (hasInline) {
        vals.push_back(inlineValue);
      } else if (o->multi) {
        std::size_t before = vals.size();
        while (i + 1 < args.size() && args[i + 1] != "--" &&
               !(args[i + 1].size() > 1 && args[i + 1][0] == '-' && findOption(p.command, args[i + 1].substr(0, args[i + 1].find('=')))))
          vals.push_back(args[++i]);
        if (vals.size() == before) throw UsageError("option '" + arg + "' needs at least one " + o->valueName);
      } else {
        if (i + 1 >= args.size()) throw UsageError("option '" + arg + "' needs a value " + o->valueName);
        vals.push_back(args[++i]);
      }
      if (!o->multi && std::string(o->name) != "set" && vals.size() > 1)
        throw UsageError("option '--" + std::string(o->name) + "' given more than once");
    } else {
      p.positional.push_back(args[i]);
    }
  }
  if (!p.has("help"))
    for (const OptionSpec& o : options())
      if (o.required && std::string(o.command) == p.command && !p.has(o.name))
        throw UsageError("'" + p.command + "' needs --" + std::string(o.name) + " " + o.valueName);
  return p;
}

std::string helpText(const std::string& command) {
  std::ostringstream s;
  if (command.empty()) {
    s << "crisp: anti-aliasing filters for 1-sample Blender renders\n\nUsage: crisp COMMAND [OPTIONS]\n\nCommands:\n";
    for (const CommandSpec& c : commands()) s << "  " << c.name << std::string(10 - std::string(c.name).size(), ' ') << c.summary << "\n";
    s << "\n`crisp help COMMAND` shows a command's options; `crisp help METHOD` a method's parameters.\n";
    return s.str();
  }
  for (const CommandSpec& c : commands()) {
    if (command != c.name) continue;
    s << "Usage: crisp " << c.name << " [OPTIONS] " << c.usage << "\n  " << c.summary << "\n\nOptions:\n";
    for (const OptionSpec& o : options()) {
      if (std::string(o.command) != command && std::string(o.command) != "*") continue;
      std::string flag = o.shortName ? std::string("-") + o.shortName + ", " : "    ";
      flag += std::string("--") + o.name;
      if (o.valueName) flag += std::string(" ") + o.valueName;
      s << "  " << flag << std::string(flag.size() < 26 ? 26 - flag.size() : 1, ' ') << o.help
        << (o.required ? " (required)" : "") << "\n";
    }
    if (takesFiles(command))
      s << "      --" << std::string(20, ' ') << "the end of the options: what follows is " << c.usage
        << ", also a name beginning with '-'\n";
    return s.str();
  }
  return "";
}

int parseIntOption(const ParsedArgs& a, const std::string& name, int fallback, int lo, int hi) {
  if (!a.has(name)) return fallback;
  const std::string& v = a.get(name);
  char* end = nullptr;
  long x = std::strtol(v.c_str(), &end, 10);
  if (v.empty() || *end || x < lo || x > hi)
    throw UsageError("--" + name + " expects a whole number in [" + std::to_string(lo) + ", " + std::to_string(hi) +
                     "], got '" + v + "'");
  return int(x);
}

std::string lowerCase(std::string text) {
  std::transform(text.begin(), text.end(), text.begin(), [](unsigned char c) { return char(std::tolower(c)); });
  return text;
}

namespace {
constexpr int kLowestResolution = 4;  // Blender's smallest render size; the largest is the library's (kMaxDimension)

bool parseResolution(const std::string& r, int& w, int& h) {
  const std::string lower = lowerCase(r);
  int consumed = 0;
  return std::sscanf(lower.c_str(), "%dx%d%n", &w, &h, &consumed) == 2 && consumed == int(r.size()) &&
         w >= kLowestResolution && h >= kLowestResolution && w <= kMaxDimension && h <= kMaxDimension;
}
}  // namespace

void checkResolutionOption(const ParsedArgs& a) {
  if (!a.has("resolution")) return;
  const std::string& r = a.get("resolution");
  int w = 0, h = 0;
  if (!parseResolution(r, w, h))
    throw UsageError("bad --resolution '" + r + "' (expected WxH, each " + std::to_string(kLowestResolution) + " to " +
                     std::to_string(kMaxDimension) + ", e.g. 480x270)");
}

std::string canonicalResolution(const std::string& text) {
  int w = 0, h = 0;
  return parseResolution(text, w, h) ? std::to_string(w) + "x" + std::to_string(h) : text;
}

void checkBlenderFrameRangeOption(const ParsedArgs& a, const std::string& name) {
  if (a.has(name)) parseFrameRange(name, a.get(name), kBlenderLowestFrame);
}

}  // namespace crisp::cli
