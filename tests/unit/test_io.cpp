// SPDX-License-Identifier: Apache-2.0
// Pass I/O: Blender-like multilayer EXRs written through OpenImageIO with the
// channel names Blender 3.4 writes (checked on a real render), plain EXR/PNG
// round trips through writeImage, damaged files and failed writes.
#include <gtest/gtest.h>
#include <signal.h>
#include <unistd.h>

#include <algorithm>
#include <atomic>
#include <cmath>
#include <cstdlib>
#include <limits>
#include <cstdint>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <functional>
#include <iterator>
#include <string>
#include <thread>
#include <vector>

#include <OpenImageIO/half.h>
#include <OpenImageIO/imageio.h>

#include "core/color.h"
#include "core/conventions.h"
#include "core/error.h"
#include "io/cryptomatte.h"
#include "io/frame.h"
#include "io/image_write_testing.h"
#include "io/temporary_file.h"

namespace fs = std::filesystem;
using namespace crisp;

namespace {

// A distinct, exactly representable (also in half) value per pixel and channel.
float pixelValue(int x, int y, int c) { return float(100 * y + x) + 0.25f * float(c); }
float pixelValue0(int x, int y) { return pixelValue(x, y, 0); }

struct Channel {
  std::string name;
  OIIO::TypeDesc type;
  std::function<float(int, int)> value;
};

struct ExrLayout {
  int width = 7, height = 5;           // data window size
  int x = 0, y = 0;                    // data window origin
  int fullWidth = 0, fullHeight = 0;   // display window (0 = same as data)
  int fullX = 0, fullY = 0;            // display window origin
  int tileWidth = 0, tileHeight = 0;   // tiled if set, else scanlines
  std::vector<std::pair<std::string, std::string>> attributes;
};

// A layout with a data window (width x height at x, y) in a display window (fullWidth x fullHeight at
// fullX, fullY).
ExrLayout windowed(int width, int height, int x, int y, int fullWidth, int fullHeight, int fullX = 0, int fullY = 0) {
  ExrLayout layout;
  layout.width = width;
  layout.height = height;
  layout.x = x;
  layout.y = y;
  layout.fullWidth = fullWidth;
  layout.fullHeight = fullHeight;
  layout.fullX = fullX;
  layout.fullY = fullY;
  return layout;
}

// The header of an EXR (or of one part) with the given channels (names used verbatim).
OIIO::ImageSpec exrSpec(const std::vector<Channel>& channels, const ExrLayout& layout, const char* compression) {
  OIIO::ImageSpec spec(layout.width, layout.height, int(channels.size()), OIIO::TypeDesc::FLOAT);
  spec.x = layout.x;
  spec.y = layout.y;
  spec.full_x = layout.fullX;
  spec.full_y = layout.fullY;
  spec.full_width = layout.fullWidth ? layout.fullWidth : layout.width;
  spec.full_height = layout.fullHeight ? layout.fullHeight : layout.height;
  spec.channelnames.clear();
  spec.channelformats.clear();
  for (const auto& c : channels) {
    spec.channelnames.push_back(c.name);
    spec.channelformats.push_back(c.type);
  }
  spec.alpha_channel = -1;
  spec.tile_width = layout.tileWidth;
  spec.tile_height = layout.tileHeight;
  spec.attribute("compression", compression);
  for (const auto& kv : layout.attributes) spec.attribute(kv.first, kv.second);
  return spec;
}

// The pixels of those channels, interleaved.
std::vector<float> exrPixels(const std::vector<Channel>& channels, const ExrLayout& layout) {
  std::vector<float> data(std::size_t(layout.width) * std::size_t(layout.height) * channels.size());
  for (int y = 0; y < layout.height; ++y)
    for (int x = 0; x < layout.width; ++x)
      for (std::size_t c = 0; c < channels.size(); ++c)
        data[(std::size_t(y) * std::size_t(layout.width) + std::size_t(x)) * channels.size() + c] = channels[c].value(x, y);
  return data;
}

// Writes an EXR through OIIO with the given channels (names used verbatim).
void writeExr(const std::string& path, const std::vector<Channel>& channels, const ExrLayout& layout,
              const char* compression = "none") {
  auto out = OIIO::ImageOutput::create(path);
  ASSERT_TRUE(out) << OIIO::geterror();
  ASSERT_TRUE(out->open(path, exrSpec(channels, layout, compression))) << out->geterror();
  ASSERT_TRUE(out->write_image(OIIO::TypeDesc::FLOAT, exrPixels(channels, layout).data())) << out->geterror();
  ASSERT_TRUE(out->close()) << out->geterror();
}

// One part of a multi-part EXR: its name (OpenEXR's "name" attribute), channels and windows.
struct ExrPart {
  std::string name;
  std::vector<Channel> channels;
  ExrLayout layout;
};

// Writes a multi-part EXR through OIIO, a part per subimage.
void writeMultiPartExr(const std::string& path, const std::vector<ExrPart>& parts) {
  auto out = OIIO::ImageOutput::create(path);
  ASSERT_TRUE(out) << OIIO::geterror();
  ASSERT_TRUE(out->supports("multiimage"));
  std::vector<OIIO::ImageSpec> specs;
  for (const ExrPart& p : parts) {
    specs.push_back(exrSpec(p.channels, p.layout, "zip"));
    specs.back().attribute("oiio:subimagename", p.name);
  }
  ASSERT_TRUE(out->open(path, int(specs.size()), specs.data())) << out->geterror();
  for (std::size_t k = 0; k < parts.size(); ++k) {
    if (k > 0) {
      ASSERT_TRUE(out->open(path, specs[k], OIIO::ImageOutput::AppendSubimage)) << out->geterror();
    }
    ASSERT_TRUE(out->write_image(OIIO::TypeDesc::FLOAT, exrPixels(parts[k].channels, parts[k].layout).data()))
        << out->geterror();
  }
  ASSERT_TRUE(out->close()) << out->geterror();
}

// The channels of `all` whose names contain `part`, renamed by `rename` (the name as a part holds it).
std::vector<Channel> channelsWith(const std::vector<Channel>& all, const std::string& part,
                                  std::function<std::string(const std::string&)> rename = nullptr) {
  std::vector<Channel> out;
  for (const Channel& c : all)
    if (c.name.find(part) != std::string::npos) out.push_back({rename ? rename(c.name) : c.name, c.type, c.value});
  return out;
}

// Objects of the synthetic frame: left columns "Left", right columns "Right",
// the bottom row background.
const std::string kLeft = "Left", kRight = "Right.001";
std::uint32_t objectAt(int x, int y, int w, int h) {
  if (y == h - 1) return 0;
  return x < w / 2 ? cryptomatteHash(kLeft) : cryptomatteHash(kRight);
}
float bitsToFloat(std::uint32_t v) { return cryptomatteHashToFloat(v); }
float bgDepth(int x, int y, int w, int h) { return objectAt(x, y, w, h) ? float(1 + x + 7 * y) : 65504.0f; }

// Channels as Blender 3.4 writes them (layer "ViewLayer"), in a shuffled
// order: the reader must go by name, not position.
std::vector<Channel> blenderChannels(const std::string& layer, int w, int h, bool withVector = true) {
  const auto F = OIIO::TypeDesc::FLOAT;
  const auto H = OIIO::TypeDesc::HALF;
  std::vector<Channel> ch = {
      {layer + ".Normal.Z", H, [](int x, int y) { return pixelValue(x, y, 2) / 1024.0f; }},
      {layer + ".Combined.B", F, [](int x, int y) { return pixelValue(x, y, 2); }},
      {layer + ".Depth.Z", H, [w, h](int x, int y) { return bgDepth(x, y, w, h); }},
      {layer + ".Combined.R", F, [](int x, int y) { return pixelValue(x, y, 0); }},
      {layer + ".CryptoObject00.r", F, [w, h](int x, int y) { return bitsToFloat(objectAt(x, y, w, h)); }},
      {layer + ".CryptoObject00.g", F, [w, h](int x, int y) { return objectAt(x, y, w, h) ? 1.0f : 0.0f; }},
      {layer + ".CryptoObject00.b", F, [](int, int) { return 0.0f; }},
      {layer + ".CryptoObject00.a", F, [](int, int) { return 0.0f; }},
      {layer + ".Combined.G", F, [](int x, int y) { return pixelValue(x, y, 1); }},
      {layer + ".Combined.A", F, [](int x, int y) { return pixelValue(x, y, 3); }},
      {layer + ".Normal.X", H, [](int x, int y) { return pixelValue(x, y, 0) / 1024.0f; }},
      {layer + ".Normal.Y", H, [](int x, int y) { return pixelValue(x, y, 1) / 1024.0f; }},
      {layer + ".DiffCol.R", F, [](int x, int y) { return pixelValue(x, y, 0) / 1000.0f; }},
      {layer + ".DiffCol.G", F, [](int x, int y) { return pixelValue(x, y, 1) / 1000.0f; }},
      {layer + ".DiffCol.B", F, [](int x, int y) { return pixelValue(x, y, 2) / 1000.0f; }},
  };
  if (withVector) {
    ch.push_back({layer + ".Vector.X", F, [](int x, int) { return 0.5f + float(x); }});
    ch.push_back({layer + ".Vector.Y", F, [](int, int y) { return 1.5f + float(y); }});
    ch.push_back({layer + ".Vector.Z", F, [](int x, int) { return -2.0f - float(x); }});
    ch.push_back({layer + ".Vector.W", F, [](int, int y) { return -3.0f - float(y); }});
  }
  return ch;
}

// The manifest attribute as Blender 3.4 wrote it for "ViewLayer.CryptoObject"
// in a real render: key "cryptomatte/542cafa/...".
std::vector<std::pair<std::string, std::string>> blenderManifest() {
  const std::string manifest = "{\"" + kLeft + "\":\"" + hashToHex(cryptomatteHash(kLeft)) + "\",\"" + kRight +
                               "\":\"" + hashToHex(cryptomatteHash(kRight)) + "\"}";
  return {{"cryptomatte/542cafa/name", "ViewLayer.CryptoObject"},
          {"cryptomatte/542cafa/hash", "MurmurHash3_32"},
          {"cryptomatte/542cafa/conversion", "uint32_to_float32"},
          {"cryptomatte/542cafa/manifest", manifest}};
}

class IoTest : public ::testing::Test {
 protected:
  fs::path dir;
  void SetUp() override {
    const auto* info = ::testing::UnitTest::GetInstance()->current_test_info();
    dir = fs::temp_directory_path() /
          ("crisp_io_" + std::to_string(::getpid()) + "_" + info->test_suite_name() + "_" + info->name());
    fs::remove_all(dir);
    fs::create_directories(dir);
  }
  void TearDown() override {
    std::error_code ec;
    fs::permissions(dir, fs::perms::owner_all, fs::perm_options::add, ec);
    fs::remove_all(dir, ec);
  }
  std::string file(const std::string& name) const { return (dir / name).string(); }
  // A Blender-like EXR (blenderChannels of the layout's data window, with the manifest) in
  // `compression`, of scanlines, or of 40 x tileHeight tiles if tileHeight is set; returns its path.
  std::string blenderExr(const std::string& stem, ExrLayout layout, const char* compression, int tileHeight = 0) const {
    layout.tileWidth = tileHeight ? 40 : 0;
    layout.tileHeight = tileHeight;
    layout.attributes = blenderManifest();
    const std::string path = file(stem + "_" + compression + (tileHeight ? "_tiled" : "") + ".exr");
    writeExr(path, blenderChannels("ViewLayer", layout.width, layout.height), layout, compression);
    return path;
  }
  std::vector<std::string> temporaries() const {
    std::vector<std::string> found;
    for (const auto& e : fs::directory_iterator(dir))
      if (e.path().filename().string().find(".tmp-") != std::string::npos) found.push_back(e.path().string());
    return found;
  }
};

// Runs `f`, expecting a crisp::Exception with `code` whose message names `needle`.
template <class F>
void expectError(F&& f, CrispError code, const std::string& needle, const std::string& needle2 = "") {
  try {
    f();
    FAIL() << "no exception; expected code " << code << " naming " << needle;
  } catch (const Exception& e) {
    EXPECT_EQ(e.code(), code) << e.what();
    EXPECT_NE(std::string(e.what()).find(needle), std::string::npos) << e.what();
    if (!needle2.empty()) {
      EXPECT_NE(std::string(e.what()).find(needle2), std::string::npos) << e.what();
    }
  }
  EXPECT_FALSE(OIIO::has_error()) << "OIIO error queue left non-empty: " << OIIO::geterror();
}

std::vector<char> readBytes(const std::string& path) {
  std::ifstream f(path, std::ios::binary);
  return std::vector<char>((std::istreambuf_iterator<char>(f)), std::istreambuf_iterator<char>());
}
void writeBytes(const std::string& path, const std::vector<char>& bytes) {
  std::ofstream f(path, std::ios::binary | std::ios::trunc);
  f.write(bytes.data(), std::streamsize(bytes.size()));
}

}  // namespace

