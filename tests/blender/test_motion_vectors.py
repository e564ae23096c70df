# SPDX-License-Identifier: GPL-2.0-or-later
"""Motion vectors reconstructed by the library (crispReconstructFrameMotion: depth + Cryptomatte IDs +
the add-on's sidecars) against Cycles' own Vector pass of the same frames, in this Blender.

* spinning_cube at 96x54, frames 1-3, rendered twice with the add-on's render_frames: Cycles (1
  sample, 0.01 px box filter, Vector + Depth + CryptoObject + sidecars, no jitter) and EEVEE (1 sample,
  Depth in half float on 3.4 + CryptoObject + sidecars, per-frame Halton jitter as temporal methods
  render it). Motion is reconstructed from Cycles' float depth and from EEVEE's half-float depth and
  compared with Cycles' Vector over pixels valid in both (same object ID, not background, valid flag);
  a third, unjittered EEVEE render separates the half-float error from the jitter's:
  previous pair (xy) of frames 2 and 3, next pair (zw) of frame 2. Median and 95th percentile of the
  error length in pixels are printed; the Cycles-depth figures are asserted against stated bounds.
* A turning camera: the rebuilt motion of the background (a direction: moved by the camera's rotation)
  against that of a far wall in the same pixels; Cycles' Vector leaves the background at 0.
* A moving-quad probe: an orthographic camera and a quad moving (+2, +1) px/frame (x right, y up).
  Cycles' raw Vector pass must read (-2, -1, -2, -1) (BLENDER.md), so a Blender change of the sign
  convention fails here; the library's reader must turn it into (-2, +1, -2, +1) (y down), and the
  reconstruction from Cycles' and EEVEE's depth must give the same.

Not covered (the reconstruction is exact for rigid motion only): deforming meshes (armatures, shape
keys, simulations, modifiers), moving textures, camera lens/sensor animation other than through the
recorded projection, transparency and anything behind the first surface; only 1-sample renders (one
surface per pixel).
"""

import ctypes
import math
import os
import sys
import tempfile
import time
import unittest

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import harness  # noqa: E402

import bpy  # noqa: E402
import common  # noqa: E402  (test_scenes/common.py)
import exr_util  # noqa: E402
from crisp import native  # noqa: E402
from crisp import plan as plan_mod  # noqa: E402
from crisp import render  # noqa: E402

LIB_OK, LIB_WHY = harness.library_usable()
SIZE = (96, 54)
FRAMES = (1, 2, 3)
# Bounds (pixels). From Cycles' own float depth the reconstruction and Cycles apply the same transforms
# to the same points: what is left is float32 rounding and the 0.005 px spread of Cycles' sample in its
# 0.01 px box filter (measured: median 2e-5 px, 95th percentile 2.5e-5 px).
CYCLES_MEDIAN_BOUND, CYCLES_P95_BOUND = 0.01, 0.02
# EEVEE unjittered samples the same points; its half-float depth moves them along their rays (see
# native/motion/reconstruct.cpp; measured median 0.003 px, 95th percentile 0.007 px).
EEVEE_MEDIAN_BOUND, EEVEE_P95_BOUND = 0.02, 0.05
# EEVEE jittered samples other points than Cycles' pixel centres (by up to ~0.7 px), so the vectors
# differ by the motion gradient over that distance, and at silhouettes a jittered sample can hit
# another part of the object: no 95th-percentile bound (measured median 0.009 px, 95th 0.067 px). A
# jitter leak would offset every vector by the jitter difference of two frames (tenths of a pixel).
EEVEE_JITTERED_MEDIAN_BOUND = 0.05
FLAG_PREVIOUS_VALID, FLAG_NEXT_VALID = 1, 2


def motion_plan(passes, jitter, motion_source):
    return plan_mod.Plan(method="motion-check", passes=list(passes), reasons={p: "motion check" for p in passes},
                         skipped={}, jitter=jitter, motion_source=motion_source)


