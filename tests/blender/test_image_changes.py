# SPDX-License-Identifier: GPL-2.0-or-later
"""Change of the image with no geometry moving (plan.scene_facts image_changes): a keyed material, a
keyed hide_render, a light switched on. Where nothing moves, the temporal filters average every
still pixel, which keeps the old image where it changed; such a scene must say what changes and have
its run blend still pixels with neighbourhood clipping (pipeline.with_plan_params). still_life, where
nothing changes, keeps the average. Also the frame-step note, which names a history only for the
temporal methods."""

import os
import sys
import tempfile
import unittest

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import harness  # noqa: E402

import bpy  # noqa: E402
from crisp import pipeline, plan  # noqa: E402


def small(scene):
    scene.render.resolution_x, scene.render.resolution_y, scene.render.resolution_percentage = 64, 36, 100
    scene.frame_start, scene.frame_end = 1, 4
    return scene


def scroll_material(scene, ob):
    """A checker on ob scrolled by a keyed Mapping node (animation of the material's node tree)."""
    mat = bpy.data.materials.new("Belt")
    mat.use_nodes = True
    nodes, links = mat.node_tree.nodes, mat.node_tree.links
    checker, mapping = nodes.new("ShaderNodeTexChecker"), nodes.new("ShaderNodeMapping")
    links.new(nodes.new("ShaderNodeTexCoord").outputs["UV"], mapping.inputs["Vector"])
    links.new(mapping.outputs["Vector"], checker.inputs["Vector"])
    links.new(checker.outputs["Color"], nodes["Principled BSDF"].inputs["Base Color"])
    location = mapping.inputs["Location"]
    location.keyframe_insert("default_value", frame=1)
    location.default_value = (0.3, 0.1, 0.0)
    location.keyframe_insert("default_value", frame=4)
    ob.data.materials.clear()
    ob.data.materials.append(mat)
    return mat