// ---------------------------------------------------------------- reading ----

TEST_F(IoTest, BlenderMultilayerFollowsConventions) {
  const int w = 7, h = 5;
  ExrLayout layout;
  layout.attributes = blenderManifest();
  const std::string path = file("blender.exr");
  writeExr(path, blenderChannels("ViewLayer", w, h), layout);

  Frame f = readFrame(path);
  ASSERT_EQ(f.width, w);
  ASSERT_EQ(f.height, h);
  EXPECT_EQ(f.passList(), "color,depth,normal,motion,id,albedo");
  EXPECT_EQ(f.channelNames.size(), blenderChannels("ViewLayer", w, h).size());
  for (const auto& c : blenderChannels("ViewLayer", w, h))
    EXPECT_NE(std::find(f.channelNames.begin(), f.channelNames.end(), c.name), f.channelNames.end()) << c.name;

  const Image& color = f.pass("color");
  ASSERT_EQ(color.channels, 4);
  // Row 0 is the top: pixel (0,0) holds what was written first, (6,4) the last.
  for (int y = 0; y < h; ++y)
    for (int x = 0; x < w; ++x)
      for (int c = 0; c < 4; ++c) ASSERT_EQ(color.at(x, y)[c], pixelValue(x, y, c)) << x << "," << y << "," << c;

  const Image& depth = f.pass("depth");
  ASSERT_EQ(depth.channels, 1);
  EXPECT_EQ(*depth.at(0, 0), 1.0f);
  EXPECT_EQ(*depth.at(6, 3), float(1 + 6 + 21));
  EXPECT_TRUE(isBackgroundDepth(*depth.at(3, h - 1)));  // half-float 65504 background
  EXPECT_FALSE(isBackgroundDepth(*depth.at(3, 0)));

  const Image& normal = f.pass("normal");
  ASSERT_EQ(normal.channels, 3);
  EXPECT_EQ(normal.at(2, 1)[0], pixelValue(2, 1, 0) / 1024.0f);
  EXPECT_EQ(normal.at(2, 1)[2], pixelValue(2, 1, 2) / 1024.0f);

  // Motion: Blender's y-up Vector becomes y-down: y and w negated, x and z kept.
  const Image& motion = f.pass("motion");
  ASSERT_EQ(motion.channels, 4);
  for (int y = 0; y < h; ++y)
    for (int x = 0; x < w; ++x) {
      EXPECT_EQ(motion.at(x, y)[0], 0.5f + float(x));
      EXPECT_EQ(motion.at(x, y)[1], -(1.5f + float(y)));
      EXPECT_EQ(motion.at(x, y)[2], -2.0f - float(x));
      EXPECT_EQ(motion.at(x, y)[3], 3.0f + float(y));
    }

  const Image& id = f.pass("id");
  ASSERT_EQ(id.format, Format::UInt);
  for (int y = 0; y < h; ++y)
    for (int x = 0; x < w; ++x) ASSERT_EQ(id.uintAt(x, y), objectAt(x, y, w, h)) << x << "," << y;
  EXPECT_EQ(id.uintAt(0, 0), cryptomatteHash(kLeft));
  EXPECT_EQ(id.uintAt(6, 0), cryptomatteHash(kRight));
  EXPECT_EQ(id.uintAt(0, h - 1), 0u);

  const Image& albedo = f.pass("albedo");
  ASSERT_EQ(albedo.channels, 3);
  EXPECT_EQ(albedo.at(6, 4)[1], pixelValue(6, 4, 1) / 1000.0f);

  ASSERT_EQ(f.objectIds.size(), 2u);
  EXPECT_EQ(f.objectIds.at(kLeft), cryptomatteHash(kLeft));
  EXPECT_EQ(f.objectIds.at(kRight), cryptomatteHash(kRight));
}

TEST_F(IoTest, IdIsZeroWhereCoverageIsZero) {
  // A hash in .r with zero coverage (a pixel Cryptomatte did not assign) is background.
  const std::uint32_t hash = cryptomatteHash("Ghost");
  std::vector<Channel> ch = {
      {"ViewLayer.Combined.R", OIIO::TypeDesc::FLOAT, [](int, int) { return 0.5f; }},
      {"ViewLayer.Combined.G", OIIO::TypeDesc::FLOAT, [](int, int) { return 0.5f; }},
      {"ViewLayer.Combined.B", OIIO::TypeDesc::FLOAT, [](int, int) { return 0.5f; }},
      {"ViewLayer.CryptoObject00.r", OIIO::TypeDesc::FLOAT, [hash](int, int) { return bitsToFloat(hash); }},
      {"ViewLayer.CryptoObject00.g", OIIO::TypeDesc::FLOAT, [](int x, int) { return x == 0 ? 0.0f : 0.75f; }},
  };
  ExrLayout layout;
  writeExr(file("cov.exr"), ch, layout);
  Frame f = readFrame(file("cov.exr"));
  EXPECT_EQ(f.pass("id").uintAt(0, 2), 0u);
  EXPECT_EQ(f.pass("id").uintAt(1, 2), hash);
  EXPECT_EQ(f.pass("color").at(3, 3)[3], 1.0f);  // no Combined.A: alpha 1
  EXPECT_TRUE(f.objectIds.empty());
}

namespace {
// A layer's Combined R, G, B, A channels of value -7 everywhere, appended to `ch`.
void addCombinedOf(std::vector<Channel>& ch, const std::string& layer) {
  for (const char* c : {"R", "G", "B", "A"})
    ch.push_back({layer + ".Combined." + c, OIIO::TypeDesc::FLOAT, [](int, int) { return -7.0f; }});
}
}  // namespace

TEST_F(IoTest, PicksBlenderDefaultLayerOrTheNamedOne) {
  // "Second" sorts before "ViewLayer" in the file; the default layer wins.
  std::vector<Channel> ch = blenderChannels("ViewLayer", 7, 5, false);
  addCombinedOf(ch, "Second");
  ExrLayout layout;
  writeExr(file("layers.exr"), ch, layout);
  Frame f = readFrame(file("layers.exr"));
  EXPECT_EQ(f.pass("color").at(1, 1)[0], pixelValue(1, 1, 0));
  EXPECT_FALSE(f.has("motion"));

  Frame second = readFrame(file("layers.exr"), "Second");
  EXPECT_EQ(second.pass("color").at(1, 1)[0], -7.0f);
  EXPECT_EQ(second.passList(), "color");
  // The layer read and the others, which nothing is read from, are named (crisp info, crisp filter).
  EXPECT_EQ(f.layer, "ViewLayer");
  EXPECT_EQ(f.layersNotRead, std::vector<std::string>{"'Second' (4 channels)"});
  EXPECT_EQ(second.layer, "Second");
  EXPECT_EQ(second.layersNotRead, std::vector<std::string>{"'ViewLayer' (15 channels)"});
  expectError([&] { readFrame(file("layers.exr"), "Nope"); }, CRISP_ERROR_INVALID_DATA, "Nope", "layers.exr");
  // A pass that is absent is reported by name.
  expectError([&] { second.pass("depth"); }, CRISP_ERROR_INVALID_DATA, "depth", "layers.exr");
}

// Blender writes the compositor's result as layer "Composite" beside the view layers: a view layer
// renamed "Main" sorts after it, and its passes were left for the composited colour alone.
TEST_F(IoTest, TheCompositorsLayerIsNotTakenForAViewLayer) {
  std::vector<Channel> ch = blenderChannels("Main", 7, 5, false);
  addCombinedOf(ch, "Composite");
  ExrLayout layout;
  writeExr(file("composite.exr"), ch, layout);
  Frame f = readFrame(file("composite.exr"));
  EXPECT_EQ(f.layer, "Main");
  EXPECT_EQ(f.pass("color").at(1, 1)[0], pixelValue(1, 1, 0));
  EXPECT_EQ(f.passList(), "color,depth,normal,id,albedo");
  EXPECT_TRUE(f.layersNotRead.empty());
  // Asked for by name it is read; a file of the compositor's layer alone is read from it.
  EXPECT_EQ(readFrame(file("composite.exr"), "Composite").pass("color").at(1, 1)[0], -7.0f);
  std::vector<Channel> alone;
  addCombinedOf(alone, "Composite");
  writeExr(file("composite_alone.exr"), alone, layout);
  EXPECT_EQ(readFrame(file("composite_alone.exr")).layer, "Composite");
}

