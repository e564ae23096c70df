// SPDX-License-Identifier: Apache-2.0
// crispAttachFrameSubsamples (RSAA's geometric sub-samples, issue 5) through
// the shared library only: the errors a caller sees, with real files written
// by the library itself. The success path (Blender's multilayer files) is
// covered by tests/unit/test_rsaa.cpp (RsaaFiles) and tests/python/test_rsaa_e2e.py.
#include <gtest/gtest.h>
#include <unistd.h>

#include <cstdint>
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

// The packed sub-sample record as crisp.h describes CRISP_FORMAT_RSAA_SUBSAMPLES.
struct Record {
  float depth[8];
  std::int16_t nx[8], ny[8], nz[8];
};
static_assert(sizeof(Record) == 80, "80-byte record");

// rsaa through the C API from packed records gives the image it gives from
// the 8 float4 images (a depth step: plane at depth 10 left of x = 7.3, 14
// right of it, normals (0, 0, 1) = snorm 32767); a float4 image is refused
// as "subsamples", an unknown format everywhere.
TEST_F(RsaaApi, PackedRecordsGiveTheFloat4Result) {
  const int W = 16, H = 9;
  const float xs[8] = {-0.375f, 0.125f, 0.375f, -0.125f, -0.25f, 0.25f, 0.25f, -0.25f};
  std::vector<float> color(4 * W * H), depth(W * H), normal(3 * W * H), sub[8];
  std::vector<Record> records(W * H);
  const auto depthAt = [](float x) { return x < 7.3f ? 10.0f : 14.0f; };
  for (auto& s : sub) s.assign(4 * W * H, 0.0f);
  for (int i = 0; i < W * H; ++i) {
    const float x = float(i % W) + 0.5f;
    for (int c = 0; c < 3; ++c) color[4 * i + c] = x < 7.3f ? 0.9f : 0.1f;
    color[4 * i + 3] = 1.0f;
    depth[i] = depthAt(x);
    normal[3 * i + 2] = 1.0f;
    for (int k = 0; k < 8; ++k) {
      sub[k][4 * i + 2] = 1.0f;
      sub[k][4 * i + 3] = records[i].depth[k] = depthAt(x + xs[k]);
      records[i].nx[k] = records[i].ny[k] = 0;
      records[i].nz[k] = 32767;
    }
  }
  std::vector<float> out[2];
  for (int packed = 0; packed < 2; ++packed) {
    out[packed].assign(4 * W * H, 0.0f);
    CrispFilter f = crispNewFilter(context, "rsaa");
    crispSetFilterImage(f, "color", color.data(), CRISP_FORMAT_FLOAT4, W, H, 0, 0);
    crispSetFilterImage(f, "depth", depth.data(), CRISP_FORMAT_FLOAT, W, H, 0, 0);
    crispSetFilterImage(f, "normal", normal.data(), CRISP_FORMAT_FLOAT3, W, H, 0, 0);
    crispSetFilterImage(f, "output", out[packed].data(), CRISP_FORMAT_FLOAT4, W, H, 0, 0);
    CrispError code;
    if (packed) {
      crispSetFilterImage(f, "subsamples", sub[0].data(), CRISP_FORMAT_FLOAT4, W, H, 0, 0);
      EXPECT_EQ(lastError(&code).find("subsamples") != std::string::npos, true);
      crispSetFilterImage(f, "subsamples", records.data(), CrispFormat(7), W, H, 0, 0);
      EXPECT_NE(lastError(&code).find("unknown format"), std::string::npos);
      crispSetFilterImage(f, "subsamples", records.data(), CRISP_FORMAT_RSAA_SUBSAMPLES, W, H, 0, 0);
    } else {
      for (int k = 0; k < 8; ++k)
        crispSetFilterImage(f, ("sub" + std::to_string(k)).c_str(), sub[k].data(), CRISP_FORMAT_FLOAT4, W, H, 0, 0);
    }
    crispSetFilterFloat(f, "proj00", 2.0f);
    crispSetFilterFloat(f, "proj11", 2.0f);
    crispCommitFilter(f);
    crispExecuteFilter(f);
    const std::string msg = lastError(&code);
    EXPECT_EQ(code, CRISP_ERROR_NONE) << msg;
    crispReleaseFilter(f);
  }
  EXPECT_EQ(out[0], out[1]);
  int changed = 0;  // the step is resampled: some pixels are no longer 0.9 or 0.1
  for (int i = 0; i < W * H; ++i) changed += out[1][4 * i] != color[4 * i];
  EXPECT_GE(changed, H);
}

TEST_F(RsaaApi, OnlyRsaaTakesTheCamera) {
  writeSidecar(true);
  expectAttachError("fxaa", CRISP_ERROR_INVALID_ARGUMENT, {"fxaa"});
}

}  // namespace
