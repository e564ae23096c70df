# SPDX-License-Identifier: GPL-2.0-or-later
# xvfb-screen: 640x400x24
"""The viewport preview in a split layout: two 3D views of the still_life scene, each looking from
another distance, drawn in turn as Blender redraws the window. With taa each view must keep a history
of its own and accumulate its redraws; one history shared by both restarted at every draw (each view's
draw saw the other's view matrix), so the preview never accumulated and asked for redraws forever."""

import os
import sys
import unittest

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import gui_harness  # noqa: E402

import bpy  # noqa: E402

import harness  # noqa: E402  (tests/blender: build_scene)
import crisp  # noqa: E402
from crisp import viewport  # noqa: E402

REDRAWS = 8

bpy.context.preferences.view.show_splash = False


def views():
    return [a for a in bpy.context.window.screen.areas if a.type == "VIEW_3D"]


def redraw():
    area = views()[0]
    region = next(r for r in area.regions if r.type == "WINDOW")
    with bpy.context.temp_override(window=bpy.context.window, area=area, region=region):
        bpy.ops.wm.redraw_timer(type="DRAW_WIN_SWAP", iterations=1)


def split_view():
    """The scene and the split layout, from a timer before the tests start: a new area gets its size
    when the window manager next handles the screen."""
    harness.build_scene("still_life")
    with bpy.context.temp_override(window=bpy.context.window, area=views()[0]):
        bpy.ops.screen.area_split(direction="VERTICAL", factor=0.5)


class TwoViews(unittest.TestCase):
    def test_each_view_accumulates_its_own_history(self):
        os.environ.setdefault("CRISP_LIBRARY", gui_harness.LIBRARY)
        crisp.register()
        settings = bpy.context.window_manager.crisp_viewport
        try:
            self.assertEqual([a.width > 100 for a in views()], [True, True], "two 3D views side by side")
            views()[1].spaces.active.region_3d.view_distance *= 1.5
            draws = []  # (region, frames in its history after the draw)
            original = viewport._filter_view

            def logged(context, region, *args):
                out = original(context, region, *args)
                draws.append((region.as_pointer(), out[1].frames))
                return out

            viewport._filter_view = logged
            settings.method = "taa"
            settings.enabled = True
            self.assertTrue(viewport.is_active(), settings.status)
            for _ in range(REDRAWS):
                for area in views():
                    area.tag_redraw()
                redraw()
            viewport._filter_view = original
            regions = sorted({r for r, _ in draws})
            self.assertEqual(len(regions), 2, "both views drew the preview")
            for r in regions:
                frames = [n for region, n in draws if region == r]
                self.assertGreaterEqual(len(frames), REDRAWS // 2, frames)
                self.assertEqual(frames, list(range(1, len(frames) + 1)), "no restart: %s" % frames)
            self.assertGreaterEqual(viewport.accumulated_frames(), REDRAWS // 2)
        finally:
            settings.enabled = False
            crisp.unregister()


if __name__ == "__main__":
    bpy.app.timers.register(split_view, first_interval=0.2)
    gui_harness.run(TwoViews, delay=1.0, ready=lambda: len(views()) == 2 and all(a.width > 100 for a in views()))
