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
//
// A multi-part EXR (Nuke and other compositors write passes as parts) is read
// as one set of channels: a pass is found in whichever part holds it, by the
// same names. A part's name can carry the layer and pass its channels leave
// out (part "ViewLayer.Depth", channel "Z"); see matchName.
#include <unistd.h>

#include <algorithm>
#include <cerrno>
#include <cmath>
#include <cstring>
#include <filesystem>
#include <functional>
#include <future>
#include <map>
#include <memory>
#include <string>
#include <system_error>
#include <vector>

#include <OpenImageIO/imagebuf.h>
#include <OpenImageIO/imageio.h>
#include <OpenImageIO/thread.h>
#include <OpenEXR/openexr.h>

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
  int index = 0;        // in its part (OIIO order)
  int part = 0;         // the part (OIIO subimage) holding it
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
// `where` names the file (and the part of a multi-part one) in the messages.
std::vector<int> matchPass(const std::string& where, const std::string& passLabel,
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
      invalidData("pass '" + passLabel + "' in " + where + " has " + std::to_string(chans.size()) + " channel(s) (" +
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
      invalidData("pass '" + passLabel + "' in " + where + " has " + std::to_string(chans.size()) + " channels (" +
                  joinChannels(chans) + "); expected " + expected());
  }
  return indices;
}

// The geometry of a read: the frame is the display window; a part's pixels
// cover its data window, possibly offset, smaller or larger.
struct Windows {
  int part = 0;                      // the part (OIIO subimage) read
  int width = 0, height = 0;         // display window size = frame size
  int dataWidth = 0, dataHeight = 0;
  long long offsetX = 0, offsetY = 0;  // data window origin relative to the display window
};

// One pass to read: its channels in a part, and how a pixel of them becomes a pixel of its image.
struct PassRead {
  std::string role;
  std::string label;         // as messages name it: "ViewLayer.Depth"
  Windows win;
  std::vector<int> indices;  // its channels in the part, required then optional (-1: absent)
  Image image;               // the frame's size, holding the value for outside the data window
  // Converts rows [y0, y1) of the part's data window, `rows` holding them as float with `channels`
  // channels per pixel, the first being the part's channel `chBegin`.
  std::function<void(PassRead&, const float* rows, int y0, int y1, int chBegin, int channels)> convertRows;
};

