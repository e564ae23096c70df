// SPDX-License-Identifier: Apache-2.0
// The per-frame JSON sidecar reader (io/sidecar.h): a sidecar shaped exactly as
// addon/crisp/render.py writes it, every required key missing in turn, wrong
// types and shapes, broken JSON, unreadable files, and the .exr -> .json path.
#include <gtest/gtest.h>
#include <unistd.h>

#include <cstdint>
#include <filesystem>
#include <fstream>
#include <string>

#include <nlohmann/json.hpp>

#include "core/error.h"
#include "io/cryptomatte.h"
#include "io/sidecar.h"

using namespace crisp;
using Json = nlohmann::json;
namespace fs = std::filesystem;

namespace {

// Keys and layout of render.py's render_frames sidecar (values from a real 96x54 render).
Json addonSidecar() {
  return Json::parse(R"json({
 "frame": 2, "file": "frame_0002.exr",
 "jitter": {"x": 0.14410602351926033, "y": -0.2579012933898057, "units": "pixels, x right, y up",
            "enabled": true, "sequence": "halton(2,3)", "index": 3, "period": 16,
            "distribution": "blackman-harris", "width": 1.5},
 "camera": {"name": "Camera",
   "matrix_world": [[1,0,0,0],[0,0.3846154510974884,-0.923076868057251,-6.0],[0,0.923076868057251,0.3846154510974884,2.5],[0,0,0,1]],
   "view": [[1,-0.0,0,-0.0],[-0.0,0.3846154510974884,0.923076868057251,7.152557373046875e-07],[0,-0.923076868057251,0.3846154510974884,-6.5],[-0.0,0,-0.0,1]],
   "projection": [[2.7777774333953857,0,0.00300222123041749,0],[0,4.9382710456848145,-0.00955191906541586,0],[0,0,-1.0001999139785767,-0.20002000033855438],[0,0,-1,0]],
   "projection_unjittered": [[2.777777671813965,0,0,0],[0,4.9382710456848145,0,0],[0,0,-1.0001999139785767,-0.20002000033855438],[0,0,-1,0]],
   "type": "PERSP", "base_shift": [0.0, 0.0]},
 "objects": {"a8fce865": {"name": "Cube", "matrix_world": [[0.9976687431335449,-0.06822473555803299,0.0015534156700596213,0],[0.06824241578578949,0.997410237789154,-0.022710133343935013,0],[0,0.022763198241591454,0.9997408986091614,0],[0,0,0,1]]}},
 "passes": ["color", "depth", "motion"], "render_flags": ["use_pass_combined", "use_pass_z"],
 "render_settings": {"engine": "BLENDER_EEVEE", "samples": 1, "resolution": [96, 54], "pixel_aspect": [1.0, 1.0],
                     "filter_size": 1.5, "film_transparent": false},
 "blender_version": "3.4.1", "render_s": 0.148
})json");
}

void expectInvalid(const Json& j, const std::string& needle) {
  try {
    parseSidecar(j.dump(), "/x/frame_0002.json");
    ADD_FAILURE() << "expected an error mentioning '" << needle << "'";
  } catch (const Exception& e) {
    EXPECT_EQ(e.code(), CRISP_ERROR_INVALID_DATA);
    const std::string msg = e.what();
    EXPECT_NE(msg.find("/x/frame_0002.json"), std::string::npos) << msg;
    EXPECT_NE(msg.find(needle), std::string::npos) << msg;
  }
}

}  // namespace

