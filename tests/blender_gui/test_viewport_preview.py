# SPDX-License-Identifier: GPL-2.0-or-later
# xvfb-screen: 640x400x24
"""The viewport preview (addon/crisp/viewport.py) on a real 3D view under Xvfb, read back as the user sees
it (screenshot of the window after a redraw and buffer swap): the still_life test scene through its
camera in solid shading, the 3D view alone in the window (640x400). With the preview on, each method must
change the pixels on edges of the unfiltered view (edges: its 3x3 luma range) and leave its flat areas
(7x7 range) alone, must not be black or shifted, taa must accumulate redraws and restart when the view,
the frame or the scene changes; switched off, no handler and no buffers remain and the view is the
unfiltered one again. In background mode the toggle must switch itself off with a message."""

import os
import subprocess
import sys
import unittest

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import gui_harness  # noqa: E402

import bpy  # noqa: E402
import numpy as np  # noqa: E402  (python3-numpy)
from mathutils import Vector  # noqa: E402

import harness  # noqa: E402  (tests/blender: build_scene)
import crisp  # noqa: E402
from crisp import gpu_filters, render, viewport  # noqa: E402

EDGE_RANGE = 0.1      # 3x3 luma range (display values) that makes a pixel an edge pixel
FLAT_RANGE = 0.02     # 7x7 luma range below which a pixel is far from any edge
CHANGED = 1.5 / 255   # a display value differing by more is "changed" (the window is 8-bit)
TAA_REDRAWS = 8
SCREENSHOT = os.path.join("/dev/shm" if os.path.isdir("/dev/shm") else "/tmp",
                          "crisp_viewport_preview_%d.png" % os.getpid())

# Before the splash screen opens (it would cover the view in the screenshots).
bpy.context.preferences.view.show_splash = False


def view3d():
    area = next(a for a in bpy.context.screen.areas if a.type == "VIEW_3D")
    region = next(r for r in area.regions if r.type == "WINDOW")
    return area, region


def maximise_view():
    """The 3D view alone in the window, without header and tool regions (runs before the tests, from a
    timer: the new screen is in place by the time they start)."""
    area, _ = view3d()
    with bpy.context.temp_override(window=bpy.context.window, area=area):
        bpy.ops.screen.screen_full_area(use_hide_panels=True)


def redraw(n=1):
    area, region = view3d()
    with bpy.context.temp_override(window=bpy.context.window, area=area, region=region):
        bpy.ops.wm.redraw_timer(type="DRAW_WIN_SWAP", iterations=n)


def screenshot():
    """Redraws the window once and returns the 3D view as shown: float RGB display values, row 0 at the
    bottom."""
    area, region = view3d()
    redraw(1)
    with bpy.context.temp_override(window=bpy.context.window, area=area, region=region):
        bpy.ops.screen.screenshot_area(filepath=SCREENSHOT)
    image = bpy.data.images.load(SCREENSHOT)
    try:
        w, h = image.size
        px = np.empty(w * h * 4, dtype=np.float32)
        image.pixels.foreach_get(px)
    finally:
        bpy.data.images.remove(image)
        os.remove(SCREENSHOT)
    return px.reshape(h, w, 4)[..., :3].astype(np.float64)


def local_extremes(rgb, radius):
    """Per-channel min and max of rgb over a (2 radius + 1)^2 window, clamp-to-edge."""
    p = np.pad(rgb, ((radius, radius), (radius, radius), (0, 0)), mode="edge")
    h, w = rgb.shape[:2]
    win = [p[dy:dy + h, dx:dx + w] for dy in range(2 * radius + 1) for dx in range(2 * radius + 1)]
    return np.min(win, axis=0), np.max(win, axis=0)


def luma_plane(rgb):
    return 0.2126 * rgb[..., 0] + 0.7152 * rgb[..., 1] + 0.0722 * rgb[..., 2]


def local_range(plane, radius):
    """Max - min of the plane over a (2 radius + 1)^2 window, clamp-to-edge."""
    p = np.pad(plane, radius, mode="edge")
    h, w = plane.shape
    win = [p[dy:dy + h, dx:dx + w] for dy in range(2 * radius + 1) for dx in range(2 * radius + 1)]
    return np.max(win, axis=0) - np.min(win, axis=0)


