# SPDX-License-Identifier: GPL-2.0-or-later
"""The panel's operators as an artist runs them: Render Reference, Render with Crisp, Compare and
Load into Compositor, on a scene whose user picked Cycles (Crisp renders with EEVEE and gives the
scene back as it was)."""

import math
import os
import sys
import tempfile
import unittest

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import harness  # noqa: E402

import bpy  # noqa: E402
import crisp  # noqa: E402

LIB_OK, LIB_WHY = harness.library_usable()


@unittest.skipUnless(LIB_OK, "library not usable: " + LIB_WHY)
class OperatorTest(unittest.TestCase):
    def setUp(self):
        crisp.register()
        self.tmp = tempfile.TemporaryDirectory()

    def tearDown(self):
        crisp.unregister()
        self.tmp.cleanup()

    def test_reference_render_compare_from_a_cycles_scene(self):
        scene = harness.build_scene("still_life")
        scene.render.engine = "CYCLES"  # the user's choice, to be restored
        scene.render.resolution_x, scene.render.resolution_y, scene.render.resolution_percentage = 64, 36, 100
        scene.frame_start, scene.frame_end = 1, 2
        s = scene.crisp
        s.method = "fxaa"
        s.reference_samples = 4
        s.output_dir = self.tmp.name
        s.load_result = True

        self.assertEqual(bpy.ops.crisp.render_reference(), {"FINISHED"})
        self.assertEqual(bpy.ops.crisp.render(), {"FINISHED"})
        self.assertEqual(bpy.ops.crisp.compare(), {"FINISHED"})

        ref = sorted(f for f in os.listdir(os.path.join(self.tmp.name, "reference")) if f.endswith(".exr"))
        self.assertEqual(ref, ["frame_0001.exr", "frame_0002.exr"])
        self.assertTrue(os.path.isfile(os.path.join(self.tmp.name, "filtered", "frame_0002.exr")))
        # Compare measured something real: a 4-sample reference is close to, not equal to, FXAA's frame.
        self.assertTrue(math.isfinite(s.last_psnr) and 15.0 < s.last_psnr < 60.0, s.last_compare)
        self.assertTrue(0.5 < s.last_ssim <= 1.0, s.last_compare)
        self.assertIn("2 frames", s.last_compare)
        self.assertEqual(scene.render.engine, "CYCLES", "the user's engine was not restored")
        self.assertIn("Crisp Result", bpy.data.node_groups)
        # Still-frame preview: the current frame's filtered PNG becomes an image Blender can show.
        scene.frame_set(2)
        self.assertEqual(bpy.ops.crisp.preview(), {"FINISHED"})
        shown = [i for i in bpy.data.images if i.filepath.endswith("frame_0002.png")]
        self.assertEqual(len(shown), 1)
        self.assertEqual(tuple(shown[0].size), (64, 36))

    def test_compare_without_reference_says_what_is_missing(self):
        scene = harness.build_scene("still_life")
        scene.frame_start, scene.frame_end = 1, 1
        scene.crisp.output_dir = self.tmp.name
        with self.assertRaises(RuntimeError) as ctx:
            bpy.ops.crisp.compare()
        self.assertIn("reference", str(ctx.exception))


if __name__ == "__main__":
    harness.run(OperatorTest)