TEST(Sidecar, ReadsEverythingTheAddonWrites) {
  const Sidecar s = parseSidecar(addonSidecar().dump(), "frame_0002.json");
  EXPECT_EQ(s.path, "frame_0002.json");
  EXPECT_EQ(s.frame, 2);
  EXPECT_EQ(s.width, 96);
  EXPECT_EQ(s.height, 54);
  EXPECT_DOUBLE_EQ(s.jitterX, 0.14410602351926033);
  EXPECT_DOUBLE_EQ(s.jitterY, -0.2579012933898057);
  EXPECT_DOUBLE_EQ(s.filterSize, 1.5);
  // Rows as written (m[row][col]): the translation is the last column.
  EXPECT_DOUBLE_EQ(s.view.m[2][3], -6.5);
  EXPECT_DOUBLE_EQ(s.view.m[1][2], 0.923076868057251);
  EXPECT_DOUBLE_EQ(s.projection.m[0][2], 0.00300222123041749);
  EXPECT_DOUBLE_EQ(s.projectionUnjittered.m[0][2], 0.0);
  EXPECT_DOUBLE_EQ(s.projection.m[3][2], -1.0);
  // The jitter is the lens shift of the projection: 2 * jitter / size in NDC.
  EXPECT_NEAR(s.projection.m[0][2], 2.0 * s.jitterX / s.width, 1e-7);
  EXPECT_NEAR(s.projection.m[1][2], 2.0 * s.jitterY / s.height, 1e-7);
  ASSERT_EQ(s.objects.size(), 1u);
  const std::uint32_t cube = cryptomatteHash("Cube");
  EXPECT_EQ(cube, 0xa8fce865u);  // keys are the Cryptomatte hash of the name
  ASSERT_NE(s.object(cube), nullptr);
  EXPECT_EQ(s.object(cube)->name, "Cube");
  EXPECT_DOUBLE_EQ(s.object(cube)->world.m[1][0], 0.06824241578578949);
  EXPECT_EQ(s.object(0x12345678u), nullptr);
}

TEST(Sidecar, EachMissingKeyIsNamed) {
  const char* const paths[][2] = {{"frame", ""},          {"render_settings", ""},   {"resolution", "render_settings"},
                                  {"jitter", ""},         {"x", "jitter"},           {"y", "jitter"},
                                  {"camera", ""},         {"view", "camera"},        {"projection", "camera"},
                                  {"projection_unjittered", "camera"}, {"objects", ""}};
  for (const auto& p : paths) {
    Json j = addonSidecar();
    if (*p[1]) j[p[1]].erase(p[0]);
    else j.erase(p[0]);
    const std::string key = *p[1] ? std::string(p[1]) + "." + p[0] : std::string(p[0]);
    expectInvalid(j, "'" + key + "' is missing");
  }
  Json j = addonSidecar();
  j["objects"]["a8fce865"].erase("matrix_world");
  expectInvalid(j, "'objects.a8fce865.matrix_world' is missing");
}

TEST(Sidecar, WrongTypesAndShapesAreNamed) {
  Json j = addonSidecar();
  j["frame"] = "two";
  expectInvalid(j, "'frame' is not an integer");
  j = addonSidecar();
  j["camera"]["view"][2] = Json::array({1, 2, 3});
  expectInvalid(j, "'camera.view' row 2");
  j = addonSidecar();
  j["camera"]["projection"][1][1] = nullptr;
  expectInvalid(j, "'camera.projection[1][1]' is not a number");
  j = addonSidecar();
  j["camera"]["projection_unjittered"] = Json::array();
  expectInvalid(j, "camera.projection_unjittered");
  j = addonSidecar();
  j["render_settings"]["resolution"] = Json::array({96});
  expectInvalid(j, "render_settings.resolution");
  j = addonSidecar();
  j["render_settings"]["resolution"] = Json::array({0, 54});
  expectInvalid(j, "out of range");
  j = addonSidecar();
  j["render_settings"]["filter_size"] = -0.5;
  expectInvalid(j, "'render_settings.filter_size' is negative");
  j = addonSidecar();
  j["render_settings"]["filter_size"] = "1.5";
  expectInvalid(j, "'render_settings.filter_size' is not a number");
  j = addonSidecar();
  j["render_settings"].erase("filter_size");  // older sidecars: not given
  EXPECT_LT(parseSidecar(j.dump(), "frame_0002.json").filterSize, 0.0);
  j = addonSidecar();
  j["objects"]["not-hex!"] = j["objects"]["a8fce865"];
  expectInvalid(j, "'objects.not-hex!' is not an 8-hex-digit");
  j = addonSidecar();
  j["jitter"]["x"] = "0.1";
  expectInvalid(j, "'jitter.x' is not a number");
  j = addonSidecar();
  j["objects"] = Json::array();
  expectInvalid(j, "'objects' is not a JSON object");
  j = addonSidecar();
  j["objects"]["a8fce865"]["geometry"] = 12;
  expectInvalid(j, "'objects.a8fce865.geometry' is not a string");
  j = addonSidecar();
  j["objects"]["a8fce865"]["deforms"] = "yes";
  expectInvalid(j, "'objects.a8fce865.deforms' is not true or false");
}

