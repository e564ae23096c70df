// SPDX-License-Identifier: Apache-2.0
// What the C API fuzz targets share: their view of libFuzzer's bytes (values
// read in order, zeros once the bytes run out, so every input is a whole
// sequence of calls), the check of an execute's output and the end of every
// sequence.
#pragma once

#include <cmath>
#include <cstdint>
#include <cstring>
#include <string>
#include <vector>

#include "crisp/crisp.h"

namespace crisp_fuzz {

struct Reader {
  const std::uint8_t* p;
  std::size_t n;
  std::uint8_t byte() {
    if (!n) return 0;
    --n;
    return *p++;
  }
  // Any float, NaN and infinities included: four bytes as its bits.
  float number() {
    std::uint32_t bits = 0;
    for (int i = 0; i < 4; ++i) bits = bits << 8 | byte();
    float f;
    std::memcpy(&f, &bits, 4);
    return f;
  }
  std::string pick(const std::vector<std::string>& names) { return names[byte() % names.size()]; }
};

// The "output" view a filter writes: the last one crispSetFilterImage accepted (a refused
// one leaves the one before; checking a refused buffer gave b7cf39b's false positives).
struct OutputView {
  const unsigned char* ptr = nullptr;
  int channels = 0;
  std::size_t width = 0, height = 0, pixelBytes = 0, rowBytes = 0;
  explicit operator bool() const { return ptr != nullptr; }
  float at(std::size_t x, std::size_t y, int c) const {
    float v;
    std::memcpy(&v, ptr + y * rowBytes + x * pixelBytes + std::size_t(c) * 4, 4);
    return v;
  }
};

// crispSetFilterImage, and whether the filter took the image (this call's error only). When
// it took an "output", *output becomes its view; strides 0 = packed, as crisp.h says.
inline bool setImage(CrispFilter filter, const char* name, void* ptr, CrispFormat format, std::size_t width,
                     std::size_t height, std::size_t pixelBytes, std::size_t rowBytes, OutputView* output) {
  crispGetError(nullptr);
  crispSetFilterImage(filter, name, ptr, format, width, height, pixelBytes, rowBytes);
  if (crispGetError(nullptr) != CRISP_ERROR_NONE) return false;
  if (output && std::strcmp(name, "output") == 0) {
    // Only float formats are output formats; any other is refused above.
    const int channels = format >= CRISP_FORMAT_FLOAT && format <= CRISP_FORMAT_FLOAT4 ? int(format) : 0;
    const std::size_t pixel = pixelBytes ? pixelBytes : std::size_t(channels) * 4;
    *output = {static_cast<const unsigned char*>(ptr), channels, width, height, pixel, rowBytes ? rowBytes : pixel * width};
  }
  return true;
}

// crisp.h: every filter's output is finite. A trap on a NaN or an infinity in `output`.
inline void trapUnlessFinite(const OutputView& output) {
  for (std::size_t y = 0; y < output.height; ++y)
    for (std::size_t x = 0; x < output.width; ++x)
      for (int c = 0; c < output.channels; ++c)
        if (!std::isfinite(output.at(x, y, c))) __builtin_trap();  // an execute without error wrote it
}

// crispExecuteFilter, and whether it reported no error (this call's only); if so, the output
// it wrote is checked (trapUnlessFinite).
inline bool execute(CrispFilter filter, const OutputView& output) {
  crispGetError(nullptr);
  crispExecuteFilter(filter);
  if (crispGetError(nullptr) != CRISP_ERROR_NONE) return false;
  if (output) trapUnlessFinite(output);
  return true;
}

// The end of every sequence: one more commit and execute (whatever state the
// calls left; its output checked as every execute's), every error read, the
// handles released.
inline void finish(CrispContext context, CrispFilter filter, const OutputView& output) {
  crispCommitFilter(filter);
  execute(filter, output);
  crispGetError(nullptr);
  crispReleaseFilter(filter);
  crispReleaseContext(context);
}

}  // namespace crisp_fuzz
