# SPDX-License-Identifier: GPL-2.0-or-later
"""Cryptomatte object IDs: MurmurHash3_x86_32 of the object name (Cryptomatte specification 1.2,
"Identifiers": hash of the UTF-8 name, seed 0; a hash whose float32 exponent would be 0 or 255 has
bit 23 flipped so the stored float is never denormal, Inf or NaN). Pure Python, no bpy."""

import struct


def _rotl32(x, r):
    return ((x << r) | (x >> (32 - r))) & 0xFFFFFFFF


def murmurhash3_x86_32(data, seed=0):
    """MurmurHash3 x86 32-bit (Appleby), written from the published algorithm description."""
    c1, c2 = 0xCC9E2D51, 0x1B873593
    h = seed & 0xFFFFFFFF
    n = len(data)
    nblocks = n // 4
    for i in range(nblocks):
        k = struct.unpack_from("<I", data, 4 * i)[0]
        k = (k * c1) & 0xFFFFFFFF
        k = _rotl32(k, 15)
        k = (k * c2) & 0xFFFFFFFF
        h ^= k
        h = _rotl32(h, 13)
        h = (h * 5 + 0xE6546B64) & 0xFFFFFFFF
    tail = data[4 * nblocks:]
    k = 0
    if len(tail) >= 3:
        k ^= tail[2] << 16
    if len(tail) >= 2:
        k ^= tail[1] << 8
    if len(tail) >= 1:
        k ^= tail[0]
        k = (k * c1) & 0xFFFFFFFF
        k = _rotl32(k, 15)
        k = (k * c2) & 0xFFFFFFFF
        h ^= k
    h ^= n
    h ^= h >> 16
    h = (h * 0x85EBCA6B) & 0xFFFFFFFF
    h ^= h >> 13
    h = (h * 0xC2B2AE35) & 0xFFFFFFFF
    h ^= h >> 16
    return h


def cryptomatte_hash(name):
    """The ID stored (float-bitcast) in CryptoObject00.r for an object named `name`."""
    h = murmurhash3_x86_32(name.encode("utf-8"))
    exponent = (h >> 23) & 0xFF
    if exponent in (0, 255):
        h ^= 1 << 23
    return h


def cryptomatte_hex(name):
    return "%08x" % cryptomatte_hash(name)
