// SPDX-License-Identifier: Apache-2.0
#include "io/sidecar.h"

#include <cerrno>
#include <cmath>
#include <cstdint>
#include <cstring>
#include <fstream>
#include <sstream>

#include <nlohmann/json.hpp>

#include "core/error.h"

namespace crisp {

namespace {

using Json = nlohmann::json;

struct Reader {
  const std::string& path;

  [[noreturn]] void bad(const std::string& key, const std::string& what) const {
    invalidData("sidecar '" + path + "': " + (key.empty() ? what : "key '" + key + "' " + what));
  }

  const Json& get(const Json& parent, const std::string& parentKey, const char* name) const {
    const std::string key = parentKey.empty() ? name : parentKey + "." + name;
    if (!parent.is_object()) bad(parentKey, "is not a JSON object");
    auto it = parent.find(name);
    if (it == parent.end()) bad(key, "is missing");
    return *it;
  }

  double number(const Json& v, const std::string& key) const {
    if (!v.is_number()) bad(key, "is not a number");
    const double d = v.get<double>();
    if (!std::isfinite(d)) bad(key, "is not finite");
    return d;
  }

  int integer(const Json& v, const std::string& key) const {
    if (!v.is_number_integer()) bad(key, "is not an integer");
    // get<int> would wrap a larger one (2^32 + 1 read as 1).
    const bool fits = v.is_number_unsigned() ? v.get<std::uint64_t>() <= std::uint64_t(kMaxInteger)
                                             : v.get<std::int64_t>() >= -kMaxInteger && v.get<std::int64_t>() <= kMaxInteger;
    if (!fits) bad(key, "is out of range (" + v.dump() + ")");
    return int(v.get<std::int64_t>());
  }
  // Frame numbers and sizes: far inside int, so that frame + 1 cannot overflow.
  static constexpr std::int64_t kMaxInteger = 1 << 30;

