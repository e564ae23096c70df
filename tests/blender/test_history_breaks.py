# SPDX-License-Identifier: GPL-2.0-or-later
"""Where a temporal filter's history must start over: a cut to another camera at a timeline marker,
and a gap in the frame numbers. still_life at 64x36 with a second camera bound to a marker at frame 4:
  * the plan lists the cut, and every frame is jittered through its own camera (the sidecar's
    projection differs from the unjittered one on both sides of the cut);
  * the add-on's run restarts the history at the cut (run.json says so) and its frames 4-6 equal, bit
    for bit, `crisp filter` over frames 4-6 alone, and so do `crisp filter`'s over frames 1-6;
  * `crisp filter` over frames 4 and 6 (5 missing) says the history starts over at 6 and gives the
    frame 6 of a run over frame 6 alone;
  * a frame without a sidecar between frames 4 and 6 is no gap: the history carries over to 6;
  * the add-on's own FrameFilter (native.py) restarts and carries over where `crisp filter` does."""

import json
import os
import subprocess
import sys
import tempfile
import unittest

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import harness  # noqa: E402

from crisp import native, pipeline, plan  # noqa: E402

CRISP = os.path.join(harness.BUILD_DIR, "bin", "crisp")


def cut_scene():
    scene = harness.cut_scene(4, 6)
    scene.render.resolution_x, scene.render.resolution_y, scene.render.resolution_percentage = 64, 36, 100
    return scene


def pixels(path):
    """The colour of an EXR as bytes, read by the library."""
    import ctypes
    with native.Context(1) as context, native.Frame(context, path) as frame:
        ptr, fmt = frame.pass_pointer("color")
        return ctypes.string_at(ptr, frame.width * frame.height * native.FORMAT_CHANNELS[fmt] * 4)


