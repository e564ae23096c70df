# SPDX-License-Identifier: GPL-2.0-or-later
"""What a run leaves behind in a long Blender session (a studio renders shot after shot in one): the
library's handles (every crispNew* released, counted at native.call), also of what fails part-way (a run
that fails before its first frame), the images Preview Frame loads, and what the add-on keeps per value
a setting takes."""

import collections
import os
import sys
import tempfile
import tracemalloc
import unittest

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import harness  # noqa: E402

import bpy  # noqa: E402
import crisp  # noqa: E402
from crisp import native, pipeline, render  # noqa: E402

LIB_OK, LIB_WHY = harness.library_usable()
PAIRS = (("crispNewContext", "crispReleaseContext"), ("crispNewFilter", "crispReleaseFilter"),
         ("crispLoadFrame", "crispReleaseFrame"))


@unittest.skipUnless(LIB_OK, "library not usable: " + LIB_WHY)
class LeftoverTest(unittest.TestCase):
    def setUp(self):
        crisp.register()
        self.addCleanup(crisp.unregister)
        self.calls = collections.Counter()
        real = native.call

        def counted(name, *args):
            self.calls[name] += 1
            return real(name, *args)
        native.call = counted
        self.addCleanup(setattr, native, "call", real)

    def live_handles(self):
        """{what: made and not released} of the library's contexts, filters and frames."""
        return {new: self.calls[new] - self.calls[release] for new, release in PAIRS
                if self.calls[new] != self.calls[release]}

    def test_a_run_that_fails_before_its_first_frame_releases_its_filter(self):
        """run.json cannot be written (a folder in its place here; a full disk on a farm): the run fails
        before any frame, and its filter and context go with it, not one more of each per retry."""
        scene = harness.build_scene("spinning_cube")
        scene.render.resolution_x, scene.render.resolution_y = 32, 18
        with tempfile.TemporaryDirectory() as d:
            os.makedirs(os.path.join(d, "run.json", "in the way"))
            for _ in range(2):
                with self.assertRaises(render.WriteFailed) as ctx:
                    pipeline.run(scene, "taa", [1, 2], d, log=lambda *a: None)
                self.assertIn("run.json", str(ctx.exception))
        self.assertEqual(self.live_handles(), {})

    def test_preview_frame_keeps_no_image_per_frame_previewed(self):
        """Preview Frame stepped through a shot (an artist checking each filtered frame) shows each frame, and
        keeps the image of the one shown, not one more image with its pixels per frame previewed."""
        scene = harness.build_scene("spinning_cube")
        scene.render.resolution_x, scene.render.resolution_y = 32, 18
        scene.frame_start, scene.frame_end = 1, 3
        with tempfile.TemporaryDirectory() as d:
            scene.crisp.method, scene.crisp.output_dir, scene.crisp.load_result = "fxaa", d, False
            self.assertEqual(bpy.ops.crisp.render(), {"FINISHED"})
            for _ in range(2):
                for f in (1, 2, 3):
                    scene.frame_set(f)
                    self.assertEqual(bpy.ops.crisp.preview(), {"FINISHED"})
            previews = [os.path.basename(i.filepath) for i in bpy.data.images if i.filepath.startswith(d)]
            self.assertEqual(previews, ["frame_0003.png"])

    def test_a_frame_filter_refusing_its_parameters_releases_what_it_made(self):
        """FrameFilter with a value the library refuses raises, and leaves no context or filter behind."""
        for _ in range(2):
            with self.assertRaises(native.CrispError):
                native.FrameFilter("taa", {"sharpen": 1e9})
        self.assertEqual(self.live_handles(), {})


class JitterTableTest(unittest.TestCase):
    def test_jitter_over_many_filter_sizes_keeps_no_table_for_each(self):
        """taa's viewport preview jitters each redraw over the scene's Film > Filter Size: a slider dragged
        over 200 values must not keep a 1025-point table of each (~80 kB) for the rest of the session."""
        render.jitter_offset(1, "blackman-harris", 1.5)
        tracemalloc.start()
        self.addCleanup(tracemalloc.stop)
        before = tracemalloc.get_traced_memory()[0]
        for n in range(200):
            render.jitter_offset(3, "blackman-harris", 1.0 + n * 0.001)
        kept = tracemalloc.get_traced_memory()[0] - before
        self.assertLess(kept, 2 * 1024 * 1024, "%d kB kept" % (kept // 1024))


if __name__ == "__main__":
    harness.run(LeftoverTest, JitterTableTest)
