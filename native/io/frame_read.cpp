// SPDX-License-Identifier: Apache-2.0
// readFrame: Blender multilayer EXRs and plain RGB(A) images through
// OpenImageIO, converted to the convention of core/conventions.h.
//
// Blender 3.4 names multilayer EXR channels "<view layer>.<pass>.<channel>"
// (checked on a real render, see the io report / tests/python/test_blender_exr.py):
//   ViewLayer.Combined.R/G/B/A, ViewLayer.Depth.Z, ViewLayer.Normal.X/Y/Z,
//   ViewLayer.Vector.X/Y/Z/W (Cycles only), ViewLayer.DiffCol.R/G/B,
//   ViewLayer.CryptoObject00.r/g/b/a (lowercase), CryptoObject01.., and the
//   manifest in the header attribute "cryptomatte/<7 hex>/manifest".
// View layer names may contain dots, so names are split from the right.
#include <unistd.h>

#include <algorithm>
#include <cerrno>
#include <cmath>
#include <cstring>
#include <filesystem>
#include <memory>
#include <string>
#include <system_error>
#include <vector>

#include <OpenImageIO/imagebuf.h>
#include <OpenImageIO/imageio.h>

#include "core/color.h"
#include "core/conventions.h"
#include "core/error.h"
#include "io/cryptomatte.h"
#include "io/frame.h"
#include "io/oiio_util.h"

