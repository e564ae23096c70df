# SPDX-License-Identifier: GPL-2.0-or-later
"""The add-on inside Blender: register/unregister, library status, the pass plan of every test scene
for every method, scene state restored after a render and after an error mid-render, the compositor
node group, and in-process bad input (no camera, empty range) touching nothing of the user's."""

import ctypes
import json
import os
import shutil
import subprocess
import sys
import tempfile
import unittest

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import harness  # noqa: E402
import exr_util  # noqa: E402

import bpy  # noqa: E402
import crisp  # noqa: E402
from crisp import compositor, hashing, native, output_folder, pipeline, plan, render  # noqa: E402

# What each scene is, by construction (see each scene's docstring): which kind of motion, how many
# objects are visible. The expected plans below follow from these facts and METHODS.md.
STATIC, ONE_MOVING, CAMERA, OBJECT_AMONG_MANY = "static", "one-moving", "camera", "object-among-many"
SCENE_KIND = {"still_life": STATIC, "spinning_cube": ONE_MOVING, "camera_dolly": CAMERA,
              "ghosting": OBJECT_AMONG_MANY, "hairball": ONE_MOVING, "foliage": OBJECT_AMONG_MANY, "shiny": STATIC,
              "light_switch": STATIC}
# Expected logical passes on EEVEE 3.4 (no Vector pass: motion is reconstructed from depth (+ ids)).
EXPECTED = {
    "none": {k: ["color"] for k in (STATIC, ONE_MOVING, CAMERA, OBJECT_AMONG_MANY)},
    "fxaa": {k: ["color"] for k in (STATIC, ONE_MOVING, CAMERA, OBJECT_AMONG_MANY)},
    "repair": {k: ["color"] for k in (STATIC, ONE_MOVING, CAMERA, OBJECT_AMONG_MANY)},
    "taa": {STATIC: ["color"], ONE_MOVING: ["color", "depth", "motion"], CAMERA: ["color", "depth", "motion"],
            OBJECT_AMONG_MANY: ["color", "depth", "motion", "id"]},
    "taa-improved": {STATIC: ["color", "depth", "id", "albedo"],
                     ONE_MOVING: ["color", "depth", "motion", "albedo"],
                     CAMERA: ["color", "depth", "motion", "id", "albedo"],
                     OBJECT_AMONG_MANY: ["color", "depth", "motion", "id", "albedo"]},
    "phlm": {STATIC: ["color"], ONE_MOVING: ["color", "depth", "motion"], CAMERA: ["color", "depth", "motion"],
             OBJECT_AMONG_MANY: ["color", "depth", "motion", "id"]},
    "rsaa": {k: ["color", "depth", "normal", "subsamples"] for k in (STATIC, ONE_MOVING, CAMERA, OBJECT_AMONG_MANY)},
}


def touched_state(scene):
    """Every property the renderer may change, to compare before/after."""
    vl = scene.view_layers[0]
    r = scene.render
    cam = scene.camera.data if scene.camera else None
    state = {"engine": r.engine, "samples": scene.eevee.taa_render_samples,
             "cubemap": scene.eevee.gi_cubemap_resolution, "filepath": r.filepath, "format": r.image_settings.file_format,
             "depth": r.image_settings.color_depth, "codec": r.image_settings.exr_codec, "frame": scene.frame_current,
             "compositing": r.use_compositing, "ext": r.use_file_extension, "stamp": r.use_stamp,
             "single": r.use_single_layer, "override": vl.material_override,
             "passes": {p.identifier: getattr(vl, p.identifier) for p in vl.bl_rna.properties
                        if p.identifier.startswith("use_pass_")}}
    if cam:
        state["shift"] = (cam.shift_x, cam.shift_y)
    return state


def image_pixels(path):
    """The pixels of the image file at path as Blender loads them (a float image: linear RGBA)."""
    image = bpy.data.images.load(path, check_existing=False)
    try:
        return list(image.pixels)
    finally:
        bpy.data.images.remove(image)


def controlled_ball(kind, animated):
    """still_life with its ball reshaped by an empty ("Control", not rendered) through a hook on three
    vertices (kind "hook") or Geometry Nodes offsetting it by the empty's relative location (kind
    "object-info"); the empty rises 0.5 from frame 1 to 3 if animated. Returns (scene, ball)."""
    scene = harness.build_scene("still_life")
    ball = scene.objects["Ball"]
    empty = bpy.data.objects.new("Control", None)  # not rendered: never in moving_objects
    scene.collection.objects.link(empty)
    if kind == "hook":
        hook = ball.modifiers.new("Hook", "HOOK")
        hook.object = empty
        hook.vertex_indices_set([0, 1, 2])
    else:
        tree = bpy.data.node_groups.new("Follow", "GeometryNodeTree")
        tree.inputs.new("NodeSocketGeometry", "Geometry")
        tree.outputs.new("NodeSocketGeometry", "Geometry")
        gin, gout = tree.nodes.new("NodeGroupInput"), tree.nodes.new("NodeGroupOutput")
        info = tree.nodes.new("GeometryNodeObjectInfo")
        info.transform_space = "RELATIVE"
        info.inputs["Object"].default_value = empty
        setpos = tree.nodes.new("GeometryNodeSetPosition")
        tree.links.new(gin.outputs[0], setpos.inputs["Geometry"])
        tree.links.new(info.outputs["Location"], setpos.inputs["Offset"])
        tree.links.new(setpos.outputs[0], gout.inputs[0])
        ball.modifiers.new("Follow", "NODES").node_group = tree
    if animated:
        empty.keyframe_insert("location", frame=1)
        empty.location.z = 0.5
        empty.keyframe_insert("location", frame=3)
    return scene, ball


