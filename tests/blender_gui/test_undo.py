# SPDX-License-Identifier: GPL-2.0-or-later
# xvfb-screen: 640x400x24
"""Undo and the add-on, as an artist meets them (found by a user test):
* Crisp's render is an undo step of its own: Ctrl-Z takes back what it set (the Output folder, the plan
  text), not the artist's edit before it (it used to take back both, and redo brought back neither).
* The viewport preview forces one sample while it is on; an undo to a step taken while it was on,
  after it went off, used to leave the scene at one sample with viewport anti-aliasing off. An undo
  to a step before it went on, while it is on, must not leave the user's settings in place either.
* Disabling and enabling the add-on again leaves the preview toggle off, not on with nothing drawing.
* A window switched to another scene while the preview is on: the preview forced only the first scene,
  so it filtered the other's fully sampled view, and the first kept one sample until the preview went
  off."""

import os
import sys
import tempfile
import unittest

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import gui_harness  # noqa: E402

import bpy  # noqa: E402

import crisp  # noqa: E402
from crisp import viewport  # noqa: E402

bpy.context.preferences.view.show_splash = False
# The render case needs the library of CRISP_BUILD_DIR, which need not be the checkout's build/ that the
# add-on finds by itself (as the other GUI tests give it).
os.environ.setdefault("CRISP_LIBRARY", gui_harness.LIBRARY)
USER = (16, "FXAA")  # the artist's viewport samples and anti-aliasing


def samples(scene=None):
    scene = scene or bpy.context.scene
    return scene.eevee.taa_samples, scene.display.viewport_aa