namespace crisp {

namespace {

// Largest frame accepted: 65536 on a side (the C API's limit) and 2^28
// pixels (16K x 16K), so a forged header cannot ask for terabytes.
constexpr long long kMaxDimension = 65536;
constexpr long long kMaxPixels = 1ll << 28;

const char* const kRoleOrder[] = {"color", "depth", "normal", "motion", "id", "albedo"};

struct ChannelName {
  std::string layer;    // "" for "R" or "Depth.Z"
  std::string pass;     // "" for "R"
  std::string channel;  // last component
  int index = 0;        // in the file (OIIO order)
};

ChannelName splitChannelName(const std::string& name, int index) {
  ChannelName c;
  c.index = index;
  std::size_t last = name.rfind('.');
  if (last == std::string::npos) {
    c.channel = name;
    return c;
  }
  c.channel = name.substr(last + 1);
  std::string prefix = name.substr(0, last);
  std::size_t mid = prefix.rfind('.');
  if (mid == std::string::npos) {
    c.pass = prefix;
  } else {
    c.pass = prefix.substr(mid + 1);
    c.layer = prefix.substr(0, mid);
  }
  return c;
}

bool iequals(const std::string& a, const std::string& b) {
  return a.size() == b.size() &&
         std::equal(a.begin(), a.end(), b.begin(), [](char x, char y) { return std::tolower(x) == std::tolower(y); });
}

// How each role is stored: the Blender pass name, the channels it must have and
// those it may have (matched case-insensitively: Cryptomatte uses "r", "g").
struct RoleSpec {
  const char* role;
  const char* blenderPass;
  std::vector<std::string> required;
  std::vector<std::string> optional;
};

const std::vector<RoleSpec>& roleSpecs() {
  static const std::vector<RoleSpec> specs = {
      {"color", "Combined", {"R", "G", "B"}, {"A"}},
      {"depth", "Depth", {"Z"}, {}},
      {"normal", "Normal", {"X", "Y", "Z"}, {}},
      {"motion", "Vector", {"X", "Y", "Z", "W"}, {}},
      {"id", "CryptoObject00", {"r", "g"}, {"b", "a"}},
      {"albedo", "DiffCol", {"R", "G", "B"}, {"A"}},
  };
  return specs;
}

std::string joinChannels(const std::vector<const ChannelName*>& chans) {
  std::string s;
  for (const ChannelName* c : chans) s += (s.empty() ? "" : ",") + c->channel;
  return s;
}

// Finds a channel of `chans` by name; nullptr if absent.
const ChannelName* findChannel(const std::vector<const ChannelName*>& chans, const std::string& name) {
  for (const ChannelName* c : chans)
    if (iequals(c->channel, name)) return c;
  return nullptr;
}

// Checks a pass's channel set against its spec and returns the file indices of
// required + optional channels (-1 where an optional one is absent).
std::vector<int> matchPass(const std::string& path, const std::string& passLabel,
                           const std::vector<const ChannelName*>& chans, const RoleSpec& spec) {
  auto expected = [&]() {
    std::string s;
    for (const auto& r : spec.required) s += (s.empty() ? "" : ",") + r;
    for (const auto& o : spec.optional) s += "[," + o + "]";
    return s;
  };
  std::vector<int> indices;
  for (const auto& r : spec.required) {
    const ChannelName* c = findChannel(chans, r);
    if (!c)
      invalidData("pass '" + passLabel + "' in '" + path + "' has " + std::to_string(chans.size()) + " channel(s) (" +
                  joinChannels(chans) + "); expected " + expected());
    indices.push_back(c->index);
  }
  for (const auto& o : spec.optional) {
    const ChannelName* c = findChannel(chans, o);
    indices.push_back(c ? c->index : -1);
  }
  for (const ChannelName* c : chans) {
    bool known = std::any_of(indices.begin(), indices.end(), [&](int i) { return i == c->index; });
    if (!known)
      invalidData("pass '" + passLabel + "' in '" + path + "' has " + std::to_string(chans.size()) + " channels (" +
                  joinChannels(chans) + "); expected " + expected());
  }
  return indices;
}

// Reads channels [chBegin, chEnd) of the data window as float, or throws
// CRISP_ERROR_IO (truncated or corrupt file) naming the file and the pass.
std::vector<float> readChannelRange(OIIO::ImageInput& in, const std::string& path, const std::string& passLabel,
                                    int chBegin, int chEnd) {
  const OIIO::ImageSpec& spec = in.spec();
  const std::size_t n = std::size_t(spec.width) * std::size_t(spec.height) * std::size_t(chEnd - chBegin);
  std::vector<float> buffer(n);
  if (!in.read_image(0, 0, chBegin, chEnd, OIIO::TypeFloat, buffer.data()))
    ioError("cannot read pass '" + passLabel + "' of '" + path + "' (truncated or corrupt file?): " +
            oiioErrors(&in));
  return buffer;
}

// The geometry of a read: the frame is the display window; the file's pixels
// cover the data window, possibly offset, smaller or larger.
struct Windows {
  int width = 0, height = 0;         // display window size = frame size
  int dataWidth = 0, dataHeight = 0;
  long long offsetX = 0, offsetY = 0;  // data window origin relative to the display window
};

// Converts one pass into an Image of the frame's size. `convert(src, dst)`
// gets the pass's file channels in `indices` order (relative to the read
// range); pixels outside the data window get `outside`.
template <class Convert>
Image convertPass(OIIO::ImageInput& in, const std::string& path, const std::string& passLabel,
                  const std::vector<int>& indices, const Windows& win, Image out, Convert convert) {
  int chBegin = 1 << 30, chEnd = -1;
  for (int i : indices)
    if (i >= 0) chBegin = std::min(chBegin, i), chEnd = std::max(chEnd, i + 1);
  const std::vector<float> buffer = readChannelRange(in, path, passLabel, chBegin, chEnd);
  const int runChannels = chEnd - chBegin;
  std::vector<int> rel;
  for (int i : indices) rel.push_back(i >= 0 ? i - chBegin : -1);
  float src[4] = {0.0f, 0.0f, 0.0f, 1.0f};
  for (int y = 0; y < win.height; ++y) {
    const long long dy = y - win.offsetY;
    if (dy < 0 || dy >= win.dataHeight) continue;
    for (int x = 0; x < win.width; ++x) {
      const long long dx = x - win.offsetX;
      if (dx < 0 || dx >= win.dataWidth) continue;
      const float* p = buffer.data() + (std::size_t(dy) * std::size_t(win.dataWidth) + std::size_t(dx)) * std::size_t(runChannels);
      for (std::size_t k = 0; k < rel.size() && k < 4; ++k) src[k] = rel[k] >= 0 ? p[rel[k]] : 1.0f;
      convert(src, out, x, y);
    }
  }
  return out;
}

bool isIntegerFormat(const OIIO::TypeDesc& t) { return !t.is_floating_point(); }

// Integer files (PNG, JPEG, 8/16-bit TIFF) hold display-encoded sRGB unless
// they say they are linear.
bool needsSrgbDecode(const OIIO::ImageSpec& spec) {
  if (!isIntegerFormat(spec.format)) return false;
  std::string cs = spec.get_string_attribute("oiio:ColorSpace");
  return !(iequals(cs, "linear") || iequals(cs, "scene_linear") || iequals(cs, "lin_srgb"));
}

std::string chooseLayer(const std::string& path, const std::vector<ChannelName>& names, const std::string& wanted) {
  std::vector<std::string> layers, withCombined;
  for (const auto& c : names) {
    if (!c.layer.empty() && std::find(layers.begin(), layers.end(), c.layer) == layers.end()) layers.push_back(c.layer);
    if (c.pass == "Combined" && std::find(withCombined.begin(), withCombined.end(), c.layer) == withCombined.end())
      withCombined.push_back(c.layer);
  }
  if (!wanted.empty()) {
    if (std::find(layers.begin(), layers.end(), wanted) != layers.end()) return wanted;
    std::string list;
    for (const auto& l : layers) list += (list.empty() ? "" : ", ") + l;
    invalidData("view layer '" + wanted + "' not found in '" + path + "' (layers: " + (list.empty() ? "none" : list) + ")");
  }
  // EXR stores channels sorted by name, so Blender's layer order is lost: prefer
  // Blender's default layer names, else the first layer (by name) with Combined.
  for (const char* preferred : {"ViewLayer", "View Layer", "RenderLayer"})
    if (std::find(withCombined.begin(), withCombined.end(), preferred) != withCombined.end()) return preferred;
  if (!withCombined.empty()) return withCombined.front();
  return std::string();  // plain image (or no colour at all: reported by the caller)
}

// The Cryptomatte manifest of `layer`'s object matte: located by the key
// derived from the matte name, or by scanning the "cryptomatte/*/name" entries.
std::string findManifest(const OIIO::ImageSpec& spec, const std::string& layer) {
  const std::string matteName = layer.empty() ? "CryptoObject" : layer + ".CryptoObject";
  const std::string prefix = cryptomatteKeyPrefix(matteName);
  if (const OIIO::ParamValue* p = spec.find_attribute(prefix + "manifest", OIIO::TypeString)) return p->get_string();
  for (const OIIO::ParamValue& p : spec.extra_attribs) {
    const std::string name = p.name().string();
    if (name.rfind("cryptomatte/", 0) == 0 && name.size() > 5 && name.compare(name.size() - 5, 5, "/name") == 0 &&
        p.type() == OIIO::TypeString && p.get_string() == matteName) {
      const std::string key = name.substr(0, name.size() - 4) + "manifest";
      if (const OIIO::ParamValue* m = spec.find_attribute(key, OIIO::TypeString)) return m->get_string();
    }
  }
  return std::string();
}

// What every read needs of a file: a flat 2D image of a size it can hold.
// `what` names the file in the messages ("'a.exr'", "mask 'm.exr'").
void checkFlatImage(const OIIO::ImageSpec& spec, const std::string& what) {
  if (spec.deep) invalidData(what + " is a deep image; only flat images are supported");
  if (spec.depth != 1 || spec.full_depth > 1) invalidData(what + " is a volume image; only 2D images are supported");
  if (spec.width <= 0 || spec.height <= 0 || spec.nchannels <= 0)
    invalidData(what + " has an empty image (" + std::to_string(spec.width) + "x" + std::to_string(spec.height) +
                ", " + std::to_string(spec.nchannels) + " channels)");
  const long long fullW = spec.full_width > 0 ? spec.full_width : spec.width;
  const long long fullH = spec.full_height > 0 ? spec.full_height : spec.height;
  for (long long d : {(long long)spec.width, (long long)spec.height, fullW, fullH})
    if (d > kMaxDimension || (long long)spec.width * spec.height > kMaxPixels || fullW * fullH > kMaxPixels)
      invalidData(what + " has an unsupported size: data window " + std::to_string(spec.width) + "x" +
                  std::to_string(spec.height) + ", display window " + std::to_string(fullW) + "x" +
                  std::to_string(fullH) + " (at most " + std::to_string(kMaxDimension) + " per side and " +
                  std::to_string(kMaxPixels) + " pixels)");
}

}  // namespace

const Image& Frame::pass(const std::string& role) const {
  auto it = passes.find(role);
  if (it == passes.end() && unusable.count(role)) invalidData(unusable.at(role));
  if (it == passes.end())
    invalidData("'" + path + "' has no " + role + " pass (passes found: " + (passes.empty() ? "none" : passList()) + ")");
  return it->second;
}

std::string Frame::passList() const {
  std::string s;
  for (const char* role : kRoleOrder)
    if (passes.count(role)) s += (s.empty() ? "" : ",") + std::string(role);
  for (const auto& kv : passes)  // roles outside the fixed order, if any
    if (std::find_if(std::begin(kRoleOrder), std::end(kRoleOrder), [&](const char* r) { return kv.first == r; }) ==
        std::end(kRoleOrder))
      s += (s.empty() ? "" : ",") + kv.first;
  return s;
}

Frame readFrame(const std::string& path) { return readFrame(path, std::string()); }

void checkReadable(const std::string& path) {
  std::error_code ec;
  const auto status = std::filesystem::status(path, ec);
  if (!std::filesystem::exists(status)) ioError("cannot read '" + path + "': no such file");
  if (std::filesystem::is_directory(status)) ioError("cannot read '" + path + "': it is a directory");
  if (std::filesystem::is_regular_file(status) && std::filesystem::file_size(path, ec) == 0 && !ec)
    ioError("cannot read '" + path + "': the file is empty");
  if (::access(path.c_str(), R_OK) != 0) ioError("cannot read '" + path + "': " + std::strerror(errno));
}

Frame readFrame(const std::string& path, const std::string& viewLayer) {
  OiioErrorDrain drain;  // whatever happens, leave no message in OIIO's global queue
  checkReadable(path);

  std::unique_ptr<OIIO::ImageInput> in;
  try {
    // Colour is read as stored, and premultiplied below where the file says
    // its alpha is unassociated (PNG), as writeImage divides it out.
    OIIO::ImageSpec config;
    config.attribute("oiio:UnassociatedAlpha", 1);
    in = OIIO::ImageInput::open(path, &config);
  } catch (const std::exception& e) {  // OIIO plugins should not throw; be safe anyway
    ioError("cannot read '" + path + "': " + e.what());
  }
  if (!in) ioError("cannot read '" + path + "' as an image: " + oiioErrors(nullptr));

  const OIIO::ImageSpec spec = in->spec();
  checkFlatImage(spec, "'" + path + "'");
  const long long fullW = spec.full_width > 0 ? spec.full_width : spec.width;
  const long long fullH = spec.full_height > 0 ? spec.full_height : spec.height;

  Windows win;
  win.width = int(fullW);
  win.height = int(fullH);
  win.dataWidth = spec.width;
  win.dataHeight = spec.height;
  win.offsetX = (long long)spec.x - (spec.full_width > 0 ? spec.full_x : spec.x);
  win.offsetY = (long long)spec.y - (spec.full_height > 0 ? spec.full_y : spec.y);

  Frame frame;
  frame.path = path;
  frame.width = win.width;
  frame.height = win.height;
  frame.windows.displayX = spec.full_width > 0 ? spec.full_x : spec.x;
  frame.windows.displayY = spec.full_height > 0 ? spec.full_y : spec.y;
  frame.windows.dataX = spec.x;
  frame.windows.dataY = spec.y;
  frame.windows.dataWidth = spec.width;
  frame.windows.dataHeight = spec.height;
  // A multi-part EXR: only the first part is read (pixels are read from subimage 0 below); the
  // others are named, so that passes they hold are not lost without a word.
  {
    std::vector<std::string> parts;
    for (int s = 1; in->seek_subimage(s, 0); ++s) {
      std::string list;
      for (const std::string& n : in->spec().channelnames) list += (list.empty() ? "" : ", ") + n;
      parts.push_back(list);
    }
    for (std::size_t k = 0; k < parts.size(); ++k)
      frame.partsNotRead.push_back("part " + std::to_string(k + 2) + " of " + std::to_string(parts.size() + 1) +
                                   " (channels: " + parts[k] + ")");
    if (!parts.empty() && !in->seek_subimage(0, 0))
      ioError("cannot read '" + path + "' (truncated or corrupt file?): " + oiioErrors(in.get()));
  }

  std::vector<ChannelName> names;
  for (int i = 0; i < spec.nchannels; ++i) {
    const std::string n = i < int(spec.channelnames.size()) ? spec.channelnames[size_t(i)] : std::string();
    frame.channelNames.push_back(n);
    names.push_back(splitChannelName(n, i));
  }

  const std::string layer = chooseLayer(path, names, viewLayer);
  const bool hasCombined =
      std::any_of(names.begin(), names.end(), [&](const ChannelName& c) { return c.layer == layer && c.pass == "Combined"; });

  auto channelsOf = [&](const std::string& passName) {
    std::vector<const ChannelName*> out;
    for (const auto& c : names)
      if (c.layer == layer && c.pass == passName) out.push_back(&c);
    return out;
  };
  auto label = [&](const std::string& passName) { return layer.empty() ? passName : layer + "." + passName; };

  // ---- colour ----
  const bool decode = needsSrgbDecode(spec);
  // The filters take colour premultiplied by alpha, as Blender's EXRs hold it.
  const bool straightAlpha = spec.get_int_attribute("oiio:UnassociatedAlpha", 0) != 0;
  auto colorConvert = [decode, straightAlpha, &frame](const float* s, Image& im, int x, int y) {
    float* d = im.at(x, y);
    for (int k = 0; k < 4; ++k) {
      frame.nonFiniteColour += !std::isfinite(s[k]);
      frame.clampedColour += std::isfinite(s[k]) && std::fabs(s[k]) > kMaxColor;
    }
    d[3] = sanitizeColor(s[3]);
    const float coverage = straightAlpha ? std::clamp(d[3], 0.0f, 1.0f) : 1.0f;
    for (int k = 0; k < 3; ++k) d[k] = sanitizeColor(decode ? srgbDecode(s[k]) : s[k]) * coverage;
  };
  if (hasCombined) {
    const RoleSpec& rs = roleSpecs()[0];
    std::vector<int> idx = matchPass(path, label("Combined"), channelsOf("Combined"), rs);
    frame.passes["color"] = convertPass(*in, path, label("Combined"), idx, win, Image(win.width, win.height, 4, 0.0f),
                                        colorConvert);
  } else {
    // A plain image: R,G,B[,A] or grey Y[,A] without a layer or pass prefix.
    std::vector<const ChannelName*> plain = channelsOf("");
    const ChannelName* r = findChannel(plain, "R");
    const ChannelName* g = findChannel(plain, "G");
    const ChannelName* b = findChannel(plain, "B");
    const ChannelName* a = findChannel(plain, "A");
    const ChannelName* grey = findChannel(plain, "Y");
    std::vector<int> idx;
    if (r && g && b) {
      idx = {r->index, g->index, b->index, a ? a->index : -1};
    } else if (grey && !r && !g && !b) {
      idx = {grey->index, grey->index, grey->index, a ? a->index : -1};
    } else {
      std::string list;
      for (const auto& n : frame.channelNames) list += (list.empty() ? "" : ", ") + n;
      invalidData("no colour in '" + path + "': expected a Combined pass or R,G,B channels (channels: " + list + ")" +
                  (frame.partsNotRead.empty() ? std::string()
                                              : "; it is a multi-part EXR, and only its first part is read"));
    }
    frame.passes["color"] = convertPass(*in, path, "color", idx, win, Image(win.width, win.height, 4, 0.0f), colorConvert);
    // Blender's single-layer EXR can carry a top-level "Z" depth channel.
    if (const ChannelName* z = findChannel(plain, "Z"))
      frame.passes["depth"] = convertPass(*in, path, "Z", {z->index}, win, Image(win.width, win.height, 1, kBackgroundDepth),
                                          [](const float* s, Image& im, int x, int y) { *im.at(x, y) = s[0]; });
  }

  if (hasCombined) {
    const auto& specs = roleSpecs();
    for (std::size_t r = 1; r < specs.size(); ++r) {
      const RoleSpec& rs = specs[r];
      std::vector<const ChannelName*> chans = channelsOf(rs.blenderPass);
      if (chans.empty()) continue;
      const std::string passLabel = label(rs.blenderPass);
      std::vector<int> idx = matchPass(path, passLabel, chans, rs);
      const std::string role = rs.role;
      if (role == "depth") {
        // Kept as stored: Blender 3.x's half-float background (65504) already
        // reads as background through isBackgroundDepth.
        frame.passes[role] = convertPass(*in, path, passLabel, idx, win, Image(win.width, win.height, 1, kBackgroundDepth),
                                         [](const float* s, Image& im, int x, int y) { *im.at(x, y) = s[0]; });
      } else if (role == "normal") {
        frame.passes[role] = convertPass(*in, path, passLabel, idx, win, Image(win.width, win.height, 3, 0.0f),
                                         [](const float* s, Image& im, int x, int y) {
                                           float* d = im.at(x, y);
                                           for (int k = 0; k < 3; ++k) d[k] = sanitizeColor(s[k]);
                                         });
      } else if (role == "motion") {
        // Blender's Vector pass is y up; the convention is y down (rows).
        frame.passes[role] = convertPass(*in, path, passLabel, idx, win, Image(win.width, win.height, 4, 0.0f),
                                         [](const float* s, Image& im, int x, int y) {
                                           float* d = im.at(x, y);
                                           d[0] = sanitizeColor(s[0]);
                                           d[1] = sanitizeColor(-s[1]);
                                           d[2] = sanitizeColor(s[2]);
                                           d[3] = sanitizeColor(-s[3]);
                                         });
      } else if (role == "id") {
        // The hash bits must survive: a half-float channel cannot hold them.
        // Only a method that reads IDs fails on it (Frame::unusable).
        if (spec.channelformat(idx[0]).basetype != OIIO::TypeDesc::FLOAT) {
          frame.unusable[role] = "pass '" + passLabel + "' in '" + path + "' is stored as " +
                                 std::string(spec.channelformat(idx[0]).c_str()) +
                                 ", not 32-bit float: object IDs would be lost";
          continue;
        }
        frame.passes[role] = convertPass(*in, path, passLabel, idx, win, Image::uintImage(win.width, win.height),
                                         [](const float* s, Image& im, int x, int y) {
                                           std::uint32_t bits;
                                           std::memcpy(&bits, &s[0], 4);
                                           im.setUint(x, y, s[1] > 0.0f ? bits : 0u);  // no coverage: background
                                         });
      } else if (role == "albedo") {
        frame.passes[role] = convertPass(*in, path, passLabel, idx, win, Image(win.width, win.height, 3, 0.0f),
                                         [](const float* s, Image& im, int x, int y) {
                                           float* d = im.at(x, y);
                                           for (int k = 0; k < 3; ++k) d[k] = sanitizeColor(s[k]);
                                         });
      }
    }
    const std::string manifest = findManifest(spec, layer);
    if (!manifest.empty()) {
      try {
        frame.objectIds = parseCryptomatteManifest(manifest);
      } catch (const Exception& e) {
        invalidData("'" + path + "': " + e.what());
      }
    }
  }

  in->close();
  return frame;
}

Image readMask(const std::string& path) {
  OiioErrorDrain drain;
  checkReadable(path);
  OIIO::ImageBuf buf(path);
  if (!buf.init_spec(path, 0, 0)) ioError("cannot read '" + path + "' as an image: " + buf.geterror());
  const OIIO::ImageSpec& spec = buf.spec();
  if (spec.nchannels != 1) {
    const Frame frame = readFrame(path);
    const Image& c = frame.pass("color");
    Image mask(c.width, c.height, 1);
    for (int y = 0; y < c.height; ++y)
      for (int x = 0; x < c.width; ++x) *mask.at(x, y) = c.at(x, y)[0];
    return mask;
  }
  checkFlatImage(spec, "mask '" + path + "'");
  const OIIO::ROI full = buf.roi_full();
  Image mask(full.width(), full.height(), 1);
  if (!buf.get_pixels(full, OIIO::TypeDesc::FLOAT, mask.data.data()))
    ioError("cannot read '" + path + "' (truncated or corrupt file?): " + buf.geterror());
  return mask;
}

}  // namespace crisp
