// SPDX-License-Identifier: Apache-2.0
// Fuzzes the C API: bytes drive a sequence of calls with arbitrary names,
// values, sizes and strides (buffers always as large as the views declare).
// Any sequence must end in results or recorded errors, never a crash; and an
// execute that reports no error leaves every value of the output it was given
// finite (crisp.h; fuzz_filters.cpp checks the other filters).
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

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  Reader r{data, size};
  CrispContext ctx = crispNewContext();
  crispSetContextInt(ctx, "numThreads", 1 + r.byte() % 2);
  CrispFilter f = crispNewFilter(ctx, r.pick(kTypes).c_str());
  std::vector<std::vector<float>> buffers;  // a moved vector keeps its data: `output` stays valid
  crisp_fuzz::OutputView output;
  for (int step = 0; step < 24 && r.n; ++step) {
    switch (r.byte() % 8) {
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
        crisp_fuzz::setImage(f, r.pick(kImages).c_str(), buffers.back().data(), CrispFormat(fmt), w, h, px, row,
                             &output);
        break;
      }
      case 2: crispSetFilterFloat(f, r.pick(kParams).c_str(), r.number()); break;
      case 3: crispSetFilterInt(f, r.pick(kParams).c_str(), int(r.byte()) - 8); break;
      case 4: crispSetFilterString(f, r.pick(kParams).c_str(), r.pick(kStrings).c_str()); break;
      case 5: crispSetFilterBool(f, r.pick(kParams).c_str(), r.byte() & 1); break;
      case 6: crispCommitFilter(f); break;
      case 7: crisp_fuzz::execute(f, output); break;
    }
    crispGetError(nullptr);
  }
  crisp_fuzz::finish(ctx, f, output);
  return 0;
}
