# SPDX-License-Identifier: Apache-2.0
"""End-to-end pass I/O: render a tiny frame in the real Blender, load it through
the real C API (libcrisp.so via ctypes) and check it against what the scene
must look like: passes present, row order, depth background, normals and the
object IDs of both objects against their Cryptomatte hashes, computed here
independently and read from the file's own manifest.
"""
import ctypes
import json
import os
import shutil
import struct
import subprocess
import textwrap

import pytest

BLENDER = shutil.which("blender")
pytestmark = pytest.mark.skipif(BLENDER is None, reason="`blender` is not on PATH: cannot render a real frame")

WIDTH, HEIGHT = 64, 48
ORTHO_SCALE = 8.0  # world units across the wider (horizontal) side: 0.125 per pixel
BOX, BALL = "TopLeftBox", "RightBall"

# An orthographic camera at z = 10 looking down -Z, so pixel (row, col) sees
# world x = -4 + (col + 0.5) / 8, y = 3 - (row + 0.5) / 8.
#   BOX:  cube of side 2 centred at (-2.5, 1.5), top face at z = 1: cols 4..19, rows 4..19.
#   BALL: sphere of radius 1 centred at (2, -1): around col 48, row 32.
SCENE_SCRIPT = textwrap.dedent(
    """
    import bpy, sys
    out = sys.argv[sys.argv.index("--") + 1]
    bpy.ops.object.select_all(action="SELECT")
    bpy.ops.object.delete()
    scene = bpy.context.scene
    bpy.ops.mesh.primitive_cube_add(size=2, location=(-2.5, 1.5, 0))
    bpy.context.object.name = "{box}"
    bpy.ops.mesh.primitive_uv_sphere_add(radius=1, location=(2, -1, 0))
    bpy.context.object.name = "{ball}"
    bpy.ops.object.light_add(type="SUN", location=(0, 0, 20))
    bpy.ops.object.camera_add(location=(0, 0, 10), rotation=(0, 0, 0))
    cam = bpy.context.object
    cam.data.type = "ORTHO"
    cam.data.ortho_scale = {scale}
    scene.camera = cam
    scene.render.engine = "BLENDER_EEVEE"
    scene.eevee.taa_render_samples = 1
    scene.eevee.gi_cubemap_resolution = "64"
    scene.render.resolution_x = {w}
    scene.render.resolution_y = {h}
    scene.render.resolution_percentage = 100
    layer = scene.view_layers[0]
    layer.use_pass_z = True
    layer.use_pass_normal = True
    layer.use_pass_vector = True
    layer.use_pass_diffuse_color = True
    layer.use_pass_cryptomatte_object = True
    settings = scene.render.image_settings
    settings.file_format = "OPEN_EXR_MULTILAYER"
    settings.color_depth = "32"
    settings.exr_codec = "NONE"
    scene.render.filepath = out
    bpy.ops.render.render(write_still=True)
    """
).format(box=BOX, ball=BALL, scale=ORTHO_SCALE, w=WIDTH, h=HEIGHT)

CRISP_ERROR_IO = 5
CRISP_FORMAT_FLOAT, CRISP_FORMAT_FLOAT3, CRISP_FORMAT_FLOAT4, CRISP_FORMAT_UINT = 1, 3, 4, 5


def murmur3_32(data: bytes, seed: int = 0) -> int:
    """MurmurHash3_x86_32, written here from the algorithm's description so the
    library's C++ version is checked against an independent implementation."""
    mask = 0xFFFFFFFF
    c1, c2 = 0xCC9E2D51, 0x1B873593
    h = seed
    rotl = lambda x, r: ((x << r) | (x >> (32 - r))) & mask  # noqa: E731
    n = len(data) // 4
    for i in range(n):
        k = int.from_bytes(data[4 * i : 4 * i + 4], "little")
        k = rotl((k * c1) & mask, 15)
        h ^= (k * c2) & mask
        h = (rotl(h, 13) * 5 + 0xE6546B64) & mask
    tail = data[4 * n :]
    k = 0
    for i, b in enumerate(tail):
        k |= b << (8 * i)
    if tail:
        k = rotl((k * c1) & mask, 15)
        h ^= (k * c2) & mask
    h ^= len(data)
    h ^= h >> 16
    h = (h * 0x85EBCA6B) & mask
    h ^= h >> 13
    h = (h * 0xC2B2AE35) & mask
    return h ^ (h >> 16)


def cryptomatte_hash(name: str) -> int:
    """Cryptomatte spec: MurmurHash3 with seed 0, bit 23 flipped when the float
    exponent would be 0 or 255."""
    h = murmur3_32(name.encode("utf-8"))
    if ((h >> 23) & 0xFF) in (0, 255):
        h ^= 1 << 23
    return h


