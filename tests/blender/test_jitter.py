# SPDX-License-Identifier: GPL-2.0-or-later
"""Sub-pixel jitter, measured: an orthographic camera looks at an emissive plane whose colour is its
own position (R = x, G = y, linear ramps). At 1 sample a pixel's value is the ramp at its sample
point, so (jittered - unjittered) / (ramp step per pixel) is the sample shift in pixels, to ~1e-4 px.
Checks both jitter distributions, the sign convention (x right, y up) and the sidecar records."""

import json
import math
import os
import sys
import tempfile
import unittest

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import harness  # noqa: E402

import bpy  # noqa: E402
import common  # noqa: E402  (test_scenes/common.py)
import exr_util  # noqa: E402
from crisp import plan, render  # noqa: E402

W, H = 64, 36


def ramp_scene():
    scene = common.reset(1, 8, (W, H))
    common.world((0, 0, 0))
    mat = bpy.data.materials.new("Ramp")
    mat.use_nodes = True
    nodes, links = mat.node_tree.nodes, mat.node_tree.links
    nodes.remove(nodes["Principled BSDF"])
    coords = nodes.new("ShaderNodeTexCoord")
    em = nodes.new("ShaderNodeEmission")
    links.new(coords.outputs["Generated"], em.inputs["Color"])
    links.new(em.outputs["Emission"], nodes["Material Output"].inputs["Surface"])
    common.mesh_object("Ramp", "plane", mat, size=4.0)
    cam = common.camera((0, 0, 5), (0, 0, 0), ortho_scale=2.0)
    cam.rotation_euler = (0, 0, 0)  # looking down -Z, image x = world x, image up = world y
    return scene


def channel(data, name):
    key = next(k for k in data if k.endswith("Combined." + name))
    return data[key]


def measure(plain, jittered):
    """Mean sample shift (dx, dy) in pixels from the two ramps, over interior pixels."""
    r0, g0, r1, g1 = channel(plain, "R"), channel(plain, "G"), channel(jittered, "R"), channel(jittered, "G")
    step_x = sum(r0[y * W + x + 1] - r0[y * W + x] for y in range(H) for x in range(W - 1)) / (H * (W - 1))
    # rows are top-down in the file: the row above has the larger y
    step_y = sum(g0[y * W + x] - g0[(y + 1) * W + x] for y in range(H - 1) for x in range(W)) / ((H - 1) * W)
    inner = [y * W + x for y in range(2, H - 2) for x in range(2, W - 2)]
    dx = sum(r1[i] - r0[i] for i in inner) / len(inner) / step_x
    dy = sum(g1[i] - g0[i] for i in inner) / len(inner) / step_y
    return dx, dy