class HistoryBreakTest(unittest.TestCase):
    @classmethod
    def setUpClass(cls):
        ok, why = harness.library_usable()
        if not ok:
            raise unittest.SkipTest(why)
        cls.scene = cut_scene()
        cls.tmp = tempfile.TemporaryDirectory()
        cls.out = os.path.join(cls.tmp.name, "run")
        cls.result = pipeline.run(cls.scene, "taa", range(1, 7), cls.out, threads=1, log=lambda s: None)
        cls.inputs = [os.path.join(cls.out, "input", "frame_%04d.exr" % f) for f in range(1, 7)]

    @classmethod
    def tearDownClass(cls):
        cls.tmp.cleanup()

    def frame_filter(self, name, inputs):
        """The add-on's own FrameFilter (as pipeline.run uses it) over `inputs` in order: the output
        folder and the restart reason of each frame."""
        out = os.path.join(self.tmp.name, name)
        os.makedirs(out)
        ff = native.FrameFilter("taa", threads=1, passes=tuple(self.result["plan"]["passes"]))
        reasons = []
        try:
            for path in inputs:
                ff.run(path, [os.path.join(out, os.path.basename(path))])
                reasons.append(ff.restart_reason)
        finally:
            ff.close()
        return out, reasons

    def crisp_filter(self, name, inputs, quiet=True):
        out = os.path.join(self.tmp.name, name)
        p = subprocess.run([CRISP, "filter", "-m", "taa", "--threads", "1", "-o", out] + ["--quiet"] * quiet + inputs,
                           stdout=subprocess.PIPE, stderr=subprocess.PIPE, timeout=120)
        self.assertEqual(p.returncode, 0, p.stderr.decode())
        return out, p.stderr.decode()

    def test_plan_lists_the_cut_and_each_camera_is_jittered(self):
        facts = plan.scene_facts(self.scene, 1, 6)
        self.assertEqual(facts.camera_cuts, [4])
        self.assertEqual(self.scene.camera.name, "Camera", "the scene's camera is put back")
        for f in range(1, 7):
            with open(os.path.join(self.out, "input", "frame_%04d.json" % f)) as fh:
                side = json.load(fh)
            self.assertEqual(side["camera"]["name"], "Camera" if f < 4 else "CamB")
            jittered = abs(side["jitter"]["x"]) + abs(side["jitter"]["y"]) > 1e-6
            self.assertEqual(side["camera"]["projection"] != side["camera"]["projection_unjittered"], jittered,
                             "frame %d: the jitter reached the frame's own camera" % f)
        self.assertEqual(self.scene.objects["CamB"].data.shift_x, 0.0, "CamB's shift is put back")
        # A frame list given backwards (the Python API allows it) is planned over its whole span.
        _, backwards = pipeline.scene_plan(self.scene, "taa", [6, 5, 3])
        self.assertEqual((backwards.frame_start, backwards.frame_end, backwards.camera_cuts), (3, 6, [4]))
        self.assertIn("Ball", backwards.visible_objects)

    def test_cut_restarts_the_history(self):
        restarts = {e["frame"]: e.get("history_restarted") for e in self.result["frames"]}
        self.assertEqual([f for f, why in restarts.items() if why], [4])
        self.assertIn("CamB", restarts[4])
        alone, _ = self.crisp_filter("from4", self.inputs[3:])
        whole, err = self.crisp_filter("whole", self.inputs, quiet=False)
        self.assertIn("history starts over (camera 'CamB' after 'Camera')", err)
        for f in (4, 5, 6):
            want = pixels(os.path.join(alone, "frame_%04d.exr" % f))
            for folder in (os.path.join(self.out, "filtered"), whole):
                self.assertEqual(pixels(os.path.join(folder, "frame_%04d.exr" % f)), want, (folder, f))

    def test_gap_restarts_the_history(self):
        gap, err = self.crisp_filter("gap", [self.inputs[3], self.inputs[5]], quiet=False)  # frames 4 and 6 of CamB
        self.assertIn("history starts over (frame 6 after frame 4)", err)
        quiet, quiet_err = self.crisp_filter("gap_quiet", [self.inputs[3], self.inputs[5]])
        # --quiet hides progress, not this warning (docs/farm.md tells farm users to look for it).
        self.assertIn("history starts over (frame 6 after frame 4)", quiet_err)
        self.assertEqual(len(quiet_err.strip().splitlines()), 1, quiet_err)
        alone, _ = self.crisp_filter("from6", [self.inputs[5]])
        for folder in (gap, quiet):
            self.assertEqual(pixels(os.path.join(folder, "frame_0006.exr")),
                             pixels(os.path.join(alone, "frame_0006.exr")), folder)
        # With frame 5 between them the history carries over: the check above can fail.
        self.assertNotEqual(pixels(os.path.join(alone, "frame_0006.exr")),
                            pixels(os.path.join(self.out, "filtered", "frame_0006.exr")))
        # The add-on's FrameFilter restarts there too, and backwards, as the CLI does.
        ours, reasons = self.frame_filter("gap_addon", [self.inputs[3], self.inputs[5]])
        self.assertEqual(reasons, [None, "frame 6 after frame 4"])
        self.assertEqual(pixels(os.path.join(ours, "frame_0006.exr")), pixels(os.path.join(alone, "frame_0006.exr")))
        _, reasons = self.frame_filter("backwards_addon", [self.inputs[5], self.inputs[4]])
        self.assertEqual(reasons, [None, "frame 5 after frame 6"])

    def test_frames_out_of_order_are_recorded_as_given(self):
        """A frame list out of order (the Python API takes one) restarts the history where it goes back,
        and run.json records the list, not a range it is not (it read [3, 2] for [3, 1, 2])."""
        out = os.path.join(self.tmp.name, "out_of_order")
        result = pipeline.run(self.scene, "taa", [3, 1, 2], out, threads=1, log=lambda s: None)
        with open(os.path.join(out, "run.json")) as fh:
            record = json.load(fh)
        self.assertEqual(record["frame_list"], [3, 1, 2])
        self.assertEqual([e["frame"] for e in record["frames"]], [3, 1, 2])
        restarts = {e["frame"]: e.get("history_restarted") for e in result["frames"]}
        self.assertEqual(restarts, {3: None, 1: "frame 1 after frame 3", 2: None})
        # An evenly stepped range keeps the two-number record alone.
        self.assertNotIn("frame_list", self.result)

    def test_frame_without_sidecar_is_no_gap(self):
        """A frame without a sidecar (its position unknown) between frames 4 and 6 is no gap: the
        history carries over to 6 (the run once compared 6 with 4, saw a gap and restarted, where a
        chunk starting at 5 did not)."""
        folder = os.path.join(self.tmp.name, "no_sidecar_5")
        os.makedirs(folder)
        for f in (4, 5, 6):
            for ext in (".exr", ".json") if f != 5 else (".exr",):
                src = os.path.join(self.out, "input", "frame_%04d%s" % (f, ext))
                with open(src, "rb") as a, open(os.path.join(folder, os.path.basename(src)), "wb") as b:
                    b.write(a.read())
        inputs = [os.path.join(folder, "frame_%04d.exr" % f) for f in (4, 5, 6)]
        whole, err = self.crisp_filter("no_sidecar_whole", inputs, quiet=False)
        self.assertNotIn("starts over", err)
        alone, _ = self.crisp_filter("no_sidecar_6", inputs[2:])
        self.assertNotEqual(pixels(os.path.join(whole, "frame_0006.exr")), pixels(os.path.join(alone, "frame_0006.exr")))
        # The add-on's FrameFilter agrees: no restart at 6, and the same frame 6 as the CLI's.
        ours, reasons = self.frame_filter("no_sidecar_addon", inputs)
        self.assertEqual(reasons, [None, None, None])
        self.assertEqual(pixels(os.path.join(ours, "frame_0006.exr")), pixels(os.path.join(whole, "frame_0006.exr")))

    def test_a_linked_camera_of_the_local_ones_name_is_a_cut(self):
        """The marker at frame 4 switches to a camera linked from another file and named "Camera" as the
        local one: the plan saw no cut and the sidecars named both "Camera" (cameras were told apart by
        name), so the history carried over the cut. The plan lists it, the sidecars name the linked one by
        its full name, and the run restarts there."""
        import bpy
        local = self.scene.camera
        marker = next(m for m in self.scene.timeline_markers if m.frame == 4)
        asset = os.path.join(self.tmp.name, "camera_asset.blend")
        local.name = "Camera (local)"  # the library's camera takes the name, then the local one gets it back
        other = bpy.data.objects.new("Camera", bpy.data.cameras.new("Asset lens"))
        other.location, other.rotation_euler = (3.5, -4.0, 2.0), (1.2, 0.0, 0.6)
        bpy.data.libraries.write(asset, {other}, fake_user=True)
        bpy.data.objects.remove(other)
        local.name = "Camera"
        with bpy.data.libraries.load(asset, link=True) as (_, linked):
            linked.objects = ["Camera"]
        linked_camera = linked.objects[0]
        self.scene.collection.objects.link(linked_camera)
        bound = marker.camera
        try:
            marker.camera = linked_camera
            self.assertEqual(plan.scene_facts(self.scene, 1, 6).camera_cuts, [4])
            out = os.path.join(self.tmp.name, "linked_camera")
            result = pipeline.run(self.scene, "taa", [3, 4], out, threads=1, log=lambda s: None)
            names = []
            for f in (3, 4):
                with open(os.path.join(out, "input", "frame_%04d.json" % f)) as fh:
                    names.append(json.load(fh)["camera"]["name"])
            self.assertEqual(names, ["Camera", linked_camera.name_full])
            restarted = {e["frame"]: e.get("history_restarted") for e in result["frames"]}
            self.assertTrue(restarted[4], result["frames"])
        finally:
            marker.camera = bound
            self.scene.collection.objects.unlink(linked_camera)
            bpy.data.libraries.remove(linked_camera.library)

if __name__ == "__main__":
    harness.run(HistoryBreakTest)