def exr_string_attributes(path):
    """String attributes of an EXR header (OpenEXR file layout: magic, version,
    then name\\0 type\\0 int32 size, value ... ending with an empty name)."""
    with open(path, "rb") as f:
        data = f.read(1 << 20)
    assert struct.unpack("<I", data[:4])[0] == 20000630, "not an OpenEXR file"
    pos, attrs = 8, {}
    while data[pos] != 0:
        end = data.index(b"\0", pos)
        name = data[pos:end].decode()
        tend = data.index(b"\0", end + 1)
        kind = data[end + 1 : tend].decode()
        (size,) = struct.unpack("<i", data[tend + 1 : tend + 5])
        value = data[tend + 5 : tend + 5 + size]
        if kind == "string":
            attrs[name] = value.decode("utf-8")
        pos = tend + 5 + size
    return attrs


class Crisp:
    def __init__(self):
        build = os.environ.get("CRISP_BUILD_DIR")
        if not build:
            pytest.fail("CRISP_BUILD_DIR is not set (run through ctest, or export it)")
        path = os.path.join(build, "lib", "libcrisp.so")
        assert os.path.exists(path), f"{path} not built"
        lib = ctypes.CDLL(path)
        lib.crispNewContext.restype = ctypes.c_void_p
        lib.crispReleaseContext.argtypes = [ctypes.c_void_p]
        lib.crispLoadFrame.restype = ctypes.c_void_p
        lib.crispLoadFrame.argtypes = [ctypes.c_void_p, ctypes.c_char_p]
        lib.crispReleaseFrame.argtypes = [ctypes.c_void_p]
        lib.crispGetFrameWidth.argtypes = [ctypes.c_void_p]
        lib.crispGetFrameHeight.argtypes = [ctypes.c_void_p]
        lib.crispGetFramePasses.restype = ctypes.c_char_p
        lib.crispGetFramePasses.argtypes = [ctypes.c_void_p]
        lib.crispGetFramePass.restype = ctypes.c_void_p
        lib.crispGetFramePass.argtypes = [ctypes.c_void_p, ctypes.c_char_p, ctypes.POINTER(ctypes.c_int)]
        lib.crispGetError.restype = ctypes.c_int
        lib.crispGetError.argtypes = [ctypes.POINTER(ctypes.c_char_p)]
        self.lib = lib
        self.ctx = lib.crispNewContext()
        assert self.ctx, self.error()

    def error(self):
        msg = ctypes.c_char_p()
        code = self.lib.crispGetError(ctypes.byref(msg))
        return code, (msg.value or b"").decode()

    def close(self):
        self.lib.crispReleaseContext(self.ctx)


class Pass:
    """A pass's packed pixels, indexed [row][col] (row 0 = top)."""

    def __init__(self, ptr, fmt, width, height):
        channels = {CRISP_FORMAT_FLOAT: 1, CRISP_FORMAT_FLOAT3: 3, CRISP_FORMAT_FLOAT4: 4, CRISP_FORMAT_UINT: 1}[fmt]
        ctype = ctypes.c_uint32 if fmt == CRISP_FORMAT_UINT else ctypes.c_float
        self.values = list(ctypes.cast(ptr, ctypes.POINTER(ctype * (width * height * channels))).contents)
        self.fmt, self.channels, self.width, self.height = fmt, channels, width, height

    def at(self, row, col):
        i = (row * self.width + col) * self.channels
        v = self.values[i : i + self.channels]
        return v[0] if self.channels == 1 else v


@pytest.fixture(scope="module")
def rendered(tmp_path_factory):
    tmp = tmp_path_factory.mktemp("blender_exr")
    script = tmp / "scene.py"
    script.write_text(SCENE_SCRIPT)
    out = tmp / "frame.exr"
    proc = subprocess.run(
        [BLENDER, "-b", "--factory-startup", "--python-exit-code", "1", "--python", str(script), "--", str(out)],
        capture_output=True, text=True, timeout=120,
    )
    assert proc.returncode == 0 and out.exists(), proc.stdout[-3000:] + proc.stderr[-3000:]
    return out


@pytest.fixture(scope="module")
def crisp():
    c = Crisp()
    yield c
    c.close()


@pytest.fixture(scope="module")
def frame(rendered, crisp):
    handle = crisp.lib.crispLoadFrame(crisp.ctx, str(rendered).encode())
    assert handle, crisp.error()
    lib = crisp.lib
    w, h = lib.crispGetFrameWidth(handle), lib.crispGetFrameHeight(handle)
    roles = lib.crispGetFramePasses(handle).decode().split(",")
    passes = {}
    for role in roles:
        fmt = ctypes.c_int(0)
        ptr = lib.crispGetFramePass(handle, role.encode(), ctypes.byref(fmt))
        assert ptr, crisp.error()
        passes[role] = Pass(ptr, fmt.value, w, h)
    lib.crispReleaseFrame(handle)
    return {"width": w, "height": h, "roles": roles, "passes": passes}


