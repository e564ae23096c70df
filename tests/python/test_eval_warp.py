# SPDX-License-Identifier: Apache-2.0
"""End to end: the temporal error's warp W and disocclusion test in `crisp eval` on a moving scene
(ghosting: a sphere crossing a wall, 64x36, 3 frames, reference 4 samples, curve 1) in real Blender.
  * The renders hold renders/warp, unjittered 1-sample frames with depth, object IDs and a sidecar
    (the pass plan plan.TEMPORAL_ERROR), and results.json says W is taken at the pixel centres.
  * Frame 3's temporal error of 'none' and 'taa' is recomputed here from the files with numpy: motion
    reconstructed through libcrisp's C API (ctypes) from that set's depth, IDs and sidecars, the
    disocclusion mask by object ID and depth, a bilinear warp; it must equal the reported figure, and
    the same recomputation from the jittered set's geometry must not.
  * A renders/warp whose frames lack that geometry falls back to the jittered set's motion and says so
    on stderr and in results.json.
  * A resume with more methods renders a set of their own for those that read other passes
    (taa-improved's IDs and albedo), and keeps taa's set and frames: each method's render time is that
    of the passes it reads; a set whose frames lack the passes it lists is rendered again.
  * --jitter uniform on a resumed folder renders the jittered set again inside the pixel and keeps
    the other sets.
Needs Blender and the built CLI and library (CRISP_BUILD_DIR)."""

import contextlib
import ctypes
import json
import os
import shutil
import subprocess
import tempfile

import numpy as np
import pytest

from crisp_test_util import CRISP, LIBRARY, Lib, display

ARGS = ["--scene", "ghosting", "--resolution", "64x36", "--frames", "1-3", "--reference-samples", "4",
        "--curve", "1", "--methods", "none,taa"]

pytestmark = [
    pytest.mark.skipif(not os.path.isfile(CRISP), reason="crisp CLI not built at %s" % CRISP),
    pytest.mark.skipif(not os.path.isfile(LIBRARY), reason="libcrisp not built"),
    pytest.mark.skipif(shutil.which("blender") is None, reason="blender not installed"),
]


TAA_SET = "jittered-depth-motion-id"  # taa's input set on this moving scene (plan.render_set_name)


def crisp_eval(out, args=ARGS):
    p = subprocess.run([CRISP, "eval"] + args + ["-o", out], stdout=subprocess.PIPE, stderr=subprocess.PIPE,
                       timeout=600)
    assert p.returncode == 0, p.stderr.decode()[-3000:]
    return p.stderr.decode()


@contextlib.contextmanager
def copy_of(out):
    """A copy of an eval folder, modification times kept (so a resume there reuses what it can)."""
    copy = tempfile.mkdtemp(prefix="crisp_eval_warp_copy_")
    try:
        shutil.copytree(out, copy, dirs_exist_ok=True)
        yield copy
    finally:
        shutil.rmtree(copy, ignore_errors=True)


def mtime(folder, *parts):
    return os.path.getmtime(os.path.join(folder, *parts))


@pytest.fixture(scope="module")
def run():
    out = tempfile.mkdtemp(prefix="crisp_eval_warp_")
    stderr = crisp_eval(out)
    yield out, stderr
    shutil.rmtree(out, ignore_errors=True)


class Geometry:
    """A render's depth, object IDs and motion (reconstructed by libcrisp from the sidecars)."""

    def __init__(self, lib, folder, frame):
        c = lib.lib
        c.crispReconstructFrameMotion.argtypes = [ctypes.c_void_p, ctypes.c_void_p, ctypes.c_char_p, ctypes.c_char_p]
        path = os.path.join(folder, "frame_%04d.exr" % frame)
        f = c.crispLoadFrame(lib.ctx, path.encode())
        assert f, path
        try:
            self.w, self.h = c.crispGetFrameWidth(f), c.crispGetFrameHeight(f)
            previous = os.path.join(folder, "frame_%04d.json" % (frame - 1))
            c.crispReconstructFrameMotion(lib.ctx, f, previous.encode(), None)
            self.depth = self.plane(c, f, b"depth", 1, ctypes.c_float)
            self.ids = self.plane(c, f, b"id", 5, ctypes.c_uint32)
            self.motion = self.plane(c, f, b"motion", 4, ctypes.c_float)
        finally:
            c.crispReleaseFrame(f)

    def plane(self, c, f, role, fmt, ctype):
        kind = ctypes.c_int()
        ptr = c.crispGetFramePass(f, role, ctypes.byref(kind))
        assert ptr and kind.value == fmt, role
        n = {1: 1, 4: 4, 5: 1}[fmt]
        a = np.ctypeslib.as_array((ctype * (self.w * self.h * n)).from_address(ptr)).copy()
        return a.reshape(self.h, self.w, n) if n > 1 else a.reshape(self.h, self.w)