TEST_F(IoTest, LayerNamesWithDotsSplitFromTheRight) {
  std::vector<Channel> ch = blenderChannels("My.Layer", 7, 5, false);
  ExrLayout layout;
  writeExr(file("dots.exr"), ch, layout);
  Frame f = readFrame(file("dots.exr"));
  EXPECT_EQ(f.passList(), "color,depth,normal,id,albedo");
  EXPECT_EQ(f.pass("color").at(4, 2)[2], pixelValue(4, 2, 2));
}

// A pass of other channels than Blender writes is unusable: the frame is read, and asking for the
// pass is the error, naming it and the file (as for half-float IDs below), so only a method that
// reads it fails. Colour of wrong channels fails the read.
TEST_F(IoTest, PassWithWrongChannelsIsAnErrorNamingIt) {
  std::vector<Channel> ch = blenderChannels("ViewLayer", 7, 5, false);
  ch.erase(std::remove_if(ch.begin(), ch.end(), [](const Channel& c) { return c.name == "ViewLayer.Normal.Z"; }),
           ch.end());
  ExrLayout layout;
  writeExr(file("normal2.exr"), ch, layout);
  const Frame normal2 = readFrame(file("normal2.exr"));
  EXPECT_TRUE(normal2.has("color") && normal2.has("depth") && !normal2.has("normal"));
  expectError([&] { normal2.pass("normal"); }, CRISP_ERROR_INVALID_DATA, "ViewLayer.Normal", "normal2.exr");

  // An extra channel is as wrong as a missing one.
  std::vector<Channel> ch2 = blenderChannels("ViewLayer", 7, 5, false);
  ch2.push_back({"ViewLayer.Depth.W", OIIO::TypeDesc::FLOAT, [](int, int) { return 0.0f; }});
  writeExr(file("depth2.exr"), ch2, layout);
  expectError([&] { readFrame(file("depth2.exr")).pass("depth"); }, CRISP_ERROR_INVALID_DATA, "ViewLayer.Depth",
              "depth2.exr");

  // Motion of two channels, as some compositors write it.
  std::vector<Channel> ch3 = blenderChannels("ViewLayer", 7, 5, false);
  for (const char* c : {"X", "Y"})
    ch3.push_back({std::string("ViewLayer.Vector.") + c, OIIO::TypeDesc::FLOAT, [](int, int) { return 1.0f; }});
  writeExr(file("vector2.exr"), ch3, layout);
  const Frame vector2 = readFrame(file("vector2.exr"));
  EXPECT_EQ(vector2.passList(), "color,depth,normal,id,albedo");
  expectError([&] { vector2.pass("motion"); }, CRISP_ERROR_INVALID_DATA, "pass 'ViewLayer.Vector' in '" + file("vector2.exr"),
              "has 2 channel(s) (X,Y); expected X,Y,Z,W");

  std::vector<Channel> ch4 = blenderChannels("ViewLayer", 7, 5, false);
  ch4.erase(std::remove_if(ch4.begin(), ch4.end(), [](const Channel& c) { return c.name == "ViewLayer.Combined.G"; }),
            ch4.end());
  writeExr(file("combined2.exr"), ch4, layout);
  expectError([&] { readFrame(file("combined2.exr")); }, CRISP_ERROR_INVALID_DATA, "pass 'ViewLayer.Combined'",
              "combined2.exr");
}

TEST_F(IoTest, MissingColourIsAnErrorNamingTheFile) {
  std::vector<Channel> ch = {{"ViewLayer.Depth.Z", OIIO::TypeDesc::FLOAT, [](int, int) { return 1.0f; }}};
  ExrLayout layout;
  writeExr(file("nocolor.exr"), ch, layout);
  expectError([&] { readFrame(file("nocolor.exr")); }, CRISP_ERROR_INVALID_DATA, "nocolor.exr", "colour");
}

// Half-float IDs cannot hold the hashes: the frame reads without them, and
// asking for its id pass is the error, naming the pass and the file.
TEST_F(IoTest, HalfFloatIdsAreRefused) {
  std::vector<Channel> ch = blenderChannels("ViewLayer", 7, 5, false);
  for (auto& c : ch)
    if (c.name == "ViewLayer.CryptoObject00.r") c.type = OIIO::TypeDesc::HALF;
  ExrLayout layout;
  writeExr(file("halfid.exr"), ch, layout);
  const Frame frame = readFrame(file("halfid.exr"));
  EXPECT_FALSE(frame.has("id"));
  EXPECT_TRUE(frame.has("color") && frame.has("depth"));
  expectError([&] { frame.pass("id"); }, CRISP_ERROR_INVALID_DATA, "CryptoObject00", "halfid.exr");
}

TEST_F(IoTest, BadManifestIsAnError) {
  ExrLayout layout;
  layout.attributes = {{"cryptomatte/542cafa/name", "ViewLayer.CryptoObject"},
                       {"cryptomatte/542cafa/manifest", "{\"Cube\":\"a8fce86\"}"}};
  writeExr(file("badmanifest.exr"), blenderChannels("ViewLayer", 7, 5, false), layout);
  expectError([&] { readFrame(file("badmanifest.exr")); }, CRISP_ERROR_INVALID_DATA, "badmanifest.exr", "Cube");
}

TEST_F(IoTest, ManifestFoundByMatteNameWhenKeyDiffers) {
  // Another writer might key the manifest differently; the name entry links it.
  ExrLayout layout;
  layout.attributes = {{"cryptomatte/0000000/name", "ViewLayer.CryptoObject"},
                       {"cryptomatte/0000000/manifest", "{\"Left\":\"" + hashToHex(cryptomatteHash(kLeft)) + "\"}"}};
  writeExr(file("otherkey.exr"), blenderChannels("ViewLayer", 7, 5, false), layout);
  Frame f = readFrame(file("otherkey.exr"));
  ASSERT_EQ(f.objectIds.size(), 1u);
  EXPECT_EQ(f.objectIds.at(kLeft), cryptomatteHash(kLeft));
}

TEST_F(IoTest, DataWindowInsideDisplayWindowIsPlaced) {
  // Display 7x5; data 3x2 at (2,1): pixels land at their display position and
  // the rest is background.
  ExrLayout layout = windowed(3, 2, 2, 1, 7, 5);
  std::vector<Channel> ch = blenderChannels("ViewLayer", 3, 2, false);
  writeExr(file("window.exr"), ch, layout);
  Frame f = readFrame(file("window.exr"));
  ASSERT_EQ(f.width, 7);
  ASSERT_EQ(f.height, 5);
  const Image& color = f.pass("color");
  EXPECT_EQ(color.at(2, 1)[0], pixelValue(0, 0, 0));  // data (0,0)
  EXPECT_EQ(color.at(4, 2)[1], pixelValue(2, 1, 1));  // data (2,1)
  EXPECT_EQ(color.at(0, 0)[0], 0.0f);
  EXPECT_EQ(color.at(0, 0)[3], 0.0f);
  EXPECT_EQ(color.at(6, 4)[0], 0.0f);
  EXPECT_TRUE(isBackgroundDepth(*f.pass("depth").at(1, 1)));
  EXPECT_EQ(*f.pass("depth").at(2, 1), 1.0f);
  EXPECT_EQ(f.pass("id").uintAt(0, 0), 0u);
  EXPECT_EQ(f.pass("id").uintAt(2, 1), cryptomatteHash(kLeft));
}

TEST_F(IoTest, DataWindowLargerThanDisplayIsCropped) {
  // Overscan: data 9x7 at (-1,-1) around a 7x5 display window.
  ExrLayout layout = windowed(9, 7, -1, -1, 7, 5);
  writeExr(file("overscan.exr"), blenderChannels("ViewLayer", 9, 7, false), layout);
  Frame f = readFrame(file("overscan.exr"));
  ASSERT_EQ(f.width, 7);
  ASSERT_EQ(f.height, 5);
  EXPECT_EQ(f.pass("color").at(0, 0)[0], pixelValue(1, 1, 0));
  EXPECT_EQ(f.pass("color").at(6, 4)[2], pixelValue(7, 5, 2));
}

TEST_F(IoTest, TallFramesReadInStripsWhateverTheLayout) {
  // A file is read a strip of rows at a time (256 rows, every channel its passes read): frames of
  // several strips, in every lossless compression, as scanlines and as tiles whose height does not
  // divide 256, with a data window cut at the top and short of the bottom and sides of the display
  // window. Every pixel of every pass must be the file's (through half where it is stored so).
  const int w = 23, h = 600, fullW = 27, fullH = 620, x0 = 2, y0 = -30;
  auto asHalf = [](float v) {  // v stored as half and read back
    std::uint16_t bits;
    float back;
    OIIO::convert_pixel_values(OIIO::TypeFloat, &v, OIIO::TypeHalf, &bits);
    OIIO::convert_pixel_values(OIIO::TypeHalf, &bits, OIIO::TypeFloat, &back);
    return back;
  };
  for (const char* compression : {"none", "rle", "zips", "zip", "piz"}) {
    for (const int tile : {0, 48}) {
      SCOPED_TRACE(std::string(compression) + (tile ? ", tiled" : ", scanlines"));
      const Frame f = readFrame(blenderExr("tall", windowed(w, h, x0, y0, fullW, fullH), compression, tile));
      ASSERT_EQ(f.width, fullW);
      ASSERT_EQ(f.height, fullH);
      ASSERT_EQ(f.passList(), "color,depth,normal,motion,id,albedo");
      long wrong = 0;
      for (int Y = 0; Y < fullH; ++Y)
        for (int X = 0; X < fullW; ++X) {
          const int x = X - x0, y = Y - y0;
          const bool inside = x >= 0 && x < w && y >= 0 && y < h;
          const float* c = f.pass("color").at(X, Y);
          const float* n = f.pass("normal").at(X, Y);
          const float* m = f.pass("motion").at(X, Y);
          const float* a = f.pass("albedo").at(X, Y);
          const float depth = *f.pass("depth").at(X, Y);
          const std::uint32_t id = f.pass("id").uintAt(X, Y);
          if (!inside) {
            wrong += c[0] != 0.0f || c[3] != 0.0f || n[0] != 0.0f || m[1] != 0.0f || a[2] != 0.0f ||
                     !isBackgroundDepth(depth) || id != 0u;
            continue;
          }
          for (int k = 0; k < 4; ++k) wrong += c[k] != pixelValue(x, y, k);
          for (int k = 0; k < 3; ++k) wrong += n[k] != asHalf(pixelValue(x, y, k) / 1024.0f);
          for (int k = 0; k < 3; ++k) wrong += a[k] != pixelValue(x, y, k) / 1000.0f;
          wrong += m[0] != 0.5f + float(x) || m[1] != -(1.5f + float(y)) || m[3] != 3.0f + float(y);
          wrong += depth != asHalf(bgDepth(x, y, w, h)) || id != objectAt(x, y, w, h);
          if (wrong && (X + Y) % 97 == 0) ADD_FAILURE() << "first wrong pixel near " << X << "," << Y;
        }
      EXPECT_EQ(wrong, 0);
    }
  }
  // Two parts of several strips each, the depth's data window (10x300 at (5,200)) inside the display
  // window and across a strip's edge.
  ExrLayout colour, depth;
  colour.width = colour.fullWidth = fullW;
  colour.height = colour.fullHeight = fullH;
  depth = windowed(10, 300, 5, 200, fullW, fullH);
  writeMultiPartExr(file("tall_parts.exr"),
                    {{"ViewLayer.Combined", channelsWith(blenderChannels("ViewLayer", fullW, fullH), ".Combined."), colour},
                     {"ViewLayer.Depth", {{"Z", OIIO::TypeDesc::FLOAT, [](int x, int y) { return float(1 + x + 10 * y); }}},
                      depth}});
  const Frame f = readFrame(file("tall_parts.exr"));
  long wrong = 0;
  for (int Y = 0; Y < fullH; ++Y)
    for (int X = 0; X < fullW; ++X) {
      for (int k = 0; k < 4; ++k) wrong += f.pass("color").at(X, Y)[k] != pixelValue(X, Y, k);
      const bool inside = X >= 5 && X < 15 && Y >= 200 && Y < 500;
      const float z = *f.pass("depth").at(X, Y);
      wrong += inside ? z != float(1 + (X - 5) + 10 * (Y - 200)) : !isBackgroundDepth(z);
    }
  EXPECT_EQ(wrong, 0);
}

