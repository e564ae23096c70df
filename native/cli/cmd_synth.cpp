// SPDX-License-Identifier: Apache-2.0
// crisp synth -o OUTDIR [--size WxH]: the analytic test chart as files, so the
// filters can be tried and measured without Blender.
#include <cstdio>

#include "cli/commands.h"
#include "synth/synthetic.h"

namespace crisp::cli {

int runSynth(const ParsedArgs& args) {
  int w = 320, h = 180;
  if (args.has("size")) {
    const std::string& s = args.get("size");
    char x = 0;
    char extra = 0;
    if (std::sscanf(s.c_str(), "%d%c%d%c", &w, &x, &h, &extra) != 3 || x != 'x' || w < 1 || h < 1 || w > 16384 || h > 16384)
      throw UsageError("--size expects WxH with 1..16384 each, got '" + s + "'");
  }
  const std::string dir = args.get("output");
  const RunFolder folder(dir);  // a run that fails leaves no folder it made behind
  const char* names[] = {"chart_1spp.exr", "chart_1spp.png", "chart_reference.exr", "chart_reference.png", "chart_edges.exr"};
  for (const char* name : names) checkOutputFile(joinPath(dir, name));  // a folder in a file's way: said before any write
  synth::Scene chart = synth::testChart(w, h);
  Image one = synth::renderCentre(chart, w, h);
  Image ref = synth::renderSupersampled(chart, w, h, 16);
  Image mask = synth::edgePixels(chart, w, h, 16);
  Image maskRgb(w, h, 3);
  for (std::size_t i = 0; i < mask.data.size(); ++i) maskRgb.data[3 * i] = maskRgb.data[3 * i + 1] = maskRgb.data[3 * i + 2] = mask.data[i];
  const Image* images[] = {&one, &one, &ref, &ref, &maskRgb};
  for (int i = 0; i < 5; ++i) writeImage(joinPath(dir, names[i]), *images[i]);
  std::printf("wrote %s/chart_1spp.exr/.png, chart_reference.exr/.png (16x16 supersampled, box), chart_edges.exr (%dx%d)\n",
              dir.c_str(), w, h);
  return 0;
}

}  // namespace crisp::cli
