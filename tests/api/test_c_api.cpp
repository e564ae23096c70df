// SPDX-License-Identifier: Apache-2.0
// The public C API and its C++ wrapper, against the shared library only.
#include <gtest/gtest.h>

#include <malloc.h>
#include <sys/mman.h>
#include <sys/resource.h>
#include <unistd.h>

#include <cmath>
#include <cstdint>
#include <cstdio>
#include <cstring>
#include <fstream>
#include <sstream>
#include <limits>
#include <map>
#include <string>
#include <thread>
#include <vector>

#include "crisp/crisp.hpp"

namespace {

std::vector<float> noise(int w, int h, int c, unsigned seed) {
  std::vector<float> v(std::size_t(w) * h * c);
  for (auto& x : v) {
    seed = seed * 1664525u + 1013904223u;
    x = float(seed >> 8) / float(1u << 24);
  }
  return v;
}

std::string lastError(CrispError* code = nullptr) {
  const char* m = nullptr;
  CrispError c = crispGetError(&m);
  if (code) *code = c;
  return m ? m : "";
}

#if defined(__SANITIZE_ADDRESS__)
#define CRISP_TEST_ASAN 1
#elif defined(__has_feature)
#if __has_feature(address_sanitizer)
#define CRISP_TEST_ASAN 1
#endif
#endif

// Runs fn with the address-space limit lowered to `headroom` bytes above what the process maps, so
// that memory runs short without any being used, then puts the limit back. False, running nothing,
// where the limit cannot be lowered: under ASan (its shadow mappings need the address space) or
// below a hard limit.
template <class Fn>
bool withAddressSpaceHeadroom(std::size_t headroom, Fn&& fn) {
#ifdef CRISP_TEST_ASAN
  return false;
#else
  // Free heap memory goes back first, so an allocation the test expects to fail cannot be served
  // from what earlier tests left in the heap.
  ::malloc_trim(0);
  rlimit was{};
  std::size_t pages = 0;
  std::ifstream("/proc/self/statm") >> pages;
  if (::getrlimit(RLIMIT_AS, &was) != 0 || pages == 0) return false;
  rlimit tight = was;
  tight.rlim_cur = rlim_t(pages) * rlim_t(::sysconf(_SC_PAGESIZE)) + rlim_t(headroom);
  if ((was.rlim_max != RLIM_INFINITY && tight.rlim_cur > was.rlim_max) || ::setrlimit(RLIMIT_AS, &tight) != 0)
    return false;
  struct Restore {
    rlimit limit;
    ~Restore() { ::setrlimit(RLIMIT_AS, &limit); }
  } restore{was};
  fn();
  return true;
#endif
}

}  // namespace

TEST(CApi, VersionAndTypes) {
  EXPECT_EQ(crispGetVersion(), CRISP_VERSION);
  EXPECT_STREQ(crispGetVersionString(), "0.2.0");
  std::string types = crispGetFilterTypes();
  for (const char* t : {"none", "fxaa", "repair"}) EXPECT_NE(types.find(t), std::string::npos) << t;
}

TEST(CApi, NoneFilterCopiesThroughStridedViews) {
  auto ctx = crisp::ContextRef::create();
  ctx.set("numThreads", 2);
  EXPECT_EQ(ctx.get("numThreads"), 2);
  ctx.commit();
  const int w = 13, h = 7;
  // RGBA input read as RGB through the pixel stride, rows padded by 3 floats.
  const std::size_t rowFloats = w * 4 + 3;
  std::vector<float> in(rowFloats * h);
  for (int y = 0; y < h; ++y)
    for (int x = 0; x < w; ++x)
      for (int c = 0; c < 4; ++c) in[y * rowFloats + x * 4 + c] = float(y * 1000 + x * 10 + c);
  std::vector<float> out(std::size_t(w) * h * 3, -1.0f);
  auto f = ctx.newFilter("none");
  f.setImage("color", in.data(), CRISP_FORMAT_FLOAT3, w, h, 16, rowFloats * 4);
  f.setImage("output", out.data(), CRISP_FORMAT_FLOAT3, w, h);
  f.commit();
  f.execute();
  for (int y = 0; y < h; ++y)
    for (int x = 0; x < w; ++x)
      for (int c = 0; c < 3; ++c) ASSERT_EQ(out[(y * w + x) * 3 + c], float(y * 1000 + x * 10 + c));
}

TEST(CApi, ErrorsNameWhatIsWrong) {
  auto ctx = crisp::ContextRef::create();
  CrispError code;
  EXPECT_EQ(crispNewFilter(ctx.handle(), "fxab"), nullptr);
  EXPECT_NE(lastError(&code).find("unknown filter type 'fxab'"), std::string::npos);
  EXPECT_EQ(code, CRISP_ERROR_INVALID_ARGUMENT);
  EXPECT_EQ(crispGetError(nullptr), CRISP_ERROR_NONE);  // cleared by the query

  auto f = ctx.newFilter("repair");
  crispSetFilterFloat(f.handle(), "sharpness", 1.0f);
  EXPECT_NE(lastError().find("unknown parameter 'sharpness'"), std::string::npos);
  crispSetFilterImage(f.handle(), "colour", nullptr, CRISP_FORMAT_FLOAT3, 4, 4, 0, 0);
  EXPECT_NE(lastError().find("no image 'colour'"), std::string::npos);

  std::vector<float> a(4 * 4 * 4), b(5 * 4 * 4);
  f.setImage("color", a.data(), CRISP_FORMAT_FLOAT4, 4, 4);
  crispExecuteFilter(f.handle());
  EXPECT_NE(lastError(&code).find("before commit"), std::string::npos);
  EXPECT_EQ(code, CRISP_ERROR_INVALID_OPERATION);
  crispCommitFilter(f.handle());
  EXPECT_NE(lastError(&code).find("'output'"), std::string::npos);
  EXPECT_EQ(code, CRISP_ERROR_INVALID_DATA);
  f.setImage("output", b.data(), CRISP_FORMAT_FLOAT4, 5, 4);
  crispCommitFilter(f.handle());
  EXPECT_NE(lastError().find("'output' is 5x4 but 'color' is 4x4"), std::string::npos);
  crispSetFilterImage(f.handle(), "output", b.data(), CRISP_FORMAT_FLOAT4, 4, 4, 8, 0);  // stride < pixel
  EXPECT_NE(lastError().find("strides"), std::string::npos);
  crispSetFilterImage(f.handle(), "color", a.data(), CRISP_FORMAT_FLOAT2, 4, 4, 0, 0);
  EXPECT_NE(lastError().find("format float2 not accepted"), std::string::npos);
  crispSetFilterImage(f.handle(), "color", a.data(), CRISP_FORMAT_FLOAT4, 0, 4, 0, 0);
  EXPECT_NE(lastError().find("out of range"), std::string::npos);
  crispSetContextInt(ctx.handle(), "numThreads", -1);
  EXPECT_NE(lastError().find("numThreads"), std::string::npos);
  crispCommitFilter(nullptr);
  EXPECT_NE(lastError().find("NULL"), std::string::npos);
  EXPECT_THROW(f.set("kappa", std::numeric_limits<float>::quiet_NaN()), crisp::Error);
}

