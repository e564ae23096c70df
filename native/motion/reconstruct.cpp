// SPDX-License-Identifier: Apache-2.0
#include "motion/reconstruct.h"

#include <algorithm>
#include <cmath>
#include <cstring>
#include <limits>
#include <vector>

#include "core/conventions.h"
#include "core/error.h"
#include "core/parallel.h"
#include "temporal/isa.h"

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

// A perspective projection whose centre is the camera's origin (Blender's,
// lens shift and jitter included): clip.w = P32 * z alone, no x, y or constant
// term in clip.x, clip.y.
bool isPerspectiveFromOrigin(const Mat4& P) {
  return P.m[3][0] == 0.0 && P.m[3][1] == 0.0 && P.m[3][2] != 0.0 && P.m[3][3] == 0.0 && P.m[0][3] == 0.0 &&
         P.m[1][3] == 0.0;
}

// Whether two frames' cameras look the same way through the same unjittered lens: the rotation part of
// their views and their unjittered projections are equal, bit for bit.
bool sameTurn(const Sidecar& a, const Sidecar& b) {
  for (int r = 0; r < 3; ++r)
    for (int c = 0; c < 3; ++c)
      if (a.view.m[r][c] != b.view.m[r][c]) return false;
  return a.projectionUnjittered == b.projectionUnjittered;
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

// Everything a pixel's reconstruction reads, set up once per frame.
struct Setup {
  int W, H;
  Mat4 P;            // jittered: the sample sat on this projection's pixel centre
  Mat4 currentClip;  // this frame's unjittered projection
  Chain staticPrevious, staticNext;
  bool hasNext;
  std::vector<ObjectChains> objects;  // sorted by hash (map order)
  const Image* ids;
  std::uint32_t loneObject;
  std::vector<double> ndcX;  // per column, as motionOfPixel computes it
  bool perspective;          // P projects from the camera's origin: a background pixel is a direction
  // The camera turned neither its view nor its projection since the previous / until the next frame
  // (a still camera, or one that only moves): every direction stays put (sameTurn).
  bool skyStillPrevious, skyStillNext;

  // The background moves: a perspective camera that turned (backgroundMotion's arithmetic runs).
  bool skyTurns() const { return perspective && !(skyStillPrevious && (!hasNext || skyStillNext)); }

  const ObjectChains* findObject(std::uint32_t hash) const {
    auto it = std::lower_bound(objects.begin(), objects.end(), hash,
                               [](const ObjectChains& o, std::uint32_t h) { return o.hash < h; });
    return it != objects.end() && it->hash == hash ? &*it : nullptr;
  }

  // The object ID of pixel (x, y): its ID pass's, else the lone object's (0: none).
  std::uint32_t idAt(int x, int y) const { return ids ? ids->uintAt(x, y) : loneObject; }

  // The chains of object `id` (toNext null without a next frame), and
  // kMotionUnknownObject where the ID is not in the sidecar (moved as the static world).
  std::uint32_t chainsOf(std::uint32_t id, const Chain*& toPrevious, const Chain*& toNext) const {
    toPrevious = &staticPrevious;
    toNext = hasNext ? &staticNext : nullptr;
    if (id == 0) return 0;
    const ObjectChains* oc = findObject(id);
    if (!oc) return kMotionUnknownObject;
    toPrevious = &oc->previous;
    if (hasNext) toNext = &oc->next;
    return 0;
  }
};

// One pair's outcome, previous (m: motion[0..1]) or next (motion[2..3]): the
// object has no match in that frame, or the point projects there (the two
// values stored) or does not.
std::uint32_t pairOutcome(bool matched, bool projects, double dx, double dy, float* m, std::uint32_t validFlag) {
  if (!matched) return kMotionUnmatchedObject;
  if (!projects) return kMotionInvalidPoint;
  m[0] = float(dx);
  m[1] = float(dy);
  return validFlag;
}

// A background pixel (depth read as infinity: the world, the sky) is a
// direction, not a point: the camera's rotation moves it across the image, its
// translation does not. Its ray through the jittered projection, (X, Y, -1)
// for the point at planar depth 1 (motionOfPixel's solve), goes through the
// static world's chains with w = 0, which drops their translations. An
// orthographic camera's rays share one direction, whose world colour is the
// same on every pixel: motion 0 there. Both paths call this for every
// background pixel: the same bits.
std::uint32_t backgroundMotion(const Setup& s, int x, int y, float* m) {
  if (!s.perspective) return kMotionBackground;
  // Where the camera did not turn, the arithmetic below gives 0 after snapStill (the chains' rotation
  // is the identity up to ~1e-16, far below its 1e-6 px): said without it, in both paths alike.
  if (!s.skyTurns()) {
    std::uint32_t flags =
        kMotionBackground | pairOutcome(s.staticPrevious.valid, true, 0.0, 0.0, m, kMotionPreviousValid);
    if (s.hasNext) flags |= pairOutcome(s.staticNext.valid, true, 0.0, 0.0, m + 2, kMotionNextValid);
    return flags;
  }
  const Mat4& P = s.P;
  const double ndcX = s.ndcX[std::size_t(x)], ndcY = 1.0 - 2.0 * (y + 0.5) / s.H;
  // P (X, Y, -1, 1) with the perspective's zero terms: clip.w = -P32, and clip.xy / clip.w = ndc.
  const double a00 = P.m[0][0], a01 = P.m[0][1], a10 = P.m[1][0], a11 = P.m[1][1];
  const double b0 = -ndcX * P.m[3][2] + P.m[0][2], b1 = -ndcY * P.m[3][2] + P.m[1][2];
  const double det = a00 * a11 - a01 * a10;
  const Vec4d direction{(b0 * a11 - a01 * b1) / det, (a00 * b1 - b0 * a10) / det, -1.0, 0.0};
  double cx, cy;
  if (det == 0.0 || !toPixel(s.currentClip * direction, s.W, s.H, cx, cy)) return kMotionBackground;
  std::uint32_t flags = kMotionBackground;
  double px = 0.0, py = 0.0;
  bool projects = s.staticPrevious.valid && toPixel(s.staticPrevious.toClip * direction, s.W, s.H, px, py);
  flags |= pairOutcome(s.staticPrevious.valid, projects, snapStill(px - cx), snapStill(py - cy), m,
                       kMotionPreviousValid);
  if (s.hasNext) {
    projects = s.staticNext.valid && toPixel(s.staticNext.toClip * direction, s.W, s.H, px, py);
    flags |= pairOutcome(s.staticNext.valid, projects, snapStill(cx - px), snapStill(cy - py), m + 2,
                         kMotionNextValid);
  }
  return flags;
}

// The reference: one pixel's motion and flags (motion starts at 0, written
// only where a pair is valid).
void motionOfPixel(const Setup& s, const Image& depth, int x, int y, FrameMotion& out) {
  const int W = s.W, H = s.H;
  const Mat4& P = s.P;
  const double ndcY = 1.0 - 2.0 * (y + 0.5) / H;
  float* m = out.motion.at(x, y);
  // Blender 3.4 EEVEE computes Depth.Z in half float (the EXR holds it as
  // float32, every value exactly a half; background 65504): 11 significant
  // bits, so d is off by up to 2^-11 relative (<= 0.002 units at 4-8 units
  // away). That slides the point by that much along its own ray: its current
  // pixel is unchanged, and the vector errs by the motion of that small
  // displacement: ~(dd / d) * parallax for a camera translation, ~theta * dd *
  // f / d pixels for a rotation by theta (object, or camera about another
  // point; f = focal length in pixels), nothing for a camera turning about its
  // own centre. Measured on the spinning cube (theta 0.07 rad/frame, d ~5.5, f
  // 133 px): median 0.003 px, max 0.011 px against Cycles' Vector
  // (tests/blender/test_motion_vectors.py). Depths at or beyond 65504 read as
  // background.
  const float d = *depth.at(x, y);
  if (isBackgroundDepth(d)) {
    out.flags.setUint(x, y, backgroundMotion(s, x, y, m));
    return;
  }
  if (!(d > 0.0f) || !std::isfinite(d)) {
    out.flags.setUint(x, y, kMotionInvalidPoint);
    return;
  }
  // Camera-space point on pixel (x, y)'s ray of the jittered projection at
  // planar depth d (camera looks down -Z): solve the two rows of clip = P *
  // (X, Y, Z, 1) with ndc = clip.xy / clip.w for X and Y. Works for
  // perspective and orthographic projections alike.
  const double ndcX = 2.0 * (x + 0.5) / W - 1.0;
  const double Z = -double(d);
  const double a00 = P.m[0][0] - ndcX * P.m[3][0], a01 = P.m[0][1] - ndcX * P.m[3][1];
  const double a10 = P.m[1][0] - ndcY * P.m[3][0], a11 = P.m[1][1] - ndcY * P.m[3][1];
  const double b0 = ndcX * (P.m[3][2] * Z + P.m[3][3]) - P.m[0][2] * Z - P.m[0][3];
  const double b1 = ndcY * (P.m[3][2] * Z + P.m[3][3]) - P.m[1][2] * Z - P.m[1][3];
  const double det = a00 * a11 - a01 * a10;
  const Vec4d point{(b0 * a11 - a01 * b1) / det, (a00 * b1 - b0 * a10) / det, Z, 1.0};
  double cx, cy;
  if (det == 0.0 || !toPixel(s.currentClip * point, W, H, cx, cy)) {
    out.flags.setUint(x, y, kMotionInvalidPoint);
    return;
  }
  const Chain *toPrevious, *toNext;
  std::uint32_t flags = s.chainsOf(s.idAt(x, y), toPrevious, toNext);
  double px = 0.0, py = 0.0;
  bool projects = toPrevious->valid && toPixel(toPrevious->toClip * point, W, H, px, py);
  flags |= pairOutcome(toPrevious->valid, projects, snapStill(px - cx), snapStill(py - cy), m, kMotionPreviousValid);
  if (toNext) {
    projects = toNext->valid && toPixel(toNext->toClip * point, W, H, px, py);
    flags |= pairOutcome(toNext->valid, projects, snapStill(cx - px), snapStill(cy - py), m + 2, kMotionNextValid);
  }
  out.flags.setUint(x, y, flags);
}

// ---- four pixels a group, two groups a step --------------------------------
// The same IEEE operations in the same order as motionOfPixel on four lanes of
// doubles (the build has no FMA contraction), so the same bits: the
// divisions, whose latency bounds the scalar loop, run four at once, and two
// groups' chains of them overlap. GCC vector types: two SSE2 operations per
// step in the baseline copy, one AVX one in the AVX2 copy. (Eight lanes in
// one 64-byte GCC vector ran 3 times slower: GCC 12 lowers it lane by lane.)
// Every lane helper is always inlined into the two row copies: no vector value
// crosses a call, so GCC's -Wpsabi note on AVX-sized arguments says nothing here.
#pragma GCC diagnostic ignored "-Wpsabi"
#define CRISP_MOTION_INLINE inline __attribute__((always_inline))
constexpr int kLanes = 4;
using DL = double __attribute__((vector_size(8 * kLanes)));
using ML = long long __attribute__((vector_size(8 * kLanes)));  // lane masks: -1 true, 0 false

CRISP_MOTION_INLINE DL splat(double v) {
  DL r;
  for (int l = 0; l < kLanes; ++l) r[l] = v;  // (not DL{} + v, which turns -0 into +0)
  return r;
}

struct PixelLanes {  // toPixel on the lanes
  DL x, y;
  ML ok;
};

CRISP_MOTION_INLINE PixelLanes toPixelLanes(const DL clip[3], double width, double height) {
  // clip: x, y, w (the z row is not read)
  PixelLanes r;
  r.x = (clip[0] / clip[2] + 1.0) * 0.5 * width;
  r.y = (1.0 - clip[1] / clip[2]) * 0.5 * height;
  const double big = std::numeric_limits<double>::max();  // |v| <= max: finite (NaN fails)
  const DL ax = r.x < 0.0 ? -r.x : r.x, ay = r.y < 0.0 ? -r.y : r.y;
  r.ok = (clip[2] > kMinCameraDepth) & (ax <= big) & (ay <= big);
  return r;
}

// Rows 0, 1 and 3 of a chain's matrix (x, y, w of the clip point) times the point
// (X, Y, Z, W) (W 1: a point; 0: a direction), each lane with its own chain, as Mat4 * Vec4d sums them.
CRISP_MOTION_INLINE void clipLanes(const Chain* const c[kLanes], DL X, DL Y, DL Z, DL W, DL clip[3]) {
  const int rows[3] = {0, 1, 3};
  bool shared = true;
  for (int l = 1; l < kLanes; ++l) shared &= c[l] == c[0];
  for (int r = 0; r < 3; ++r) {
    DL m[4];
    for (int k = 0; k < 4; ++k) {
      m[k] = splat(c[0]->toClip.m[rows[r]][k]);
      if (!shared)
        for (int l = 1; l < kLanes; ++l) m[k][l] = c[l]->toClip.m[rows[r]][k];
    }
    clip[r] = m[0] * X + m[1] * Y + m[2] * Z + m[3] * W;
  }
}

CRISP_MOTION_INLINE DL snapStillLanes(DL v) {
  const DL a = v < 0.0 ? -v : v;
  return a < 1e-6 ? splat(0.0) : v;
}

// The lanes' (X, Y, Z, W) through the current chain and each lane's previous and next: where they fall in
// the current frame and the motions towards the other two, with motionOfPixel's and backgroundMotion's
// sums and snaps.
struct Projected {
  PixelLanes current, previous, next;
  DL mx, my, nx, ny;
};

template <bool HasNext>
CRISP_MOTION_INLINE void projectLanes(const Setup& s, const Chain* const current[kLanes],
                                      const Chain* const toPrevious[kLanes], const Chain* const toNext[kLanes], DL X,
                                      DL Y, DL Z, DL W, Projected& p) {
  DL clip[3];
  clipLanes(current, X, Y, Z, W, clip);
  p.current = toPixelLanes(clip, s.W, s.H);
  clipLanes(toPrevious, X, Y, Z, W, clip);
  p.previous = toPixelLanes(clip, s.W, s.H);
  p.mx = snapStillLanes(p.previous.x - p.current.x);
  p.my = snapStillLanes(p.previous.y - p.current.y);
  if constexpr (HasNext) {
    clipLanes(toNext, X, Y, Z, W, clip);
    p.next = toPixelLanes(clip, s.W, s.H);
    p.nx = snapStillLanes(p.current.x - p.next.x);
    p.ny = snapStillLanes(p.current.y - p.next.y);
  }
}

// One lane group of a row: its inputs, and what the vector steps leave for
// the per-pixel epilogue.
struct Group {
  int x;
  float depth[kLanes];
  bool background[kLanes];
  bool anyPoint;
  const Chain* toPrevious[kLanes];
  const Chain* toNext[kLanes];
  std::uint32_t flags[kLanes];
  ML pointOk;
  Projected p;
};

// The per-row state of the object lookups: IDs come in runs, and the last
// pixel's lookup serves the next of the same ID.
struct ObjectRun {
  std::uint32_t id = 0, flags = 0;
  const Chain* toPrevious;  // id 0: the static world
  const Chain* toNext;
};

CRISP_MOTION_INLINE void loadGroup(const Image& depth, int x, int y, Group& g) {
  g.x = x;
  g.anyPoint = false;
  for (int l = 0; l < kLanes; ++l) {
    g.depth[l] = *depth.at(x + l, y);
    g.background[l] = isBackgroundDepth(g.depth[l]);
    g.anyPoint |= !g.background[l];
  }
}

CRISP_MOTION_INLINE void groupObjects(const Setup& s, int y, ObjectRun& run, Group& g) {
  for (int l = 0; l < kLanes; ++l) {
    const std::uint32_t id = s.idAt(g.x + l, y);
    if (id != run.id) {
      run.id = id;
      run.flags = s.chainsOf(id, run.toPrevious, run.toNext);
    }
    g.toPrevious[l] = run.toPrevious;
    g.toNext[l] = run.toNext;
    g.flags[l] = run.flags;
  }
}

// motionOfPixel's arithmetic on the group's lanes.
template <bool HasNext>
CRISP_MOTION_INLINE void groupMath(const Setup& s, double ndcY, double a10, double a11,
                                   const Chain* const current[kLanes], Group& g) {
  const Mat4& P = s.P;
  using FL = float __attribute__((vector_size(4 * kLanes)));
  FL depth;
  DL ndcX;
  std::memcpy(&depth, g.depth, sizeof depth);
  std::memcpy(&ndcX, &s.ndcX[std::size_t(g.x)], sizeof ndcX);
  const DL Z = -__builtin_convertvector(depth, DL);
  const DL a00 = P.m[0][0] - ndcX * P.m[3][0], a01 = P.m[0][1] - ndcX * P.m[3][1];
  const DL b0 = ndcX * (P.m[3][2] * Z + P.m[3][3]) - P.m[0][2] * Z - P.m[0][3];
  const DL b1 = ndcY * (P.m[3][2] * Z + P.m[3][3]) - P.m[1][2] * Z - P.m[1][3];
  const DL det = a00 * a11 - a01 * a10;
  const DL X = (b0 * a11 - a01 * b1) / det, Y = (a00 * b1 - b0 * a10) / det;
  projectLanes<HasNext>(s, current, g.toPrevious, g.toNext, X, Y, Z, splat(1.0), g.p);
  g.pointOk = (det != 0.0) & g.p.current.ok;
}

// motionOfPixel's decisions on each lane, and the stores.
template <bool HasNext>
CRISP_MOTION_INLINE void groupFinish(const Setup& s, const Group& g, int y, FrameMotion& out) {
  for (int l = 0; l < kLanes; ++l) {
    const int x = g.x + l;
    const float d = g.depth[l];
    if (g.background[l]) {
      out.flags.setUint(x, y, backgroundMotion(s, x, y, out.motion.at(x, y)));
      continue;
    }
    if (!(d > 0.0f) || !std::isfinite(d) || !g.pointOk[l]) {
      out.flags.setUint(x, y, kMotionInvalidPoint);
      continue;
    }
    float* m = out.motion.at(x, y);
    std::uint32_t f = g.flags[l];
    f |= pairOutcome(g.toPrevious[l]->valid, g.p.previous.ok[l], g.p.mx[l], g.p.my[l], m, kMotionPreviousValid);
    if constexpr (HasNext)
      f |= pairOutcome(g.toNext[l]->valid, g.p.next.ok[l], g.p.nx[l], g.p.ny[l], m + 2, kMotionNextValid);
    out.flags.setUint(x, y, f);
  }
}

// backgroundMotion's arithmetic on a group of background pixels under a camera that turned (skyTurns):
// the same operations in the same order, so the same bits; its decisions and stores stay per lane.
struct SkyGroup {
  int x;
  ML ok;  // the direction projects into the current frame
  Projected p;
};

template <bool HasNext>
CRISP_MOTION_INLINE void skyGroupMath(const Setup& s, double ndcY, const Chain* const current[kLanes],
                                      const Chain* const toPrevious[kLanes], const Chain* const toNext[kLanes],
                                      SkyGroup& g) {
  const Mat4& P = s.P;
  DL ndcX;
  std::memcpy(&ndcX, &s.ndcX[std::size_t(g.x)], sizeof ndcX);
  const double a00 = P.m[0][0], a01 = P.m[0][1], a10 = P.m[1][0], a11 = P.m[1][1];
  const DL b0 = -ndcX * P.m[3][2] + P.m[0][2];
  const double b1 = -ndcY * P.m[3][2] + P.m[1][2];
  const double det = a00 * a11 - a01 * a10;
  const DL X = (b0 * a11 - a01 * b1) / det, Y = (a00 * b1 - b0 * a10) / det;
  projectLanes<HasNext>(s, current, toPrevious, toNext, X, Y, splat(-1.0), splat(0.0), g.p);
  g.ok = (splat(det) != 0.0) & g.p.current.ok;
}

template <bool HasNext>
CRISP_MOTION_INLINE void skyGroupFinish(const Setup& s, const SkyGroup& g, int y, FrameMotion& out) {
  for (int l = 0; l < kLanes; ++l) {
    const int x = g.x + l;
    std::uint32_t f = kMotionBackground;
    if (g.ok[l]) {
      float* m = out.motion.at(x, y);
      f |= pairOutcome(s.staticPrevious.valid, s.staticPrevious.valid && g.p.previous.ok[l], g.p.mx[l], g.p.my[l], m,
                       kMotionPreviousValid);
      if constexpr (HasNext)
        f |= pairOutcome(s.staticNext.valid, s.staticNext.valid && g.p.next.ok[l], g.p.nx[l], g.p.ny[l], m + 2,
                         kMotionNextValid);
    }
    out.flags.setUint(x, y, f);
  }
}

// Row y: two lane groups a step, their arithmetic side by side so that the
// two chains of divisions overlap (one group's latency, not its throughput,
// bounds it), then a last group, then the tail pixel by pixel.
template <bool HasNext>
CRISP_MOTION_INLINE void motionRowLanes(const Setup& s, const Image& depth, int y, FrameMotion& out) {
  const Mat4& P = s.P;
  const double ndcY = 1.0 - 2.0 * (y + 0.5) / s.H;
  const double a10 = P.m[1][0] - ndcY * P.m[3][0], a11 = P.m[1][1] - ndcY * P.m[3][1];
  const Chain staticChain{s.currentClip, true};
  const Chain *current[kLanes], *skyPrevious[kLanes], *skyNext[kLanes];  // the static world's, every lane
  for (int l = 0; l < kLanes; ++l) {
    current[l] = &staticChain;
    skyPrevious[l] = &s.staticPrevious;
    skyNext[l] = &s.staticNext;
  }
  const bool skyTurns = s.skyTurns();
  ObjectRun run;
  run.toPrevious = &s.staticPrevious;
  run.toNext = s.hasNext ? &s.staticNext : nullptr;
  Group a, b;
  int x = 0;
  for (; x + 2 * kLanes <= s.W; x += 2 * kLanes) {
    loadGroup(depth, x, y, a);
    loadGroup(depth, x + kLanes, y, b);
    if (!a.anyPoint && !b.anyPoint) {  // the sky: directions, no points
      if (skyTurns) {
        SkyGroup sa, sb;
        sa.x = x;
        sb.x = x + kLanes;
        skyGroupMath<HasNext>(s, ndcY, current, skyPrevious, skyNext, sa);
        skyGroupMath<HasNext>(s, ndcY, current, skyPrevious, skyNext, sb);
        skyGroupFinish<HasNext>(s, sa, y, out);
        skyGroupFinish<HasNext>(s, sb, y, out);
      } else {  // backgroundMotion's still sky: no arithmetic
        for (int l = 0; l < 2 * kLanes; ++l)
          out.flags.setUint(x + l, y, backgroundMotion(s, x + l, y, out.motion.at(x + l, y)));
      }
      continue;
    }
    groupObjects(s, y, run, a);
    groupObjects(s, y, run, b);
    groupMath<HasNext>(s, ndcY, a10, a11, current, a);
    groupMath<HasNext>(s, ndcY, a10, a11, current, b);
    groupFinish<HasNext>(s, a, y, out);
    groupFinish<HasNext>(s, b, y, out);
  }
  if (x + kLanes <= s.W) {
    loadGroup(depth, x, y, a);
    groupObjects(s, y, run, a);
    groupMath<HasNext>(s, ndcY, a10, a11, current, a);
    groupFinish<HasNext>(s, a, y, out);
    x += kLanes;
  }
  for (; x < s.W; ++x) motionOfPixel(s, depth, x, y, out);
}

void motionRowBaseline(const Setup& s, const Image& depth, int y, FrameMotion& out) {
  if (s.hasNext)
    motionRowLanes<true>(s, depth, y, out);
  else
    motionRowLanes<false>(s, depth, y, out);
}

#ifdef CRISP_TEMPORAL_HAS_AVX2
CRISP_TEMPORAL_AVX2 void motionRowAvx2(const Setup& s, const Image& depth, int y, FrameMotion& out) {
  if (s.hasNext)
    motionRowLanes<true>(s, depth, y, out);
  else
    motionRowLanes<false>(s, depth, y, out);
}
#else
void motionRowAvx2(const Setup& s, const Image& depth, int y, FrameMotion& out) { motionRowBaseline(s, depth, y, out); }
#endif

}  // namespace

