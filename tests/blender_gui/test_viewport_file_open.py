# SPDX-License-Identifier: GPL-2.0-or-later
# xvfb-screen: 640x400x24
"""The viewport preview across File > Open: it ends with the file it filtered. Its draw and scene
handlers go, the one-sample settings it forced go back into that file's scene, and the opened file,
whose scene has the same name, keeps its own settings, also after the preview is switched on and off
there; with Load UI off the toggle goes off too. A file saved while the preview is on holds the
user's settings, not the forced ones. (It used to keep drawing with the toggle shown off, and wrote the
first file's settings into the second.) A file written without the save handlers while the preview was
on (an auto save, the last session's quit.blend) opens with the user's settings too."""

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


class PreviewAcrossFileOpen(unittest.TestCase):
    def test_open_ends_the_preview_and_keeps_each_files_settings(self):
        crisp.register()
        self.addCleanup(crisp.unregister)
        tmp = tempfile.TemporaryDirectory()
        self.addCleanup(tmp.cleanup)
        other = os.path.join(tmp.name, "other.blend")
        scene = bpy.context.scene
        scene.eevee.taa_samples, scene.display.viewport_aa = 16, "8"
        bpy.ops.wm.save_as_mainfile(filepath=other, copy=True)  # another file, its scene also "Scene"
        scene.eevee.taa_samples, scene.display.viewport_aa = 32, "FXAA"
        settings = bpy.context.window_manager.crisp_viewport
        settings.enabled = True
        self.assertTrue(viewport.is_active())
        self.assertEqual((scene.eevee.taa_samples, scene.display.viewport_aa), (1, "OFF"))  # forced while on

        # Saved while on: the file holds the user's settings, and the preview goes on forcing one sample.
        saved = os.path.join(tmp.name, "saved.blend")
        bpy.ops.wm.save_as_mainfile(filepath=saved, copy=True)
        self.assertEqual((scene.eevee.taa_samples, scene.display.viewport_aa), (1, "OFF"))
        self.assertTrue(viewport.is_active())

        bpy.ops.wm.open_mainfile(filepath=saved, load_ui=False)  # keeps this window manager
        self.assertFalse(viewport.is_active())
        self.assertFalse(bpy.context.window_manager.crisp_viewport.enabled, "toggle on, nothing filtering")
        self.assertEqual((bpy.context.scene.eevee.taa_samples, bpy.context.scene.display.viewport_aa), (32, "FXAA"))
        bpy.context.window_manager.crisp_viewport.enabled = True

        bpy.ops.wm.open_mainfile(filepath=other)
        self.assertFalse(viewport.is_active(), "the preview still draws after File > Open")
        self.assertNotIn(viewport._on_scene_change, bpy.app.handlers.depsgraph_update_post)
        self.assertFalse(bpy.context.window_manager.crisp_viewport.enabled)
        opened = bpy.context.scene
        self.assertEqual((opened.eevee.taa_samples, opened.display.viewport_aa), (16, "8"))
        settings = bpy.context.window_manager.crisp_viewport
        settings.enabled = True
        settings.enabled = False
        self.assertEqual((opened.eevee.taa_samples, opened.display.viewport_aa), (16, "8"))

    def test_a_file_written_without_the_save_handlers_opens_with_the_users_settings(self):
        crisp.register()
        self.addCleanup(crisp.unregister)
        tmp = tempfile.TemporaryDirectory()
        self.addCleanup(tmp.cleanup)
        scene = bpy.context.scene
        scene.eevee.taa_samples, scene.display.viewport_aa = 24, "16"
        settings = bpy.context.window_manager.crisp_viewport
        settings.enabled = True
        self.assertEqual((scene.eevee.taa_samples, scene.display.viewport_aa), (1, "OFF"))
        # As an auto save writes the file: no save_pre, so the forced values and their record go in.
        autosaved = os.path.join(tmp.name, "autosave.blend")
        bpy.data.libraries.write(autosaved, {scene})
        bpy.ops.wm.open_mainfile(filepath=autosaved, load_ui=False)
        opened = bpy.data.scenes[0]
        self.assertEqual((opened.eevee.taa_samples, opened.display.viewport_aa), (24, "16"))
        self.assertNotIn(viewport.FORCED_KEY, opened)


if __name__ == "__main__":
    gui_harness.run(PreviewAcrossFileOpen, delay=0.5)