  Mat4 matrix(const Json& v, const std::string& key) const {
    if (!v.is_array() || v.size() != 4) bad(key, "is not a 4x4 matrix (a list of 4 rows)");
    Mat4 m;
    for (int r = 0; r < 4; ++r) {
      const Json& row = v[std::size_t(r)];
      if (!row.is_array() || row.size() != 4) bad(key, "row " + std::to_string(r) + " does not hold 4 numbers");
      for (int c = 0; c < 4; ++c)
        m.m[r][c] = number(row[std::size_t(c)], key + "[" + std::to_string(r) + "][" + std::to_string(c) + "]");
    }
    return m;
  }
};

std::uint32_t parseHashKey(const std::string& text, const Reader& rd) {
  const std::string key = "objects." + text;
  if (text.size() != 8) rd.bad(key, "is not an 8-hex-digit Cryptomatte hash");
  std::uint32_t h = 0;
  for (char ch : text) {
    int d;
    if (ch >= '0' && ch <= '9') d = ch - '0';
    else if (ch >= 'a' && ch <= 'f') d = ch - 'a' + 10;
    else if (ch >= 'A' && ch <= 'F') d = ch - 'A' + 10;
    else rd.bad(key, "is not an 8-hex-digit Cryptomatte hash");
    h = (h << 4) | std::uint32_t(d);
  }
  return h;
}

}  // namespace

Sidecar parseSidecar(const std::string& text, const std::string& path) {
  Reader rd{path};
  Json root;
  try {
    root = Json::parse(text);
  } catch (const Json::exception& e) {  // parse_error, and out_of_range for a number beyond double (1e999)
    rd.bad("", std::string("is not valid JSON (") + e.what() + ")");
  }
  if (!root.is_object()) rd.bad("", "is not a JSON object");

  Sidecar s;
  s.path = path;
  s.frame = rd.integer(rd.get(root, "", "frame"), "frame");

  const Json& settings = rd.get(root, "", "render_settings");
  const Json& res = rd.get(settings, "render_settings", "resolution");
  if (!res.is_array() || res.size() != 2) rd.bad("render_settings.resolution", "is not [width, height]");
  s.width = rd.integer(res[0], "render_settings.resolution[0]");
  s.height = rd.integer(res[1], "render_settings.resolution[1]");
  if (s.width < 1 || s.height < 1 || s.width > (1 << 16) || s.height > (1 << 16))
    rd.bad("render_settings.resolution", "is out of range (" + std::to_string(s.width) + "x" + std::to_string(s.height) + ")");

  if (settings.is_object() && settings.contains("filter_size")) {
    s.filterSize = rd.number(settings["filter_size"], "render_settings.filter_size");
    if (!(s.filterSize >= 0.0)) rd.bad("render_settings.filter_size", "is negative");
  }

  const Json& jitter = rd.get(root, "", "jitter");
  s.jitterX = rd.number(rd.get(jitter, "jitter", "x"), "jitter.x");
  s.jitterY = rd.number(rd.get(jitter, "jitter", "y"), "jitter.y");

  const Json& camera = rd.get(root, "", "camera");
  if (camera.is_object() && camera.contains("name")) {
    if (!camera["name"].is_string()) rd.bad("camera.name", "is not a string");
    s.camera = camera["name"].get<std::string>();
  }
  s.view = rd.matrix(rd.get(camera, "camera", "view"), "camera.view");
  s.projection = rd.matrix(rd.get(camera, "camera", "projection"), "camera.projection");
  s.projectionUnjittered = rd.matrix(rd.get(camera, "camera", "projection_unjittered"), "camera.projection_unjittered");

  const Json& objects = rd.get(root, "", "objects");
  if (!objects.is_object()) rd.bad("objects", "is not a JSON object (hash -> object)");
  for (auto it = objects.begin(); it != objects.end(); ++it) {
    const std::string key = "objects." + it.key();
    const std::uint32_t hash = parseHashKey(it.key(), rd);
    SidecarObject ob;
    const Json& name = rd.get(it.value(), key, "name");
    if (!name.is_string()) rd.bad(key + ".name", "is not a string");
    ob.name = name.get<std::string>();
    ob.world = rd.matrix(rd.get(it.value(), key, "matrix_world"), key + ".matrix_world");
    if (it.value().contains("geometry")) {
      const Json& geometry = it.value()["geometry"];
      if (!geometry.is_string()) rd.bad(key + ".geometry", "is not a string (a digest of the geometry)");
      ob.geometry = geometry.get<std::string>();
    }
    if (it.value().contains("deforms")) {
      const Json& deforms = it.value()["deforms"];
      if (!deforms.is_boolean()) rd.bad(key + ".deforms", "is not true or false");
      ob.deforms = deforms.get<bool>();
    }
    s.objects[hash] = std::move(ob);
  }
  return s;
}

Sidecar readSidecar(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  if (!in) ioError("cannot open sidecar '" + path + "': " + std::strerror(errno));
  std::ostringstream text;
  text << in.rdbuf();
  if (in.bad()) ioError("cannot read sidecar '" + path + "'");
  return parseSidecar(text.str(), path);
}

std::string sidecarPathFor(const std::string& framePath) {
  const std::size_t slash = framePath.find_last_of('/');
  const std::size_t dot = framePath.find_last_of('.');
  const std::size_t nameStart = slash == std::string::npos ? 0 : slash + 1;
  if (dot == std::string::npos || dot <= nameStart) return framePath + ".json";
  return framePath.substr(0, dot) + ".json";
}

bool sameCameraAndObjects(const Sidecar& a, const Sidecar& b) {
  if (a.view.m != b.view.m || a.projectionUnjittered.m != b.projectionUnjittered.m || a.objects.size() != b.objects.size())
    return false;
  for (const auto& [hash, object] : a.objects) {
    const SidecarObject* other = b.object(hash);
    if (!other || other->world.m != object.world.m) return false;
    if (other->geometry != object.geometry || other->deforms || object.deforms) return false;
  }
  return true;
}

std::string shotBreak(const Sidecar& previous, const Sidecar& next) {
  if (!previous.camera.empty() && !next.camera.empty() && next.camera != previous.camera)
    return "camera '" + next.camera + "' after '" + previous.camera + "'";
  if (next.frame != previous.frame + 1)
    return "frame " + std::to_string(next.frame) + " after frame " + std::to_string(previous.frame);
  return "";
}

bool sequenceIsStill(const std::vector<std::string>& sidecarPaths) {
  for (std::size_t i = 1; i < sidecarPaths.size(); ++i) {
    const Sidecar a = readSidecar(sidecarPaths[i - 1]), b = readSidecar(sidecarPaths[i]);
    if (shotBreak(a, b).empty() && !sameCameraAndObjects(a, b)) return false;
  }
  return true;
}

}  // namespace crisp
