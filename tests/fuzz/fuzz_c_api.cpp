// SPDX-License-Identifier: Apache-2.0
// Fuzzes the C API: bytes drive a sequence of calls with arbitrary names,
// values, sizes and strides (buffers always as large as the views declare).
// Now and then the output is set in place, on the colour image's own view.
// Any sequence must end in results or recorded errors, never a crash; an
// execute that reports no error leaves every value of the output it was given
// finite (crisp.h; fuzz_filters.cpp checks the other filters); and a sequence
// that ran with the output in place writes the same values when run again with
// the output apart (crisp.h; fuzz_common.h's checkInPlace).
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
  CrispFilter f = crispNewFilter(ctx, r.pick(kTypes).c_str());
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
    switch (r.byte() % 9) {
      case 0:
      case 1: {
        int w = 1 + r.byte() % 24, h = 1 + r.byte() % 24;
        int fmt = r.byte() % 7;
        std::size_t px = (r.byte() % 5) * 4, row = (r.byte() % 3) * 4 * std::size_t(w + 1);
        int ch = fmt >= 1 && fmt <= 4 ? fmt : 1;
        std::size_t pixelBytes = px ? px : std::size_t(ch) * 4;
        std::size_t rowBytes = row ? row : pixelBytes * w;
        std::size_t floats = (rowBytes * (h - 1) + pixelBytes * (w - 1) + std::size_t(ch) * 4) / 4 + 1;
        std::vector<float> buf(floats);
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
      case 2: crispSetFilterFloat(f, r.pick(kParams).c_str(), r.number()); break;
      case 3: crispSetFilterInt(f, r.pick(kParams).c_str(), int(r.byte()) - 8); break;
      case 4: crispSetFilterString(f, r.pick(kParams).c_str(), r.pick(kStrings).c_str()); break;
      case 5: crispSetFilterBool(f, r.pick(kParams).c_str(), r.byte() & 1); break;
      case 6: crispCommitFilter(f); break;
      case 7: executed(crisp_fuzz::execute(f, output)); break;
      case 8: {  // the output in place: the colour's own view (crisp.h: the result is the same)
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

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  crisp_fuzz::checkInPlace("fuzz_c_api",
                           [&](bool apart, crisp_fuzz::Trace& trace) { run(data, size, apart, trace); });
  return 0;
}