def look_through_camera(space, camera, distance=5.0):
    """The user view set to the camera's position, direction and lens (not the camera view itself: its
    passepartout is drawn by the region, not by draw_view3d, so the preview would differ there)."""
    bpy.context.view_layer.update()  # the camera's constraints are evaluated here
    rv3d = space.region_3d
    rv3d.view_perspective = "PERSP"
    rotation = camera.matrix_world.to_quaternion()
    rv3d.view_rotation = rotation
    rv3d.view_distance = distance
    rv3d.view_location = camera.matrix_world.translation + rotation @ Vector((0.0, 0.0, -distance))
    space.lens = camera.data.lens


class ViewportPreview(unittest.TestCase):
    @classmethod
    def setUpClass(cls):
        os.environ.setdefault("CRISP_LIBRARY", gui_harness.LIBRARY)
        crisp.register()
        bpy.context.preferences.system.viewport_aa = "OFF"  # the unfiltered view must be aliased
        harness.build_scene("still_life")
        area, region = view3d()
        cls.size = (region.width, region.height)
        space = area.spaces.active
        space.shading.type = "SOLID"
        space.overlay.show_overlays = False
        space.show_gizmo = False
        look_through_camera(space, bpy.context.scene.camera)
        cls.space = space
        cls.settings = bpy.context.window_manager.crisp_viewport
        cls.settings.enabled = False
        cls.base = screenshot()
        if os.environ.get("CRISP_DUMP_DIR"):
            np.save(os.path.join(os.environ["CRISP_DUMP_DIR"], "base.npy"), cls.base)
        plane = luma_plane(cls.base)
        cls.edge = local_range(plane, 1) > EDGE_RANGE
        cls.flat = (local_range(plane, 3) < FLAT_RANGE) & ~cls.edge
        print("view %dx%d: %d edge pixels, %d flat pixels" % (cls.size + (cls.edge.sum(), cls.flat.sum())),
              file=sys.stderr)

    @classmethod
    def tearDownClass(cls):
        cls.settings.enabled = False
        crisp.unregister()

    def setUp(self):
        self.assertEqual(self.base.shape[:2], self.size[::-1], "the screenshot must be the 3D view alone")
        self.assertGreater(int(self.edge.sum()), 500, "the test scene must show edges")
        self.assertGreater(int(self.flat.sum()), 20000, "the test scene must have flat areas")

    def switch_on(self, method):
        self.settings.method = method
        self.settings.enabled = True
        self.assertTrue(viewport.is_active(), self.settings.status)

    def switch_off(self):
        self.settings.enabled = False
        self.assertFalse(viewport.is_active())
        self.assertEqual(self.settings.status, "", "no error may have switched the preview off")

    def check_filtered(self, method, shown):
        """shown: the view with the preview on. Edges change, flat areas do not, nothing moves."""
        if os.environ.get("CRISP_DUMP_DIR"):
            np.save(os.path.join(os.environ["CRISP_DUMP_DIR"], method.split()[0] + ".npy"), shown)
        diff = np.abs(shown - self.base).max(axis=2)
        changed = diff > CHANGED
        edge_frac, flat_frac = changed[self.edge].mean(), changed[self.flat].mean()
        # Against the view moved by one pixel: the unmoved one must match best on the edges (a mirrored,
        # shifted or black preview does not).
        # The filters blend neighbouring pixels: a value outside the 5x5 range of the unfiltered view is
        # invented (wrong colour management, garbage).
        lo, hi = local_extremes(self.base, 2)
        inside = ((shown >= lo - 2 / 255) & (shown <= hi + 2 / 255)).all(axis=2).mean()
        err = {}
        for dy in (-1, 0, 1):
            for dx in (-1, 0, 1):
                moved = np.roll(self.base, (dy, dx), axis=(0, 1))
                err[(dx, dy)] = np.abs(shown - moved).max(axis=2)[self.edge].mean()
        print("preview %s: %.1f%% of edge pixels changed, %.3f%% of flat pixels (worst %.4f); mean |diff| %.5f; "
              "edge error unmoved %.4f, best moved %.4f; %.3f%% inside the 5x5 range"
              % (method, 100 * edge_frac, 100 * flat_frac, float(diff[self.flat].max()), float(diff.mean()),
                 err[(0, 0)], min(v for k, v in err.items() if k != (0, 0)), 100 * inside), file=sys.stderr)
        self.assertGreater(float(shown.max()), 0.5, method + ": the preview must not be black")
        self.assertLess(abs(float(shown.mean() - self.base.mean())), 0.01, method + ": the mean must not move")
        self.assertGreater(edge_frac, 0.2, method + " must change the edges")
        self.assertLess(flat_frac, 0.002, method + " must leave flat areas alone")
        self.assertEqual(min(err, key=err.get), (0, 0), method + ": the preview must not be moved or mirrored")
        self.assertGreater(inside, 0.99, method + ": values must come from the neighbourhood")

    def test_fxaa(self):
        self.switch_on("fxaa")
        shown = screenshot()
        # The preview's input: the unfiltered 1-sample view (not smoothed by Blender: ONE_SAMPLE), to the
        # 8-bit rounding and dither of the window.
        seen = np.asarray(viewport._State.offscreen.texture_color.read().to_list(), dtype=np.float64)[..., :3]
        self.switch_off()
        input_diff = np.abs(seen - self.base).max(axis=2)
        print("preview input: %.3f%% of edge pixels and %.3f%% of all differ from the view by > 3/255"
              % (100 * (input_diff[self.edge] > 3 / 255).mean(), 100 * (input_diff > 3 / 255).mean()), file=sys.stderr)
        self.assertLess(float((input_diff[self.edge] > 3 / 255).mean()), 0.01, "the preview must filter the raw view")
        self.check_filtered("fxaa", shown)

    def test_repair(self):
        self.switch_on("repair")
        shown = screenshot()
        self.switch_off()
        self.check_filtered("repair", shown)

    def test_taa_accumulates_and_restarts(self):
        self.switch_on("taa")
        redraw(TAA_REDRAWS)
        shown = screenshot()
        frames = viewport.accumulated_frames()
        self.assertGreaterEqual(frames, TAA_REDRAWS, "taa must keep its history between redraws")
        # A view change (zoom) restarts the accumulation.
        rv3d = self.space.region_3d
        distance = rv3d.view_distance
        rv3d.view_distance = distance * 1.01
        try:
            redraw(1)
            self.assertEqual(viewport.accumulated_frames(), 1, "a view change must reset the history")
        finally:
            rv3d.view_distance = distance
        self.switch_off()
        self.check_filtered("taa (%d redraws)" % frames, shown)

    def test_taa_restarts_on_settings_edit(self):
        """An edit of the filter's settings (scene.crisp, which fires no depsgraph update) restarts the
        history, like a view change."""
        params = bpy.context.scene.crisp.taa
        before = params.feedbackMax
        self.addCleanup(setattr, params, "feedbackMax", before)
        self.addCleanup(setattr, self.settings, "enabled", False)
        self.switch_on("taa")
        redraw(TAA_REDRAWS)
        self.assertGreaterEqual(viewport.accumulated_frames(), TAA_REDRAWS)
        params.feedbackMax = 0.9
        redraw(1)
        self.assertEqual(viewport.accumulated_frames(), 1, "a settings edit must reset the history")
        self.switch_off()

    def test_taa_restarts_on_frame_change_and_scene_edit(self):
        """A frame change or an edit of the scene (the view itself unchanged) restarts taa's history: with
        no motion vectors to reproject it, a history kept across them ghosts."""
        scene = bpy.context.scene
        ball = bpy.data.objects["Ball"]
        self.addCleanup(setattr, ball, "location", ball.location.copy())
        self.addCleanup(scene.frame_set, scene.frame_current)
        self.addCleanup(setattr, self.settings, "enabled", False)

        def move_ball():
            ball.location.x += 0.1
            bpy.context.view_layer.update()

        self.switch_on("taa")
        for change, edit in (("a frame change", lambda: scene.frame_set(scene.frame_current + 1)),
                             ("a scene edit", move_ball)):
            redraw(TAA_REDRAWS)
            self.assertGreaterEqual(viewport.accumulated_frames(), TAA_REDRAWS)
            edit()
            redraw(1)
            self.assertEqual(viewport.accumulated_frames(), 1, change + " must reset the history")
        self.switch_off()

    def test_taa_jitters_as_the_renders(self):
        """The preview jitters the view as the renders do (render.jitter_offset: the panel's Jitter over
        EEVEE's filter size), and a change of the Jitter restarts the history."""
        scene = bpy.context.scene
        seen = []
        original = gpu_filters.GpuFilter.set_params

        def logged(filt, params):
            if "jitterX" in params:
                seen.append((params["jitterX"], params["jitterY"]))
            return original(filt, params)

        gpu_filters.GpuFilter.set_params = logged
        self.addCleanup(setattr, gpu_filters.GpuFilter, "set_params", original)
        self.addCleanup(setattr, scene.crisp, "jitter_distribution", scene.crisp.jitter_distribution)
        self.addCleanup(setattr, self.settings, "enabled", False)
        for distribution, reach in (("blackman-harris", scene.render.filter_size), ("uniform", 0.5)):
            scene.crisp.jitter_distribution = distribution
            seen.clear()
            if not self.settings.enabled:
                self.switch_on("taa")
            redraw(6)
            self.assertGreaterEqual(len(seen), 6)
            self.assertEqual(viewport.accumulated_frames(), len(seen), "one history since the Jitter changed")
            expected = [render.jitter_offset(k, distribution, scene.render.filter_size,
                                             period=viewport.ACCUMULATE_FRAMES)[:2] for k in range(len(seen))]
            for got, want in zip(seen, expected):
                self.assertAlmostEqual(got[0], want[0], places=6)
                self.assertAlmostEqual(got[1], want[1], places=6)
            largest = max(max(abs(x), abs(y)) for x, y in seen)
            self.assertLessEqual(largest, reach, distribution)
            if distribution == "blackman-harris":
                self.assertGreater(largest, 0.5, "EEVEE's jitter reaches past the pixel")
        size = scene.render.filter_size
        self.addCleanup(setattr, scene.render, "filter_size", size)
        # taa's filterSize (the pixel filter its unjitter assumes) is the scene's, as in the renders
        # (pipeline.with_scene_filter_size), not the library's 1.5 whatever the scene says.
        scene.crisp.jitter_distribution = "blackman-harris"
        filt = next(f for (_region, method), f in viewport._State.filters.items() if method == "taa")
        self.assertEqual(filt.params["filterSize"], size)
        scene.render.filter_size = 0.75
        redraw(2)
        self.assertEqual(filt.params["filterSize"], 0.75)
        self.assertIsNone(viewport._State.rejected)
        # A filter size the library refuses (taa's range is 4 px, within which the jitter stays in its
        # +-4 px) is said in the panel naming the scene's setting, the view is left unfiltered, and the
        # preview stays on.
        scene.render.filter_size = 10.0
        redraw(3)
        self.assertTrue(viewport.is_active(), self.settings.status)
        self.assertIn("Film > Filter Size (10 px)", viewport._State.rejected or "")
        self.assertIn("'filterSize' = 10 is out of range", viewport._State.rejected or "")
        scene.render.filter_size = size
        redraw(1)
        self.assertIsNone(viewport._State.rejected)
        self.switch_off()

    def test_settings_the_library_rejects_are_not_run(self):
        """Settings the library refuses (an even REPAIR patchSize, TAA feedbackMin > feedbackMax) are not
        run: the view stays unfiltered, the panel names the library's reason, and the preview stays on and
        filters again once they are valid."""
        scene = bpy.context.scene
        self.addCleanup(setattr, self.settings, "enabled", False)
        for method, group, bad, reason in (("repair", scene.crisp.repair, {"patchSize": 6}, "must be odd"),
                                           ("taa", scene.crisp.taa, {"feedbackMin": 0.9, "feedbackMax": 0.8},
                                            "must not exceed")):
            before = {k: getattr(group, k) for k in bad}
            for k, v in bad.items():
                setattr(group, k, v)
            try:
                self.switch_on(method)
                shown = screenshot()
                diff = float(np.abs(shown - self.base).max())
                print("preview %s with rejected settings: differs from the unfiltered view by up to %.1f/255; %s"
                      % (method, 255 * diff, viewport.rejected_settings()), file=sys.stderr)
                self.assertLessEqual(diff, 0.5 / 255, method + ": rejected settings must not be run")
                self.assertIn(reason, viewport.rejected_settings() or "", method)
            finally:
                for k, v in before.items():
                    setattr(group, k, v)
            self.assertTrue(viewport.is_active(), method + ": the preview must stay on")
            shown = screenshot()
            self.assertIsNone(viewport.rejected_settings())
            self.assertGreater(float(np.abs(shown - self.base).max()), 0.1, method + " must filter again")
            self.switch_off()

    def test_z_off_restores_view(self):
        """Runs last: after on/off cycles, no handler and no buffers remain and the view is unfiltered."""
        before = screenshot()
        self.switch_on("fxaa")
        redraw(1)
        self.switch_off()
        self.assertIsNone(viewport._State.handle)
        self.assertIsNone(viewport._State.offscreen)
        self.assertNotIn(viewport._on_scene_change, bpy.app.handlers.depsgraph_update_post)
        self.assertFalse(viewport.is_active())
        after = screenshot()
        for label, a, b in (("before and after", before, after), ("first and after", self.base, after)):
            diff = np.abs(a - b).max(axis=2)
            print("preview off, %s: %d pixels differ, by up to %.1f/255" % (label, (diff > 0).sum(), 255 * diff.max()),
                  file=sys.stderr)
        self.assertLessEqual(float(np.abs(after - before).max()), 0.5 / 255,
                             "with the preview off the view must be the unfiltered one")

    def test_one_sample_settings(self):
        """While on, the scene's own viewport anti-aliasing (which draw_view3d would apply) is off and EEVEE
        draws 1 sample; switching off restores the values."""
        scene = bpy.context.scene
        before = (scene.display.viewport_aa, scene.eevee.taa_samples)
        scene.display.viewport_aa, scene.eevee.taa_samples = "8", 16
        try:
            self.switch_on("fxaa")
            self.assertEqual((scene.display.viewport_aa, scene.eevee.taa_samples), ("OFF", 1))
            self.switch_off()
            self.assertEqual((scene.display.viewport_aa, scene.eevee.taa_samples), ("8", 16))
        finally:
            scene.display.viewport_aa, scene.eevee.taa_samples = before

    def test_background_mode_switches_off(self):
        """Blender without a window: switching the preview on switches it back off with a message."""
        script = ("import sys; sys.path.insert(0, %r); import bpy, crisp; crisp.register(); "
                  "s = bpy.context.window_manager.crisp_viewport; s.enabled = True; "
                  "from crisp import viewport; "
                  "print('CRISP_RESULT', s.enabled, viewport.is_active(), repr(s.status))" % gui_harness.ADDON_DIR)
        p = subprocess.run([bpy.app.binary_path, "-b", "--factory-startup", "--python-exit-code", "1",
                            "--python-expr", script], stdout=subprocess.PIPE, stderr=subprocess.STDOUT,
                           env=dict(os.environ), timeout=120)
        out = p.stdout.decode("utf-8", "replace")
        line = next((l for l in out.splitlines() if l.startswith("CRISP_RESULT")), None)
        self.assertIsNotNone(line, out)
        self.assertTrue(line.startswith("CRISP_RESULT False False "), line)
        self.assertIn("background mode", line)


def start():
    maximise_view()
    gui_harness.run(ViewportPreview, delay=0.5)


if __name__ == "__main__":
    bpy.app.timers.register(start, first_interval=0.5)
