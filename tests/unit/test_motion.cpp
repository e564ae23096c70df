// SPDX-License-Identifier: Apache-2.0
// Motion reconstruction (motion/reconstruct.h) on synthetic depth and camera /
// object matrices built the way Blender builds them (view = inverse camera
// world matrix, OpenGL-style projection with the jitter as lens shift), where
// the exact motion follows from a closed form: pan, dolly, rotating object,
// jitter, background, points behind the camera, missing IDs.
#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <string>
#include <unistd.h>

#include "core/conventions.h"
#include "core/error.h"
#include "io/frame.h"
#include "camera_matrices.h"
#include "motion/reconstruct.h"
#include "temporal/isa.h"

using namespace crisp;
namespace fs = std::filesystem;

namespace {

constexpr int W = 40, H = 24;
constexpr double kNear = test::kCameraNear, kFar = test::kCameraFar;
constexpr std::uint32_t kCube = 0x4a8fce86u, kBall = 0x3f123456u, kStranger = 0x40abcdefu;
using test::rotationZ;
using test::translation;

// camera_matrices.h's perspective at this file's W x H.
Mat4 perspective(double s, double dx = 0, double dy = 0) { return test::perspective(s, W, H, dx, dy); }

Mat4 orthographic(double scale, double dx = 0, double dy = 0) {
  Mat4 p;
  p.m[0][0] = 2.0 / scale;
  p.m[1][1] = 2.0 / scale * W / H;
  p.m[0][3] = -2.0 * dx / W;
  p.m[1][3] = -2.0 * dy / H;
  p.m[2][2] = -2.0 / (kFar - kNear);
  p.m[2][3] = -(kFar + kNear) / (kFar - kNear);
  p.m[3][3] = 1.0;
  return p;
}

// A camera at `cameraWorld` (looking down its local -Z).
Sidecar sidecar(const Mat4& cameraWorld, const Mat4& projection, const Mat4& unjittered, double jx = 0, double jy = 0,
                const std::string& path = "mem.json") {
  Sidecar s;
  s.path = path;
  s.width = W;
  s.height = H;
  s.jitterX = jx;
  s.jitterY = jy;
  EXPECT_TRUE(invert(cameraWorld, s.view));
  s.projection = projection;
  s.projectionUnjittered = unjittered;
  return s;
}
Sidecar sidecar(const Mat4& cameraWorld, double s = 1.8) { return sidecar(cameraWorld, perspective(s), perspective(s)); }

Image constantDepth(float d) { return Image(W, H, 1, d); }

// A depth ramp so no two pixels share a depth.
Image rampDepth() {
  Image im(W, H, 1);
  for (int y = 0; y < H; ++y)
    for (int x = 0; x < W; ++x) *im.at(x, y) = 3.0f + 0.05f * x + 0.11f * y;
  return im;
}

std::uint32_t flagsAt(const FrameMotion& fm, int x, int y) { return fm.flags.uintAt(x, y); }

double ndcX(double x) { return 2.0 * (x + 0.5) / W - 1.0; }
double ndcY(double y) { return 1.0 - 2.0 * (y + 0.5) / H; }

}  // namespace

TEST(Motion, PanSidewaysGivesParallaxInverseToDepth) {
  const double s = 1.8, t = 0.25;
  const Sidecar prev = sidecar(translation(-t, 0, 0), s), cur = sidecar(Mat4::identity(), s);
  const Image depth = rampDepth();
  const FrameMotion fm = reconstructMotion(depth, nullptr, cur, prev, nullptr, "pan", 1);
  for (int y = 0; y < H; ++y)
    for (int x = 0; x < W; ++x) {
      const double d = *depth.at(x, y);
      // The previous camera sat t to the left: the point was f * t / d pixels further right.
      const double expected = s * W / 2.0 * t / d;
      ASSERT_NEAR(fm.motion.at(x, y)[0], expected, 1e-4) << x << "," << y;
      ASSERT_NEAR(fm.motion.at(x, y)[1], 0.0, 1e-4);
      ASSERT_EQ(fm.motion.at(x, y)[2], 0.0f);
      ASSERT_EQ(flagsAt(fm, x, y), std::uint32_t(kMotionPreviousValid));
    }
}

