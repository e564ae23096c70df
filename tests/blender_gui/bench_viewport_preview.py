# SPDX-License-Identifier: GPL-2.0-or-later
"""Time per redraw of the 3D view with the Crisp preview off and on (each method), for the note of issue 7.
Not a test (not in the CTest glob). Run in Blender with a window whose size sets the view's:

  xvfb-run -a -s "-screen 0 1280x720x24" blender --factory-startup --python tests/blender_gui/bench_viewport_preview.py

The view is maximised without panels (so it is the whole window: 1280x720 with the command above) and shows
the still_life test scene in solid shading through its camera, like test_viewport_preview.py. Each redraw
is one wm.redraw_timer DRAW_WIN_SWAP (draws the window and swaps buffers, which on llvmpipe waits for the
rendering), timed alone with time.perf_counter; printed: the median of REDRAWS after WARMUP redraws, and
the preview's own CPU time per redraw (viewport.last_draw_ms, the GPU may still be working after it)."""

import os
import statistics
import sys
import time
import traceback

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import bpy  # noqa: E402

import test_viewport_preview as tvp  # noqa: E402  (helpers; also switches the splash screen off)
from crisp import viewport  # noqa: E402

WARMUP = 2
REDRAWS = int(os.environ.get("CRISP_BENCH_REDRAWS", "7"))


def timed_redraws():
    for _ in range(WARMUP):
        tvp.redraw(1)
    wall, cpu = [], []
    for _ in range(REDRAWS):
        t0 = time.perf_counter()
        tvp.redraw(1)
        wall.append(1000.0 * (time.perf_counter() - t0))
        cpu.append(viewport.last_draw_ms())
    return statistics.median(wall), statistics.median(cpu), min(wall), max(wall)


def bench():
    code = 1
    try:
        import crisp
        os.environ.setdefault("CRISP_LIBRARY", tvp.gui_harness.LIBRARY)
        crisp.register()
        bpy.context.preferences.system.viewport_aa = "OFF"
        tvp.harness.build_scene("still_life")
        area, region = tvp.view3d()
        space = area.spaces.active
        space.shading.type = "SOLID"
        tvp.look_through_camera(space, bpy.context.scene.camera)
        settings = bpy.context.window_manager.crisp_viewport
        print("view %dx%d, %d redraws per case (median, min-max); load average %s"
              % (region.width, region.height, REDRAWS, os.getloadavg()))
        settings.enabled = False
        wall, _, lo, hi = timed_redraws()
        print("bench off     %7.1f ms per redraw (%.0f-%.0f)" % (wall, lo, hi))
        for method in ("fxaa", "repair", "taa"):
            settings.method = method
            settings.enabled = True
            wall, cpu, lo, hi = timed_redraws()
            settings.enabled = False
            print("bench %-7s %7.1f ms per redraw (%.0f-%.0f), preview CPU %.1f ms%s"
                  % (method, wall, lo, hi, cpu, " " + settings.status if settings.status else ""))
        print("load average after %s" % (os.getloadavg(),))
        code = 0
    except Exception:
        traceback.print_exc()
    sys.stdout.flush()
    os._exit(code)


def start():
    tvp.maximise_view()
    bpy.app.timers.register(bench, first_interval=0.5)


if __name__ == "__main__":
    bpy.app.timers.register(start, first_interval=0.5)