def warp(img, mx, my):
    """temporal_error.cpp warpPrevious: bilinear at p + motion, clamped to the border."""
    h, w = img.shape[:2]
    ys, xs = np.mgrid[0:h, 0:w]
    x = np.clip(xs + mx, 0, w - 1).astype(np.float32)
    y = np.clip(ys + my, 0, h - 1).astype(np.float32)
    x0, y0 = x.astype(int), y.astype(int)
    x1, y1 = np.minimum(x0 + 1, w - 1), np.minimum(y0 + 1, h - 1)
    fx, fy = (x - x0)[..., None], (y - y0)[..., None]
    top = img[y0, x0] * (1 - fx) + img[y0, x1] * fx
    bottom = img[y1, x0] * (1 - fx) + img[y1, x1] * fx
    return top * (1 - fy) + bottom * fy


def temporal_error(now, before, ref_now, ref_before, g, g_before):
    """METHODS.md: mean over valid pixels of |(out_t - W out_t-1) - (ref_t - W ref_t-1)|."""
    h, w = g.depth.shape
    mx, my = g.motion[..., 0], g.motion[..., 1]
    ys, xs = np.mgrid[0:h, 0:w]
    px, py = xs + mx, ys + my
    valid = (px >= -0.5) & (py >= -0.5) & (px <= w - 0.5) & (py <= h - 0.5)
    nx = np.clip(np.floor(px + 0.5).astype(int), 0, w - 1)  # lround for the in-picture taps
    ny = np.clip(np.floor(py + 0.5).astype(int), 0, h - 1)
    valid &= g.ids == g_before.ids[ny, nx]
    d, dp = g.depth, g_before.depth[ny, nx]
    bg, bgp = d >= 65504, dp >= 65504
    valid &= (bg == bgp) & (bg | (np.abs(d - dp) <= 0.1 * np.maximum(np.abs(d), 1e-6)))
    o, op = display(now), warp(display(before), mx, my)
    r, rp = display(ref_now), warp(display(ref_before), mx, my)
    e = np.abs((o - op) - (r - rp)).mean(-1)
    return float(e[valid].mean()), float(valid.mean())


def reported(out, name, frame):
    scene = json.load(open(os.path.join(out, "results.json")))["scenes"][0]
    m = next(m for m in scene["methods"] if m["name"] == name)
    return next(f["temporal_error"] for f in m["frames"] if f["frame"] == frame), scene


def test_unjittered_geometry_is_rendered_for_the_warp(run):
    out, _ = run
    scene = json.load(open(os.path.join(out, "renders", "scene.json")))
    assert scene["sets"]["warp"]["passes"] == ["color", "depth", "motion", "id"]
    assert scene["sets"]["warp"]["method"] == "temporal-error"
    assert "unjittered" not in scene["sets"], "no method here reads unjittered frames beyond colour"
    assert scene["inputs"] == {"none": "eevee_1", "taa": TAA_SET}  # no method reads renders/warp
    assert scene["sets"][TAA_SET]["passes"] == ["color", "depth", "motion", "id"]
    side = json.load(open(os.path.join(out, "renders", "warp", "frame_0002.json")))
    assert not side["jitter"]["enabled"] and side["jitter"]["x"] == 0 and side["jitter"]["y"] == 0
    jittered = json.load(open(os.path.join(out, "renders", TAA_SET, "frame_0002.json")))
    assert jittered["jitter"]["enabled"] and (jittered["jitter"]["x"], jittered["jitter"]["y"]) != (0, 0)
    _, results = reported(out, "none", 3)
    assert "pixel centres" in results["temporal_error_warp"]


