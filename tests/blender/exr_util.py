# SPDX-License-Identifier: GPL-2.0-or-later
"""Test helper: a minimal reader of uncompressed scanline OpenEXR files (what the add-on writes:
codec NONE), written from the OpenEXR file layout document ("The OpenEXR File Layout": magic,
version, header attributes, line offset table, scanline blocks with channels in chlist order).
An independent cross-check of the library's reader; not used by the add-on."""

import struct

PIXEL_TYPES = {0: ("I", 4), 1: ("e", 2), 2: ("f", 4)}


def _cstr(buf, pos):
    end = buf.index(b"\0", pos)
    return buf[pos:end].decode("utf-8"), end + 1


def read_header(buf):
    if buf[:4] != b"\x76\x2f\x31\x01":
        raise ValueError("not an OpenEXR file")
    flags = struct.unpack_from("<I", buf, 4)[0]
    if flags & 0x200 or flags & 0x1000:
        raise ValueError("tiled or multi-part EXR not supported by this helper")
    pos, attrs = 8, {}
    while True:
        name, pos = _cstr(buf, pos)
        if not name:
            break
        kind, pos = _cstr(buf, pos)
        size = struct.unpack_from("<i", buf, pos)[0]
        pos += 4
        raw = buf[pos:pos + size]
        pos += size
        if kind == "chlist":
            chans, p = [], 0
            while raw[p] != 0:
                cname, p = _cstr(raw, p)
                ptype = struct.unpack_from("<i", raw, p)[0]
                chans.append((cname, ptype))
                p += 16
            attrs[name] = chans
        elif kind == "box2i":
            attrs[name] = struct.unpack("<4i", raw)
        elif kind == "compression":
            attrs[name] = raw[0]
        elif kind == "string":
            attrs[name] = raw.decode("utf-8", "replace")
        else:
            attrs[name] = raw
    return attrs, pos


def read(path):
    """(header dict, {channel: flat list of values, row 0 = top}, width, height)."""
    with open(path, "rb") as f:
        buf = f.read()
    attrs, pos = read_header(buf)
    if attrs.get("compression", 0) != 0:
        raise ValueError("%s is compressed; this helper reads codec NONE only" % path)
    x0, y0, x1, y1 = attrs["dataWindow"]
    w, h = x1 - x0 + 1, y1 - y0 + 1
    pos += 8 * h  # line offset table; blocks follow in order
    chans = attrs["channels"]
    data = {c: [] for c, _ in chans}
    for _ in range(h):
        pos += 8  # y, data size
        for c, t in chans:
            fmt, size = PIXEL_TYPES[t]
            data[c].extend(struct.unpack_from("<%d%s" % (w, fmt), buf, pos))
            pos += size * w
    return attrs, data, w, h


def channels(path):
    with open(path, "rb") as f:
        buf = f.read(1 << 16)
    attrs, _ = read_header(buf)
    return [c for c, _ in attrs["channels"]], attrs