class ImageChangeTest(unittest.TestCase):
    def setUp(self):
        self.scene = small(harness.build_scene("still_life"))
        self.tmp = tempfile.TemporaryDirectory()

    def tearDown(self):
        self.tmp.cleanup()

    def mesh(self):
        return next(o for o in plan.visible_objects(self.scene) if o.type == "MESH")

    def test_still_life_stays_still(self):
        # Neither the compositor's image sequence (Crisp's own results, shown after the filters) nor an
        # animated clipping distance changes what the filters see.
        self.scene.use_nodes = True
        shown = self.scene.node_tree.nodes.new("CompositorNodeImage")
        shown.image = bpy.data.images.new("Crisp Frames", 4, 4)
        shown.image.source = "SEQUENCE"
        cam = self.scene.camera.data
        cam.keyframe_insert("clip_end", frame=1)
        cam.clip_end *= 2
        cam.keyframe_insert("clip_end", frame=4)
        facts = plan.scene_facts(self.scene, 1, 4)
        self.assertEqual(facts.image_changes, [])
        p = plan.make_plan("taa", facts)
        self.assertTrue(p.still_average)
        self.assertNotIn("history:", p.describe())

    def test_keyed_material_is_named_and_not_averaged(self):
        scroll_material(self.scene, self.mesh())
        facts = plan.scene_facts(self.scene, 1, 4)
        self.assertFalse(facts.camera_moves or facts.moving_objects or facts.deforming_objects)
        self.assertEqual(facts.image_changes, ["material 'Belt'"])
        logged = []
        result = pipeline.run(self.scene, "taa", [1, 2], os.path.join(self.tmp.name, "taa"), threads=1,
                              log=logged.append)
        self.assertFalse(result["plan"]["still_average"])
        self.assertIs(result["params"].get("staticAccumulation"), False)  # the clipped blend, run for real
        self.assertIn("history: material 'Belt' changes the image", "\n".join(logged))
        # A parameter the artist sets is kept.
        result = pipeline.run(self.scene, "taa", [1], os.path.join(self.tmp.name, "own"), threads=1,
                              params={"staticAccumulation": True}, log=lambda s: None)
        self.assertIs(result["params"]["staticAccumulation"], True)
        # phlm forgets still pixels as fast as moving ones, and a spatial method has nothing to change.
        phlm = pipeline.with_plan_params("phlm", None, plan.make_plan("phlm", facts))
        self.assertEqual((phlm["lambda"], phlm["footprintBox"]), (0.7, False))
        self.assertIsNone(pipeline.with_plan_params("fxaa", None, plan.make_plan("fxaa", facts)))

    def test_eval_measures_what_the_add_on_runs(self):
        """crisp eval's taa row runs with the plan's staticAccumulation=false too, and says so; a row that
        sets it keeps its own value."""
        import json
        import subprocess
        scroll_material(self.scene, self.mesh())
        blend = os.path.join(self.tmp.name, "scroll.blend")
        bpy.ops.wm.save_as_mainfile(filepath=blend, copy=True)
        out = os.path.join(self.tmp.name, "eval")
        p = subprocess.run([os.path.join(harness.BUILD_DIR, "bin", "crisp"), "eval", "--scene", blend, "--frames",
                            "1-2", "--methods", "taa,taa:staticAccumulation=true", "--resolution", "48x27",
                            "--reference-samples", "2", "--curve", "1", "-q", "-o", out],
                           capture_output=True, text=True, timeout=600)
        self.assertEqual(p.returncode, 0, p.stderr)
        self.assertIn("taa runs with staticAccumulation=false, as its plan for this scene asks (material 'Belt'",
                      p.stderr)
        self.assertNotIn("taa:staticAccumulation=true runs with", p.stderr)
        with open(os.path.join(out, "renders", "scene.json")) as f:
            self.assertEqual(json.load(f)["plans"]["taa"]["params"], {"staticAccumulation": False})
        with open(os.path.join(out, "results.json")) as f:
            rows = {m["name"]: m for m in json.load(f)["scenes"][0]["methods"]}
        # The two settings differ on the second frame, where the average and the clipped blend part.
        a, b = (rows[n]["frames"][-1]["psnr"] for n in ("taa", "taa:staticAccumulation=true"))
        self.assertNotEqual(a, b)

    def test_crisp_filter_runs_what_the_add_on_runs(self):
        """crisp filter over the add-on's inputs takes the plan's parameters from their sidecars: its taa
        frames are the add-on's to the bit, and it says what it set; a parameter --set gives is kept
        (another image); phlm's lambda takes lambdaMoving's value as --set gives it."""
        import glob
        import json
        import subprocess
        import numpy as np
        scroll_material(self.scene, self.mesh())
        crisp = os.path.join(harness.BUILD_DIR, "bin", "crisp")
        out = os.path.join(self.tmp.name, "taa")
        pipeline.run(self.scene, "taa", [1, 2, 3], out, threads=1, log=lambda s: None)
        inputs = sorted(glob.glob(os.path.join(out, "input", "frame_*.exr")))
        self.assertEqual(len(inputs), 3)

        def pixels(path):
            image = bpy.data.images.load(path)
            try:
                return np.array(image.pixels[:], dtype=np.float32)
            finally:
                bpy.data.images.remove(image)

        def crisp_filter(method, folder, *options):
            p = subprocess.run([crisp, "filter", "-m", method, "--threads", "1", "-q", *options, "-o", folder, *inputs],
                               capture_output=True, text=True, timeout=300)
            self.assertEqual(p.returncode, 0, p.stderr)
            return p.stderr

        cli = os.path.join(self.tmp.name, "cli")
        said = crisp_filter("taa", cli)
        self.assertIn("filter: taa runs with staticAccumulation=false, as the renders' plan asks (material 'Belt' "
                      "changes the image", said)
        for f in inputs:
            name = os.path.basename(f)
            self.assertTrue(np.array_equal(pixels(os.path.join(cli, name)), pixels(os.path.join(out, "filtered", name))),
                            name)
        averaged = os.path.join(self.tmp.name, "averaged")
        self.assertNotIn("runs with", crisp_filter("taa", averaged, "--set", "staticAccumulation=true"))
        last = os.path.basename(inputs[-1])
        self.assertFalse(np.array_equal(pixels(os.path.join(averaged, last)), pixels(os.path.join(cli, last))))
        # taa's inputs carry every pass phlm reads on a still scene.
        said = crisp_filter("phlm", os.path.join(self.tmp.name, "phlm"), "--set", "lambdaMoving=0.8")
        self.assertIn("filter: phlm runs with lambda=0.8, as the renders' plan asks", said)
        self.assertIn("filter: phlm runs with footprintBox=false, as the renders' plan asks", said)

        def edit_sidecar(exr, change):
            side = exr[:-len(".exr")] + ".json"
            with open(side) as f:
                record = json.load(f)
            change(record)
            with open(side, "w") as f:
                json.dump(record, f)
            return side
        # A frame of another build (no history) among them: named, and the first input's plan is taken.
        older = edit_sidecar(inputs[-1], lambda record: record.pop("history"))
        said = crisp_filter("taa", os.path.join(self.tmp.name, "mixed"))
        self.assertIn("filter: warning: the inputs' sidecars disagree on the renders' plan: '%s' blends still pixels "
                      "as moving ones, '%s' keeps the still average" % (inputs[0][:-len(".exr")] + ".json", older), said)
        self.assertIn("taa runs with staticAccumulation=false", said)
        # ... and the add-on renders such a frame again rather than reading it (a pre-roll, a resume).
        from crisp import render
        the_plan = plan.make_plan("taa", plan.scene_facts(self.scene, 1, 3))
        reusable = [render.reusable_input(self.scene, render.eevee_engine(self.scene), os.path.join(out, "input"), f,
                                          the_plan, 1, "blackman-harris") for f in (2, 3)]
        self.assertEqual(reusable, [True, False])
        # A sidecar whose plan gives what no parameter takes is refused, naming the key, before any output.
        side = edit_sidecar(inputs[0], lambda record: record["history"]["params"]["taa"].update(
            staticAccumulation="fast"))
        bad = os.path.join(self.tmp.name, "bad")
        p = subprocess.run([crisp, "filter", "-m", "taa", "-q", "-o", bad, *inputs], capture_output=True, text=True)
        self.assertEqual(p.returncode, 1, p.stderr)
        self.assertIn("sidecar '%s' history.params.taa.staticAccumulation: expected a value or the name of a "
                      "parameter of taa, got \"fast\"" % side, p.stderr)
        self.assertFalse(glob.glob(os.path.join(bad, "*.exr")))

    def test_keyed_hide_render_is_named(self):
        ob = self.mesh()
        ob.hide_render = True
        ob.keyframe_insert("hide_render", frame=1)
        ob.hide_render = False
        ob.keyframe_insert("hide_render", frame=3)
        facts = plan.scene_facts(self.scene, 1, 4)
        # A pop-in is a step: the hold's release takes it in, and still pixels keep their average.
        self.assertEqual(facts.image_steps, ["visibility of '%s' (frame 3)" % ob.name])
        self.assertEqual(facts.image_changes, [])
        self.assertTrue(plan.make_plan("taa-improved", facts).still_average)
        # Switched on and off on most frames, it goes on: no average.
        for f in (2, 3, 4):  # keys: hidden at 1, shown at 2, hidden at 3, shown at 4
            ob.hide_render = f == 3
            ob.keyframe_insert("hide_render", frame=f)
        facts = plan.scene_facts(self.scene, 1, 4)
        self.assertIn("visibility of '%s'" % ob.name, facts.image_changes)
        self.assertFalse(plan.make_plan("taa-improved", facts).still_average)

    def test_a_light_switched_on_is_a_step_that_keeps_the_average(self):
        """light_switch's lamp (CONSTANT keys, on at frame 41): the hold's release takes it in, so the
        average stays, and the plan says when the image changes."""
        scene = small(harness.build_scene("light_switch"))
        facts = plan.scene_facts(scene, 1, 80)
        self.assertEqual((facts.image_changes, facts.image_steps), ([], ["light 'Switched' (frame 41)"]))
        p = plan.make_plan("taa", facts)
        self.assertTrue(p.still_average)
        self.assertIn("light 'Switched' (frame 41) changes the image in a step", p.describe())
        self.assertIsNone(pipeline.with_plan_params("taa", None, p))

    def test_light_energy_and_light_motion_are_named(self):
        light = next(o for o in self.scene.objects if o.type == "LIGHT")
        light.data.keyframe_insert("energy", frame=1)
        light.data.energy *= 3
        light.data.keyframe_insert("energy", frame=4)
        self.assertEqual(plan.scene_facts(self.scene, 1, 4).image_changes, ["light '%s'" % light.name])
        light.data.animation_data_clear()
        light.keyframe_insert("location", frame=1)
        light.location.x += 1
        light.keyframe_insert("location", frame=4)
        facts = plan.scene_facts(self.scene, 1, 4)
        self.assertEqual((facts.image_changes, facts.moving_objects), (["light '%s'" % light.name], []))

    def test_frame_step_note_names_a_history_only_for_temporal_methods(self):
        self.scene.frame_step = 2
        notes = {m: "\n".join(pipeline.scene_notes(self.scene, [1, 2, 3], self.scene.view_layers[0], method=m))
                 for m in ("fxaa", "rsaa", "taa")}
        for m in ("fxaa", "rsaa"):
            self.assertIn("the scene's frame step 2 is not used", notes[m])
            self.assertNotIn("history", notes[m])
        self.assertIn("taa's history needs every frame", notes["taa"])


if __name__ == "__main__":
    harness.run(ImageChangeTest)