TEST(Motion, PanUpwardsIsYDownInPixels) {
  const double s = 1.8, t = 0.2;
  // Camera moved up by t: the point was higher in the previous image, so a smaller row.
  const FrameMotion fm = reconstructMotion(constantDepth(5.0f), nullptr, sidecar(Mat4::identity(), s),
                                           sidecar(translation(0, -t, 0), s), nullptr, "pan-up", 1);
  const double expected = -(s * W / H) * H / 2.0 * t / 5.0;
  EXPECT_LT(expected, 0.0);
  for (int y = 0; y < H; ++y)
    for (int x = 0; x < W; ++x) {
      ASSERT_NEAR(fm.motion.at(x, y)[0], 0.0, 1e-4);
      ASSERT_NEAR(fm.motion.at(x, y)[1], expected, 1e-4);
    }
}

TEST(Motion, OrthographicPanIsIndependentOfDepth) {
  const double scale = 4.0, t = 0.3;
  const Sidecar prev = sidecar(translation(-t, 0, 0), orthographic(scale), orthographic(scale));
  const Sidecar cur = sidecar(Mat4::identity(), orthographic(scale), orthographic(scale));
  const FrameMotion fm = reconstructMotion(rampDepth(), nullptr, cur, prev, nullptr, "ortho", 1);
  for (int y = 0; y < H; ++y)
    for (int x = 0; x < W; ++x) ASSERT_NEAR(fm.motion.at(x, y)[0], t / scale * W, 1e-4);
}

TEST(Motion, DollyScalesAboutTheImageCentre) {
  const double s = 1.8, t = 0.7;
  // Current camera is t closer to the scene (moved along -Z) than the previous one.
  const FrameMotion fm = reconstructMotion(rampDepth(), nullptr, sidecar(translation(0, 0, -t), s),
                                           sidecar(Mat4::identity(), s), nullptr, "dolly", 1);
  const Image depth = rampDepth();
  for (int y = 0; y < H; ++y)
    for (int x = 0; x < W; ++x) {
      const double k = *depth.at(x, y) / (*depth.at(x, y) + t);  // ndc shrinks by d / (d + t)
      ASSERT_NEAR(fm.motion.at(x, y)[0], (ndcX(x) * k - ndcX(x)) * W / 2.0, 1e-4);
      ASSERT_NEAR(fm.motion.at(x, y)[1], -(ndcY(y) * k - ndcY(y)) * H / 2.0, 1e-4);
    }
}

TEST(Motion, RotatingObjectMatchedByIdAndStaticRest) {
  // Camera 10 above the origin looking straight down; a floor object turning about world Z
  // through the origin; ground (id 0) and an unknown id stay put.
  const double s = 2.0, d = 10.0, a0 = 0.30, a1 = 0.42;
  Sidecar prev = sidecar(translation(0, 0, d), s), cur = sidecar(translation(0, 0, d), s);
  prev.objects[kCube] = {"Cube", rotationZ(a0) * translation(0, 0, 0), "", false};
  cur.objects[kCube] = {"Cube", rotationZ(a1), "", false};
  Image ids = Image::uintImage(W, H);
  for (int y = 0; y < H; ++y)
    for (int x = 0; x < W; ++x) ids.setUint(x, y, x < W / 2 ? kCube : (y < H / 2 ? 0u : kStranger));
  const FrameMotion fm = reconstructMotion(constantDepth(float(d)), &ids, cur, prev, nullptr, "spin", 2);
  for (int y = 0; y < H; ++y)
    for (int x = 0; x < W; ++x) {
      const float* m = fm.motion.at(x, y);
      if (x < W / 2) {
        // Image positions turn about the image centre by a0 - a1 (world x right, y up in the image).
        const double wx = ndcX(x) * d / s, wy = ndcY(y) * d / (s * W / H);
        const double c = std::cos(a0 - a1), sn = std::sin(a0 - a1);
        const double px = c * wx - sn * wy, py = sn * wx + c * wy;
        const double expectedX = (px - wx) * s / d * W / 2.0;
        const double expectedY = -(py - wy) * (s * W / H) / d * H / 2.0;
        ASSERT_NEAR(m[0], expectedX, 1e-4) << x << "," << y;
        ASSERT_NEAR(m[1], expectedY, 1e-4) << x << "," << y;
        ASSERT_EQ(flagsAt(fm, x, y), std::uint32_t(kMotionPreviousValid));
      } else {
        ASSERT_NEAR(m[0], 0.0, 1e-5);
        ASSERT_NEAR(m[1], 0.0, 1e-5);
        ASSERT_EQ(flagsAt(fm, x, y), kMotionPreviousValid | (y < H / 2 ? 0u : std::uint32_t(kMotionUnknownObject)));
      }
    }
  // Something actually moved: the far left column moves by pixels, not hundredths.
  EXPECT_GT(std::fabs(fm.motion.at(0, 0)[1]) + std::fabs(fm.motion.at(0, 0)[0]), 1.0);
}