// A NULL string value is refused naming the filter and the parameter (it said only "parameter
// value is NULL", which of a caller's many string settings it did not say), and sets nothing.
TEST(CApi, NullStringValueNamesTheParameter) {
  auto ctx = crisp::ContextRef::create();
  auto f = ctx.newFilter("taa");
  CrispError code;
  crispSetFilterString(f.handle(), "clipSpace", nullptr);
  const std::string msg = lastError(&code);
  EXPECT_EQ(code, CRISP_ERROR_INVALID_ARGUMENT) << msg;
  EXPECT_EQ(msg, "filter 'taa': parameter 'clipSpace': value is NULL");
  EXPECT_EQ(f.get<std::string>("clipSpace"), "rgb");
}

// Execute without a valid commit says why: never committed, the last commit
// failed, or the first change since the last commit.
TEST(CApi, ExecuteWithoutACommitNamesWhy) {
  auto ctx = crisp::ContextRef::create();
  auto f = ctx.newFilter("fxaa");
  std::vector<float> a(4 * 4 * 4, 0.5f), b(4 * 4 * 4), small(2 * 4 * 4);
  f.setImage("color", a.data(), CRISP_FORMAT_FLOAT4, 4, 4);
  f.setImage("output", b.data(), CRISP_FORMAT_FLOAT4, 4, 4);
  CrispError code;
  crispExecuteFilter(f.handle());
  EXPECT_NE(lastError(&code).find("execute called before commit"), std::string::npos);
  f.commit();
  f.execute();
  crispSetFilterFloat(f.handle(), "edgeThreshold", 0.2f);
  crispSetFilterString(f.handle(), "preset", "12");  // unknown to fxaa: refused, changes nothing
  lastError();
  crispExecuteFilter(f.handle());
  std::string msg = lastError(&code);
  EXPECT_EQ(code, CRISP_ERROR_INVALID_OPERATION) << msg;
  EXPECT_NE(msg.find("parameter 'edgeThreshold' was set"), std::string::npos) << msg;
  f.commit();
  f.execute();
  f.setImage("output", small.data(), CRISP_FORMAT_FLOAT4, 2, 4);
  crispCommitFilter(f.handle());  // fails: 2x4 against 4x4
  EXPECT_NE(lastError().find("'output' is 2x4"), std::string::npos);
  crispExecuteFilter(f.handle());
  msg = lastError(&code);
  EXPECT_EQ(code, CRISP_ERROR_INVALID_OPERATION) << msg;
  EXPECT_NE(msg.find("after a commit that failed"), std::string::npos) << msg;
  f.setImage("output", b.data(), CRISP_FORMAT_FLOAT4, 4, 4);
  f.commit();
  f.execute();
  crispUnsetFilterImage(f.handle(), "output");
  crispExecuteFilter(f.handle());
  EXPECT_NE(lastError().find("image 'output' was unset"), std::string::npos);
  // The same size in another format is a change too (the kernel reads the pixels otherwise).
  f.setImage("output", b.data(), CRISP_FORMAT_FLOAT4, 4, 4);
  f.commit();
  f.execute();
  f.setImage("color", a.data(), CRISP_FORMAT_FLOAT3, 4, 4);
  crispExecuteFilter(f.handle());
  msg = lastError(&code);
  EXPECT_EQ(code, CRISP_ERROR_INVALID_OPERATION) << msg;
  EXPECT_NE(msg.find("image 'color' was set to a new size or format"), std::string::npos) << msg;
}

// crisp.h: each side of an image is in [1, 65536]; setting a view allocates nothing, so the
// largest side is taken and one more is refused, naming the image.
TEST(CApi, ImageSideLimitIsInclusive) {
  auto ctx = crisp::ContextRef::create();
  auto f = ctx.newFilter("fxaa");
  std::vector<float> row(4 * 65537, 0.5f);
  CrispError code;
  for (std::size_t side : {std::size_t(65536), std::size_t(65537)}) {
    crispSetFilterImage(f.handle(), "color", row.data(), CRISP_FORMAT_FLOAT4, side, 1, 0, 0);
    std::string msg = lastError(&code);
    if (side == 65536) {
      EXPECT_EQ(code, CRISP_ERROR_NONE) << msg;
    } else {
      EXPECT_EQ(code, CRISP_ERROR_INVALID_ARGUMENT) << msg;
      EXPECT_NE(msg.find("image 'color': size 65537x1 is out of range [1, 65536]"), std::string::npos) << msg;
    }
  }
}