def pixel_of(x, y):
    """(row, col) of the pixel whose centre sees world (x, y)."""
    scale = WIDTH / ORTHO_SCALE
    return int((HEIGHT / 2 / scale - y) * scale), int((x + ORTHO_SCALE / 2) * scale)


BOX_PIXEL = pixel_of(-2.5, 1.5)  # centre of the box: top-left quadrant
BALL_PIXEL = pixel_of(2.0, -1.0)
EMPTY_PIXEL = pixel_of(-2.5, -1.5)  # the box mirrored top-bottom: nothing there


def test_passes_present(frame):
    assert (frame["width"], frame["height"]) == (WIDTH, HEIGHT)
    # EEVEE 3.4 ignores use_pass_vector (BLENDER.md); the others must be there.
    for role in ("color", "depth", "normal", "id", "albedo"):
        assert role in frame["roles"], frame["roles"]
    assert frame["passes"]["color"].fmt == CRISP_FORMAT_FLOAT4
    assert frame["passes"]["id"].fmt == CRISP_FORMAT_UINT


def test_colour_is_plausible(frame):
    color = frame["passes"]["color"]
    values = color.values
    assert all(v == v and abs(v) < 1e4 for v in values)  # finite
    assert all(v >= 0 for v in values)
    assert all(color.at(r, c)[3] == pytest.approx(1.0) for r in range(HEIGHT) for c in range(WIDTH))
    lit = color.at(*BOX_PIXEL)
    background = color.at(*EMPTY_PIXEL)
    assert max(lit[:3]) > 0.05, lit
    assert lit[:3] != background[:3]


def test_depth_and_normal(frame):
    depth, normal = frame["passes"]["depth"], frame["passes"]["normal"]
    assert depth.at(*EMPTY_PIXEL) >= 65504.0  # background (half-float max in 3.4)
    assert depth.at(*BOX_PIXEL) == pytest.approx(9.0, abs=0.01)  # camera z 10, box top z 1
    assert depth.at(*BALL_PIXEL) == pytest.approx(9.0, abs=0.05)  # sphere top, seen from above
    n = normal.at(*BOX_PIXEL)
    assert n == pytest.approx([0.0, 0.0, 1.0], abs=1e-3)


def test_row_order_top_down(frame):
    """The box is in the top-left: row 0 must be the top of the picture."""
    ids, depth = frame["passes"]["id"], frame["passes"]["depth"]
    row, col = BOX_PIXEL
    assert row < HEIGHT // 2 and col < WIDTH // 2
    assert ids.at(row, col) == cryptomatte_hash(BOX)
    assert ids.at(HEIGHT - 1 - row, col) == 0  # mirrored vertically: empty
    assert ids.at(row, WIDTH - 1 - col) == 0  # mirrored horizontally: empty
    # The box's edges where the geometry puts them (cols 4..19, rows 4..19).
    assert ids.at(4, 4) == cryptomatte_hash(BOX) and ids.at(19, 19) == cryptomatte_hash(BOX)
    assert ids.at(3, 10) == 0 and ids.at(20, 10) == 0 and ids.at(10, 3) == 0 and ids.at(10, 20) == 0
    assert depth.at(3, 10) >= 65504.0 and depth.at(4, 10) < 100.0


def test_ids_match_cryptomatte_hashes_and_manifest(frame, rendered):
    ids = frame["passes"]["id"]
    box, ball = cryptomatte_hash(BOX), cryptomatte_hash(BALL)
    assert ids.at(*BOX_PIXEL) == box
    assert ids.at(*BALL_PIXEL) == ball
    assert ids.at(*EMPTY_PIXEL) == 0
    assert set(ids.values) == {0, box, ball}

    # The file's own manifest agrees with the independent hash.
    attrs = exr_string_attributes(rendered)
    key = "cryptomatte/%07x/" % (murmur3_32(b"ViewLayer.CryptoObject") >> 4)
    assert attrs.get(key + "name") == "ViewLayer.CryptoObject", sorted(attrs)
    manifest = json.loads(attrs[key + "manifest"])
    assert int(manifest[BOX], 16) == box
    assert int(manifest[BALL], 16) == ball


def test_damaged_render_is_an_io_error(rendered, crisp, tmp_path):
    cut = tmp_path / "cut.exr"
    data = rendered.read_bytes()
    cut.write_bytes(data[: len(data) // 2])
    assert not crisp.lib.crispLoadFrame(crisp.ctx, str(cut).encode())
    code, message = crisp.error()
    assert code == CRISP_ERROR_IO
    assert str(cut) in message
    assert crisp.error()[0] == 0  # the error was cleared by the query
