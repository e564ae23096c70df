// SPDX-License-Identifier: Apache-2.0
// crispAttachFrameSubsamples (RSAA's geometric sub-samples, issue 5) through
// the shared library only: the errors a caller sees, with real files written
// by the library itself. The success path (Blender's multilayer files) is
// covered by tests/unit/test_rsaa.cpp (RsaaFiles) and tests/python/test_rsaa_e2e.py.
#include <gtest/gtest.h>
#include <unistd.h>

#include <cstdint>
#include <cstdio>
#include <cstring>
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

// A depth step for rsaa: plane at depth 10 left of x = 7.3, 14 right of it,
// normals (0, 0, 1) = snorm 32767, as 8 float4 images and as packed records;
// colour 0.9 / 0.1 across the step, plus a fine texture when `textured` (for
// the texture pass, FXAA by default, to work on).
struct DepthStep {
  static constexpr int W = 16, H = 9;
  std::vector<float> color, depth, normal, sub[8];
  std::vector<Record> records;
  explicit DepthStep(bool textured) : color(4 * W * H), depth(W * H), normal(3 * W * H), records(W * H) {
    const float xs[8] = {-0.375f, 0.125f, 0.375f, -0.125f, -0.25f, 0.25f, 0.25f, -0.25f};
    const auto depthAt = [](float x) { return x < 7.3f ? 10.0f : 14.0f; };
    for (auto& s : sub) s.assign(4 * W * H, 0.0f);
    for (int i = 0; i < W * H; ++i) {
      const float x = float(i % W) + 0.5f;
      const float texture = textured ? 0.3f * float((i * 7 + i / W * 3) % 5 == 0) : 0.0f;
      for (int c = 0; c < 3; ++c) color[4 * i + c] = (x < 7.3f ? 0.9f : 0.1f) + texture;
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
  }
};

// One rsaa frame through the C API: the sub-samples packed or as sub0..sub7;
// the output in `out`, or in the buffer of input `aliased` ("color", "sub0",
// ..., "subsamples"), whose copy it then returns. With `staleSubs`, packed
// records come with a stale sub0..sub7 of another size (sub0-3 another width, sub4-7 another
// height), which they supersede.
std::vector<float> runRsaa(CrispContext context, DepthStep scene, bool packed, const std::string& aliased = "",
                           bool staleSubs = false) {
  const int W = DepthStep::W, H = DepthStep::H;
  std::vector<float> out(4 * W * H, 0.0f);
  float* output = out.data();
  CrispFilter f = crispNewFilter(context, "rsaa");
  crispSetFilterImage(f, "color", scene.color.data(), CRISP_FORMAT_FLOAT4, W, H, 0, 0);
  if (aliased == "color") output = scene.color.data();
  crispSetFilterImage(f, "depth", scene.depth.data(), CRISP_FORMAT_FLOAT, W, H, 0, 0);
  crispSetFilterImage(f, "normal", scene.normal.data(), CRISP_FORMAT_FLOAT3, W, H, 0, 0);
  std::vector<float> stale(4 * W * H, 0.0f);
  for (int k = 0; staleSubs && k < 8; ++k)
    crispSetFilterImage(f, ("sub" + std::to_string(k)).c_str(), stale.data(), CRISP_FORMAT_FLOAT4, k < 4 ? W / 2 : W,
                        k < 4 ? H : H - 1, 0, 0);
  if (packed) {
    crispSetFilterImage(f, "subsamples", scene.records.data(), CRISP_FORMAT_RSAA_SUBSAMPLES, W, H, 0, 0);
    if (aliased == "subsamples") output = reinterpret_cast<float*>(scene.records.data());
  } else {
    for (int k = 0; k < 8; ++k) {
      const std::string role = "sub" + std::to_string(k);
      crispSetFilterImage(f, role.c_str(), scene.sub[k].data(), CRISP_FORMAT_FLOAT4, W, H, 0, 0);
      if (aliased == role) output = scene.sub[k].data();
    }
  }
  crispSetFilterImage(f, "output", output, CRISP_FORMAT_FLOAT4, W, H, 0, 0);
  crispSetFilterFloat(f, "proj00", 2.0f);
  crispSetFilterFloat(f, "proj11", 2.0f);
  crispCommitFilter(f);
  crispExecuteFilter(f);
  CrispError code;
  const std::string msg = lastError(&code);
  EXPECT_EQ(code, CRISP_ERROR_NONE) << msg;
  crispReleaseFilter(f);
  if (output != out.data()) out.assign(output, output + out.size());
  return out;
}

// rsaa through the C API from packed records gives the image it gives from
// the 8 float4 images; a float4 image is refused as "subsamples", naming the
// format it needs, and an unknown format is refused everywhere.
TEST_F(RsaaApi, PackedRecordsGiveTheFloat4Result) {
  const DepthStep scene(false);
  const std::vector<float> out[2] = {runRsaa(context, scene, false), runRsaa(context, scene, true)};
  EXPECT_EQ(out[0], out[1]);
  EXPECT_EQ(out[1], runRsaa(context, scene, true, "", true)) << "with a stale sub0..sub7 of another size";
  int changed = 0;  // the step is resampled: some pixels are no longer 0.9 or 0.1
  for (int i = 0; i < DepthStep::W * DepthStep::H; ++i) changed += out[1][4 * i] != scene.color[4 * i];
  EXPECT_GE(changed, DepthStep::H);

  DepthStep bad(false);
  CrispFilter f = crispNewFilter(context, "rsaa");
  CrispError code;
  crispSetFilterImage(f, "subsamples", bad.sub[0].data(), CRISP_FORMAT_FLOAT4, DepthStep::W, DepthStep::H, 0, 0);
  std::string msg = lastError(&code);
  EXPECT_EQ(code, CRISP_ERROR_INVALID_ARGUMENT) << msg;
  EXPECT_NE(msg.find("'subsamples'"), std::string::npos) << msg;
  EXPECT_NE(msg.find("rsaa_subsamples"), std::string::npos) << msg;
  crispSetFilterImage(f, "subsamples", bad.records.data(), CrispFormat(7), DepthStep::W, DepthStep::H, 0, 0);
  EXPECT_NE(lastError(&code).find("unknown format"), std::string::npos);
  crispReleaseFilter(f);
}

// crisp.h: the output may share an input's buffer with the result of separate
// buffers; rsaa's texture pass (FXAA) reads the sub-samples again after rows
// of the output are written, so an output in a sub-sample's buffer needs them
// kept apart, as colour, depth and normal are.
TEST_F(RsaaApi, OutputInAnInputsBufferEqualsSeparateBuffers) {
  const DepthStep scene(true);
  for (const bool packed : {false, true}) {
    const std::vector<float> separate = runRsaa(context, scene, packed);
    for (const char* role : packed ? std::vector<const char*>{"color", "subsamples"}
                                   : std::vector<const char*>{"color", "sub0", "sub3", "sub7"})
      EXPECT_EQ(separate, runRsaa(context, scene, packed, role)) << "output in the '" << role << "' buffer";
  }
}

// A one-pixel-wide view addresses one column, so its pixel stride may be anything the address space holds
// (crispSetFilterImage takes it). rsaa's overlap test of colour and output added a whole pixel stride
// past each row: a pointer overflow, which the sanitizer build stopped at (found by a probe of the C API).
TEST_F(RsaaApi, OneColumnViewsWithAHugePixelStride) {
  const int H = 5;
  std::vector<float> color(4 * H), depth(H), normal(3 * H, 0.0f), records(20 * H, 1.0f);
  for (int y = 0; y < H; ++y) {
    color[4 * y] = color[4 * y + 1] = color[4 * y + 2] = y < 2 ? 0.9f : 0.1f;
    color[4 * y + 3] = 1.0f;
    depth[y] = y < 2 ? 1.0f : 3.0f;
    normal[3 * y + 2] = 1.0f;
    const std::int16_t up[2] = {0, 32767};  // the records' normals: +z
    for (int k = 8; k < 20; ++k) std::memcpy(&records[20 * y + k], up, sizeof up);
  }
  std::vector<float> outputs[2];
  for (const std::size_t pixelStride : {std::size_t(0), std::size_t(0x7FFFFFFFFFFFFFF0ull)}) {
    std::vector<float> out(4 * H, -1.0f);
    CrispFilter f = crispNewFilter(context, "rsaa");
    crispSetFilterImage(f, "color", color.data(), CRISP_FORMAT_FLOAT4, 1, H, pixelStride, 16);
    crispSetFilterImage(f, "depth", depth.data(), CRISP_FORMAT_FLOAT, 1, H, pixelStride, 4);
    crispSetFilterImage(f, "normal", normal.data(), CRISP_FORMAT_FLOAT3, 1, H, pixelStride, 12);
    crispSetFilterImage(f, "subsamples", records.data(), CRISP_FORMAT_RSAA_SUBSAMPLES, 1, H, pixelStride, 80);
    crispSetFilterImage(f, "output", out.data(), CRISP_FORMAT_FLOAT4, 1, H, pixelStride, 16);
    crispCommitFilter(f);
    crispExecuteFilter(f);
    CrispError code;
    const std::string msg = lastError(&code);
    EXPECT_EQ(code, CRISP_ERROR_NONE) << pixelStride << ": " << msg;
    crispReleaseFilter(f);
    outputs[pixelStride != 0] = out;
  }
  EXPECT_EQ(outputs[0], outputs[1]);
  EXPECT_NE(outputs[1][0], -1.0f);
}

TEST_F(RsaaApi, OnlyRsaaTakesTheCamera) {
  writeSidecar(true);
  expectAttachError("fxaa", CRISP_ERROR_INVALID_ARGUMENT, {"fxaa"});
}

}  // namespace