TEST(Motion, JitterNeverLeaks) {
  const double s = 1.8;
  // Static scene and camera; both frames jittered differently: motion must be zero.
  const Sidecar prev = sidecar(Mat4::identity(), perspective(s, -0.41, 0.13), perspective(s), -0.41, 0.13);
  const Sidecar cur = sidecar(Mat4::identity(), perspective(s, 0.37, -0.28), perspective(s), 0.37, -0.28);
  const Sidecar next = sidecar(Mat4::identity(), perspective(s, 0.05, 0.44), perspective(s), 0.05, 0.44);
  const FrameMotion fm = reconstructMotion(rampDepth(), nullptr, cur, prev, &next, "jitter", 1);
  for (int y = 0; y < H; ++y)
    for (int x = 0; x < W; ++x)
      for (int c = 0; c < 4; ++c) ASSERT_NEAR(fm.motion.at(x, y)[c], 0.0, 1e-5) << x << "," << y << " c" << c;

  // A pan on a constant-depth plane moves every point equally: the jittered result equals the
  // unjittered one, although the jittered samples hit other points of the plane.
  const double t = 0.3;
  const Sidecar panPrev = sidecar(translation(-t, 0, 0), perspective(s, -0.41, 0.13), perspective(s));
  const FrameMotion jittered = reconstructMotion(constantDepth(4.0f), nullptr, cur, panPrev, nullptr, "jitter", 1);
  const FrameMotion plain = reconstructMotion(constantDepth(4.0f), nullptr, sidecar(Mat4::identity(), s),
                                              sidecar(translation(-t, 0, 0), s), nullptr, "plain", 1);
  for (int y = 0; y < H; ++y)
    for (int x = 0; x < W; ++x) {
      ASSERT_NEAR(jittered.motion.at(x, y)[0], plain.motion.at(x, y)[0], 1e-4);
      ASSERT_NEAR(jittered.motion.at(x, y)[1], plain.motion.at(x, y)[1], 1e-4);
    }
  EXPECT_NEAR(plain.motion.at(3, 3)[0], s * W / 2.0 * t / 4.0, 1e-4);
}

TEST(Motion, JitteredSampleIsUnprojectedAtItsOwnPosition) {
  // Dolly with jitter: the vector is the one of the point the jittered sample hit, i.e. of the
  // unjittered position (x + 0.5 + jx, y + 0.5 - jy) (y down), never of the pixel centre.
  const double s = 1.8, t = 0.7, jx = 0.35, jy = -0.25;
  const Sidecar cur = sidecar(translation(0, 0, -t), perspective(s, jx, jy), perspective(s), jx, jy);
  const FrameMotion fm = reconstructMotion(constantDepth(3.0f), nullptr, cur, sidecar(Mat4::identity(), s),
                                           nullptr, "dolly-jitter", 1);
  const double k = 3.0 / (3.0 + t);
  for (int y = 0; y < H; y += 5)
    for (int x = 0; x < W; x += 7) {
      const double nx = 2.0 * (x + 0.5 + jx) / W - 1.0, ny = 1.0 - 2.0 * (y + 0.5 - jy) / H;
      ASSERT_NEAR(fm.motion.at(x, y)[0], (nx * k - nx) * W / 2.0, 1e-4);
      ASSERT_NEAR(fm.motion.at(x, y)[1], -(ny * k - ny) * H / 2.0, 1e-4);
    }
}

TEST(Motion, NextFrameGivesCurrentMinusNext) {
  const double s = 1.8, t = 0.2;
  // Steady pan to the right: xy = +f t/d, zw = current - next = +f t/d too (Vector pass convention).
  const Sidecar prev = sidecar(translation(-t, 0, 0), s), cur = sidecar(Mat4::identity(), s),
                next = sidecar(translation(t, 0, 0), s);
  const FrameMotion fm = reconstructMotion(constantDepth(2.0f), nullptr, cur, prev, &next, "next", 1);
  const double expected = s * W / 2.0 * t / 2.0;
  for (int y = 0; y < H; ++y)
    for (int x = 0; x < W; ++x) {
      ASSERT_NEAR(fm.motion.at(x, y)[0], expected, 1e-4);
      ASSERT_NEAR(fm.motion.at(x, y)[2], expected, 1e-4);
      ASSERT_NEAR(fm.motion.at(x, y)[3], 0.0, 1e-4);
      ASSERT_EQ(flagsAt(fm, x, y), kMotionPreviousValid | kMotionNextValid);
    }
}

