# SPDX-License-Identifier: GPL-2.0-or-later
"""Is an OpenEXR file whole? Blender can leave a truncated file without an error (a disk that fills up
while it writes), and a render renamed into place must not be one. Read from the OpenEXR file layout
document ("The OpenEXR File Layout": magic, version and flags, header attributes up to an empty name,
the chunk offset table, then the chunks, each starting with its y and its data size). Pure Python: no
``bpy``, so plain tests reach it."""

import os
import struct

MAGIC = b"\x76\x2f\x31\x01"
TILED, MULTI_PART = 0x200, 0x1000
# Scanlines per chunk of each compression (the layout document's table): NONE, RLE, ZIPS 1; ZIP, PXR24
# 16; PIZ, B44, B44A, DWAA 32; DWAB 256.
LINES_PER_CHUNK = {0: 1, 1: 1, 2: 1, 3: 16, 4: 32, 5: 16, 6: 32, 7: 32, 8: 32, 9: 256}


def _cstr(buf, pos):
    end = buf.find(b"\0", pos)
    if end < 0:
        raise IndexError("a name runs past the bytes read")
    return buf[pos:end].decode("utf-8", "replace"), end + 1


def read_header(buf):
    """(flags, {attribute name: (type name, raw bytes)}, offset of the first byte after the header).
    Raises ValueError if buf is not the start of an OpenEXR file, or IndexError / struct.error if the
    header does not end inside buf."""
    if buf[:4] != MAGIC:
        raise ValueError("not an OpenEXR file")
    flags = struct.unpack_from("<I", buf, 4)[0]
    pos, attrs = 8, {}
    while True:
        name, pos = _cstr(buf, pos)
        if not name:
            return flags, attrs, pos
        kind, pos = _cstr(buf, pos)
        size = struct.unpack_from("<i", buf, pos)[0]
        if size < 0 or pos + 4 + size > len(buf):
            raise IndexError("attribute '%s' runs past the bytes read" % name)
        attrs[name] = (kind, bytes(buf[pos + 4:pos + 4 + size]))
        pos += 4 + size


def incomplete(path):
    """None if the scanline EXR at path holds every chunk its header announces, else what is wrong
    (named for a message). Tiled and multi-part files are not checked (Blender writes neither)."""
    size = os.path.getsize(path)
    with open(path, "rb") as f:
        buf = f.read(min(size, 1 << 16))
        while True:
            try:
                flags, attrs, pos = read_header(buf)
                break
            except (IndexError, struct.error):
                if len(buf) == size:
                    return "its header ends early (%d bytes in all)" % size
                buf += f.read(min(size - len(buf), len(buf)))
            except ValueError as e:
                return str(e)
        if flags & (TILED | MULTI_PART):
            return None
        if "dataWindow" not in attrs or "compression" not in attrs:
            return "its header has no dataWindow or compression"
        y0, y1 = struct.unpack_from("<4i", attrs["dataWindow"][1])[1::2]
        chunks = -(-(y1 - y0 + 1) // LINES_PER_CHUNK.get(attrs["compression"][1][0], 1))
        f.seek(pos)
        table = f.read(8 * chunks)
        if len(table) < 8 * chunks:
            return "it ends inside its table of %d chunks (%d bytes in all)" % (chunks, size)
        offsets = struct.unpack("<%dQ" % chunks, table)
        if any(o < pos + 8 * chunks or o + 8 > size for o in offsets):
            return "its table points past its end (%d bytes): chunks were never written" % size
        last = max(offsets)
        f.seek(last)
        data_size = struct.unpack("<i", f.read(8)[4:])[0]
        if data_size < 0 or last + 8 + data_size > size:
            return "its last chunk ends after the file (%d of %d bytes)" % (size, last + 8 + max(data_size, 0))
    return None