TEST_F(IoTest, InputsThatOnceCrashedAReaderAreRefusedCleanly) {
  // tests/fuzz/regressions/frame_reader_*: fuzz_frame_reader's inputs (a byte picking the extension,
  // then the file) that crashed the process once. frame_reader_core_zero_lines_per_chunk: a corrupt
  // header OpenEXR's C library parsed leniently into 0 lines per chunk, on which OIIO's reader over
  // that library (tried for speed, and dropped) divided by zero (SIGFPE).
  int seen = 0;
  for (const auto& entry : fs::directory_iterator(CRISP_FUZZ_REGRESSIONS)) {
    if (entry.path().filename().string().rfind("frame_reader_", 0) != 0) continue;
    SCOPED_TRACE(entry.path().string());
    const std::vector<char> bytes = readBytes(entry.path().string());
    ASSERT_FALSE(bytes.empty());
    static const char* const kExt[] = {".exr", ".png", ".exr", ".exr"};
    const std::string path = file("regression" + std::string(kExt[bytes[0] & 3]));
    writeBytes(path, std::vector<char>(bytes.begin() + 1, bytes.end()));
    try {
      readFrame(path);
    } catch (const Exception& e) {
      EXPECT_NE(std::string(e.what()).find(path), std::string::npos) << e.what();
    }
    ++seen;
  }
  EXPECT_GE(seen, 1);
}

TEST_F(IoTest, ThreadsReadingAtOnceGetWhatAReadAloneGets) {
  // crispLoadFrame may be called on several threads at once (a host's own threads), and readFrame
  // converts strips on a thread of OIIO's pool: threads reading files of several compressions at
  // once must each get the pixels a read alone gets.
  const int w = 16, h = 600;
  std::vector<std::string> paths;
  std::vector<Frame> alone;
  for (const char* compression : {"dwaa", "zip", "none", "piz"}) {
    paths.push_back(blenderExr("threads", windowed(w, h, 0, 0, w, h), compression));
    alone.push_back(readFrame(paths.back()));
  }
  std::atomic<int> wrong{0}, failed{0};
  std::vector<std::thread> threads;
  for (int t = 0; t < 4; ++t)
    threads.emplace_back([&, t] {
      for (int k = 0; k < 24; ++k) {
        const std::size_t f = std::size_t(t + k) % paths.size();
        try {
          const Frame frame = readFrame(paths[f]);
          for (const auto& [role, image] : alone[f].passes)
            wrong += image.data != frame.pass(role).data;
        } catch (const Exception&) {
          ++failed;
        }
      }
    });
  for (std::thread& t : threads) t.join();
  EXPECT_EQ(failed, 0);
  EXPECT_EQ(wrong, 0);
}

// Plain float R,G,B,A channels of pixelValue, for tests of windows.
static std::vector<Channel> plainRgba() {
  std::vector<Channel> ch;
  for (int c = 0; c < 4; ++c)
    ch.push_back({std::string(1, "RGBA"[c]), OIIO::TypeDesc::FLOAT, [c](int x, int y) { return pixelValue(x, y, c); }});
  return ch;
}

// The data window (x, y, width, height), then the display window, of a file as OIIO reads it.
static std::vector<int> windowsOf(const std::string& path) {
  auto in = OIIO::ImageInput::open(path);
  if (!in) return {};
  const OIIO::ImageSpec& s = in->spec();
  return {s.x, s.y, s.width, s.height, s.full_x, s.full_y, s.full_width, s.full_height};
}

TEST_F(IoTest, WrittenExrKeepsTheInputsWindows) {
  // Display 7x5 at (10,20); data 3x2 at (12,21): the frame read and written back lies where it was.
  ExrLayout layout = windowed(3, 2, 12, 21, 7, 5, 10, 20);
  writeExr(file("in.exr"), plainRgba(), layout);
  const Frame f = readFrame(file("in.exr"));
  ASSERT_EQ(f.width, 7);
  EXPECT_EQ(f.windows.displayX, 10);
  EXPECT_EQ(f.windows.displayY, 20);
  EXPECT_EQ(f.windows.dataX, 12);
  EXPECT_EQ(f.windows.dataY, 21);
  EXPECT_EQ(f.windows.dataWidth, 3);
  EXPECT_EQ(f.windows.dataHeight, 2);
  writeImage(file("out.exr"), f.pass("color").view(), f.windows);
  EXPECT_EQ(windowsOf(file("out.exr")), windowsOf(file("in.exr")));
  EXPECT_EQ(windowsOf(file("out.exr")), (std::vector<int>{12, 21, 3, 2, 10, 20, 7, 5}));
  const Frame back = readFrame(file("out.exr"));
  EXPECT_EQ(back.pass("color").data, f.pass("color").data);
  EXPECT_EQ(back.pass("color").at(2, 1)[0], pixelValue(0, 0, 0));
  EXPECT_EQ(back.pass("color").at(4, 2)[3], pixelValue(2, 1, 3));
  // A PNG has no windows: it holds the display window.
  writeImage(file("out.png"), f.pass("color").view(), f.windows);
  EXPECT_EQ(windowsOf(file("out.png")), (std::vector<int>{0, 0, 7, 5, 0, 0, 7, 5}));
  // Without windows: the display window at origin 0, all of it data.
  writeImage(file("plain.exr"), f.pass("color"));
  EXPECT_EQ(windowsOf(file("plain.exr")), (std::vector<int>{0, 0, 7, 5, 0, 0, 7, 5}));
}

TEST_F(IoTest, WrittenDataWindowIsClippedToTheDisplayWindow) {
  // Overscan (data 9x7 at (-1,-1) around display 7x5) is read cropped: the output is the display window.
  ExrLayout layout = windowed(9, 7, -1, -1, 7, 5);
  writeExr(file("overscan.exr"), plainRgba(), layout);
  Frame f = readFrame(file("overscan.exr"));
  writeImage(file("out.exr"), f.pass("color").view(), f.windows);
  EXPECT_EQ(windowsOf(file("out.exr")), (std::vector<int>{0, 0, 7, 5, 0, 0, 7, 5}));
  EXPECT_EQ(readFrame(file("out.exr")).pass("color").data, f.pass("color").data);
  // Partly outside: the overlap. Wholly outside (nothing of the file in view): the display window.
  layout.width = 4;
  layout.height = 3;
  layout.x = 5;
  layout.y = -2;
  writeExr(file("corner.exr"), plainRgba(), layout);
  f = readFrame(file("corner.exr"));
  writeImage(file("corner_out.exr"), f.pass("color").view(), f.windows);
  EXPECT_EQ(windowsOf(file("corner_out.exr")), (std::vector<int>{5, 0, 2, 1, 0, 0, 7, 5}));
  EXPECT_EQ(readFrame(file("corner_out.exr")).pass("color").data, f.pass("color").data);
  layout.x = 20;
  layout.y = 20;
  writeExr(file("away.exr"), plainRgba(), layout);
  f = readFrame(file("away.exr"));
  writeImage(file("away_out.exr"), f.pass("color").view(), f.windows);
  EXPECT_EQ(windowsOf(file("away_out.exr")), (std::vector<int>{0, 0, 7, 5, 0, 0, 7, 5}));
}

