// SPDX-License-Identifier: Apache-2.0
// What the C API fuzz targets share: their view of libFuzzer's bytes (values
// read in order, zeros once the bytes run out, so every input is a whole
// sequence of calls) and the end of every sequence.
#pragma once

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

// The end of every sequence: one more commit and execute (whatever state the
// calls left), every error read, the handles released.
inline void finish(CrispContext context, CrispFilter filter) {
  crispCommitFilter(filter);
  crispExecuteFilter(filter);
  crispGetError(nullptr);
  crispReleaseFilter(filter);
  crispReleaseContext(context);
}

}  // namespace crisp_fuzz