// A frame says how many colour values its file held as NaN or Inf (its colour pass holds them
// sanitised), so a caller can refuse to measure it, as crisp compare does.
TEST(CApi, FrameCountsNonFiniteColour) {
  auto ctx = crisp::ContextRef::create();
  const std::string path = ::testing::TempDir() + "crisp_nonfinite_" + std::to_string(::getpid()) + ".exr";
  std::vector<float> rgba(4 * 3 * 2, 0.5f);
  rgba[1] = std::numeric_limits<float>::quiet_NaN();
  rgba[6] = std::numeric_limits<float>::infinity();
  rgba[8] = -std::numeric_limits<float>::infinity();
  crispWriteImage(ctx.handle(), path.c_str(), rgba.data(), CRISP_FORMAT_FLOAT4, 3, 2, 0, 0);
  ASSERT_EQ(lastError(), "");
  CrispFrame frame = crispLoadFrame(ctx.handle(), path.c_str());
  ASSERT_NE(frame, nullptr) << lastError();
  EXPECT_EQ(crispGetFrameNonFiniteColour(frame), 3);
  CrispFormat format;
  const float* color = static_cast<const float*>(crispGetFramePass(frame, "color", &format));
  ASSERT_NE(color, nullptr);
  EXPECT_EQ(color[1], 0.0f);  // sanitised
  crispReleaseFrame(frame);
  EXPECT_EQ(crispGetFrameNonFiniteColour(nullptr), 0);
  EXPECT_NE(lastError().find("NULL"), std::string::npos);
  std::remove(path.c_str());
}

TEST(CApi, FirstErrorIsKeptAndErrorsArePerThread) {
  auto ctx = crisp::ContextRef::create();
  crispNewFilter(ctx.handle(), "first");
  crispNewFilter(ctx.handle(), "second");
  std::string other;
  std::thread t([&] { other = lastError(); });  // another thread sees none
  t.join();
  EXPECT_EQ(other, "");
  EXPECT_NE(lastError().find("'first'"), std::string::npos);
  EXPECT_EQ(lastError(), "");
}

TEST(CApi, EverySpatialFilterKeepsOutputFiniteOnNanAndInf) {
  auto ctx = crisp::ContextRef::create();
  const int w = 31, h = 17;
  for (const char* type : {"none", "fxaa", "repair"}) {
    std::vector<float> in = noise(w, h, 4, 7);
    in[0] = std::numeric_limits<float>::quiet_NaN();
    in[4 * 40 + 1] = std::numeric_limits<float>::infinity();
    in[4 * 77 + 2] = -std::numeric_limits<float>::infinity();
    in[4 * 100] = 1e30f;
    std::vector<float> out(in.size());
    auto f = ctx.newFilter(type);
    f.setImage("color", in.data(), CRISP_FORMAT_FLOAT4, w, h);
    f.setImage("output", out.data(), CRISP_FORMAT_FLOAT4, w, h);
    f.commit();
    f.execute();
    for (float v : out) ASSERT_TRUE(std::isfinite(v)) << type;
  }
}

TEST(CApi, InPlaceAndOddSizes) {
  auto ctx = crisp::ContextRef::create();
  for (const char* type : {"none", "fxaa", "repair"})
    for (auto [w, h] : {std::pair{1, 1}, {2, 3}, {17, 9}}) {
      std::vector<float> img = noise(w, h, 3, 11);
      auto f = ctx.newFilter(type);
      f.setImage("color", img.data(), CRISP_FORMAT_FLOAT3, w, h);
      f.setImage("output", img.data(), CRISP_FORMAT_FLOAT3, w, h);  // in place
      f.commit();
      f.execute();
      for (float v : img) ASSERT_TRUE(std::isfinite(v)) << type << " " << w << "x" << h;
    }
}

TEST(CApi, ReleaseOrderDoesNotMatter) {
  CrispContext c = crispNewContext();
  CrispFilter f = crispNewFilter(c, "none");
  crispReleaseContext(c);  // the filter keeps the context alive
  std::vector<float> img(4 * 4 * 3, 0.5f);
  crispSetFilterImage(f, "color", img.data(), CRISP_FORMAT_FLOAT3, 4, 4, 0, 0);
  crispSetFilterImage(f, "output", img.data(), CRISP_FORMAT_FLOAT3, 4, 4, 0, 0);
  crispCommitFilter(f);
  crispExecuteFilter(f);
  EXPECT_EQ(crispGetError(nullptr), CRISP_ERROR_NONE);
  crispReleaseFilter(f);
}

TEST(CApi, ReleasingNullDoesNothing) {  // crisp.h: as free(NULL), so cleanup need not test its handles
  crispReleaseContext(nullptr);
  crispReleaseFilter(nullptr);
  crispReleaseFrame(nullptr);
  EXPECT_EQ(crispGetError(nullptr), CRISP_ERROR_NONE);
  crispRetainContext(nullptr);  // retaining nothing is a mistake, and is named
  EXPECT_NE(lastError().find("context"), std::string::npos);
}

TEST(CApi, DocListsParametersAndImages) {
  auto ctx = crisp::ContextRef::create();
  for (const char* type : {"fxaa", "repair"}) {
    std::string d = ctx.newFilter(type).doc();
    EXPECT_NE(d.find("| name | type | default | range | meaning | source |"), std::string::npos) << type;
    EXPECT_NE(d.find("`color`"), std::string::npos) << type;
  }
}

TEST(CApi, InfoJsonDescribesImagesAndParameters) {
  auto ctx = crisp::ContextRef::create();
  auto f = ctx.newFilter("repair");
  std::string info = crispGetFilterInfo(f.handle());
  EXPECT_EQ(crispGetError(nullptr), CRISP_ERROR_NONE);
  EXPECT_EQ(info.rfind("{\"type\": \"repair\", \"images\": [", 0), 0u) << info;
  EXPECT_NE(info.find("{\"name\": \"color\", \"required\": true"), std::string::npos) << info;
  EXPECT_NE(info.find("\"name\": \"mask\", \"type\": \"string\", \"default\": \"gauss5\", \"choices\": [\"gauss5\", \"box3\"]"),
            std::string::npos)
      << info;
  EXPECT_NE(info.find("\"name\": \"patchSize\", \"type\": \"int\", \"default\": 5, \"min\": 3"), std::string::npos) << info;
}