// A PassRead whose `convert(src, image, x, y)` gets the pass's channels in `indices` order (1 for an
// absent optional one) and writes pixel (x, y) of the image.
template <class Convert>
PassRead passRead(const std::string& role, const std::string& label, std::vector<int> indices, const Windows& win,
                  Image image, Convert convert) {
  PassRead read{role, label, win, std::move(indices), std::move(image), {}};
  read.convertRows = [convert](PassRead& p, const float* rows, int y0, int y1, int chBegin, int channels) mutable {
    const Windows& w = p.win;
    const std::size_t n = std::min<std::size_t>(p.indices.size(), 4);
    int rel[4] = {-1, -1, -1, -1};
    for (std::size_t k = 0; k < n; ++k) rel[k] = p.indices[k] >= 0 ? p.indices[k] - chBegin : -1;
    // The frame's columns the data window covers.
    const long long x0 = std::max(0ll, w.offsetX), x1 = std::min<long long>(w.width, w.offsetX + w.dataWidth);
    float src[4] = {0.0f, 0.0f, 0.0f, 1.0f};
    for (int dy = y0; dy < y1; ++dy) {
      const long long y = dy + w.offsetY;
      if (y < 0 || y >= w.height) continue;
      const float* row = rows + std::size_t(dy - y0) * std::size_t(w.dataWidth) * std::size_t(channels);
      for (long long x = x0; x < x1; ++x) {
        const float* s = row + std::size_t(x - w.offsetX) * std::size_t(channels);
        for (std::size_t k = 0; k < n; ++k) src[k] = rel[k] >= 0 ? s[rel[k]] : 1.0f;
        convert(src, p.image, int(x), int(y));
      }
    }
  };
  return read;
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
  // Blender's default layer names, else the first layer (by name) with Combined
  // other than "Composite", the compositor's result that Blender writes beside
  // the view layers (a view layer "Main" sorts after it); Composite alone, where
  // it is the only one.
  for (const char* preferred : {"ViewLayer", "View Layer", "RenderLayer"})
    if (std::find(withCombined.begin(), withCombined.end(), preferred) != withCombined.end()) return preferred;
  for (const std::string& l : withCombined)
    if (l != "Composite") return l;
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

// A display window (x, y, width, height); the data window where the file gives none.
struct DisplayWindow {
  long long x = 0, y = 0, width = 0, height = 0;
  bool operator!=(const DisplayWindow& o) const { return x != o.x || y != o.y || width != o.width || height != o.height; }
  std::string text() const {
    return std::to_string(width) + "x" + std::to_string(height) + " at (" + std::to_string(x) + "," +
           std::to_string(y) + ")";
  }
};

DisplayWindow displayWindow(const OIIO::ImageSpec& spec) {
  DisplayWindow d;
  d.x = spec.full_width > 0 ? spec.full_x : spec.x;
  d.y = spec.full_height > 0 ? spec.full_y : spec.y;
  d.width = spec.full_width > 0 ? spec.full_width : spec.width;
  d.height = spec.full_height > 0 ? spec.full_height : spec.height;
  return d;
}

// What every read needs of a file: a flat 2D image of a size it can hold.
// `what` names the file in the messages ("'a.exr'", "mask 'm.exr'").
void checkFlatImage(const OIIO::ImageSpec& spec, const std::string& what) {
  if (spec.deep) invalidData(what + " is a deep image; only flat images are supported");
  if (spec.depth != 1 || spec.full_depth > 1) invalidData(what + " is a volume image; only 2D images are supported");
  if (spec.width <= 0 || spec.height <= 0 || spec.nchannels <= 0)
    invalidData(what + " has an empty image (" + std::to_string(spec.width) + "x" + std::to_string(spec.height) +
                ", " + std::to_string(spec.nchannels) + " channels)");
  const DisplayWindow display = displayWindow(spec);
  const long long fullW = display.width, fullH = display.height;
  for (long long d : {(long long)spec.width, (long long)spec.height, fullW, fullH})
    if (d > kMaxDimension || (long long)spec.width * spec.height > kMaxPixels || fullW * fullH > kMaxPixels)
      invalidData(what + " has an unsupported size: data window " + std::to_string(spec.width) + "x" +
                  std::to_string(spec.height) + ", display window " + std::to_string(fullW) + "x" +
                  std::to_string(fullH) + " (at most " + std::to_string(kMaxDimension) + " per side and " +
                  std::to_string(kMaxPixels) + " pixels)");
}

bool isBlenderPass(const std::string& pass) {
  const auto& specs = roleSpecs();
  return std::any_of(specs.begin(), specs.end(), [&](const RoleSpec& r) { return pass == r.blenderPass; });
}

// The name a channel of a multi-part file is matched by. OpenEXR 2's parts
// have names, and some writers let a part's name carry the layer and pass its
// channels leave out (part "ViewLayer.Depth", channel "Z"): a channel without
// a layer of its own whose part name and name together name a pass read here
// is read as "<part name>.<channel>". Any other keeps its own name, so a part
// "rgba" holding R,G,B,A is plain colour, and "ViewLayer.Depth.Z" is the same
// in any part.
std::string matchName(const std::string& stored, const std::string& partName) {
  if (partName.empty() || stored.rfind(partName + ".", 0) == 0 || !splitChannelName(stored, 0).layer.empty())
    return stored;
  const std::string qualified = partName + "." + stored;
  return isBlenderPass(splitChannelName(qualified, 0).pass) ? qualified : stored;
}

// A part of the file (an OIIO subimage; a single-part file has one).
struct Part {
  OIIO::ImageSpec spec;
  std::string name;   // an EXR part's name ("oiio:subimagename"), "" if none
  bool read = false;  // a pass is read from it
};

std::string partLabel(const std::vector<Part>& parts, int p) {
  const Part& part = parts[std::size_t(p)];
  return "part " + std::to_string(p + 1) + " of " + std::to_string(parts.size()) +
         (part.name.empty() ? std::string() : " ('" + part.name + "')");
}

// Rows of a part read at once: 256, a multiple of every OpenEXR chunk's height (1 to 256 lines), so no
// chunk is decoded twice; fewer for a very wide part, so that a strip stays near 64 MB; a multiple of
// a tiled part's tile height.
int stripRows(const OIIO::ImageSpec& spec, int channels) {
  const long long rowFloats = std::max(1ll, (long long)spec.width * channels);
  long long rows = std::clamp((16ll << 20) / rowFloats, 16ll, 256ll);
  if (spec.tile_height > 0) rows = std::max(1ll, rows / spec.tile_height) * spec.tile_height;
  return int(std::min<long long>(rows, spec.height));
}

// Reads the passes: each part once, in strips of rows holding every channel its passes read, so a
// file is decoded once however many passes come from it (a read per pass decoded the whole file
// each time). Throws CRISP_ERROR_IO (truncated or corrupt file) naming the file, the part, the
// passes and the rows.
void readPasses(OIIO::ImageInput& in, const std::string& path, const std::vector<Part>& parts,
                std::vector<PassRead>& reads) {
  std::vector<int> partsRead;
  for (const PassRead& r : reads)
    if (std::find(partsRead.begin(), partsRead.end(), r.win.part) == partsRead.end()) partsRead.push_back(r.win.part);
  for (int part : partsRead) {
    std::vector<PassRead*> mine;
    int chBegin = 1 << 30, chEnd = -1;
    std::string labels;
    for (PassRead& r : reads) {
      if (r.win.part != part) continue;
      mine.push_back(&r);
      labels += (labels.empty() ? "'" : ", '") + r.label + "'";
      for (int i : r.indices)
        if (i >= 0) chBegin = std::min(chBegin, i), chEnd = std::max(chEnd, i + 1);
    }
    const OIIO::ImageSpec& spec = parts[std::size_t(part)].spec;
    const int channels = chEnd - chBegin;
    const int rows = stripRows(spec, channels);
    // Two strips: one is read (decoded on OpenEXR's threads) while the one before is converted on a
    // thread of OIIO's pool, so that the two overlap. Conversions run one at a time, in order;
    // whatever is thrown, the one under way ends before its strip is freed.
    std::vector<float> strips[2];
    for (std::vector<float>& strip : strips)
      strip.resize(std::size_t(rows) * std::size_t(spec.width) * std::size_t(channels));
    std::future<void> converting;
    struct Finish {
      std::future<void>& converting;
      ~Finish() {
        if (converting.valid()) converting.wait();
      }
    } finish{converting};
    for (int y0 = 0, k = 0; y0 < spec.height; y0 += rows, ++k) {
      const int y1 = std::min(spec.height, y0 + rows);
      std::vector<float>& strip = strips[k & 1];
      const bool read = spec.tile_width > 0
                            ? in.read_tiles(part, 0, spec.x, spec.x + spec.width, spec.y + y0, spec.y + y1, spec.z,
                                            spec.z + 1, chBegin, chEnd, OIIO::TypeFloat, strip.data())
                            : in.read_scanlines(part, 0, spec.y + y0, spec.y + y1, spec.z, chBegin, chEnd,
                                                OIIO::TypeFloat, strip.data());
      if (!read)
        ioError("cannot read " + std::string(mine.size() > 1 ? "passes " : "pass ") + labels + " of '" + path + "'" +
                (parts.size() > 1 ? " (" + partLabel(parts, part) + ")" : std::string()) + ", rows " +
                std::to_string(spec.y + y0) + "-" + std::to_string(spec.y + y1 - 1) +
                " (truncated or corrupt file?): " + oiioErrors(&in));
      if (converting.valid()) converting.get();
      converting = OIIO::default_thread_pool()->push([&mine, &strip, y0, y1, chBegin, channels](int) {
        for (PassRead* r : mine) r->convertRows(*r, strip.data(), y0, y1, chBegin, channels);
      });
    }
    converting.get();
  }
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
  // Opening a FIFO waits for a writer (for ever); a device or socket holds no image file either.
  if (!std::filesystem::is_regular_file(status)) {
    const char* kind = std::filesystem::is_fifo(status)             ? "a named pipe (FIFO)"
                       : std::filesystem::is_socket(status)         ? "a socket"
                       : std::filesystem::is_character_file(status) ? "a character device"
                       : std::filesystem::is_block_file(status)     ? "a block device"
                                                                    : "a special file";
    ioError("cannot read '" + path + "': it is " + std::string(kind) + ", not a regular file");
  }
  if (std::filesystem::file_size(path, ec) == 0 && !ec)
    ioError("cannot read '" + path + "': the file is empty");
  if (::access(path.c_str(), R_OK) != 0) ioError("cannot read '" + path + "': " + std::strerror(errno));
}

namespace {

// A file opened by OpenEXR's C library, closed when it goes. Its errors are not printed: the callers
// say what is wrong, naming the file.
struct ExrCoreFile {
  exr_context_t exr = nullptr;
  bool open(const std::string& path) {
    exr_context_initializer_t init = EXR_DEFAULT_CONTEXT_INITIALIZER;
    init.error_handler_fn = [](exr_const_context_t, exr_result_t, const char*) {};
    init.flags = EXR_CONTEXT_FLAG_SILENT_HEADER_PARSE;
    return exr_start_read(&exr, path.c_str(), &init) == EXR_ERR_SUCCESS;
  }
  ~ExrCoreFile() {
    if (exr) exr_finish(&exr);
  }
};

// OpenEXR's C++ library, which OIIO reads EXRs through, took an uncompressed tile whose size field
// was too small without an error, and OIIO's reader over its C library (not used here) read a file cut
// short inside an uncompressed chunk with zeros (both found by an independent review). So before an
// uncompressed part is read, each chunk of it (of its full-resolution level, the one read) is checked
// through OpenEXR's C library: the size it stores must be its lines' size, and it must end within the
// file. About 1 ms for a 1920x1080 frame's 1080 chunks.
void checkUncompressedChunks(const std::string& path, const std::vector<Part>& parts) {
  std::vector<int> uncompressed;
  for (std::size_t p = 0; p < parts.size(); ++p)
    if (parts[p].read && parts[p].spec.get_string_attribute("compression", "none") == "none") uncompressed.push_back(int(p));
  if (uncompressed.empty()) return;
  ExrCoreFile context;
  std::error_code ec;
  const std::uint64_t fileSize = std::filesystem::file_size(path, ec);
  if (ec || !context.open(path))
    ioError("cannot read '" + path + "': its header could not be read again to check its chunks");
  for (int p : uncompressed) {
    auto check = [&](exr_result_t result, const exr_chunk_info_t& chunk, const std::string& which) {
      if (result == EXR_ERR_SUCCESS && chunk.packed_size == chunk.unpacked_size &&
          chunk.data_offset <= fileSize && chunk.packed_size <= fileSize - chunk.data_offset)
        return;
      ioError("cannot read '" + path + "'" + (parts.size() > 1 ? " (" + partLabel(parts, p) + ")" : std::string()) +
              ": its uncompressed " + which + " is truncated or corrupt" +
              (result == EXR_ERR_SUCCESS ? " (" + std::to_string(chunk.packed_size) + " bytes stored at byte " +
                                                std::to_string(chunk.data_offset) + " of " + std::to_string(fileSize) +
                                                ", " + std::to_string(chunk.unpacked_size) + " expected)"
                                         : " (" + std::string(exr_get_error_code_as_string(result)) + ")"));
    };
    exr_attr_box2i_t dw;
    exr_chunk_info_t chunk{};
    if (exr_get_data_window(context.exr, p, &dw) != EXR_ERR_SUCCESS) check(EXR_ERR_INVALID_ATTR, chunk, "data window");
    std::int32_t tileWidth = 0, tileHeight = 0;
    if (exr_get_tile_sizes(context.exr, p, 0, 0, &tileWidth, &tileHeight) == EXR_ERR_SUCCESS && tileWidth > 0 &&
        tileHeight > 0) {
      const long long tilesX = ((long long)dw.max.x - dw.min.x + tileWidth) / tileWidth;
      const long long tilesY = ((long long)dw.max.y - dw.min.y + tileHeight) / tileHeight;
      // Each chunk has an 8-byte entry in the file's offset table: more tiles than that can hold is
      // a corrupt header, said now rather than after millions of reads.
      if (tilesX * tilesY > (long long)(fileSize / 8)) check(EXR_ERR_INVALID_ATTR, chunk, "tile table");
      for (long long ty = 0; ty < tilesY; ++ty)
        for (long long tx = 0; tx < tilesX; ++tx)
          check(exr_read_tile_chunk_info(context.exr, p, int(tx), int(ty), 0, 0, &chunk), chunk,
                "tile " + std::to_string(tx) + "," + std::to_string(ty));
    } else {
      std::int32_t lines = 1;
      if (exr_get_scanlines_per_chunk(context.exr, p, &lines) != EXR_ERR_SUCCESS || lines < 1) lines = 1;
      for (long long y = dw.min.y; y <= dw.max.y; y += lines)
        check(exr_read_scanline_chunk_info(context.exr, p, int(y), &chunk), chunk, "row " + std::to_string(y));
    }
  }
}

// readFrame, and readGeometryFrame where colourPixels is false: the colour's
// part still sets the frame's size and windows, but its pixels are not read.
Frame readFrameReading(const std::string& path, const std::string& viewLayer, bool colourPixels) {
  OiioErrorDrain drain;  // whatever happens, leave no message in OIIO's global queue
  checkReadable(path);

  // Colour is read as stored, and premultiplied below where the file says
  // its alpha is unassociated (PNG), as writeImage divides it out.
  OIIO::ImageSpec config;
  config.attribute("oiio:UnassociatedAlpha", 1);
  std::unique_ptr<OIIO::ImageInput> in;
  try {
    in = OIIO::ImageInput::open(path, &config);
  } catch (const std::exception& e) {  // OIIO plugins should not throw; be safe anyway
    ioError("cannot read '" + path + "': " + e.what());
  }
  if (!in) ioError("cannot read '" + path + "' as an image: " + oiioErrors(nullptr));
  const bool exr = in->format_name() == std::string("openexr");

  // Every part's header; a part's pixels are read only for the passes it holds.
  std::vector<Part> parts;
  parts.push_back({in->spec(), in->spec().get_string_attribute("oiio:subimagename"), false});
  checkFlatImage(parts[0].spec, "'" + path + "'");
  for (int s = 1; in->seek_subimage(s, 0); ++s)
    parts.push_back({in->spec(), in->spec().get_string_attribute("oiio:subimagename"), false});
  const bool multiPart = parts.size() > 1;
  // Names the file in a message, and the part of a multi-part one.
  auto where = [&](int p) { return "'" + path + "'" + (multiPart ? " (" + partLabel(parts, p) + ")" : ""); };

  Frame frame;
  frame.path = path;
  std::vector<ChannelName> names;
  for (std::size_t p = 0; p < parts.size(); ++p) {
    const OIIO::ImageSpec& spec = parts[p].spec;
    for (int i = 0; i < spec.nchannels; ++i) {
      const std::string stored = i < int(spec.channelnames.size()) ? spec.channelnames[size_t(i)] : std::string();
      const std::string n = multiPart ? matchName(stored, parts[p].name) : stored;
      frame.channelNames.push_back(n);
      names.push_back(splitChannelName(n, i));
      names.back().part = int(p);
    }
  }

  const std::string layer = chooseLayer(path, names, viewLayer);
  frame.layer = layer;
  {
    // Blender writes the compositor's result beside the view layers, as layer "Composite" (whenever
    // its compositor runs): that is no view layer left out, and the passes are the view layer's.
    std::map<std::string, int> others;  // layer -> channels
    for (const ChannelName& c : names)
      if (!c.layer.empty() && c.layer != layer && c.layer != "Composite") ++others[c.layer];
    for (const auto& [name, count] : others)
      frame.layersNotRead.push_back("'" + name + "' (" + std::to_string(count) + " channel" + (count == 1 ? "" : "s") + ")");
  }
  const bool hasCombined =
      std::any_of(names.begin(), names.end(), [&](const ChannelName& c) { return c.layer == layer && c.pass == "Combined"; });

  auto channelsOf = [&](const std::string& passName) {
    std::vector<const ChannelName*> out;
    for (const auto& c : names)
      if (c.layer == layer && c.pass == passName) out.push_back(&c);
    return out;
  };
  auto label = [&](const std::string& passName) { return layer.empty() ? passName : layer + "." + passName; };
  // The part a pass is read from: all of its channels are in one.
  auto partOf = [&](const std::string& passLabel, const std::vector<const ChannelName*>& chans) {
    for (const ChannelName* c : chans)
      if (c->part != chans.front()->part)
        invalidData("pass '" + passLabel + "' of '" + path + "' is in more than one part (" +
                    partLabel(parts, chans.front()->part) + ", " + partLabel(parts, c->part) +
                    "); a pass must be in one part");
    return chans.front()->part;
  };

  // The colour's part sets the frame: its display window. Every other part a
  // pass is read from must have the same one; its data window may differ.
  DisplayWindow display;
  int colourPart = -1;
  auto windowsOf = [&](int p) {
    const OIIO::ImageSpec& spec = parts[std::size_t(p)].spec;
    if (p != 0) checkFlatImage(spec, where(p));  // the first part was checked above
    const DisplayWindow d = displayWindow(spec);
    if (colourPart < 0) {
      colourPart = p;
      display = d;
    } else if (d != display) {
      invalidData("'" + path + "': " + partLabel(parts, p) + " has the display window " + d.text() + ", and " +
                  partLabel(parts, colourPart) + ", which holds the colour, " + display.text() +
                  "; the parts read must share one display window");
    }
    parts[std::size_t(p)].read = true;
    Windows win;
    win.part = p;
    win.width = int(d.width);
    win.height = int(d.height);
    win.dataWidth = spec.width;
    win.dataHeight = spec.height;
    win.offsetX = (long long)spec.x - d.x;
    win.offsetY = (long long)spec.y - d.y;
    return win;
  };

  // ---- colour ----
  // Which part, and the indices of its R,G,B[,A] in it.
  std::vector<int> colourIdx;
  std::string colourLabel = "color";
  Windows colourWin;
  if (hasCombined) {
    colourLabel = label("Combined");
    const std::vector<const ChannelName*> chans = channelsOf("Combined");
    const int p = partOf(colourLabel, chans);
    colourWin = windowsOf(p);
    colourIdx = matchPass(where(p), colourLabel, chans, roleSpecs()[0]);
  } else {
    // A plain image: R,G,B[,A] or grey Y[,A] without a layer or pass prefix,
    // of one part: the first part's, else the one part that has them.
    auto plainColour = [&](int p) {
      std::vector<const ChannelName*> plain;
      for (const ChannelName* c : channelsOf(""))
        if (c->part == p) plain.push_back(c);
      const ChannelName* r = findChannel(plain, "R");
      const ChannelName* g = findChannel(plain, "G");
      const ChannelName* b = findChannel(plain, "B");
      const ChannelName* a = findChannel(plain, "A");
      const ChannelName* grey = findChannel(plain, "Y");
      if (r && g && b) return std::vector<int>{r->index, g->index, b->index, a ? a->index : -1};
      if (grey && !r && !g && !b) return std::vector<int>{grey->index, grey->index, grey->index, a ? a->index : -1};
      return std::vector<int>();
    };
    std::vector<int> withColour;
    for (int p = 0; p < int(parts.size()); ++p)
      if (!plainColour(p).empty()) withColour.push_back(p);
    if (withColour.empty()) {
      std::string list;
      for (const auto& n : frame.channelNames) list += (list.empty() ? "" : ", ") + n;
      invalidData("no colour in '" + path + "': expected a Combined pass or R,G,B channels (channels: " + list + ")" +
                  (multiPart ? " in any of its " + std::to_string(parts.size()) + " parts" : std::string()));
    }
    if (withColour.size() > 1 && withColour.front() != 0)
      invalidData("'" + path + "' has R,G,B colour in more than one part (" + partLabel(parts, withColour[0]) + ", " +
                  partLabel(parts, withColour[1]) + ") and none in its first: which is the colour is unclear");
    colourWin = windowsOf(withColour.front());
    colourIdx = plainColour(withColour.front());
  }
  const OIIO::ImageSpec& colourSpec = parts[std::size_t(colourPart)].spec;
  frame.width = colourWin.width;
  frame.height = colourWin.height;
  frame.windows.displayX = int(display.x);
  frame.windows.displayY = int(display.y);
  frame.windows.dataX = colourSpec.x;
  frame.windows.dataY = colourSpec.y;
  frame.windows.dataWidth = colourSpec.width;
  frame.windows.dataHeight = colourSpec.height;
  const int w = frame.width, h = frame.height;

  const bool decode = needsSrgbDecode(colourSpec);
  // The filters take colour premultiplied by alpha, as Blender's EXRs hold it.
  const bool straightAlpha = colourSpec.get_int_attribute("oiio:UnassociatedAlpha", 0) != 0;
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
  std::vector<PassRead> reads;  // planned here, read together at the end
  auto asStored1 = [](const float* s, Image& im, int x, int y) { *im.at(x, y) = s[0]; };
  if (colourPixels)
    reads.push_back(passRead("color", colourLabel, colourIdx, colourWin, Image(w, h, 4, 0.0f), colorConvert));

  if (!hasCombined) {
    // Blender's single-layer EXR can carry a top-level "Z" depth channel: the
    // colour's part's, else the one part that has one.
    std::vector<const ChannelName*> zs;
    for (const ChannelName* c : channelsOf(""))
      if (iequals(c->channel, "Z")) zs.insert(c->part == colourPart ? zs.begin() : zs.end(), c);
    if (zs.size() > 1 && zs.front()->part != colourPart)
      invalidData("'" + path + "' has a Z channel in more than one part (" + partLabel(parts, zs[0]->part) + ", " +
                  partLabel(parts, zs[1]->part) + ") and none beside the colour: which is the depth is unclear");
    if (!zs.empty())
      reads.push_back(passRead("depth", "Z", {zs.front()->index}, windowsOf(zs.front()->part),
                               Image(w, h, 1, kBackgroundDepth), asStored1));
  }

  if (hasCombined) {
    // Normals and albedo: three channels, sanitised as colour is.
    auto sanitized3 = [](const float* s, Image& im, int x, int y) {
      float* d = im.at(x, y);
      for (int k = 0; k < 3; ++k) d[k] = sanitizeColor(s[k]);
    };
    int idPart = -1;
    const auto& specs = roleSpecs();
    for (std::size_t r = 1; r < specs.size(); ++r) {
      const RoleSpec& rs = specs[r];
      std::vector<const ChannelName*> chans = channelsOf(rs.blenderPass);
      if (chans.empty()) continue;
      const std::string passLabel = label(rs.blenderPass);
      const int p = partOf(passLabel, chans);
      const std::string role = rs.role;
      std::vector<int> idx;
      try {
        idx = matchPass(where(p), passLabel, chans, rs);
      } catch (const Exception& e) {
        // Other channels than Blender writes (a 2-channel Vector): an error only for a method
        // that reads the pass, as a half-float ID pass is (Frame::unusable), not for every method.
        frame.unusable[role] = e.what();
        continue;
      }
      const Windows win = windowsOf(p);
      if (role == "depth") {
        // Kept as stored: Blender 3.x's half-float background (65504) already
        // reads as background through isBackgroundDepth.
        reads.push_back(passRead(role, passLabel, idx, win, Image(w, h, 1, kBackgroundDepth), asStored1));
      } else if (role == "normal") {
        reads.push_back(passRead(role, passLabel, idx, win, Image(w, h, 3, 0.0f), sanitized3));
      } else if (role == "motion") {
        // Blender's Vector pass is y up; the convention is y down (rows).
        reads.push_back(passRead(role, passLabel, idx, win, Image(w, h, 4, 0.0f),
                                 [](const float* s, Image& im, int x, int y) {
                                   float* d = im.at(x, y);
                                   d[0] = sanitizeColor(s[0]);
                                   d[1] = sanitizeColor(-s[1]);
                                   d[2] = sanitizeColor(s[2]);
                                   d[3] = sanitizeColor(-s[3]);
                                 }));
      } else if (role == "id") {
        // The hash bits must survive: a half-float channel cannot hold them.
        // Only a method that reads IDs fails on it (Frame::unusable).
        idPart = p;
        const OIIO::TypeDesc format = parts[std::size_t(p)].spec.channelformat(idx[0]);
        if (format.basetype != OIIO::TypeDesc::FLOAT) {
          frame.unusable[role] = "pass '" + passLabel + "' in " + where(p) + " is stored as " +
                                 std::string(format.c_str()) + ", not 32-bit float: object IDs would be lost";
          continue;
        }
        reads.push_back(passRead(role, passLabel, idx, win, Image::uintImage(w, h),
                                 [](const float* s, Image& im, int x, int y) {
                                   std::uint32_t bits;
                                   std::memcpy(&bits, &s[0], 4);
                                   im.setUint(x, y, s[1] > 0.0f ? bits : 0u);  // no coverage: background
                                 }));
      } else if (role == "albedo") {
        reads.push_back(passRead(role, passLabel, idx, win, Image(w, h, 3, 0.0f), sanitized3));
      }
    }
    // The manifest is in the header of the ID pass's part, or of another part.
    std::string manifest = idPart >= 0 ? findManifest(parts[std::size_t(idPart)].spec, layer) : std::string();
    for (std::size_t p = 0; manifest.empty() && p < parts.size(); ++p)
      if (int(p) != idPart) manifest = findManifest(parts[p].spec, layer);
    if (!manifest.empty()) {
      try {
        frame.objectIds = parseCryptomatteManifest(manifest);
      } catch (const Exception& e) {
        invalidData("'" + path + "': " + e.what());
      }
    }
  }

  if (exr) checkUncompressedChunks(path, parts);
  readPasses(*in, path, parts, reads);
  for (PassRead& r : reads) frame.passes[r.role] = std::move(r.image);

  // The parts no pass was read from, named: what they hold is not lost without a word.
  for (std::size_t p = 0; p < parts.size(); ++p) {
    if (parts[p].read) continue;
    std::string list;
    for (const std::string& n : parts[p].spec.channelnames) list += (list.empty() ? "" : ", ") + n;
    frame.partsNotRead.push_back(partLabel(parts, int(p)) + " (channels: " + list + ")");
  }

  in->close();
  return frame;
}
}  // namespace

Frame readFrame(const std::string& path, const std::string& viewLayer) {
  return readFrameReading(path, viewLayer, true);
}

Frame readGeometryFrame(const std::string& path) { return readFrameReading(path, std::string(), false); }

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
