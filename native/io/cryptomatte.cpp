// SPDX-License-Identifier: Apache-2.0
// Cryptomatte name hash and manifest parsing (see cryptomatte.h for sources).
#include "io/cryptomatte.h"

#include <cstring>

#include "core/error.h"

namespace crisp {

namespace {

std::uint32_t rotl32(std::uint32_t x, int r) { return (x << r) | (x >> (32 - r)); }

// MurmurHash3 finaliser: forces all bits of the state to avalanche.
std::uint32_t fmix32(std::uint32_t h) {
  h ^= h >> 16;
  h *= 0x85ebca6bu;
  h ^= h >> 13;
  h *= 0xc2b2ae35u;
  h ^= h >> 16;
  return h;
}

}  // namespace

std::uint32_t murmurHash3_x86_32(const void* data, std::size_t length, std::uint32_t seed) {
  const auto* bytes = static_cast<const unsigned char*>(data);
  const std::uint32_t c1 = 0xcc9e2d51u, c2 = 0x1b873593u;
  std::uint32_t h = seed;
  const std::size_t blocks = length / 4;
  for (std::size_t i = 0; i < blocks; ++i) {
    // Blocks are read little-endian whatever the host order.
    const unsigned char* p = bytes + 4 * i;
    std::uint32_t k = std::uint32_t(p[0]) | std::uint32_t(p[1]) << 8 | std::uint32_t(p[2]) << 16 |
                      std::uint32_t(p[3]) << 24;
    k *= c1;
    k = rotl32(k, 15);
    k *= c2;
    h ^= k;
    h = rotl32(h, 13);
    h = h * 5 + 0xe6546b64u;
  }
  const unsigned char* tail = bytes + 4 * blocks;
  std::uint32_t k = 0;
  switch (length & 3) {
    case 3: k ^= std::uint32_t(tail[2]) << 16; [[fallthrough]];
    case 2: k ^= std::uint32_t(tail[1]) << 8; [[fallthrough]];
    case 1:
      k ^= std::uint32_t(tail[0]);
      k *= c1;
      k = rotl32(k, 15);
      k *= c2;
      h ^= k;
  }
  h ^= std::uint32_t(length);
  return fmix32(h);
}

std::uint32_t cryptomatteHash(const std::string& name) {
  std::uint32_t h = murmurHash3_x86_32(name.data(), name.size(), 0);
  // Spec, "Hashing": avoid exponents 0 (zero/denormal) and 255 (inf/NaN).
  const std::uint32_t exponent = (h >> 23) & 0xffu;
  if (exponent == 0 || exponent == 255) h ^= 1u << 23;
  return h;
}

float cryptomatteHashToFloat(std::uint32_t hash) {
  float f;
  std::memcpy(&f, &hash, 4);
  return f;
}

std::string hashToHex(std::uint32_t hash) {
  static const char digits[] = "0123456789abcdef";
  std::string s(8, '0');
  for (int i = 7; i >= 0; --i, hash >>= 4) s[std::size_t(i)] = digits[hash & 15u];
  return s;
}

std::string cryptomatteKeyPrefix(const std::string& layerName) {
  return "cryptomatte/" + hashToHex(murmurHash3_x86_32(layerName.data(), layerName.size(), 0)).substr(0, 7) + "/";
}

namespace {

// A strict parser for the one JSON shape a manifest has (RFC 8259 object whose
// values are strings). Anything else is reported with its byte offset.
class ManifestParser {
 public:
  explicit ManifestParser(const std::string& text) : s_(text) {}

  std::map<std::string, std::uint32_t> parse() {
    std::map<std::string, std::uint32_t> out;
    skipSpace();
    expect('{');
    skipSpace();
    if (peek() == '}') {
      ++pos_;
    } else {
      for (;;) {
        skipSpace();
        std::string name = parseString();
        skipSpace();
        expect(':');
        skipSpace();
        std::size_t valueAt = pos_;
        std::string value = parseString();
        out[name] = parseHex(value, valueAt, name);
        skipSpace();
        if (peek() == ',') {
          ++pos_;
          continue;
        }
        expect('}');
        break;
      }
    }
    skipSpace();
    if (pos_ != s_.size()) error("unexpected text after the closing brace");
    return out;
  }

 private:
  const std::string& s_;
  std::size_t pos_ = 0;