// The output may be given an input's buffer (crisp.h): every filter then gives the bits it gives
// with separate buffers, frame after frame, including the temporal ones whose row bands read
// neighbours that other bands have already overwritten.
TEST(CApi, InPlaceEqualsSeparateBuffers) {
  auto ctx = crisp::ContextRef::create();
  ctx.set("numThreads", 2);
  ctx.commit();
  const int w = 96, h = 72;
  const std::size_t n = std::size_t(w) * h * 4;
  struct Case {
    const char* type;
    const char* aliased;
  };
  const Case cases[] = {{"none", "color"},         {"fxaa", "color"},        {"repair", "color"},
                        {"taa", "color"},          {"taa", "motion"},        {"taa", "depth"},
                        {"taa-improved", "color"}, {"taa-improved", "depth"}, {"phlm", "color"},
                        {"phlm", "motion"},        {"phlm", "depth"}};
  for (const Case& c : cases) {
    const bool temporal = std::string(c.type).rfind("taa", 0) == 0 || std::string(c.type) == "phlm";
    auto separate = ctx.newFilter(c.type);
    auto inPlace = ctx.newFilter(c.type);
    std::vector<float> out(n), shared(n);
    for (int frame = 0; frame < 4; ++frame) {
      std::map<std::string, std::vector<float>> inputs;
      inputs["color"] = noise(w, h, 4, 100u + unsigned(frame));
      for (int y = 0; y < h; ++y)  // an edge moving right, so history and clipping have work to do
        for (int x = 0; x < w; ++x)
          if (x < 30 + 2 * frame) inputs["color"][(std::size_t(y) * w + x) * 4 + 1] += 4.0f;
      if (temporal) {
        inputs["motion"].assign(n, 0.0f);
        inputs["depth"].assign(n, 0.0f);
        for (std::size_t i = 0; i < n; i += 4) {
          inputs["motion"][i] = -0.7f, inputs["motion"][i + 1] = -0.3f;
          inputs["depth"][i] = 5.0f + float(i % 97) * 0.01f;
        }
      }
      for (auto* f : {&separate, &inPlace}) {
        const bool aliasing = f == &inPlace;
        for (auto& [role, data] : inputs) {
          float* p = data.data();
          if (aliasing && role == c.aliased) {
            shared = data;
            p = shared.data();
          }
          f->setImage(role.c_str(), p, CRISP_FORMAT_FLOAT4, w, h);
        }
        f->setImage("output", aliasing ? shared.data() : out.data(), CRISP_FORMAT_FLOAT4, w, h);
        if (temporal) {
          f->set("jitterX", 0.25f * float(frame % 3) - 0.25f);
          f->set("jitterY", 0.2f - 0.2f * float(frame % 2));
        }
        f->commit();
        f->execute();
      }
      ASSERT_EQ(0, std::memcmp(out.data(), shared.data(), n * sizeof(float)))
          << c.type << " with the output in the '" << c.aliased << "' buffer, frame " << frame;
    }
  }
}

// crisp.h: a returned string stays valid until the filter changes, whatever else is read.
TEST(CApi, ReturnedStringsSurviveOtherGetters) {
  auto ctx = crisp::ContextRef::create();
  auto f = ctx.newFilter("repair");
  const char* mask = crispGetFilterString(f.handle(), "mask");
  const std::string maskWas = mask;
  const char* doc = crispGetFilterDoc(f.handle());
  const std::string docWas = doc;
  const char* estimator = crispGetFilterString(f.handle(), "angleEstimator");
  const std::string estimatorWas = estimator;
  crispGetFilterInfo(f.handle());
  crispGetFilterString(f.handle(), "angleEstimator");
  EXPECT_EQ(std::string(mask), maskWas);
  EXPECT_EQ(std::string(doc), docWas);
  EXPECT_EQ(std::string(estimator), estimatorWas);
  EXPECT_FALSE(maskWas.empty());
  EXPECT_NE(maskWas, estimatorWas);
}

// Strides whose span wraps around size_t, or passes what a process can address, are refused at
// once, not left to crash execute; so is a negative stride cast to size_t, named as negative.
TEST(CApi, StridesThatWrapAreRefused) {
  auto ctx = crisp::ContextRef::create();
  auto f = ctx.newFilter("fxaa");
  std::vector<float> img(3 * 4);
  const std::size_t huge = std::size_t(1) << 62;  // 2 of them pass PTRDIFF_MAX
  crispSetFilterImage(f.handle(), "color", img.data(), CRISP_FORMAT_FLOAT4, 3, 1, huge, 16);
  CrispError code;
  EXPECT_NE(lastError(&code).find("span more memory"), std::string::npos);
  EXPECT_EQ(code, CRISP_ERROR_INVALID_ARGUMENT);
  crispSetFilterImage(f.handle(), "color", img.data(), CRISP_FORMAT_FLOAT4, 1, 3, 16, huge);
  EXPECT_NE(lastError(&code).find("span more memory"), std::string::npos);
  // A bottom-up image: the last row's address and a row stride of -48 bytes.
  crispSetFilterImage(f.handle(), "color", img.data() + 8, CRISP_FORMAT_FLOAT4, 1, 3, 16, std::size_t(-48));
  EXPECT_EQ(lastError(&code), "image 'color': negative strides (pixel 16, row -48 bytes) are not "
                              "supported: pass the image top row first, with positive strides");
  EXPECT_EQ(code, CRISP_ERROR_INVALID_ARGUMENT);
  crispSetFilterImage(f.handle(), "color", img.data(), CRISP_FORMAT_FLOAT4, 3, 1, 0, 0);
  EXPECT_EQ(crispGetError(nullptr), CRISP_ERROR_NONE);
}