FrameMotion reconstructMotion(const Image& depth, const Image* ids, const Sidecar& current, const Sidecar& previous,
                              const Sidecar* next, const std::string& frameLabel, int numThreads, MotionPath path) {
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
  Setup setup{W, H, current.projection, current.projectionUnjittered, staticPrevious, staticNext, next != nullptr,
              std::move(objects), ids, loneObject, std::vector<double>(std::size_t(W)),
              isPerspectiveFromOrigin(current.projection), sameTurn(current, previous),
              next != nullptr && sameTurn(current, *next)};
  for (int x = 0; x < W; ++x) setup.ndcX[std::size_t(x)] = 2.0 * (x + 0.5) / W - 1.0;
  FrameMotion out;
  out.motion = Image(W, H, 4, 0.0f);
  out.flags = Image::uintImage(W, H);
  const bool lanes = path == MotionPath::Fast;
  const bool avx2 = lanes && temporal::useAvx2();
  parallelRows(W, H, numThreads, [&](int y0, int y1) {
    for (int y = y0; y < y1; ++y) {
      if (avx2)
        motionRowAvx2(setup, depth, y, out);
      else if (lanes)
        motionRowBaseline(setup, depth, y, out);
      else
        for (int x = 0; x < W; ++x) motionOfPixel(setup, depth, x, y, out);
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
