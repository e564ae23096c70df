// SPDX-License-Identifier: Apache-2.0
// RSAA's geometric sub-samples of a frame (issue 5, seed 003 section 4.4):
// the Blender add-on (addon/crisp/render.py, _render_subsamples) renders 8
// depth + normal images frame_NNNN_subK.exr at the RSAA pattern's offsets and
// lists them in the frame's sidecar:
//   "subsamples": [{"offset": [x, y] (pixels, x right, y UP), "file": "frame_0001_sub0.exr", "render_s": ..}, ..]
// attachSubsamples() reads them into the frame as the pass "subsamples" (one
// 80-byte record per pixel, rsaa/subsample_record.h, Format::RsaaSubsamples:
// what the rsaa filter reads) and as passes sub0..sub7 (float4: world normal
// xyz, planar depth in w; the filter's other accepted form, and eval's
// geometric-edge map), and rsaaCameraParams() gives the filter's camera
// parameters from the sidecar.
//
// Header-only so that crisp_core, the CLI and libcrisp get it without a
// build-file change (native/CMakeLists.txt is shared).
#pragma once

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <fstream>
#include <sstream>
#include <string>
#include <utility>
#include <vector>

#include <nlohmann/json.hpp>

#include "core/error.h"
#include "core/filter.h"
#include "io/frame.h"
#include "io/sidecar.h"
#include "rsaa/offset_table.h"
#include "rsaa/subsample_record.h"

