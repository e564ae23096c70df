// SPDX-License-Identifier: Apache-2.0
// The per-frame JSON sidecar the Blender add-on writes next to each input EXR
// (addon/crisp/render.py, render_frames): frame number, sub-pixel jitter,
// camera matrices with and without jitter, resolution, and the world matrix
// of every visible object keyed by its Cryptomatte hash.
#pragma once

#include <cstdint>
#include <map>
#include <string>
#include <vector>

#include "motion/matrix.h"

namespace crisp {

struct SidecarObject {
  std::string name;
  Mat4 world;            // object -> world ("matrix_world")
  std::string geometry;  // "geometry": digest of its evaluated vertices, for an object that may deform; else ""
  bool deforms = false;  // "deforms": its settings make it deform, and it has no digest (plan.geometry_record)
};

struct Sidecar {
  std::string path;
  int frame = 0;
  int width = 0;   // render_settings.resolution (pixels, percentage applied)
  int height = 0;
  // Sub-pixel jitter as the add-on writes it: pixels, x RIGHT, y UP (camera
  // shift moved every sample point by (+jitterX, +jitterY)). 0 when disabled.
  double jitterX = 0.0;
  double jitterY = 0.0;
  // render_settings.filter_size: Blender's Film > Filter Size (px), the pixel
  // filter the frame was jittered over and EEVEE filters with; < 0 when the
  // sidecar does not give it.
  double filterSize = -1.0;
  std::string camera;         // camera.name: the scene's camera this frame, by its full name (empty if not given)
  Mat4 view;                  // world -> camera (camera.view; camera looks down -Z)
  Mat4 projection;            // camera -> clip, with the jitter shift (camera.projection)
  Mat4 projectionUnjittered;  // camera -> clip, without it (camera.projection_unjittered)
  std::map<std::uint32_t, SidecarObject> objects;  // Cryptomatte hash -> object

  const SidecarObject* object(std::uint32_t hash) const {
    auto it = objects.find(hash);
    return it == objects.end() ? nullptr : &it->second;
  }
};

// Reads and checks a sidecar. Throws CRISP_ERROR_IO if the file cannot be
// read, CRISP_ERROR_INVALID_DATA naming the file and the key (e.g.
// "camera.projection_unjittered") if the JSON is malformed, a key is missing
// or a value has the wrong type/shape.
Sidecar readSidecar(const std::string& path);
// The same from text; `path` only names the source in messages.
Sidecar parseSidecar(const std::string& text, const std::string& path);

// The sidecar path of a frame file: the same path with the extension replaced
// by ".json" (frame_0003.exr -> frame_0003.json).
std::string sidecarPathFor(const std::string& framePath);

// True when the two frames have the same camera (view and unjittered
// projection) and the same objects at the same world matrices with the same
// geometry (digests equal, neither "deforms"): nothing moves between them, so
// they need no motion vectors (jitter is not motion).
bool sameCameraAndObjects(const Sidecar& a, const Sidecar& b);
// Why `next` does not continue the shot of `previous`, where a temporal
// filter's history starts over: "camera 'B' after 'A'" (a cut at a timeline
// marker) or "frame 8 after frame 3" (a gap in the frame numbers); "" if it is
// the next frame of the same camera. Cameras are compared only when both
// sidecars name one (older builds named none).
std::string shotBreak(const Sidecar& previous, const Sidecar& next);
// The same as sameCameraAndObjects over a sequence of sidecar files
// (consecutive pairs), except across a shotBreak: nothing is reprojected there.
bool sequenceIsStill(const std::vector<std::string>& sidecarPaths);

}  // namespace crisp