CYCLES_PLAN = motion_plan(("color", "depth", "motion", "id"), False, "renderer")
EEVEE_PLAN = motion_plan(("color", "depth", "id"), True, "reconstruct")
EEVEE_UNJITTERED_PLAN = motion_plan(("color", "depth", "id"), False, "reconstruct")


def reconstruct(ctx, frame, previous_json, next_json):
    """crispReconstructFrameMotion through ctypes (the add-on's native.py does not declare it)."""
    fn = native.load().dll.crispReconstructFrameMotion
    fn.restype = None
    fn.argtypes = [ctypes.c_void_p, ctypes.c_void_p, ctypes.c_char_p, ctypes.c_char_p]
    fn(ctx.handle, frame.handle, previous_json.encode(), next_json.encode() if next_json else None)
    msg = ctypes.c_char_p()
    code = native.call("crispGetError", ctypes.byref(msg))
    if code:
        raise native.CrispError("crispReconstructFrameMotion: %s" % (msg.value or b"").decode())


def percentile(values, q):
    s = sorted(values)
    if not s:
        return float("nan")
    k = (len(s) - 1) * q
    lo = int(math.floor(k))
    hi = min(lo + 1, len(s) - 1)
    return s[lo] + (s[hi] - s[lo]) * (k - lo)


def sidecar(folder, f):
    return os.path.join(folder, "frame_%04d.json" % f)


def exr(folder, f):
    return os.path.join(folder, "frame_%04d.exr" % f)


class Passes:
    """One frame's passes as flat lists (read through the library), optionally with motion rebuilt."""

    def __init__(self, ctx, folder, f, rebuild=False, first=FRAMES[0], last=FRAMES[-1]):
        with native.Frame(ctx, exr(folder, f)) as fr:
            self.width, self.height = fr.width, fr.height
            self.roles = fr.passes()
            if rebuild:
                reconstruct(ctx, fr, sidecar(folder, f - 1), sidecar(folder, f + 1) if f < last else None)
                self.flags, _ = fr.pass_values("motion_flags")
            self.motion, _ = fr.pass_values("motion")
            self.depth, _ = fr.pass_values("depth")
            self.id, _ = fr.pass_values("id") if "id" in self.roles else ([0] * (fr.width * fr.height), 1)


