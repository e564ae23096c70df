// SPDX-License-Identifier: Apache-2.0
// crispAttachFrameSubsamples (RSAA's geometric sub-samples, issue 5) through
// the shared library only: the errors a caller sees, with real files written
// by the library itself. The success path (Blender's multilayer files) is
// covered by tests/unit/test_rsaa.cpp (RsaaFiles) and tests/python/test_rsaa_e2e.py.
#include <gtest/gtest.h>
#include <unistd.h>

#include <cstdio>
#include <filesystem>
#include <fstream>
#include <initializer_list>
#include <string>
#include <vector>

#include "crisp/crisp.h"

namespace {

namespace fs = std::filesystem;

std::string lastError(CrispError* code) {
  const char* m = nullptr;
  *code = crispGetError(&m);
  return m ? m : "";
}

class RsaaApi : public ::testing::Test {
 protected:
  void SetUp() override {
    dir = fs::temp_directory_path() / ("crisp_rsaa_api_" + std::to_string(::getpid()));
    fs::create_directories(dir);
    context = crispNewContext();
    crispCommitContext(context);
    std::vector<float> grey(4 * 3 * 4, 0.5f);
    // Plain RGBA EXRs: a frame and 8 "sub-samples" that hold no Depth/Normal pass.
    crispWriteImage(context, (dir / "frame_0001.exr").c_str(), grey.data(), CRISP_FORMAT_FLOAT4, 4, 3, 0, 0);
    for (int k = 0; k < 8; ++k)
      crispWriteImage(context, (dir / ("frame_0001_sub" + std::to_string(k) + ".exr")).c_str(), grey.data(),
                      CRISP_FORMAT_FLOAT4, 4, 3, 0, 0);
    ASSERT_EQ(crispGetError(nullptr), CRISP_ERROR_NONE);
    frame = crispLoadFrame(context, (dir / "frame_0001.exr").c_str());
    ASSERT_NE(frame, nullptr);
  }
  void TearDown() override {
    crispReleaseFrame(frame);
    crispReleaseContext(context);
    std::error_code ec;
    fs::remove_all(dir, ec);
  }
  // The add-on's sidecar with the default pattern (x right, y up), or without the list.
  void writeSidecar(bool withList) {
    const float x[8] = {-0.375f, 0.125f, 0.375f, -0.125f, -0.25f, 0.25f, 0.25f, -0.25f};
    const float y[8] = {-0.125f, -0.375f, 0.125f, 0.375f, 0.25f, 0.25f, -0.25f, -0.25f};
    std::string list;
    for (int k = 0; k < 8; ++k) {
      char buf[120];
      std::snprintf(buf, sizeof buf, "%s{\"offset\": [%g, %g], \"file\": \"frame_0001_sub%d.exr\"}", k ? "," : "",
                    double(x[k]), double(y[k]), k);
      list += buf;
    }
    std::ofstream((dir / "frame_0001.json").string())
        << R"({"frame": 1, "render_settings": {"resolution": [4, 3]}, "jitter": {"x": 0, "y": 0},
              "camera": {"view": [[1,0,0,0],[0,1,0,0],[0,0,1,0],[0,0,0,1]],
                         "projection": [[2,0,0,0],[0,2.6,0,0],[0,0,-1,-0.2],[0,0,-1,0]],
                         "projection_unjittered": [[2,0,0,0],[0,2.6,0,0],[0,0,-1,-0.2],[0,0,-1,0]]},
              "objects": {})"
        << (withList ? ", \"subsamples\": [" + list + "]" : std::string()) << "}";
  }
  // crispAttachFrameSubsamples with a new filter of `type` must fail with `expected`, naming each needle.
  void expectAttachError(const char* type, CrispError expected, std::initializer_list<const char*> needles) {
    CrispFilter filter = crispNewFilter(context, type);
    crispAttachFrameSubsamples(context, frame, filter);
    CrispError code;
    const std::string msg = lastError(&code);
    EXPECT_EQ(code, expected) << msg;
    for (const char* n : needles) EXPECT_NE(msg.find(n), std::string::npos) << msg;
    crispReleaseFilter(filter);
  }
  fs::path dir;
  CrispContext context = nullptr;
  CrispFrame frame = nullptr;
};

TEST_F(RsaaApi, NullArgumentsAreErrors) {
  CrispError code;
  crispAttachFrameSubsamples(context, nullptr, nullptr);
  EXPECT_NE(lastError(&code).find("frame"), std::string::npos);
  EXPECT_NE(code, CRISP_ERROR_NONE);
}

TEST_F(RsaaApi, SidecarMissingOrWithoutListIsNamed) {
  CrispError code;
  crispAttachFrameSubsamples(context, frame, nullptr);
  std::string msg = lastError(&code);
  EXPECT_EQ(code, CRISP_ERROR_IO) << msg;
  EXPECT_NE(msg.find("frame_0001.json"), std::string::npos) << msg;
  writeSidecar(false);
  crispAttachFrameSubsamples(context, frame, nullptr);
  msg = lastError(&code);
  EXPECT_EQ(code, CRISP_ERROR_INVALID_DATA) << msg;
  EXPECT_NE(msg.find("not rendered for rsaa"), std::string::npos) << msg;
}

TEST_F(RsaaApi, SubsampleWithoutGeometryIsNamedAndTheFrameKeepsItsPasses) {
  writeSidecar(true);
  expectAttachError("rsaa", CRISP_ERROR_INVALID_DATA, {"frame_0001_sub0.exr", "'depth'"});
  EXPECT_STREQ(crispGetFramePasses(frame), "color");
}

TEST_F(RsaaApi, OnlyRsaaTakesTheCamera) {
  writeSidecar(true);
  expectAttachError("fxaa", CRISP_ERROR_INVALID_ARGUMENT, {"fxaa"});
}

}  // namespace
