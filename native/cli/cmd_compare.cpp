// SPDX-License-Identifier: Apache-2.0
// crisp compare --reference REF... --test TEST... [--mask M] [--json FILE] [--maps DIR]
#include <cstdio>
#include <filesystem>
#include <map>
#include <optional>
#include <set>
#include <sstream>
#include <vector>

#include "cli/commands.h"
#include "cli/progress.h"
#include "core/error.h"
#include "metrics/metrics.h"

namespace crisp::cli {

namespace {

namespace fs = std::filesystem;

constexpr const char* kMapSuffixes[] = {".error.exr", ".ssim.exr", ".flip.exr", ".flip.png"};

// The name each --test file's maps take in --maps: its stem, or where two tests share a stem (the
// usual "two methods, one frame" comparison) its folder's name and stem, or failing that the
// stem and its position.
std::vector<std::string> mapStems(const std::vector<std::string>& tests) {
  auto unique = [](const std::vector<std::string>& names) {
    return std::set<std::string>(names.begin(), names.end()).size() == names.size();
  };
  std::vector<std::string> stems, qualified, numbered;
  for (std::size_t i = 0; i < tests.size(); ++i) {
    stems.push_back(fileStem(tests[i]));
    const std::string folder = fs::absolute(tests[i]).parent_path().filename().string();
    qualified.push_back(folder + "_" + stems.back());
    numbered.push_back(stems.back() + "_" + std::to_string(i + 1));
  }
  return unique(stems) ? stems : unique(qualified) ? qualified : numbered;
}

// Refuses, before anything is written, a map or --json file that is an input file.
void refuseClobbering(const ParsedArgs& args, const std::string& mapsDir, const std::vector<std::string>& stems) {
  std::set<fs::path> inputs;
  std::error_code ec;
  for (const char* option : {"reference", "test", "mask"})
    for (const std::string& in : args.all(option)) inputs.insert(fs::weakly_canonical(in, ec));
  auto refuse = [&](const std::string& out, const std::string& what) {
    if (inputs.count(fs::weakly_canonical(out, ec)))
      throw UsageError(what + " '" + out + "' is an input file; choose another");
  };
  if (args.has("json")) refuse(args.get("json"), "--json");
  if (mapsDir.empty()) return;
  for (const std::string& stem : stems)
    for (const char* suffix : kMapSuffixes) refuse(joinPath(mapsDir, stem + suffix), "map");
}

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

// Files are paired in the order given. A reference paired with a test of another name while a test
// of its own name is given elsewhere (a sequence listed in another order, or one frame missing
// from each list) is most often a mistake: said, not refused (comparing frame N with N+1 is a use).
void warnCrossedPairs(const std::vector<std::string>& refs, const std::vector<std::string>& tests) {
  std::map<std::string, std::size_t> testAt;
  for (std::size_t i = 0; i < tests.size(); ++i) testAt.emplace(fileStem(tests[i]), i);
  std::size_t crossed = 0;
  std::string first;
  for (std::size_t i = 0; i < refs.size(); ++i) {
    const std::string stem = fileStem(refs[i]);
    const auto same = testAt.find(stem);
    if (stem == fileStem(tests[i]) || same == testAt.end()) continue;
    if (crossed++ == 0)
      first = "reference '" + refs[i] + "' is paired with test '" + tests[i] + "', though test '" +
              tests[same->second] + "' has its name";
  }
  if (crossed > 0)
    std::fprintf(stderr, "compare: warning: files are paired in the order given: %s (%zu such pair%s)\n",
                 first.c_str(), crossed, crossed == 1 ? "" : "s");
}

}  // namespace

int runCompare(const ParsedArgs& args) {
  const auto& refs = args.all("reference");
  const auto& tests = args.all("test");
  if (refs.size() != tests.size())
    throw UsageError("--reference has " + std::to_string(refs.size()) + " files but --test has " +
                     std::to_string(tests.size()) + "; they are paired in order");
  const int threads = parseIntOption(args, "threads", 0, 0, 1024);
  warnCrossedPairs(refs, tests);
  Image mask;
  if (args.has("mask")) mask = readMask(args.get("mask"));
  const std::string mapsDir = args.getOr("maps", "");
  const std::vector<std::string> stems = mapStems(tests);
  refuseClobbering(args, mapsDir, stems);
  // The maps' folder first, so that --json may name a file in it; made by RunFolder, so that a
  // run that fails leaves no empty folder behind.
  std::optional<RunFolder> mapsFolder;
  if (!mapsDir.empty()) mapsFolder.emplace(mapsDir);
  if (args.has("json")) checkOutputFile(args.get("json"));  // written last: said now, not after every frame

  std::vector<Metrics> all;
  std::ostringstream frames;
  Progress progress("compare", int(refs.size()), args.has("quiet"));
  std::printf("%-28s %-28s %10s %9s %9s %8s %8s\n", "reference", "test", "mse", "psnr", "snr", "ssim", "flip");
  for (std::size_t i = 0; i < refs.size(); ++i) {
    Frame ref = readFrame(refs[i]);
    Frame tst = readFrame(tests[i]);
    for (const Frame* f : {&ref, &tst})
      if (f->nonFiniteColour > 0)
        invalidData("'" + f->path + "' has " + std::to_string(f->nonFiniteColour) +
                    " non-finite colour values (NaN or Inf): it has no error to measure, only the values they are "
                    "read as (0, +-65504)");
    Image errMap, ssimMap, flipMap;
    MetricMaps maps;
    if (!mapsDir.empty()) maps = {&errMap, &ssimMap, &flipMap};
    Metrics m;
    try {
      m = compareImages(ref.pass("color"), tst.pass("color"), args.has("mask") ? &mask : nullptr, maps, threads);
    } catch (const Exception& e) {
      // The mask can be what is wrong (its size, no pixel selected): named too.
      const std::string with = args.has("mask") ? " under mask '" + args.get("mask") + "'" : "";
      throw Exception(e.code(), "comparing '" + tests[i] + "' with '" + refs[i] + "'" + with + ": " + e.what());
    }
    all.push_back(m);
    std::printf("%-28.28s %-28.28s %10.3e %9.3f %9.3f %8.5f %8.5f\n", fileStem(refs[i]).c_str(),
                fileStem(tests[i]).c_str(), m.mse, m.psnr, m.snr, m.ssim, m.flip);
    frames << (i ? ",\n    " : "\n    ") << "{\"reference\": " << jsonQuote(refs[i]) << ", \"test\": " << jsonQuote(tests[i])
           << ", " << figuresJson(m) << ", \"pixels\": " << m.pixels;
    if (!mapsDir.empty()) frames << ", \"maps\": " << jsonQuote(joinPath(mapsDir, stems[i]));
    frames << "}";
    if (!mapsDir.empty()) {
      const std::string base = joinPath(mapsDir, stems[i]);
      const Image* images[] = {&errMap, &ssimMap, &flipMap, &flipMap};
      for (int k = 0; k < 4; ++k) writeMap(base + kMapSuffixes[k], *images[k]);
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