def test_temporal_error_recomputed_from_the_pixel_centres(run):
    out, _ = run
    lib = Lib()
    ref = [lib.color(os.path.join(out, "renders", "reference_4", "frame_%04d.exr" % f)) for f in (2, 3)]
    geometry = {s: [Geometry(lib, os.path.join(out, "renders", s), f) for f in (2, 3)]
                for s in ("warp", TAA_SET)}
    for name in ("none", "taa"):
        test = [lib.color(os.path.join(out, "methods", name, "frame_%04d.exr" % f)) for f in (2, 3)]
        want, _ = reported(out, name, 3)
        got, valid = temporal_error(test[1], test[0], ref[1], ref[0], geometry["warp"][1],
                                    geometry["warp"][0])
        assert 0.5 < valid < 1 and want > 0, (name, valid, want)  # the sphere disoccludes some wall
        assert abs(got - want) <= 1e-3 * want, (name, got, want)
        # The jittered frames' geometry describes other points: another figure.
        other, _ = temporal_error(test[1], test[0], ref[1], ref[0], geometry[TAA_SET][1], geometry[TAA_SET][0])
        assert abs(other - want) > 1e-2 * want, (name, other, want)


def test_old_renders_fall_back_to_the_jittered_motion_and_say_so(run):
    out, _ = run
    with copy_of(out) as copy:
        # Frames that lost their geometry (colour only, as eevee_1's; the sidecars still list it).
        for f in (1, 2, 3):
            name = "frame_%04d.exr" % f
            shutil.copy(os.path.join(copy, "renders", "eevee_1", name), os.path.join(copy, "renders", "warp", name))
        stderr = crisp_eval(copy)
        assert "warp lacks depth" in stderr and "delete it" in stderr, stderr[-2000:]
        want, scene = reported(copy, "none", 3)
        assert "jittered 1-sample frames" in scene["temporal_error_warp"]
        lib = Lib()
        ref = [lib.color(os.path.join(copy, "renders", "reference_4", "frame_%04d.exr" % f)) for f in (2, 3)]
        test = [lib.color(os.path.join(copy, "methods", "none", "frame_%04d.exr" % f)) for f in (2, 3)]
        g = [Geometry(lib, os.path.join(copy, "renders", TAA_SET), f) for f in (2, 3)]
        got, _ = temporal_error(test[1], test[0], ref[1], ref[0], g[1], g[0])
        assert abs(got - want) <= 1e-3 * want, (got, want)


def test_warp_ids_stored_as_half_float_are_named(run):
    """Object IDs in half floats lose their hashes: renders/warp is then passed over as lacking
    them, and stderr says why (not as if the pass were missing)."""
    out, _ = run
    with copy_of(out) as copy:
        for f in (1, 2, 3):
            name = os.path.join(copy, "renders", "warp", "frame_%04d.exr" % f)
            info = subprocess.run(["oiiotool", "--info", "-v", name], capture_output=True, text=True, check=True)
            names = info.stdout.split("channel list:")[1].splitlines()[0].split(",")
            crypto = [c.strip().split(" ")[0] for c in names if "CryptoObject" in c]
            assert crypto, names
            half = name + ".half.exr"
            subprocess.run(["oiiotool", name, "-d", "float", *[a for c in crypto for a in ("-d", c + "=half")],
                            "-o", half], check=True, capture_output=True)
            os.replace(half, name)
        stderr = crisp_eval(copy)
        assert "warp lacks id (held unusable: pass" in stderr, stderr[-2000:]
        assert "object IDs would be lost" in stderr, stderr[-2000:]
        _, scene = reported(copy, "none", 3)
        assert "jittered 1-sample frames" in scene["temporal_error_warp"]


