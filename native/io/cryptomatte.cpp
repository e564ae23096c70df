// SPDX-License-Identifier: Apache-2.0
// Cryptomatte name hash and manifest parsing (see cryptomatte.h for sources).
#include "io/cryptomatte.h"

#include <cstring>

#include <nlohmann/json.hpp>

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

std::map<std::string, std::uint32_t> parseCryptomatteManifest(const std::string& text) {
  const std::string what = "Cryptomatte manifest is not a JSON object of name -> hash strings: ";
  nlohmann::json doc;
  try {
    doc = nlohmann::json::parse(text);  // RFC 8259, strict: the message names the byte
  } catch (const nlohmann::json::parse_error& e) {
    invalidData(what + e.what());
  }
  if (!doc.is_object()) invalidData(what + "it is a JSON " + doc.type_name());
  std::map<std::string, std::uint32_t> out;
  for (const auto& [name, value] : doc.items()) {
    const std::string hex = value.is_string() ? value.get<std::string>() : value.dump();
    std::uint32_t h = 0;
    bool ok = value.is_string() && hex.size() == 8;
    for (std::size_t i = 0; ok && i < hex.size(); ++i) {
      const char c = hex[i];
      const int d = c >= '0' && c <= '9'   ? c - '0'
                    : c >= 'a' && c <= 'f' ? c - 'a' + 10
                    : c >= 'A' && c <= 'F' ? c - 'A' + 10
                                           : -1;
      ok = d >= 0;
      h = h * 16 + std::uint32_t(ok ? d : 0);
    }
    if (!ok)
      invalidData(what + "the hash of '" + name + "' is " + (value.is_string() ? "\"" + hex + "\"" : hex) +
                  ", not 8 hex digits");
    out[name] = h;
  }
  return out;
}

}  // namespace crisp
