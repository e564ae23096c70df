# SPDX-License-Identifier: GPL-2.0-or-later
"""batch.py end to end in fresh Blender processes (as `crisp render` runs it): files, passes in the
EXRs (through the library, cross-checked with a minimal EXR reader), sidecars, run.json, filtered
output; and bad input (no camera, empty range, unwritable output, unknown method, missing library)
giving clear errors with a non-zero exit code and leaving the user's .blend untouched."""

import hashlib
import json
import os
import sys
import tempfile
import unittest

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import harness  # noqa: E402

import bpy  # noqa: E402
import exr_util  # noqa: E402
from crisp import exr_file, hashing, native, render  # noqa: E402

LIB_OK, LIB_WHY = harness.library_usable()


def files(d):
    return sorted(os.listdir(d)) if os.path.isdir(d) else []


class BatchTest(unittest.TestCase):
    @classmethod
    def setUpClass(cls):
        cls.tmp = tempfile.TemporaryDirectory()

    @classmethod
    def tearDownClass(cls):
        cls.tmp.cleanup()

    @unittest.skipUnless(LIB_OK, "library not usable: " + LIB_WHY)
    def test_spatial_method_end_to_end(self):
        out = os.path.join(self.tmp.name, "fxaa")
        rc, log = harness.blender_batch(["--scene-script", "still_life", "--frames", "1-2", "--method", "fxaa",
                                         "--resolution", "96x54", "-o", out], env={"CRISP_LIBRARY": harness.LIBRARY})
        self.assertEqual(rc, 0, log[-3000:])
        self.assertEqual(files(os.path.join(out, "input")),
                         ["frame_0001.exr", "frame_0001.json", "frame_0002.exr", "frame_0002.json"])
        self.assertEqual(files(os.path.join(out, "filtered")),
                         [".crisp", "frame_0001.exr", "frame_0001.png", "frame_0002.exr", "frame_0002.png"])
        self.assertEqual(files(os.path.join(out, "filtered", ".crisp")), ["frame_0001.png.json", "frame_0002.png.json"])
        with open(os.path.join(out, "run.json")) as f:
            run = json.load(f)
        self.assertEqual(run["blender_version"], bpy.app.version_string)
        self.assertEqual(run["method"], "fxaa")
        self.assertEqual(run["plan"]["passes"], ["color"])
        self.assertIn("color", run["plan"]["reasons"])
        self.assertEqual([fr["frame"] for fr in run["frames"]], [1, 2])
        for fr in run["frames"]:
            self.assertGreater(fr["render_s"], 0)
            self.assertGreaterEqual(fr["filter_s"], 0)
        with native.Context() as ctx:
            for f in (1, 2):
                with native.Frame(ctx, os.path.join(out, "input", "frame_%04d.exr" % f)) as fr:
                    self.assertEqual((fr.width, fr.height), (96, 54))
                    self.assertEqual(fr.passes(), ["color"])  # only the planned pass was rendered
                    color, _ = fr.pass_values("color")
                with native.Frame(ctx, os.path.join(out, "filtered", "frame_%04d.exr" % f)) as filt:
                    self.assertEqual((filt.width, filt.height), (96, 54))
                    out_color, _ = filt.pass_values("color")
                self.assertNotEqual(color, out_color, "FXAA changed nothing")
                diff = sum(abs(a - b) for a, b in zip(color, out_color)) / len(color)
                self.assertLess(diff, 0.1, "FXAA output far from its input")

    @unittest.skipUnless(LIB_OK, "library not usable: " + LIB_WHY)
    def test_temporal_method_on_eevee_reconstructs_motion(self):
        # EEVEE 3.4 writes no Vector pass: the pipeline must rebuild motion from depth and sidecars.
        out = os.path.join(self.tmp.name, "taa")
        rc, log = harness.blender_batch(["--scene-script", "spinning_cube", "--frames", "1-3", "--method", "taa",
                                         "--resolution", "96x54", "-o", out], env={"CRISP_LIBRARY": harness.LIBRARY})
        self.assertEqual(rc, 0, log[-3000:])
        with open(os.path.join(out, "run.json")) as f:
            run = json.load(f)
        self.assertIn("motion", run["plan"]["passes"])
        path = lambda kind, f, ext="exr": os.path.join(out, kind, "frame_%04d.%s" % (f, ext))  # noqa: E731
        with native.Context() as ctx:
            with native.Frame(ctx, path("input", 2)) as fr:
                self.assertNotIn("motion", fr.passes())
                fr.reconstruct_motion(ctx, path("input", 1, "json"))
                motion, channels = fr.pass_values("motion")
            moving = sum(1 for i in range(0, len(motion), channels) if abs(motion[i]) + abs(motion[i + 1]) > 0.05)
            self.assertGreater(moving, 50, "the spinning cube shows no reconstructed motion")
            colors = {}
            for kind in ("input", "filtered"):
                for f in (1, 3):
                    with native.Frame(ctx, path(kind, f)) as fr:
                        colors[kind, f], _ = fr.pass_values("color")
        # Frame 1 has no history: its output is a new filter's first frame (this frame's unjittered
        # mix, taa.cpp "Jitter"); by frame 3 history shapes the output: a new filter given frame 3
        # alone gives something else.
        def fresh(f):
            target = os.path.join(self.tmp.name, "fresh_%d.exr" % f)
            ff = native.FrameFilter("taa", None, 0, tuple(run["plan"]["passes"]))
            try:
                ff.run(path("input", f), [target])
            finally:
                ff.close()
            with native.Context() as ctx, native.Frame(ctx, target) as fr:
                return fr.pass_values("color")[0]
        first = max(abs(a - b) for a, b in zip(fresh(1), colors["filtered", 1]))
        self.assertLess(first, 1e-6)
        self.assertNotEqual(colors["input", 1], colors["filtered", 1])  # the mix, not the jittered sample
        self.assertGreater(max(abs(a - b) for a, b in zip(fresh(3), colors["filtered", 3])), 1e-3)

    def test_passes_and_sidecars_of_a_temporal_plan(self):
        """ghosting + taa-improved on EEVEE 3.4: colour, depth, ID, albedo, no Vector (reconstructed
        later), jitter on; Cryptomatte hashes of the sidecar = the EXR manifest = the ID pass."""
        out = os.path.join(self.tmp.name, "taai")
        rc, log = harness.blender_batch(["--scene-script", "ghosting", "--frames", "3-4", "--method", "taa-improved",
                                         "--resolution", "96x54", "--no-filter", "-o", out])
        self.assertEqual(rc, 0, log[-3000:])
        for f in (3, 4):
            exr = os.path.join(out, "input", "frame_%04d.exr" % f)
            # Whole, as render._render_to checked before the rename; cut short, it would not have been.
            self.assertIsNone(exr_file.incomplete(exr))
            with open(exr, "rb") as src, open(os.path.join(self.tmp.name, "cut.exr"), "wb") as dst:
                dst.write(src.read()[:-100])
            self.assertIn("last chunk ends after the file", exr_file.incomplete(dst.name))
            names, header = exr_util.channels(exr)
            layers = {n.split(".")[1] for n in names}
            self.assertEqual(layers, {"Combined", "Depth", "CryptoObject00", "DiffCol"}, names)
            with open(os.path.join(out, "input", "frame_%04d.json" % f)) as fh:
                side = json.load(fh)
            self.assertEqual(side["frame"], f)
            self.assertTrue(side["jitter"]["enabled"])
            want = render.jitter_offset(f, "blackman-harris", side["render_settings"]["filter_size"])
            self.assertAlmostEqual(side["jitter"]["x"], want[0])
            self.assertEqual(side["render_settings"]["samples"], 1)
            self.assertEqual(side["render_settings"]["gi_cubemap_resolution"], "64")
            self.assertEqual(side["blender_version"], bpy.app.version_string)
            names_by_hash = {h: o["name"] for h, o in side["objects"].items()}
            self.assertEqual(sorted(names_by_hash.values()), ["Sphere", "Wall"])
            manifest_key = next(k for k in header if k.startswith("cryptomatte/") and k.endswith("/manifest"))
            manifest = json.loads(header[manifest_key])
            self.assertEqual({n: h for n, h in manifest.items()}, {n: h for h, n in names_by_hash.items()})
            # sphere moved between the frames, the wall did not
            if f == 4:
                prev = json.load(open(os.path.join(out, "input", "frame_0003.json")))
                sph = hashing.cryptomatte_hex("Sphere")
                wall = hashing.cryptomatte_hex("Wall")
                self.assertNotEqual(prev["objects"][sph]["matrix_world"], side["objects"][sph]["matrix_world"])
                self.assertEqual(prev["objects"][wall]["matrix_world"], side["objects"][wall]["matrix_world"])
            if LIB_OK:
                with native.Context() as ctx, native.Frame(ctx, exr) as fr:
                    self.assertEqual(sorted(fr.passes()), ["albedo", "color", "depth", "id"])
                    ids, _ = fr.pass_values("id")
                    known = {int(h, 16) for h in names_by_hash} | {0}
                    self.assertTrue(set(ids) <= known, set(ids) - known)
                    self.assertEqual(set(ids) - {0}, {int(h, 16) for h in names_by_hash})
        with open(os.path.join(out, "run.json")) as fh:
            run = json.load(fh)
        self.assertEqual(run["plan"]["motion_source"], "reconstruct")
        self.assertNotIn("filter_s", run["frames"][0])

    def test_ids_for_motion_alone_are_not_bound_to_filters_without_them(self):
        """ghosting: one of two objects moves, so the plan renders object IDs for motion reconstruction;
        taa and phlm read none, and filter the frames (they failed binding 'id' before)."""
        for method in ("taa", "phlm"):
            out = os.path.join(self.tmp.name, "ids_" + method)
            rc, log = harness.blender_batch(["--scene-script", "ghosting", "--frames", "1-2", "--method", method,
                                             "--resolution", "64x36", "-o", out])
            self.assertEqual(rc, 0, log[-3000:])
            names, _ = exr_util.channels(os.path.join(out, "input", "frame_0002.exr"))
            self.assertIn("CryptoObject00", {n.split(".")[1] for n in names})
            for f in (1, 2):
                self.assertTrue(os.path.isfile(os.path.join(out, "filtered", "frame_%04d.exr" % f)), (method, f))

    def test_bad_inputs_clear_errors_user_file_untouched(self):
        blend = os.path.join(self.tmp.name, "user.blend")
        harness.build_scene("still_life")
        bpy.ops.wm.save_as_mainfile(filepath=blend, copy=True)
        digest = hashlib.sha256(open(blend, "rb").read()).hexdigest()
        mtime = os.stat(blend).st_mtime_ns
        nocam = os.path.join(self.tmp.name, "nocam.py")
        with open(nocam, "w") as f:
            f.write("import bpy\nfor o in list(bpy.data.objects):\n    bpy.data.objects.remove(o)\n"
                    "bpy.ops.mesh.primitive_cube_add()\n")
        blocker = os.path.join(self.tmp.name, "a_file")
        open(blocker, "w").close()
        out = os.path.join(self.tmp.name, "bad_out")
        cases = [
            (["--frames", "1-2", "--scene-script", nocam, "-o", out], None, 2, "no camera"),
            (["--frames", "5-3", "-o", out], blend, 2, "frame range 5-3 is empty"),
            (["--frames", "1-2", "-o", os.path.join(blocker, "out")], blend, 2, "is not writable"),
            # Blender reads a backslash in a render's path as a folder separator: it rendered elsewhere.
            (["--frames", "1-2", "-o", out + "\\010"], blend, 2, "has a backslash in its path"),
            (["--frames", "1-2", "--method", "smaa", "-o", out], blend, 2, "unknown method 'smaa'"),
            (["--frames", "1-2", "--library", "/nonexistent/libcrisp.so", "-o", out], blend, 3,
             "/nonexistent/libcrisp.so: no such file"),
            (["--frames", "1-2", "--resolution", "big", "-o", out], blend, 2, "bad --resolution"),
            # A parameter value the library refuses: 5 (crisp render says 1, as for its own check).
            (["--frames", "1-2", "--set", "subpix=abc", "-o", out], blend, 5,
             "parameter 'subpix' takes a number, not 'abc'"),
            (["--frames", "1-2", "--set", "reference=maybe", "-o", out], blend, 5, "takes true or false"),
            # A rule the library checks at commit: found before frame 1 is rendered, not after.
            (["--frames", "1-2", "--method", "repair", "--set", "patchSize=4", "-o", out], blend, 5, "must be odd"),
            (["--frames", "1-2", "--method", "taa", "--set", "feedbackMin=0.9", "--set", "feedbackMax=0.8",
              "-o", out], blend, 5, "must not exceed 'feedbackMax'"),
        ]
        for args, opened, code, message in cases:
            with self.subTest(args=args):
                rc, log = harness.blender_batch(args, blend=opened)
                self.assertEqual(rc, code, log[-2000:])
                self.assertIn("crisp: error: ", log)
                self.assertIn(message, log)
                self.assertFalse(os.path.exists(out) and files(out), "output written on bad input")
        # Blender failing to save a frame (input/ is /proc, where no file can be made): exit 4, said.
        stuck = os.path.join(self.tmp.name, "stuck")
        os.makedirs(stuck)
        os.symlink("/proc", os.path.join(stuck, "input"))
        rc, log = harness.blender_batch(["--frames", "1-2", "-o", stuck], blend=blend)
        self.assertEqual(rc, 4, log[-2000:])
        self.assertIn("crisp: error: Blender could not render frame 1", log)
        self.assertNotIn("Traceback", log)
        # A frame's file gone as Blender wrote it (a scene's handler removes it here): a failed render,
        # exit 4, not bad input.
        vanish = os.path.join(self.tmp.name, "vanish.py")
        with open(vanish, "w") as f:
            f.write("import bpy, os\n"
                    "def vanish(scene, *_):\n"
                    "    path = bpy.path.abspath(scene.render.filepath)\n"
                    "    if os.path.isfile(path):\n"
                    "        os.remove(path)\n"
                    "bpy.app.handlers.render_write.append(vanish)\n")
        rc, log = harness.blender_batch(["--frames", "1", "--resolution", "16x8", "--scene-script", vanish,
                                         "-o", os.path.join(self.tmp.name, "vanished")])
        self.assertEqual(rc, 4, log[-2000:])
        self.assertIn("crisp: error: Blender wrote no file for frame 1", log)
        # run.json that cannot be written (a folder in its place): exit 4, named, no temporary left.
        jammed = os.path.join(self.tmp.name, "jammed")
        os.makedirs(os.path.join(jammed, "run.json"))
        rc, log = harness.blender_batch(["--frames", "1", "-o", jammed], blend=blend)
        self.assertEqual(rc, 4, log[-2000:])
        self.assertIn("crisp: error: cannot write %s: " % os.path.join(jammed, "run.json"), log)
        self.assertNotIn("Traceback", log)
        self.assertEqual([n for n in os.listdir(jammed) if ".tmp" in n], [])
        self.assertEqual(hashlib.sha256(open(blend, "rb").read()).hexdigest(), digest)
        self.assertEqual(os.stat(blend).st_mtime_ns, mtime)
        self.assertFalse(os.path.exists(blend + "1"), "no .blend1 backup: the file was never saved")

    @unittest.skipUnless(LIB_OK, "library not usable: " + LIB_WHY)
    def test_an_output_relative_to_the_blend_file(self):
        """-o //NAME is NAME beside the opened .blend, as Blender's own -o reads it. It was made at the
        root folder (/NAME) while Blender wrote the frame beside the .blend, where Crisp did not look:
        'Blender wrote no file', a temporary left there. Without a saved .blend it is refused."""
        folder = os.path.join(self.tmp.name, "my shot ü")
        os.makedirs(folder)
        blend = os.path.join(folder, "shot.blend")
        harness.build_scene("still_life")
        bpy.ops.wm.save_as_mainfile(filepath=blend, copy=True)
        name = "crisp_out_%d" % os.getpid()
        self.addCleanup(lambda: os.path.isdir("/" + name) and __import__("shutil").rmtree("/" + name))
        rc, log = harness.blender_batch(["--frames", "1", "--resolution", "16x8", "-o", "//" + name], blend=blend)
        self.assertEqual(rc, 0, log[-2000:])
        self.assertEqual(files(os.path.join(folder, name, "filtered")), [".crisp", "frame_0001.exr", "frame_0001.png"])
        self.assertIn("crisp: done: %s" % os.path.join(folder, name), log)
        self.assertFalse(os.path.exists("/" + name), "a folder made at the root")
        rc, log = harness.blender_batch(["--frames", "1", "--resolution", "16x8", "--scene-script", "still_life",
                                         "-o", "//" + name])
        self.assertEqual(rc, 2, log[-2000:])
        self.assertIn("crisp: error: the output folder '//%s' is relative to the .blend file" % name, log)
        self.assertFalse(os.path.exists("/" + name), "a folder made at the root")

    def test_plan_only_prints_reasons(self):
        out = os.path.join(self.tmp.name, "plan")
        rc, log = harness.blender_batch(["--scene-script", "camera_dolly", "--method", "taa", "--plan-only", "-o", out])
        self.assertEqual(rc, 0, log[-2000:])
        self.assertIn("+ motion", log)
        self.assertIn("the camera move", log)
        self.assertEqual(files(out), ["run.json"])
        run = json.load(open(os.path.join(out, "run.json")))
        self.assertEqual(run["plan"]["passes"], ["color", "depth", "motion"])
        self.assertEqual(run["frames"], [])


if __name__ == "__main__":
    harness.run(BatchTest)