namespace crisp {

// Pass names of the sub-samples in a Frame, in the pattern's order.
inline std::string subsamplePass(int k) { return "sub" + std::to_string(k); }
// The pass (and rsaa image) holding all 8 as packed records.
constexpr const char* kPackedSubsamplePass = "subsamples";

// One sub-sample file as the sidecar lists it.
struct SubsampleEntry {
  double offsetX = 0.0, offsetY = 0.0;  // pixels, x right, y UP (the add-on's convention)
  std::string file;                     // path (resolved against the sidecar's folder)
  double renderSeconds = 0.0;           // time Blender took for it (0 if not recorded)
};

// The sidecar's "subsamples" list, checked: 8 entries whose offsets are the
// pattern the shipped offset table was generated for (rsaa::kTablePattern,
// library y down = the add-on's y negated). Throws CRISP_ERROR_INVALID_DATA
// naming the sidecar and what is wrong (no list: the frame was not rendered
// for rsaa).
inline std::vector<SubsampleEntry> readSubsampleList(const std::string& sidecarPath) {
  std::ifstream in(sidecarPath, std::ios::binary);
  if (!in) ioError("cannot open sidecar '" + sidecarPath + "' (rsaa reads the sub-sample list and camera from it)");
  std::ostringstream text;
  text << in.rdbuf();
  nlohmann::json root;
  try {
    root = nlohmann::json::parse(text.str());
  } catch (const nlohmann::json::parse_error& e) {
    invalidData("sidecar '" + sidecarPath + "' is not valid JSON (" + e.what() + ")");
  }
  const auto bad = [&](const std::string& what) { invalidData("sidecar '" + sidecarPath + "': " + what); };
  // crisp render --method rsaa renders no geometry when no object is visible (plan.py) and passes the
  // colour through: such a frame was made for rsaa (made_with) with a plan without sub-samples (passes).
  const auto has = [&](const char* key) { return root.is_object() && root.contains(key); };
  const bool planWithoutGeometry =
      has("made_with") && root["made_with"].is_object() && root["made_with"].contains("method") &&
      root["made_with"]["method"] == "rsaa" && has("passes") && root["passes"].is_array() &&
      std::find(root["passes"].begin(), root["passes"].end(), "subsamples") == root["passes"].end();
  if (planWithoutGeometry && !has("subsamples"))
    bad("has no 'subsamples' list: the frame was rendered for rsaa with no visible object, so without geometry "
        "(crisp render --method rsaa keeps such frames' colour as rendered; filter them with -m none)");
  if (!root.is_object() || !root.contains("subsamples"))
    bad("has no 'subsamples' list: the frame was not rendered for rsaa (crisp render --method rsaa renders the 8 "
        "geometric sub-samples frame_NNNN_sub0..7.exr)");
  const nlohmann::json& list = root["subsamples"];
  if (!list.is_array() || list.size() != std::size_t(rsaa::kSamples))
    bad("'subsamples' is not a list of " + std::to_string(rsaa::kSamples) + " entries");
  std::string dir;
  const std::size_t slash = sidecarPath.find_last_of('/');
  if (slash != std::string::npos) dir = sidecarPath.substr(0, slash + 1);
  std::vector<SubsampleEntry> out;
  for (int k = 0; k < rsaa::kSamples; ++k) {
    const nlohmann::json& e = list[std::size_t(k)];
    const std::string key = "subsamples[" + std::to_string(k) + "]";
    if (!e.is_object() || !e.contains("file") || !e["file"].is_string()) bad("key '" + key + ".file' is missing");
    if (!e.contains("offset") || !e["offset"].is_array() || e["offset"].size() != 2 || !e["offset"][0].is_number() ||
        !e["offset"][1].is_number())
      bad("key '" + key + ".offset' is not [x, y]");
    SubsampleEntry s;
    s.offsetX = e["offset"][0].get<double>();
    s.offsetY = e["offset"][1].get<double>();
    const std::string file = e["file"].get<std::string>();
    s.file = !file.empty() && file[0] == '/' ? file : dir + file;
    if (e.contains("render_s") && e["render_s"].is_number()) s.renderSeconds = e["render_s"].get<double>();
    // The offset table was fitted for one pattern; another pattern's samples would get wrong offsets.
    if (std::fabs(s.offsetX - rsaa::kTablePattern.x[k]) > 1e-6 || std::fabs(-s.offsetY - rsaa::kTablePattern.y[k]) > 1e-6) {
      char buf[200];
      std::snprintf(buf, sizeof buf, "%s.offset is (%g, %g) but the offset table was built for (%g, %g) (x right, y up)",
                    key.c_str(), s.offsetX, s.offsetY, double(rsaa::kTablePattern.x[k]), double(-rsaa::kTablePattern.y[k]));
      bad(buf);
    }
    out.push_back(std::move(s));
  }
  return out;
}

// Reads the sub-sample files listed in `sidecarPath` into frame.passes
// sub0..sub7 (float4: normal xyz, depth) and "subsamples" (the same values as
// packed records: depth as is, normals snorm16). Each file must hold Depth
// and Normal passes at the frame's size. Throws naming the file; the frame is
// unchanged then.
inline void attachSubsamples(Frame& frame, const std::string& sidecarPath) {
  const std::vector<SubsampleEntry> list = readSubsampleList(sidecarPath);
  std::vector<Image> packedAll;  // the frame changes only when every file is good
  for (int k = 0; k < rsaa::kSamples; ++k) {
    const std::string& file = list[std::size_t(k)].file;
    std::ifstream probe(file, std::ios::binary);
    if (!probe)
      ioError("sub-sample " + std::to_string(k) + " '" + file + "' (listed in '" + sidecarPath +
              "') does not exist or cannot be read; render the frame again with crisp render --method rsaa");
    const Frame sub = readGeometryFrame(file);  // its colour is not used
    if (sub.width != frame.width || sub.height != frame.height)
      invalidData("sub-sample " + std::to_string(k) + " '" + file + "' is " + std::to_string(sub.width) + "x" +
                  std::to_string(sub.height) + " but frame '" + frame.path + "' is " + std::to_string(frame.width) + "x" +
                  std::to_string(frame.height));
    for (const char* role : {"depth", "normal"})
      if (!sub.has(role))
        invalidData("sub-sample " + std::to_string(k) + " '" + file + "' has no '" + role + "' pass (has: " +
                    sub.passList() + ")");
    const Image& depth = sub.pass("depth");
    const Image& normal = sub.pass("normal");
    Image packed(frame.width, frame.height, 4);
    const std::size_t n = std::size_t(frame.width) * std::size_t(frame.height);
    for (std::size_t i = 0; i < n; ++i) {
      float* p = packed.data.data() + 4 * i;
      const float* nrm = normal.data.data() + std::size_t(normal.channels) * i;
      p[0] = nrm[0];
      p[1] = nrm[1];
      p[2] = nrm[2];
      p[3] = depth.data[std::size_t(depth.channels) * i];
    }
    packedAll.push_back(std::move(packed));
  }
  Image records = rsaa::packSubsamples(packedAll.data());
  for (int k = 0; k < rsaa::kSamples; ++k) frame.passes[subsamplePass(k)] = std::move(packedAll[std::size_t(k)]);
  frame.passes[kPackedSubsamplePass] = std::move(records);
}

// The names of the rsaa filter's camera parameters, in rsaaCameraParams' order.
inline const std::vector<std::string>& rsaaCameraParamNames() {
  static const std::vector<std::string> names = {"orthographic", "proj00", "proj11", "proj02", "proj12",
                                                 "view00",       "view01", "view02", "view10", "view11",
                                                 "view12",       "view20", "view21", "view22"};
  return names;
}

// The rsaa filter's camera parameters from a sidecar: projection terms
// (jitter included, as the frame was rendered) and the rotation rows of the
// world->view matrix. Orthographic when projection[3][3] == 1.
inline std::vector<std::pair<std::string, double>> rsaaCameraParams(const Sidecar& s) {
  const auto& P = s.projection.m;
  const bool ortho = P[3][3] == 1.0;
  if (P[0][0] == 0.0 || P[1][1] == 0.0)
    invalidData("sidecar '" + s.path + "': camera.projection has a zero focal term ([0][0] or [1][1])");
  std::vector<double> values = {ortho ? 1.0 : 0.0, P[0][0], P[1][1], ortho ? 0.0 : P[0][2], ortho ? 0.0 : P[1][2]};
  for (int r = 0; r < 3; ++r)
    for (int c = 0; c < 3; ++c) values.push_back(s.view.m[r][c]);
  std::vector<std::pair<std::string, double>> out;
  for (std::size_t i = 0; i < values.size(); ++i) out.emplace_back(rsaaCameraParamNames()[i], values[i]);
  return out;
}

// Whether name is one of the parameters rsaaCameraParams gives (the sidecar
// decides them: a caller's value is replaced frame by frame).
inline bool isRsaaCameraParam(const std::string& name) {
  const auto& names = rsaaCameraParamNames();
  return std::find(names.begin(), names.end(), name) != names.end();
}

// Whether the filter reads geometric sub-samples (rsaa).
inline bool readsSubsamples(const Filter& filter) {
  for (const ImageRole& role : filter.roles())
    if (subsamplePass(0) == role.name) return true;
  return false;
}

// Sets the rsaa filter's camera parameters from the frame's sidecar (its
// path with ".json"); marks the filter dirty only when a value changes, so a
// sequence from one camera commits once. All or none: a value the filter
// refuses leaves every parameter as it was (they are set on a copy first).
inline void applyRsaaCamera(Filter& filter, const Frame& frame) {
  if (!readsSubsamples(filter))
    invalidArgument(std::string("filter '") + filter.type() + "' reads no geometric sub-samples (only rsaa does)");
  bool changed = false;
  ParamSet p = filter.params();
  for (const auto& [name, value] : rsaaCameraParams(readSidecar(sidecarPathFor(frame.path)))) {
    if (name == "orthographic") {
      if (p.getBool(name) != (value != 0.0)) {
        p.setBool(name, value != 0.0);
        changed = true;
      }
    } else if (p.getFloat(name) != float(value)) {
      p.setFloat(name, float(value));
      changed = true;
    }
  }
  if (!changed) return;
  filter.params() = std::move(p);
  filter.markDirty("the camera parameters were set from sidecar '" + sidecarPathFor(frame.path) + "'");
}

// Everything rsaa needs beyond the frame's own passes: the sub-samples (if
// not attached yet) and the camera.
inline void attachRsaaInputs(Filter& filter, Frame& frame) {
  if (!readsSubsamples(filter))
    invalidArgument(std::string("filter '") + filter.type() + "' reads no geometric sub-samples (only rsaa does)");
  if (!frame.has(kPackedSubsamplePass)) attachSubsamples(frame, sidecarPathFor(frame.path));
  applyRsaaCamera(filter, frame);
}

}  // namespace crisp