class AddonTest(unittest.TestCase):
    def test_register_unregister(self):
        crisp.register()
        try:
            self.assertTrue(hasattr(bpy.types.Scene, "crisp"))
            self.assertTrue(hasattr(bpy.ops.crisp, "render"))
            self.assertIn("CRISP_PT_render", dir(bpy.types))
            s = bpy.context.scene.crisp
            self.assertEqual(s.reference_samples, 256)
            s.method = "fxaa"
            self.assertEqual(s.method, "fxaa")
        finally:
            crisp.unregister()
        self.assertFalse(hasattr(bpy.types.Scene, "crisp"))
        self.assertNotIn("CRISP_PT_render", dir(bpy.types))
        crisp.register()  # twice in a row must work too
        crisp.unregister()

    def test_settings_mirror_the_library_parameter_tables(self):
        from crisp import properties
        crisp.register()
        try:
            s = bpy.context.scene.crisp
            for method in native.filter_types():
                info = native.filter_info(method)
                group = properties.param_group(s, method)
                shown = [p for p in info["params"] if p["name"] not in properties.PIPELINE_PARAMS]
                if not shown:
                    self.assertIsNone(group, method)
                    continue
                for p in shown:  # same names and defaults as the library
                    value = getattr(group, p["name"])
                    if p["type"] == "float":  # the panel shows its default and limits as they are
                        digits = group.bl_rna.properties[p["name"]].precision
                        for k in ("default", "min", "max"):
                            self.assertAlmostEqual(round(p[k], digits), p[k], places=9, msg=(method, p["name"], k))
                    if p["type"] == "float":
                        self.assertAlmostEqual(value, p["default"], places=5, msg=(method, p["name"]))
                    else:
                        self.assertEqual(value, p["default"], (method, p["name"]))
                self.assertEqual(properties.changed_params(s, method), {}, method)
            # rsaa's camera comes from each frame's sidecar: not in the panel, and exactly the parameters
            # the CLI refuses in --set for that reason.
            rsaa_names = {p["name"] for p in native.filter_info("rsaa")["params"]}
            self.assertLessEqual(properties.RSAA_CAMERA_PARAMS, rsaa_names)
            self.assertFalse(any(hasattr(s.rsaa, name) for name in properties.RSAA_CAMERA_PARAMS))
            cli = os.path.join(harness.BUILD_DIR, "bin", "crisp")
            with tempfile.TemporaryDirectory() as d:
                for name in sorted(rsaa_names):
                    value = "true" if name == "orthographic" else "1"
                    run = subprocess.run([cli, "filter", "-m", "rsaa", "--set", "%s=%s" % (name, value), "-o", d,
                                          os.path.join(d, "none.exr")], capture_output=True, text=True)
                    refused = "takes its camera from each frame's sidecar" in run.stderr
                    self.assertEqual(refused, name in properties.RSAA_CAMERA_PARAMS, (name, run.stderr))
            s.repair.kappa = -1.0
            s.repair.mask = "box3"
            self.assertEqual(properties.changed_params(s, "repair"), {"kappa": -1.0, "mask": "box3"})
            with self.assertRaises(TypeError):
                s.repair.mask = "gaussian"  # not one of the library's choices
        finally:
            crisp.unregister()

    @unittest.skipUnless(harness.library_usable()[0], "libcrisp not built")
    def test_library_path_changed_after_loading_says_what_it_takes(self):
        """The preferences' library path changed once a library is loaded: a path with no file is named,
        and another library asks for a restart (a process cannot unload one); the loaded one's own path
        asks nothing. (Each used to be ignored without a word.)"""
        native.load()
        saved = native._preference_path
        self.addCleanup(native.set_preference_path, saved)
        with tempfile.TemporaryDirectory() as d:
            native.set_preference_path(os.path.join(d, "libcrisp.so"))
            self.assertIn("no file at", native.preference_note())
            other = shutil.copy(native._lib.path, os.path.join(d, "libcrisp.so"))
            self.assertIn("restart Blender to load " + other, native.preference_note())
        native.set_preference_path(native._lib.path)
        self.assertIsNone(native.preference_note())
        native.set_preference_path("")
        self.assertIsNone(native.preference_note())

    @unittest.skipUnless(harness.library_usable()[0], "libcrisp not built")
    def test_temporal_methods_filter_with_the_scenes_filter_size(self):
        """The frames are jittered over the scene's Film > Filter Size, and EEVEE's reference is filtered
        with it: a temporal method's filterSize (the pixel filter its unjitter assumes) is that size, not
        the library's 1.5 whatever the scene said. A size the library refuses is said before anything is
        rendered, naming the Film setting; the default size sends nothing."""
        scene = harness.build_scene("still_life")
        scene.render.resolution_x, scene.render.resolution_y, scene.render.resolution_percentage = 32, 18, 100

        def colour(path):
            with native.Context(1) as ctx, native.Frame(ctx, path) as frame:
                return frame.pass_values("color")[0]

        for method in plan.TEMPORAL_METHODS:
            with tempfile.TemporaryDirectory() as d:
                scene.render.filter_size = 0.75
                result = pipeline.run(scene, method, [1, 2], d, write_png=False, log=lambda *a: None)
                self.assertEqual(result["params"], {"filterSize": 0.75}, method)
                inputs = [os.path.join(d, "input", render.frame_name(f)) for f in (1, 2)]
                made = colour(os.path.join(d, "filtered", render.frame_name(2)))
                for params, same in (({"filterSize": 0.75}, True), ({}, False)):
                    ff = native.FrameFilter(method, params, 1, result["plan"]["passes"])
                    try:
                        for i, path in enumerate(inputs):
                            ff.run(path, [os.path.join(d, "check_%d.exr" % i)])
                    finally:
                        ff.close()
                    self.assertEqual(colour(os.path.join(d, "check_1.exr")) == made, same, (method, params))
                # A crisp render --set filterSize=... keeps its own; the default size adds nothing.
                result = pipeline.run(scene, method, [1], d, params={"filterSize": "2"}, log=lambda *a: None)
                self.assertEqual(result["params"], {"filterSize": "2"})
                scene.render.filter_size = 1.5
                self.assertEqual(pipeline.run(scene, method, [1], d, log=lambda *a: None)["params"], {})
            with tempfile.TemporaryDirectory() as d:
                scene.render.filter_size = 5.0
                try:
                    with self.assertRaisesRegex(pipeline.InputError, r"'filterSize' = 5 is out of range.*Film > "
                                                                     r"Filter Size, 5 px"):
                        pipeline.run(scene, method, [1], d, log=lambda *a: None)
                finally:  # Blender's default again: the scene outlives this test (build_scene reuses it)
                    scene.render.filter_size = 1.5
                self.assertEqual(os.listdir(d), [])

    @unittest.skipUnless(harness.library_usable()[0], "libcrisp not built")
    def test_the_smallest_filter_size_is_the_librarys(self):
        """The floor put under the scene's Film > Filter Size (Blender's goes to 0) for the renders and the
        viewport's preview (pipeline.MIN_FILTER_SIZE) is the loaded library's own minimum, read from its
        table once, not on each draw; a literal 0.01 stood for it. Without a library: 0.01."""
        spec = next(p for p in native.filter_info("taa")["params"] if p["name"] == "filterSize")
        self.assertEqual(pipeline.MIN_FILTER_SIZE, spec["min"])
        calls = []
        real = native.filter_info
        native.filter_info = lambda method: calls.append(method) or real(method)
        try:
            for _ in range(100):
                pipeline.MIN_FILTER_SIZE
        finally:
            native.filter_info = real
        self.assertEqual(calls, [])
        scene = harness.build_scene("still_life")
        scene.render.filter_size = 0.0
        saved = dict(native.load().param_specs)
        try:
            for method in plan.TEMPORAL_METHODS:  # a library whose minimum is another
                native.load().param_specs[(method, "filterSize")] = dict(spec, min=0.25)
            self.assertEqual(pipeline.MIN_FILTER_SIZE, 0.25)
            for method in plan.TEMPORAL_METHODS:
                self.assertEqual(pipeline.with_scene_filter_size(scene, method, {}), {"filterSize": 0.25})
        finally:
            native.load().param_specs.clear()
            native.load().param_specs.update(saved)
        param_spec = native.param_spec

        def no_library(*_args):
            raise native.CrispError("no library")
        native.param_spec = no_library
        try:
            self.assertEqual(pipeline.MIN_FILTER_SIZE, pipeline.FALLBACK_MIN_FILTER_SIZE)
        finally:
            native.param_spec = param_spec
        scene.render.filter_size = 1.5

    def test_output_folder_that_is_a_file_is_named_so(self):
        with tempfile.NamedTemporaryFile() as f:
            with self.assertRaisesRegex(pipeline.InputError, "is a file, not a folder"):
                pipeline.check_output_dir(f.name)

    def test_a_file_where_a_run_writes_its_frames_is_named_so(self):
        """A file named input (or filtered) in the output folder: refused as bad input before anything is
        rendered or written, naming it, rather than a 'File exists' error mid-run; the file is kept."""
        scene = harness.build_scene("still_life")
        scene.render.resolution_x, scene.render.resolution_y = 32, 18
        for sub, filter_frames in (("input", False), ("filtered", True)):
            with tempfile.TemporaryDirectory() as d:
                with open(os.path.join(d, sub), "w") as f:
                    f.write("the user's")
                with self.assertRaisesRegex(pipeline.InputError, "'%s' is a file, not a folder"
                                            % os.path.join(d, sub)):
                    pipeline.run(scene, "none", [1], d, filter_frames=filter_frames, log=lambda *a: None)
                self.assertEqual(sorted(os.listdir(d)), [sub])
                with open(os.path.join(d, sub)) as f:
                    self.assertEqual(f.read(), "the user's")

    def test_missing_library_still_registers_and_says_why(self):
        saved_lib, saved_env = native._lib, os.environ.get("CRISP_LIBRARY")
        native._lib = None
        os.environ["CRISP_LIBRARY"] = "/nonexistent/libcrisp.so"
        try:
            crisp.register()
            ok, text = native.status()
            self.assertFalse(ok)
            self.assertIn("/nonexistent/libcrisp.so", text)
            # The method menu falls back to the static list.
            from crisp import properties
            names = [i[0] for i in properties.method_items(None, bpy.context)]
            self.assertEqual(names, list(plan.METHOD_PASSES))
            with self.assertRaises(native.CrispError):
                native.filter_types()
            crisp.unregister()
        finally:
            native._lib = saved_lib
            if saved_env is None:
                os.environ.pop("CRISP_LIBRARY", None)
            else:
                os.environ["CRISP_LIBRARY"] = saved_env

    def test_plan_of_every_scene_for_every_method(self):
        for name in harness.SCENES:
            scene = harness.build_scene(name)
            frames = list(range(scene.frame_start, scene.frame_end + 1))
            kind = SCENE_KIND[name]
            for method in plan.METHOD_PASSES:
                with self.subTest(scene=name, method=method):
                    p, facts = pipeline.scene_plan(scene, method, frames)
                    self.assertEqual(p.passes, EXPECTED[method][kind], p.describe())
                    for q in p.passes:
                        self.assertTrue(p.reasons[q], "no reason for %s" % q)
                    self.assertNotIn("use_pass_vector", p.render_flags(), "EEVEE 3.4 writes no Vector pass")
                    self.assertEqual(p.jitter, method in plan.TEMPORAL_METHODS)
                    if "motion" in p.passes:
                        self.assertEqual(p.motion_source, "reconstruct")
                    if "motion" in p.skipped and method in plan.TEMPORAL_METHODS:
                        self.assertIn("nothing moves", p.skipped["motion"])
            self.assertEqual(scene.frame_current, scene.frame_start, "planning must restore the frame")

    def test_shiny_moving_light_needs_no_motion(self):
        scene = harness.build_scene("shiny")
        lamp = scene.objects["Lamp"]
        scene.frame_set(1)
        a = lamp.matrix_world.translation.copy()
        scene.frame_set(scene.frame_end)
        self.assertGreater((lamp.matrix_world.translation - a).length, 1.0, "the light really moves")
        p, _ = pipeline.scene_plan(scene, "taa", list(range(1, scene.frame_end + 1)))
        self.assertNotIn("motion", p.passes)

    def test_render_visibility_decides_what_counts(self):
        """An object hidden in the viewport only (the eye, the monitor icon) still renders: it counts,
        and its motion with it. One hidden from render, or in a collection excluded from the layer or
        hidden from render, does not."""
        scene = harness.build_scene("ghosting")  # Sphere moves across a still Wall
        frames = list(range(1, 4))
        sphere = scene.objects["Sphere"]
        sphere.hide_set(True)
        sphere.hide_viewport = True
        p, facts = pipeline.scene_plan(scene, "taa", frames)
        self.assertIn("Sphere", facts.visible_objects)
        self.assertEqual(facts.moving_objects, ["Sphere"])
        self.assertIn("motion", p.passes)
        self.assertTrue(sphere.hide_get() and sphere.hide_viewport, "planning hides it again")
        sphere.hide_viewport = False  # the eye alone
        self.assertEqual(pipeline.scene_plan(scene, "taa", frames)[1].moving_objects, ["Sphere"])
        self.assertTrue(sphere.hide_get())
        # The sidecars' matrices follow it too (render_frames), and it is hidden again afterwards.
        scene.render.resolution_x, scene.render.resolution_y = 32, 18
        sphere.hide_viewport = True  # not evaluated in the viewport at all
        with tempfile.TemporaryDirectory() as d:
            render.render_frames(scene, p, [1, 3], d)
            key = hashing.cryptomatte_hex("Sphere")
            moved = [json.load(open(os.path.join(d, "frame_%04d.json" % f)))["objects"][key]["matrix_world"]
                     for f in (1, 3)]
        self.assertNotEqual(moved[0], moved[1])
        self.assertTrue(sphere.hide_get() and sphere.hide_viewport)
        hidden = bpy.data.collections.new("Hidden")
        scene.collection.children.link(hidden)
        hidden.objects.link(sphere)
        for c in list(sphere.users_collection):
            if c is not hidden:
                c.objects.unlink(sphere)
        hidden.hide_render = True
        self.assertNotIn("Sphere", pipeline.scene_plan(scene, "taa", frames)[1].visible_objects)
        hidden.hide_render = False
        scene.view_layers[0].layer_collection.children["Hidden"].exclude = True
        p, facts = pipeline.scene_plan(scene, "taa", frames)
        self.assertNotIn("Sphere", facts.visible_objects)
        self.assertNotIn("motion", p.passes)

    def test_instanced_geometry_counts(self):
        """Geometry that renders through a collection instance (an empty instancing a collection excluded
        from the layer, as linked assets arrive) counts as visible, its motion is seen, and the sidecars
        carry each source instanced once with the instance's matrix; a source instanced twice shares one
        Cryptomatte ID, so its instances are not listed."""
        scene = harness.build_scene("ghosting")
        asset = bpy.data.collections.new("Asset")
        scene.collection.children.link(asset)
        sphere = scene.objects["Sphere"]
        sphere.animation_data_clear()
        for c in list(sphere.users_collection):
            c.objects.unlink(sphere)
        asset.objects.link(sphere)
        scene.view_layers[0].layer_collection.children["Asset"].exclude = True
        inst = bpy.data.objects.new("AssetInstance", None)
        inst.instance_type, inst.instance_collection = "COLLECTION", asset
        scene.collection.objects.link(inst)
        inst.location.x = -1.0
        inst.keyframe_insert("location", frame=1)
        inst.location.x = 1.0
        inst.keyframe_insert("location", frame=3)
        sphere.hide_viewport = True  # a heavy asset hidden in the viewport for speed still renders
        p, facts = pipeline.scene_plan(scene, "taa-improved", [1, 2, 3])
        self.assertTrue(sphere.hide_viewport)
        self.assertIn("Sphere", facts.visible_objects)
        self.assertEqual(facts.moving_objects, ["Sphere"])
        self.assertEqual(facts.shared_id_movers, [])  # instanced once: its ID tells its pixels apart
        self.assertIn("motion", p.passes)
        self.assertIn("id", p.passes)
        self.assertIn("subsamples", pipeline.scene_plan(scene, "rsaa", [1, 2, 3])[0].passes)
        scene.render.resolution_x, scene.render.resolution_y = 32, 18
        key = hashing.cryptomatte_hex("Sphere")
        with tempfile.TemporaryDirectory() as d:
            render.render_frames(scene, p, [1, 3], d)
            tables = [json.load(open(os.path.join(d, "frame_%04d.json" % f)))["objects"] for f in (1, 3)]
        xs = [t[key]["matrix_world"][0][3] for t in tables]  # the sphere's own x plus the instancer's
        self.assertAlmostEqual(xs[1] - xs[0], 2.0, places=5)
        twin = bpy.data.objects.new("AssetInstance2", None)
        twin.instance_type, twin.instance_collection = "COLLECTION", asset
        scene.collection.objects.link(twin)
        with tempfile.TemporaryDirectory() as d:
            render.render_frames(scene, p, [1], d)
            self.assertNotIn(key, json.load(open(os.path.join(d, "frame_0001.json")))["objects"])
        # Its pixels are then reconstructed as still: the run says so, naming the source and the method,
        # rather than planning motion that the moving copy will not get.
        self.assertEqual(pipeline.scene_plan(scene, "taa", [1, 2, 3])[1].shared_id_movers, ["Sphere"])
        lines = []
        with tempfile.TemporaryDirectory() as d:
            pipeline.run(scene, "taa", [1, 2, 3], d, plan_only=True, log=lines.append)
        notes = [line for line in lines if line.startswith("note: 'Sphere' moves but renders more than once")]
        self.assertEqual(len(notes), 1, lines)
        self.assertIn("taa may leave a trail", notes[0])
        twin.location.x = 5.0  # a still twin shares the ID just the same
        self.assertEqual(pipeline.scene_plan(scene, "taa", [1, 2, 3])[1].shared_id_movers, ["Sphere"])
        bpy.data.objects.remove(twin)
        self.assertEqual(pipeline.scene_plan(scene, "taa", [1, 2, 3])[1].shared_id_movers, [])

    def test_background_set_objects_count(self):
        """Objects of the scene's background set render behind it, at its frames: the plan sees them and
        their motion (also when hidden in the set's viewport), the sidecars carry their matrices, and
        what planning unhid in the set is hidden again. A set object hidden from render does not count."""
        scene = harness.build_scene("ghosting")  # Sphere moves across a still Wall
        backdrop = bpy.data.scenes.new("Backdrop")
        sphere = scene.objects["Sphere"]
        for c in list(sphere.users_collection):
            c.objects.unlink(sphere)
        backdrop.collection.objects.link(sphere)
        scene.background_set = backdrop
        sphere.hide_set(True, view_layer=backdrop.view_layers[0])
        sphere.hide_viewport = True
        frames = [1, 2, 3]
        p, facts = pipeline.scene_plan(scene, "taa", frames)
        self.assertEqual(facts.visible_objects, ["Wall", "Sphere"])
        self.assertEqual(facts.moving_objects, ["Sphere"])
        self.assertIn("motion", p.passes)
        self.assertIn("id", p.passes)
        self.assertTrue(sphere.hide_viewport and sphere.hide_get(view_layer=backdrop.view_layers[0]))
        scene.render.resolution_x, scene.render.resolution_y = 32, 18
        key = hashing.cryptomatte_hex("Sphere")
        with tempfile.TemporaryDirectory() as d:
            render.render_frames(scene, p, frames, d)
            moved = [json.load(open(os.path.join(d, "frame_%04d.json" % f)))["objects"][key]["matrix_world"]
                     for f in (1, 3)]
        self.assertNotEqual(moved[0], moved[1])
        self.assertTrue(sphere.hide_viewport and sphere.hide_get(view_layer=backdrop.view_layers[0]))
        sphere.hide_render = True
        p, facts = pipeline.scene_plan(scene, "taa", frames)
        self.assertEqual(facts.visible_objects, ["Wall"])
        self.assertNotIn("motion", p.passes)

    def test_geometry_that_varies_without_keyframes_deforms(self):
        """Geometry Nodes reading the scene's time (inside a nested group), and a modifier setting driven
        by the frame, change the geometry with no keyframe: the object deforms, so taa gets motion and
        IDs. Geometry Nodes that do not vary leave the scene still."""
        def plan_of(scene):
            return pipeline.scene_plan(scene, "taa", [1, 2, 3])

        scene = harness.build_scene("still_life")
        ball = scene.objects["Ball"]
        inner = bpy.data.node_groups.new("Inner", "GeometryNodeTree")
        inner.inputs.new("NodeSocketGeometry", "Geometry")
        inner.outputs.new("NodeSocketGeometry", "Geometry")
        gin, gout = inner.nodes.new("NodeGroupInput"), inner.nodes.new("NodeGroupOutput")
        setpos = inner.nodes.new("GeometryNodeSetPosition")
        inner.links.new(gin.outputs[0], setpos.inputs["Geometry"])
        inner.links.new(setpos.outputs[0], gout.inputs[0])
        outer = bpy.data.node_groups.new("Outer", "GeometryNodeTree")
        outer.inputs.new("NodeSocketGeometry", "Geometry")
        outer.outputs.new("NodeSocketGeometry", "Geometry")
        oin, oout = outer.nodes.new("NodeGroupInput"), outer.nodes.new("NodeGroupOutput")
        group = outer.nodes.new("GeometryNodeGroup")
        group.node_tree = inner
        outer.links.new(oin.outputs[0], group.inputs[0])
        outer.links.new(group.outputs[0], oout.inputs[0])
        mod = ball.modifiers.new("Wobble", "NODES")
        mod.node_group = outer
        p, facts = plan_of(scene)
        self.assertEqual(facts.deforming_objects, [], "geometry nodes that do not vary: still")
        self.assertNotIn("motion", p.passes)
        offset = inner.nodes.new("ShaderNodeCombineXYZ")
        time = inner.nodes.new("GeometryNodeInputSceneTime")
        inner.links.new(time.outputs["Seconds"], offset.inputs["Z"])
        inner.links.new(offset.outputs[0], setpos.inputs["Offset"])
        scene.frame_set(1)
        z1 = ball.evaluated_get(bpy.context.evaluated_depsgraph_get()).data.vertices[0].co.z
        scene.frame_set(3)
        z3 = ball.evaluated_get(bpy.context.evaluated_depsgraph_get()).data.vertices[0].co.z
        self.assertGreater(abs(z3 - z1), 1e-3, "the set-up moves the geometry")
        p, facts = plan_of(scene)
        self.assertEqual(facts.deforming_objects, [ball.name])
        self.assertIn("motion", p.passes)
        self.assertIn("id", p.passes)
        # A modifier setting driven by the frame, no keyframe anywhere.
        ball.modifiers.remove(mod)
        self.assertEqual(plan_of(scene)[1].deforming_objects, [])
        bend = ball.modifiers.new("Bend", "SIMPLE_DEFORM")
        bend.driver_add("angle").driver.expression = "frame * 0.1"
        self.assertFalse(ball.animation_data.action)
        self.assertEqual(plan_of(scene)[1].deforming_objects, [ball.name])

    def test_geometry_moved_by_another_object_deforms(self):
        """A hook pulled by an animated empty and Geometry Nodes that read an animated empty (Object
        Info, relative) reshape the ball with no animation of the ball's own: measured, it deforms, so
        taa gets motion (and with it depth for the disocclusion test). The same set-ups with the empty
        still leave the scene still."""
        def plan_of(scene):
            return pipeline.scene_plan(scene, "taa", [1, 2, 3])

        for kind in ("hook", "object-info"):
            with self.subTest(kind=kind):
                scene, ball = controlled_ball(kind, animated=True)
                self.assertFalse(plan._deforms(ball), "nothing in the ball's own settings says it deforms")
                self.assertTrue(plan._may_deform(ball), "so its geometry is measured")
                zs = []
                for f in (1, 3):
                    scene.frame_set(f)
                    zs.append(ball.evaluated_get(bpy.context.evaluated_depsgraph_get()).data.vertices[0].co.z)
                self.assertGreater(abs(zs[1] - zs[0]), 0.1, "the set-up moves the geometry")
                scene.frame_set(1)
                p, facts = plan_of(scene)
                self.assertEqual(facts.deforming_objects, [ball.name])
                self.assertEqual(facts.moving_objects, [])
                self.assertIn("motion", p.passes)
                self.assertIn("depth", p.passes)
                self.assertEqual(scene.frame_current, 1, "planning restores the frame")
                scene, ball = controlled_ball(kind, animated=False)
                p, facts = plan_of(scene)
                self.assertEqual(facts.deforming_objects, [], "a still control object: still")
                self.assertEqual(p.passes, ["color"])
        ball.modifiers.clear()
        ball.modifiers.new("Smooth", "SUBSURF")
        self.assertFalse(plan._may_deform(ball), "a modifier that reads nothing else is not measured")

    def test_an_instanced_source_is_measured_once_a_frame(self):
        """A hooked ball instanced on 50 vertices is one object to measure, not 50: its geometry digest
        is taken once a frame (a scattered asset with thousands of instances would otherwise be digested
        thousands of times a frame), and its deformation is still found."""
        scene, ball = controlled_ball("hook", animated=True)
        points = bpy.data.meshes.new("Points")
        points.from_pydata([(i * 0.1, 0.0, 0.0) for i in range(50)], [], [])
        scatter = bpy.data.objects.new("Scatter", points)
        scene.collection.objects.link(scatter)
        scatter.instance_type = "VERTS"
        ball.parent = scatter
        scene.frame_set(1)
        self.assertEqual(len(plan.rendered_instances(scene.view_layers[0])), 51)
        digests = []
        measure = plan._geometry_fingerprint

        def counted(ob, depsgraph):
            digests.append(ob.name)
            return measure(ob, depsgraph)

        plan._geometry_fingerprint = counted
        try:
            facts = plan.scene_facts(scene, 1, 3)
        finally:
            plan._geometry_fingerprint = measure
        self.assertEqual(facts.deforming_objects, [ball.name])
        self.assertLessEqual(digests.count(ball.name), 3, "at most once a frame")

    def test_deformation_found_wherever_blender_keeps_it(self):
        """Each case reshapes geometry in renders (or, for the last three, does not) in a way an earlier
        check missed (or flagged): keys in an NLA strip, a modifier whose name needs escaping in its
        data path, an object hidden from render on the last frame only, a control object driving a
        modifier shown in renders only, grease pencil drawn anew on each frame; an armature modifier
        whose rig never moves, static hair, and a wave modifier off in renders."""
        def keyed_displace(box, name):
            m = box.modifiers.new(name, "DISPLACE")
            path = plan._path_of_modifier(name) + ".strength"
            m.strength = 0.0
            box.keyframe_insert(path, frame=1)
            m.strength = 0.5
            box.keyframe_insert(path, frame=3)

        def nla(scene):
            box = scene.objects["Box"]
            keyed_displace(box, "Disp")
            ad = box.animation_data
            ad.nla_tracks.new().strips.new("keys", 1, ad.action)
            ad.action = None

        def quoted(scene):
            keyed_displace(scene.objects["Box"], 'Di"s\\p')

        def hidden_last(scene):
            ball = scene.objects["Ball"]
            ball.modifiers.new("Wave", "WAVE").height = 0.3
            ball.keyframe_insert("hide_render", frame=1)
            ball.hide_render = True
            ball.keyframe_insert("hide_render", frame=3)
            scene.frame_set(1)

        def render_only_hook(scene):
            empty = bpy.data.objects.new("Control", None)
            scene.collection.objects.link(empty)
            hook = scene.objects["Ball"].modifiers.new("Hook", "HOOK")
            hook.object = empty
            hook.vertex_indices_set([0, 1, 2])
            hook.show_viewport = False
            empty.keyframe_insert("location", frame=1)
            empty.location.z = 0.5
            empty.keyframe_insert("location", frame=3)

        def grease_pencil(scene):
            gp = bpy.data.grease_pencils.new("Sketch")
            scene.collection.objects.link(bpy.data.objects.new("Sketch", gp))
            layer = gp.layers.new("Lines")
            for f, x in ((1, 0.0), (2, 0.5), (3, 1.0)):
                stroke = layer.frames.new(f).strokes.new()
                stroke.points.add(2)
                stroke.points[0].co, stroke.points[1].co = (x, 0, 1), (x + 0.5, 0, 1.5)

        def grease_pencil_noise(scene):  # one drawing, a noise modifier that varies with the frame
            gp = bpy.data.grease_pencils.new("Sketch")
            sketch = bpy.data.objects.new("Sketch", gp)
            scene.collection.objects.link(sketch)
            stroke = gp.layers.new("Lines").frames.new(1).strokes.new()
            stroke.points.add(4)
            sketch.grease_pencil_modifiers.new("Noise", "GP_NOISE")
            return sketch

        def grease_pencil_tint(scene):  # one drawing, a tint: drawn the same on every frame
            sketch = grease_pencil_noise(scene)
            sketch.grease_pencil_modifiers.remove(sketch.grease_pencil_modifiers["Noise"])
            sketch.grease_pencil_modifiers.new("Tint", "GP_TINT")

        def still_rig(scene):
            rig = bpy.data.objects.new("Rig", bpy.data.armatures.new("Rig"))
            scene.collection.objects.link(rig)
            scene.objects["Box"].modifiers.new("Rig", "ARMATURE").object = rig

        def posed_rig(scene):  # an armature whose bone is keyed: measured, as the viewport poses it
            rig = bpy.data.objects.new("Rig", bpy.data.armatures.new("Rig"))
            scene.collection.objects.link(rig)
            bpy.context.view_layer.objects.active = rig
            bpy.ops.object.mode_set(mode="EDIT")
            bone = rig.data.edit_bones.new("Bone")
            bone.head, bone.tail = (0, 0, 0), (0, 0, 1)
            bpy.ops.object.mode_set(mode="OBJECT")
            box = scene.objects["Box"]
            box.vertex_groups.new(name="Bone").add(range(len(box.data.vertices)), 1.0, "REPLACE")
            box.modifiers.new("Rig", "ARMATURE").object = rig
            pose = rig.pose.bones["Bone"]
            pose.keyframe_insert("location", frame=1)
            pose.location.x = 0.3
            pose.keyframe_insert("location", frame=3)

        def static_hair(scene):
            scene.objects["Ball"].modifiers.new("Hair", "PARTICLE_SYSTEM").particle_system.settings.type = "HAIR"

        def wave_off_in_renders(scene):
            scene.objects["Box"].modifiers.new("Wave", "WAVE").show_render = False

        for set_up, deforming in ((nla, ["Box"]), (quoted, ["Box"]), (hidden_last, ["Ball"]),
                                  (render_only_hook, ["Ball"]), (grease_pencil, ["Sketch"]),
                                  (grease_pencil_noise, ["Sketch"]), (grease_pencil_tint, []),
                                  (posed_rig, ["Box"]), (still_rig, []), (static_hair, []), (wave_off_in_renders, [])):
            with self.subTest(case=set_up.__name__):
                scene = harness.build_scene("still_life")
                set_up(scene)
                p, facts = pipeline.scene_plan(scene, "taa", [1, 2, 3])
                self.assertEqual(facts.deforming_objects, deforming)
                self.assertEqual("motion" in p.passes, bool(deforming))
                if set_up is render_only_hook:
                    self.assertFalse(scene.objects["Ball"].modifiers["Hook"].show_viewport,
                                     "planning switches it off again")

    def test_a_modifier_off_in_renders_reshapes_nothing(self):
        """A hook shown in the viewport but not in renders, pulled by an animated empty: the renders do
        not deform, so neither the plan nor the sidecars' digests say so; the hook stays on in the
        viewport afterwards."""
        scene, ball = controlled_ball("hook", animated=True)
        hook = ball.modifiers["Hook"]
        hook.show_render = False
        p, facts = pipeline.scene_plan(scene, "taa", [1, 2, 3])
        self.assertEqual(facts.deforming_objects, [])
        self.assertNotIn("motion", p.passes)
        self.assertTrue(hook.show_viewport)
        scene.render.resolution_x, scene.render.resolution_y = 32, 18
        key = hashing.cryptomatte_hex(ball.name)
        with tempfile.TemporaryDirectory() as d:
            render.render_frames(scene, p, [1, 3], d)
            digests = [json.load(open(os.path.join(d, "frame_%04d.json" % f)))["objects"][key].get("geometry")
                       for f in (1, 3)]
        self.assertIsNotNone(digests[0])
        self.assertEqual(digests[0], digests[1])
        self.assertTrue(hook.show_viewport)

    @unittest.skipUnless(harness.library_usable()[0], "libcrisp not built")
    def test_sidecars_tell_crisp_filter_the_geometry_changed(self):
        """A ball reshaped by a hook keeps its matrix: the sidecars carry a digest of its geometry, which
        differs between frames where the control object moves, so `crisp filter` rebuilds motion for
        taa as the add-on's plan does; with the control object still, the digests agree and the
        sequence is still."""
        crisp_cli = os.path.join(harness.BUILD_DIR, "bin", "crisp")
        for animated in (True, False):
            with self.subTest(animated=animated), tempfile.TemporaryDirectory() as d:
                scene, ball = controlled_ball("hook", animated)
                scene.render.resolution_x, scene.render.resolution_y = 32, 18
                p = plan.make_plan("taa", plan.SceneFacts(1, 3, deforming_objects=[ball.name],
                                                          visible_objects=["Ball", "Box"]))
                render.render_frames(scene, p, [1, 2, 3], d)
                key = hashing.cryptomatte_hex(ball.name)
                digests = [json.load(open(os.path.join(d, "frame_%04d.json" % f)))["objects"][key]["geometry"]
                           for f in (1, 2, 3)]
                self.assertEqual(len(set(digests)), 3 if animated else 1, digests)
                out = os.path.join(d, "out")
                run = subprocess.run([crisp_cli, "filter", "-m", "taa", "--quiet", "-o", out]
                                     + [os.path.join(d, "frame_%04d.exr" % f) for f in (1, 2, 3)],
                                     capture_output=True, text=True)
                self.assertEqual(run.returncode, 0, run.stderr)
                stamp = json.load(open(os.path.join(out, ".crisp", "frame_0003.json")))
                self.assertEqual(stamp["motion_from_sidecars"], animated, stamp)

    def test_camera_projection_changes_move_the_picture(self):
        """A zoom (animated lens), an animated shift and an animated orthographic scale move every pixel
        with the camera's matrix unchanged: the camera moves. Animated clipping distances move none."""
        def animate(data, prop, a, b):
            setattr(data, prop, a)
            data.keyframe_insert(prop, frame=1)
            setattr(data, prop, b)
            data.keyframe_insert(prop, frame=3)

        for prop, a, b, moves in (("lens", 35.0, 60.0, True), ("shift_x", 0.0, 0.2, True),
                                  ("shift_y", 0.0, -0.1, True), ("ortho_scale", 4.0, 6.0, True),
                                  ("clip_end", 50.0, 80.0, False), ("clip_start", 0.1, 0.5, False)):
            with self.subTest(prop=prop):
                scene = harness.build_scene("still_life")
                data = scene.camera.data
                if prop == "ortho_scale":
                    data.type = "ORTHO"
                animate(data, prop, a, b)
                p, facts = pipeline.scene_plan(scene, "taa", [1, 2, 3])
                self.assertEqual(facts.camera_moves, moves)
                self.assertEqual("motion" in p.passes, moves, p.describe())

    def test_rendered_frames_keep_an_animated_shift(self):
        """The jitter is added to each frame's own shift: an animated shift is rendered as animated
        (the sidecars' unjittered projections follow it, the jittered ones differ from those by the
        jitter alone), and no jitter is left on the camera afterwards."""
        scene = harness.build_scene("still_life")
        scene.render.resolution_x, scene.render.resolution_y = 32, 18
        data = scene.camera.data
        data.shift_x = 0.0
        data.keyframe_insert("shift_x", frame=1)
        data.shift_x = 0.2
        data.keyframe_insert("shift_x", frame=3)
        p, _ = pipeline.scene_plan(scene, "taa", [1, 2, 3])
        self.assertTrue(p.jitter)
        scene.frame_set(2)
        with tempfile.TemporaryDirectory() as d:
            render.render_frames(scene, p, [1, 3], d)
            sidecars = [json.load(open(os.path.join(d, "frame_%04d.json" % f))) for f in (1, 3)]
        unit = 2.0 / 32  # projection x per pixel: 2 / width
        for sidecar, shift in zip(sidecars, (0.0, 0.2)):
            cam = sidecar["camera"]
            self.assertAlmostEqual(cam["base_shift"][0], shift, places=6)
            self.assertAlmostEqual(cam["projection_unjittered"][0][2], 2 * shift, places=5)
            jx = cam["projection"][0][2] - cam["projection_unjittered"][0][2]
            self.assertAlmostEqual(jx, sidecar["jitter"]["x"] * unit, places=5)
            self.assertNotEqual(sidecar["jitter"]["x"], 0.0)
        self.assertEqual(scene.frame_current, 2)
        self.assertAlmostEqual(data.shift_x, 0.1, places=6, msg="the animation's shift at frame 2, no jitter left")

    @unittest.skipUnless(harness.library_usable()[0], "libcrisp not built")
    def test_a_frame_rendered_again_without_subsamples_drops_the_old_ones(self):
        """rsaa's eight geometry renders of a frame belong to that frame's picture: rendered again for
        another method, the frame's sidecar no longer lists them and they go; frames not rendered again
        keep theirs."""
        scene = harness.build_scene("still_life")
        scene.render.resolution_x, scene.render.resolution_y = 16, 8
        facts = plan.SceneFacts(1, 2, visible_objects=["Box", "Ball"])
        with tempfile.TemporaryDirectory() as d:
            render.render_frames(scene, plan.make_plan("rsaa", facts), [1, 2], d)
            subs = lambda f: sorted(n for n in os.listdir(d) if n.startswith("frame_%04d_sub" % f))
            self.assertEqual(len(subs(1)), len(render.RSAA_PATTERN))
            render.render_frames(scene, plan.make_plan("taa", facts), [1], d)
            self.assertEqual(subs(1), [])
            self.assertEqual(len(subs(2)), len(render.RSAA_PATTERN))
            self.assertNotIn("subsamples", json.load(open(os.path.join(d, "frame_0001.json"))))

    def test_an_object_that_appears_later_gets_rsaas_geometry(self):
        """An object hidden from the render on the first frame and shown from the second (hide_render
        keyed) is visible over the range: rsaa renders its geometry. The facts were taken from the first
        frame alone, so rsaa rendered none and left frames 2-3 as rendered ("no visible object")."""
        scene = harness.build_scene("spinning_cube")
        cube = scene.objects["Cube"]
        cube.hide_render = True
        cube.keyframe_insert("hide_render", frame=1)
        cube.hide_render = False
        cube.keyframe_insert("hide_render", frame=2)
        p, facts = pipeline.scene_plan(scene, "rsaa", [1, 2, 3])
        self.assertEqual(facts.visible_objects, ["Cube"])
        self.assertIn("subsamples", p.passes, p.describe())
        p, facts = pipeline.scene_plan(scene, "rsaa", [1])  # hidden on every frame planned: nothing to render
        self.assertEqual(facts.visible_objects, [])
        self.assertNotIn("subsamples", p.passes, p.describe())

    def test_subsamples_render_at_one_sample(self):
        """A frame rendered with more samples (--samples 4) still gets its eight geometry renders at one
        sample: their depth and normal are the first sample's at any count, so more only cost time
        (16 samples made them 4.5x slower). EEVEE's effects that shade Combined alone (AO, SSR, bloom,
        soft shadows) are off in them too. The frames themselves, the second after the first's geometry
        renders too, keep their samples and effects; the scene its settings."""
        scene = harness.build_scene("still_life")
        scene.render.resolution_x, scene.render.resolution_y = 16, 8
        scene.eevee.use_gtao = scene.eevee.use_ssr = scene.eevee.use_bloom = True
        effects = ("use_gtao", "use_ssr", "use_bloom", "use_soft_shadows")
        facts = plan.SceneFacts(1, 2, visible_objects=["Box", "Ball"])
        seen = []

        def record(s, *args):
            seen.append((os.path.basename(s.render.filepath), s.eevee.taa_render_samples, s.cycles.samples,
                         [getattr(s.eevee, e) for e in effects]))
        bpy.app.handlers.render_pre.append(record)
        self.addCleanup(bpy.app.handlers.render_pre.remove, record)
        for engine in (None, "CYCLES"):
            seen.clear()
            before = (scene.eevee.taa_render_samples, scene.cycles.samples, [getattr(scene.eevee, e) for e in effects])
            self.assertEqual(before[2], [True] * 4)
            with tempfile.TemporaryDirectory() as d:
                render.render_frames(scene, plan.make_plan("rsaa", facts), [1, 2], d, samples=4, engine=engine)
            per_frame = 1 + len(render.RSAA_PATTERN)
            self.assertEqual(len(seen), 2 * per_frame, seen)
            for first in (0, per_frame):  # each frame's own render, then its geometry renders
                main = seen[first][1] if engine is None else seen[first][2]
                self.assertEqual(main, 4, seen)
                self.assertNotIn("_sub", seen[first][0])
                self.assertEqual(seen[first][3], [True] * 4, seen)
            for name, eevee, cycles, on in seen[1:per_frame] + seen[per_frame + 1:]:
                self.assertIn("_sub", name)
                self.assertEqual(eevee if engine is None else cycles, 1, seen)
                if engine is None:
                    self.assertEqual(on, [False] * 4, seen)
            self.assertEqual((scene.eevee.taa_render_samples, scene.cycles.samples,
                              [getattr(scene.eevee, e) for e in effects]), before)

    def test_rsaa_without_geometry_takes_its_parameters(self):
        """rsaa on a plan with no sub-samples (nothing visible) filters as 'none'; the rsaa parameters
        the user set are not set on that filter (they failed as unknown to 'none')."""
        f = native.FrameFilter("rsaa", {"threshold": "0.3"}, passes=("color",))
        f.close()

    def test_state_restored_after_render_and_after_error(self):
        scene = harness.build_scene("spinning_cube")
        scene.render.resolution_x, scene.render.resolution_y = 32, 18
        scene.render.filepath = "//user_path_"
        scene.camera.data.shift_x = 0.01
        scene.view_layers[0].use_pass_mist = True
        scene.frame_set(5)
        before = touched_state(scene)
        the_plan = plan.make_plan("taa-improved", plan.scene_facts(scene, 1, 3))
        with tempfile.TemporaryDirectory() as d:
            render.render_frames(scene, the_plan, [1, 2], d)
            self.assertEqual(touched_state(scene), before)
            self.assertEqual(sorted(f for f in os.listdir(d) if f.endswith(".exr")), ["frame_0001.exr", "frame_0002.exr"])

            class Boom(Exception):
                pass

            def explode(frame, info):
                raise Boom("mid-render failure")
            with self.assertRaises(Boom):
                render.render_frames(scene, the_plan, [1, 2, 3], os.path.join(d, "b"), on_frame=explode)
            self.assertEqual(touched_state(scene), before)
            # cancel after the first frame: the rest is not rendered, settings are back
            calls = []
            render.render_frames(scene, the_plan, [1, 2, 3], os.path.join(d, "c"),
                                 should_cancel=lambda: calls.append(1) or len(calls) > 1)
            self.assertEqual(touched_state(scene), before)
            self.assertEqual(sorted(f for f in os.listdir(os.path.join(d, "c")) if f.endswith(".exr")),
                             ["frame_0001.exr"])

    def test_a_run_closed_after_its_scene_was_deleted_touches_nothing_of_it(self):
        """A clicked run waits between frames (iter_render_frames) while scripts and other windows run: its
        scene deleted then, the run's restore wrote the scene's old settings into the freed scene's render
        settings and view layer (Blender crashed, or not), and raised ReferenceError. What other data
        holds (the camera's jittered shift) is still put back."""
        scene = harness.build_scene("spinning_cube")
        doomed = bpy.data.scenes.new("Doomed")
        doomed.render.resolution_x, doomed.render.resolution_y = 32, 18
        doomed.collection.objects.link(scene.camera)
        doomed.camera = scene.camera
        doomed.camera.data.shift_x = 0.01
        the_plan = plan.make_plan("taa", plan.scene_facts(doomed, 1, 3))
        self.assertTrue(the_plan.jitter)
        with tempfile.TemporaryDirectory() as d:
            steps = render.iter_render_frames(doomed, the_plan, [1, 2, 3], d)
            next(steps)
            self.assertNotEqual(scene.camera.data.shift_x, 0.01)  # the first frame's jitter, kept between frames
            bpy.data.scenes.remove(doomed)
            steps.close()
        self.assertAlmostEqual(scene.camera.data.shift_x, 0.01, places=7)

    def test_a_movie_output_keeps_its_settings(self):
        """A scene whose output is a movie without audio: Blender resets the movie settings (an MKV
        container, its H.264 preset) when the file format is switched back to FFmpeg, so Crisp's renders
        (which write EXRs) left an MPEG-4 container as MKV and another quality behind."""
        scene = harness.build_scene("still_life")
        scene.render.resolution_x, scene.render.resolution_y = 32, 18
        scene.render.image_settings.file_format = "FFMPEG"
        ffmpeg = scene.render.ffmpeg
        ffmpeg.format, ffmpeg.codec, ffmpeg.audio_codec = "MPEG4", "H264", "NONE"
        ffmpeg.constant_rate_factor, ffmpeg.ffmpeg_preset, ffmpeg.gopsize = "HIGH", "BEST", 12

        def settings():
            return {p.identifier: getattr(ffmpeg, p.identifier) for p in ffmpeg.bl_rna.properties
                    if p.identifier != "rna_type"}
        before = settings()
        try:
            with tempfile.TemporaryDirectory() as d:
                render.render_frames(scene, plan.make_plan("fxaa", plan.SceneFacts(1, 1)), [1], d)
            self.assertEqual(scene.render.image_settings.file_format, "FFMPEG")
            self.assertEqual({k: v for k, v in settings().items() if v != before[k]}, {})
        finally:
            scene.render.image_settings.file_format = "PNG"

    def test_an_exr_output_with_a_preview_leaves_no_jpeg(self):
        """The user's EXR output with Preview on (a JPEG beside each EXR): Crisp's renders wrote a JPEG beside
        each temporary EXR (.frame_0001.tmp-<host>-<pid>-<n>.jpg) and left it in input/."""
        scene = harness.build_scene("still_life")
        scene.render.resolution_x, scene.render.resolution_y = 32, 18
        settings = scene.render.image_settings
        settings.file_format, settings.use_preview = "OPEN_EXR", True
        try:
            with tempfile.TemporaryDirectory() as d:
                render.render_frames(scene, plan.make_plan("fxaa", plan.SceneFacts(1, 1)), [1], d)
                self.assertEqual(sorted(os.listdir(d)), ["frame_0001.exr", "frame_0001.json"])
            self.assertTrue(settings.use_preview, "put back")
        finally:
            settings.file_format, settings.use_preview = "PNG", False

    def test_frame_ranges_parse_as_the_cli_checks_them(self):
        """crisp render checks --frames before Blender starts (cli/frame_range.h); batch.py must read
        the ranges that check lets through, negative frames among them, as the same frames."""
        for text, frames in (("3", [3]), ("2-4", [2, 3, 4]), ("-2", [-2]), ("-3--1", [-3, -2, -1]),
                             ("-1-1", [-1, 0, 1])):
            self.assertEqual(list(pipeline.parse_frames(text)), frames, text)
        for text in ("a-b", "1-", "4-2", "-1--3"):
            with self.assertRaises(pipeline.InputError, msg=text):
                pipeline.parse_frames(text)

    def test_no_camera_and_empty_range_touch_nothing(self):
        scene = harness.build_scene("still_life")
        before_state = touched_state(scene)
        with tempfile.TemporaryDirectory() as d:
            out = os.path.join(d, "out")
            with self.assertRaisesRegex(pipeline.InputError, "empty"):
                pipeline.run(scene, "fxaa", pipeline.parse_frames("5-3", scene), out, filter_frames=False)
            cam = scene.camera
            scene.camera = None
            try:
                # The scene has a camera object, which is not its camera: named, not "add one".
                with self.assertRaisesRegex(pipeline.InputError,
                                            "no scene camera, though it has the camera object 'Camera'"):
                    pipeline.run(scene, "fxaa", range(1, 3), out, filter_frames=False)
                cam.name = "Lens"  # ... and with no camera object at all: add one
                scene.collection.objects.unlink(cam)
                with self.assertRaisesRegex(pipeline.InputError, "has no camera: add one"):
                    pipeline.run(scene, "fxaa", range(1, 3), out, filter_frames=False)
                scene.collection.objects.link(cam)
                cam.name = "Camera"
            finally:
                scene.camera = cam
            # No scene camera, but a timeline marker binds one: Blender renders through it (the marker makes it
            # the scene camera as the frame changes); Crisp, which starts from the scene camera, says so.
            scene.timeline_markers.new("Shot", frame=1).camera = cam
            scene.camera = None
            try:
                with self.assertRaisesRegex(pipeline.InputError,
                                            "no scene camera; timeline marker 'Shot' binds 'Camera'"):
                    pipeline.run(scene, "fxaa", range(1, 3), out, filter_frames=False)
                # Before its first marker Blender takes the first marker's camera too.
                scene.timeline_markers[0].frame = 10
                with self.assertRaisesRegex(pipeline.InputError,
                                            "no scene camera; timeline marker 'Shot' binds 'Camera'"):
                    pipeline.run(scene, "fxaa", range(1, 3), out, filter_frames=False)
            finally:
                scene.timeline_markers.clear()
                scene.camera = cam
            with self.assertRaisesRegex(pipeline.InputError, "unknown method 'smaa'"):
                pipeline.run(scene, "smaa", range(1, 3), out, filter_frames=False)
            # An empty as the scene camera (Blender renders through it), stereoscopy, non-square pixels
            # under a jittering method: refused by name before anything is written.
            empty = bpy.data.objects.new("Viewpoint", None)
            scene.collection.objects.link(empty)
            scene.camera = empty
            try:
                with self.assertRaisesRegex(pipeline.InputError, "'Viewpoint' is an empty object, not a camera"):
                    pipeline.run(scene, "fxaa", range(1, 3), out, filter_frames=False)
                with self.assertRaisesRegex(render.RenderError, "not a camera"):
                    render.render_frames(scene, plan.make_plan("none", plan.SceneFacts(1, 2)), [1], out)
            finally:
                scene.camera = cam
            # ... also when a timeline marker makes it the scene camera on a later frame of the run (a
            # marker after the run's frames does not matter).
            scene.timeline_markers.new("Start", frame=1).camera = cam
            scene.timeline_markers.new("Cut", frame=2).camera = empty
            try:
                with self.assertRaisesRegex(pipeline.InputError, "marker 'Cut' \\(frame 2\\) makes 'Viewpoint'"):
                    pipeline.run(scene, "fxaa", range(1, 3), out, filter_frames=False)
                with self.assertRaisesRegex(render.RenderError, "marker 'Cut'"):
                    render.render_frames(scene, plan.make_plan("none", plan.SceneFacts(1, 2)), [1, 2], out)
                self.assertIsNone(render.camera_problem(scene, [1]))
            finally:
                scene.timeline_markers.clear()
                scene.camera = cam
            scene.render.use_multiview = True
            try:
                with self.assertRaisesRegex(pipeline.InputError, "stereoscopy is on"):
                    pipeline.run(scene, "fxaa", range(1, 3), out, filter_frames=False)
            finally:
                scene.render.use_multiview = False
            # A percentage that leaves no pixel (Blender: "Image too small"; taa divided by zero).
            size = scene.render.resolution_x, scene.render.resolution_y
            scene.render.resolution_x, scene.render.resolution_y = 64, 36
            scene.render.resolution_percentage = 1
            try:
                for method in ("fxaa", "taa"):
                    with self.assertRaisesRegex(pipeline.InputError, "renders 0x0 pixels \\(64x36 at 1%\\)"):
                        pipeline.run(scene, method, range(1, 3), out, filter_frames=False)
            finally:
                scene.render.resolution_percentage = 100
                scene.render.resolution_x, scene.render.resolution_y = size
            scene.render.pixel_aspect_x = 2.0
            logged = []
            try:
                with self.assertRaisesRegex(pipeline.InputError, "taa renders jittered frames, and jitter needs "
                                                                 "square pixels"):
                    pipeline.run(scene, "taa", range(1, 3), out, filter_frames=False, log=logged.append)
                # rsaa's sub-samples are jittered renders too: refused before its first frame, not after it
                with self.assertRaisesRegex(pipeline.InputError, "rsaa renders sub-samples by jittering the "
                                                                 "camera, and jitter needs square pixels"):
                    pipeline.run(scene, "rsaa", range(1, 3), out, filter_frames=False, log=logged.append)
            finally:
                scene.render.pixel_aspect_x = 1.0
            self.assertFalse(os.path.exists(out), "nothing written on bad input")
        self.assertEqual(touched_state(scene), before_state)

    @unittest.skipUnless(harness.library_usable()[0], "libcrisp not built")
    def test_pngs_follow_the_scenes_colour_management(self):
        """Under Filmic with a look and an exposure, the run's PNG of method "none" (the 1-sample frame
        as rendered) matches Blender's own PNG of that frame within its dither (a plain sRGB encoding of
        the linear EXR was 0.034 off on average, 0.17 at most); the output settings are put back."""
        scene = harness.build_scene("still_life")
        scene.render.resolution_x, scene.render.resolution_y = 64, 36
        view = scene.view_settings
        view.view_transform, view.look, view.exposure = "Filmic", "High Contrast", 0.7
        settings = scene.render.image_settings
        settings.file_format, settings.color_depth = "OPEN_EXR", "16"
        with tempfile.TemporaryDirectory() as d:
            pipeline.run(scene, "none", [1], d, log=lambda *a: None)
            self.assertEqual((settings.file_format, settings.color_depth), ("OPEN_EXR", "16"))
            a = image_pixels(os.path.join(d, "filtered", "frame_0001.png"))
            # Blender's own 1-sample PNG of frame 1, with the light probes Crisp renders with.
            scene.eevee.taa_render_samples = 1
            scene.eevee.gi_cubemap_resolution = render.CUBEMAP_RESOLUTION
            scene.render.use_compositing = False  # as Crisp renders (the scene may hold an earlier test's nodes)
            settings.file_format, settings.color_mode, settings.color_depth = "PNG", "RGBA", "8"
            scene.render.filepath = os.path.join(d, "own.png")
            scene.frame_set(1)
            bpy.ops.render.render(write_still=True, scene=scene.name)  # not the context's scene
            b = image_pixels(scene.render.filepath)
        diff = [abs(x - y) for i, (x, y) in enumerate(zip(a, b)) if i % 4 != 3]
        self.assertEqual(len(a), len(b))
        self.assertLessEqual(max(diff), 3.5 / 255)
        self.assertLess(sum(diff) / len(diff), 0.005)

    @unittest.skipUnless(harness.library_usable()[0], "libcrisp not built")
    def test_png_of_the_output_equals_the_png_of_its_exr(self):
        """The run makes each PNG from the filter's output in memory (render.write_display_png), not from
        the EXR it wrote loaded back: the PNG must be what Blender makes of that EXR, byte for byte in
        every pixel, under Filmic with a look and an exposure and with a transparent film (taa filters the
        alpha, so the outlines are partly covered)."""
        scene = harness.build_scene("still_life")
        scene.render.resolution_x, scene.render.resolution_y = 64, 36
        scene.render.film_transparent = True
        view = scene.view_settings
        view.view_transform, view.look, view.exposure = "Filmic", "High Contrast", 0.7
        try:
            with tempfile.TemporaryDirectory() as d:
                pipeline.run(scene, "taa", [1, 2], d, log=lambda *a: None)
                for f in (1, 2):
                    exr = os.path.join(d, "filtered", render.frame_name(f))
                    image = bpy.data.images.load(exr, check_existing=False)
                    settings = scene.render.image_settings
                    settings.file_format, settings.color_mode, settings.color_depth = "PNG", "RGBA", "8"
                    image.save_render(os.path.join(d, "from_exr.png"), scene=scene)
                    bpy.data.images.remove(image)
                    a = image_pixels(os.path.join(d, "filtered", render.frame_name(f, ".png")))
                    b = image_pixels(os.path.join(d, "from_exr.png"))
                    self.assertEqual(len(a), 64 * 36 * 4)
                    alphas = a[3::4]
                    self.assertTrue(any(0.0 < x < 1.0 for x in alphas), "no partly covered pixel to compare")
                    self.assertTrue(a == b, "frame %d: %d values differ" % (f, sum(x != y for x, y in zip(a, b))))
        finally:
            scene.render.film_transparent = False

    def test_filtered_exrs_follow_the_scenes_exr_output_settings(self):
        """With the scene's File Format OpenEXR, the filtered EXRs are stored at its Color Depth and Codec,
        as Blender stores its own render (they were always float ZIP); with another format (PNG), float ZIP.
        The renders' own settings (float, no codec) never leak into them, the run says what it used, and a
        resume after the settings changed makes the frames again."""
        scene = harness.build_scene("still_life")
        scene.render.resolution_x, scene.render.resolution_y = 48, 27
        settings = scene.render.image_settings
        half, full = 1, 2  # the EXR channel list's pixel types
        codes = {"NONE": 0, "ZIP": 3, "PIZ": 4, "DWAA": 8}  # the header's compression byte
        try:
            with tempfile.TemporaryDirectory() as d:
                logged = []
                pipeline.run(scene, "taa", [1, 2], d, log=logged.append)
                self.assertFalse([s for s in logged if "stored as the scene's Output" in s], logged)
                for f in (1, 2):
                    names, attrs = exr_util.channels(os.path.join(d, "filtered", render.frame_name(f)))
                    self.assertEqual(({t for _, t in attrs["channels"]}, attrs["compression"]), ({full}, codes["ZIP"]))
                settings.file_format, settings.color_depth, settings.exr_codec = "OPEN_EXR", "16", "DWAA"
                logged = []
                pipeline.run(scene, "taa", [1, 2], d, log=logged.append, resume=True)
                self.assertIn("info: the filtered EXRs are stored as the scene's Output properties say: half float, "
                              "DWAA (Color Depth, Codec)", logged)
                self.assertTrue([s for s in logged if s.startswith("frame 1 was made with other settings (exr ")],
                                logged)
                for f in (1, 2):
                    names, attrs = exr_util.channels(os.path.join(d, "filtered", render.frame_name(f)))
                    self.assertEqual(names, ["A", "B", "G", "R"])
                    self.assertEqual(({t for _, t in attrs["channels"]}, attrs["compression"]), ({half}, codes["DWAA"]))
                    names, attrs = exr_util.channels(os.path.join(d, "input", render.frame_name(f)))
                    self.assertEqual(({t for _, t in attrs["channels"]}, attrs["compression"]), ({full}, codes["NONE"]))
                    self.assertTrue(os.path.isfile(os.path.join(d, "filtered", render.frame_name(f, ".png"))))
                with open(os.path.join(d, "run.json")) as fh:
                    self.assertEqual(json.load(fh)["exr"], {"depth": 16, "codec": "dwaa"})
                self.assertEqual((settings.file_format, settings.color_depth, settings.exr_codec),
                                 ("OPEN_EXR", "16", "DWAA"), "put back after the renders")
                # Back to PNG output: the resume makes the half DWAA frames again as float ZIP.
                settings.file_format = "PNG"
                logged = []
                pipeline.run(scene, "taa", [1, 2], d, log=logged.append, resume=True)
                self.assertTrue([s for s in logged if s.startswith("frame 1 was made with other settings (exr ")],
                                logged)
                for f in (1, 2):
                    names, attrs = exr_util.channels(os.path.join(d, "filtered", render.frame_name(f)))
                    self.assertEqual(({t for _, t in attrs["channels"]}, attrs["compression"]), ({full}, codes["ZIP"]))
                # Full float PIZ, as a multilayer output: the filtered frames are still one RGBA layer.
                settings.file_format, settings.color_depth, settings.exr_codec = "OPEN_EXR_MULTILAYER", "32", "PIZ"
                pipeline.run(scene, "fxaa", [1], os.path.join(d, "multi"), log=lambda *a: None)
                names, attrs = exr_util.channels(os.path.join(d, "multi", "filtered", render.frame_name(1)))
                self.assertEqual(names, ["A", "B", "G", "R"])
                self.assertEqual(({t for _, t in attrs["channels"]}, attrs["compression"]), ({full}, codes["PIZ"]))
        finally:
            settings.file_format, settings.color_depth, settings.exr_codec = "PNG", "8", "ZIP"

    def test_values_the_output_menus_hide_are_kept_and_followed(self):
        """Values Blender's Output menus no longer list read "" and Blender still writes them: B44A chosen at
        half float before the Color Depth or File Format changed, RGBA chosen for an FFmpeg output before its
        codec changed to H.264. A run leaves them as they were (it ended with "could not restore" and lost
        them), and in OpenEXR at full float the filtered EXRs are B44A, as Blender's own render of the scene
        is (the library was handed the codec "" and refused it)."""
        scene = harness.build_scene("spinning_cube")
        scene.render.resolution_x, scene.render.resolution_y = 48, 27
        settings, ffmpeg = scene.render.image_settings, scene.render.ffmpeg
        full, b44a = 2, 7  # the EXR channel list's pixel type, the header's compression byte

        def state():
            return (settings.file_format, settings.color_depth, settings.color_mode, settings.exr_codec,
                    ffmpeg.format, ffmpeg.codec)

        def hidden():  # what the menus hide, read where they list it (the FFmpeg colour first: a format
            ffmpeg.codec = "PNG"  # switch would change it)
            mode = settings.color_mode
            settings.file_format, settings.color_depth = "OPEN_EXR", "16"
            return settings.exr_codec, mode

        try:
            for file_format, depth, rgba in (("OPEN_EXR", "32", False), ("JPEG", "8", False),
                                             ("FFMPEG", "8", False), ("FFMPEG", "8", True)):
                settings.file_format, settings.color_depth, settings.exr_codec = "OPEN_EXR", "16", "B44A"
                settings.file_format, settings.color_depth = file_format, depth
                if file_format == "FFMPEG":  # not the defaults a switch of format back to FFmpeg gives
                    ffmpeg.format, ffmpeg.codec = "QUICKTIME", "PNG"
                    settings.color_mode = "RGBA" if rgba else "RGB"
                    ffmpeg.codec = "H264" if rgba else "PNG"
                before = state()
                self.assertEqual(before[3], "", "the menu shows B44A")
                self.assertEqual(before[2] == "", rgba, "the menu shows RGBA")
                with tempfile.TemporaryDirectory() as d:
                    pipeline.run(scene, "fxaa", [1], d, log=lambda *a: None)
                    if file_format == "OPEN_EXR":
                        _, attrs = exr_util.channels(os.path.join(d, "filtered", render.frame_name(1)))
                        self.assertEqual(({t for _, t in attrs["channels"]}, attrs["compression"]), ({full}, b44a))
                self.assertEqual(state(), before, (file_format, rgba))
                self.assertEqual(hidden(), ("B44A", "RGBA" if rgba else before[2]), (file_format, rgba))
        finally:
            settings.file_format, settings.color_depth, settings.exr_codec = "PNG", "8", "ZIP"
            settings.color_mode = "RGBA"

    def test_aovs_are_left_out_of_the_renders_and_put_back(self):
        """The view layer's AOVs, which no filter reads: EEVEE rendered each once more per frame into
        Crisp's inputs (four made a frame about 4 times slower and 5 times larger), and one named "Depth"
        beside the Z pass made rsaa's renders crash Blender. They are removed for the renders: the inputs
        hold none, the filtered frames are those of the scene without them, and afterwards the AOVs are
        back in their order, names and types, with the active one, and the compositor's link from one of
        them still takes it."""
        scene = harness.build_scene("spinning_cube")
        scene.render.resolution_x, scene.render.resolution_y = 48, 27
        layer = render.default_view_layer(scene)
        nodes, viewer = [], None

        with tempfile.TemporaryDirectory() as d:
            for method in ("taa", "rsaa"):
                pipeline.run(scene, method, [1, 2], os.path.join(d, method + "_plain"), log=lambda *a: None)
            aovs = [("Depth", "COLOR"), ("mask", "VALUE"), ("spec", "COLOR")]
            for name, kind in aovs:
                aov = layer.aovs.add()
                aov.name, aov.type = name, kind
            layer.active_aov_index = 1
            try:
                for material in bpy.data.materials:  # each AOV written with a value far from any depth
                    if material.use_nodes:
                        for name, _ in aovs:
                            node = material.node_tree.nodes.new("ShaderNodeOutputAOV")
                            node.name = name  # (Blender 3.4: the AOV node's name is the AOV it writes)
                            node.inputs["Color"].default_value = (0.25, 0.5, 0.75, 1.0)
                            nodes.append((material, node))
                scene.use_nodes = True
                tree = scene.node_tree
                viewer = tree.nodes.new("CompositorNodeViewer")
                tree.links.new(tree.nodes["Render Layers"].outputs["mask"], viewer.inputs["Image"])
                for method in ("taa", "rsaa"):
                    out = os.path.join(d, method + "_aov")
                    pipeline.run(scene, method, [1, 2], out, log=lambda *a: None)
                    names, _ = exr_util.channels(os.path.join(out, "input", render.frame_name(2)))
                    layers = {}
                    for n in names:
                        layers.setdefault(n.split(".")[1], []).append(n.split(".")[-1])
                    self.assertFalse({"mask", "spec"} & set(layers), (method, names))
                    self.assertEqual(layers.get("Depth", ["Z"]), ["Z"], method)  # the Z pass, not the AOV's RGBA
                    self.assertEqual([(a.name, a.type) for a in layer.aovs], aovs, method)
                    self.assertEqual(layer.active_aov_index, 1, method)
                    link, = viewer.inputs["Image"].links
                    self.assertEqual((link.from_socket.name, link.is_valid), ("mask", True), method)
                    for f in (1, 2):
                        plain = image_pixels(os.path.join(d, method + "_plain", "filtered", render.frame_name(f)))
                        self.assertTrue(image_pixels(os.path.join(out, "filtered", render.frame_name(f))) == plain,
                                        (method, f))
            finally:
                for material, node in nodes:
                    material.node_tree.nodes.remove(node)
                if viewer is not None:
                    scene.node_tree.nodes.remove(viewer)
                with bpy.context.temp_override(view_layer=layer):
                    while len(layer.aovs):  # Blender 3.4's collection has no remove: the operator removes the active
                        layer.active_aov_index = 0
                        bpy.ops.scene.view_layer_remove_aov()

    def test_a_scene_linked_under_the_name_of_the_files_own_is_refused(self):
        """The file's own scene and one linked from another file under the same name: Blender renders a
        scene by its name, so a run of the linked one rendered the file's own into its frames. Refused
        before anything is made, naming both and the way out."""
        scene = harness.build_scene("still_life")
        scene.render.resolution_x, scene.render.resolution_y = 32, 18
        with tempfile.TemporaryDirectory() as d:
            library = os.path.join(d, "set.blend")
            bpy.data.libraries.write(library, {scene})
            with bpy.data.libraries.load(library, link=True) as (_, linked):
                linked.scenes = [scene.name]
            twin = linked.scenes[0]
            try:
                self.assertEqual((twin.name, twin.library is not None), (scene.name, True))
                for which in (scene, twin):
                    out = os.path.join(d, "out")
                    with self.assertRaises(pipeline.InputError) as caught:
                        pipeline.run(which, "fxaa", [1], out, log=lambda *a: None)
                    self.assertIn("2 scenes are named '%s' (this file's own and one linked from '%s')"
                                  % (scene.name, twin.library.filepath), str(caught.exception))
                    self.assertIn("rename this file's own scene", str(caught.exception))
                    self.assertFalse(os.path.exists(out))
            finally:
                bpy.data.libraries.remove(twin.library)

    def test_a_resume_over_a_record_edited_by_hand(self):
        """run.json's frames edited into something else than a list of entries (null, a number, entries
        whose frame is not a number): a resume records the frames it keeps and makes without them; it
        raised a TypeError, and so did every resume after it."""
        scene = harness.build_scene("still_life")
        scene.render.resolution_x, scene.render.resolution_y = 32, 18
        with tempfile.TemporaryDirectory() as d:
            pipeline.run(scene, "fxaa", [1, 2], d, log=lambda *a: None)
            record = os.path.join(d, "run.json")
            for frames in (None, 5, "1-2", [{"frame": [1]}, {"frame": "2"}, 7, {"frame": 2, "render_s": 0.5}]):
                with open(record) as fh:
                    data = json.load(fh)
                data["frames"] = frames
                with open(record, "w") as fh:
                    json.dump(data, fh)
                os.remove(os.path.join(d, "filtered", render.frame_name(2)))
                pipeline.run(scene, "fxaa", [1, 2], d, log=lambda *a: None, resume=True)
                with open(record) as fh:
                    written = json.load(fh)
                self.assertEqual([e["frame"] for e in written["frames"]], [1, 2], frames)
                self.assertEqual(written["status"], "complete")

    def test_a_linked_object_with_a_local_ones_name(self):
        """still_life's still "Ball" beside a moving "Ball" linked from another file, into the scene's
        collections or through a collection instance: the plan saw one of them (objects were told apart
        by name) and no motion. Both are seen: the linked one moves, and since Cryptomatte hashes the name
        alone they share an object ID, which the run says, as of instances; the sidecars leave that ID
        out (its pixels taken as still; the local Ball's matrix stood for the instance's)."""
        scene = harness.build_scene("still_life")
        scene.render.resolution_x, scene.render.resolution_y = 32, 18
        local = bpy.data.objects["Ball"]
        with tempfile.TemporaryDirectory() as d:
            asset = os.path.join(d, "asset.blend")
            local.name = "Ball (local)"  # the library's sphere takes the name, then the local one gets it back
            props = bpy.data.collections.new("Props")
            ball = bpy.data.objects.new("Ball", local.data)
            props.objects.link(ball)
            for frame, x in ((1, -1.0), (3, 1.0)):
                ball.location = (x, 0.0, 0.5)
                ball.keyframe_insert("location", frame=frame)
            bpy.data.libraries.write(asset, {props}, fake_user=True)
            action = ball.animation_data.action
            bpy.data.objects.remove(ball)
            bpy.data.collections.remove(props)
            bpy.data.actions.remove(action)
            local.name = "Ball"
            with bpy.data.libraries.load(asset, link=True) as (_, linked):
                linked.collections = ["Props"]
            props = linked.collections[0]
            try:
                # Linked into the scene's collections, and instanced by an empty (Blender's default link).
                for way in ("collection", "instance"):
                    if way == "collection":
                        scene.collection.children.link(props)
                    else:
                        scene.collection.children.unlink(props)
                        empty = bpy.data.objects.new("Props instance", None)
                        empty.instance_type, empty.instance_collection = "COLLECTION", props
                        scene.collection.objects.link(empty)
                    the_plan, facts = pipeline.scene_plan(scene, "taa", [1, 2, 3])
                    self.assertIn("motion", the_plan.passes, way)
                    self.assertEqual((facts.moving_objects, facts.shared_id_movers), (["Ball"], ["Ball"]), way)
                    self.assertEqual(facts.visible_objects.count("Ball"), 2, way)
                    logged = []
                    pipeline.run(scene, "taa", [1, 2], os.path.join(d, way), log=logged.append)
                    self.assertTrue([s for s in logged if s.startswith("note: 'Ball' moves but renders more than "
                                                                       "once")], (way, logged))
                    side = render.read_sidecar(os.path.join(d, way, "input"), 2)
                    self.assertNotIn(hashing.cryptomatte_hex("Ball"), side["objects"], way)
                    self.assertIn(hashing.cryptomatte_hex("Floor"), side["objects"], way)
            finally:
                if props.name in scene.collection.children:
                    scene.collection.children.unlink(props)
                if "Props instance" in bpy.data.objects:
                    bpy.data.objects.remove(bpy.data.objects["Props instance"])
                bpy.data.libraries.remove(props.library)

    def test_the_renders_are_stored_with_the_input_codec_asked(self):
        """input/ and reference/ are stored with the run's input codec (uncompressed unless asked), all of
        them lossless: the filtered frames are those of uncompressed renders, value for value. The sidecar
        and run.json say which; a resume under another codec keeps the frames (they would be the same); a
        lossy codec is refused before anything is made."""
        scene = harness.build_scene("spinning_cube")
        scene.render.resolution_x, scene.render.resolution_y = 48, 27
        codes = {"NONE": 0, "ZIP": 3, "PIZ": 4}  # the header's compression byte

        def compression(path):
            return exr_util.channels(path)[1]["compression"]

        with tempfile.TemporaryDirectory() as d:
            runs = {"none": os.path.join(d, "none"), "piz": os.path.join(d, "piz"), "zip": os.path.join(d, "zip")}
            for codec, out in runs.items():
                pipeline.run(scene, "taa", [1, 2, 3], out, reference_samples=2, log=lambda *a: None,
                             input_codec=codec.upper() if codec == "piz" else codec)
                with open(os.path.join(out, "run.json")) as fh:
                    self.assertEqual(json.load(fh)["input_codec"], codec)
                for f in (1, 2, 3):
                    for folder in ("input", "reference"):
                        self.assertEqual(compression(os.path.join(out, folder, render.frame_name(f))),
                                         codes[codec.upper()], (codec, folder, f))
                    side = render.read_sidecar(os.path.join(out, "input"), f)
                    self.assertIn("codec %s," % codec.upper(), side["render_settings"]["exr"])
            self.assertLess(os.path.getsize(os.path.join(runs["piz"], "input", "frame_0002.exr")),
                            os.path.getsize(os.path.join(runs["none"], "input", "frame_0002.exr")))
            for f in (1, 2, 3):
                plain = image_pixels(os.path.join(runs["none"], "filtered", render.frame_name(f)))
                self.assertEqual(len(plain), 48 * 27 * 4)
                for codec in ("piz", "zip"):
                    self.assertTrue(image_pixels(os.path.join(runs[codec], "filtered", render.frame_name(f))) == plain,
                                    (codec, f))
            logged = []
            pipeline.run(scene, "taa", [1, 2, 3], runs["piz"], reference_samples=2, log=logged.append, resume=True,
                         input_codec="none")
            self.assertIn("every output of frames 1-3 exists; nothing to do", logged)
            lossy = os.path.join(d, "lossy")
            for codec in ("dwaa", None):  # a lossy codec, and no codec at all (not read as "none")
                with self.assertRaises(pipeline.InputError) as caught:
                    pipeline.run(scene, "taa", [1], lossy, log=lambda *a: None, input_codec=codec)
                self.assertIn("input codec %r is not one of: none, piz, zip" % codec, str(caught.exception))
            self.assertFalse(os.path.exists(lossy))

    def test_settings_crisp_leaves_out_are_said(self):
        """The scene's motion blur and its compositor are not applied to Crisp's frames: the log says so
        (and what the run does instead) rather than dropping them silently."""
        scene = harness.build_scene("still_life")
        scene.render.resolution_x, scene.render.resolution_y = 32, 18
        scene.eevee.use_motion_blur = True
        scene.use_nodes = scene.render.use_compositing = True
        tree = scene.node_tree  # Blender's default, made here: an earlier test may have left other nodes
        tree.nodes.clear()
        layers, composite = tree.nodes.new("CompositorNodeRLayers"), tree.nodes.new("CompositorNodeComposite")
        tree.links.new(layers.outputs["Image"], composite.inputs["Image"])
        logged = []
        with tempfile.TemporaryDirectory() as d:
            pipeline.run(scene, "fxaa", [1], d, filter_frames=False, log=logged.append)
            self.assertTrue(any("motion blur is off" in line for line in logged), logged)
            # The default tree, and Crisp's own result node beside it (a second run after the first put it
            # there), composite nothing Crisp's frames miss: no note on every run.
            pipeline.run(scene, "fxaa", [1], d, log=logged.append)
            compositor.load_result(scene, os.path.join(d, "filtered"), 1, 1)
            pipeline.run(scene, "fxaa", [1], d, filter_frames=False, log=logged.append)
            self.assertFalse(any("compositor is not applied" in line for line in logged), logged)
            # Nor does a node that feeds nothing, a muted one, or the user's own node of Crisp's group.
            glare = tree.nodes.new("CompositorNodeGlare")
            mine = tree.nodes.new("CompositorNodeGroup")
            mine.node_tree = next(n.node_tree for n in tree.nodes if n.get(compositor.NODE_TAG))
            pipeline.run(scene, "fxaa", [1], d, filter_frames=False, log=logged.append)
            tree.links.new(mine.outputs["Image"], composite.inputs["Image"])
            pipeline.run(scene, "fxaa", [1], d, filter_frames=False, log=logged.append)
            tree.links.new(layers.outputs["Image"], glare.inputs["Image"])
            tree.links.new(glare.outputs["Image"], composite.inputs["Image"])
            glare.mute = True
            pipeline.run(scene, "fxaa", [1], d, filter_frames=False, log=logged.append)
            self.assertFalse(any("compositor is not applied" in line for line in logged), logged)
            glare.mute = False  # a node that changes the image
            pipeline.run(scene, "fxaa", [1], d, filter_frames=False, log=logged.append)
            self.assertTrue(any("compositor is not applied" in line for line in logged), logged)
            # So does the user's copy of Crisp's group (which keeps its tag) with a node added inside.
            logged.clear()
            mine.node_tree = mine.node_tree.copy()
            inner = mine.node_tree.nodes
            inner_glare = inner.new("CompositorNodeGlare")
            mine.node_tree.links.new(inner["Crisp Frames"].outputs["Image"], inner_glare.inputs["Image"])
            mine.node_tree.links.new(inner_glare.outputs["Image"], inner["Group Output"].inputs["Image"])
            tree.links.new(mine.outputs["Image"], composite.inputs["Image"])
            pipeline.run(scene, "fxaa", [1], d, filter_frames=False, log=logged.append)
        self.assertTrue(any("compositor is not applied" in line for line in logged), logged)
        scene.render.film_transparent = True
        logged.clear()
        with tempfile.TemporaryDirectory() as d:
            pipeline.run(scene, "fxaa", [1], d, filter_frames=False, log=logged.append)
            self.assertFalse(any("transparent" in line for line in logged), "nothing filtered: nothing to say")
            pipeline.run(scene, "fxaa", [1], d, log=logged.append)
        self.assertTrue(any("fxaa anti-aliases the colour, not the alpha" in line for line in logged), logged)
        # rsaa resamples colour and alpha together at geometric edges: the outline's alpha is smooth.
        logged.clear()
        with tempfile.TemporaryDirectory() as d:
            pipeline.run(scene, "rsaa", [1], d, write_png=False, log=logged.append)
            with native.Context() as ctx, native.Frame(ctx, os.path.join(d, "filtered", "frame_0001.exr")) as fr:
                ptr, fmt = fr.pass_pointer("color")
                self.assertEqual(fmt, native.FORMAT_FLOAT4)
                alpha = list((ctypes.c_float * (fr.width * fr.height * 4)).from_address(ptr))[3::4]
        self.assertTrue(any(0.0 < a < 1.0 for a in alpha), "some outline pixel blends alpha")
        notes = [line for line in logged if "transparent" in line]
        self.assertEqual(len(notes), 1, logged)
        self.assertIn("colour and alpha together on geometric edges", notes[0])
        self.assertNotIn("not the alpha", notes[0])
        scene.render.film_transparent = False
        # A render region (cropped or not): Crisp renders and filters the whole frame, and says so.
        scene.render.use_border = scene.render.use_crop_to_border = True
        scene.render.border_min_x = scene.render.border_min_y = 0.25
        logged.clear()
        with tempfile.TemporaryDirectory() as d:
            pipeline.run(scene, "fxaa", [1], d, filter_frames=False, log=logged.append)
            with open(os.path.join(d, "input", "frame_0001.json")) as f:
                self.assertEqual(json.load(f)["render_settings"]["resolution"], [32, 18])
        self.assertTrue(any("render region is not used" in n and "whole frame, 32x18" in n for n in logged), logged)
        self.assertTrue(scene.render.use_border, "put back")
        scene.render.use_border = False
        # Sequencer strips (Blender would render the edit, not the camera's view); a sound strip alone
        # changes no picture.
        editor = scene.sequence_editor_create()
        red = editor.sequences.new_effect("Red", "COLOR", channel=1, frame_start=1, frame_end=10)
        logged.clear()
        with tempfile.TemporaryDirectory() as d:
            pipeline.run(scene, "fxaa", [1], d, filter_frames=False, log=logged.append)
        self.assertTrue(any("sequencer strips are not applied" in n for n in logged), logged)
        editor.sequences.remove(red)
        # The world's probe at Crisp's cubemap size, not the scene's (sharp reflections of a detailed world
        # differ from Blender's own render: mean 0.11 on mirror balls under a checker world at 512).
        scene.eevee.gi_cubemap_resolution = "512"
        logged.clear()
        with tempfile.TemporaryDirectory() as d:
            pipeline.run(scene, "fxaa", [1], d, filter_frames=False, log=logged.append)
        # Said as information, not as a note the operator turns into a warning: Blender's default is 512,
        # so nearly every artist's scene would warn of it.
        self.assertTrue(any(n.startswith("info: the world's reflection probe is rendered at 64 px, not the scene's 512")
                            for n in logged), logged)
        self.assertEqual(scene.eevee.gi_cubemap_resolution, "512", "put back")
        scene.eevee.gi_cubemap_resolution = render.CUBEMAP_RESOLUTION
        self.assertTrue(scene.eevee.use_motion_blur, "put back")
        scene.eevee.use_motion_blur = False
        scene.use_nodes = False
        logged.clear()
        with tempfile.TemporaryDirectory() as d:
            pipeline.run(scene, "fxaa", [1], d, filter_frames=False, log=logged.append)
        self.assertFalse([line for line in logged if "motion blur" in line or "compositor" in line
                          or "region" in line or "sequencer" in line or "probe" in line], logged)

    def test_temporal_methods_anti_alias_a_transparent_films_alpha(self):
        """With Film > Transparent the 1-sample render's alpha is 0 or 1 along every outline; after one
        jitter period taa's alpha is close to EEVEE's own 64-sample alpha (native/filters/temporal_alpha.h)."""
        scene = harness.build_scene("still_life")
        scene.render.resolution_x, scene.render.resolution_y = 64, 36
        scene.render.film_transparent = True

        def alpha_of(path):
            with native.Context() as ctx, native.Frame(ctx, path) as fr:
                ptr, fmt = fr.pass_pointer("color")
                self.assertEqual(fmt, native.FORMAT_FLOAT4)
                return list((ctypes.c_float * (fr.width * fr.height * 4)).from_address(ptr))[3::4]

        logged = []
        with tempfile.TemporaryDirectory() as d:
            pipeline.run(scene, "taa", list(range(1, 17)), d, write_png=False, log=logged.append)
            filtered = alpha_of(os.path.join(d, "filtered", "frame_0016.exr"))
            one = alpha_of(os.path.join(d, "input", "frame_0016.exr"))
            scene.eevee.taa_render_samples = 64
            scene.render.use_compositing = False
            settings = scene.render.image_settings
            settings.file_format, settings.color_mode, settings.color_depth = "OPEN_EXR", "RGBA", "32"
            scene.render.filepath = os.path.join(d, "reference.exr")
            scene.frame_set(16)
            bpy.ops.render.render(write_still=True, scene=scene.name)
            reference = alpha_of(scene.render.filepath)
        self.assertEqual(len(filtered), len(reference))
        outline = [i for i, a in enumerate(reference) if 0.02 < a < 0.98]
        self.assertGreater(len(outline), 20, "the still life has an outline against the film")
        # (After some other tests' renders, EEVEE leaves a few alphas 2e-6 off 0 or 1.)
        soft = sorted(set(a for a in one if 1e-4 < a < 1.0 - 1e-4))
        self.assertEqual(soft, [], "the 1-sample alpha is hard-edged")
        err_one = sum(abs(one[i] - reference[i]) for i in outline) / len(outline)
        err_taa = sum(abs(filtered[i] - reference[i]) for i in outline) / len(outline)
        print("transparent still_life 64x36, frame 16, %d outline pixels: mean |alpha - EEVEE 64|: 1 sample %.4f, "
              "taa %.4f" % (len(outline), err_one, err_taa), file=sys.stderr)
        self.assertLess(err_taa, 0.4 * err_one)
        self.assertTrue(all(0.0 <= a <= 1.0 for a in filtered))
        self.assertTrue(any("anti-aliases the alpha as well" in line for line in logged), logged)

    def test_run_json_says_how_the_run_ended(self):
        """run.json is this run's record also when the run is stopped or fails part-way; a resume
        keeps the frames made before it."""
        scene = harness.build_scene("still_life")
        scene.render.resolution_x, scene.render.resolution_y = 32, 18

        def record(d):
            with open(os.path.join(d, "run.json")) as f:
                run = json.load(f)
            return run["status"], [e["frame"] for e in run["frames"]]

        def interrupt_after(n):
            calls = []

            def should_cancel():
                calls.append(1)
                if len(calls) > n:
                    raise KeyboardInterrupt
                return False
            return should_cancel

        with tempfile.TemporaryDirectory() as d:
            pipeline.run(scene, "fxaa", range(1, 4), d, filter_frames=False, log=lambda *a: None)
            self.assertEqual(record(d), ("complete", [1, 2, 3]))
            # Interrupted after frame 1: the record is this run's, not the complete one before it.
            with self.assertRaises(KeyboardInterrupt):
                pipeline.run(scene, "none", range(1, 4), d, filter_frames=False, log=lambda *a: None, samples=2,
                             should_cancel=interrupt_after(1))
            run = json.load(open(os.path.join(d, "run.json")))
            self.assertEqual((run["method"], run["status"], [e["frame"] for e in run["frames"]]),
                             ("none", "failed: KeyboardInterrupt", [1]))
            # Cancelled (should_cancel) after frame 2 of a resume: frame 1 kept (with its entry), 2 made,
            # 3 (the first run's, at 1 sample) not.
            calls = []
            pipeline.run(scene, "none", range(1, 4), d, filter_frames=False, log=lambda *a: None, samples=2,
                         resume=True, should_cancel=lambda: calls.append(1) or len(calls) > 1)
            self.assertEqual(record(d), ("cancelled at frame 3", [1, 2]))
            self.assertIn("render_s", json.load(open(os.path.join(d, "run.json")))["frames"][0])
            pipeline.run(scene, "none", range(1, 4), d, filter_frames=False, log=lambda *a: None, samples=2,
                         resume=True)
            self.assertEqual(record(d), ("complete", [1, 2, 3]))
        with tempfile.TemporaryDirectory() as d:
            # Stopped among the references (should_cancel is asked before each frame, then before each
            # reference frame): every frame made, the first reference not.
            calls = []
            pipeline.run(scene, "none", range(1, 3), d, filter_frames=False, log=lambda *a: None,
                         reference_samples=2, should_cancel=lambda: calls.append(1) or len(calls) > 2)
            self.assertEqual(record(d), ("cancelled at reference frame 1", [1, 2]))

    @unittest.skipUnless(harness.library_usable()[0], "libcrisp not built")
    def test_a_temporal_run_that_cannot_continue_the_frames_before_says_so(self):
        """Frame 3 rendered again alone (a retake, a farm task run again without pre-roll) starts taa's history
        at one sample, while the frame 2 beside it in filtered/ continues a history from frame 1: the
        sequence flickers there. The log says so and how to continue it; with a pre-roll it is not said."""
        scene = harness.build_scene("spinning_cube")
        scene.render.resolution_x, scene.render.resolution_y = 32, 18
        with tempfile.TemporaryDirectory() as d:
            pipeline.run(scene, "taa", range(1, 4), d, log=lambda *a: None)
            logged = []
            pipeline.run(scene, "taa", [3], d, log=logged.append)
            self.assertTrue(any(line.startswith("note: taa's history starts again at frame 3") and "--preroll" in line
                                for line in logged), logged)
            logged.clear()
            pipeline.run(scene, "taa", [3], d, log=logged.append, preroll=2, shot=range(1, 4))
            self.assertFalse([line for line in logged if "history starts again" in line], logged)
            logged.clear()
            pipeline.run(scene, "fxaa", [3], d, log=logged.append)  # no history to continue
            self.assertFalse([line for line in logged if "history starts again" in line], logged)
            logged.clear()  # the first frame of another shot: its history starts there, whatever came before
            pipeline.run(scene, "taa", [3, 4], d, log=logged.append, preroll=2, shot=range(3, 5))
            self.assertFalse([line for line in logged if "history starts again" in line], logged)

    def test_frame_step_is_named_not_silently_ignored(self):
        scene = harness.build_scene("still_life")
        scene.frame_step = 2
        lines = []
        try:
            with tempfile.TemporaryDirectory() as d:
                pipeline.run(scene, "taa", range(1, 4), d, plan_only=True, log=lines.append)
        finally:
            scene.frame_step = 1
        self.assertIn("note: the scene's frame step 2 is not used", "\n".join(lines))

    def test_folder_names(self):
        names = ["Shot_1", "Shot/1", "Shot:1", "Shot 1", "Shot 1.", "..", "Scène", "a\\b", "CON", "aux.txt", "con"]
        folders = [output_folder.folder_name(n) for n in names]
        self.assertEqual(len(set(folders)), len(names), folders)
        self.assertEqual((folders[0], folders[3], folders[6]), ("Shot_1", "Shot 1", "Scène"))
        for f in folders:
            self.assertFalse(set(f) & set('<>:"/\\|?*') or f in ("", ".", "..") or f.endswith((".", " ")), f)
            self.assertNotIn(f.split(".")[0].upper(), output_folder.WINDOWS_RESERVED, f)

    def test_each_scene_its_own_folder_kept_when_renamed(self):
        crisp.register()
        self.addCleanup(crisp.unregister)
        scene = harness.build_scene("still_life")
        scene.name = "Shot"
        scene.crisp.property_unset("output_dir")
        # Unsaved, // means no folder: the renders say so instead of writing to the working folder.
        self.assertEqual(bpy.data.filepath, "", "no earlier test in this file saves")
        with self.assertRaisesRegex(output_folder.UnsavedFile, "save the .blend"):
            output_folder.out_dir(scene, writing=True)
        self.assertEqual(scene.crisp.output_dir, "")
        scene.crisp.output_dir = "//renders/"  # relative to a file that is not saved: the same
        with self.assertRaisesRegex(output_folder.UnsavedFile, "not saved yet"):
            output_folder.out_dir(scene, writing=True)
        scene.crisp.output_dir = "renders/"  # relative to the working folder: never meant
        with self.assertRaisesRegex(output_folder.UnsavedFile, "is relative"):
            output_folder.out_dir(scene, writing=True)
        scene.crisp.output_dir = "~/crisp_renders"
        self.assertEqual(output_folder.out_dir(scene, writing=False), os.path.expanduser("~/crisp_renders"))
        scene.crisp.property_unset("output_dir")
        with tempfile.TemporaryDirectory() as d:
            bpy.ops.wm.save_as_mainfile(filepath=os.path.join(d, "f.blend"))
            self.assertEqual(output_folder.default_out_dir(scene), "//crisp/Shot/")
            # A file an older add-on rendered into //crisp/ for this scene keeps that folder.
            os.makedirs(os.path.join(d, "crisp"))
            with open(os.path.join(d, "crisp", "run.json"), "w") as f:
                json.dump({"scene": "Shot"}, f)
            self.assertEqual(output_folder.default_out_dir(scene), "//crisp/")
            os.remove(os.path.join(d, "crisp", "run.json"))
            # The first operator pins the folder into the scene; renamed, the scene keeps it, and a new
            # scene given the old name gets another (so does one whose name differs only in case).
            self.assertEqual(output_folder.out_dir(scene, writing=False), os.path.join(d, "crisp", "Shot"))
            self.assertEqual(scene.crisp.output_dir, "", "only a render pins the folder")
            self.assertEqual(output_folder.out_dir(scene, writing=True), os.path.join(d, "crisp", "Shot"))
            self.assertEqual(scene.crisp.output_dir, "//crisp/Shot/")
            scene.name = "Renamed"
            self.assertEqual(output_folder.out_dir(scene, writing=True), os.path.join(d, "crisp", "Shot"))
            newcomer, lower = bpy.data.scenes.new("Shot"), bpy.data.scenes.new("shot")
            self.assertEqual(output_folder.default_out_dir(newcomer), "//crisp/Shot-2/")
            self.assertEqual(output_folder.default_out_dir(lower), "//crisp/shot-2/")
            # A folder holding another scene's runs (a chunk's run file names the scene too) is not taken.
            os.makedirs(os.path.join(d, "crisp", "Shot-2"))
            with open(os.path.join(d, "crisp", "Shot-2", "run_0001-0004.json"), "w") as f:
                json.dump({"scene": "Elsewhere"}, f)
            self.assertEqual(output_folder.default_out_dir(newcomer), "//crisp/Shot-3/")
            # Runs of a scene of this name are its own: its Output emptied by an undo, or a farm's
            # chunks rendered by `crisp render` (run_AAAA-BBBB.json) into //crisp/<scene>/.
            solo = bpy.data.scenes.new("Solo")
            os.makedirs(os.path.join(d, "crisp", "Solo"))
            with open(os.path.join(d, "crisp", "Solo", "run_0001-0001.json"), "w") as f:
                json.dump({"scene": "Solo"}, f)
            self.assertEqual(output_folder.default_out_dir(solo), "//crisp/Solo/")
            # A copy keeps the pinned Output, as a copied scene keeps its render path; its first render
            # gives it its own folder, and the scene the folder was named after keeps it.
            copy = scene.copy()
            self.assertEqual(output_folder.sharing(copy), ["Renamed"])
            original = bpy.data.scenes.new("Shot.0")  # the folder's namesake, sharing it too
            original.crisp.output_dir = original.crisp.output_pinned = "//crisp/Shot/"
            self.assertEqual(output_folder.out_dir(copy, writing=True), os.path.join(d, "crisp", "Renamed.001"))
            self.assertEqual(output_folder.sharing(copy), [])
            bpy.data.scenes.remove(newcomer)
            namesake = bpy.data.scenes.new("Shot")  # the name the folder was made for: it stays
            namesake.crisp.output_dir = namesake.crisp.output_pinned = "//crisp/Shot/"
            self.assertEqual(output_folder.out_dir(namesake, writing=True), os.path.join(d, "crisp", "Shot"))
            # An Output the user set is used as it is, shared or not.
            lower.crisp.output_dir = "//crisp/Shot/"
            self.assertEqual(output_folder.out_dir(lower, writing=True), os.path.join(d, "crisp", "Shot"))
            for s in (lower, copy, solo, original, namesake):
                bpy.data.scenes.remove(s)

    def test_no_compositor_note_for_nodes_after_crisps_result(self):
        """The run's note that the compositor is not applied to Crisp's frames is for nodes that change the
        render: the artist's nodes after Crisp's result node (a grade of the filtered frames, where the note
        says to apply the compositor) do apply it to them, and are not noted (they were, on every run). A
        node that changes the render before it is mixed with Crisp's frames still is."""
        scene = harness.build_scene("still_life")
        scene.render.resolution_x, scene.render.resolution_y = 32, 18
        scene.use_nodes = scene.render.use_compositing = True
        tree = scene.node_tree
        tree.nodes.clear()
        layers, composite = tree.nodes.new("CompositorNodeRLayers"), tree.nodes.new("CompositorNodeComposite")
        tree.links.new(layers.outputs["Image"], composite.inputs["Image"])
        with tempfile.TemporaryDirectory() as d:
            img = bpy.data.images.new("stand_in", 8, 4)  # a stand-in filtered frame
            img.filepath_raw, img.file_format = os.path.join(d, "frame_0001.png"), "PNG"
            img.save()
            node = compositor.load_result(scene, d, 1, 1, ext=".png")
            grade = tree.nodes.new("CompositorNodeColorBalance")
            tree.links.new(node.outputs["Image"], grade.inputs["Image"])
            tree.links.new(grade.outputs["Image"], composite.inputs["Image"])
            logged = []
            pipeline.run(scene, "fxaa", [1], os.path.join(d, "run"), filter_frames=False, log=logged.append)
            self.assertFalse(any("compositor is not applied" in line for line in logged), logged)
            glare, mix = tree.nodes.new("CompositorNodeGlare"), tree.nodes.new("CompositorNodeMixRGB")
            tree.links.new(layers.outputs["Image"], glare.inputs["Image"])
            tree.links.new(grade.outputs["Image"], mix.inputs[1])
            tree.links.new(glare.outputs["Image"], mix.inputs[2])
            tree.links.new(mix.outputs["Image"], composite.inputs["Image"])
            pipeline.run(scene, "fxaa", [1], os.path.join(d, "run"), filter_frames=False, log=logged.append)
            self.assertTrue(any("compositor is not applied" in line for line in logged), logged)
            bpy.data.images.remove(img)

    def test_compositor_group_per_folder(self):
        scene = harness.build_scene("still_life")
        with tempfile.TemporaryDirectory() as d:
            folders = [os.path.join(d, "one"), os.path.join(d, "two")]
            for folder in folders:
                os.makedirs(folder)
                img = bpy.data.images.new("stand_in", 8, 4)
                img.filepath_raw = os.path.join(folder, "frame_0001.png")
                img.file_format = "PNG"
                img.save()
            scene.use_nodes = True
            scene.node_tree.nodes.clear()
            # A node the user added, showing another scene's result group, stays as it is.
            other = bpy.data.scenes.new("Other")
            theirs = crisp.compositor.load_result(other, folders[1], 1, 1, ext=".png").node_tree
            user_node = scene.node_tree.nodes.new("CompositorNodeGroup")
            user_node.node_tree = theirs
            for _ in range(2):
                node = crisp.compositor.load_result(scene, folders[0], 1, 1, ext=".png")
            mine = [g for g in bpy.data.node_groups if g.get("crisp_folder") == os.path.normcase(folders[0])]
            self.assertEqual(len(mine), 1, [g.name for g in bpy.data.node_groups])
            self.assertEqual(node.node_tree, mine[0])
            self.assertEqual(user_node.node_tree, theirs)
            # A longer range for the other scene: the user's node follows it.
            crisp.compositor.load_result(other, folders[1], 1, 3, ext=".png")
            self.assertEqual(user_node.node_tree.nodes["Crisp Frames"].frame_duration, 3)
            # A copy of the scene (its compositor holds copies of both nodes), given the other folder:
            # Crisp's node is switched to that folder's group, the user's stays untagged.
            copy = scene.copy()
            copied = crisp.compositor.load_result(copy, folders[1], 1, 1, ext=".png")
            group_nodes = [n for n in copy.node_tree.nodes if n.bl_idname == "CompositorNodeGroup"]
            self.assertEqual(len(group_nodes), 2)
            self.assertTrue(copied.get("crisp_result"))
            self.assertEqual(copied.node_tree, theirs)
            self.assertEqual([n.get("crisp_result") for n in group_nodes].count(True), 1)
            # Without Crisp's node, a user's node already showing the group is used as it is: not
            # tagged, no second node.
            copy.node_tree.nodes.remove(copied)
            again = crisp.compositor.load_result(copy, folders[1], 1, 1, ext=".png")
            self.assertIsNone(again.get("crisp_result"))
            self.assertEqual(len([n for n in copy.node_tree.nodes if n.bl_idname == "CompositorNodeGroup"]), 1)
            for s in (other, copy):
                bpy.data.scenes.remove(s)

    def test_compositor_node_group(self):
        scene = harness.build_scene("still_life")
        with tempfile.TemporaryDirectory() as d:
            # two stand-in filtered frames (plain PNGs written by Blender itself)
            img = bpy.data.images.new("stand_in", 8, 4)
            img.pixels[:] = [0.5] * (8 * 4 * 4)
            for f in (3, 4):
                img.filepath_raw = os.path.join(d, "frame_%04d.png" % f)
                img.file_format = "PNG"
                img.save()
            # A node of the one group all scenes shared before is switched to this scene's own group.
            shared = bpy.data.node_groups.new("Crisp Result", "CompositorNodeTree")
            scene.use_nodes = True
            scene.node_tree.nodes.clear()
            old_node = scene.node_tree.nodes.new("CompositorNodeGroup")
            old_node.node_tree = shared
            node = crisp.compositor.load_result(scene, d, 3, 4, ext=".png")
            group = node.node_tree
            self.assertEqual(group.get("crisp_folder"), os.path.normcase(d))
            self.assertEqual(node, old_node)
            self.assertEqual(node.node_tree, group)
            self.assertTrue(scene.use_nodes)
            frames = group.nodes["Crisp Frames"]
            self.assertEqual(frames.image.source, "SEQUENCE")
            self.assertEqual(frames.frame_duration, 2)
            self.assertEqual(frames.frame_start, 3)
            self.assertEqual(bpy.path.abspath(frames.image.filepath), os.path.join(d, "frame_0003.png"))
            out = group.nodes["Group Output"]
            self.assertTrue(out.inputs["Image"].is_linked)
            # negative frames cannot be a Blender image sequence: refused, not shown at the wrong frames
            with self.assertRaisesRegex(ValueError, "cannot show negative frame numbers"):
                crisp.compositor.load_result(scene, d, -2, 4, ext=".png")
            # loading again reuses the group and the node
            crisp.compositor.load_result(scene, d, 3, 4, ext=".png")
            self.assertEqual(len([n for n in scene.node_tree.nodes if n.bl_idname == "CompositorNodeGroup"]), 1)
            self.assertEqual(crisp.compositor.preview(os.path.join(d, "frame_0004.png")).size[:], (8, 4))


if __name__ == "__main__":
    harness.run(AddonTest)