// Every codec of Blender's OpenEXR output, at 32 and 16 bits (Color Depth), stored as asked and read
// back: the lossless ones exactly (at 16 bits, as half rounds), the lossy ones close; half's
// overflow is written as +-65504, not infinity; windows are kept; an unknown codec is refused.
TEST_F(IoTest, ExrStoredAsBlendersOutputSettingsSay) {
  const int w = 37, h = 21;  // odd sizes: partial blocks for b44 and dwa (4x4, 32 rows)
  Image img(w, h, 4);
  for (int y = 0; y < h; ++y)
    for (int x = 0; x < w; ++x)
      for (int c = 0; c < 4; ++c) img.at(x, y)[c] = c == 3 ? 1.0f : 0.05f + 0.9f * float((x * 7 + y * 3 + c * 5) % 31) / 30.0f;
  img.at(3, 4)[0] = 1e6f;     // an HDR firefly beyond half's range
  img.at(5, 6)[1] = -70000.0f;
  const std::vector<std::string> lossless = {"none", "zip", "zips", "piz", "rle"};
  for (const std::string& codec : exrCompressions()) {
    for (bool half : {false, true}) {
      SCOPED_TRACE(codec + (half ? " half" : " float"));
      const std::string path = file("out_" + codec + (half ? "_16" : "_32") + ".exr");
      ExrStorage storage;
      storage.half = half;
      storage.compression = codec;
      FrameWindows windows;
      windows.displayX = 4;
      windows.displayY = 2;
      windows.dataX = 4;
      windows.dataY = 2;
      windows.dataWidth = w;
      windows.dataHeight = h;
      writeImage(path, img.view(), windows, storage);
      // The file's own values, through OIIO (readFrame would clamp to kMaxColor, which is 65504 too).
      auto in = OIIO::ImageInput::open(path);
      ASSERT_TRUE(in);
      EXPECT_EQ(in->spec().format, half ? OIIO::TypeDesc::HALF : OIIO::TypeDesc::FLOAT);
      EXPECT_EQ(in->spec().get_string_attribute("compression"), codec);
      Image back(w, h, 4);
      ASSERT_TRUE(in->read_image(0, 0, 0, 4, OIIO::TypeDesc::FLOAT, back.data.data())) << in->geterror();
      in.reset();
      EXPECT_EQ(windowsOf(path), (std::vector<int>{4, 2, w, h, 4, 2, w, h}));
      // Lossy: pxr24 keeps 24 of a float's 32 bits (and is lossless on half); b44 stores float
      // channels as they are; dwa quantises colour (alpha too, at its default level 45).
      const bool exact = std::find(lossless.begin(), lossless.end(), codec) != lossless.end() ||
                         (half && codec == "pxr24") || (!half && (codec == "b44" || codec == "b44a"));
      double worst = 0.0;
      for (int y = 0; y < h; ++y)
        for (int x = 0; x < w; ++x)
          for (int c = 0; c < 4; ++c) {
            float want = img.at(x, y)[c];
            if (half) want = float(Imath::half(std::clamp(want, -65504.0f, 65504.0f)));
            const float got = back.at(x, y)[c];
            // b44 codes a 4x4 block of half by steps from its largest value: +-65504 beside
            // values near 1 comes back infinite (the codec's range, Blender's files alike).
            const bool b44Extreme = half && codec.rfind("b44", 0) == 0 && std::fabs(want) > 1.0f;
            if (!b44Extreme) {
              ASSERT_TRUE(std::isfinite(got)) << x << "," << y << "," << c;
            }
            if (exact) {
              ASSERT_EQ(got, want) << x << "," << y << "," << c;
            }
            // Away from the fireflies' block (dwa's 8x8, b44's 4x4 lie in it), where lossy
            // codecs spend their range on them.
            if (exact || x >= 8 || y >= 8) worst = std::max(worst, double(std::fabs(got - want)));
          }
      // A lossy codec still holds the picture: dwa within 2 %, b44 (a 4x4 block's steps from its
      // largest value, on this pattern's steps of 0.2 between pixels) within 6 %.
      if (exact) {
        EXPECT_EQ(back.at(3, 4)[0], half ? 65504.0f : 1e6f);
        EXPECT_EQ(back.at(5, 6)[1], half ? -65504.0f : -70000.0f);
      } else {
        EXPECT_LT(worst, codec.rfind("b44", 0) == 0 ? 0.06 : 0.02);
      }
    }
  }
  ExrStorage unknown;
  unknown.compression = "lzw";
  writeImage(file("keep.exr"), img.view());
  const auto before = std::filesystem::file_size(file("keep.exr"));
  try {
    writeImage(file("keep.exr"), img.view(), unknown);
    ADD_FAILURE() << "an unknown codec was taken";
  } catch (const Exception& e) {
    EXPECT_EQ(e.code(), CRISP_ERROR_INVALID_ARGUMENT);
    EXPECT_NE(std::string(e.what()).find("unknown EXR compression 'lzw' (known: none, zip, zips, piz, pxr24, rle, "
                                         "b44, b44a, dwaa, dwab)"),
              std::string::npos)
        << e.what();
  }
  EXPECT_EQ(std::filesystem::file_size(file("keep.exr")), before);
}

// ------------------------------------------------------- multi-part EXRs ----

// The same pixels, bit for bit (IDs are uint bits in float storage).
static bool sameImage(const Image& a, const Image& b) {
  return a.width == b.width && a.height == b.height && a.channels == b.channels && a.data.size() == b.data.size() &&
         std::memcmp(a.data.data(), b.data.data(), a.data.size() * sizeof(float)) == 0;
}

static std::function<std::string(const std::string&)> without(const std::string& prefix) {
  return [prefix](const std::string& n) { return n.substr(prefix.size()); };
}

// rsaa's sub-samples read their geometry alone (io/subsamples.h): every pass as
// readFrame reads it, the same size and windows, and no colour pixels.
TEST_F(IoTest, GeometryFrameIsTheFrameWithoutItsColour) {
  const int w = 7, h = 5;
  ExrLayout layout;
  layout.attributes = blenderManifest();
  const std::string path = file("geometry.exr");
  writeExr(path, blenderChannels("ViewLayer", w, h), layout);
  const Frame full = readFrame(path);
  const Frame geometry = readGeometryFrame(path);
  EXPECT_EQ(geometry.passList(), "depth,normal,motion,id,albedo");
  EXPECT_EQ(geometry.width, full.width);
  EXPECT_EQ(geometry.height, full.height);
  EXPECT_EQ(geometry.windows.dataWidth, full.windows.dataWidth);
  EXPECT_EQ(geometry.layer, full.layer);
  for (const char* role : {"depth", "normal", "motion", "id", "albedo"})
    EXPECT_TRUE(sameImage(geometry.pass(role), full.pass(role))) << role;
  // The colour's part still sets the frame: a file without colour is refused as readFrame refuses it.
  const std::string noColour = file("geometry_no_colour.exr");
  std::vector<Channel> channels;
  for (const Channel& c : blenderChannels("ViewLayer", w, h))
    if (c.name.find(".Combined.") == std::string::npos) channels.push_back(c);
  writeExr(noColour, channels, layout);
  expectError([&] { readGeometryFrame(noColour); }, CRISP_ERROR_INVALID_DATA, noColour, "no colour");
}

TEST_F(IoTest, MultiPartPassesAreReadFromAnyPart) {
  // Blender's passes split into parts as a compositor writes them: full names, names the part's
  // name completes ("ViewLayer.Depth" holding "Z", "ViewLayer" holding "Normal.X"), the manifest
  // in the ID part's header, and a part holding nothing read here. The frame is the single-part one.
  const std::vector<Channel> all = blenderChannels("ViewLayer", 7, 5);
  ExrLayout single;
  single.attributes = blenderManifest();
  writeExr(file("single.exr"), all, single);
  const Frame ref = readFrame(file("single.exr"));
  ExrLayout plain, withManifest;
  withManifest.attributes = blenderManifest();
  writeMultiPartExr(file("parts.exr"),
                    {{"ViewLayer.Combined", channelsWith(all, ".Combined."), plain},
                     {"ViewLayer.Depth", channelsWith(all, ".Depth.", without("ViewLayer.Depth.")), plain},
                     {"ViewLayer", channelsWith(all, ".Normal.", without("ViewLayer.")), plain},
                     {"crypto", channelsWith(all, ".CryptoObject00."), withManifest},
                     {"ViewLayer.DiffCol", channelsWith(all, ".DiffCol."), plain},
                     {"motion", channelsWith(all, ".Vector."), plain},
                     {"other", {{"diffuse.R", OIIO::TypeDesc::FLOAT, [](int, int) { return 1.0f; }}}, plain}});
  const Frame f = readFrame(file("parts.exr"));
  EXPECT_EQ(f.passList(), "color,depth,normal,motion,id,albedo");
  EXPECT_EQ(f.passList(), ref.passList());
  for (const auto& [role, image] : ref.passes) EXPECT_TRUE(f.has(role) && sameImage(f.pass(role), image)) << role;
  EXPECT_EQ(f.objectIds, ref.objectIds);
  EXPECT_EQ(f.objectIds.size(), 2u);
  ASSERT_EQ(f.partsNotRead.size(), 1u);
  EXPECT_EQ(f.partsNotRead[0], "part 7 of 7 ('other') (channels: diffuse.R)");
  for (const char* name : {"ViewLayer.Depth.Z", "ViewLayer.Normal.X", "diffuse.R"})
    EXPECT_NE(std::find(f.channelNames.begin(), f.channelNames.end(), name), f.channelNames.end()) << name;
}

TEST_F(IoTest, MultiPartPlainColourAndDepthInAnyPart) {
  // A depth part first, the colour second (each named as a compositor names it): colour and depth.
  ExrLayout layout;
  writeMultiPartExr(file("later.exr"),
                    {{"depth", {{"Z", OIIO::TypeDesc::FLOAT, [](int x, int) { return float(x) + 0.5f; }}}, layout},
                     {"rgba", plainRgba(), layout}});
  const Frame f = readFrame(file("later.exr"));
  EXPECT_EQ(f.passList(), "color,depth");
  EXPECT_TRUE(f.partsNotRead.empty());
  EXPECT_EQ(f.pass("color").at(6, 4)[3], pixelValue(6, 4, 3));
  EXPECT_EQ(*f.pass("depth").at(3, 2), 3.5f);
  // The first part's colour is the colour when a later part has R,G,B too (an AOV of its own).
  writeMultiPartExr(file("aov.exr"), {{"rgba", plainRgba(), layout},
                                      {"diffuse", channelsWith(plainRgba(), "B", [](const std::string&) { return "R"; }),
                                       layout}});
  EXPECT_EQ(readFrame(file("aov.exr")).pass("color").at(1, 1)[0], pixelValue(1, 1, 0));
}

TEST_F(IoTest, MultiPartPartsKeepTheirOwnDataWindows) {
  // Display 7x5 in both parts; the depth part's data window 3x2 at (2,1): placed as in one part.
  ExrLayout colour, depth;
  colour.fullWidth = depth.fullWidth = 7;
  colour.fullHeight = depth.fullHeight = 5;
  depth.width = 3;
  depth.height = 2;
  depth.x = 2;
  depth.y = 1;
  writeMultiPartExr(file("windows.exr"),
                    {{"ViewLayer.Combined", channelsWith(blenderChannels("ViewLayer", 7, 5, false), ".Combined."), colour},
                     {"ViewLayer.Depth", {{"Z", OIIO::TypeDesc::FLOAT, [](int x, int y) { return float(1 + x + 10 * y); }}},
                      depth}});
  const Frame f = readFrame(file("windows.exr"));
  ASSERT_EQ(f.width, 7);
  ASSERT_EQ(f.height, 5);
  EXPECT_EQ(f.windows.dataWidth, 7);  // the colour's
  EXPECT_TRUE(isBackgroundDepth(*f.pass("depth").at(1, 1)));
  EXPECT_EQ(*f.pass("depth").at(2, 1), 1.0f);
  EXPECT_EQ(*f.pass("depth").at(4, 2), 13.0f);
  EXPECT_TRUE(isBackgroundDepth(*f.pass("depth").at(5, 2)));
}