// The background is at infinity: a camera that only moves leaves it where it was.
TEST(Motion, BackgroundIsStillUnderACameraThatOnlyMoves) {
  Image depth = constantDepth(4.0f);
  *depth.at(1, 1) = kFarDepth;          // Blender 3.x half-float background
  *depth.at(2, 1) = kBackgroundDepth;   // 1e10
  *depth.at(3, 1) = 70000.0f;           // beyond half max: background too
  const FrameMotion fm = reconstructMotion(depth, nullptr, sidecar(Mat4::identity()), sidecar(translation(-1, 0, 0)),
                                           nullptr, "bg", 1);
  for (int x : {1, 2, 3}) {
    EXPECT_EQ(fm.motion.at(x, 1)[0], 0.0f);
    EXPECT_EQ(fm.motion.at(x, 1)[1], 0.0f);
    EXPECT_EQ(flagsAt(fm, x, 1), std::uint32_t(kMotionBackground | kMotionPreviousValid));
  }
  EXPECT_GT(fm.motion.at(4, 1)[0], 1.0f);
  EXPECT_EQ(flagsAt(fm, 4, 1), std::uint32_t(kMotionPreviousValid));
}

// A camera turning about its own centre moves every point by the same vector whatever its depth, so
// the background (a direction) must move as a point at any depth in the same pixel does: a rolling,
// panning, tilting, jittered camera with lens shift, the previous and the next frame.
TEST(Motion, BackgroundTurnsWithTheCamera) {
  const double s = 1.6;
  auto turn = [](double yaw, double pitch, double roll) {
    Mat4 y = Mat4::identity(), p = Mat4::identity();
    y.m[0][0] = std::cos(yaw), y.m[0][2] = std::sin(yaw), y.m[2][0] = -std::sin(yaw), y.m[2][2] = std::cos(yaw);
    p.m[1][1] = std::cos(pitch), p.m[1][2] = -std::sin(pitch), p.m[2][1] = std::sin(pitch), p.m[2][2] = std::cos(pitch);
    return translation(0.4, -2.0, 1.5) * y * p * rotationZ(roll);
  };
  const Sidecar prev = sidecar(turn(0.06, -0.02, 0.03), perspective(s, 0.3, 0.2), perspective(s, 0.3, 0.2), 0, 0);
  const Sidecar cur = sidecar(turn(0.0, 0.0, 0.0), perspective(s, 0.3 - 0.21, 0.2 + 0.33), perspective(s, 0.3, 0.2),
                              -0.21, 0.33);
  const Sidecar next = sidecar(turn(-0.05, 0.04, -0.02), perspective(s, 0.3, 0.2), perspective(s, 0.3, 0.2));
  const FrameMotion sky = reconstructMotion(constantDepth(kFarDepth), nullptr, cur, prev, &next, "sky", 1);
  const FrameMotion wall = reconstructMotion(constantDepth(9.0f), nullptr, cur, prev, &next, "wall", 1);
  double largest = 0.0;
  for (int y = 0; y < H; ++y)
    for (int x = 0; x < W; ++x) {
      ASSERT_EQ(flagsAt(sky, x, y), std::uint32_t(kMotionBackground | kMotionPreviousValid | kMotionNextValid));
      for (int c = 0; c < 4; ++c) {
        ASSERT_NEAR(sky.motion.at(x, y)[c], wall.motion.at(x, y)[c], 1e-3) << x << "," << y << " c" << c;
        largest = std::max(largest, std::fabs(double(sky.motion.at(x, y)[c])));
      }
    }
  EXPECT_GT(largest, 1.0) << "the camera should turn the sky by pixels";
}

// An orthographic camera's rays share one direction: its background keeps motion 0, flagged.
TEST(Motion, OrthographicBackgroundIsZero) {
  const Sidecar prev = sidecar(rotationZ(0.2), orthographic(6.0), orthographic(6.0));
  const Sidecar cur = sidecar(Mat4::identity(), orthographic(6.0), orthographic(6.0));
  const FrameMotion fm = reconstructMotion(constantDepth(kFarDepth), nullptr, cur, prev, nullptr, "ortho", 1);
  for (int y = 0; y < H; ++y)
    for (int x = 0; x < W; ++x) {
      ASSERT_EQ(flagsAt(fm, x, y), std::uint32_t(kMotionBackground));
      ASSERT_EQ(fm.motion.at(x, y)[0], 0.0f);
      ASSERT_EQ(fm.motion.at(x, y)[1], 0.0f);
    }
}