TEST(Sidecar, BrokenJsonAndMissingFiles) {
  try {
    parseSidecar("{\"frame\": 2, ", "cut.json");
    ADD_FAILURE();
  } catch (const Exception& e) {
    EXPECT_EQ(e.code(), CRISP_ERROR_INVALID_DATA);
    EXPECT_NE(std::string(e.what()).find("cut.json"), std::string::npos);
    EXPECT_NE(std::string(e.what()).find("not valid JSON"), std::string::npos);
  }
  // Python's json.dump writes NaN for a non-finite matrix entry, which is not JSON.
  std::string withNan = addonSidecar().dump();
  withNan.replace(withNan.find("-6.5"), 4, "NaN");
  EXPECT_THROW(parseSidecar(withNan, "nan.json"), Exception);
  try {
    readSidecar("/nonexistent/frame_0007.json");
    ADD_FAILURE();
  } catch (const Exception& e) {
    EXPECT_EQ(e.code(), CRISP_ERROR_IO);
    EXPECT_NE(std::string(e.what()).find("/nonexistent/frame_0007.json"), std::string::npos);
  }
}

// Numbers JSON can hold but the reader's types cannot (found by fuzz_sidecar): a number beyond
// double threw nlohmann's out_of_range past the reader (the CLI said "[json.exception...]"
// without naming the file), and an integer beyond int wrapped (a width of 2^32 + 96 read as 96).
TEST(Sidecar, NumbersBeyondTheirTypesAreNamed) {
  std::string huge = addonSidecar().dump();
  huge.replace(huge.find("-6.5"), 4, "-6e999");
  try {
    parseSidecar(huge, "/x/frame_0002.json");
    ADD_FAILURE() << "a number beyond double was read";
  } catch (const Exception& e) {
    EXPECT_EQ(e.code(), CRISP_ERROR_INVALID_DATA);
    EXPECT_NE(std::string(e.what()).find("/x/frame_0002.json"), std::string::npos) << e.what();
    EXPECT_NE(std::string(e.what()).find("not valid JSON"), std::string::npos) << e.what();
  }
  Json j = addonSidecar();
  j["render_settings"]["resolution"][0] = (std::int64_t(1) << 32) + 96;
  expectInvalid(j, "'render_settings.resolution[0]' is out of range (4294967392)");
  j = addonSidecar();
  j["frame"] = 2147483647;  // frame + 1, the next frame's number, would overflow
  expectInvalid(j, "'frame' is out of range");
  j = addonSidecar();
  j["frame"] = std::uint64_t(1) << 63;
  expectInvalid(j, "'frame' is out of range");
  j = addonSidecar();
  j["frame"] = -(std::int64_t(1) << 62);
  expectInvalid(j, "'frame' is out of range");
  j = addonSidecar();
  j["frame"] = -20;  // Blender's frames may be negative
  EXPECT_EQ(parseSidecar(j.dump(), "f.json").frame, -20);
  j["frame"] = 1 << 30;
  EXPECT_EQ(parseSidecar(j.dump(), "f.json").frame, 1 << 30);
}

