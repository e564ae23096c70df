# SPDX-License-Identifier: GPL-2.0-or-later
"""A render of a view layer other than the context's: still_life at 64x36 with a second layer that
leaves the Ball out. pipeline.run(view_layer=that layer) must render that layer, with the passes its
plan switched on there (taa-improved reads depth and object IDs), and its sidecar must list that
layer's objects; rendering the context's layer instead failed with "no 'depth' pass" or, for a
colour-only method, filtered the wrong picture. Without a layer given, the one planned and rendered
is the context's if it renders, else the first that does."""

import json
import os
import sys
import tempfile
import unittest

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import harness  # noqa: E402

import bpy  # noqa: E402
from crisp import native, pipeline, render  # noqa: E402


def colour(path):
    import ctypes
    with native.Context(1) as context, native.Frame(context, path) as frame:
        ptr, fmt = frame.pass_pointer("color")
        return ctypes.string_at(ptr, frame.width * frame.height * native.FORMAT_CHANNELS[fmt] * 4)


class ViewLayerTest(unittest.TestCase):
    def test_the_layer_asked_for_is_rendered(self):
        ok, why = harness.library_usable()
        if not ok:
            self.skipTest(why)
        scene = harness.build_scene("still_life")
        scene.render.resolution_x, scene.render.resolution_y, scene.render.resolution_percentage = 64, 36, 100
        first = scene.view_layers[0]
        second = scene.view_layers.new("NoBall")
        ball = bpy.data.objects["Ball"]
        group = bpy.data.collections.new("BallGroup")
        scene.collection.children.link(group)
        for c in list(ball.users_collection):
            c.objects.unlink(ball)
        group.objects.link(ball)
        second.layer_collection.children["BallGroup"].exclude = True
        self.assertEqual(bpy.context.view_layer.name, first.name, "the context's layer is the other one")
        with tempfile.TemporaryDirectory() as tmp:
            made = {}
            for layer in (first, second):
                out = os.path.join(tmp, layer.name)
                logged = []
                result = pipeline.run(scene, "taa-improved", [1], out, threads=1, view_layer=layer, log=logged.append)
                # The other layer renders in Blender's own render too: its absence is said, the layer recorded.
                other = second if layer is first else first
                self.assertIn("note: only the view layer '%s' is rendered and filtered, not '%s'"
                              % (layer.name, other.name), "\n".join(logged))
                self.assertEqual(result["view_layer"], layer.name)
                with open(os.path.join(out, "input", "frame_0001.json")) as fh:
                    objects = sorted(o["name"] for o in json.load(fh)["objects"].values())
                self.assertEqual("Ball" in objects, layer is first, objects)
                made[layer.name] = colour(os.path.join(out, "input", "frame_0001.exr"))
            self.assertTrue(made[first.name] != made[second.name], "the Ball is not in the second layer's render")
        self.assertEqual([layer.use for layer in scene.view_layers], [True, True], "the layers' use is put back")
        # No layer given: the context's if it renders, else the first that does (planned and rendered alike).
        self.assertEqual(render.default_view_layer(scene).name, first.name)
        first.use = False
        self.assertEqual(render.default_view_layer(scene).name, second.name)
        self.assertEqual(render.default_view_layer(scene, first).name, first.name, "a layer given is kept")
        first.use = True

    def test_an_object_hidden_from_render_is_neither_visible_nor_moving(self):
        """An object hidden from render (its camera icon) does not reach the render: the scene's facts list
        it neither as visible nor as moving, and taa's plan renders no motion for it (ghosting with its
        moving sphere hidden: only the still wall is left)."""
        scene = harness.build_scene("ghosting")
        the_plan, facts = pipeline.scene_plan(scene, "taa", [1, 2, 3])
        self.assertEqual((facts.visible_objects, facts.moving_objects), (["Wall", "Sphere"], ["Sphere"]))
        self.assertIn("motion", the_plan.passes)
        bpy.data.objects["Sphere"].hide_render = True
        the_plan, facts = pipeline.scene_plan(scene, "taa", [1, 2, 3])
        self.assertEqual(facts.visible_objects, ["Wall"])
        self.assertEqual(facts.moving_objects, [])
        self.assertNotIn("motion", the_plan.passes)


if __name__ == "__main__":
    harness.run(ViewLayerTest)
