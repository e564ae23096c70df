// SPDX-License-Identifier: Apache-2.0
// crisp compare --reference REF... --test TEST... [--mask M] [--json FILE] [--maps DIR]
#include <cstdio>
#include <sstream>

#include "cli/commands.h"
#include "cli/progress.h"
#include "core/error.h"
#include "metrics/metrics.h"

namespace crisp::cli {

namespace {

void writeMap(const std::string& path, const Image& map) {
  // Single-channel maps are written as grey RGB so any viewer shows them.
  Image rgb(map.width, map.height, 3);
  for (std::size_t i = 0; i < map.data.size(); ++i)
    for (int c = 0; c < 3; ++c) rgb.data[i * 3 + c] = map.data[i];
  writeImage(path, rgb);
}

std::string figuresJson(const Metrics& m) {
  std::ostringstream s;
  s << "\"mse\": " << jsonNumber(m.mse) << ", \"rmse\": " << jsonNumber(m.rmse) << ", \"psnr\": " << jsonNumber(m.psnr)
    << ", \"snr\": " << jsonNumber(m.snr) << ", \"ssim\": " << jsonNumber(m.ssim) << ", \"flip\": " << jsonNumber(m.flip);
  return s.str();
}

}  // namespace

int runCompare(const ParsedArgs& args) {
  const auto& refs = args.all("reference");
  const auto& tests = args.all("test");
  if (!args.positional.empty()) throw UsageError("unexpected argument '" + args.positional.front() + "'");
  if (refs.size() != tests.size())
    throw UsageError("--reference has " + std::to_string(refs.size()) + " files but --test has " +
                     std::to_string(tests.size()) + "; they are paired in order");
  const int threads = parseIntOption(args, "threads", 0, 0, 1024);
  Image mask;
  if (args.has("mask")) {
    Frame m = readFrame(args.get("mask"));
    const Image& c = m.pass("color");
    mask = Image(c.width, c.height, 1);
    for (int y = 0; y < c.height; ++y)
      for (int x = 0; x < c.width; ++x) *mask.at(x, y) = c.at(x, y)[0];
  }
  const std::string mapsDir = args.getOr("maps", "");
  if (!mapsDir.empty()) makeDirectories(mapsDir);

  std::vector<Metrics> all;
  std::ostringstream frames;
  Progress progress("compare", int(refs.size()), args.has("quiet"));
  std::printf("%-28s %-28s %10s %9s %9s %8s %8s\n", "reference", "test", "mse", "psnr", "snr", "ssim", "flip");
  for (std::size_t i = 0; i < refs.size(); ++i) {
    Frame ref = readFrame(refs[i]);
    Frame tst = readFrame(tests[i]);
    Image errMap, ssimMap, flipMap;
    MetricMaps maps;
    if (!mapsDir.empty()) maps = {&errMap, &ssimMap, &flipMap};
    Metrics m;
    try {
      m = compareImages(ref.pass("color"), tst.pass("color"), args.has("mask") ? &mask : nullptr, maps, threads);
    } catch (const Exception& e) {
      throw Exception(e.code(), "comparing '" + tests[i] + "' with '" + refs[i] + "': " + e.what());
    }
    all.push_back(m);
    std::printf("%-28.28s %-28.28s %10.3e %9.3f %9.3f %8.5f %8.5f\n", fileStem(refs[i]).c_str(),
                fileStem(tests[i]).c_str(), m.mse, m.psnr, m.snr, m.ssim, m.flip);
    frames << (i ? ",\n    " : "\n    ") << "{\"reference\": " << jsonQuote(refs[i]) << ", \"test\": " << jsonQuote(tests[i])
           << ", " << figuresJson(m) << ", \"pixels\": " << m.pixels << "}";
    if (!mapsDir.empty()) {
      const std::string base = joinPath(mapsDir, fileStem(tests[i]));
      writeMap(base + ".error.exr", errMap);
      writeMap(base + ".ssim.exr", ssimMap);
      writeMap(base + ".flip.exr", flipMap);
      writeMap(base + ".flip.png", flipMap);
    }
    progress.step(fileStem(tests[i]));
  }
  // Means over frames (PSNR/SNR: mean of the per-frame dB values, as in the
  // source documents' per-frame plots; mse is the plain mean).
  Metrics mean;
  for (const Metrics& m : all) {
    mean.mse += m.mse / all.size();
    mean.rmse += m.rmse / all.size();
    mean.psnr += m.psnr / all.size();
    mean.snr += m.snr / all.size();
    mean.ssim += m.ssim / all.size();
    mean.flip += m.flip / all.size();
  }
  std::printf("%-57s %10.3e %9.3f %9.3f %8.5f %8.5f\n", "mean", mean.mse, mean.psnr, mean.snr, mean.ssim, mean.flip);
  if (args.has("json")) {
    std::ostringstream j;
    j << "{\n  \"encoding\": \"sRGB of linear clamped to [0,1]\",\n  \"frames\": [" << frames.str() << "\n  ],\n  \"mean\": {"
      << figuresJson(mean) << "}\n}\n";
    writeTextFile(args.get("json"), j.str());
  }
  return 0;
}

}  // namespace crisp::cli