TEST(Sidecar, ReadsAFileFromDisk) {
  const fs::path path = fs::temp_directory_path() / ("crisp_sidecar_" + std::to_string(::getpid()) + ".json");
  {
    std::ofstream out(path);
    out << addonSidecar().dump(1);
  }
  const Sidecar s = readSidecar(path.string());
  EXPECT_EQ(s.path, path.string());
  EXPECT_EQ(s.frame, 2);
  EXPECT_EQ(s.objects.size(), 1u);
  fs::remove(path);
}

TEST(Sidecar, PathOfAFrame) {
  EXPECT_EQ(sidecarPathFor("/out/input/frame_0003.exr"), "/out/input/frame_0003.json");
  EXPECT_EQ(sidecarPathFor("frame.v2/frame_0003.exr"), "frame.v2/frame_0003.json");
  EXPECT_EQ(sidecarPathFor("dir.d/frame"), "dir.d/frame.json");
  EXPECT_EQ(sidecarPathFor("/a/.hidden"), "/a/.hidden.json");
}

TEST(Sidecar, StillFramesDifferOnlyInJitter) {
  Json a = addonSidecar(), b = addonSidecar();
  b["frame"] = 3;
  b["jitter"]["x"] = -0.3;  // jitter and its shifted projection are not motion
  b["camera"]["projection"][0][2] = -0.006;
  EXPECT_TRUE(sameCameraAndObjects(parseSidecar(a.dump(), "a.json"), parseSidecar(b.dump(), "b.json")));
  Json moved = b;
  moved["objects"]["a8fce865"]["matrix_world"][0][3] = 0.01;
  EXPECT_FALSE(sameCameraAndObjects(parseSidecar(a.dump(), "a.json"), parseSidecar(moved.dump(), "m.json")));
  Json panned = b;
  panned["camera"]["view"][0][3] = 0.5;
  EXPECT_FALSE(sameCameraAndObjects(parseSidecar(a.dump(), "a.json"), parseSidecar(panned.dump(), "p.json")));
  Json gone = b;
  gone["objects"] = Json::object();
  EXPECT_FALSE(sameCameraAndObjects(parseSidecar(a.dump(), "a.json"), parseSidecar(gone.dump(), "g.json")));
}

// An object reshaped in place (a hook, a lattice: the add-on's plan.geometry_record)
// keeps its matrix; its geometry digest tells the frames apart, and one that
// deforms with no digest is never still.
TEST(Sidecar, GeometryThatChangesInPlaceIsMotion) {
  Json a = addonSidecar(), b = addonSidecar();
  b["frame"] = 3;
  a["objects"]["a8fce865"]["geometry"] = "00ff";
  b["objects"]["a8fce865"]["geometry"] = "00ff";
  EXPECT_EQ(parseSidecar(a.dump(), "a.json").object(0xa8fce865)->geometry, "00ff");
  EXPECT_TRUE(sameCameraAndObjects(parseSidecar(a.dump(), "a.json"), parseSidecar(b.dump(), "b.json")));
  Json reshaped = b;
  reshaped["objects"]["a8fce865"]["geometry"] = "01ff";
  EXPECT_FALSE(sameCameraAndObjects(parseSidecar(a.dump(), "a.json"), parseSidecar(reshaped.dump(), "r.json")));
  Json unmeasured = b;  // an older sidecar: no digest where the other has one
  unmeasured["objects"]["a8fce865"].erase("geometry");
  EXPECT_FALSE(sameCameraAndObjects(parseSidecar(a.dump(), "a.json"), parseSidecar(unmeasured.dump(), "u.json")));
  Json deforming = a;
  deforming["objects"]["a8fce865"].erase("geometry");
  deforming["objects"]["a8fce865"]["deforms"] = true;
  EXPECT_FALSE(sameCameraAndObjects(parseSidecar(deforming.dump(), "d.json"), parseSidecar(deforming.dump(), "d.json")));
  deforming["objects"]["a8fce865"]["deforms"] = false;
  EXPECT_TRUE(sameCameraAndObjects(parseSidecar(deforming.dump(), "d.json"), parseSidecar(deforming.dump(), "d.json")));
}
