// SPDX-License-Identifier: Apache-2.0
// Reading a frame (io/frame.h readFrame, what crispLoadFrame and `crisp filter` do per frame): an
// uncompressed multilayer EXR as the add-on's renders are, with colour and depth (taa) or also
// object IDs and albedo (taa-improved). The files are written once per size to the temporary folder,
// so the page cache holds them: the time is decoding and conversion, not the disk.
#include <benchmark/benchmark.h>
#include <unistd.h>

#include <cmath>
#include <filesystem>
#include <map>
#include <memory>
#include <string>
#include <vector>

#include <OpenImageIO/imageio.h>

#include "bench_common.h"
#include "io/frame.h"

namespace {

namespace bench = crisp::bench;
namespace fs = std::filesystem;

// The test files, removed when the program ends.
struct Files {
  std::map<std::string, std::string> paths;
  ~Files() {
    std::error_code ec;
    for (const auto& kv : paths) fs::remove(kv.second, ec);
  }
};

const std::string& blenderExr(int width, int height, bool allPasses) {
  static Files files;
  const std::string key = std::to_string(width) + "x" + std::to_string(height) + (allPasses ? "_all" : "");
  auto it = files.paths.find(key);
  if (it != files.paths.end()) return it->second;
  std::vector<std::string> names = {"ViewLayer.Combined.R", "ViewLayer.Combined.G", "ViewLayer.Combined.B",
                                    "ViewLayer.Combined.A", "ViewLayer.Depth.Z"};
  if (allPasses)
    for (const char* n : {"ViewLayer.CryptoObject00.r", "ViewLayer.CryptoObject00.g", "ViewLayer.CryptoObject00.b",
                          "ViewLayer.CryptoObject00.a", "ViewLayer.DiffCol.R", "ViewLayer.DiffCol.G",
                          "ViewLayer.DiffCol.B"})
      names.push_back(n);
  const int channels = int(names.size());
  std::vector<float> pixels(std::size_t(width) * std::size_t(height) * std::size_t(channels));
  for (std::size_t i = 0; i < pixels.size(); ++i) pixels[i] = 0.5f + 0.5f * std::sin(0.001f * float(i));
  OIIO::ImageSpec spec(width, height, channels, OIIO::TypeFloat);
  spec.channelnames = names;
  spec.attribute("compression", "none");
  const std::string path =
      (fs::temp_directory_path() / ("crisp_bench_frame_" + std::to_string(::getpid()) + "_" + key + ".exr")).string();
  auto out = OIIO::ImageOutput::create(path);
  if (!out || !out->open(path, spec) || !out->write_image(OIIO::TypeFloat, pixels.data()) || !out->close())
    throw std::runtime_error("cannot write the benchmark's frame " + path);
  return files.paths[key] = path;
}

void readFrame(benchmark::State& state, int width, int height, bool allPasses) {
  const std::string& path = blenderExr(width, height, allPasses);
  for (auto _ : state) {
    crisp::Frame frame = crisp::readFrame(path);
    benchmark::DoNotOptimize(frame.passes.begin()->second.data.data());
  }
  bench::setPixelRate(state, width, height);
}

void registerAll() {
  for (const auto& s : bench::kSizes) {
    const int w = s[0], h = s[1];
    for (const bool all : {false, true}) {
      const std::string name =
          std::string("io.read_frame.") + (all ? "color_depth_id_albedo" : "color_depth") + bench::sizeTag(w, h);
      bench::registerTimed(name, [w, h, all](benchmark::State& st) { readFrame(st, w, h, all); });
    }
  }
}

const bool registered = (registerAll(), true);

}  // namespace