TEST(Motion, PointsBehindThePreviousCameraAndBadDepthsAreInvalid) {
  // The previous camera stood 5 units further forward: points 2 units away were behind it.
  Image depth = constantDepth(2.0f);
  *depth.at(0, 0) = 8.0f;  // this one was still in front of it
  *depth.at(1, 0) = std::nanf("");  // reads as background (conventions.h)
  *depth.at(2, 0) = -1.0f;
  *depth.at(3, 0) = 0.0f;
  const Sidecar next = sidecar(translation(0, 0, 0.5));
  const FrameMotion fm = reconstructMotion(depth, nullptr, sidecar(Mat4::identity()), sidecar(translation(0, 0, -5)),
                                           &next, "behind", 1);
  EXPECT_EQ(flagsAt(fm, 0, 0), kMotionPreviousValid | kMotionNextValid);
  for (int x : {1, 2, 3}) {
    // The background is a direction: the cameras' translations leave it still, both pairs valid.
    const std::uint32_t background = kMotionBackground | kMotionPreviousValid | kMotionNextValid;
    EXPECT_EQ(flagsAt(fm, x, 0), std::uint32_t(x == 1 ? background : kMotionInvalidPoint)) << x;
    for (int c = 0; c < 4; ++c) EXPECT_EQ(fm.motion.at(x, 0)[c], 0.0f);
  }
  const std::uint32_t f = flagsAt(fm, 5, 5);
  EXPECT_EQ(f, kMotionInvalidPoint | kMotionNextValid);  // only the previous pair is lost
  EXPECT_EQ(fm.motion.at(5, 5)[0], 0.0f);
  EXPECT_EQ(fm.motion.at(5, 5)[1], 0.0f);
  EXPECT_NE(fm.motion.at(5, 5)[2], 0.0f);
}

TEST(Motion, ObjectMissingFromThePreviousFrameIsUnmatched) {
  Sidecar prev = sidecar(Mat4::identity()), cur = sidecar(Mat4::identity());
  cur.objects[kBall] = {"Ball", translation(0, 0, -3), "", false};
  Image ids = Image::uintImage(W, H);
  ids.setUint(4, 4, kBall);
  const FrameMotion fm = reconstructMotion(constantDepth(3.0f), &ids, cur, prev, nullptr, "appear", 1);
  EXPECT_EQ(flagsAt(fm, 4, 4), std::uint32_t(kMotionUnmatchedObject));
  EXPECT_EQ(flagsAt(fm, 5, 4), std::uint32_t(kMotionPreviousValid));
}

TEST(Motion, WithoutIdsALoneObjectOwnsEveryPixel) {
  const double s = 1.8;
  Sidecar prev = sidecar(Mat4::identity(), s), cur = sidecar(Mat4::identity(), s);
  prev.objects[kCube] = {"Cube", translation(-0.1, 0, -4), "", false};
  cur.objects[kCube] = {"Cube", translation(0, 0, -4), "", false};
  const FrameMotion fm = reconstructMotion(constantDepth(4.0f), nullptr, cur, prev, nullptr, "lone", 1);
  EXPECT_NEAR(fm.motion.at(7, 7)[0], -s * W / 2.0 * 0.1 / 4.0, 1e-4);  // was 0.1 to the left

  // Two objects, one moving, no IDs: refused, naming the frame and what to render.
  cur.objects[kBall] = {"Ball", translation(1, 0, -4), "", false};
  prev.objects[kBall] = {"Ball", translation(1, 0, -4), "", false};
  try {
    reconstructMotion(constantDepth(4.0f), nullptr, cur, prev, nullptr, "two.exr", 1);
    FAIL() << "expected an error";
  } catch (const Exception& e) {
    EXPECT_EQ(e.code(), CRISP_ERROR_INVALID_DATA);
    EXPECT_NE(std::string(e.what()).find("two.exr"), std::string::npos) << e.what();
    EXPECT_NE(std::string(e.what()).find("CryptoObject"), std::string::npos) << e.what();
  }
  // Two objects that do not move while the camera does: static world, no IDs needed.
  prev.objects[kCube] = cur.objects[kCube];
  Sidecar panPrev = sidecar(translation(-0.2, 0, 0), s);
  panPrev.objects = prev.objects;
  const FrameMotion pan = reconstructMotion(constantDepth(4.0f), nullptr, cur, panPrev, nullptr, "two", 1);
  EXPECT_NEAR(pan.motion.at(7, 7)[0], s * W / 2.0 * 0.2 / 4.0, 1e-4);
}