class JitterTest(unittest.TestCase):
    @classmethod
    def setUpClass(cls):
        cls.scene = ramp_scene()
        cls.tmp = tempfile.TemporaryDirectory()
        facts = plan.scene_facts(cls.scene, 1, 3)
        still = plan.make_plan("none", facts)
        render.render_frames(cls.scene, still, [1], os.path.join(cls.tmp.name, "plain"))
        cls.plain = exr_util.read(os.path.join(cls.tmp.name, "plain", "frame_0001.exr"))[1]
        cls.jittered_plan = plan.make_plan("taa", facts)
        assert cls.jittered_plan.jitter

    @classmethod
    def tearDownClass(cls):
        cls.tmp.cleanup()

    def check(self, distribution, frames):
        out = os.path.join(self.tmp.name, distribution)
        render.render_frames(self.scene, self.jittered_plan, frames, out, jitter_distribution=distribution)
        for f in frames:
            want_x, want_y, index = render.jitter_offset(f, distribution, self.scene.render.filter_size)
            self.assertGreater(abs(want_x) + abs(want_y), 0.05, "a jitter worth measuring")
            got_x, got_y = measure(self.plain, exr_util.read(os.path.join(out, "frame_%04d.exr" % f))[1])
            with self.subTest(distribution=distribution, frame=f):
                self.assertAlmostEqual(got_x, want_x, delta=0.01)
                self.assertAlmostEqual(got_y, want_y, delta=0.01)
            with open(os.path.join(out, "frame_%04d.json" % f)) as fh:
                side = json.load(fh)
            self.assertEqual(side["frame"], f)
            self.assertEqual(side["jitter"]["distribution"], distribution)
            self.assertEqual(side["jitter"]["index"], index)
            self.assertAlmostEqual(side["jitter"]["x"], want_x, places=9)
            # Orthographic projection: the jitter shifts NDC x by 2 dx / W (ortho uses m[0][3]).
            p, q = side["camera"]["projection"], side["camera"]["projection_unjittered"]
            self.assertAlmostEqual(abs(p[0][3] - q[0][3]), abs(2 * want_x / W), places=5)
        self.assertEqual((self.scene.camera.data.shift_x, self.scene.camera.data.shift_y), (0.0, 0.0))

    def test_uniform_halton(self):
        self.check("uniform", [1, 2])

    def test_blackman_harris_halton(self):
        self.check("blackman-harris", [3, 4])

    def test_fixed_sensor_fit(self):
        """A camera whose sensor fit is fixed to the short or the long side of the non-square image: the
        camera shift per pixel is along that side (render.shift_per_pixel), so the samples move by the
        requested jitter with either fit (a shift taken along the other side is 64/36 too large or small)."""
        cam = self.scene.camera.data
        self.addCleanup(setattr, cam, "sensor_fit", cam.sensor_fit)
        still = plan.make_plan("none", plan.scene_facts(self.scene, 1, 3))
        for fit in ("HORIZONTAL", "VERTICAL"):
            cam.sensor_fit = fit
            out = os.path.join(self.tmp.name, fit)
            render.render_frames(self.scene, still, [1], os.path.join(out, "plain"))
            render.render_frames(self.scene, self.jittered_plan, [1], out, jitter_distribution="uniform")
            want_x, want_y, _ = render.jitter_offset(1, "uniform", self.scene.render.filter_size)
            got_x, got_y = measure(exr_util.read(os.path.join(out, "plain", "frame_0001.exr"))[1],
                                   exr_util.read(os.path.join(out, "frame_0001.exr"))[1])
            with self.subTest(sensor_fit=fit):
                self.assertAlmostEqual(got_x, want_x, delta=0.01)
                self.assertAlmostEqual(got_y, want_y, delta=0.01)

    def test_animated_shift_keeps_the_jitter(self):
        """A shift animated by keyframes (x) and by a driver (y): the render evaluates the animation again,
        which would put the shift back over the jitter. Each frame's samples move by the animated shift
        plus the jitter (measured against an unjittered render with the same animation), the curves are
        unmuted afterwards and the shift is the animation's again."""
        cam = self.scene.camera.data
        cam.keyframe_insert("shift_x", frame=1)
        cam.shift_x = 0.02  # 0.64 px at 64 px across an orthographic scale of 2
        cam.keyframe_insert("shift_x", frame=3)
        driver = cam.driver_add("shift_y")
        driver.driver.expression = "0.01 * frame"

        def clean_up():
            cam.driver_remove("shift_y")
            cam.animation_data_clear()
            cam.shift_x = cam.shift_y = 0.0
        self.addCleanup(clean_up)
        out = os.path.join(self.tmp.name, "animated")
        still = plan.make_plan("none", plan.scene_facts(self.scene, 1, 3))
        render.render_frames(self.scene, still, [2, 3], os.path.join(out, "plain"))
        render.render_frames(self.scene, self.jittered_plan, [2, 3], out, jitter_distribution="uniform")
        for f in (2, 3):
            want_x, want_y, _ = render.jitter_offset(f, "uniform", self.scene.render.filter_size)
            got_x, got_y = measure(exr_util.read(os.path.join(out, "plain", "frame_%04d.exr" % f))[1],
                                   exr_util.read(os.path.join(out, "frame_%04d.exr" % f))[1])
            with self.subTest(frame=f):
                self.assertGreater(abs(want_x), 0.05)
                self.assertGreater(abs(want_y), 0.05)
                self.assertAlmostEqual(got_x, want_x, delta=0.01)
                self.assertAlmostEqual(got_y, want_y, delta=0.01)
        self.assertFalse(any(fc.mute for fc in cam.animation_data.action.fcurves))
        self.assertFalse(driver.mute)
        self.scene.frame_set(3)
        self.assertAlmostEqual(cam.shift_x, 0.02, places=6)
        self.assertAlmostEqual(cam.shift_y, 0.03, places=6)

    def test_halton_points(self):
        self.assertEqual([render.halton(i, 2) for i in (1, 2, 3)], [0.5, 0.25, 0.75])
        self.assertAlmostEqual(render.halton(1, 3), 1 / 3)
        # Blackman-Harris offsets stay within EEVEE's support [-filter_size, filter_size], spread
        # beyond the pixel as EEVEE's own samples do, and have zero mean over the period.
        xs = [render.jitter_offset(f, "blackman-harris", 1.5)[0] for f in range(16)]
        self.assertLess(max(abs(x) for x in xs), 1.5)
        self.assertGreater(max(abs(x) for x in xs), 0.75)
        self.assertLess(abs(sum(xs) / 16), 0.05)