def test_resume_renders_a_set_for_other_passes_and_keeps_the_rest(run):
    out, _ = run
    with copy_of(out) as copy:
        renders = os.path.join(copy, "renders")
        before = {s: mtime(renders, s, "frame_0002.exr") for s in (TAA_SET, "warp")}
        made = {m: mtime(copy, "methods", m, "frame_0002.exr") for m in ("none", "taa")}
        crisp_eval(copy, ARGS[:-1] + ["none,taa,taa-improved"])
        scene = json.load(open(os.path.join(renders, "scene.json")))
        improved = scene["inputs"]["taa-improved"]
        assert improved == "jittered-depth-motion-id-albedo" and scene["inputs"]["taa"] == TAA_SET
        side = json.load(open(os.path.join(renders, improved, "frame_0002.json")))
        assert side["passes"] == ["color", "depth", "motion", "id", "albedo"], side["passes"]
        # taa's set and frames, and the warp, are kept: taa-improved's passes are not charged to taa.
        for s, t in before.items():
            assert mtime(renders, s, "frame_0002.exr") == t, s
        for m, t in made.items():
            assert mtime(copy, "methods", m, "frame_0002.exr") == t, m
        results = json.load(open(os.path.join(copy, "results.json")))["scenes"][0]
        entry = {m["name"]: m for m in results["methods"]}
        assert not entry["taa-improved"]["error"], entry["taa-improved"]["error"]
        assert entry["taa-improved"]["input"] == improved and entry["taa"]["input"] == TAA_SET
        # A set whose frames lack the passes it lists (an older run's, say) is rendered again.
        name = os.path.join(renders, TAA_SET, "frame_0002.exr")
        shutil.copy(os.path.join(renders, "eevee_1", "frame_0002.exr"), name)
        crisp_eval(copy, ARGS[:-1] + ["none,taa,taa-improved"])
        assert mtime(renders, TAA_SET, "frame_0002.exr") != before[TAA_SET]
        assert mtime(copy, "methods", "taa", "frame_0002.exr") != made["taa"]


def test_jitter_uniform_renders_the_jittered_set_again(run):
    """--jitter uniform on a resumed folder: the jittered set is rendered again inside the pixel, the
    temporal method made again from it, the warp set and the reference kept."""
    out, _ = run
    with copy_of(out) as copy:
        renders = os.path.join(copy, "renders")
        kept = {s: mtime(renders, s, "frame_0002.exr") for s in ("warp", "reference_4")}
        made = {m: mtime(copy, "methods", m, "frame_0002.exr") for m in ("none", "taa")}
        stderr = crisp_eval(copy, ARGS + ["--jitter", "uniform"])
        for f in (1, 2, 3):
            jitter = json.load(open(os.path.join(renders, TAA_SET, "frame_%04d.json" % f)))["jitter"]
            assert jitter["distribution"] == "uniform"
            assert -0.5 <= jitter["x"] <= 0.5 and -0.5 <= jitter["y"] <= 0.5
        for s, t in kept.items():
            assert mtime(renders, s, "frame_0002.exr") == t, s
        assert "methods/taa: frames whose input frame changed" in stderr
        assert mtime(copy, "methods", "taa", "frame_0002.exr") != made["taa"]
        assert mtime(copy, "methods", "none", "frame_0002.exr") == made["none"]
        scene = json.load(open(os.path.join(copy, "results.json")))["scenes"][0]
        assert scene["jitter_distribution"] == "uniform"


def test_report_says_the_filter_size_the_temporal_methods_filter_with(run):
    """The renders' Film > Filter Size spreads the jitter, filters EEVEE's reference and is the temporal
    methods' filterSize (runMethod, from the sidecars): results.json and the report's "How this was
    made" say it, as they say the jitter's distribution."""
    out, _ = run
    scene = json.load(open(os.path.join(out, "results.json")))["scenes"][0]
    assert scene["filter_size"] == 1.5, scene.get("filter_size")
    chromium = shutil.which("chromium") or shutil.which("chromium-browser")
    if chromium is None:
        return
    profile = tempfile.mkdtemp(prefix="crisp_chromium_")
    try:
        dom = subprocess.run([chromium, "--headless", "--no-sandbox", "--disable-gpu", "--no-first-run",
                              "--user-data-dir=" + profile, "--virtual-time-budget=3000", "--dump-dom",
                              "file://" + os.path.join(out, "report.html")],
                             stdout=subprocess.PIPE, stderr=subprocess.PIPE, timeout=120).stdout.decode()
    finally:
        shutil.rmtree(profile, ignore_errors=True)
    assert "crisp eval report: OK" in dom
    assert "Film &gt; Filter Size 1.5 px (the Blackman-Harris jitter" in dom
