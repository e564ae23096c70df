// SPDX-License-Identifier: Apache-2.0
// Cryptomatte helpers: the object-name hash and the manifest parser.
// Reference: Friedman & Jones, "Fully Automatic ID Mattes with Support for
// Motion Blur and Transparency" (SIGGRAPH 2015 poster) and the Cryptomatte
// specification v1.2 (Psyop), section "Hashing" and "Manifest".
#pragma once

#include <cstddef>
#include <cstdint>
#include <map>
#include <string>

namespace crisp {

// MurmurHash3_x86_32 (Austin Appleby's published algorithm): 4-byte blocks,
// little-endian, with the fmix32 finaliser.
std::uint32_t murmurHash3_x86_32(const void* data, std::size_t length, std::uint32_t seed);

// The Cryptomatte ID of a name: MurmurHash3_x86_32(name, seed 0) with the
// spec's tweak that flips bit 23 when the float exponent would be 0 or 255,
// so the hash read as a float32 is never denormal, zero, inf or NaN.
std::uint32_t cryptomatteHash(const std::string& name);

// The hash as stored in a CryptoObject channel (same bits as a float).
float cryptomatteHashToFloat(std::uint32_t hash);

// Metadata key prefix Blender and the spec use for a layer name such as
// "ViewLayer.CryptoObject": "cryptomatte/" + first 7 hex digits of the raw
// MurmurHash3 of the name + "/".
std::string cryptomatteKeyPrefix(const std::string& layerName);

// Parses a manifest: a flat JSON object of name -> 8-hex-digit hash string,
// e.g. {"Cube":"a8fce865"}. Throws CRISP_ERROR_INVALID_DATA describing the
// first problem (position included); the caller adds the file name.
std::map<std::string, std::uint32_t> parseCryptomatteManifest(const std::string& json);

// 8 lowercase hex digits, as in a manifest.
std::string hashToHex(std::uint32_t hash);

}  // namespace crisp