def rgb(path):
    data = exr_util.read(path)[1]
    keys = [next(k for k in data if k == c or k.endswith("Combined." + c)) for c in "RGB"]
    return [data[k] for k in keys]


def psnr_display(a, b):
    """PSNR of two linear RGB images on sRGB-encoded values clamped to [0, 1] (as crisp compare)."""
    def enc(v):
        v = min(max(v, 0.0), 1.0)
        return 12.92 * v if v <= 0.0031308 else 1.055 * v ** (1 / 2.4) - 0.055
    n = len(a[0]) * 3
    mse = sum((enc(x) - enc(y)) ** 2 for ca, cb in zip(a, b) for x, y in zip(ca, cb)) / n
    return 10 * math.log10(1.0 / max(mse, 1e-12))


class EeveeFilterMatchTest(unittest.TestCase):
    """The jitter spreads samples as EEVEE spreads its own: the mean of 8 jittered 1-sample renders
    (Halton points 1..8) of still_life's checker floor, wires and text is close to EEVEE's 8-sample
    render, much closer than with the window of total width filter_size (the reading that spread
    samples over only +-0.75 px; at 240x135 that gave 23.6 dB against 31.6 dB)."""

    def test_mean_of_jittered_frames_is_close_to_eevees_render(self):
        import still_life  # test_scenes/ is on sys.path (harness)
        scene = still_life.build()
        scene.render.resolution_x, scene.render.resolution_y, scene.render.resolution_percentage = 160, 90, 100
        cam = scene.camera.data
        unit = render.shift_per_pixel(scene)
        size = scene.render.filter_size
        with tempfile.TemporaryDirectory() as tmp:
            render.render_reference(scene, [1], os.path.join(tmp, "eevee"), 8)
            eevee = rgb(os.path.join(tmp, "eevee", "frame_0001.exr"))
            means = {}
            for name, spread in (("full", size), ("half", size / 2)):
                acc = None
                for f in range(8):  # Halton points 1..8
                    dx, dy, _ = render.jitter_offset(f, "blackman-harris", spread)
                    cam.shift_x, cam.shift_y = dx * unit, dy * unit
                    out = os.path.join(tmp, name, str(f))
                    render.render_reference(scene, [1], out, 1)
                    img = rgb(os.path.join(out, "frame_0001.exr"))
                    acc = img if acc is None else [[x + y for x, y in zip(ca, cb)] for ca, cb in zip(acc, img)]
                means[name] = [[x / 8 for x in c] for c in acc]
            cam.shift_x = cam.shift_y = 0.0
        full, half = psnr_display(means["full"], eevee), psnr_display(means["half"], eevee)
        print("mean of 8 jittered 1-sample renders vs EEVEE 8 samples: %.2f dB (window +-filter_size), "
              "%.2f dB (window +-filter_size/2)" % (full, half))
        self.assertGreater(full, half + 3.0)
        self.assertGreater(full, 27.0)

if __name__ == "__main__":
    harness.run(JitterTest, EeveeFilterMatchTest)