  [[noreturn]] void error(const std::string& what) const {
    invalidData("Cryptomatte manifest is not a JSON object of name -> hash strings: " + what + " at byte " +
                std::to_string(pos_));
  }
  char peek() const { return pos_ < s_.size() ? s_[pos_] : '\0'; }
  void skipSpace() {
    while (pos_ < s_.size() && (s_[pos_] == ' ' || s_[pos_] == '\t' || s_[pos_] == '\n' || s_[pos_] == '\r')) ++pos_;
  }
  void expect(char c) {
    if (pos_ >= s_.size()) error(std::string("expected '") + c + "' but the text ended");
    if (s_[pos_] != c) error(std::string("expected '") + c + "'");
    ++pos_;
  }
  unsigned hex4() {
    if (pos_ + 4 > s_.size()) error("truncated \\u escape");
    unsigned v = 0;
    for (int i = 0; i < 4; ++i) {
      char c = s_[pos_++];
      int d = c >= '0' && c <= '9' ? c - '0' : c >= 'a' && c <= 'f' ? c - 'a' + 10 : c >= 'A' && c <= 'F' ? c - 'A' + 10 : -1;
      if (d < 0) error("bad hex digit in \\u escape");
      v = v * 16 + unsigned(d);
    }
    return v;
  }
  static void appendUtf8(std::string& out, unsigned cp) {
    if (cp < 0x80) {
      out += char(cp);
    } else if (cp < 0x800) {
      out += char(0xc0 | (cp >> 6));
      out += char(0x80 | (cp & 0x3f));
    } else if (cp < 0x10000) {
      out += char(0xe0 | (cp >> 12));
      out += char(0x80 | ((cp >> 6) & 0x3f));
      out += char(0x80 | (cp & 0x3f));
    } else {
      out += char(0xf0 | (cp >> 18));
      out += char(0x80 | ((cp >> 12) & 0x3f));
      out += char(0x80 | ((cp >> 6) & 0x3f));
      out += char(0x80 | (cp & 0x3f));
    }
  }
  std::string parseString() {
    expect('"');
    std::string out;
    for (;;) {
      if (pos_ >= s_.size()) error("unterminated string");
      char c = s_[pos_++];
      if (c == '"') return out;
      if (static_cast<unsigned char>(c) < 0x20) error("control character inside a string");
      if (c != '\\') {
        out += c;  // UTF-8 bytes pass through unchanged
        continue;
      }
      if (pos_ >= s_.size()) error("unterminated escape");
      char e = s_[pos_++];
      switch (e) {
        case '"': out += '"'; break;
        case '\\': out += '\\'; break;
        case '/': out += '/'; break;
        case 'b': out += '\b'; break;
        case 'f': out += '\f'; break;
        case 'n': out += '\n'; break;
        case 'r': out += '\r'; break;
        case 't': out += '\t'; break;
        case 'u': {
          unsigned cp = hex4();
          if (cp >= 0xd800 && cp < 0xdc00) {  // high surrogate: a low one must follow
            if (pos_ + 2 > s_.size() || s_[pos_] != '\\' || s_[pos_ + 1] != 'u') error("lone UTF-16 surrogate");
            pos_ += 2;
            unsigned lo = hex4();
            if (lo < 0xdc00 || lo >= 0xe000) error("bad UTF-16 surrogate pair");
            cp = 0x10000 + ((cp - 0xd800) << 10) + (lo - 0xdc00);
          } else if (cp >= 0xdc00 && cp < 0xe000) {
            error("lone UTF-16 surrogate");
          }
          appendUtf8(out, cp);
          break;
        }
        default: error(std::string("unknown escape '\\") + e + "'");
      }
    }
  }
  std::uint32_t parseHex(const std::string& v, std::size_t at, const std::string& name) {
    std::uint32_t h = 0;
    bool ok = v.size() == 8;
    for (std::size_t i = 0; ok && i < v.size(); ++i) {
      char c = v[i];
      int d = c >= '0' && c <= '9' ? c - '0' : c >= 'a' && c <= 'f' ? c - 'a' + 10 : c >= 'A' && c <= 'F' ? c - 'A' + 10 : -1;
      if (d < 0) ok = false;
      h = h * 16 + std::uint32_t(d < 0 ? 0 : d);
    }
    if (!ok) {
      pos_ = at;
      error("hash of '" + name + "' is \"" + v + "\", not 8 hex digits");
    }
    return h;
  }
};

}  // namespace

std::map<std::string, std::uint32_t> parseCryptomatteManifest(const std::string& json) {
  return ManifestParser(json).parse();
}

}  // namespace crisp
