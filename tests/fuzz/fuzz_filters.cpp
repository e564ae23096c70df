// SPDX-License-Identifier: Apache-2.0
// Fuzzes the filters fuzz_c_api leaves out (taa, taa-improved, phlm, rsaa)
// over frame sequences: bytes pick the filter, one frame size, the images the
// filter's own table offers (crispGetFilterInfo, read once at start: names,
// channels, ID or not; now and then another size or format; the output now
// and then in place, in an input's buffer, as crisp.h allows), parameter
// values near and beyond their limits, and a run of commits, executes, resets,
// new frame sizes (every image set again) and new pixel values, extreme ones
// (NaN, +-Inf, 1e30, denormals) included. A sequence must end in
// results or recorded errors, never a crash; an execute that reports no
// error leaves every output value finite (the temporal methods' stability
// contract, taa.h and phlm.h); and a sequence that ran with the output in an
// input's buffer writes the same values when run again with the output in a
// buffer of its own (crisp.h). seeds() below writes inputs that reach a few
// frames of each filter with the output in place at once (fuzz_common.h's
// writeSeedsIfAsked; scripts/test.sh starts from them).
//
// These filters' sources are built with coverage but without ASan/UBSan in
// the fuzz build (native/CMakeLists.txt: instrumenting phlm.cpp alone took
// 20 min of one core), so a bad access inside them shows here only as a
// crash; the C API layer and the buffers are instrumented, and the sanitizer
// stage of scripts/test.sh runs the filters' unit tests under ASan + UBSan.
#include <algorithm>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <deque>
#include <exception>
#include <limits>
#include <map>
#include <stdexcept>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "crisp/crisp.h"
#include "fuzz_common.h"

namespace {

// A pixel value from the bytes: ordinary mostly, an extreme one now and then.
struct Reader : crisp_fuzz::Reader {
  float value() {
    static const float kExtreme[] = {std::numeric_limits<float>::quiet_NaN(),
                                     std::numeric_limits<float>::infinity(),
                                     -std::numeric_limits<float>::infinity(),
                                     1e30f,
                                     -1e30f,
                                     1e-40f,
                                     65504.0f,
                                     0.0f};
    const std::uint8_t b = byte();
    if (b < 200) return float(b) / 100.0f - 0.5f;  // -0.5 .. 1.49
    if (b < 240) return kExtreme[b % 8];
    return number();
  }
};

struct ImageRole {
  std::string name;
  int minChannels = 1, maxChannels = 4;
  bool uint = false, required = false;
};
struct Param {
  std::string name, type;
  float min = 0, max = 0;
  std::vector<std::string> choices;
};

struct Table {
  std::vector<ImageRole> images;
  std::vector<Param> params;
};

// A filter's images and parameters from its crispGetFilterInfo JSON (crisp.h gives its shape); throws
// if the text is not JSON of that shape (nlohmann's at() and get<>() refuse a missing member or a value
// of another kind, so a table the library ever writes differently fails at once rather than being
// misread).
Table readTable(const std::string& info) {
  const nlohmann::json doc = nlohmann::json::parse(info);
  auto arrayAt = [](const nlohmann::json& o, const char* key) -> const nlohmann::json& {
    const nlohmann::json& a = o.at(key);
    if (!a.is_array()) throw std::runtime_error(std::string("'") + key + "' is not an array");
    return a;
  };
  Table t;
  for (const nlohmann::json& image : arrayAt(doc, "images")) {
    ImageRole role;
    role.name = image.at("name").get<std::string>();
    role.minChannels = image.at("minChannels").get<int>();
    role.maxChannels = image.at("maxChannels").get<int>();
    role.uint = image.at("uint").get<bool>();
    role.required = image.at("required").get<bool>();
    if (role.name.empty() || role.minChannels < 1 || role.maxChannels < role.minChannels)
      throw std::runtime_error("image '" + role.name + "': no name, or a channel range that is empty");
    t.images.push_back(role);
  }
  for (const nlohmann::json& param : arrayAt(doc, "params")) {
    Param p;
    p.name = param.at("name").get<std::string>();
    p.type = param.at("type").get<std::string>();
    if (p.type == "string") {
      for (const nlohmann::json& choice : arrayAt(param, "choices")) p.choices.push_back(choice.get<std::string>());
    } else if (p.type == "int" || p.type == "float") {
      p.min = param.at("min").get<float>();
      p.max = param.at("max").get<float>();
      if (!(p.min <= p.max)) throw std::runtime_error("parameter '" + p.name + "': min above max");
    } else if (p.type != "bool") {
      throw std::runtime_error("parameter '" + p.name + "': unknown type '" + p.type + "'");
    }
    t.params.push_back(p);
  }
  if (t.images.empty() || t.params.empty()) throw std::runtime_error("no images or no parameters");
  return t;
}

const char* const kTypes[] = {"taa", "taa-improved", "phlm", "rsaa"};
std::vector<Table> gTables;  // kTypes' tables, read once (LLVMFuzzerInitialize)

struct Buffer {
  std::vector<float> data;
  CrispFormat format = CRISP_FORMAT_UNDEFINED;
  int w = 0, h = 0, channels = 0;
  std::size_t pixelFloats = 0, rowFloats = 0;
};

void run(const std::uint8_t* data, std::size_t size, bool apart, crisp_fuzz::Trace& trace);
std::vector<crisp_fuzz::Seed> seeds();

}  // namespace