TEST_F(IoTest, MultiPartDisagreementsAreErrorsNamingThem) {
  const std::vector<Channel> all = blenderChannels("ViewLayer", 7, 5, false);
  // (Parts of different display windows are no case: OpenEXR refuses to write them, the display
  // window being an attribute its parts share; the reader still checks, for other formats.)
  ExrLayout layout;
  // A pass in two parts (or split over two).
  writeMultiPartExr(file("twice.exr"), {{"ViewLayer.Combined", channelsWith(all, ".Combined."), layout},
                                        {"a", channelsWith(all, ".Depth."), layout},
                                        {"b", channelsWith(all, ".Depth."), layout}});
  expectError([&] { readFrame(file("twice.exr")); }, CRISP_ERROR_INVALID_DATA,
              "pass 'ViewLayer.Depth' of '" + file("twice.exr") + "' is in more than one part", "part 2 of 3 ('a'), part 3 of 3 ('b')");
  writeMultiPartExr(file("split.exr"), {{"ViewLayer.Combined", channelsWith(all, "Combined.R"), layout},
                                        {"gb", channelsWith(all, "Combined.", [](const std::string& n) {
                                           return n.back() == 'R' ? "ViewLayer.Combined.X" : n; }), layout}});
  expectError([&] { readFrame(file("split.exr")); }, CRISP_ERROR_INVALID_DATA, "pass 'ViewLayer.Combined' of", "more than one part");
  // Plain colour in two later parts and none in the first; a Z in two parts, none beside the colour.
  writeMultiPartExr(file("colours.exr"), {{"depth", {{"Z", OIIO::TypeDesc::FLOAT, pixelValue0}}, layout},
                                          {"a", plainRgba(), layout}, {"b", plainRgba(), layout}});
  expectError([&] { readFrame(file("colours.exr")); }, CRISP_ERROR_INVALID_DATA, "colours.exr' has R,G,B colour in more than one part",
              "part 2 of 3 ('a'), part 3 of 3 ('b')");
  writeMultiPartExr(file("depths.exr"), {{"rgba", plainRgba(), layout},
                                         {"a", {{"Z", OIIO::TypeDesc::FLOAT, pixelValue0}}, layout},
                                         {"b", {{"Z", OIIO::TypeDesc::FLOAT, pixelValue0}}, layout}});
  expectError([&] { readFrame(file("depths.exr")); }, CRISP_ERROR_INVALID_DATA, "depths.exr' has a Z channel in more than one part");
  // A channel of a wrong pass names its part (when the pass is asked for: PassWithWrongChannels...).
  writeMultiPartExr(file("wrong.exr"), {{"ViewLayer.Combined", channelsWith(all, ".Combined."), layout},
                                        {"ViewLayer.Normal", {{"X", OIIO::TypeDesc::FLOAT, pixelValue0}}, layout}});
  expectError([&] { readFrame(file("wrong.exr")).pass("normal"); }, CRISP_ERROR_INVALID_DATA,
              "pass 'ViewLayer.Normal' in '" + file("wrong.exr") + "' (part 2 of 2 ('ViewLayer.Normal')) has 1 channel(s)");
}

TEST_F(IoTest, PlainExrWithZChannel) {
  std::vector<Channel> ch = {
      {"R", OIIO::TypeDesc::HALF, [](int x, int y) { return pixelValue(x, y, 0); }},
      {"G", OIIO::TypeDesc::HALF, [](int x, int y) { return pixelValue(x, y, 1); }},
      {"B", OIIO::TypeDesc::HALF, [](int x, int y) { return pixelValue(x, y, 2); }},
      {"Z", OIIO::TypeDesc::FLOAT, [](int x, int) { return x == 0 ? 1e10f : 3.0f; }},
  };
  ExrLayout layout;
  writeExr(file("plainz.exr"), ch, layout);
  Frame f = readFrame(file("plainz.exr"));
  EXPECT_EQ(f.passList(), "color,depth");
  EXPECT_EQ(f.pass("color").at(6, 4)[0], pixelValue(6, 4, 0));  // linear EXR: no decoding
  EXPECT_EQ(f.pass("color").at(6, 4)[3], 1.0f);
  EXPECT_TRUE(isBackgroundDepth(*f.pass("depth").at(0, 2)));
  EXPECT_EQ(*f.pass("depth").at(1, 2), 3.0f);
}

TEST_F(IoTest, NonFiniteColourIsSanitised) {
  const float inf = std::numeric_limits<float>::infinity(), nan = std::numeric_limits<float>::quiet_NaN();
  std::vector<Channel> ch = {
      {"R", OIIO::TypeDesc::FLOAT, [nan](int x, int) { return x == 0 ? nan : 1.0f; }},
      {"G", OIIO::TypeDesc::FLOAT, [inf](int x, int) { return x == 0 ? inf : 1.0f; }},
      {"B", OIIO::TypeDesc::FLOAT, [inf](int x, int) { return x == 0 ? -inf : 1.0f; }},
  };
  ExrLayout layout;
  writeExr(file("nan.exr"), ch, layout);
  Frame f = readFrame(file("nan.exr"));
  EXPECT_EQ(f.pass("color").at(0, 0)[0], 0.0f);
  EXPECT_EQ(f.pass("color").at(0, 0)[1], kMaxColor);
  EXPECT_EQ(f.pass("color").at(0, 0)[2], -kMaxColor);
  const long rows = f.pass("color").height;  // the non-finite values sit in column 0 of every row
  EXPECT_EQ(f.nonFiniteColour, 3 * rows);
  // Alpha is colour too: a NaN alpha is counted and read as 0.
  ch.push_back({"A", OIIO::TypeDesc::FLOAT, [nan](int x, int) { return x == 1 ? nan : 1.0f; }});
  writeExr(file("nan_alpha.exr"), ch, layout);
  Frame g = readFrame(file("nan_alpha.exr"));
  EXPECT_EQ(g.nonFiniteColour, 4 * rows);
  EXPECT_EQ(g.pass("color").at(1, 0)[3], 0.0f);
  EXPECT_EQ(g.pass("color").at(2, 0)[3], 1.0f);
}

TEST_F(IoTest, EightBitPngIsSrgbDecoded) {
  // An 8-bit file written directly through OIIO: code value v reads as srgbDecode(v/255).
  const int w = 7, h = 5;
  auto out = OIIO::ImageOutput::create(file("direct.png"));
  ASSERT_TRUE(out);
  OIIO::ImageSpec spec(w, h, 3, OIIO::TypeDesc::UINT8);
  ASSERT_TRUE(out->open(file("direct.png"), spec));
  std::vector<unsigned char> px(std::size_t(w * h * 3));
  for (int i = 0; i < w * h * 3; ++i) px[std::size_t(i)] = (unsigned char)(i * 7 % 256);
  ASSERT_TRUE(out->write_image(OIIO::TypeDesc::UINT8, px.data()));
  ASSERT_TRUE(out->close());
  Frame f = readFrame(file("direct.png"));
  for (int y = 0; y < h; ++y)
    for (int x = 0; x < w; ++x)
      for (int c = 0; c < 3; ++c) {
        const int i = (y * w + x) * 3 + c;
        ASSERT_NEAR(f.pass("color").at(x, y)[c], srgbDecode(float(i * 7 % 256) / 255.0f), 1e-6f) << x << "," << y;
      }
  EXPECT_EQ(f.pass("color").at(0, 0)[3], 1.0f);
}

TEST_F(IoTest, GreyPngBecomesRgb) {
  auto out = OIIO::ImageOutput::create(file("grey.png"));
  ASSERT_TRUE(out);
  OIIO::ImageSpec spec(3, 2, 1, OIIO::TypeDesc::UINT8);
  ASSERT_TRUE(out->open(file("grey.png"), spec));
  const unsigned char px[6] = {0, 50, 100, 150, 200, 255};
  ASSERT_TRUE(out->write_image(OIIO::TypeDesc::UINT8, px));
  ASSERT_TRUE(out->close());
  Frame f = readFrame(file("grey.png"));
  const float* p = f.pass("color").at(1, 1);  // value 200
  EXPECT_NEAR(p[0], srgbDecode(200.0f / 255.0f), 1e-6f);
  EXPECT_EQ(p[0], p[1]);
  EXPECT_EQ(p[0], p[2]);
}

// ---------------------------------------------------------------- writing ----

TEST_F(IoTest, ExrRoundTripIsExactAndTopDown) {
  const int w = 7, h = 5;
  Image im(w, h, 4);
  for (int y = 0; y < h; ++y)
    for (int x = 0; x < w; ++x)
      for (int c = 0; c < 4; ++c) im.at(x, y)[c] = pixelValue(x, y, c) * 0.001f - 0.1f;
  writeImage(file("rgba.exr"), im);
  Frame f = readFrame(file("rgba.exr"));
  ASSERT_EQ(f.width, w);
  ASSERT_EQ(f.height, h);
  EXPECT_EQ(f.pass("color").data, im.data);
  EXPECT_TRUE(temporaries().empty());

  // Reading the file with OIIO directly: the first scanline is row 0.
  auto in = OIIO::ImageInput::open(file("rgba.exr"));
  ASSERT_TRUE(in);
  EXPECT_EQ(in->spec().nchannels, 4);
  EXPECT_EQ(in->spec().format, OIIO::TypeDesc::FLOAT);
  std::vector<float> first(std::size_t(w) * 4);
  ASSERT_TRUE(in->read_scanline(0, 0, OIIO::TypeDesc::FLOAT, first.data()));
  EXPECT_EQ(first[0], im.at(0, 0)[0]);
  EXPECT_EQ(first[4 * 6 + 2], im.at(6, 0)[2]);
}

TEST_F(IoTest, RgbViewWithPaddedStridesGetsAlphaOne) {
  // A float3 view inside a larger buffer: 5 floats per pixel, 2 pixels of row padding.
  const int w = 7, h = 5, pixelFloats = 5, rowFloats = (w + 2) * pixelFloats;
  std::vector<float> buffer(std::size_t(rowFloats * h), -99.0f);
  for (int y = 0; y < h; ++y)
    for (int x = 0; x < w; ++x)
      for (int c = 0; c < 3; ++c) buffer[std::size_t(y * rowFloats + x * pixelFloats + c)] = pixelValue(x, y, c);
  ImageView view = makeView(buffer.data(), Format::Float3, w, h, pixelFloats * 4, std::size_t(rowFloats) * 4);
  writeImage(file("rgb.exr"), view);
  Frame f = readFrame(file("rgb.exr"));
  for (int y = 0; y < h; ++y)
    for (int x = 0; x < w; ++x) {
      for (int c = 0; c < 3; ++c) ASSERT_EQ(f.pass("color").at(x, y)[c], pixelValue(x, y, c));
      ASSERT_EQ(f.pass("color").at(x, y)[3], 1.0f);
    }
}