// crispWriteImageEXR stores an .exr at Blender's Color Depth and Codec: a half-float DWAA file reads
// back close to what was written (its firefly at half's largest value, not infinity), and is smaller
// than crispWriteImage's float ZIP; a depth, codec or file type it cannot write is refused, naming
// it, and leaves the file there as it was.
TEST(CApi, WriteImageEXRStoresAtTheDepthAndCodecAsked) {
  auto ctx = crisp::ContextRef::create();
  const std::string stem = ::testing::TempDir() + "crisp_exr_" + std::to_string(::getpid());
  const int w = 48, h = 40;
  std::vector<float> rgba(std::size_t(w) * h * 4);
  std::uint32_t seed = 12345u;  // a render's noise: every mantissa bit busy, as in a filtered frame
  for (std::size_t i = 0; i < rgba.size(); ++i) {
    seed = seed * 1664525u + 1013904223u;
    rgba[i] = i % 4 == 3 ? 1.0f : 0.25f + 0.5f * float((i / 4) % w) / float(w) + float(seed >> 8) * 0x1p-30f;
  }
  rgba[4 * 50] = 3e5f;  // beyond half's range
  auto sizeOf = [](const std::string& p) {
    std::ifstream f(p, std::ios::binary | std::ios::ate);
    return std::size_t(f.tellg());
  };
  crispWriteImage(ctx.handle(), (stem + "_float.exr").c_str(), rgba.data(), CRISP_FORMAT_FLOAT4, w, h, 0, 0);
  ASSERT_EQ(lastError(), "");
  ctx.writeImageEXR((stem + "_half.exr").c_str(), rgba.data(), CRISP_FORMAT_FLOAT4, w, h, 16, "dwaa");
  EXPECT_LT(sizeOf(stem + "_half.exr"), sizeOf(stem + "_float.exr") / 2);
  CrispFrame frame = crispLoadFrame(ctx.handle(), (stem + "_half.exr").c_str());
  ASSERT_NE(frame, nullptr) << lastError();
  CrispFormat format;
  const float* color = static_cast<const float*>(crispGetFramePass(frame, "color", &format));
  ASSERT_NE(color, nullptr);
  EXPECT_EQ(crispGetFrameNonFiniteColour(frame), 0);
  double worst = 0.0;
  for (std::size_t i = 0; i < rgba.size(); ++i)
    if (i / 4 % w >= 8 || i / 4 / w >= 8) worst = std::max(worst, double(std::fabs(color[i] - rgba[i])));
  EXPECT_LT(worst, 0.03);  // dwaa is lossy: about 2.5 % at most on this noise
  EXPECT_GT(color[4 * 50], 60000.0f);
  crispReleaseFrame(frame);
  ctx.writeImageEXR((stem + "_zip32.exr").c_str(), rgba.data(), CRISP_FORMAT_FLOAT4, w, h, 32, nullptr);
  EXPECT_EQ(sizeOf(stem + "_zip32.exr"), sizeOf(stem + "_float.exr"));  // NULL: crispWriteImage's zip
  struct Case {
    std::string path;
    int depth;
    const char* codec;
    const char* words;
  };
  const Case cases[] = {{stem + "_float.exr", 8, "zip", "EXR bit depth 8"},
                        {stem + "_float.exr", 16, "lzw", "unknown EXR compression 'lzw' (known: none, zip,"},
                        {stem + "_float.exr", 16, "ZIP", "unknown EXR compression 'ZIP'"},
                        {stem + ".png", 16, "zip", "writes .exr files, not"}};
  const std::size_t before = sizeOf(stem + "_float.exr");
  for (const Case& c : cases) {
    CrispError code;
    crispWriteImageEXR(ctx.handle(), c.path.c_str(), rgba.data(), CRISP_FORMAT_FLOAT4, w, h, 0, 0, c.depth, c.codec);
    const std::string error = lastError(&code);
    EXPECT_EQ(code, CRISP_ERROR_INVALID_ARGUMENT) << error;
    EXPECT_NE(error.find(c.words), std::string::npos) << error;
  }
  EXPECT_EQ(sizeOf(stem + "_float.exr"), before);
  EXPECT_NE(::access((stem + ".png").c_str(), F_OK), 0);
  for (const char* suffix : {"_float.exr", "_half.exr", "_zip32.exr"}) std::remove((stem + suffix).c_str());
}