class UndoWithCrisp(unittest.TestCase):
    def setUp(self):
        crisp.register()
        self.addCleanup(lambda: crisp.unregister() if hasattr(bpy.types.Scene, "crisp") else None)
        scene = bpy.context.scene
        scene.eevee.taa_samples, scene.display.viewport_aa = USER
        bpy.ops.ed.undo_push(message="start")

    def test_render_is_its_own_undo_step(self):
        tmp = tempfile.TemporaryDirectory()
        self.addCleanup(tmp.cleanup)
        bpy.ops.wm.save_as_mainfile(filepath=os.path.join(tmp.name, "shot.blend"))
        scene = bpy.context.scene
        scene.render.resolution_x, scene.render.resolution_y = 32, 18
        scene.frame_start = scene.frame_end = 1
        scene.crisp.method = "fxaa"
        scene.crisp.load_result = False
        # An AOV, which the render removes for its renders with Blender's operator (no undo step of its own).
        bpy.context.view_layer.aovs.add().name = "mask"
        bpy.ops.ed.undo_push(message="settings")
        cube = bpy.data.objects["Cube"]
        cube.location.x += 0.5
        bpy.ops.ed.undo_push(message="move the cube")
        # As a click on the panel's button: undo=True asks for the step an operator with the UNDO option
        # pushes (Blender pushes none for an operator without it).
        self.assertEqual(bpy.ops.crisp.render("EXEC_DEFAULT", True), {"FINISHED"})
        self.assertTrue(bpy.context.scene.crisp.output_dir)
        self.assertTrue(os.path.isfile(os.path.join(tmp.name, "crisp", "Scene", "filtered", "frame_0001.exr")))
        self.assertEqual([a.name for a in bpy.context.view_layer.aovs], ["mask"])
        bpy.ops.ed.undo()
        self.assertEqual(bpy.context.scene.crisp.output_dir, "", "the render's own change is undone")
        self.assertAlmostEqual(bpy.data.objects["Cube"].location.x, 0.5, places=6, msg="the artist's edit stays")
        self.assertEqual([a.name for a in bpy.context.view_layer.aovs], ["mask"])
        bpy.ops.ed.redo()
        self.assertTrue(bpy.context.scene.crisp.output_dir, "and redone")
        self.assertEqual([a.name for a in bpy.context.view_layer.aovs], ["mask"])

    def test_undo_keeps_the_settings_the_preview_is_not_showing(self):
        settings = bpy.context.window_manager.crisp_viewport
        settings.method = "fxaa"
        settings.enabled = True
        self.assertTrue(viewport.is_active())
        self.assertEqual(samples(), (1, "OFF"))
        bpy.data.objects["Cube"].location.z += 0.3
        bpy.ops.ed.undo_push(message="move while the preview is on")
        bpy.data.objects["Cube"].location.z += 0.3
        bpy.ops.ed.undo_push(message="move again")
        bpy.ops.ed.undo()  # to a step taken while on, while on: still forced
        self.assertEqual(samples(), (1, "OFF"))
        bpy.ops.ed.undo()
        bpy.ops.ed.undo()  # to the step before the preview went on, while it is on: forced again
        self.assertEqual(samples(), (1, "OFF"))
        bpy.ops.ed.redo()
        settings = bpy.context.window_manager.crisp_viewport
        settings.enabled = False
        self.assertEqual(samples(), USER)
        bpy.ops.ed.redo()  # to a step taken while it was on, now off: the artist's settings
        self.assertEqual(samples(), USER)
        bpy.ops.ed.undo()
        self.assertEqual(samples(), USER)

    def test_one_sample_chosen_after_the_preview_went_off_survives_undo(self):
        """The user's values the preview put back are only for steps taken while it was on: a later
        choice of one sample (or no viewport anti-aliasing) is the artist's, and an undo keeps it. (The
        values put back were once applied after every later undo and redo.)"""
        settings = bpy.context.window_manager.crisp_viewport
        settings.method = "fxaa"
        settings.enabled = True
        bpy.data.objects["Cube"].location.z += 0.3
        bpy.ops.ed.undo_push(message="move while the preview is on")
        settings.enabled = False
        self.assertEqual(samples(), USER)
        scene = bpy.context.scene
        scene.eevee.taa_samples, scene.display.viewport_aa = 1, "OFF"
        bpy.ops.ed.undo_push(message="the artist's own choice")
        bpy.data.objects["Cube"].location.z += 0.3
        bpy.ops.ed.undo_push(message="move again")
        bpy.ops.ed.undo()
        self.assertEqual(samples(), (1, "OFF"), "the artist's choice after the preview went off")
        bpy.ops.ed.undo()
        bpy.ops.ed.undo()  # to the step taken while the preview was on: the artist's values then
        self.assertEqual(samples(), USER)
        bpy.ops.ed.redo()
        bpy.ops.ed.redo()
        self.assertEqual(samples(), (1, "OFF"))
        self.assertNotIn(viewport.FORCED_KEY, bpy.context.scene)

    def test_file_saved_while_the_preview_is_on_has_the_users_values(self):
        tmp = tempfile.TemporaryDirectory()
        self.addCleanup(tmp.cleanup)
        settings = bpy.context.window_manager.crisp_viewport
        settings.method = "fxaa"
        settings.enabled = True
        path = os.path.join(tmp.name, "on.blend")
        bpy.ops.wm.save_as_mainfile(filepath=path, copy=True)
        self.assertEqual(samples(), (1, "OFF"), "forced again after the save")
        bpy.data.objects["Cube"].location.z += 0.3
        bpy.ops.ed.undo_push(message="move after the save")
        bpy.ops.ed.undo()
        self.assertEqual(samples(), (1, "OFF"))
        settings.enabled = False
        self.assertEqual(samples(), USER)
        with bpy.data.libraries.load(path, link=True) as (_src, dst):
            dst.scenes = ["Scene"]
        saved = dst.scenes[0]
        self.addCleanup(bpy.data.libraries.remove, saved.library)
        self.assertEqual(samples(saved), USER)
        self.assertNotIn(viewport.FORCED_KEY, saved, "the file holds no trace of the preview")

    def test_failed_draws_leave_no_timer_after_unregister(self):
        """Each view's failed draw (two 3D views, or the same one drawn again before the timers run)
        queued a switch-off; unregister removed only the last, and the others ran without the add-on."""
        settings = bpy.context.window_manager.crisp_viewport
        settings.method = "fxaa"
        settings.enabled = True
        queued = []
        real = viewport._draw_preview

        def failing(_context):
            raise RuntimeError("probe")
        viewport._draw_preview = failing
        self.addCleanup(setattr, viewport, "_draw_preview", real)
        for _ in range(2):
            viewport._draw()
            queued.append(viewport._State.pending_off)
        crisp.unregister()
        self.assertFalse([t for t in queued if bpy.app.timers.is_registered(t)], "a switch-off outlives the add-on")

    def test_the_preview_follows_the_window_to_another_scene(self):
        first = bpy.context.window.scene
        other = bpy.data.scenes.new("Other")
        self.addCleanup(bpy.data.scenes.remove, other)
        other.eevee.taa_samples, other.display.viewport_aa = 32, "8"
        settings = bpy.context.window_manager.crisp_viewport
        settings.method = "fxaa"
        settings.enabled = True
        self.addCleanup(lambda: setattr(bpy.context.window, "scene", first))
        self.assertEqual(samples(first), (1, "OFF"))
        bpy.context.window.scene = other
        area = next(a for a in bpy.context.screen.areas if a.type == "VIEW_3D")
        region = next(r for r in area.regions if r.type == "WINDOW")
        with bpy.context.temp_override(window=bpy.context.window, area=area, region=region):
            bpy.ops.wm.redraw_timer(type="DRAW_WIN_SWAP", iterations=2)
        self.assertEqual(viewport._State.rejected, None)
        self.assertEqual(samples(other), (1, "OFF"), "the scene the window shows now is drawn with one sample")
        self.assertEqual(samples(first), USER, "the scene no window shows has the artist's values back")
        self.assertIn(viewport.FORCED_KEY, other)
        self.assertNotIn(viewport.FORCED_KEY, first)
        bpy.context.window.scene = first
        with bpy.context.temp_override(window=bpy.context.window, area=area, region=region):
            bpy.ops.wm.redraw_timer(type="DRAW_WIN_SWAP", iterations=1)
        self.assertEqual((samples(first), samples(other)), ((1, "OFF"), (32, "8")))
        settings.enabled = False
        self.assertEqual((samples(first), samples(other)), (USER, (32, "8")))
        self.assertNotIn(viewport.FORCED_KEY, first)

    def test_add_on_enabled_again_starts_with_the_preview_off(self):
        settings = bpy.context.window_manager.crisp_viewport
        settings.method = "fxaa"
        settings.enabled = True
        self.assertTrue(viewport.is_active())
        crisp.unregister()
        self.assertEqual(samples(), USER)
        crisp.register()
        self.assertFalse(bpy.context.window_manager.crisp_viewport.enabled, "toggle on with nothing drawing")
        self.assertFalse(viewport.is_active())
        bpy.context.window_manager.crisp_viewport.enabled = True
        self.assertTrue(viewport.is_active())
        bpy.context.window_manager.crisp_viewport.enabled = False


if __name__ == "__main__":
    gui_harness.run(UndoWithCrisp, delay=0.5)
