// SPDX-License-Identifier: Apache-2.0
// Fuzzes the filters fuzz_c_api leaves out (taa, taa-improved, phlm, rsaa)
// over frame sequences: bytes pick the filter, one frame size, the images the
// filter's own table offers (crispGetFilterInfo: names, channels, ID or not;
// now and then another size or format; the output now and then in place, in
// an input's buffer, as crisp.h allows), parameter values near and beyond
// their limits, and a run of commits, executes, resets, new frame sizes (every
// image set again) and new pixel values,
// extreme ones (NaN, +-Inf, 1e30, denormals) included. A sequence must end in
// results or recorded errors, never a crash; and an execute that reports no
// error leaves every output value finite (the temporal methods' stability
// contract, taa.h and phlm.h).
//
// These filters' sources are built with coverage but without ASan/UBSan in
// the fuzz build (native/CMakeLists.txt: instrumenting phlm.cpp alone took
// 20 min of one core), so a bad access inside them shows here only as a
// crash; the C API layer and the buffers are instrumented, and the sanitizer
// stage of scripts/test.sh runs the filters' unit tests under ASan + UBSan.
#include <cmath>
#include <cstdint>
#include <cstring>
#include <deque>
#include <limits>
#include <map>
#include <string>
#include <vector>

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

// The text of "key": "value" or "key": value after `from` (the library's own JSON, crisp.h).
std::string field(const std::string& json, std::size_t from, std::size_t to, const std::string& key) {
  const std::size_t k = json.find("\"" + key + "\": ", from);
  if (k == std::string::npos || k >= to) return "";
  std::size_t b = k + key.size() + 4;
  if (json[b] == '"') return json.substr(b + 1, json.find('"', b + 1) - b - 1);
  if (json[b] == '[') return json.substr(b + 1, json.find(']', b) - b - 1);
  return json.substr(b, json.find_first_of(",}", b) - b);
}

// Each {...} object of the array after "key" (objects hold no nested braces).
std::vector<std::pair<std::size_t, std::size_t>> objects(const std::string& json, const std::string& key) {
  std::vector<std::pair<std::size_t, std::size_t>> out;
  std::size_t at = json.find("\"" + key + "\": [");
  if (at == std::string::npos) return out;
  const std::size_t end = json.find(']', json.find("}]", at));
  for (std::size_t b = json.find('{', at); b != std::string::npos && b < end; b = json.find('{', b + 1))
    out.emplace_back(b, json.find('}', b));
  return out;
}

const char* const kTypes[] = {"taa", "taa-improved", "phlm", "rsaa"};

struct Buffer {
  std::vector<float> data;
  CrispFormat format = CRISP_FORMAT_UNDEFINED;
  int w = 0, h = 0, channels = 0;
  std::size_t pixelFloats = 0, rowFloats = 0;
};

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  Reader r{{data, size}};
  CrispContext ctx = crispNewContext();
  crispSetContextInt(ctx, "numThreads", 1 + r.byte() % 2);
  CrispFilter f = crispNewFilter(ctx, kTypes[r.byte() % 4]);
  const std::string info = crispGetFilterInfo(f);
  std::vector<ImageRole> images;
  for (auto [b, e] : objects(info, "images")) {
    ImageRole role;
    role.name = field(info, b, e, "name");
    role.minChannels = std::stoi(field(info, b, e, "minChannels"));
    role.maxChannels = std::stoi(field(info, b, e, "maxChannels"));
    role.uint = field(info, b, e, "uint") == "true";
    role.required = field(info, b, e, "required") == "true";
    images.push_back(role);
  }
  std::vector<Param> params;
  for (auto [b, e] : objects(info, "params")) {
    Param p;
    p.name = field(info, b, e, "name");
    p.type = field(info, b, e, "type");
    if (p.type == "string") {
      const std::string list = field(info, b, e, "choices");
      for (std::size_t q = list.find('"'); q != std::string::npos; q = list.find('"', list.find('"', q + 1) + 1))
        p.choices.push_back(list.substr(q + 1, list.find('"', q + 1) - q - 1));
    } else if (p.type != "bool") {
      p.min = std::stof(field(info, b, e, "min"));
      p.max = std::stof(field(info, b, e, "max"));
    }
    params.push_back(p);
  }
  if (images.empty() || params.empty()) __builtin_trap();  // the table itself is broken

  int w = 16 - r.byte() % 16, h = 16 - r.byte() % 16;  // 16x16 once the bytes run out
  std::deque<Buffer> buffers;  // push_back keeps references valid: `current` and `output` stay valid
  crisp_fuzz::OutputView output;  // the output the filter writes, for the finite check
  std::map<std::string, Buffer*> current;  // the buffer each role's image is (the filter kept it)
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
        if (crisp_fuzz::setImage(f, "output", in->data.data(), in->format, std::size_t(in->w), std::size_t(in->h),
                                 in->pixelFloats * 4, in->rowFloats * 4, &output))
          current["output"] = in;
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
                             b.pixelFloats * 4, b.rowFloats * 4, &output))
      current[role.name] = &b;
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
    const std::uint8_t op = r.n ? r.byte() : 9;
    switch (op % 10) {
      case 0: {
        const ImageRole& role = images[r.byte() % images.size()];
        if (r.byte() % 8 == 0) {
          crispUnsetFilterImage(f, role.name.c_str());
          current.erase(role.name);
          if (role.name == "output") output = {};
        } else {
          setImage(role);
        }
        break;
      }
      case 1:
      case 2: setParam(params[r.byte() % params.size()]); break;
      case 3: crispCommitFilter(f); break;
      case 4: crispResetFilter(f); break;
      case 5: {  // the next frame's pixels in an image already set
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
      case 6: {  // a new frame size: every image set again at it (the history is dropped)
        w = 16 - r.byte() % 16, h = 16 - r.byte() % 16;
        for (const ImageRole& role : images)
          if (current.count(role.name)) setImage(role);
        break;
      }
      default: {
        crispCommitFilter(f);
        crisp_fuzz::execute(f, output);  // its output finite if it reported no error
        break;
      }
    }
    crispGetError(nullptr);
  }
  crisp_fuzz::finish(ctx, f, output);
  return 0;
}
