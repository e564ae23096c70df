// SPDX-License-Identifier: Apache-2.0
// Fuzzes what reads the add-on's per-frame JSON sidecars: the parser, the shot
// checks, and motion reconstruction from them. The input is up to three
// sidecar texts separated by NUL bytes: the current frame's, the previous
// one's, the next one's. Any bytes must give a Sidecar or a crisp::Exception;
// where two parse, motion is reconstructed over a depth and ID image of the
// current sidecar's size (small sizes only) on the fast path and the
// reference, which must give the same bits and finite vectors (reconstruct.h:
// an invalid pair is 0, never NaN), or the same exception.
#include <cmath>
#include <cstdint>
#include <cstring>
#include <string>
#include <vector>

#include "core/error.h"
#include "io/sidecar.h"
#include "motion/reconstruct.h"

namespace {

// Depths a 1-sample render holds, and the ones the reconstruction must refuse
// per pixel: in front of the camera, far, the background, zero, negative, not finite.
constexpr float kDepths[] = {7.0f, 6.5f, 0.1f, 2.0f, 40.0f, 1e10f, 0.0f, -1.0f, INFINITY, NAN, 7.25f, 1e-30f};

bool sameBits(const crisp::Image& a, const crisp::Image& b) {
  return a.width == b.width && a.height == b.height && a.format == b.format && a.data.size() == b.data.size() &&
         std::memcmp(a.data.data(), b.data.data(), a.data.size() * sizeof(float)) == 0;
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  std::vector<std::string> texts(1);
  for (std::size_t i = 0; i < size; ++i) {
    if (data[i] == 0 && texts.size() < 3) texts.emplace_back();
    else texts.back() += char(data[i]);
  }
  std::vector<crisp::Sidecar> sidecars;
  for (std::size_t i = 0; i < texts.size(); ++i) {
    try {
      sidecars.push_back(crisp::parseSidecar(texts[i], "sidecar" + std::to_string(i)));
    } catch (const crisp::Exception&) {
      return 0;
    }
  }
  if (sidecars.size() < 2) return 0;
  const crisp::Sidecar& current = sidecars[0];
  const crisp::Sidecar& previous = sidecars[1];
  const crisp::Sidecar* next = sidecars.size() > 2 ? &sidecars[2] : nullptr;
  (void)crisp::shotBreak(previous, current);
  (void)crisp::sameCameraAndObjects(previous, current);

  // The current sidecar's size when small, else 8x6 (refused as another size).
  const bool small = std::size_t(current.width) * std::size_t(current.height) <= 64 * 64;
  const int w = small ? current.width : 8, h = small ? current.height : 6;
  crisp::Image depth(w, h, 1);
  crisp::Image ids = crisp::Image::uintImage(w, h);
  std::vector<std::uint32_t> hashes = {0u, 0xdeadbeefu};
  for (const auto& [hash, object] : current.objects) hashes.push_back(hash);
  for (int y = 0; y < h; ++y)
    for (int x = 0; x < w; ++x) {
      const std::size_t k = std::size_t(y) * std::size_t(w) + std::size_t(x);
      depth.at(x, y)[0] = kDepths[k % (sizeof kDepths / sizeof kDepths[0])];
      ids.setUint(x, y, hashes[(k / 3) % hashes.size()]);
    }
  const crisp::Image* const idPasses[] = {&ids, nullptr};
  for (const crisp::Image* idPass : idPasses) {
    std::string fastError, referenceError;
    crisp::FrameMotion fast, reference;
    try {
      fast = crisp::reconstructMotion(depth, idPass, current, previous, next, "fuzz", 1, crisp::MotionPath::Fast);
    } catch (const crisp::Exception& e) {
      fastError = e.what();
    }
    try {
      reference =
          crisp::reconstructMotion(depth, idPass, current, previous, next, "fuzz", 1, crisp::MotionPath::Reference);
    } catch (const crisp::Exception& e) {
      referenceError = e.what();
    }
    if (fastError != referenceError) __builtin_trap();
    if (!fastError.empty()) continue;
    if (!sameBits(fast.motion, reference.motion) || !sameBits(fast.flags, reference.flags)) __builtin_trap();
    for (float v : fast.motion.data)
      if (!std::isfinite(v)) __builtin_trap();
  }
  return 0;
}