TEST(Motion, ThreadCountDoesNotChangeTheResult) {
  Sidecar prev = sidecar(translation(-0.1, 0.05, 0.2)), cur = sidecar(Mat4::identity());
  const FrameMotion a = reconstructMotion(rampDepth(), nullptr, cur, prev, nullptr, "t", 1);
  const FrameMotion b = reconstructMotion(rampDepth(), nullptr, cur, prev, nullptr, "t", 0);
  EXPECT_EQ(a.motion.data, b.motion.data);
  EXPECT_EQ(a.flags.data.size(), b.flags.data.size());
}

TEST(Motion, BadInputsAreRefusedWithTheirNames) {
  const Sidecar cur = sidecar(Mat4::identity(), perspective(1.8), perspective(1.8), 0, 0, "cur.json");
  Sidecar small = cur;
  small.path = "prev.json";
  small.width = W / 2;
  auto expectError = [](auto&& fn, const std::string& needle) {
    try {
      fn();
      ADD_FAILURE() << "expected an error mentioning " << needle;
    } catch (const Exception& e) {
      EXPECT_EQ(e.code(), CRISP_ERROR_INVALID_DATA);
      EXPECT_NE(std::string(e.what()).find(needle), std::string::npos) << e.what();
    }
  };
  expectError([&] { reconstructMotion(constantDepth(1.0f), nullptr, cur, small, nullptr, "f.exr", 1); }, "prev.json");
  expectError([&] { reconstructMotion(Image(W, H + 1, 1), nullptr, cur, cur, nullptr, "f.exr", 1); }, "f.exr");
  expectError([&] { reconstructMotion(Image(W, H, 3), nullptr, cur, cur, nullptr, "f.exr", 1); }, "depth");
  Sidecar singular = cur;
  singular.view = Mat4();
  expectError([&] { reconstructMotion(constantDepth(1.0f), nullptr, singular, cur, nullptr, "f.exr", 1); },
              "camera.view");
}

// The file-level entry point: the frame's own sidecar next to it, the neighbours by path.
TEST(Motion, ReconstructFrameMotionReadsTheSidecarsFromDisk) {
  const fs::path dir = fs::temp_directory_path() / ("crisp_motion_" + std::to_string(::getpid()));
  fs::create_directories(dir);
  auto writeSidecar = [&](const std::string& name, double cameraX, const std::string& objects = "{}") {
    const Sidecar s = sidecar(translation(cameraX, 0, 0), 1.8);
    std::ofstream out(dir / name);
    auto mat = [&](const Mat4& m) {
      std::string t = "[";
      for (int r = 0; r < 4; ++r) {
        t += r ? ",[" : "[";
        for (int c = 0; c < 4; ++c) t += (c ? "," : "") + std::to_string(m.m[r][c]);
        t += "]";
      }
      return t + "]";
    };
    out << "{\"frame\": 1, \"jitter\": {\"x\": 0.0, \"y\": 0.0}, \"render_settings\": {\"resolution\": [" << W << ", "
        << H << "]}, \"camera\": {\"view\": " << mat(s.view) << ", \"projection\": " << mat(s.projection)
        << ", \"projection_unjittered\": " << mat(s.projectionUnjittered) << "}, \"objects\": " << objects << "}";
  };
  writeSidecar("frame_0001.json", -0.25);
  writeSidecar("frame_0002.json", 0.0);
  Frame frame;
  frame.path = (dir / "frame_0002.exr").string();
  frame.width = W;
  frame.height = H;
  frame.passes["depth"] = constantDepth(2.0f);
  reconstructFrameMotion(frame, (dir / "frame_0001.json").string(), "", 1);
  ASSERT_TRUE(frame.has("motion"));
  ASSERT_TRUE(frame.has("motion_flags"));
  EXPECT_EQ(frame.pass("motion").channels, 4);
  EXPECT_EQ(frame.pass("motion_flags").format, Format::UInt);
  EXPECT_NEAR(frame.pass("motion").at(9, 9)[0], 1.8 * W / 2.0 * 0.25 / 2.0, 1e-3);  // 6 decimals in the JSON

  try {
    reconstructFrameMotion(frame, (dir / "frame_0000.json").string(), "", 1);
    ADD_FAILURE() << "expected an I/O error";
  } catch (const Exception& e) {
    EXPECT_EQ(e.code(), CRISP_ERROR_IO);
    EXPECT_NE(std::string(e.what()).find("frame_0000.json"), std::string::npos) << e.what();
  }

  // Two objects, one of them moving: pixels must be matched to objects by their IDs. An ID pass
  // the file holds unusable (half float) is named with its reason, not as a missing pass.
  auto objects = [](double x) {
    return "{\"0000000a\": {\"name\": \"Still\", \"matrix_world\": [[1,0,0,0],[0,1,0,0],[0,0,1,0],[0,0,0,1]]}, "
           "\"0000000b\": {\"name\": \"Moving\", \"matrix_world\": [[1,0,0," + std::to_string(x) +
           "],[0,1,0,0],[0,0,1,0],[0,0,0,1]]}}";
  };
  writeSidecar("frame_0001.json", -0.25, objects(0.0));
  writeSidecar("frame_0002.json", 0.0, objects(0.5));
  Frame withIds = frame;
  withIds.passes.erase("motion");
  withIds.unusable["id"] = "pass 'ViewLayer.CryptoObject00' in 'frame_0002.exr' is stored as half, not 32-bit float";
  try {
    reconstructFrameMotion(withIds, (dir / "frame_0001.json").string(), "", 1);
    ADD_FAILURE() << "expected an invalid-data error";
  } catch (const Exception& e) {
    EXPECT_EQ(e.code(), CRISP_ERROR_INVALID_DATA);
    EXPECT_EQ(std::string(e.what()), withIds.unusable["id"]);
  }
  withIds.unusable.clear();  // no ID pass at all: said as missing
  try {
    reconstructFrameMotion(withIds, (dir / "frame_0001.json").string(), "", 1);
    ADD_FAILURE() << "expected an invalid-data error";
  } catch (const Exception& e) {
    EXPECT_NE(std::string(e.what()).find("has no id pass"), std::string::npos) << e.what();
  }
  fs::remove_all(dir);
}