// crispWriteImage checks its view as crispSetFilterImage does: a stride that wraps, one smaller
// than a pixel or row, or a pointer or stride off the 4-byte grid is refused (it used to read
// outside the buffer: SIGSEGV for a stride of (size_t)-16), and nothing is written.
TEST(CApi, BadViewsAreRefusedByWriteImageAndSetImage) {
  auto ctx = crisp::ContextRef::create();
  auto f = ctx.newFilter("fxaa");
  const std::string path = ::testing::TempDir() + "crisp_badview_" + std::to_string(::getpid()) + ".exr";
  std::remove(path.c_str());
  std::vector<float> img(4 * 4 * 4 + 1, 0.5f);
  char* bytes = reinterpret_cast<char*>(img.data());
  struct Case {
    void* ptr;
    std::size_t pixel, row;
    const char* words;
  };
  const Case cases[] = {
      {img.data(), std::size_t(-16), 0, "negative strides (pixel -16, row -64 bytes)"},
      {img.data(), std::size_t(1) << 62, 0, "span more memory"},
      {img.data(), 4, 0, "smaller than the pixels"},
      {img.data(), 16, 7, "smaller than the pixels"},
      {bytes + 1, 0, 0, "multiples of 4 bytes"},
      {img.data(), 18, 0, "multiples of 4 bytes"},
      {img.data(), 16, 66, "multiples of 4 bytes"},
  };
  for (const Case& c : cases) {
    CrispError code;
    crispWriteImage(ctx.handle(), path.c_str(), c.ptr, CRISP_FORMAT_FLOAT4, 4, 1, c.pixel, c.row);
    const std::string written = lastError(&code);
    EXPECT_EQ(code, CRISP_ERROR_INVALID_ARGUMENT) << c.pixel << " " << c.row;
    EXPECT_NE(written.find(c.words), std::string::npos) << written;
    EXPECT_NE(written.find("image to write to"), std::string::npos) << written;
    EXPECT_NE(::access(path.c_str(), F_OK), 0) << "nothing written for " << written;
    crispSetFilterImage(f.handle(), "color", c.ptr, CRISP_FORMAT_FLOAT4, 4, 1, c.pixel, c.row);
    const std::string set = lastError(&code);
    EXPECT_EQ(code, CRISP_ERROR_INVALID_ARGUMENT) << c.pixel << " " << c.row;
    EXPECT_NE(set.find(c.words), std::string::npos) << set;
  }
  // The good view writes; a format no enumerator names is refused as one.
  crispWriteImage(ctx.handle(), path.c_str(), img.data(), CRISP_FORMAT_FLOAT4, 4, 1, 16, 64);
  EXPECT_EQ(lastError(), "");
  EXPECT_EQ(::access(path.c_str(), F_OK), 0);
  std::remove(path.c_str());
  crispSetFilterImage(f.handle(), "color", img.data(), static_cast<CrispFormat>(99), 4, 1, 0, 0);
  EXPECT_NE(lastError().find("unknown format 99"), std::string::npos);
  // Negative ints too (CRISP_FORMAT_MIN_ENUM_: without it they were outside the enum's range, undefined
  // behaviour that the sanitizer build stopped at), in every function taking a format.
  for (int bad : {-1, INT32_MIN}) {
    const CrispFormat format = static_cast<CrispFormat>(bad);
    CrispError code = CRISP_ERROR_NONE;
    crispSetFilterImage(f.handle(), "color", img.data(), format, 4, 1, 0, 0);
    EXPECT_NE(lastError().find("unknown format " + std::to_string(bad)), std::string::npos) << bad;
    crispWriteImage(ctx.handle(), path.c_str(), img.data(), format, 4, 1, 0, 0);
    EXPECT_NE(lastError(&code), "") << bad;
    EXPECT_EQ(code, CRISP_ERROR_INVALID_ARGUMENT) << bad;
    crispWriteImageEXR(ctx.handle(), path.c_str(), img.data(), format, 4, 1, 0, 0, 32, "zip");
    EXPECT_EQ((lastError(&code), code), CRISP_ERROR_INVALID_ARGUMENT) << bad;
    CrispMetrics metrics;
    crispCompareImages(ctx.handle(), img.data(), img.data(), format, 4, 1, nullptr, &metrics);
    EXPECT_EQ((lastError(&code), code), CRISP_ERROR_INVALID_ARGUMENT) << bad;
    EXPECT_NE(::access(path.c_str(), F_OK), 0) << bad;
  }
  // No error: the message pointer is set to NULL, as crisp.h says.
  const char* message = "stale";
  EXPECT_EQ(crispGetError(&message), CRISP_ERROR_NONE);
  EXPECT_EQ(message, nullptr);
}

// crisp.h: ptr = NULL unsets the image, with any format and size.
TEST(CApi, NullPointerUnsetsTheImage) {
  auto ctx = crisp::ContextRef::create();
  auto f = ctx.newFilter("taa");
  std::vector<float> img(4 * 4 * 4, 0.5f), out(img.size()), depth(5 * 5);
  f.setImage("color", img.data(), CRISP_FORMAT_FLOAT4, 4, 4);
  f.setImage("output", out.data(), CRISP_FORMAT_FLOAT4, 4, 4);
  f.setImage("depth", depth.data(), CRISP_FORMAT_FLOAT, 5, 5);
  crispCommitFilter(f.handle());
  EXPECT_NE(lastError().find("'depth' is 5x5"), std::string::npos);  // the wrong size is seen...
  crispSetFilterImage(f.handle(), "depth", nullptr, CRISP_FORMAT_UNDEFINED, 0, 0, 0, 0);
  EXPECT_EQ(lastError(), "");
  crispCommitFilter(f.handle());  // ...and gone once unset
  EXPECT_EQ(lastError(), "");
}

