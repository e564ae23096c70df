// SPDX-License-Identifier: Apache-2.0
#include "motion/reconstruct.h"

#include <algorithm>
#include <cmath>
#include <vector>

#include "core/conventions.h"
#include "core/error.h"
#include "core/parallel.h"

namespace crisp {

namespace {

// A point must be at least this far in front of a camera (scene units along
// its axis; clip w of a perspective projection) to be projected.
constexpr double kMinCameraDepth = 1e-6;

// Current camera space -> clip space of a neighbouring frame's unjittered
// camera, for one object (or the static world).
struct Chain {
  Mat4 toClip;
  bool valid = false;  // false: object absent from that frame (or singular)
};

struct ObjectChains {
  std::uint32_t hash = 0;
  Chain previous, next;
};

Chain makeChain(const Sidecar& other, const Mat4& currentCameraToWorld, const Mat4* objectCurrentToOther) {
  Chain c;
  Mat4 worldToWorld = objectCurrentToOther ? *objectCurrentToOther : Mat4::identity();
  c.toClip = other.projectionUnjittered * other.view * worldToWorld * currentCameraToWorld;
  c.valid = c.toClip.finite();
  return c;
}

// world_other * inverse(world_current) of one object, or false if it has no
// match in `other` or its current matrix is singular.
bool objectChange(const SidecarObject& cur, const Sidecar& other, std::uint32_t hash, Mat4& out) {
  const SidecarObject* o = other.object(hash);
  Mat4 inv;
  if (!o || !invert(cur.world, inv)) return false;
  out = o->world * inv;
  return true;
}

// Pixel position (x right, y DOWN, pixel centres at +0.5) of a clip-space
// point, or false if it is on/behind the camera plane or not finite.
// A still point's vector is exactly 0: its chains (other frame's view times
// the inverse of this one's) multiply out to the identity only up to double
// rounding, ~1e-10 px, and the temporal filters keep their exact static path
// (running average, no resampling) for velocity exactly 0 only. Measured on the
// ghosting scene before this: half the still wall's pixels had |v| < 1e-3 px
// but not 0, took the feedback blend, and flickered. 1e-6 px is far below any
// motion that matters (depth is half-float: ~1e-3 px of error anyway).
double snapStill(double v) { return std::fabs(v) < 1e-6 ? 0.0 : v; }

bool toPixel(const Vec4d& clip, int width, int height, double& px, double& py) {
  if (!(clip.w > kMinCameraDepth)) return false;
  px = (clip.x / clip.w + 1.0) * 0.5 * width;
  py = (1.0 - clip.y / clip.w) * 0.5 * height;
  return std::isfinite(px) && std::isfinite(py);
}

bool anyObjectMoves(const Sidecar& a, const Sidecar& b) {
  for (const auto& kv : a.objects) {
    const SidecarObject* o = b.object(kv.first);
    if (o && !(o->world == kv.second.world)) return true;
  }
  return false;
}

// Whether pixels must be matched to objects by their IDs: more than one
// object, and one of them moves (reconstructMotion's "without IDs" rule).
bool needsIds(const Sidecar& current, const Sidecar& previous, const Sidecar* next) {
  return current.objects.size() != 1 &&
         (anyObjectMoves(current, previous) || (next && anyObjectMoves(current, *next)));
}

void checkSameSize(const Sidecar& current, const Sidecar& other, const char* which) {
  if (other.width != current.width || other.height != current.height)
    invalidData(std::string(which) + " sidecar '" + other.path + "' is for " + std::to_string(other.width) + "x" +
                std::to_string(other.height) + " but '" + current.path + "' is " + std::to_string(current.width) +
                "x" + std::to_string(current.height) + ": motion in pixels needs one resolution");
}

}  // namespace

FrameMotion reconstructMotion(const Image& depth, const Image* ids, const Sidecar& current, const Sidecar& previous,
                              const Sidecar* next, const std::string& frameLabel, int numThreads) {
  const int W = current.width, H = current.height;
  if (depth.channels != 1 || depth.format == Format::UInt)
    invalidData("'" + frameLabel + "': the depth pass must be 1 float channel");
  if (depth.width != W || depth.height != H)
    invalidData("'" + frameLabel + "': depth is " + std::to_string(depth.width) + "x" + std::to_string(depth.height) +
                " but its sidecar '" + current.path + "' says " + std::to_string(W) + "x" + std::to_string(H));
  if (ids && (ids->format != Format::UInt || ids->width != W || ids->height != H))
    invalidData("'" + frameLabel + "': the id pass must be uint32 of the depth's size");
  checkSameSize(current, previous, "previous");
  if (next) checkSameSize(current, *next, "next");

  Mat4 cameraToWorld;
  if (!invert(current.view, cameraToWorld))
    invalidData("sidecar '" + current.path + "': key 'camera.view' is singular");
  Mat4 projectionCheck;
  if (!invert(current.projection, projectionCheck))
    invalidData("sidecar '" + current.path + "': key 'camera.projection' is singular");

  // Which object a pixel belongs to. Without IDs, only a lone object (or a
  // scene where nothing moves but the camera) can be handled.
  std::uint32_t loneObject = 0;
  if (!ids) {
    if (current.objects.size() == 1) {
      loneObject = current.objects.begin()->first;
    } else if (needsIds(current, previous, next)) {
      invalidData("'" + frameLabel + "' has no id pass (Cryptomatte object) but objects move between '" +
                  previous.path + "', '" + current.path + "'" + (next ? ", '" + next->path + "'" : std::string()) +
                  ": pixels cannot be matched to their objects; render the CryptoObject pass");
    }
  }

  const Chain staticPrevious = makeChain(previous, cameraToWorld, nullptr);
  const Chain staticNext = next ? makeChain(*next, cameraToWorld, nullptr) : Chain{};
  std::vector<ObjectChains> objects;  // sorted by hash (map order)
  objects.reserve(current.objects.size());
  for (const auto& kv : current.objects) {
    ObjectChains oc;
    oc.hash = kv.first;
    Mat4 change;
    if (objectChange(kv.second, previous, kv.first, change)) oc.previous = makeChain(previous, cameraToWorld, &change);
    if (next && objectChange(kv.second, *next, kv.first, change)) oc.next = makeChain(*next, cameraToWorld, &change);
    objects.push_back(oc);
  }
  auto findObject = [&](std::uint32_t hash) -> const ObjectChains* {
    auto it = std::lower_bound(objects.begin(), objects.end(), hash,
                               [](const ObjectChains& o, std::uint32_t h) { return o.hash < h; });
    return it != objects.end() && it->hash == hash ? &*it : nullptr;
  };

  const Mat4& P = current.projection;  // jittered: the sample sat on this projection's pixel centre
  const Mat4& currentClip = current.projectionUnjittered;

  FrameMotion out;
  out.motion = Image(W, H, 4, 0.0f);
  out.flags = Image::uintImage(W, H);
  parallelRows(W, H, numThreads, [&](int y0, int y1) {
    for (int y = y0; y < y1; ++y) {
      const double ndcY = 1.0 - 2.0 * (y + 0.5) / H;
      for (int x = 0; x < W; ++x) {
        float* m = out.motion.at(x, y);
        std::uint32_t flags = 0;
        // Blender 3.4 EEVEE computes Depth.Z in half float (the EXR holds it
        // as float32, every value exactly a half; background 65504): 11
        // significant bits, so d is off by up to 2^-11 relative (<= 0.002
        // units at 4-8 units away). That slides the
        // point by that much along its own ray: its current pixel is
        // unchanged, and the vector errs by the motion of that small
        // displacement: ~(dd / d) * parallax for a camera translation, ~theta
        // * dd * f / d pixels for a rotation by theta (object, or camera about
        // another point; f = focal length in pixels), nothing for a camera
        // turning about its own centre. Measured on the spinning cube (theta
        // 0.07 rad/frame, d ~5.5, f 133 px): median 0.003 px, max 0.011 px
        // against Cycles' Vector (tests/blender/test_motion_vectors.py).
        // Depths at or beyond 65504 read as background.
        const float d = *depth.at(x, y);
        if (isBackgroundDepth(d)) {
          out.flags.setUint(x, y, kMotionBackground);
          continue;
        }
        if (!(d > 0.0f) || !std::isfinite(d)) {
          out.flags.setUint(x, y, kMotionInvalidPoint);
          continue;
        }
        // Camera-space point on pixel (x, y)'s ray of the jittered projection
        // at planar depth d (camera looks down -Z): solve the two rows of
        // clip = P * (X, Y, Z, 1) with ndc = clip.xy / clip.w for X and Y.
        // Works for perspective and orthographic projections alike.
        const double ndcX = 2.0 * (x + 0.5) / W - 1.0;
        const double Z = -double(d);
        const double a00 = P.m[0][0] - ndcX * P.m[3][0], a01 = P.m[0][1] - ndcX * P.m[3][1];
        const double a10 = P.m[1][0] - ndcY * P.m[3][0], a11 = P.m[1][1] - ndcY * P.m[3][1];
        const double b0 = ndcX * (P.m[3][2] * Z + P.m[3][3]) - P.m[0][2] * Z - P.m[0][3];
        const double b1 = ndcY * (P.m[3][2] * Z + P.m[3][3]) - P.m[1][2] * Z - P.m[1][3];
        const double det = a00 * a11 - a01 * a10;
        const Vec4d point{(b0 * a11 - a01 * b1) / det, (a00 * b1 - b0 * a10) / det, Z, 1.0};
        double cx, cy;
        if (det == 0.0 || !toPixel(currentClip * point, W, H, cx, cy)) {
          out.flags.setUint(x, y, kMotionInvalidPoint);
          continue;
        }

        const Chain* toPrevious = &staticPrevious;
        const Chain* toNext = next ? &staticNext : nullptr;
        const std::uint32_t id = ids ? ids->uintAt(x, y) : loneObject;
        if (id != 0) {
          if (const ObjectChains* oc = findObject(id)) {
            toPrevious = &oc->previous;
            if (next) toNext = &oc->next;
          } else {
            flags |= kMotionUnknownObject;
          }
        }
        double px, py;
        if (!toPrevious->valid) {
          flags |= kMotionUnmatchedObject;
        } else if (toPixel(toPrevious->toClip * point, W, H, px, py)) {
          m[0] = float(snapStill(px - cx));
          m[1] = float(snapStill(py - cy));
          flags |= kMotionPreviousValid;
        } else {
          flags |= kMotionInvalidPoint;
        }
        if (toNext) {
          if (!toNext->valid) {
            flags |= kMotionUnmatchedObject;
          } else if (toPixel(toNext->toClip * point, W, H, px, py)) {
            m[2] = float(snapStill(cx - px));
            m[3] = float(snapStill(cy - py));
            flags |= kMotionNextValid;
          } else {
            flags |= kMotionInvalidPoint;
          }
        }
        out.flags.setUint(x, y, flags);
      }
    }
  });
  return out;
}

void reconstructFrameMotion(Frame& frame, const std::string& previousSidecarPath, const std::string& nextSidecarPath,
                            int numThreads) {
  if (previousSidecarPath.empty()) invalidArgument("motion reconstruction of '" + frame.path + "' needs the previous frame's sidecar");
  const Image& depth = frame.pass("depth");
  const Sidecar current = readSidecar(sidecarPathFor(frame.path));
  const Sidecar previous = readSidecar(previousSidecarPath);
  Sidecar next;
  if (!nextSidecarPath.empty()) next = readSidecar(nextSidecarPath);
  const Image* ids = frame.has("id") ? &frame.pass("id") : nullptr;
  // An ID pass the file holds unusable (half float, Frame::unusable) is named as
  // such where the IDs are needed, not as a missing pass.
  if (!ids && frame.unusable.count("id") && needsIds(current, previous, nextSidecarPath.empty() ? nullptr : &next))
    frame.pass("id");  // throws, saying why
  FrameMotion fm = reconstructMotion(depth, ids, current, previous, nextSidecarPath.empty() ? nullptr : &next,
                                     frame.path, numThreads);
  frame.passes["motion"] = std::move(fm.motion);
  frame.passes["motion_flags"] = std::move(fm.flags);
}

}  // namespace crisp