TEST_F(IoTest, PngRoundTripWithinOneCodeValue) {
  const int w = 7, h = 5;
  Image im(w, h, 4);
  for (int y = 0; y < h; ++y)
    for (int x = 0; x < w; ++x) {
      float* p = im.at(x, y);
      p[0] = float(x) / float(w - 1);           // 0..1 across
      p[1] = float(y) / float(h - 1) * 0.25f;   // dark values, where sRGB is steep
      p[2] = float(x * h + y) / float(w * h) * 1.5f - 0.2f;  // includes out-of-range values
      p[3] = 1.0f - float(y) * 0.2f;
    }
  writeImage(file("rgba.png"), im);
  EXPECT_TRUE(temporaries().empty());
  Frame f = readFrame(file("rgba.png"));
  ASSERT_EQ(f.width, w);
  ASSERT_EQ(f.height, h);
  // Colour is premultiplied in the library and straight in the PNG: compared
  // straight (divided by each side's alpha), where the file's code values are.
  for (int y = 0; y < h; ++y)
    for (int x = 0; x < w; ++x) {
      const float a = im.at(x, y)[3], readA = f.pass("color").at(x, y)[3];
      ASSERT_NEAR(readA, a, 0.5f / 255.0f) << x << "," << y;
      for (int c = 0; c < 3; ++c) {
        const float want = srgbEncode(im.at(x, y)[c] / a), got = srgbEncode(f.pass("color").at(x, y)[c] / readA);
        ASSERT_NEAR(got, want, 1.0f / 255.0f + 1e-6f) << x << "," << y << "," << c;
      }
    }
  // The top row is the first one in the file: alpha 1 there, 0.2 at the bottom.
  EXPECT_NEAR(f.pass("color").at(3, 0)[3], 1.0f, 1e-6f);
  EXPECT_NEAR(f.pass("color").at(3, h - 1)[3], 0.2f, 0.5f / 255.0f);
}

// A PNG's alpha is straight: writeImage divides a partial coverage out of the
// premultiplied colour (as Blender writes a transparent film's PNG, so a
// viewer's composite has no dark fringe), and readFrame multiplies it back,
// for its own PNGs and for straight-alpha PNGs written elsewhere.
TEST_F(IoTest, PngAlphaIsStraightInTheFile) {
  Image im(2, 1, 4);
  const float half[4] = {0.25f, 0.1f, 0.0f, 0.5f}, none[4] = {0.3f, 0.0f, 0.0f, 0.0f};
  std::copy(half, half + 4, im.at(0, 0));
  std::copy(none, none + 4, im.at(1, 0));
  writeImage(file("edge.png"), im);
  OIIO::ImageSpec asStored;  // OIIO premultiplies a PNG's colour on read unless told not to
  asStored.attribute("oiio:UnassociatedAlpha", 1);
  auto in = OIIO::ImageInput::open(file("edge.png"), &asStored);
  ASSERT_TRUE(in);
  std::vector<unsigned char> codes(8);
  ASSERT_TRUE(in->read_image(0, 0, 0, 4, OIIO::TypeDesc::UINT8, codes.data()));
  in->close();
  EXPECT_EQ(codes[0], (unsigned char)std::lround(srgbEncode(0.5f) * 255.0f));  // 0.25 / 0.5
  EXPECT_EQ(codes[1], (unsigned char)std::lround(srgbEncode(0.2f) * 255.0f));
  EXPECT_EQ(codes[3], 128);
  EXPECT_EQ(codes[4], (unsigned char)std::lround(srgbEncode(0.3f) * 255.0f));  // coverage 0: as given
  EXPECT_EQ(codes[7], 0);
  Frame f = readFrame(file("edge.png"));
  const float* p = f.pass("color").at(0, 0);
  EXPECT_NEAR(p[0], 0.25f * 128.0f / 255.0f / 0.5f, 0.004f);
  EXPECT_NEAR(p[3], 128.0f / 255.0f, 1e-6f);
  EXPECT_EQ(f.pass("color").at(1, 0)[0], 0.0f);  // premultiplied by coverage 0
}

TEST_F(IoTest, WriteReplacesAnExistingFileWhole) {
  Image a(7, 5, 4, 0.25f), b(3, 2, 4, 0.75f);
  writeImage(file("out.exr"), a);
  writeImage(file("out.exr"), b);
  Frame f = readFrame(file("out.exr"));
  EXPECT_EQ(f.width, 3);
  EXPECT_EQ(f.pass("color").at(2, 1)[0], 0.75f);
  EXPECT_TRUE(temporaries().empty());
}

TEST_F(IoTest, FailedWritesLeaveNoTraceAndTheOldFileIntact) {
  Image im(7, 5, 4, 0.5f);
  // Non-existent folder.
  const std::string missingDir = file("no/such/dir/out.exr");
  expectError([&] { writeImage(missingDir, im); }, CRISP_ERROR_IO, missingDir);

  // The target is a directory: OIIO writes the temporary file, the rename fails.
  fs::create_directory(dir / "adir.exr");
  expectError([&] { writeImage(file("adir.exr"), im); }, CRISP_ERROR_IO, "adir.exr");
  EXPECT_TRUE(fs::is_directory(dir / "adir.exr"));
  EXPECT_TRUE(temporaries().empty());

  // A name near NAME_MAX still writes (the temporary name is shortened).
  const std::string longName = std::string(240, 'n') + ".exr";
  writeImage(file(longName), im);
  EXPECT_EQ(readFrame(file(longName)).pass("color").at(6, 4)[0], 0.5f);
  EXPECT_TRUE(temporaries().empty());

  // A late failure (after the temporary file is complete, before the rename):
  // the old file keeps its bytes and the temporary file is removed.
  for (const char* name : {"late.exr", "late.png"}) {
    Image old(7, 5, 4, 0.125f);
    writeImage(file(name), old);
    const std::vector<char> before = readBytes(file(name));
    std::string seenTemporary;
    setWriteImageFaultForTesting([&](const std::string& tmp) {
      seenTemporary = tmp;
      EXPECT_TRUE(fs::exists(tmp));
      ioError("simulated failure writing '" + std::string(name) + "'");
    });
    expectError([&] { writeImage(file(name), im); }, CRISP_ERROR_IO, name);
    setWriteImageFaultForTesting(nullptr);
    EXPECT_FALSE(seenTemporary.empty());
    EXPECT_FALSE(fs::exists(seenTemporary));
    EXPECT_EQ(readBytes(file(name)), before);
    EXPECT_TRUE(temporaries().empty());
  }

  // Unknown extension and bad views are refused before touching the disk.
  writeBytes(file("keep.tif"), {'x', 'y'});
  expectError([&] { writeImage(file("keep.tif"), im); }, CRISP_ERROR_INVALID_ARGUMENT, "keep.tif");
  EXPECT_EQ(readBytes(file("keep.tif")), std::vector<char>({'x', 'y'}));
  Image ids = Image::uintImage(7, 5);
  expectError([&] { writeImage(file("ids.exr"), ids); }, CRISP_ERROR_INVALID_ARGUMENT, "ids.exr");
  expectError([&] { writeImage(file("empty.exr"), Image()); }, CRISP_ERROR_INVALID_ARGUMENT, "empty.exr");
  EXPECT_FALSE(fs::exists(dir / "ids.exr"));
  EXPECT_TRUE(temporaries().empty());
}

// Ctrl-C (SIGINT) while a file is being written, in a program that asked for it (the crisp
// command): the temporary file is removed, the old file keeps its bytes, and the process still
// ends by the signal.
TEST_F(IoTest, InterruptRemovesTheFileBeingWritten) {
  // A fresh process (not a fork of this one, whose OIIO threads a fork would leave locked): the
  // threadsafe death test runs this test again from the start, and that process's SetUp made a
  // folder named by its own pid. It works in this process's folder instead (the environment is
  // inherited), so that the checks below see what it did.
  // Only this process writes the old file (an EXR holds the second it was written: capDate).
  static const char* const kShared = "CRISP_IO_TEST_INTERRUPT_DIR";
  Image old(7, 5, 4, 0.125f), im(7, 5, 4, 0.5f);
  std::vector<char> before;
  if (const char* parent = std::getenv(kShared)) {
    fs::remove_all(dir);
    dir = parent;
  } else {
    ::setenv(kShared, dir.c_str(), 1);
    writeImage(file("sig.exr"), old);
    before = readBytes(file("sig.exr"));
  }
  // Unset however this test ends, so that a later run in this process (--gtest_repeat) is a parent.
  struct Unset {
    ~Unset() { ::unsetenv(kShared); }
  } unsetAtExit;
  static std::string seen;  // the hook's record, in the dying process's folder
  seen = file("hook_ran");
  GTEST_FLAG_SET(death_test_style, "threadsafe");
  EXPECT_EXIT(
      {
        removeTemporaryFilesOnSignals();
        setWriteImageFaultForTesting([](const std::string& tmp) {
          if (!fs::exists(tmp)) return;
          std::ofstream(seen) << tmp;  // the temporary file is complete, not yet renamed
          ::raise(SIGINT);
        });
        writeImage(file("sig.exr"), im);
        std::exit(0);  // not reached unless the signal went astray
      },
      ::testing::KilledBySignal(SIGINT), "");
  // The interrupted write happened here, its temporary file existed, and is gone; the old file is whole.
  ASSERT_TRUE(fs::exists(file("hook_ran")));
  std::ifstream record(file("hook_ran"));
  const std::string tmp((std::istreambuf_iterator<char>(record)), std::istreambuf_iterator<char>());
  EXPECT_EQ(fs::path(tmp).parent_path(), dir);
  EXPECT_FALSE(fs::exists(tmp)) << tmp;
  EXPECT_EQ(readBytes(file("sig.exr")), before);
  EXPECT_TRUE(temporaries().empty());
}

TEST_F(IoTest, ReadOnlyFolderKeepsTheOldFile) {
  if (::geteuid() == 0) GTEST_SKIP() << "running as root: folder permissions are not enforced";
  Image old(7, 5, 4, 0.125f), im(7, 5, 4, 0.5f);
  writeImage(file("ro.png"), old);
  const std::vector<char> before = readBytes(file("ro.png"));
  fs::permissions(dir, fs::perms::owner_read | fs::perms::owner_exec, fs::perm_options::replace);
  expectError([&] { writeImage(file("ro.png"), im); }, CRISP_ERROR_IO, "ro.png");
  fs::permissions(dir, fs::perms::owner_all, fs::perm_options::add);
  EXPECT_EQ(readBytes(file("ro.png")), before);
  EXPECT_TRUE(temporaries().empty());
}

// ------------------------------------------------------------ bad files ----

TEST_F(IoTest, MissingEmptyAndNonImageFiles) {
  expectError([&] { readFrame(file("missing.exr")); }, CRISP_ERROR_IO, file("missing.exr"));
  writeBytes(file("empty.exr"), {});
  expectError([&] { readFrame(file("empty.exr")); }, CRISP_ERROR_IO, file("empty.exr"));
  const std::string text = "this is not an image\n";
  writeBytes(file("text.exr"), std::vector<char>(text.begin(), text.end()));
  expectError([&] { readFrame(file("text.exr")); }, CRISP_ERROR_IO, file("text.exr"));
  writeBytes(file("text.png"), std::vector<char>(text.begin(), text.end()));
  expectError([&] { readFrame(file("text.png")); }, CRISP_ERROR_IO, file("text.png"));
  expectError([&] { readFrame(dir.string()); }, CRISP_ERROR_IO, dir.string());
}

