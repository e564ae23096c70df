// SPDX-License-Identifier: Apache-2.0
// crisp info FILE...: the passes in each file, and per method what is missing,
// checked as `crisp filter` checks it (rsaa: its sidecar and sub-sample files too).
#include <cstdio>
#include <cstring>

#include "cli/commands.h"
#include "core/error.h"
#include "core/filter.h"
#include "io/subsamples.h"

namespace crisp::cli {

int runInfo(const ParsedArgs& args) {
  if (args.positional.empty()) throw UsageError("'info' needs at least one FILE");
  Context context;
  int failed = 0;
  for (const std::string& path : args.positional) {
    // A file that cannot be read is reported, and the others still are.
    Frame frame;
    try {
      frame = readFrame(path);
    } catch (const Exception& e) {
      std::printf("%s\n  error: %s\n", path.c_str(), e.what());
      ++failed;
      continue;
    }
    std::printf("%s\n  size: %dx%d\n  channels:", path.c_str(), frame.width, frame.height);
    for (const std::string& c : frame.channelNames) std::printf(" %s", c.c_str());
    std::printf("\n  passes: %s\n", frame.passList().c_str());
    if (!frame.layersNotRead.empty()) std::printf("  layer read: '%s'\n", frame.layer.c_str());
    for (const std::string& layer : frame.layersNotRead) std::printf("  not read: layer %s\n", layer.c_str());
    for (const std::string& part : frame.partsNotRead) std::printf("  not read: %s\n", part.c_str());
    if (frame.nonFiniteColour > 0)  // as crisp filter warns and crisp compare refuses
      std::printf("  non-finite colour values: %ld, read as 0 (NaN) or +-65504 (Inf)\n", frame.nonFiniteColour);
    if (frame.clampedColour > 0)
      std::printf("  colour values beyond +-65504: %ld, read as +-65504\n", frame.clampedColour);
    for (const auto& [role, why] : frame.unusable) std::printf("  unusable: %s (%s)\n", role.c_str(), why.c_str());
    if (!frame.objectIds.empty()) {
      std::printf("  objects (cryptomatte):");
      for (const auto& [name, hash] : frame.objectIds) std::printf(" %s=%08x", name.c_str(), unsigned(hash));
      std::printf("\n");
    }
    std::printf("  methods:\n");
    for (const std::string& type : filterTypes()) {
      auto filter = createFilter(context, type);
      std::string missing, optional;
      const bool subsamples = readsSubsamples(*filter);
      for (const ImageRole& r : filter->roles()) {
        if (std::string(r.name) == "output" || frame.has(r.name)) continue;
        if (frame.unusable.count(r.name)) {  // crisp filter refuses it (cli/files.cpp bindFrame)
          missing += std::string(" ") + r.name + " (unusable)";
          continue;
        }
        // rsaa's sub-samples come from the files its sidecar names, checked below.
        if (subsamples && (std::strcmp(r.name, kPackedSubsamplePass) == 0 || std::strncmp(r.name, "sub", 3) == 0))
          continue;
        (r.required ? missing : optional) += std::string(" ") + r.name;
      }
      if (subsamples) {
        try {
          attachRsaaInputs(*filter, frame);
        } catch (const Exception& e) {
          missing += std::string(" sub-samples (") + e.what() + ")";
        }
      }
      std::printf("    %-14s %s%s%s\n", type.c_str(), missing.empty() ? "ready" : ("missing:" + missing).c_str(),
                  optional.empty() ? "" : "; optional, absent:", optional.c_str());
    }
  }
  if (failed > 0)
    throw Exception(CRISP_ERROR_INVALID_DATA, std::to_string(failed) + " of " +
                                                  std::to_string(args.positional.size()) + " files could not be read");
  return 0;
}

}  // namespace crisp::cli
