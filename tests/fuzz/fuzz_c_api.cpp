// SPDX-License-Identifier: Apache-2.0
// Fuzzes the C API: bytes drive a sequence of calls with arbitrary names,
// values, sizes and strides (buffers always as large as the views declare).
// Now and then the output is set in place, on the colour image's own view.
// Any sequence must end in results or recorded errors, never a crash; an
// execute that reports no error leaves every value of the output it was given
// finite (crisp.h; fuzz_filters.cpp checks the other filters); and a sequence
// that ran with the output in place writes the same values when run again with
// the output apart (crisp.h; fuzz_common.h's checkInPlace). seeds() below
// writes inputs that reach the output in place for each filter at once
// (fuzz_common.h's writeSeedsIfAsked; scripts/test.sh starts from them).
#include <cstdint>
#include <cstring>
#include <string>
#include <vector>

#include "crisp/crisp.h"
#include "fuzz_common.h"

namespace {

using crisp_fuzz::Reader;

// The filters made: those the fuzz build instruments with ASan + UBSan
// (native/CMakeLists.txt, CRISP_FUZZ); fuzz_filters.cpp runs the others.
const std::vector<std::string> kTypes = {"none", "fxaa", "repair", "bogus", ""};
const std::vector<std::string> kImages = {"color", "output", "depth", "normal", "motion", "id", "albedo", "x"};
const std::vector<std::string> kParams = {"kappa", "patchSize", "mask", "edgeThreshold", "edgeThresholdMin",
                                          "subpix", "reference", "angleEstimator", "nope"};
const std::vector<std::string> kStrings = {"gauss5", "box3", "regression", "thesis", "", "zzz"};

// What a step does: its byte modulo kOps (the seeds write these).
enum Op : int {
  kImage = 0,  // and 1: a buffer of bytes' values, set as an image of a name
  kFloat = 2,
  kInt,
  kString,
  kBool,
  kCommit,
  kExecute,
  kInPlace,  // the output on the colour's own view
  kOps
};

// The floats of the buffer made for an image of w x h in format fmt, strides px and row in bytes (0 =
// packed, as crisp.h says): as many as the view covers, and one more. The bytes give them, 4 a value.
std::size_t bufferFloats(int w, int h, int fmt, std::size_t px, std::size_t row) {
  const int ch = fmt >= 1 && fmt <= 4 ? fmt : 1;
  const std::size_t pixelBytes = px ? px : std::size_t(ch) * 4;
  const std::size_t rowBytes = row ? row : pixelBytes * std::size_t(w);
  return (rowBytes * std::size_t(h - 1) + pixelBytes * std::size_t(w - 1) + std::size_t(ch) * 4) / 4 + 1;
}

// An image the filter took: the buffer and the arguments it was set with.
struct Set {
  std::size_t buffer = 0;
  CrispFormat format = CRISP_FORMAT_UNDEFINED;
  int w = 0, h = 0;
  std::size_t px = 0, row = 0;
};

// One run of the sequence the bytes make (crisp_fuzz::checkInPlace). `apart`: the output the bytes put
// in the colour's buffer gets a buffer of its own of the same layout instead, and after each execute
// the colour's buffer gets what the execute wrote, as in the run in place.
void run(const std::uint8_t* data, std::size_t size, bool apart, crisp_fuzz::Trace& trace) {
  Reader r{data, size};
  CrispContext ctx = crispNewContext();
  crispSetContextInt(ctx, "numThreads", 1 + r.byte() % 2);
  trace.filter = r.pick(kTypes);
  CrispFilter f = crispNewFilter(ctx, trace.filter.c_str());
  std::vector<std::vector<float>> buffers;  // a moved vector keeps its data: `output` stays valid
  std::vector<std::vector<float>> apartOutputs;  // apart: the outputs' own (kept out of the compared `buffers`)
  crisp_fuzz::OutputView output;
  bool hasColor = false;
  Set color;  // the "color" the filter holds, if hasColor
  float* shared = nullptr;  // the colour's buffer the output is in (apart: would be in), or none
  auto executed = [&](bool ok) {
    crisp_fuzz::recordExecute(trace, ok, output, apart ? shared : nullptr);
    // In place: the output's buffer is the colour the filter still holds (a later colour ends it).
    if (ok && output && shared && hasColor && shared == buffers[color.buffer].data()) trace.inPlace = true;
  };
  for (int step = 0; step < 24 && r.n; ++step) {
    switch (r.byte() % kOps) {
      case kImage:
      case kImage + 1: {
        int w = 1 + r.byte() % 24, h = 1 + r.byte() % 24;
        int fmt = r.byte() % 7;
        std::size_t px = (r.byte() % 5) * 4, row = (r.byte() % 3) * 4 * std::size_t(w + 1);
        std::vector<float> buf(bufferFloats(w, h, fmt, px, row));
        for (auto& v : buf) v = r.n ? r.number() : 0.5f;
        buffers.push_back(std::move(buf));
        const std::string name = r.pick(kImages);
        if (crisp_fuzz::setImage(f, name.c_str(), buffers.back().data(), CrispFormat(fmt), w, h, px, row,
                                 &output)) {
          if (name == "color") hasColor = true, color = {buffers.size() - 1, CrispFormat(fmt), w, h, px, row};
          if (name == "output") shared = nullptr;
        }
        break;
      }
      case kFloat: crispSetFilterFloat(f, r.pick(kParams).c_str(), r.number()); break;
      case kInt: crispSetFilterInt(f, r.pick(kParams).c_str(), int(r.byte()) - 8); break;
      case kString: crispSetFilterString(f, r.pick(kParams).c_str(), r.pick(kStrings).c_str()); break;
      case kBool: crispSetFilterBool(f, r.pick(kParams).c_str(), r.byte() & 1); break;
      case kCommit: crispCommitFilter(f); break;
      case kExecute: executed(crisp_fuzz::execute(f, output)); break;
      case kInPlace: {  // the output in place: the colour's own view (crisp.h: the result is the same)
        if (!hasColor) break;
        float* target = buffers[color.buffer].data();
        if (apart) {  // the same layout, filled without reading a byte: both runs read the same bytes
          apartOutputs.emplace_back(buffers[color.buffer].size(), -1234.5f);  // an unwritten value shows
          target = apartOutputs.back().data();
        }
        if (crisp_fuzz::setImage(f, "output", target, color.format, std::size_t(color.w), std::size_t(color.h),
                                 color.px, color.row, &output))
          shared = buffers[color.buffer].data();
        break;
      }
    }
    crispGetError(nullptr);
  }
  crisp_fuzz::finish(ctx, f, output, executed);  // its execute compared too: a set and the end suffice
  for (const auto& b : buffers) trace.buffers.push_back(b);
}

// ---- seeds (fuzz_common.h's writeSeedsIfAsked) ----------------------------------------------------------
// For each filter: a colour image of a few pixels with a staircase edge (what fxaa and repair change), the
// output on its buffer, a commit and two executes (with finish's, three: each after the first reads what
// the one before wrote), on one thread and two, packed and padded, fast and reference paths; and the same
// with the output apart. libFuzzer mutates them from the start of the 30 s.

struct SeedImage {
  int w = 8, h = 6;
  CrispFormat format = CRISP_FORMAT_FLOAT4;
  int pxUnits = 0;  // the pixel stride: pxUnits * 4 bytes (0 = packed), as kImage reads it
};

// kImage: an image of `image`'s layout named `name`, its pixels a staircase edge of bright and dark,
// tinted per channel, alpha (4 channels) varied below 1; padding 0.25.
void writeImage(crisp_fuzz::Writer& out, const SeedImage& image, const std::string& name) {
  out.byte(kImage);
  out.byte(image.w - 1);
  out.byte(image.h - 1);
  out.byte(int(image.format));
  out.byte(image.pxUnits);
  out.byte(0);  // packed rows
  const int ch = int(image.format);
  const std::size_t pixelFloats = image.pxUnits ? std::size_t(image.pxUnits) : std::size_t(ch);
  std::vector<float> values(bufferFloats(image.w, image.h, ch, pixelFloats * 4, 0), 0.25f);
  for (int y = 0; y < image.h; ++y)
    for (int x = 0; x < image.w; ++x)
      for (int c = 0; c < ch; ++c) {
        const bool bright = (2 * x + 3 * y) % 9 < 4;
        float v = (bright ? 0.9f : 0.05f) + 0.03f * float(c) + 0.01f * float((x * 7 + y * 5 + c) % 4);
        if (c == 3) v = 1.0f - 0.125f * float((x + y) % 3);
        values[(std::size_t(y) * std::size_t(image.w) + std::size_t(x)) * pixelFloats + std::size_t(c)] = v;
      }
  for (float v : values) out.number(v);
  out.pick(kImages, name);
}

// A seed: `threads` threads, filter `type`, a colour of `image`'s layout, `reference` set if asked, then the
// output on the colour's buffer (inPlace) or an image of its own of the same layout, a commit and two
// executes.
crisp_fuzz::Seed seed(const std::string& name, const std::string& type, int threads, const SeedImage& image,
                      bool reference, bool inPlace) {
  crisp_fuzz::Writer out;
  out.byte(threads - 1);
  out.pick(kTypes, type);
  writeImage(out, image, "color");
  if (reference) {
    out.byte(kBool);
    out.pick(kParams, "reference");
    out.byte(1);
  }
  if (inPlace)
    out.byte(kInPlace);
  else
    writeImage(out, image, "output");
  out.byte(kCommit);
  out.byte(kExecute);
  out.byte(kExecute);
  return {name, out.bytes, type, inPlace, 3};
}

std::vector<crisp_fuzz::Seed> seeds() {
  const SeedImage packed;                                          // 8x6 RGBA
  const SeedImage padded{7, 5, CRISP_FORMAT_FLOAT3, 4};            // RGB in 16-byte pixels
  const SeedImage small{3, 2, CRISP_FORMAT_FLOAT4, 0};             // smaller than repair's patch
  std::vector<crisp_fuzz::Seed> all;
  for (const std::string type : {"none", "fxaa", "repair"}) {
    all.push_back(seed(type + "-in-place", type, 1, packed, false, true));
    all.push_back(seed(type + "-in-place-rgb-padded-2-threads", type, 2, padded, false, true));
    all.push_back(seed(type + "-apart", type, 1, packed, false, false));
  }
  for (const std::string type : {"fxaa", "repair"}) {
    all.push_back(seed(type + "-in-place-reference", type, 1, packed, true, true));
    all.push_back(seed(type + "-in-place-small", type, 1, small, false, true));
  }
  return all;
}

}  // namespace

extern "C" int LLVMFuzzerInitialize(int*, char***) {
  crisp_fuzz::writeSeedsIfAsked("fuzz_c_api", seeds(), run);
  return 0;
}

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  crisp_fuzz::checkInPlace("fuzz_c_api",
                           [&](bool apart, crisp_fuzz::Trace& trace) { run(data, size, apart, trace); });
  return 0;
}