// A still point gets a vector of exactly 0, not the ~1e-10 px that the chain
// (other view times this camera's world matrix) leaves in double rounding: the
// temporal filters keep their exact static path for velocity 0 only (measured on
// the ghosting scene: half the still wall's pixels had |v| in (0, 1e-3) px).
TEST(Motion, StillPointsGetExactlyZero) {
  const double s = 1.8;
  const Mat4 camera = translation(0.3, -7.0, 2.0) * rotationZ(0.7);  // not exact in binary
  const Sidecar prev = sidecar(camera, perspective(s, -0.41, 0.13), perspective(s), -0.41, 0.13);
  const Sidecar cur = sidecar(camera, perspective(s, 0.37, -0.28), perspective(s), 0.37, -0.28);
  const FrameMotion fm = reconstructMotion(rampDepth(), nullptr, cur, prev, &prev, "still", 1);
  for (int y = 0; y < H; ++y)
    for (int x = 0; x < W; ++x)
      for (int c = 0; c < 4; ++c) ASSERT_EQ(fm.motion.at(x, y)[c], 0.0f) << x << "," << y << " c" << c;
}

// The fast path (four pixels at a time, reconstruct.cpp) gives the reference's
// bits on every copy the CPU runs: widths that leave a tail of 1-3 pixels, a
// sky of whole background groups, groups that mix background, bad depths
// (0, negative, -inf, NaN, +inf, denormal), points behind the previous
// camera, ids of a moving object, of an object missing from the previous
// frame, unknown ids and id 0, with and without the next frame and the ids.
TEST(Motion, FastPathEqualsReference) {
  const double s = 1.7;
  for (const bool cameraMoves : {true, false})  // a still camera: static points snap to exactly 0
    for (const int w : {43, 4, 3, 17})
      for (const int h : {9, 2}) {
        auto sized = [&](Sidecar sc) {
          sc.width = w;
          sc.height = h;
          return sc;
        };
        // The camera moves forward past some points (behind it in the previous frame) and turns.
        // A still camera away from the origin: its chains multiply out to the identity only up to
        // rounding, so still points take the snap to 0.
        const Mat4 pose = translation(0.31, -0.17, 0.7) * rotationZ(0.23);
        Sidecar prev = sized(sidecar(cameraMoves ? translation(0.3, -0.2, 2.5) * rotationZ(0.2) : pose,
                                     perspective(s, 0.2, -0.3), perspective(s), 0.2, -0.3));
        Sidecar cur = sized(sidecar(cameraMoves ? Mat4::identity() : pose, perspective(s, -0.37, 0.41), perspective(s),
                                    -0.37, 0.41));
        // The next camera turns too (a roll): the sky moves towards both frames.
        Sidecar next = sized(sidecar(translation(-0.1, 0.05, -0.4) * rotationZ(-0.15), perspective(s, 0.11, 0.07),
                                     perspective(s), 0.11, 0.07));
        cur.objects[kCube] = {"Cube", rotationZ(0.4) * translation(0.5, 0, -3), "", false};
        prev.objects[kCube] = {"Cube", rotationZ(0.3) * translation(0.45, 0, -3), "", false};
        next.objects[kCube] = {"Cube", rotationZ(0.5) * translation(0.55, 0, -3), "", false};
        cur.objects[kBall] = {"Ball", translation(-1, 0, -4), "", false};  // absent before and after: unmatched
        Image depth(w, h, 1), ids = Image::uintImage(w, h);
        const float odd[] = {0.0f, -1.0f, -INFINITY, NAN, INFINITY, kFarDepth, 1e-40f, 0.5f, 1e-3f, 2.4f};
        for (int y = 0; y < h; ++y)
          for (int x = 0; x < w; ++x) {
            const int i = y * w + x;
            float d = 1.0f + 0.37f * float((i * 7919) % 23);  // 1 .. 9: some behind the previous camera
            const bool sky = (y == 0 && x < 8) || (y == h - 1 && x >= 4 && x < 20);  // whole background groups
            if (sky) d = kFarDepth;
            if (i % 5 == 3 && !sky) d = odd[(i / 5) % 10];
            *depth.at(x, y) = d;
            const std::uint32_t choice[] = {0u, kCube, kBall, kStranger, kCube};
            ids.setUint(x, y, choice[(i * 31) % 5]);
          }
        // The fast path takes eight pixels a step (x = 0, 8, ...): a step all background runs the sky's lanes.
        int skySteps = 0;
        for (int y = 0; y < h; ++y)
          for (int x = 0; x + 8 <= w; x += 8) {
            bool all = true;
            for (int k = 0; k < 8; ++k) all &= isBackgroundDepth(*depth.at(x + k, y));
            skySteps += all;
          }
        if (w >= 8) EXPECT_GE(skySteps, 2) << w << "x" << h;
        for (const bool withNext : {false, true})
          for (const bool withIds : {false, true}) {
            const Image* idp = withIds ? &ids : nullptr;
            // Without ids only a lone object, or a scene where no object moves, is allowed.
            Sidecar c = cur, p = prev, n = next;
            if (!withIds) {
              c.objects.erase(kBall);
              p.objects.erase(kBall);
              n.objects.erase(kBall);
            }
            const FrameMotion ref =
                reconstructMotion(depth, idp, c, p, withNext ? &n : nullptr, "ref", 1, MotionPath::Reference);
            int valid = 0, still = 0, turnedSky = 0;
            for (int y = 0; y < h; ++y)
              for (int x = 0; x < w; ++x) {
                const bool reconstructed = (flagsAt(ref, x, y) & kMotionPreviousValid) != 0;
                valid += reconstructed;
                still += reconstructed && ref.motion.at(x, y)[0] == 0.0f;
                turnedSky += (flagsAt(ref, x, y) & kMotionBackground) && ref.motion.at(x, y)[0] != 0.0f;
              }
            EXPECT_EQ(turnedSky > 0, cameraMoves) << "the turning camera moves the sky, the still one does not";
            if (w * h > 20) {
              EXPECT_GT(valid, w * h / 4) << "the inputs should give mostly real motion";
              if (!cameraMoves && withIds) {
                EXPECT_GT(still, w * h / 8) << "a still camera should leave still points";
              }
            }
            for (const auto isa : {temporal::Isa::Auto, temporal::Isa::Baseline}) {
              temporal::setFastPathIsa(isa);
              for (const int threads : {1, 2}) {
                const FrameMotion fast = reconstructMotion(depth, idp, c, p, withNext ? &n : nullptr, "fast", threads);
                const std::string where = std::to_string(w) + "x" + std::to_string(h) + (withNext ? " next" : "") +
                                          (withIds ? " ids" : "") + " isa " + std::to_string(int(isa));
                ASSERT_EQ(0, std::memcmp(ref.motion.data.data(), fast.motion.data.data(),
                                         ref.motion.data.size() * sizeof(float))) << where;
                ASSERT_EQ(0, std::memcmp(ref.flags.data.data(), fast.flags.data.data(),
                                         ref.flags.data.size() * sizeof(float))) << where;
              }
            }
            temporal::setFastPathIsa(temporal::Isa::Auto);
          }
      }
}