def compare(truth, rebuilt, pairs):
    """Error lengths (px) of rebuilt vs truth motion over pixels valid in both, per pair 'xy'/'zw'."""
    errors, lengths = [], []
    for i in range(truth.width * truth.height):
        if truth.id[i] == 0 or truth.id[i] != rebuilt.id[i] or truth.depth[i] >= 65504.0:
            continue
        for pair in pairs:
            bit, c = (FLAG_PREVIOUS_VALID, 0) if pair == "xy" else (FLAG_NEXT_VALID, 2)
            if not rebuilt.flags[i] & bit:
                continue
            tx, ty = truth.motion[4 * i + c], truth.motion[4 * i + c + 1]
            rx, ry = rebuilt.motion[4 * i + c], rebuilt.motion[4 * i + c + 1]
            errors.append(math.hypot(rx - tx, ry - ty))
            if os.environ.get("CRISP_MOTION_DEBUG") and errors[-1] > 0.3:
                print("  debug: pixel (%d,%d) %s truth (%.3f,%.3f) rebuilt (%.3f,%.3f) depth %.4f/%.4f" % (
                    i % truth.width, i // truth.width, pair, tx, ty, rx, ry, truth.depth[i], rebuilt.depth[i]))
            lengths.append(math.hypot(tx, ty))
    return errors, lengths


@unittest.skipUnless(LIB_OK, "library not usable: " + LIB_WHY)
class SpinningCubeAgainstCycles(unittest.TestCase):
    @classmethod
    def setUpClass(cls):
        cls.tmp = tempfile.TemporaryDirectory()
        scene = harness.build_scene("spinning_cube")
        scene.render.resolution_x, scene.render.resolution_y = SIZE
        cls.cycles_dir = os.path.join(cls.tmp.name, "cycles")
        cls.eevee_dir = os.path.join(cls.tmp.name, "eevee")
        cls.eevee_plain_dir = os.path.join(cls.tmp.name, "eevee_unjittered")
        watched = [(scene.render, "engine"), (scene.cycles, "samples"), (scene.cycles, "filter_width"),
                   (scene.cycles, "pixel_filter_type"), (scene.cycles, "use_denoising"),
                   (scene.view_layers[0], "use_pass_vector"), (scene.render, "filepath")]
        cls.before = [getattr(o, a) for o, a in watched]
        t0 = time.perf_counter()
        render.render_frames(scene, CYCLES_PLAN, FRAMES, cls.cycles_dir, engine="CYCLES")
        t1 = time.perf_counter()
        cls.after = [getattr(o, a) for o, a in watched]
        render.render_frames(scene, EEVEE_PLAN, FRAMES, cls.eevee_dir)
        render.render_frames(scene, EEVEE_UNJITTERED_PLAN, FRAMES, cls.eevee_plain_dir)
        print("motion: rendered %d frames %dx%d with Cycles in %.2f s, EEVEE in %.2f s"
              % (len(FRAMES), SIZE[0], SIZE[1], t1 - t0, time.perf_counter() - t1), flush=True)
        cls.ctx = native.Context()

    @classmethod
    def tearDownClass(cls):
        cls.ctx.close()
        cls.tmp.cleanup()

    def test_cycles_settings_restored(self):
        self.assertEqual(self.after, self.before)

    def check(self, folder, label, median_bound, p95_bound=None):
        errors, lengths = [], []
        for f in FRAMES[1:]:
            truth = Passes(self.ctx, self.cycles_dir, f)
            self.assertIn("motion", truth.roles, "Cycles wrote no Vector pass")
            rebuilt = Passes(self.ctx, folder, f, rebuild=True)
            e, n = compare(truth, rebuilt, ("xy", "zw") if f < FRAMES[-1] else ("xy",))
            errors += e
            lengths += n
        self.assertGreater(len(errors), 500, "too few pixels valid in both to compare")
        median, p95 = percentile(errors, 0.5), percentile(errors, 0.95)
        print("motion: %s depth vs Cycles Vector: median %.2e px, 95th percentile %.2e px, max %.2e px over %d "
              "vectors (Cycles |v|: median %.2f px, max %.2f px)" % (label, median, p95, max(errors), len(errors),
                                                                  percentile(lengths, 0.5), max(lengths)),
              flush=True)
        # The comparison means something only if things move by pixels.
        self.assertGreater(percentile(lengths, 0.5), 0.5)
        self.assertLess(median, median_bound)
        if p95_bound is not None:
            self.assertLess(p95, p95_bound)
        return median, p95

    def test_cycles_depth_reconstruction_matches_cycles_vector(self):
        self.check(self.cycles_dir, "Cycles (float)", CYCLES_MEDIAN_BOUND, CYCLES_P95_BOUND)

    def test_eevee_depth_reconstruction_matches_cycles_vector(self):
        import json
        jitters = []
        for f in FRAMES:
            with open(sidecar(self.eevee_dir, f)) as fh:
                j = json.load(fh)["jitter"]
            jitters.append((j["x"], j["y"]))
        self.assertTrue(all(abs(x) + abs(y) > 1e-3 for x, y in jitters), "EEVEE frames were not jittered")
        self.check(self.eevee_dir, "EEVEE (half float, jittered)", EEVEE_JITTERED_MEDIAN_BOUND)

    def test_eevee_unjittered_depth_reconstruction_matches_cycles_vector(self):
        """Without jitter EEVEE samples the same points as Cycles: what is left is half-float depth."""
        self.check(self.eevee_plain_dir, "EEVEE (half float, unjittered)", EEVEE_MEDIAN_BOUND, EEVEE_P95_BOUND)

    def test_eevee_depth_is_half_float(self):
        """The premise of the EEVEE figures: 3.4 computes Depth in half float (every value exactly a
        half, background 65504) although the file stores it as float32; Cycles' depth is float."""
        import struct

        def depth_values(folder):
            _, data, _, _ = exr_util.read(exr(folder, 2))
            names = [n for n in data if n.endswith("Depth.Z")]
            self.assertEqual(len(names), 1, list(data))
            return data[names[0]]

        def is_half(v):
            return struct.unpack("<e", struct.pack("<e", v))[0] == v

        eevee = depth_values(self.eevee_dir)
        cycles = [v for v in depth_values(self.cycles_dir) if v < 65504.0]
        self.assertTrue(cycles)
        self.assertLess(sum(map(is_half, cycles)), len(cycles) // 2, "Cycles depth looks half-quantised")
        if bpy.app.version < (4, 2, 0):
            self.assertIn(65504.0, eevee, "EEVEE 3.x background should read 65504")
            self.assertTrue(all(is_half(v) for v in eevee), "EEVEE 3.x depth is no longer half-quantised")


def build_probe():
    """Orthographic camera looking down -Z at a 1x1 quad moving (+0.2, +0.1) units/frame = (+2, +1) px."""
    scene = common.reset(1, 3, resolution=(32, 32))
    common.world((0.1, 0.1, 0.1))
    quad = common.mesh_object("Probe", "plane", common.emission("ProbeWhite", (1, 1, 1)), size=1.0)
    common.keyframes(quad, "location", [(-0.2, -0.1, 0.0), (0.2, 0.1, 0.0)], [1, 3])
    cam = common.camera((0, 0, 10), (0, 0, 0), ortho_scale=3.2)
    cam.rotation_euler = (0.0, 0.0, 0.0)
    return scene


@unittest.skipUnless(LIB_OK, "library not usable: " + LIB_WHY)
class MovingQuadProbe(unittest.TestCase):
    @classmethod
    def setUpClass(cls):
        cls.tmp = tempfile.TemporaryDirectory()
        scene = build_probe()
        cls.cycles_dir = os.path.join(cls.tmp.name, "cycles")
        cls.eevee_dir = os.path.join(cls.tmp.name, "eevee")
        render.render_frames(scene, CYCLES_PLAN, FRAMES, cls.cycles_dir, engine="CYCLES")
        render.render_frames(scene, EEVEE_PLAN, FRAMES, cls.eevee_dir)
        cls.ctx = native.Context()
        # Quad centre at frame 2: world origin = image centre; pixels (14..17, 14..17) lie well inside.
        cls.inner = [(x, y) for y in range(13, 19) for x in range(13, 19)]

    @classmethod
    def tearDownClass(cls):
        cls.ctx.close()
        cls.tmp.cleanup()

    def test_cycles_vector_sign_convention(self):
        _, data, w, h = exr_util.read(exr(self.cycles_dir, 2))
        names = {n.rsplit(".", 1)[-1]: n for n in data if ".Vector." in n}
        self.assertEqual(sorted(names), ["W", "X", "Y", "Z"], list(data))
        for x, y in self.inner:
            raw = [data[names[c]][y * w + x] for c in "XYZW"]  # as stored: y up
            for got, want in zip(raw, (-2.0, -1.0, -2.0, -1.0)):
                self.assertAlmostEqual(got, want, delta=0.02, msg="pixel (%d,%d): Vector %r" % (x, y, raw))

    def test_library_reads_vector_y_down(self):
        p = Passes(self.ctx, self.cycles_dir, 2)
        for x, y in self.inner:
            v = p.motion[4 * (y * p.width + x): 4 * (y * p.width + x) + 4]
            for got, want in zip(v, (-2.0, 1.0, -2.0, 1.0)):
                self.assertAlmostEqual(got, want, delta=0.02)

    def test_reconstruction_of_the_probe(self):
        for folder in (self.cycles_dir, self.eevee_dir):
            p = Passes(self.ctx, folder, 2, rebuild=True)
            for x, y in self.inner:
                i = y * p.width + x
                self.assertEqual(p.flags[i], FLAG_PREVIOUS_VALID | FLAG_NEXT_VALID, folder)
                for got, want in zip(p.motion[4 * i: 4 * i + 4], (-2.0, 1.0, -2.0, 1.0)):
                    self.assertAlmostEqual(got, want, delta=1e-3, msg="%s (%d,%d)" % (folder, x, y))
            corner = 0  # background
            self.assertEqual(p.flags[corner], 4)
            self.assertEqual(p.motion[0:4], [0.0, 0.0, 0.0, 0.0])


def build_turning_camera(backdrop):
    """A perspective camera turning about its own centre (pan, tilt) over frames 1-3, over the world's
    background or, with `backdrop`, a wall 400 units away that fills the view: no parallax either way."""
    scene = common.reset(1, 3, resolution=(64, 36))
    common.world((0.2, 0.3, 0.5))
    cam = common.camera((0, 0, 1.5), (0, 10, 1.5), lens=35)
    cam.data.clip_end = 1000.0
    common.keyframes(cam, "rotation_euler", [(1.45, 0.0, 0.12), (1.62, 0.0, -0.1)], [1, 3])
    if backdrop:
        wall = common.mesh_object("Wall", "plane", common.emission("Wall", (1, 1, 1)), size=4000.0)
        wall.location, wall.rotation_euler = (0, 400, 0), (1.5708, 0, 0)
    return scene


@unittest.skipUnless(LIB_OK, "library not usable: " + LIB_WHY)
class TurningCameraBackground(unittest.TestCase):
    """Cycles' Vector pass leaves the background at 0, so the truth is a point at a finite depth in the same
    pixel: a camera turning about its centre moves every point by one vector whatever its depth, and the
    rebuilt background of EEVEE's jittered renders, from the sidecars as written, must move as the wall does."""

    @classmethod
    def setUpClass(cls):
        cls.tmp = tempfile.TemporaryDirectory()
        cls.dirs = {}
        for backdrop in (False, True):
            cls.dirs[backdrop] = os.path.join(cls.tmp.name, "wall" if backdrop else "sky")
            render.render_frames(build_turning_camera(backdrop), EEVEE_PLAN, FRAMES, cls.dirs[backdrop])
        cls.ctx = native.Context()

    @classmethod
    def tearDownClass(cls):
        cls.ctx.close()
        cls.tmp.cleanup()

    def test_the_background_turns_with_the_camera(self):
        sky, wall = (Passes(self.ctx, self.dirs[b], 2, rebuild=True) for b in (False, True))
        self.assertTrue(all(d >= 65504.0 for d in sky.depth), "the sky render should be all background")
        self.assertTrue(all(d < 65504.0 for d in wall.depth), "the wall should fill the view")
        errors, lengths = [], []
        for i in range(sky.width * sky.height):
            self.assertEqual(sky.flags[i], 4 | FLAG_PREVIOUS_VALID | FLAG_NEXT_VALID)
            self.assertEqual(wall.flags[i], FLAG_PREVIOUS_VALID | FLAG_NEXT_VALID)
            for c in (0, 2):
                errors.append(math.hypot(sky.motion[4 * i + c] - wall.motion[4 * i + c],
                                         sky.motion[4 * i + c + 1] - wall.motion[4 * i + c + 1]))
                lengths.append(math.hypot(wall.motion[4 * i + c], wall.motion[4 * i + c + 1]))
        print("motion: background vs a wall 400 units away, turning camera: max %.2e px (|v| median %.2f px)"
              % (max(errors), percentile(lengths, 0.5)), flush=True)
        self.assertGreater(percentile(lengths, 0.5), 1.0, "the camera should turn the view by pixels")
        self.assertLess(max(errors), 0.01)


if __name__ == "__main__":
    harness.run(SpinningCubeAgainstCycles, MovingQuadProbe, TurningCameraBackground)