// Reads each filter's table once. One it cannot read stops the target here, with a message, before
// any input: each input would fail on it, or misread it and fuzz something else. Then, if asked, the
// seeds are written (they read the tables) and the process exits.
extern "C" int LLVMFuzzerInitialize(int*, char***) {
  for (const char* type : kTypes) {
    CrispContext ctx = crispNewContext();
    CrispFilter f = crispNewFilter(ctx, type);
    const char* info = f ? crispGetFilterInfo(f) : nullptr;
    try {
      if (!info) throw std::runtime_error("no filter or no table");
      gTables.push_back(readTable(info));
    } catch (const std::exception& e) {
      std::fprintf(stderr, "fuzz_filters: filter '%s': its crispGetFilterInfo table is unreadable: %s\n%s\n", type,
                   e.what(), info ? info : "");
      std::abort();
    }
    crispReleaseFilter(f);
    crispReleaseContext(ctx);
    crispGetError(nullptr);
  }
  crisp_fuzz::writeSeedsIfAsked("fuzz_filters", seeds(), run);
  return 0;
}

namespace {

// What a step does: its byte modulo kOps (the seeds write these).
enum Op : int {
  kImage = 0,  // an image set again (another buffer, or the output in place) or unset
  kParam = 1,  // and 2
  kCommit = 3,
  kReset,
  kPixels,  // new pixel values in a buffer
  kSize,    // a new frame size
  kExecute,  // and 8, 9: a commit and an execute
  kOps = 10
};

// One run of the sequence the bytes make. `apart`: an output the bytes put in an input's buffer
// gets a buffer of its own instead, and after each execute the input's buffer gets what the execute
// wrote, so that every buffer holds what it holds in the run in place.
void run(const std::uint8_t* data, std::size_t size, bool apart, crisp_fuzz::Trace& trace) {
  Reader r{{data, size}};
  CrispContext ctx = crispNewContext();
  crispSetContextInt(ctx, "numThreads", 1 + r.byte() % 2);
  const int type = r.byte() % 4;
  trace.filter = kTypes[type];
  CrispFilter f = crispNewFilter(ctx, kTypes[type]);
  const std::vector<ImageRole>& images = gTables[type].images;
  const std::vector<Param>& params = gTables[type].params;

  int w = 16 - r.byte() % 16, h = 16 - r.byte() % 16;  // 16x16 once the bytes run out
  std::deque<Buffer> buffers;  // push_back keeps references valid: `current` and `output` stay valid
  crisp_fuzz::OutputView output;  // the output the filter writes, for the finite check
  std::map<std::string, Buffer*> current;  // the buffer each role's image is (the filter kept it)
  Buffer* shared = nullptr;  // the input's buffer the output is in (apart: would be in), or none
  std::deque<Buffer> apartOutputs;  // apart: the outputs' own buffers (not in `buffers`, which case 5 indexes)
  // Pixel values from a few bytes, not one a value (so the bytes reach the steps): a pattern of
  // edges and ramps, then a few values anywhere, extreme ones among them.
  auto fill = [&](Buffer& buf) {
    const int a = r.byte() % 7, b = r.byte() % 5, period = 2 + r.byte() % 6;
    for (std::size_t i = 0; i < buf.data.size(); ++i) {
      const std::size_t x = i % buf.rowFloats, y = i / buf.rowFloats;
      buf.data[i] = float((x * a + y * b + x / 4) % period) / float(period - 1);
    }
    for (int k = 0, count = r.byte() % 8; k < count && !buf.data.empty(); ++k)
      buf.data[(std::size_t(r.byte()) * 257u + r.byte()) % buf.data.size()] = r.value();
  };
  auto setImage = [&](const ImageRole& role) {
    // The output in place now and then: the buffer of an input of this size that an output can be
    // (crisp.h: the output may share an input's buffer; the result is the same).
    if (role.name == "output" && r.byte() % 4 == 0) {
      for (auto& [name, in] : current) {
        if (name == "output" || in->w != w || in->h != h || in->format < CRISP_FORMAT_FLOAT3 ||
            in->format > CRISP_FORMAT_FLOAT4)
          continue;
        Buffer* target = in;
        if (apart) {  // the same layout, filled without reading a byte: both runs read the same bytes
          apartOutputs.push_back(*in);
          target = &apartOutputs.back();
          std::fill(target->data.begin(), target->data.end(), -1234.5f);  // an unwritten value shows
        }
        if (crisp_fuzz::setImage(f, "output", target->data.data(), in->format, std::size_t(in->w),
                                 std::size_t(in->h), in->pixelFloats * 4, in->rowFloats * 4, &output))
          current["output"] = target, shared = in;
        return;
      }
    }
    Buffer buf;
    const std::uint8_t shape = r.byte();
    buf.w = shape % 16 == 15 ? 1 + r.byte() % 16 : w;  // another size now and then: refused at commit
    buf.h = shape % 16 == 14 ? 1 + r.byte() % 16 : h;
    CrispFormat format;
    if (shape % 16 == 13) {
      format = CrispFormat(r.byte() % 8);  // any format, unknown ones included
    } else if (role.minChannels > 4) {
      format = CRISP_FORMAT_RSAA_SUBSAMPLES;  // the only role of more than 4 channels: rsaa's 80-byte records
    } else if (role.uint) {
      format = shape & 16 ? CRISP_FORMAT_FLOAT : CRISP_FORMAT_UINT;
    } else {
      const int span = std::max(1, std::min(role.maxChannels, 4) - role.minChannels + 1);
      format = CrispFormat(std::min(role.maxChannels, 4) - (shape >> 5) % span);  // all channels by default
    }
    buf.format = format;
    buf.channels = format >= CRISP_FORMAT_FLOAT && format <= CRISP_FORMAT_FLOAT4 ? int(format) : 1;
    if (format == CRISP_FORMAT_RSAA_SUBSAMPLES) buf.channels = 20;
    buf.pixelFloats = std::size_t(buf.channels) + (shape & 64 ? 1 : 0);  // a padded pixel now and then
    buf.rowFloats = buf.pixelFloats * std::size_t(buf.w) + (shape & 128 ? 3 : 0);
    buf.data.resize(buf.rowFloats * std::size_t(buf.h));
    fill(buf);
    if (format == CRISP_FORMAT_UINT || format == CRISP_FORMAT_RSAA_SUBSAMPLES)
      for (auto& v : buf.data) {  // object IDs: a few distinct values; records: whatever bits
        std::uint32_t bits;
        std::memcpy(&bits, &v, 4);
        bits = (bits >> 23) % 4 * 0x9E3779B9u;
        std::memcpy(&v, &bits, 4);
      }
    buffers.push_back(std::move(buf));
    Buffer& b = buffers.back();
    // A refused image (a format the role does not take) leaves the one before, the output's too.
    if (crisp_fuzz::setImage(f, role.name.c_str(), b.data.data(), format, std::size_t(b.w), std::size_t(b.h),
                             b.pixelFloats * 4, b.rowFloats * 4, &output)) {
      current[role.name] = &b;
      if (role.name == "output") shared = nullptr;
    }
  };
  // After an execute: what it wrote, for the comparison; apart, a copy in the input's buffer the
  // output would have been in (the run in place wrote there).
  auto executed = [&](bool ok) {
    crisp_fuzz::recordExecute(trace, ok, output, shared && apart ? shared->data.data() : nullptr);
    if (!ok || !output) return;
    for (const auto& [name, in] : current)
      if (shared && name != "output" && in == shared) trace.inPlace = true;
  };
  auto setParam = [&](const Param& p) {
    const std::uint8_t how = r.byte();
    if (p.type == "bool") {
      crispSetFilterBool(f, p.name.c_str(), how & 1);
    } else if (p.type == "string") {
      const std::string value = how % 8 == 0 || p.choices.empty() ? "zzz" : p.choices[how % p.choices.size()];
      crispSetFilterString(f, p.name.c_str(), value.c_str());
    } else {
      const float t = float(r.byte()) / 255.0f;
      float v = p.min + t * (p.max - p.min);
      if (how % 8 == 0) v = p.max * (1.0f + t) + 1.0f;  // beyond the range: refused by name
      if (how % 16 == 1) v = std::numeric_limits<float>::quiet_NaN();
      if (p.type == "int")
        crispSetFilterInt(f, p.name.c_str(), int(std::fmax(std::fmin(v, 1e9f), -1e9f)));
      else
        crispSetFilterFloat(f, p.name.c_str(), v);
    }
  };

  // Every image, or the required ones and some others, so most sequences reach execute.
  const bool all = r.byte() & 1;
  for (const ImageRole& role : images)
    if (all || role.required || (r.byte() & 1)) setImage(role);
  // Once the bytes run out, executes up to step 8: short inputs still run a history.
  for (int step = 0; step < 48 && (r.n || step < 8); ++step) {
    const std::uint8_t op = r.n ? r.byte() : kExecute;
    switch (op % kOps) {
      case kImage: {
        const ImageRole& role = images[r.byte() % images.size()];
        if (r.byte() % 8 == 0) {
          crispUnsetFilterImage(f, role.name.c_str());
          current.erase(role.name);
          if (role.name == "output") output = {}, shared = nullptr;
        } else {
          setImage(role);
        }
        break;
      }
      case kParam:
      case kParam + 1: setParam(params[r.byte() % params.size()]); break;
      case kCommit: crispCommitFilter(f); break;
      case kReset: crispResetFilter(f); break;
      case kPixels: {  // the next frame's pixels in an image already set
        if (buffers.empty()) break;
        Buffer& b = buffers[r.byte() % buffers.size()];
        if (r.byte() & 1) {
          fill(b);
        } else {
          for (int k = 0, count = 1 + r.byte() % 8; k < count && !b.data.empty(); ++k)
            b.data[(std::size_t(r.byte()) * 257u + r.byte()) % b.data.size()] = r.value();
        }
        break;
      }
      case kSize: {  // a new frame size: every image set again at it (the history is dropped)
        w = 16 - r.byte() % 16, h = 16 - r.byte() % 16;
        for (const ImageRole& role : images)
          if (current.count(role.name)) setImage(role);
        break;
      }
      default: {
        crispCommitFilter(f);
        executed(crisp_fuzz::execute(f, output));  // its output finite if it reported no error
        break;
      }
    }
    crispGetError(nullptr);
  }
  crisp_fuzz::finish(ctx, f, output, executed);  // its execute compared too
  for (const Buffer& b : buffers) trace.buffers.push_back(b.data);
}

// ---- seeds (fuzz_common.h's writeSeedsIfAsked) ----------------------------------------------------------
// For each filter: its images at one size (every role, or the required ones and a few), the output on the
// colour's buffer, three frames (the colour's pixels new before each execute after the first, as a
// renderer writes the next frame into the buffer the filter wrote), then executes with the same pixels
// (run() executes up to step 8 once the bytes run out); on one thread and two, packed and padded RGBA or
// RGB, fast and reference paths; and the same with the output apart. libFuzzer mutates them from the
// start of the 30 s. The images are the filter's own table's (gTables), as run() reads them.

struct FilterSeed {
  std::string name;
  int type = 0;  // in kTypes
  int threads = 1, w = 8, h = 6;
  bool all = true;                    // every role set; else the required ones and `optional`
  std::vector<std::string> optional;  // the optional roles set when not `all`
  std::uint8_t colorShape = 0;        // setImage's shape byte for the colour (0: packed, every channel)
  bool reference = false;             // the "reference" parameter on
  bool inPlace = true;                // the output on the colour's buffer, or one of its own
};

// fill(): a pattern of edges and ramps picked by `k`, and two values set apart.
void writeFill(crisp_fuzz::Writer& out, int k) {
  out.byte(1 + k % 6);  // a
  out.byte(1 + k % 4);  // b
  out.byte(k % 6);      // period 2 + k % 6
  out.byte(2);          // two values anywhere: an index of two bytes and an ordinary value (a byte below 200)
  // fill() reads the value before the index (C++17: the right of `=` first); with all three bytes below
  // 200 either order reads three bytes and an ordinary value.
  for (int i = 0; i < 2; ++i) {
    out.byte((k * 59 + i * 97) % 200);
    out.byte((k * 37 + i * 101) % 200);
    out.byte((k * 11 + i * 53) % 200);
  }
}

crisp_fuzz::Seed writeSeed(const FilterSeed& s) {
  crisp_fuzz::Writer out;
  out.byte(s.threads - 1);
  out.byte(s.type);
  out.byte(16 - s.w);
  out.byte(16 - s.h);
  out.byte(s.all ? 1 : 0);
  int k = 0;
  for (const ImageRole& role : gTables[std::size_t(s.type)].images) {
    if (!s.all && !role.required) {
      const bool set = std::find(s.optional.begin(), s.optional.end(), role.name) != s.optional.end();
      out.byte(set ? 1 : 0);
      if (!set) continue;
    }
    if (role.name == "output") {
      out.byte(s.inPlace ? 0 : 1);  // in place when a multiple of 4
      if (s.inPlace) continue;      // the colour's buffer: no more bytes
    }
    out.byte(role.name == "color" ? s.colorShape : 0);
    writeFill(out, k++);
  }
  if (s.reference) {
    const std::vector<Param>& params = gTables[std::size_t(s.type)].params;
    std::size_t index = 0;
    while (index < params.size() && params[index].name != "reference") ++index;
    if (index == params.size()) {
      std::fprintf(stderr, "fuzz_filters: seed '%s': filter '%s' has no parameter 'reference'\n", s.name.c_str(),
                   kTypes[s.type]);
      std::abort();
    }
    out.byte(kParam);
    out.byte(int(index));
    out.byte(1);           // a bool's value: its low bit
  }
  for (int frame = 1; frame < 3; ++frame) {
    out.byte(kExecute);
    out.byte(kPixels);
    out.byte(0);  // the colour's buffer: the first one made
    out.byte(1);  // a new fill
    writeFill(out, 40 + frame);
  }
  out.byte(kExecute);
  return {s.name, out.bytes, kTypes[s.type], s.inPlace, 3};
}

std::vector<crisp_fuzz::Seed> seeds() {
  std::vector<crisp_fuzz::Seed> all;
  for (int type = 0; type < 4; ++type) {
    const std::string name = kTypes[type];
    FilterSeed s;
    s.type = type;
    if (name == "taa-improved") {  // albedo sorts before color: the output would take its buffer
      s.all = false;
      s.optional = {"motion", "depth", "id"};
    }
    s.name = name + "-in-place";
    all.push_back(writeSeed(s));
    FilterSeed reference = s;
    reference.name = name + "-in-place-reference", reference.reference = true;
    all.push_back(writeSeed(reference));
    FilterSeed apart = s;
    apart.name = name + "-apart", apart.inPlace = false;
    all.push_back(writeSeed(apart));
    FilterSeed few = s;  // the required roles (and rsaa's sub-samples), RGB in padded pixels and rows
    few.name = name + "-in-place-rgb-padded-2-threads", few.threads = 2, few.w = 7, few.h = 5, few.all = false;
    few.optional = name == "rsaa" ? std::vector<std::string>{"subsamples"} : std::vector<std::string>{};
    few.colorShape = 32 | 64 | 128;  // one channel fewer than 4, a float more a pixel, 3 more a row
    all.push_back(writeSeed(few));
    if (name == "taa-improved") {
      FilterSeed albedo = s;
      albedo.name = name + "-in-place-albedo", albedo.all = true;
      all.push_back(writeSeed(albedo));
    }
  }
  return all;
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  // A sequence with the output in place runs again apart (fuzz_common.h, crisp.h).
  crisp_fuzz::checkInPlace("fuzz_filters",
                           [&](bool apart, crisp_fuzz::Trace& trace) { run(data, size, apart, trace); });
  return 0;
}