// crisp.h "History": which changes between frames keep a temporal filter's
// history and which drop it. Six frames of one noise image, then a seventh of
// another, with a change made at the seventh. Dropped history gives exactly
// a new filter's first frame on the seventh; kept history differs from it
// (the first six frames still show through the clip box).
TEST(CApi, TemporalHistoryIsKeptOrDroppedAsDocumented) {
  auto ctx = crisp::ContextRef::create();
  ctx.set("numThreads", 2);
  ctx.commit();
  const int w = 40, h = 24;
  struct Inputs {
    int w, h;
    std::vector<float> color, motion, depth, output;
    std::vector<std::uint32_t> id;
    Inputs(int width, int height, unsigned seed)
        : w(width), h(height), color(noise(width, height, 4, seed)), motion(std::size_t(width) * height * 2, 0.0f),
          depth(std::size_t(width) * height, 5.0f), output(std::size_t(width) * height * 4),
          id(std::size_t(width) * height, 7u) {}
  };
  struct Change {
    const char* what;
    bool drops;
    bool motionBefore, depthBefore, motionAfter, depthAfter;
    int widthAfter;
    const char* clipSpaceAfter;  // or nullptr
    bool resetFilter;
  };
  const Change changes[] = {
      {"nothing", false, true, true, true, true, w, nullptr, false},
      {"depth (and taa-improved's id) goes", false, true, true, true, false, w, nullptr, false},
      {"depth (and taa-improved's id) appears", false, true, false, true, true, w, nullptr, false},
      {"motion goes", false, true, true, false, true, w, nullptr, false},
      {"motion appears", false, false, true, true, true, w, nullptr, false},
      {"both go", false, true, true, false, false, w, nullptr, false},
      {"a new size", true, true, true, true, true, w - 8, nullptr, false},
      {"crispResetFilter", true, true, true, true, true, w, nullptr, true},
      {"clipSpace ycocg", true, true, true, true, true, w, "ycocg", false},
  };
  for (const char* type : {"taa", "taa-improved", "phlm"}) {
    for (const Change& c : changes) {
      if (c.clipSpaceAfter && std::string(type) == "phlm") continue;  // phlm has no clip space
      const std::string where = std::string(type) + ", " + c.what;
      auto bind = [&](crisp::FilterRef& f, Inputs& in, bool motion, bool depth, int frame) {
        f.setImage("color", in.color.data(), CRISP_FORMAT_FLOAT4, in.w, in.h);
        if (motion) f.setImage("motion", in.motion.data(), CRISP_FORMAT_FLOAT2, in.w, in.h);
        else f.unsetImage("motion");
        if (depth) f.setImage("depth", in.depth.data(), CRISP_FORMAT_FLOAT, in.w, in.h);
        else f.unsetImage("depth");
        // taa-improved's id goes with the depth (and comes back with it).
        if (std::string(type) == "taa-improved" && depth)
          f.setImage("id", in.id.data(), CRISP_FORMAT_UINT, in.w, in.h);
        else if (std::string(type) == "taa-improved")
          f.unsetImage("id");
        f.setImage("output", in.output.data(), CRISP_FORMAT_FLOAT4, in.w, in.h);
        f.set("jitterX", 0.25f * float(frame % 3) - 0.25f);
        f.set("jitterY", 0.2f - 0.2f * float(frame % 2));
        f.commit();
        f.execute();
      };
      auto kept = ctx.newFilter(type), fresh = ctx.newFilter(type);
      Inputs before(w, h, 11u), after(c.widthAfter, h, 12u), first(c.widthAfter, h, 12u);
      for (int frame = 0; frame < 6; ++frame) bind(kept, before, c.motionBefore, c.depthBefore, frame);
      if (c.resetFilter) kept.reset();
      if (c.clipSpaceAfter) {
        kept.set("clipSpace", c.clipSpaceAfter);
        fresh.set("clipSpace", c.clipSpaceAfter);
      }
      bind(kept, after, c.motionAfter, c.depthAfter, 6);
      bind(fresh, first, c.motionAfter, c.depthAfter, 6);
      const bool same = after.output == first.output;
      EXPECT_EQ(same, c.drops) << where << (c.drops ? ": the history was kept" : ": the history was dropped");
    }
  }
}

// A commit that runs out of memory at a new size leaves the temporal filter unallocated: a second
// commit at that size allocates again (and fails again while memory is short), instead of taking
// the buffers of the old size for the new one, which execute then wrote past (taa, taa-improved
// and phlm took the new size before their buffers had it). Memory is made short by lowering the
// address-space limit to 64 MB above what the process maps, far below the 1 GB of one history
// buffer of an 8192x8192 frame (whose images are mapped, never touched); skipped where the limit
// cannot be lowered (ASan).
TEST(CApi, CommitAfterOutOfMemoryAllocatesAgain) {
  auto ctx = crisp::ContextRef::create();
  ctx.set("numThreads", 1);
  ctx.commit();
  const std::size_t small = 64, big = 8192, bigBytes = big * big * 16;
  // Never touched (the commit fails before any execute): PROT_NONE, so that no overcommit policy
  // (vm.overcommit_memory=2 ignores MAP_NORESERVE) charges them.
  void* bigColor = ::mmap(nullptr, bigBytes, PROT_NONE, MAP_PRIVATE | MAP_ANONYMOUS | MAP_NORESERVE, -1, 0);
  void* bigOut = ::mmap(nullptr, bigBytes, PROT_NONE, MAP_PRIVATE | MAP_ANONYMOUS | MAP_NORESERVE, -1, 0);
  if (bigColor == MAP_FAILED || bigOut == MAP_FAILED) GTEST_SKIP() << "no 1 GB of address space to map";
  struct Unmap {
    void *a, *b;
    std::size_t bytes;
    ~Unmap() { ::munmap(a, bytes), ::munmap(b, bytes); }
  } unmap{bigColor, bigOut, bigBytes};
  for (const char* type : {"taa", "taa-improved", "phlm"}) {
    auto f = ctx.newFilter(type), fresh = ctx.newFilter(type);
    std::vector<float> color = noise(int(small), int(small), 4, 3), out(color.size()), freshOut(color.size());
    f.setImage("color", color.data(), CRISP_FORMAT_FLOAT4, small, small);
    f.setImage("output", out.data(), CRISP_FORMAT_FLOAT4, small, small);
    f.commit();
    f.execute();
    f.setImage("color", bigColor, CRISP_FORMAT_FLOAT4, big, big);
    f.setImage("output", bigOut, CRISP_FORMAT_FLOAT4, big, big);
    CrispError first = CRISP_ERROR_NONE, second = CRISP_ERROR_NONE;
    std::string firstMessage, secondMessage;
    if (!withAddressSpaceHeadroom(std::size_t(64) << 20, [&] {
          crispCommitFilter(f.handle());
          firstMessage = lastError(&first);
          crispCommitFilter(f.handle());
          secondMessage = lastError(&second);
        }))
      GTEST_SKIP() << "the address-space limit cannot be lowered here";
    EXPECT_EQ(first, CRISP_ERROR_OUT_OF_MEMORY) << type << ": " << firstMessage;
    const std::string said = std::string("filter '") + type + "': out of memory allocating its buffers for 8192x8192";
    EXPECT_NE(firstMessage.find(said), std::string::npos) << firstMessage;
    // (Not executed otherwise: it would write past the old size's buffers.)
    ASSERT_EQ(second, CRISP_ERROR_OUT_OF_MEMORY)
        << type << ": the retry took the old size's buffers: " << secondMessage;
    // Back at the small size, the filter starts over as a new one does.
    f.setImage("color", color.data(), CRISP_FORMAT_FLOAT4, small, small);
    f.setImage("output", out.data(), CRISP_FORMAT_FLOAT4, small, small);
    f.commit();
    f.execute();
    fresh.setImage("color", color.data(), CRISP_FORMAT_FLOAT4, small, small);
    fresh.setImage("output", freshOut.data(), CRISP_FORMAT_FLOAT4, small, small);
    fresh.commit();
    fresh.execute();
    EXPECT_TRUE(out == freshOut) << type;
  }
}

