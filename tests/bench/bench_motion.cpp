// SPDX-License-Identifier: Apache-2.0
// Motion reconstruction (motion/reconstruct.h): the step taa, taa-improved and
// phlm need before they run on EEVEE 3.4's frames, which carry no Vector pass.
// A camera dolly toward a field of three objects, one of them moving, at the
// frame sizes of the filter benchmarks: the cost to add to a temporal filter's
// own per frame. The sidecars are in memory, so file reading is not timed.
#include <benchmark/benchmark.h>

#include <cmath>
#include <cstdint>

#include "bench_common.h"
#include "camera_matrices.h"  // tests/unit
#include "motion/matrix.h"
#include "motion/reconstruct.h"

namespace {

namespace bench = crisp::bench;
using crisp::Image;
using crisp::Mat4;
using crisp::Sidecar;

constexpr std::uint32_t kIds[3] = {0x4a8fce86u, 0x3f123456u, 0x40abcdefu};
using crisp::test::translation;

// Frame `frame` of the dolly: the camera 0.1 closer each frame, object 1 moving sideways; with
// `turns`, the camera also rolls 0.01 rad a frame, which moves the background (the sky's directions).
Sidecar dollyFrame(int width, int height, int frame, double jx, double jy, bool turns = false) {
  Sidecar s;
  s.path = "frame_" + std::to_string(frame) + ".json";
  s.frame = frame;
  s.width = width;
  s.height = height;
  s.jitterX = jx;
  s.jitterY = jy;
  crisp::invert(translation(0.0, 0.0, 10.0 - 0.1 * frame) * crisp::test::rotationZ(turns ? 0.01 * frame : 0.0),
                s.view);
  s.projection = crisp::test::perspective(1.8, width, height, jx, jy);
  s.projectionUnjittered = crisp::test::perspective(1.8, width, height);
  for (int k = 0; k < 3; ++k) {
    crisp::SidecarObject o;
    o.name = "object" + std::to_string(k);
    o.world = translation(k == 1 ? 0.05 * frame : 0.0, 0.0, 0.0);
    s.objects[kIds[k]] = o;
  }
  return s;
}

void reconstruct(benchmark::State& state, int width, int height, int threads,
                 crisp::MotionPath path = crisp::MotionPath::Fast, bool turns = false) {
  // Depth a slanted plane with some background, ids in three vertical bands.
  Image depth(width, height, 1), ids = Image::uintImage(width, height);
  for (int y = 0; y < height; ++y)
    for (int x = 0; x < width; ++x) {
      *depth.at(x, y) = y < height / 8 ? 1e10f : 4.0f + 6.0f * float(y) / float(height) + 0.5f * std::sin(0.01f * x);
      ids.setUint(x, y, kIds[3 * x / width]);
    }
  const Sidecar previous = dollyFrame(width, height, 1, 0.3, -0.2, turns),
                current = dollyFrame(width, height, 2, -0.4, 0.1, turns);
  for (auto _ : state) {
    crisp::FrameMotion m = crisp::reconstructMotion(depth, &ids, current, previous, nullptr, "bench", threads, path);
    benchmark::DoNotOptimize(m.motion.data.data());
    benchmark::ClobberMemory();
  }
  bench::setPixelRate(state, width, height);
}

void registerAll() {
  for (const auto& s : bench::kSizes) {
    const int w = s[0], h = s[1];
    bench::registerTimed("motion.reconstruct.mt" + bench::sizeTag(w, h),
                         [w, h](benchmark::State& st) { reconstruct(st, w, h, 0); });
    bench::registerTimed("motion.reconstruct.st" + bench::sizeTag(w, h),
                         [w, h](benchmark::State& st) { reconstruct(st, w, h, 1); });
    // A camera that also turns: the background's eighth of the frame moves too.
    bench::registerTimed("motion.reconstruct.turn.mt" + bench::sizeTag(w, h), [w, h](benchmark::State& st) {
      reconstruct(st, w, h, 0, crisp::MotionPath::Fast, true);
    });
    bench::registerTimed("motion.reconstruct.turn.st" + bench::sizeTag(w, h), [w, h](benchmark::State& st) {
      reconstruct(st, w, h, 1, crisp::MotionPath::Fast, true);
    });
    // The scalar reference, one pixel at a time (the fast path's baseline).
    bench::registerTimed("motion.reconstruct.reference.mt" + bench::sizeTag(w, h), [w, h](benchmark::State& st) {
      reconstruct(st, w, h, 0, crisp::MotionPath::Reference);
    });
    bench::registerTimed("motion.reconstruct.reference.st" + bench::sizeTag(w, h), [w, h](benchmark::State& st) {
      reconstruct(st, w, h, 1, crisp::MotionPath::Reference);
    });
  }
}

const bool registered = (registerAll(), true);

}  // namespace
