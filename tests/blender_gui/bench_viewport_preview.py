# SPDX-License-Identifier: GPL-2.0-or-later
"""Time per redraw of the 3D view with the Crisp preview off and on (each method), for the note of issue 7.
Not a test (not in the CTest glob). Run in Blender with a window whose size sets the view's:

  xvfb-run -a -s "-screen 0 1280x720x24" blender --factory-startup --python tests/blender_gui/bench_viewport_preview.py

The view is maximised without panels (so it is the whole window: 1280x720 with the command above) and shows
the still_life test scene in solid shading through its camera, like test_viewport_preview.py. Each redraw
is one wm.redraw_timer DRAW_WIN_SWAP (draws the window and swaps buffers, which on llvmpipe waits for the
rendering), timed alone with time.perf_counter; printed: the median of REDRAWS after WARMUP redraws, and
the preview's own CPU time per redraw (viewport.last_draw_ms, the GPU may still be working after it).
Then the stages alone, from a draw handler of the same view, each ended by reading one pixel back (which
waits for the GPU): draw_view3d into an RGBA32F offscreen, the decode pass, and each filter's passes."""

import os
import statistics
import sys
import time
import traceback

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import bpy  # noqa: E402
import gpu  # noqa: E402

import test_viewport_preview as tvp  # noqa: E402  (helpers; also switches the splash screen off)
from crisp import gpu_filters, viewport  # noqa: E402

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


class Stages:
    resources = None
    times = []


def _wait(framebuffer):
    with framebuffer.bind():
        framebuffer.read_color(0, 0, 1, 1, 4, 0, "FLOAT")


def stage_handler():
    ctx = bpy.context
    region, rv3d = ctx.region, ctx.region_data
    w, h = region.width, region.height
    guard = gpu.types.GPUOffScreen(4, 4)  # restores the region's framebuffer, like the preview
    with guard.bind():
        if Stages.resources is None:
            Stages.resources = (gpu.types.GPUOffScreen(w, h, format="RGBA32F"), gpu_filters.Target(w, h),
                                {m: gpu_filters.GpuFilter(m) for m in ("fxaa", "repair", "taa")})
        offscreen, decoded, filters = Stages.resources
        t0 = time.perf_counter()
        offscreen.draw_view3d(ctx.scene, ctx.view_layer, ctx.space_data, region, rv3d.view_matrix,
                              rv3d.window_matrix, do_color_management=True)
        with offscreen.bind():
            gpu.state.active_framebuffer_get().read_color(0, 0, 1, 1, 4, 0, "FLOAT")
        t1 = time.perf_counter()
        gpu_filters.run_pass("decode", decoded, {"colorImage": offscreen.texture_color})
        _wait(decoded.framebuffer)
        row = [t1 - t0, time.perf_counter() - t1]
        for filt in filters.values():
            t = time.perf_counter()
            filt.run(decoded.texture, w, h)
            _wait(filt.output.framebuffer)
            row.append(time.perf_counter() - t)
        Stages.times.append(row)
    guard.free()


def stage_times():
    """With the scene at one sample, as the preview sets it (viewport.ONE_SAMPLE)."""
    scene = bpy.context.scene
    saved = [(group, name, getattr(getattr(scene, group), name)) for group, name, _ in viewport.ONE_SAMPLE]
    for group, name, value in viewport.ONE_SAMPLE:
        setattr(getattr(scene, group), name, value)
    handle = bpy.types.SpaceView3D.draw_handler_add(stage_handler, (), "WINDOW", "POST_PIXEL")
    try:
        tvp.redraw(WARMUP + REDRAWS)
    finally:
        bpy.types.SpaceView3D.draw_handler_remove(handle, "WINDOW")
        for group, name, value in saved:
            setattr(getattr(scene, group), name, value)
    rows = Stages.times[WARMUP:]
    for i, name in enumerate(("draw_view3d", "decode", "fxaa", "repair", "taa")):
        print("stage %-11s %7.1f ms (median)" % (name, 1000.0 * statistics.median(r[i] for r in rows)))


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
        stage_times()
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
