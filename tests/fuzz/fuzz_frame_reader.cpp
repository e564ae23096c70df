// SPDX-License-Identifier: Apache-2.0
// Fuzzes the pass reader: any bytes written to a file must give a Frame or a
// crisp::Exception, never a crash, hang or sanitizer report.
#include <unistd.h>

#include <cstdint>
#include <cstdio>
#include <string>

#include "core/error.h"
#include "io/frame.h"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  // The first byte picks the extension, so both the EXR and PNG readers run.
  static const char* kExt[] = {".exr", ".png", ".exr", ".exr"};
  const char* ext = size ? kExt[data[0] & 3] : ".exr";
  static const std::string dir = [] {
    const char* shm = "/dev/shm";
    return access(shm, W_OK) == 0 ? std::string(shm) : std::string("/tmp");
  }();
  const std::string path = dir + "/crisp-fuzz-" + std::to_string(getpid()) + ext;
  if (FILE* f = std::fopen(path.c_str(), "wb")) {
    if (size > 1) std::fwrite(data + 1, 1, size - 1, f);
    std::fclose(f);
  } else {
    return 0;
  }
  try {
    crisp::Frame frame = crisp::readFrame(path);
    // Touch every pass so a short buffer would show up under ASan.
    double sum = 0;
    for (const auto& [role, image] : frame.passes) {
      if (image.data.size() != std::size_t(image.width) * image.height * image.channels) __builtin_trap();
      for (float v : image.data) sum += v;
    }
    (void)sum;
  } catch (const crisp::Exception&) {
  }
  std::remove(path.c_str());
  return 0;
}