// The C++ wrapper takes a double literal for a float parameter (it was ambiguous between the int,
// float and bool overloads: a compile error), and the value still goes through the range check.
TEST(CApi, WrapperSetsAFloatParameterFromADouble) {
  auto ctx = crisp::ContextRef::create();
  auto f = ctx.newFilter("taa");
  f.set("jitterX", 0.25);
  EXPECT_EQ(f.get<float>("jitterX"), 0.25f);
  EXPECT_THROW(f.set("jitterX", 4.5), crisp::Error);
  EXPECT_EQ(f.get<float>("jitterX"), 0.25f);
  // Beyond float's range it reached the library as an infinity, and the error named "inf" alone.
  for (const double huge : {1e40, -1e300}) {
    try {
      f.set("jitterX", huge);
      ADD_FAILURE() << huge << " was taken";
    } catch (const crisp::Error& e) {
      std::ostringstream given;
      given << "(given " << huge << ", beyond a float's range)";
      EXPECT_NE(std::string(e.what()).find(given.str()), std::string::npos) << e.what();
      EXPECT_EQ(e.code(), CRISP_ERROR_INVALID_ARGUMENT);
    }
  }
  EXPECT_EQ(f.get<float>("jitterX"), 0.25f);
}

// The one image-sized allocation of execute (crisp.h: the copy of the inputs an in-place output
// overwrites, on the first in-place run of a size) names the filter and the size when it fails, as
// commit does, instead of a bare "out of memory"; the next execute, with memory back, runs. The
// 64 MB copy is above glibc's largest mmap threshold, so it always asks for a new mapping, which the
// lowered address-space limit refuses (skipped where it cannot be lowered, as above).
TEST(CApi, ExecuteOutOfMemoryNamesTheFilter) {
  auto ctx = crisp::ContextRef::create();
  ctx.set("numThreads", 1);
  ctx.commit();
  const int side = 2048;
  std::vector<float> color = noise(side, side, 4, 9), out(color.size());
  auto f = ctx.newFilter("taa");
  f.setImage("color", color.data(), CRISP_FORMAT_FLOAT4, side, side);
  f.setImage("output", out.data(), CRISP_FORMAT_FLOAT4, side, side);
  f.commit();
  f.execute();
  f.setImage("output", color.data(), CRISP_FORMAT_FLOAT4, side, side);  // in place: no new commit needed
  CrispError code = CRISP_ERROR_NONE;
  std::string message;
  if (!withAddressSpaceHeadroom(std::size_t(8) << 20, [&] {
        crispExecuteFilter(f.handle());
        message = lastError(&code);
      }))
    GTEST_SKIP() << "the address-space limit cannot be lowered here";
  EXPECT_EQ(code, CRISP_ERROR_OUT_OF_MEMORY) << message;
  EXPECT_EQ(message, "filter 'taa': out of memory filtering a 2048x2048 frame");
  f.execute();
}

// taa, taa-improved and phlm allocate the alpha's history in the execute whose alpha first is
// below 1 (temporal_alpha.h). Memory running short part-way through that (after the alpha as
// RGB, before its filtered copy) failed that execute, and the next one, with memory back, wrote
// the alpha through the copy that was never made (a crash). Every address-space limit between
// the alpha's kernel fitting and all of it fitting is tried: each failed execute is followed by
// one that runs and writes alphas in [0, 1]. Skipped where the limit cannot be lowered (ASan).
TEST(CApi, ExecuteAfterTheAlphasAllocationRanShortRuns) {
  auto ctx = crisp::ContextRef::create();
  ctx.set("numThreads", 1);
  ctx.commit();
  const int side = 1536;  // the alpha's kernel ~85 MB, its RGB in and out 28 MB each
  std::vector<float> color = noise(side, side, 4, 5), out(color.size());
  for (std::size_t i = 3; i < color.size(); i += 4) color[i] = (i / 4) % 3 ? 1.0f : 0.0f;  // a transparent film
  int failed = 0;
  for (std::size_t mb = 64; mb <= 184; mb += 8) {
    auto f = ctx.newFilter("taa");
    f.setImage("color", color.data(), CRISP_FORMAT_FLOAT4, side, side);
    f.setImage("output", out.data(), CRISP_FORMAT_FLOAT4, side, side);
    f.commit();
    CrispError code = CRISP_ERROR_NONE;
    if (!withAddressSpaceHeadroom(mb << 20, [&] {
          crispExecuteFilter(f.handle());
          lastError(&code);
        }))
      GTEST_SKIP() << "the address-space limit cannot be lowered here";
    if (code == CRISP_ERROR_NONE) continue;
    ++failed;
    f.execute();
    bool inRange = true;
    for (std::size_t i = 3; i < out.size(); i += 4) inRange &= out[i] >= 0.0f && out[i] <= 1.0f;
    EXPECT_TRUE(inRange) << "after a failed execute with " << mb << " MB of headroom";
  }
  EXPECT_GT(failed, 0) << "no limit made the alpha's allocation fail";
}
