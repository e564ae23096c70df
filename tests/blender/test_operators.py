# SPDX-License-Identifier: GPL-2.0-or-later
"""The panel's operators as an artist runs them: Render Reference, Render with Crisp, Compare and
Load into Compositor, on a scene whose user picked Cycles (Crisp renders with EEVEE and gives the
scene back as it was)."""

import contextlib
import io
import json
import math
import os
import shutil
import subprocess
import sys
import tempfile
import unittest

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import harness  # noqa: E402

import bpy  # noqa: E402
import crisp  # noqa: E402
from crisp import compositor, exr_file, native, operators, pipeline  # noqa: E402

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
        s.input_codec = "piz"

        self.assertEqual(bpy.ops.crisp.render_reference(), {"FINISHED"})
        self.assertEqual(bpy.ops.crisp.render(), {"FINISHED"})
        self.assertEqual(bpy.ops.crisp.compare(), {"FINISHED"})

        ref = sorted(f for f in os.listdir(os.path.join(self.tmp.name, "reference")) if f.endswith(".exr"))
        self.assertEqual(ref, ["frame_0001.exr", "frame_0002.exr"])
        for folder in ("reference", "input"):  # the panel's Input Codec
            with open(os.path.join(self.tmp.name, folder, "frame_0002.exr"), "rb") as fh:
                self.assertEqual(exr_file.read_header(fh.read(1 << 16))[1]["compression"][1], b"\x04", folder)  # PIZ
        self.assertTrue(os.path.isfile(os.path.join(self.tmp.name, "filtered", "frame_0002.exr")))
        # Compare measured something real: a 4-sample reference is close to, not equal to, FXAA's frame.
        self.assertTrue(math.isfinite(s.last_psnr) and 15.0 < s.last_psnr < 60.0, s.last_compare)
        self.assertTrue(0.5 < s.last_ssim <= 1.0, s.last_compare)
        self.assertIn("2 frames", s.last_compare)
        # One run's sequence, until a frame's input is newer than its output (a stopped run) or missing.
        frames = [1, 2]
        self.assertEqual(pipeline.sequence_warnings(self.tmp.name, frames), [])
        side = os.path.join(self.tmp.name, "input", "frame_0002.json")
        st = os.stat(side)
        os.utime(side, ns=(st.st_atime_ns, st.st_mtime_ns + 10**9))
        self.assertEqual(bpy.ops.crisp.load_result(), {"FINISHED"})  # loads, and warns
        warned = pipeline.sequence_warnings(self.tmp.name, frames + [3])
        self.assertTrue(any("frame 2 is older than its input" in w for w in warned), warned)
        self.assertTrue(any("frame 3 has no filtered image" in w for w in warned), warned)
        os.utime(side, ns=(st.st_atime_ns, st.st_mtime_ns))
        # A reference holding NaN has no error to measure: refused, as `crisp compare` refuses it.
        ref1 = os.path.join(self.tmp.name, "reference", "frame_0001.exr")
        subprocess.run(["oiiotool", ref1, "--subc", "1", "--powc", "0.5", "-d", "float", "-o", ref1 + ".nan.exr"],
                       check=True, capture_output=True)
        os.replace(ref1 + ".nan.exr", ref1)
        with self.assertRaises(RuntimeError) as ctx:
            bpy.ops.crisp.compare()
        self.assertIn("non-finite colour values", str(ctx.exception))
        self.assertIn("frame_0001.exr", str(ctx.exception))
        self.assertEqual(scene.render.engine, "CYCLES", "the user's engine was not restored")
        self.assertIn("Crisp Result: " + scene.name, [g.name for g in bpy.data.node_groups])
        # Still-frame preview: the current frame's filtered PNG becomes an image Blender can show.
        scene.frame_set(2)
        self.assertEqual(bpy.ops.crisp.preview(), {"FINISHED"})
        shown = [i for i in bpy.data.images if i.filepath.endswith("frame_0002.png")]
        self.assertEqual(len(shown), 1)
        self.assertEqual(tuple(shown[0].size), (64, 36))

    def test_two_scenes_of_one_file_keep_their_own_frames(self):
        # Both scenes keep the default output folder: //crisp/<scene name>/ beside the saved file.
        a = harness.build_scene("still_life")
        a.render.resolution_x, a.render.resolution_y, a.render.resolution_percentage = 64, 36, 100
        a.frame_start, a.frame_end = 1, 1
        a.crisp.method = "fxaa"
        a.crisp.load_result = a.crisp.write_png = True
        a.crisp.property_unset("output_dir")  # build_scene may hand back the scene an earlier test set
        a.use_nodes = True  # a result loaded before the copy: the copy's compositor holds a's node
        a.node_tree.nodes.clear()
        for g in [g for g in bpy.data.node_groups if g.name.startswith("Crisp Result")]:
            bpy.data.node_groups.remove(g)
        earlier = a.node_tree.nodes.new("CompositorNodeGroup")
        earlier.node_tree = bpy.data.node_groups.new("Crisp Result: " + a.name, "CompositorNodeTree")
        earlier["crisp_result"] = True  # as compositor.load_result tags its node
        b = a.copy()
        b.name = "Other Shot"
        b.render.resolution_x, b.render.resolution_y = 48, 28
        bpy.ops.wm.save_as_mainfile(filepath=os.path.join(self.tmp.name, "two.blend"))

        def in_scene(scene, op):
            with bpy.context.temp_override(scene=scene, view_layer=scene.view_layers[0]):
                self.assertEqual(op(), {"FINISHED"})

        for scene in (a, b):
            self.assertEqual(scene.crisp.output_dir, "")
            in_scene(scene, bpy.ops.crisp.render)
        folder = {a: os.path.join(self.tmp.name, "crisp", a.name), b: os.path.join(self.tmp.name, "crisp", "Other Shot")}
        for scene, size in ((a, (64, 36)), (b, (48, 28))):
            exr = bpy.data.images.load(os.path.join(folder[scene], "filtered", "frame_0001.exr"))
            self.assertEqual(tuple(exr.size), size, exr.filepath)
            bpy.data.images.remove(exr)
            # One node each (the copy's node of the first scene's group was switched to its own group).
            node, = [n for n in scene.node_tree.nodes if n.bl_idname == "CompositorNodeGroup"]
            self.assertEqual(os.path.normpath(bpy.path.abspath(node.node_tree.get("crisp_folder"))),
                             os.path.join(folder[scene], "filtered"))
            self.assertEqual(scene.crisp.output_dir, "//crisp/%s/" % os.path.basename(folder[scene]), "pinned")
            shown = bpy.path.abspath(node.node_tree.nodes["Crisp Frames"].image.filepath)
            self.assertEqual(os.path.dirname(os.path.normpath(shown)), os.path.join(folder[scene], "filtered"))

        # Again without PNGs: the first run's PNG goes, so Preview Frame shows this run's EXR; one the
        # user changed since stays.
        png = os.path.join(folder[a], "filtered", "frame_0001.png")
        self.assertTrue(os.path.isfile(png))
        b.crisp.write_png = False
        edited = os.path.join(folder[b], "filtered", "frame_0001.png")
        with open(edited, "ab") as f:
            f.write(b"painted")
        in_scene(b, bpy.ops.crisp.render)
        self.assertTrue(os.path.isfile(edited), "a PNG the user changed was deleted")
        a.crisp.write_png = False
        a.crisp.method = "repair"
        in_scene(a, bpy.ops.crisp.render)
        self.assertFalse(os.path.exists(png), "a PNG of the fxaa run beside repair's EXR")
        a.frame_current = 1
        in_scene(a, bpy.ops.crisp.preview)
        shown = {os.path.basename(i.filepath) for i in bpy.data.images}
        self.assertIn("frame_0001.exr", shown)
        self.assertNotIn("frame_0001.png", shown)

    def small_scene(self, first, last, load_result):
        scene = harness.build_scene("still_life")
        scene.render.resolution_x, scene.render.resolution_y, scene.render.resolution_percentage = 64, 36, 100
        scene.frame_start, scene.frame_end = first, last
        scene.crisp.method = "fxaa"
        scene.crisp.output_dir = self.tmp.name
        scene.crisp.load_result = load_result
        return scene

    def result_groups(self):
        return [g for g in bpy.data.node_groups if g.name.startswith(compositor.GROUP_NAME)]

    @staticmethod
    def save_as(path):
        os.makedirs(os.path.dirname(path), exist_ok=True)
        bpy.ops.wm.save_as_mainfile(filepath=path)

    def test_render_loads_every_frame_of_the_range(self):
        """Render with Crisp over frames 2..4 loads a sequence of all three into the compositor (the
        Image node starts at frame 2 and lasts 3 frames), not the first frame alone."""
        scene = self.small_scene(2, 4, load_result=True)
        self.assertEqual(bpy.ops.crisp.render(), {"FINISHED"})
        node = next(n for n in scene.node_tree.nodes if n.get(compositor.NODE_TAG))
        frames = node.node_tree.nodes["Crisp Frames"]
        self.assertEqual((frames.frame_start, frames.frame_duration), (2, 3))

    def test_the_runs_notes_reach_the_artist(self):
        """What the run says it leaves out (here the render region) is reported as a warning, in the Info
        editor, not printed to the console alone, where an artist in Blender's window never sees it."""
        scene = self.small_scene(1, 1, load_result=False)
        scene.render.use_border = True
        self.addCleanup(setattr, scene.render, "use_border", False)
        reports = io.StringIO()  # an operator's reports other than errors go to stdout
        with contextlib.redirect_stdout(reports):
            self.assertEqual(bpy.ops.crisp.render(), {"FINISHED"})
        self.assertIn("Warning: Crisp: the render region is not used", reports.getvalue())
        # (the scene may hold an earlier test's compositor, which is another note)
        self.assertRegex(reports.getvalue(),
                         "filtered with fxaa into %s; [1-9] notes? in the Info editor" % self.tmp.name)

    def test_render_reference_says_what_it_leaves_out(self):
        """Render Reference rendered a Cycles scene with EEVEE, without motion blur and the render region,
        and said none of it, where Render with Crisp says each (pipeline.scene_notes)."""
        scene = self.small_scene(1, 1, load_result=False)
        scene.crisp.reference_samples = 2
        scene.render.engine = "CYCLES"
        scene.render.use_border = True
        scene.render.use_motion_blur = True
        self.addCleanup(setattr, scene.render, "use_border", False)
        self.addCleanup(setattr, scene.render, "use_motion_blur", False)
        self.addCleanup(setattr, scene.render, "engine", "BLENDER_EEVEE")
        reports = io.StringIO()
        with contextlib.redirect_stdout(reports):
            self.assertEqual(bpy.ops.crisp.render_reference(), {"FINISHED"})
        said = reports.getvalue()
        self.assertIn("Warning: Crisp: the scene's engine is CYCLES; Crisp renders with EEVEE", said)
        self.assertIn("Warning: Crisp: the render region is not used: Crisp renders the whole frame", said)
        self.assertIn("Warning: Crisp: the scene's motion blur is off in Crisp's renders", said)
        self.assertEqual((scene.render.engine, scene.render.use_motion_blur), ("CYCLES", True))

    def test_a_note_per_frame_does_not_fill_the_info_editor(self):
        """A note made for each frame (here: a filtered PNG the artist changed, kept by a run without
        PNGs) is reported for the first few frames and counted for the rest; the console has them all."""
        scene = self.small_scene(1, 7, load_result=False)
        self.assertEqual(bpy.ops.crisp.render(), {"FINISHED"})
        for f in range(1, 8):
            with open(os.path.join(self.tmp.name, "filtered", "frame_%04d.png" % f), "ab") as png:
                png.write(b"\0")  # changed since: the artist's now
        scene.crisp.write_png = False
        reports = io.StringIO()
        try:
            with contextlib.redirect_stdout(reports):
                self.assertEqual(bpy.ops.crisp.render(), {"FINISHED"})
        finally:  # (not a cleanup: those run after tearDown has unregistered scene.crisp)
            scene.crisp.write_png = True
        warnings = [line for line in reports.getvalue().splitlines() if line.startswith("Warning: Crisp:")]
        kept = [line for line in warnings if "kept " in line]
        self.assertEqual(len(kept), operators.MAX_NOTES_REPORTED, reports.getvalue())
        self.assertIn("Warning: Crisp: and %d more notes in the console" % (7 - operators.MAX_NOTES_REPORTED),
                      reports.getvalue())
        self.assertRegex(reports.getvalue(), "; [7-9] notes in the Info editor")  # (and an earlier test's compositor)

    def test_load_result_warns_of_a_missing_last_frame(self):
        """Load into Compositor checks the scene's whole range, the last frame too: with that frame's
        filtered image gone it loads the rest and warns, naming the frame."""
        scene = self.small_scene(1, 2, load_result=False)
        self.assertEqual(bpy.ops.crisp.render(), {"FINISHED"})
        os.remove(os.path.join(self.tmp.name, "filtered", "frame_0002.exr"))
        reports = io.StringIO()  # an operator's reports other than errors go to stdout
        with contextlib.redirect_stdout(reports):
            self.assertEqual(bpy.ops.crisp.load_result(), {"FINISHED"})
        self.assertIn("frame 2 has no filtered image", reports.getvalue())
        self.assertIsNotNone(next((n for n in scene.node_tree.nodes if n.get(compositor.NODE_TAG)), None))

    def test_load_result_starts_at_the_first_frame_there_is(self):
        """With the range's first frames missing (a run of a later part of the range), Load into Compositor
        loads from the first frame there is, shown at its own scene frame, and warns of the others; with no
        frame of the range at all it fails, naming the range. (It failed whenever the first was missing.)"""
        scene = self.small_scene(2, 4, load_result=False)
        self.assertEqual(bpy.ops.crisp.render(), {"FINISHED"})
        os.remove(os.path.join(self.tmp.name, "filtered", "frame_0002.exr"))
        scene.frame_start = 1
        reports = io.StringIO()
        with contextlib.redirect_stdout(reports):
            self.assertEqual(bpy.ops.crisp.load_result(), {"FINISHED"})
        self.assertIn("frames 1, 2 have no filtered image", reports.getvalue())
        node = next(n for n in scene.node_tree.nodes if n.get(compositor.NODE_TAG))
        frames = node.node_tree.nodes["Crisp Frames"]
        self.assertEqual((frames.frame_start, frames.frame_duration, frames.frame_offset), (3, 2, 2))
        self.assertEqual(os.path.basename(frames.image.filepath), "frame_0003.exr")
        scene.frame_start, scene.frame_end = 6, 7
        with self.assertRaisesRegex(RuntimeError, "no filtered frame of frames 6-7 in .*filtered: render with "
                                                  "Crisp first"):
            bpy.ops.crisp.load_result()

    def test_the_result_follows_a_moved_project(self):
        """The compositor's frames are found after the project folder (the .blend with its //crisp/
        output) is moved or renamed: the image's path is relative to the .blend, as Blender's own Open
        Image makes it, and Load into Compositor there updates the same group, not a second one. (The
        path was absolute: after a move the node showed no image.)"""
        project = os.path.join(self.tmp.name, "project")
        scene = self.small_scene(1, 2, load_result=True)
        scene.crisp.property_unset("output_dir")  # the default, //crisp/<scene>/
        name = scene.name
        self.save_as(os.path.join(project, "shot.blend"))
        self.assertEqual(bpy.ops.crisp.render(), {"FINISHED"})
        bpy.ops.wm.save_mainfile()
        moved = os.path.join(self.tmp.name, "moved")
        os.rename(project, moved)
        bpy.ops.wm.open_mainfile(filepath=os.path.join(moved, "shot.blend"))
        scene = bpy.data.scenes[name]
        node = next(n for n in scene.node_tree.nodes if n.get(compositor.NODE_TAG))
        image = node.node_tree.nodes["Crisp Frames"].image
        shown = os.path.normpath(bpy.path.abspath(image.filepath))
        self.assertEqual(shown, os.path.join(moved, "crisp", name, "filtered", "frame_0001.exr"))
        image.reload()
        self.assertEqual(tuple(image.size), (64, 36))
        with bpy.context.temp_override(scene=scene, view_layer=scene.view_layers[0]):
            self.assertEqual(bpy.ops.crisp.load_result(), {"FINISHED"})
        self.assertEqual(self.result_groups(), [node.node_tree])

    def test_a_rerun_keeps_the_artists_compositing(self):
        """As an artist works: a scene whose compositor is in use (Render Layers -> Glare -> Composite) is
        rendered with a temporal method, Crisp's node is wired into the tree and, inside Crisp's group, a
        colour grade is put between the frames and the group's output (where the run's note says to apply
        the compositor); the scene is renamed, rendered again and loaded again. Every run finds the same
        node, group and image, and leaves every link, the group's inside too, and the nodes' places as
        the artist left them; the group takes the scene's new name. (A re-run wired the frames straight to the group's output again, cutting
        the grade out of the chain, and moved the group's nodes back.)"""
        bpy.ops.wm.read_homefile(use_empty=True)
        scene = self.small_scene(1, 3, load_result=True)
        scene.crisp.method = "taa"
        tree, layers, composite, glare = self.glare_tree(scene)

        links = self.links

        self.assertEqual(bpy.ops.crisp.render(), {"FINISHED"})
        self.assertEqual(links(tree), [("Glare", "Image", "Composite", "Image"),
                                       ("Render Layers", "Image", "Glare", "Image")])
        node, = [n for n in tree.nodes if n.get(compositor.NODE_TAG)]
        group = node.node_tree
        frames = group.nodes["Crisp Frames"]
        self.assertEqual(os.path.normpath(bpy.path.abspath(frames.image.filepath)),
                         os.path.join(self.tmp.name, "filtered", "frame_0001.exr"))
        self.assertEqual((frames.frame_start, frames.frame_duration, frames.frame_offset), (1, 3, 0))
        mix = tree.nodes.new("CompositorNodeMixRGB")
        tree.links.new(node.outputs["Image"], mix.inputs[1])
        tree.links.new(glare.outputs["Image"], mix.inputs[2])
        tree.links.new(node.outputs["Alpha"], mix.inputs["Fac"])
        tree.links.new(mix.outputs["Image"], composite.inputs["Image"])
        grade = group.nodes.new("CompositorNodeColorBalance")
        group.links.new(frames.outputs["Image"], grade.inputs["Image"])
        group.links.new(grade.outputs["Image"], group.nodes["Group Output"].inputs["Image"])
        frames.location = (-700, 120)
        node.location = (40, -500)
        node.label = "Crisp AA"
        placed = {n.name: tuple(n.location) for t in (tree, group) for n in t.nodes}
        wired = (links(tree), links(group))

        scene.name = "sh010"
        bpy.data.scenes.new("Scene")  # a new scene of the old name: the group's name is no longer its
        scene.crisp.method = "fxaa"
        self.assertEqual(bpy.ops.crisp.render(), {"FINISHED"})
        self.assertEqual(bpy.ops.crisp.load_result(), {"FINISHED"})
        self.assertEqual([n for n in tree.nodes if n.bl_idname == "CompositorNodeGroup"], [node])
        self.assertEqual(self.result_groups(), [group])
        self.assertEqual((node.node_tree, node.label), (group, "Crisp AA"))
        self.assertEqual(group.name, "Crisp Result: sh010")
        group.name = "Crisp Result: the AA pass"  # the artist's name for it stays
        self.assertEqual(bpy.ops.crisp.load_result(), {"FINISHED"})
        self.assertEqual(group.name, "Crisp Result: the AA pass")
        self.assertEqual([i for i in bpy.data.images if i.source == "SEQUENCE"], [frames.image])
        self.assertEqual((links(tree), links(group)), wired)
        self.assertEqual({n.name: tuple(n.location) for t in (tree, group) for n in t.nodes}, placed)
        self.assertEqual((frames.frame_start, frames.frame_duration, frames.frame_offset), (1, 3, 0))

    @staticmethod
    def glare_tree(scene):
        """The scene's compositor in use with the artist's nodes: Render Layers -> Glare -> Composite.
        Returns (tree, layers, composite, glare)."""
        scene.use_nodes = True
        tree = scene.node_tree
        tree.nodes.clear()
        layers, composite = tree.nodes.new("CompositorNodeRLayers"), tree.nodes.new("CompositorNodeComposite")
        glare = tree.nodes.new("CompositorNodeGlare")
        tree.links.new(layers.outputs["Image"], glare.inputs["Image"])
        tree.links.new(glare.outputs["Image"], composite.inputs["Image"])
        return tree, layers, composite, glare

    @staticmethod
    def links(tree):
        return sorted((l.from_node.name, l.from_socket.identifier, l.to_node.name, l.to_socket.identifier)
                      for l in tree.links)

    def test_the_render_takes_the_loaded_frames(self):
        """Render with Crisp loading its frames into Blender's default compositor (Render Layers ->
        Composite) links Crisp's node into Composite, so the render (F12) is the filtered frames; it left
        them beside it, and the render was the unfiltered one unless the artist wired it. Linked once: the
        artist who takes the render back into Composite afterwards keeps it, on later runs and loads too,
        which say how to connect the frames again."""
        bpy.ops.wm.read_homefile(use_empty=True)
        scene = self.small_scene(1, 1, load_result=True)
        reports = io.StringIO()
        with contextlib.redirect_stdout(reports):
            self.assertEqual(bpy.ops.crisp.render(), {"FINISHED"})
        self.assertNotIn("Composite", reports.getvalue())
        tree = scene.node_tree
        node, = [n for n in tree.nodes if n.get(compositor.NODE_TAG)]
        composite, layers = tree.nodes["Composite"], tree.nodes["Render Layers"]
        self.assertEqual([l.from_node for l in composite.inputs["Image"].links], [node])
        tree.links.new(layers.outputs["Image"], composite.inputs["Image"])  # the artist's choice
        wired = self.links(tree)
        for op in (bpy.ops.crisp.render, bpy.ops.crisp.load_result):
            reports = io.StringIO()
            with contextlib.redirect_stdout(reports):
                self.assertEqual(op(), {"FINISHED"})
            self.assertEqual(self.links(tree), wired, op)
            self.assertIn("Warning: Crisp: the compositor's Composite node does not take the filtered frames",
                          reports.getvalue())

    def test_a_render_layers_plate_of_another_scene_or_layer_is_not_replaced(self):
        """Composite taking a Render Layers node of another scene, or of another view layer of this one,
        straight: that is the artist's plate, not the render Crisp filtered. Load into Compositor left it
        in place of the filtered frames (the plate went from the render); it leaves their tree as it is
        and says how to connect Crisp's node. A node of the filtered layer is still linked."""
        bpy.ops.wm.read_homefile(use_empty=True)
        scene = self.small_scene(1, 1, load_result=False)
        self.assertEqual(bpy.ops.crisp.render(), {"FINISHED"})
        plate = bpy.data.scenes.new("Plate")
        self.addCleanup(bpy.data.scenes.remove, plate)
        layer = scene.view_layers.new("Plate Layer")
        self.addCleanup(scene.view_layers.remove, layer)
        scene.use_nodes = True
        tree = scene.node_tree
        for case in ("another scene", "another layer", "the filtered layer"):
            tree.nodes.clear()
            layers, composite = tree.nodes.new("CompositorNodeRLayers"), tree.nodes.new("CompositorNodeComposite")
            if case == "another scene":
                layers.scene = plate
            elif case == "another layer":
                layers.layer = "Plate Layer"
            tree.links.new(layers.outputs["Image"], composite.inputs["Image"])
            theirs = self.links(tree)
            reports = io.StringIO()
            with contextlib.redirect_stdout(reports):
                self.assertEqual(bpy.ops.crisp.load_result(), {"FINISHED"})
            node, = [n for n in tree.nodes if n.get(compositor.NODE_TAG)]
            if case == "the filtered layer":
                self.assertEqual(self.links(tree), [(node.name, node.outputs["Image"].identifier, "Composite",
                                                     "Image")])
            else:
                self.assertEqual(self.links(tree), theirs, case)
                self.assertIn("Warning: Crisp: the compositor's Composite node does not take the filtered frames",
                              reports.getvalue())

    def load_reports(self, op=None):
        """Runs Load into Compositor (or `op`), FINISHED; what it printed (its reports)."""
        reports = io.StringIO()
        with contextlib.redirect_stdout(reports):
            self.assertEqual((op or bpy.ops.crisp.load_result)(), {"FINISHED"})
        return reports.getvalue()

    def test_each_composite_node_takes_the_frames_or_is_named(self):
        """Two Composite nodes, one through the artist's Invert and one straight from Render Layers: Blender
        renders only the active one, which Python cannot read. Load into Compositor linked Crisp's node into
        the straight one and said nothing, and the render (the inverted one, here) was not the filtered
        frames; it still links the straight one, and names the other as not taking them. Two straight ones
        both take them, without a note."""
        bpy.ops.wm.read_homefile(use_empty=True)
        scene = self.small_scene(1, 1, load_result=False)
        self.assertEqual(bpy.ops.crisp.render(), {"FINISHED"})
        scene.use_nodes = True
        tree = scene.node_tree
        for graded in (True, False):
            tree.nodes.clear()
            layers = tree.nodes.new("CompositorNodeRLayers")
            straight, other = (tree.nodes.new("CompositorNodeComposite") for _ in range(2))
            straight.name, other.name = "Composite Straight", "Composite Graded"
            tree.links.new(layers.outputs["Image"], straight.inputs["Image"])
            if graded:
                invert = tree.nodes.new("CompositorNodeInvert")
                tree.links.new(layers.outputs["Image"], invert.inputs["Color"])
                tree.links.new(invert.outputs["Color"], other.inputs["Image"])
            else:
                tree.links.new(layers.outputs["Image"], other.inputs["Image"])
            tree.nodes.active = other
            reports = self.load_reports()
            node, = [n for n in tree.nodes if n.get(compositor.NODE_TAG)]
            into = sorted(l.to_node.name for l in node.outputs["Image"].links)
            if graded:
                self.assertEqual(into, ["Composite Straight"])
                self.assertIn("Warning: Crisp: the compositor has 2 Composite nodes and Blender renders only the "
                              "active one, which an add-on cannot see; 'Composite Graded' does not take the "
                              "filtered frames", reports)
            else:
                self.assertEqual(into, ["Composite Graded", "Composite Straight"])
                self.assertNotIn("Composite", reports)

    def test_compositing_switched_off_stays_off_where_the_artists_nodes_would_change_the_render(self):
        """The artist's tree (Render Layers -> Glare -> Composite) with Use Nodes switched off: Render with
        Crisp turned it on without a word, so the render took the Glare the artist had switched off. It is
        left off, with Crisp's node in the tree and a note saying how to render the frames. Blender's
        default tree switched off is turned on and takes the frames, as a scene without a tree."""
        bpy.ops.wm.read_homefile(use_empty=True)
        scene = self.small_scene(1, 1, load_result=True)
        tree, layers, composite, glare = self.glare_tree(scene)
        theirs = self.links(tree)
        scene.use_nodes = False
        reports = self.load_reports(bpy.ops.crisp.render)
        self.assertFalse(scene.use_nodes)
        self.assertEqual(self.links(tree), theirs)
        self.assertEqual(len([n for n in tree.nodes if n.get(compositor.NODE_TAG)]), 1)
        self.assertIn("Warning: Crisp: the compositor's Use Nodes is off, so the render (F12) is the unfiltered "
                      "one", reports)
        self.assertNotIn("is not applied to Crisp's frames", reports)
        tree.nodes.remove(glare)
        tree.links.new(layers.outputs["Image"], composite.inputs["Image"])
        reports = self.load_reports()
        self.assertTrue(scene.use_nodes)
        node, = [n for n in tree.nodes if n.get(compositor.NODE_TAG)]
        self.assertEqual([l.from_node for l in composite.inputs["Image"].links], [node])
        self.assertNotIn("Warning", reports)

    def test_a_plate_of_another_scenes_frames_is_not_taken_for_this_scenes(self):
        """A second scene whose Composite takes a node of the first scene's result group (that shot's
        filtered frames as a plate): its run took that node for its own frames, so its render showed the
        other shot's frames and nothing was said. Its run says the compositor is not applied to its frames,
        and Load into Compositor adds its own group's node and says its Composite does not take it."""
        bpy.ops.wm.read_homefile(use_empty=True)
        a = self.small_scene(1, 1, load_result=True)
        self.assertEqual(bpy.ops.crisp.render(), {"FINISHED"})
        theirs, = [n for n in a.node_tree.nodes if n.get(compositor.NODE_TAG)]
        b = a.copy()
        b.name = "Other Shot"
        b.crisp.output_dir = os.path.join(self.tmp.name, "b")
        tree = b.node_tree
        for n in [n for n in tree.nodes if n.bl_idname == "CompositorNodeGroup"]:
            tree.nodes.remove(n)
        plate = tree.nodes.new("CompositorNodeGroup")
        plate.node_tree = theirs.node_tree
        plate.name = "Plate"
        tree.links.new(plate.outputs["Image"], tree.nodes["Composite"].inputs["Image"])
        wired = self.links(tree)
        with bpy.context.temp_override(scene=b, view_layer=b.view_layers[0]):
            reports = self.load_reports(bpy.ops.crisp.render)
            self.assertIn("note: the scene's compositor is not applied to Crisp's frames", reports)
            reports = self.load_reports()
        self.assertIn("Warning: Crisp: the compositor's Composite node does not take the filtered frames", reports)
        node, = [n for n in tree.nodes if n.get(compositor.NODE_TAG)]
        self.assertNotEqual(node.node_tree, theirs.node_tree)
        self.assertEqual(os.path.dirname(os.path.normpath(bpy.path.abspath(
            node.node_tree.nodes["Crisp Frames"].image.filepath))), os.path.join(self.tmp.name, "b", "filtered"))
        self.assertEqual([l for l in self.links(tree) if node.name not in (l[0], l[2])], wired)

    def test_loading_leaves_the_artists_compositing_and_says_how_to_connect(self):
        """Load into Compositor with the artist's nodes between Render Layers and Composite (a glare) does
        not rewire their tree: it says how to connect Crisp's node. The Viewer is left showing what the
        artist last looked at. Once their tree takes the render straight again, a load links Crisp's node
        into Composite, its Alpha too where Composite takes the render's."""
        bpy.ops.wm.read_homefile(use_empty=True)
        scene = self.small_scene(1, 1, load_result=False)
        self.assertEqual(bpy.ops.crisp.render(), {"FINISHED"})
        scene.use_nodes = True
        tree = scene.node_tree
        tree.nodes.clear()
        layers, composite = tree.nodes.new("CompositorNodeRLayers"), tree.nodes.new("CompositorNodeComposite")
        glare, viewer = tree.nodes.new("CompositorNodeGlare"), tree.nodes.new("CompositorNodeViewer")
        tree.links.new(layers.outputs["Image"], glare.inputs["Image"])
        tree.links.new(glare.outputs["Image"], composite.inputs["Image"])
        tree.links.new(layers.outputs["Alpha"], composite.inputs["Alpha"])
        tree.links.new(layers.outputs["Image"], viewer.inputs["Image"])
        theirs = self.links(tree)
        reports = io.StringIO()
        with contextlib.redirect_stdout(reports):
            self.assertEqual(bpy.ops.crisp.load_result(), {"FINISHED"})
        self.assertEqual(self.links(tree), theirs)
        self.assertIn("Warning: Crisp: the compositor's Composite node does not take the filtered frames, so the "
                      "render (F12) is the unfiltered one: link the 'Crisp Result' node's Image output into",
                      reports.getvalue())
        tree.nodes.remove(glare)
        tree.links.new(layers.outputs["Image"], composite.inputs["Image"])
        reports = io.StringIO()
        with contextlib.redirect_stdout(reports):
            self.assertEqual(bpy.ops.crisp.load_result(), {"FINISHED"})
        self.assertNotIn("Composite", reports.getvalue())
        node, = [n for n in tree.nodes if n.get(compositor.NODE_TAG)]
        image, alpha = (node.outputs[name].identifier for name in ("Image", "Alpha"))
        self.assertEqual(self.links(tree), sorted([(node.name, image, "Composite", "Image"),
                                                   (node.name, alpha, "Composite", "Alpha"),
                                                   ("Render Layers", "Image", "Viewer", "Image")]))
        # The render does not take them either with the compositor off, or without a Composite node.
        scene.render.use_compositing = False
        self.addCleanup(setattr, scene.render, "use_compositing", True)
        for change, expected in ((lambda: None, "Post Processing > Compositing is off"),
                                 (lambda: tree.nodes.remove(composite), "the compositor has no Composite node")):
            change()
            reports = io.StringIO()
            with contextlib.redirect_stdout(reports):
                self.assertEqual(bpy.ops.crisp.load_result(), {"FINISHED"})
            self.assertIn("Warning: Crisp: " + expected, reports.getvalue())

    def test_a_deleted_result_group_is_made_again_in_the_same_node(self):
        """The artist deletes Crisp's group (Outliner, Blender File > Node Groups > Delete): Crisp's node
        in the compositor is left showing nothing, its links kept. Load into Compositor makes the group
        again and puts it in that node, links and all, rather than a second node beside the empty one."""
        bpy.ops.wm.read_homefile(use_empty=True)
        scene = self.small_scene(1, 1, load_result=True)
        self.assertEqual(bpy.ops.crisp.render(), {"FINISHED"})
        tree = scene.node_tree
        node, = [n for n in tree.nodes if n.get(compositor.NODE_TAG)]
        composite = next(n for n in tree.nodes if n.bl_idname == "CompositorNodeComposite")
        tree.links.new(node.outputs["Image"], composite.inputs["Image"])
        bpy.data.node_groups.remove(node.node_tree)
        self.assertIsNone(node.node_tree)
        self.assertEqual(bpy.ops.crisp.load_result(), {"FINISHED"})
        self.assertEqual([n for n in tree.nodes if n.bl_idname == "CompositorNodeGroup"], [node])
        self.assertEqual(self.result_groups(), [node.node_tree])
        self.assertEqual([l.from_node for l in composite.inputs["Image"].links], [node])

    def test_a_range_starting_elsewhere_leaves_no_image_behind(self):
        """Renders of ranges that start at other frames load sequences starting at other files: the one
        the group showed before, shown nowhere else now, goes, and the one shown takes its name. (Each
        such render left one more image in the file: "Crisp Scene.001", ".002", ...)"""
        bpy.ops.wm.read_homefile(use_empty=True)
        scene = self.small_scene(1, 2, load_result=True)
        self.assertEqual(bpy.ops.crisp.render(), {"FINISHED"})
        kept = bpy.data.images.new("the artist's", 4, 4)
        for first, last in ((3, 4), (2, 3), (1, 2)):
            scene.frame_start, scene.frame_end = first, last
            self.assertEqual(bpy.ops.crisp.render(), {"FINISHED"})
            node = next(n for n in scene.node_tree.nodes if n.get(compositor.NODE_TAG))
            shown = node.node_tree.nodes["Crisp Frames"].image
            self.assertEqual(os.path.basename(shown.filepath), "frame_%04d.exr" % first)
            self.assertEqual(sorted(i.name for i in bpy.data.images if i.type != "RENDER_RESULT"),
                             sorted(["Crisp " + scene.name, kept.name]))
            self.assertEqual(shown.name, "Crisp " + scene.name)

    def test_preview_of_the_first_frame_is_that_frame(self):
        """Preview Frame without PNGs at the range's first frame shows that frame's EXR as a still image,
        not the compositor's sequence, which starts with the same file: the Image Editor numbers a sequence
        1 to 100 from the timeline, so at frame 150 it read frame_0100.exr, which does not exist. And Load
        into Compositor after a preview leaves the previewed image a still one."""
        scene = self.small_scene(150, 151, load_result=True)
        scene.crisp.write_png = False
        try:
            self.assertEqual(bpy.ops.crisp.render(), {"FINISHED"})
        finally:  # (not a cleanup: those run after tearDown has unregistered scene.crisp)
            scene.crisp.write_png = True
        first = os.path.join(self.tmp.name, "filtered", "frame_0150.exr")
        node = next(n for n in scene.node_tree.nodes if n.get(compositor.NODE_TAG))
        sequence = node.node_tree.nodes["Crisp Frames"].image
        shown = compositor.preview(first)
        self.assertEqual(shown.source, "FILE")
        self.assertEqual(os.path.normpath(bpy.path.abspath(shown.filepath_from_user())), first)
        self.assertEqual(tuple(shown.size), (64, 36))
        self.assertEqual(sequence.source, "SEQUENCE")
        self.assertEqual(bpy.ops.crisp.load_result(), {"FINISHED"})
        self.assertEqual(shown.source, "FILE")
        self.assertEqual(node.node_tree.nodes["Crisp Frames"].image, sequence)
        self.assertEqual(compositor.preview(first), shown)

    def test_the_result_group_survives_save_as_and_a_first_save(self):
        """Load into Compositor finds the group it made (one group, which every node showing it follows)
        after Save As to another folder, which rebases the image's relative path, and after a file that
        was unsaved at the load is saved, which makes the path relative, and then moved. (A group tag
        relative to the .blend went stale in both: a second group was made.)"""
        bpy.ops.wm.read_homefile(use_empty=True)  # no group an earlier test's file holds
        renders = os.path.join(self.tmp.name, "renders")
        scene = self.small_scene(1, 1, load_result=True)
        scene.crisp.output_dir = renders
        name = scene.name
        self.save_as(os.path.join(self.tmp.name, "a", "proj", "shot.blend"))
        self.assertEqual(bpy.ops.crisp.render(), {"FINISHED"})
        self.save_as(os.path.join(self.tmp.name, "b", "deeper", "proj", "shot.blend"))
        with bpy.context.temp_override(scene=bpy.data.scenes[name]):
            self.assertEqual(bpy.ops.crisp.load_result(), {"FINISHED"})
        self.assertEqual(len(self.result_groups()), 1, [(g.name, g.get(compositor.FOLDER_TAG))
                                                        for g in self.result_groups()])

        bpy.ops.wm.read_homefile(use_empty=True)  # unsaved, frames inside the folder-to-be of the project
        project = os.path.join(self.tmp.name, "project")
        scene = self.small_scene(1, 1, load_result=True)
        scene.crisp.output_dir = os.path.join(project, "crisp", "Scene")
        name = scene.name
        self.assertEqual(bpy.ops.crisp.render(), {"FINISHED"})
        scene.crisp.output_dir = "//crisp/Scene/"
        self.save_as(os.path.join(project, "shot.blend"))  # remaps paths relative
        moved = os.path.join(self.tmp.name, "moved")
        os.rename(project, moved)
        bpy.ops.wm.open_mainfile(filepath=os.path.join(moved, "shot.blend"))
        with bpy.context.temp_override(scene=bpy.data.scenes[name]):
            self.assertEqual(bpy.ops.crisp.load_result(), {"FINISHED"})
        groups = self.result_groups()
        self.assertEqual(len(groups), 1, [(g.name, g.get(compositor.FOLDER_TAG)) for g in groups])
        self.assertEqual(groups[0].get(compositor.FOLDER_TAG), os.path.join(moved, "crisp", "Scene", "filtered"))

    def test_a_users_group_showing_the_frames_is_not_taken_over(self):
        """A group of the user's own that holds a copy of Crisp's image node (ungrouped and grouped
        again with their nodes) shows the same frames, but is theirs: Load into Compositor makes or
        keeps Crisp's own group and leaves the user's as it was (it was found by its frames, tagged,
        and rewired, image straight to output, cutting the user's chain)."""
        bpy.ops.wm.read_homefile(use_empty=True)
        scene = self.small_scene(1, 1, load_result=True)
        self.assertEqual(bpy.ops.crisp.render(), {"FINISHED"})
        crisp_group, = self.result_groups()
        image = crisp_group.nodes["Crisp Frames"].image
        for node in [n for n in scene.node_tree.nodes if n.get(compositor.NODE_TAG)]:
            scene.node_tree.nodes.remove(node)
        bpy.data.node_groups.remove(crisp_group)
        theirs = bpy.data.node_groups.new("A grade", "CompositorNodeTree")  # sorts before "Crisp Result"
        theirs.outputs.new("NodeSocketColor", "Image")
        frames = theirs.nodes.new("CompositorNodeImage")
        frames.name, frames.image = "Crisp Frames", image
        glare, out = theirs.nodes.new("CompositorNodeGlare"), theirs.nodes.new("NodeGroupOutput")
        theirs.links.new(frames.outputs["Image"], glare.inputs["Image"])
        theirs.links.new(glare.outputs["Image"], out.inputs["Image"])
        with bpy.context.temp_override(scene=scene):
            self.assertEqual(bpy.ops.crisp.load_result(), {"FINISHED"})
        node = next(n for n in scene.node_tree.nodes if n.get(compositor.NODE_TAG))
        self.assertNotEqual(node.node_tree, theirs)
        self.assertNotIn(compositor.FOLDER_TAG, theirs)
        self.assertEqual(sorted((l.from_node.name, l.to_node.name) for l in theirs.links),
                         [("Crisp Frames", glare.name), (glare.name, out.name)])

    def test_linked_images_and_groups_are_not_taken_over(self):
        """A result group and image linked from another project's .blend, with the same relative paths
        as this project's, are that project's frames: Render with Crisp loads this project's into groups
        and images of its own (the linked ones were resolved against this .blend and reused, showing the
        other project's frames)."""
        lib_dir, main_dir = os.path.join(self.tmp.name, "lib"), os.path.join(self.tmp.name, "main")
        for d in (lib_dir, main_dir):
            bpy.ops.wm.read_homefile(use_empty=True)
            scene = self.small_scene(1, 1, load_result=True)
            scene.crisp.property_unset("output_dir")  # //crisp/<scene>/ in each project
            name = scene.name
            self.save_as(os.path.join(d, "shot.blend"))
            if d == main_dir:  # the other project's result, linked before this one has any
                with bpy.data.libraries.load(os.path.join(lib_dir, "shot.blend"), link=True, relative=True) as (
                        src, dst):
                    dst.node_groups = [n for n in src.node_groups if n.startswith(compositor.GROUP_NAME)]
                self.assertEqual([g.library is not None for g in self.result_groups()], [True])
                self.assertEqual([i.library is not None for i in bpy.data.images], [True])
            self.assertEqual(bpy.ops.crisp.render(), {"FINISHED"})
            bpy.ops.wm.save_mainfile()
        node = next(n for n in scene.node_tree.nodes if n.get(compositor.NODE_TAG))
        self.assertIsNone(node.node_tree.library, "the linked group was taken over")
        image = node.node_tree.nodes["Crisp Frames"].image
        self.assertIsNone(image.library, "the linked image was taken over")
        self.assertEqual(os.path.dirname(os.path.normpath(bpy.path.abspath(image.filepath))),
                         os.path.join(main_dir, "crisp", name, "filtered"))

    def test_compositor_shows_each_frames_own_file(self):
        """The loaded sequence maps scene frame N to filtered/frame_N.exr (two frames of other colours,
        composited at each frame; only the compositor runs, no Render Layers node)."""
        folder = os.path.join(self.tmp.name, "filtered")
        os.makedirs(folder)
        colours = {2: (0.2, 0.3, 0.4), 3: (0.9, 0.1, 0.05)}
        for f, c in colours.items():
            subprocess.run(["oiiotool", "--pattern", "constant:color=%g,%g,%g" % c, "8x8", "3", "-d", "float",
                            "-o", os.path.join(folder, "frame_%04d.exr" % f)], check=True, capture_output=True)
        scene = bpy.data.scenes.new("Compositor Frames")
        self.addCleanup(bpy.data.scenes.remove, scene)
        scene.render.resolution_x = scene.render.resolution_y = 8
        scene.render.resolution_percentage = 100
        scene.render.image_settings.file_format = "OPEN_EXR"
        node = compositor.load_result(scene, folder, 2, 3)
        tree = scene.node_tree
        for n in [n for n in tree.nodes if n.bl_idname == "CompositorNodeRLayers"]:
            tree.nodes.remove(n)
        composite = next(n for n in tree.nodes if n.bl_idname == "CompositorNodeComposite")
        tree.links.new(node.outputs["Image"], composite.inputs["Image"])
        for f, c in colours.items():
            scene.frame_set(f)
            scene.render.filepath = os.path.join(self.tmp.name, "composited_%d.exr" % f)
            with bpy.context.temp_override(scene=scene, view_layer=scene.view_layers[0]):
                bpy.ops.render.render(write_still=True)
            image = bpy.data.images.load(scene.render.filepath)
            shown = tuple(image.pixels[:3])
            bpy.data.images.remove(image)
            for got, want in zip(shown, c):
                self.assertAlmostEqual(got, want, places=4, msg="frame %d shows %s" % (f, shown))

    def test_compare_images_measures_the_test_against_the_reference(self):
        """native.compare_images(reference, test) gives the figures of `crisp compare --reference --test`
        for the same files (a checker reference against its darkened, blurred copy). SNR, over the
        reference's energy, is the one a swap of the two images changes: PSNR, SSIM and the perceptual
        error (flip.cpp) are symmetric."""
        ref, test, js = (os.path.join(self.tmp.name, n) for n in ("ref.exr", "test.exr", "m.json"))
        subprocess.run(["oiiotool", "--pattern", "checker:width=4:height=4", "48x32", "3", "-d", "float",
                        "-o", ref], check=True, capture_output=True)
        subprocess.run(["oiiotool", ref, "--blur", "5x5", "--mulc", "0.8", "-d", "float", "-o", test],
                       check=True, capture_output=True)
        with native.Context(1) as ctx:
            got = native.compare_images(ctx, ref, test)
        subprocess.run([os.path.join(harness.BUILD_DIR, "bin", "crisp"), "compare", "-q", "--reference", ref,
                        "--test", test, "--json", js], check=True, capture_output=True)
        with open(js) as f:
            want = json.load(f)["frames"][0]
        for k in ("psnr", "ssim", "snr", "flip"):
            self.assertAlmostEqual(got[k], want[k], places=5, msg=k)

    def test_compare_without_reference_says_what_is_missing(self):
        scene = harness.build_scene("still_life")
        scene.frame_start, scene.frame_end = 1, 1
        scene.crisp.output_dir = self.tmp.name
        with self.assertRaises(RuntimeError) as ctx:
            bpy.ops.crisp.compare()
        self.assertIn("reference", str(ctx.exception))

    def test_compare_warns_when_the_frames_are_not_one_run(self):
        """Compare averaged whatever filtered frames the folder held: frames of two methods, or frames
        without a reference left out, gave one figure without a word (Load into Compositor warned about
        the same folder). It now warns as Load into Compositor does, and names frames it could not
        measure."""
        scene = harness.build_scene("still_life")
        scene.render.resolution_x, scene.render.resolution_y = 32, 18
        scene.frame_start, scene.frame_end = 1, 3
        s = scene.crisp
        s.output_dir = self.tmp.name
        s.reference_samples = 2
        s.method = "fxaa"
        self.assertEqual(bpy.ops.crisp.render(), {"FINISHED"})
        scene.frame_end = 2
        self.assertEqual(bpy.ops.crisp.render_reference(), {"FINISHED"})
        self.assertEqual(bpy.ops.crisp.compare(), {"FINISHED"})
        self.assertNotIn("not one run", s.last_compare)  # one run over frames 1-2
        scene.frame_end = 3
        reports = io.StringIO()  # an operator's reports other than errors go to stdout
        with contextlib.redirect_stdout(reports):
            self.assertEqual(bpy.ops.crisp.compare(), {"FINISHED"})
        self.assertIn("Warning: Crisp: frame 3 has no reference frame (Render Reference)", reports.getvalue())
        self.assertIn("2 frames", s.last_compare)
        self.assertIn("not one run", s.last_compare)
        self.assertEqual(pipeline.compare_dirs(os.path.join(self.tmp.name, "filtered"),
                                               os.path.join(self.tmp.name, "reference"), [1, 2, 3])["no_reference"],
                         [3])
        scene.frame_start = scene.frame_end = 2
        s.method = "repair"
        self.assertEqual(bpy.ops.crisp.render(), {"FINISHED"})
        scene.frame_start, scene.frame_end = 1, 2
        self.assertEqual(pipeline.sequence_warnings(self.tmp.name, [1, 2]),
                         ["frame 2 was made with other settings than frame 1"])
        self.assertEqual(bpy.ops.crisp.compare(), {"FINISHED"})
        self.assertIn("not one run", s.last_compare)

    def test_update_plan_says_when_a_render_would_be_refused(self):
        """Update Plan wrote a full plan and said nothing on a scene the render refuses (no camera,
        non-square pixels for a jittered method). It still writes the plan, and warns why."""
        scene = harness.build_scene("still_life")
        scene.crisp.method = "taa"
        for spoil, why in ((lambda: setattr(scene.render, "pixel_aspect_x", 2.0), "jitter needs square pixels"),
                           (lambda: setattr(scene, "camera", None), "camera")):
            reports = io.StringIO()
            with contextlib.redirect_stdout(reports):
                self.assertEqual(bpy.ops.crisp.plan(), {"FINISHED"})
            self.assertNotIn("would be refused", reports.getvalue())
            spoil()
            with contextlib.redirect_stdout(reports):
                self.assertEqual(bpy.ops.crisp.plan(), {"FINISHED"})
            self.assertIn("Warning: Crisp: a render would be refused:", reports.getvalue())
            self.assertIn(why, reports.getvalue().split("would be refused:")[1])
            self.assertTrue(scene.crisp.plan_text)
            scene.render.pixel_aspect_x = 1.0

    def test_sequence_warnings_match_a_frame_whose_scene_file_is_unknown(self):
        """crisp render records the .blend's fingerprint (scene_key); the add-on, whose scene may be
        edited, records none, which a resume takes as a match. Load into Compositor compared the two
        records as they were, and warned of other settings over frames made alike."""
        os.makedirs(os.path.join(self.tmp.name, "input"))
        os.makedirs(os.path.join(self.tmp.name, "filtered"))
        base = {"scene": "s", "method": "taa", "params": {}, "samples": 1, "library": "x"}
        for f, key in ((1, "sha256:abc"), (2, None), (3, "sha256:abc")):
            with open(os.path.join(self.tmp.name, "input", "frame_%04d.json" % f), "w") as fh:
                json.dump({"made_with": dict(base, scene_key=key)}, fh)
            with open(os.path.join(self.tmp.name, "filtered", "frame_%04d.exr" % f), "w") as fh:
                fh.write("x")
        self.assertEqual(pipeline.sequence_warnings(self.tmp.name, [1, 2, 3]), [])
        with open(os.path.join(self.tmp.name, "input", "frame_0003.json"), "w") as fh:
            json.dump({"made_with": dict(base, scene_key="sha256:abc", method="phlm")}, fh)
        exr = os.path.join(self.tmp.name, "filtered", "frame_0003.exr")
        os.utime(exr, ns=(os.stat(exr).st_atime_ns, os.stat(exr).st_mtime_ns + 10**9))  # written after its input
        self.assertEqual(pipeline.sequence_warnings(self.tmp.name, [1, 2, 3]),
                         ["frame 3 was made with other settings than frame 1"])

    def test_the_scene_key_covers_the_files_the_renders_read(self):
        """batch.external_files, what scene_key hashes beside the .blend: a texture (named relative to the
        .blend's folder, also from beside it: ../tex), every frame of an image sequence, of a movie clip of
        numbered images and every UDIM tile, not a packed image, nor Crisp's own filtered frames loaded into
        the compositor or previewed, which each run rewrites (a resume on a farm would otherwise never find
        its frames made alike). Editing a texture changes the key; moving the project with its times does not."""
        from crisp import batch
        bpy.ops.wm.read_homefile(use_empty=True)
        home = self.tmp.name
        os.makedirs(os.path.join(home, "tex"))
        os.makedirs(os.path.join(home, "out", "filtered"))

        def pattern(path, colour="1,0,0"):
            subprocess.run(["oiiotool", "--pattern", "constant:color=" + colour, "4x4", "3", "-d", "half", "-o",
                            os.path.join(home, path)], check=True, capture_output=True)
        for path in ("tex/wood.png", "tex/seq.0001.png", "tex/seq.0002.png", "tex/seq.0010.png", "tex/other.0001.png",
                     "tex/u.1001.png", "tex/u.1002.png", "tex/packed.png", "out/filtered/frame_0001.exr",
                     "out/filtered/frame_0002.exr", "tex/plate.0001.png", "tex/plate.0002.png"):
            pattern(path)
        os.makedirs(os.path.join(home, "shots"))
        bpy.ops.wm.save_as_mainfile(filepath=os.path.join(home, "shots", "shot.blend"))
        wood = bpy.data.images.load(os.path.join(home, "tex", "wood.png"))
        sequence = bpy.data.images.load(os.path.join(home, "tex", "seq.0001.png"))
        sequence.source = "SEQUENCE"
        udim = bpy.data.images.load(os.path.join(home, "tex", "u.1001.png"))
        udim.source = "TILED"
        udim.tiles.new(1002)
        packed = bpy.data.images.load(os.path.join(home, "tex", "packed.png"))
        packed.pack()
        plate = bpy.data.movieclips.load(os.path.join(home, "tex", "plate.0001.png"))  # a clip of numbered images
        self.assertEqual(plate.source, "SEQUENCE")
        for image in (wood, sequence, udim, packed, plate):
            image.use_fake_user = True  # (saved with the file, as a material's would be)
        scene = bpy.context.scene
        compositor.load_result(scene, os.path.join(home, "out", "filtered"), 1, 2)
        compositor.preview(os.path.join(home, "out", "filtered", "frame_0002.exr"))
        names = [name for name, _ in batch.external_files()]
        self.assertEqual(names, [os.path.join("..", "tex", f) for f in (
            "plate.0001.png", "plate.0002.png", "seq.0001.png", "seq.0002.png", "seq.0010.png", "u.1001.png",
            "u.1002.png", "wood.png")])
        key = batch.scene_key(None)
        self.assertEqual(batch.scene_key(None), key)
        pattern("out/filtered/frame_0001.exr", "0,1,0")  # a run writing its frames: the same key
        self.assertEqual(batch.scene_key(None), key)
        for edited in ("tex/wood.png", "tex/seq.0010.png", "tex/u.1002.png", "tex/plate.0002.png"):
            pattern(edited, "0,0,1")
            self.assertNotEqual(batch.scene_key(None), key, edited)
            key = batch.scene_key(None)
        # The project, its paths relative, copied elsewhere with its times (cp -a) and opened there: the
        # same key.
        bpy.ops.file.make_paths_relative()
        bpy.ops.wm.save_mainfile()
        key = batch.scene_key(None)
        moved = home + "_moved"
        self.addCleanup(shutil.rmtree, moved, True)
        shutil.copytree(home, moved)  # (copy2: times kept)
        bpy.ops.wm.open_mainfile(filepath=os.path.join(moved, "shots", "shot.blend"))
        self.assertEqual(batch.scene_key(None), key)

    def test_a_run_into_a_folder_relative_to_the_blend_file_writes_beside_it(self):
        """pipeline.run(..., "//out") made /out (os.path reads // as the root) while Blender rendered
        beside the .blend, and the run failed finding no frame. It now reads // as Blender does, and
        refuses it when no .blend file is saved."""
        scene = harness.build_scene("still_life")
        scene.render.resolution_x, scene.render.resolution_y = 32, 18
        name = "crisp_test_%d" % os.getpid()
        with self.assertRaises(pipeline.InputError) as ctx:
            pipeline.run(scene, "fxaa", [1], "//" + name, log=lambda *a: None)
        self.assertIn("no saved .blend file", str(ctx.exception))
        self.assertFalse(os.path.exists("/" + name))
        bpy.ops.wm.save_as_mainfile(filepath=os.path.join(self.tmp.name, "shot.blend"))
        scene = bpy.context.scene
        result = pipeline.run(scene, "fxaa", [1], "//" + name, log=lambda *a: None)
        self.assertEqual(result["status"], "complete")
        self.assertTrue(os.path.isfile(os.path.join(self.tmp.name, name, "filtered", "frame_0001.exr")))
        self.assertFalse(os.path.exists("/" + name))


if __name__ == "__main__":
    harness.run(OperatorTest)