TEST_F(IoTest, TruncatedExrIsAnIoError) {
  for (const char* compression : {"none", "zip"}) {
    SCOPED_TRACE(compression);
    ExrLayout layout;
    layout.width = 64;
    layout.height = 48;
    layout.attributes = blenderManifest();
    const std::string path = file(std::string("trunc_") + compression + ".exr");
    writeExr(path, blenderChannels("ViewLayer", 64, 48), layout, compression);
    ASSERT_NO_THROW(readFrame(path));
    std::vector<char> bytes = readBytes(path);
    bytes.resize(bytes.size() / 2);
    writeBytes(path, bytes);
    expectError([&] { readFrame(path); }, CRISP_ERROR_IO, path);
    // The header alone, cut inside the line offset table.
    bytes.resize(bytes.size() / 8);
    writeBytes(path, bytes);
    try {
      readFrame(path);
      ADD_FAILURE() << "read a file cut to " << bytes.size() << " bytes";
    } catch (const Exception& e) {
      EXPECT_TRUE(e.code() == CRISP_ERROR_IO || e.code() == CRISP_ERROR_INVALID_DATA) << e.what();
      EXPECT_NE(std::string(e.what()).find(path), std::string::npos) << e.what();
    }
    EXPECT_FALSE(OIIO::has_error());
  }
}

TEST_F(IoTest, ShortUncompressedChunksAreAnIoError) {
  // An uncompressed file cut inside its last chunk, or one whose first chunk says it holds a byte less
  // than its rows: OpenEXR's C++ library took such a tile without an error (and OIIO's reader over
  // its C library read both with zeros): readFrame checks an uncompressed part's chunks first.
  // Scanlines and tiles.
  const int w = 16, h = 300;
  for (const int tile : {0, 48}) {
    SCOPED_TRACE(tile ? "tiled" : "scanlines");
    const std::string whole = blenderExr("short", windowed(w, h, 0, 0, w, h), "none", tile);
    const std::vector<char> bytes = readBytes(whole);
    const std::string cut = file("cut.exr"), lying = file("lying.exr");
    writeBytes(cut, std::vector<char>(bytes.begin(), bytes.end() - 100));
    // The first chunk's size field one less. Its offset is the first entry of the offset table, which
    // follows the header (attributes "name\0type\0" int32 size, value; then a 0 byte); its leader is
    // int32 y, int32 size (scanlines) or int32 tx, ty, lx, ly, size (tiles).
    std::size_t at = 8;
    while (bytes.at(at) != 0) {
      at += std::strlen(bytes.data() + at) + 1;
      at += std::strlen(bytes.data() + at) + 1;
      std::int32_t attributeSize;
      std::memcpy(&attributeSize, bytes.data() + at, 4);
      at += 4 + std::size_t(attributeSize);
    }
    std::uint64_t first;
    std::memcpy(&first, bytes.data() + at + 1, 8);
    std::vector<char> lied = bytes;
    const std::size_t sizeField = std::size_t(first) + (tile ? 16 : 4);
    std::int32_t size;
    std::memcpy(&size, lied.data() + sizeField, 4);
    size -= 1;
    std::memcpy(lied.data() + sizeField, &size, 4);
    writeBytes(lying, lied);
    EXPECT_NO_THROW(readFrame(whole));
    expectError([&] { readFrame(cut); }, CRISP_ERROR_IO, "cut.exr");
    expectError([&] { readFrame(lying); }, CRISP_ERROR_IO, "lying.exr");
  }
}

TEST_F(IoTest, CorruptBytesAreAnError) {
  ExrLayout layout;
  layout.width = 64;
  layout.height = 48;
  const std::string path = file("corrupt.exr");
  writeExr(path, blenderChannels("ViewLayer", 64, 48), layout, "zip");
  const std::vector<char> good = readBytes(path);

  // Compressed pixel data overwritten: decompression fails.
  std::vector<char> bytes = good;
  for (std::size_t i = bytes.size() / 2; i < bytes.size() / 2 + 2000 && i < bytes.size(); ++i) bytes[i] = char(i * 37);
  writeBytes(path, bytes);
  expectError([&] { readFrame(path); }, CRISP_ERROR_IO, path);

  // Magic number destroyed: not recognised as an image at all.
  bytes = good;
  bytes[0] = 'X';
  bytes[1] = 'Y';
  writeBytes(path, bytes);
  expectError([&] { readFrame(path); }, CRISP_ERROR_IO, path);
}

// Finds an EXR box2i attribute ("dataWindow"/"displayWindow") in the header.
std::size_t findBoxAttribute(const std::vector<char>& bytes, const std::string& name) {
  const std::string key = name + std::string(1, '\0') + "box2i" + std::string(1, '\0');
  auto it = std::search(bytes.begin(), bytes.end(), key.begin(), key.end());
  if (it == bytes.end()) return 0;
  return std::size_t(it - bytes.begin()) + key.size() + 4;  // skip the int32 size
}

TEST_F(IoTest, AbsurdAndZeroSizesAreRefused) {
  ExrLayout layout;
  const std::string path = file("size.exr");
  writeExr(path, blenderChannels("ViewLayer", 7, 5), layout);
  const std::vector<char> good = readBytes(path);
  const std::size_t data = findBoxAttribute(good, "dataWindow"), display = findBoxAttribute(good, "displayWindow");
  ASSERT_NE(data, 0u);
  ASSERT_NE(display, 0u);
  auto patch = [&](std::vector<char>& b, std::size_t at, std::int32_t xmax, std::int32_t ymax) {
    std::memcpy(&b[at + 8], &xmax, 4);  // box2i = xmin, ymin, xmax, ymax (little-endian int32)
    std::memcpy(&b[at + 12], &ymax, 4);
  };
  for (auto [xmax, ymax] : {std::pair<std::int32_t, std::int32_t>{999999, 999999}, {2000000000, 4}, {6, -5}}) {
    SCOPED_TRACE(std::to_string(xmax) + "x" + std::to_string(ymax));
    std::vector<char> bytes = good;
    patch(bytes, data, xmax, ymax);
    patch(bytes, display, xmax, ymax);
    writeBytes(path, bytes);
    try {
      readFrame(path);
      ADD_FAILURE() << "accepted a forged size";
    } catch (const Exception& e) {
      EXPECT_TRUE(e.code() == CRISP_ERROR_IO || e.code() == CRISP_ERROR_INVALID_DATA) << e.what();
      EXPECT_NE(std::string(e.what()).find(path), std::string::npos) << e.what();
    }
    EXPECT_FALSE(OIIO::has_error());
  }
  // A small data window in a display window within the per-side limit but over the pixel limit
  // (60000 x 60000 = 3.6e9 > kMaxPixels): the frame would be allocated at the display size.
  std::vector<char> bytes = good;
  patch(bytes, display, 59999, 59999);
  writeBytes(path, bytes);
  try {
    readFrame(path);
    ADD_FAILURE() << "accepted a 60000x60000 display window";
  } catch (const Exception& e) {
    EXPECT_NE(std::string(e.what()).find("display window 60000x60000"), std::string::npos) << e.what();
  }
}

// ---------------------------------------------------------- Cryptomatte ----

TEST(Cryptomatte, MurmurHash3ReferenceVectors) {
  // Published MurmurHash3_x86_32 test vectors (SMHasher verification set).
  EXPECT_EQ(murmurHash3_x86_32("", 0, 0), 0u);
  EXPECT_EQ(murmurHash3_x86_32("", 0, 1), 0x514e28b7u);
  EXPECT_EQ(murmurHash3_x86_32("", 0, 0xffffffffu), 0x81f16f39u);
  EXPECT_EQ(murmurHash3_x86_32("\0\0\0\0", 4, 0), 0x2362f9deu);
  EXPECT_EQ(murmurHash3_x86_32("aaaa", 4, 0x9747b28cu), 0x5a97808au);
  EXPECT_EQ(murmurHash3_x86_32("The quick brown fox jumps over the lazy dog", 43, 0x9747b28cu), 0x2fa826cdu);
}

TEST(Cryptomatte, MatchesARealBlenderManifest) {
  // Blender 3.4.1, default cube: manifest {"Cube":"a8fce865"} under the key
  // "cryptomatte/542cafa/" for the matte "ViewLayer.CryptoObject".
  EXPECT_EQ(hashToHex(cryptomatteHash("Cube")), "a8fce865");
  EXPECT_EQ(cryptomatteKeyPrefix("ViewLayer.CryptoObject"), "cryptomatte/542cafa/");
}

TEST(Cryptomatte, HashIsAlwaysANormalFloat) {
  int tweaked = 0;
  for (int i = 0; i < 20000; ++i) {
    const std::string name = "Object." + std::to_string(i);
    const std::uint32_t raw = murmurHash3_x86_32(name.data(), name.size(), 0);
    const std::uint32_t h = cryptomatteHash(name);
    const std::uint32_t e = (raw >> 23) & 0xffu;
    if (e == 0 || e == 255) {
      ++tweaked;
      EXPECT_EQ(h, raw ^ (1u << 23)) << name;
    } else {
      EXPECT_EQ(h, raw) << name;
    }
    ASSERT_TRUE(std::isnormal(cryptomatteHashToFloat(h))) << name;
  }
  EXPECT_GT(tweaked, 0);  // 2/256 of names need the tweak: the branch is exercised
}

TEST(Cryptomatte, ManifestParser) {
  auto m = parseCryptomatteManifest(
      " { \"Cube\" : \"a8fce865\", \"Say \\\"hi\\\"\\\\\":\"0000000A\",\n\"caf\\u00e9 \\ud83d\\ude00\":\"ffffffff\" } ");
  ASSERT_EQ(m.size(), 3u);
  EXPECT_EQ(m.at("Cube"), 0xa8fce865u);
  EXPECT_EQ(m.at("Say \"hi\"\\"), 0x0000000au);
  EXPECT_EQ(m.at("caf\xc3\xa9 \xf0\x9f\x98\x80"), 0xffffffffu);
  EXPECT_TRUE(parseCryptomatteManifest("{}").empty());
  for (const char* bad : {"", "[]", "{", "{\"a\"}", "{\"a\":1}", "{\"a\":\"xyz\"}", "{\"a\":\"123456789\"}",
                          "{\"a\":\"00000000\",}", "{\"a\":\"00000000\"} x", "{\"\\ud800\":\"00000000\"}",
                          "{\"a\\q\":\"00000000\"}"}) {
    try {
      parseCryptomatteManifest(bad);
      ADD_FAILURE() << "accepted: " << bad;
    } catch (const Exception& e) {
      EXPECT_EQ(e.code(), CRISP_ERROR_INVALID_DATA) << bad;
    }
  }
}
