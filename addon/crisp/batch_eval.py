# SPDX-License-Identifier: GPL-2.0-or-later
"""Headless driver of the renders behind `crisp eval`, run inside Blender:

    blender -b [SCENE.blend] --factory-startup --python-exit-code 1 --python <repo>/addon/crisp/batch_eval.py -- \\
        -o RENDERDIR --methods none,fxaa,taa [--frames A-B] [--resolution WxH] [--scene-script NAME]
        [--reference-samples 64] [--curve 1,2,4,8] [--smaa-threshold 0.2] [--progress-fd N]
        [--filter-size-max METHOD=PX]... [--jitter DIST]
    blender -b SCENE.blend --factory-startup --python-exit-code 1 --python <repo>/addon/crisp/batch_eval.py -- \
        --read-panel [--jitter DIST] [--library PATH]

Renders (eval_renders.py has the layout): EEVEE's curve (each count in --curve, always including 1),
the 1-sample inputs of the methods whose plans need more than colour (jittered for temporal methods),
the reference, and Blender's compositor SMAA on the 1-sample frames; writes RENDERDIR/scene.json.
Frames already rendered (EXR present and timed) are skipped. The methods themselves run in the CLI,
not here. --filter-size-max (given by crisp eval, from the library's parameter tables): the largest Film >
Filter Size a method filters with (a temporal method takes the renders' as its filterSize); a scene
whose filter size is above it is refused before the first render, not after every render.

Progress: one line per render on file descriptor --progress-fd (default: stderr):
    `progress DONE TOTAL COST_DONE COST_TOTAL SECONDS_LEFT ITEM`
where COST counts EEVEE samples (an SMAA pass counts 1), so the time left follows the real cost.

--read-panel (crisp eval's first step, before anything is rendered): reads the opened .blend's Crisp
panel as crisp render does (batch.py panel_settings: the method and the jitter when the file set them,
the panel's changed parameters of that method), has the library check the panel's values
(batch.py check_panel_params) and prints one line `crisp-panel: {JSON}` with them (method, params,
jitter, from_panel, file, and line: what came from the panel, said as crisp eval says it), then exits.
crisp eval measures the panel's method and parameters as a row of their own and renders with its jitter
unless --jitter is given (given here too, so the line leaves the panel's out). --library: libcrisp.so
(the panel's parameters are the library's).

Exit codes: 0 done; 2 bad input; 4 render failed (as batch.py); 3 library missing or failing and 5 a
panel value the library refuses (--read-panel, as batch.py).
"""

import json

import argparse
import os
import sys
import time

ADDON_DIR = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
if ADDON_DIR not in sys.path:
    sys.path.insert(0, ADDON_DIR)


def _argv():
    return sys.argv[sys.argv.index("--") + 1:] if "--" in sys.argv else []


def make_parser():
    p = argparse.ArgumentParser(prog="batch_eval.py", description="Crisp eval renders (inside Blender)")
    p.add_argument("-o", "--output", default="")  # required but with --read-panel
    p.add_argument("--methods", default="none")
    p.add_argument("--frames", default="")
    p.add_argument("--warmup", type=int, default=0)  # crisp eval --warmup: checked here against the range
    p.add_argument("--resolution", default="")
    p.add_argument("--scene-script", default="")
    p.add_argument("--scene-name", default="")  # crisp eval --scene-name (batch.named_scene)
    p.add_argument("--reference-samples", type=int, default=64)
    p.add_argument("--curve", default="1,2,4,8,16")
    p.add_argument("--smaa-threshold", type=float, default=None)
    p.add_argument("--jitter", default=None)  # None: not given (batch.DEFAULT_JITTER; --read-panel: the panel's)
    p.add_argument("--read-panel", action="store_true")
    p.add_argument("--library", default="")
    p.add_argument("--progress-fd", type=int, default=-1)
    p.add_argument("--filter-size-max", action="append", default=[], metavar="METHOD=PX")
    return p


def parse_filter_size_limits(items):
    """--filter-size-max METHOD=PX items -> [(METHOD, PX)], in the order given."""
    limits = []
    for item in items:
        method, _, px = item.rpartition("=")
        try:
            limits.append((method, float(px)))
        except ValueError:
            raise ValueError("bad --filter-size-max '%s' (expected METHOD=PX)" % item)
        if not method:
            raise ValueError("bad --filter-size-max '%s' (expected METHOD=PX)" % item)
    return limits


def filter_size_problem(size, limits):
    """Why the methods of limits cannot filter frames rendered with Film > Filter Size `size` px, or None."""
    over = [(m, px) for m, px in limits if size > px]
    if not over:
        return None
    largest = min(px for _, px in over)
    names = ", ".join(m for m, _ in over)
    return ("the scene's Film > Filter Size %g px is above %g px, the largest %s filter%s with (a temporal method "
            "takes the renders' Filter Size as its filterSize): lower it, give --methods '%s:filterSize=...' to "
            "filter with another, or set CRISP_EVAL_FILTER_SIZE to render with another"
            % (size, largest, names, "s" if len(over) == 1 else "", over[0][0]))


def parse_curve(text):
    try:
        counts = sorted({int(v) for v in text.split(",") if v.strip()} | {1})
    except ValueError:
        raise ValueError("bad --curve '%s' (expected sample counts like 1,2,4,8)" % text)
    if counts[0] < 1:
        raise ValueError("--curve sample counts must be >= 1, got '%s'" % text)
    return counts


def read_panel(jitter, scene_name=""):
    """--read-panel: the opened .blend's Crisp panel, checked, as one line `crisp-panel: {JSON}`."""
    from crisp import batch, native
    scene = batch.named_scene(scene_name)
    try:
        method, jitter, params, from_panel = batch.panel_settings(scene, None, jitter, {})
        batch.check_panel_params(method, params, from_panel, {}, way_out="run crisp eval with --no-panel")
    except batch.PanelError as e:
        batch.fail(e.exit, str(e))
    except native.CrispError as e:
        batch.fail(3, str(e))
    record = {"file": batch.panel_source(), "method": method, "params": params, "jitter": jitter,
              "from_panel": from_panel,
              # eval renders every temporal method's inputs with the panel's jitter, whichever method it names
              "line": batch.panel_line(method, jitter, from_panel, command="eval", jitters=True)}
    print("crisp-panel: " + json.dumps(record), flush=True)


def stop_line(stop, done, total):
    """What crisp eval says of a run a signal stopped (the progress pipe's `stop` line): which signal, and
    how far it came; the renders it made are kept (eval_renders: whole files only), and the same command
    resumes from them."""
    stopped = "stopped by Ctrl-C (SIGINT)" if isinstance(stop, KeyboardInterrupt) else str(stop)  # batch.Stopped's
    if done == 0:  # (also in the warm-up render, which is not kept)
        return "%s before its first render" % stopped
    return ("%s after the render it was on: %d of %d renders are done, and the same command goes on from them"
            % (stopped, done, total))


def main(argv):
    from crisp import batch, render

    fail = batch.fail
    parser = make_parser()
    parser.error = lambda msg: fail(2, msg)
    args = parser.parse_args(argv)
    if args.library:
        os.environ["CRISP_LIBRARY"] = os.path.abspath(args.library)
    if args.jitter is not None and args.jitter not in render.JITTER_DISTRIBUTIONS:
        fail(2, "unknown --jitter '%s' (known: %s)" % (args.jitter, ", ".join(render.JITTER_DISTRIBUTIONS)))
    if args.read_panel:
        return read_panel(args.jitter, args.scene_name)
    if not args.output:
        fail(2, "-o RENDERDIR is required")
    args.jitter = args.jitter or batch.DEFAULT_JITTER
    progress = os.fdopen(args.progress_fd, "w", buffering=1) if args.progress_fd >= 0 else sys.stderr
    try:
        curve = parse_curve(args.curve)
        filter_size_limits = parse_filter_size_limits(args.filter_size_max)
    except ValueError as e:
        fail(2, str(e))
    if args.reference_samples < 1:
        fail(2, "--reference-samples must be >= 1")
    methods = [m for m in args.methods.split(",") if m]
    # Ctrl-C, SIGTERM (crisp eval passes on its own), SIGHUP: the run ends after the render it is on
    # (each is written whole, through a temporary name) and crisp eval says how far it came.
    count = {"total": 0, "done": lambda: 0}
    try:
        should_cancel = batch.stop_on_signals()
        render_all(args, progress, curve, filter_size_limits, methods, count, should_cancel)
    except (KeyboardInterrupt, batch.Stopped) as e:
        try:
            done = count["done"]()
        except OSError:  # (the folder gone, a full disk): said without the count
            done = 0
        line = stop_line(e, done, count["total"])
        try:
            progress.write("stop %s\n" % line)
            progress.flush()
        except OSError:  # crisp is gone (killed outright): the log still says it
            pass
        fail(4, line)


def render_all(args, progress, curve, filter_size_limits, methods, count, should_cancel):
    """The renders of main's arguments into args.output; count: {"total": renders, "done": () -> how many
    of them are made, as their folders' times.json record them}."""
    import runpy
    import bpy
    from crisp import batch, eval_renders, pipeline, render

    fail = batch.fail
    # What the opened .blend reads besides itself (its libraries, images and other files; batch.scene_key):
    # crisp eval checks the .blend and a scene script before Blender starts (eval_settings.json), these
    # only Blender can list. Taken before anything changes the scene.
    files_key = None if args.scene_script else batch.scene_key(None)
    if args.scene_script:
        path = batch.scene_script_path(args.scene_script)
        sys.path.insert(0, os.path.dirname(path))
        runpy.run_path(path, run_name="__main__")
    scene = batch.named_scene(args.scene_name)
    said = batch.active_scene_line(scene, args.scene_name)
    if said:  # Blender's output goes to the log: crisp eval shows a "say" line of the progress pipe
        progress.write("say %s\n" % said)
        progress.flush()
    # An experiment knob (issue 5): EEVEE's pixel filter (render.filter_size, px) for every render of
    # the run. The 1-sample frames do not depend on it (their one sample sits on the pixel centre);
    # the reference and the curve do: EEVEE spreads its samples over +-filter_size px with
    # Blackman-Harris weights, while rsaa resamples towards the colour covered by the pixel's own
    # square. CRISP_EVAL_FILTER_SIZE=0.5 gives a reference close to that target.
    filter_size = os.environ.get("CRISP_EVAL_FILTER_SIZE", "")
    if filter_size:
        try:
            scene.render.filter_size = float(filter_size)
        except ValueError:
            fail(2, "bad CRISP_EVAL_FILTER_SIZE '%s' (pixels, e.g. 0.5)" % filter_size)
    if args.resolution:
        try:
            pipeline.apply_resolution(scene, args.resolution)
        except pipeline.InputError as e:
            fail(2, str(e))
    try:
        out = pipeline.output_argument(args.output)  # crisp eval resolves // itself; a direct run as well
        render.check_blender_version()
        frames = list(pipeline.parse_frames(args.frames, scene))
        if args.warmup >= len(frames):  # before anything is rendered (the scene's own range, without --frames)
            raise pipeline.InputError("--warmup %d leaves none of the %d frames (%d-%d) to measure"
                                      % (args.warmup, len(frames), frames[0], frames[-1]))
        problem = render.camera_problem(scene, frames) or filter_size_problem(scene.render.filter_size,
                                                                              filter_size_limits)
        if problem:
            raise pipeline.InputError(problem)
        pipeline.check_output_dir(out)
        # A resumed run reuses the renders it finds: those of a scene whose linked library or texture was
        # edited since would be measured as this one's. (Records of earlier builds hold no key: taken as now.)
        record = eval_renders.read_json(os.path.join(out, "scene.json"), {})
        there = record.get("scene_files") if isinstance(record, dict) else None
        if files_key and there and there != files_key:
            raise pipeline.InputError(
                "'%s' holds renders made when the scene's linked libraries, images or other files were "
                "others (scene_files %s there, %s here); use another -o folder or delete it"
                % (os.path.dirname(os.path.normpath(out)), there, files_key))
        # crisp eval's settings key holds the file, not which of its scenes: the scene the renders are of
        # is the record's, however it was chosen (--scene-name, or the file's active scene).
        there = record.get("scene") if isinstance(record, dict) else None
        if there and there != scene.name and eval_renders.holds_renders(out):
            raise pipeline.InputError(
                "'%s' holds renders of the scene '%s', not of '%s' (%s); give --scene-name '%s' to measure that "
                "one, use another -o folder or delete it"
                % (os.path.dirname(os.path.normpath(out)), there, scene.name,
                   "--scene-name" if args.scene_name else "the file's active scene", there))
        plans, sets, unknown, facts = eval_renders.group_plans(scene, methods, frames)
        pipeline.check_camera_shifts(scene, list(plans))
    except pipeline.InputError as e:
        fail(2, str(e))
    except render.RenderError as e:
        fail(2, str(e))

    compositor = eval_renders.SmaaCompositor(
        args.smaa_threshold if args.smaa_threshold is not None else eval_renders.SMAA_THRESHOLD)
    w, h = render.render_size(scene)
    info = {
        "blender_version": bpy.app.version_string, "scene": scene.name, "resolution": [w, h],
        "scene_label": (os.path.splitext(os.path.basename(args.scene_script))[0] if args.scene_script
                        else os.path.splitext(os.path.basename(bpy.data.filepath))[0] or scene.name),
        "frames": [frames[0], frames[-1]], "engine": render.eevee_engine(scene),
        "curve": curve, "reference_samples": args.reference_samples, "jitter_distribution": args.jitter,
        "filter_size": scene.render.filter_size,
        "facts": {"camera_moves": facts.camera_moves, "moving_objects": facts.moving_objects,
                  "deforming_objects": facts.deforming_objects, "visible_objects": facts.visible_objects,
                  "camera_cuts": facts.camera_cuts},
        # With what the plan asks of each filter (pipeline.with_plan_params), which eval.cpp sets where the
        # row's own settings do not: the rows measure what the add-on runs.
        "plans": {m: dict(p.to_json(), params=pipeline.with_plan_params(m, None, p) or {}) for m, p in plans.items()},
        "inputs": {m: eval_renders.input_set(plans.get(m)) for m in methods},
        "sets": {name: p.to_json() for name, p in sets.items()},
        "unplanned_methods": unknown, "smaa": compositor.settings(), "scene_files": files_key,
    }
    eval_renders.write_json(os.path.join(out, "scene.json"), info)

    # The work list, in the order a user wants results: cheap inputs first, the reference last but one
    # so an interrupted run has something to show, and SMAA (needs eevee_1) at the end.
    jobs = [("eevee_%d" % s, s) for s in curve]
    jobs += [(name, 1) for name in sets]
    jobs += [("reference_%d" % args.reference_samples, args.reference_samples), ("blender-smaa", 1)]
    cost_total = sum(c for _, c in jobs) * len(frames)
    state = {"done": 0, "cost": 0, "rendered_cost": 0, "rendered_s": 0.0}
    total = count["total"] = len(jobs) * len(frames)

    def renders_missing():
        """How many of the renders are still to make, as their sets' times.json say (makes no folder)."""
        return sum(len(eval_renders.TimeBook(os.path.join(out, n)).missing(frames))
                   if os.path.isdir(os.path.join(out, n)) else len(frames) for n, _ in jobs)
    count["done"] = lambda: total - renders_missing()
    t_start = time.perf_counter()
    t_last = [t_start]

    def step(name, frame, cost, skipped=False):
        now = time.perf_counter()
        state["done"] += 1
        state["cost"] += cost
        if not skipped:
            state["rendered_cost"] += cost
            state["rendered_s"] += now - t_last[0]
        t_last[0] = now
        rate = state["rendered_s"] / state["rendered_cost"] if state["rendered_cost"] else 0.0
        left = rate * (cost_total - state["cost"])
        progress.write("progress %d %d %d %d %.1f %s frame %d%s\n" % (
            state["done"], total, state["cost"], cost_total, left, name, frame, " (done before)" if skipped else ""))
        progress.flush()
        should_cancel()  # a stop Blender's own Python swallowed (a scene's frame change handler)

    try:
        if renders_missing():
            eval_renders.warm_up(scene, os.path.join(out, "warmup"))
        for name, the_plan in sets.items():  # each pass configuration's first render costs more still
            if eval_renders.input_frames_to_render(scene, the_plan, frames, os.path.join(out, name), args.jitter):
                eval_renders.warm_up(scene, os.path.join(out, "warmup", name), the_plan, args.jitter)
        t_last[0] = time.perf_counter()
        # Frame by frame across the curve and the input sets, so that load from other processes on a
        # shared machine spreads over every sample count instead of skewing one of them.
        for f in frames:
            for s in curve:
                eval_renders.render_curve_set(scene, [f], os.path.join(out, "eevee_%d" % s), s, step)
            for name, the_plan in sets.items():
                eval_renders.render_input_set(scene, the_plan, [f], os.path.join(out, name), args.jitter, step)
        eval_renders.render_curve_set(scene, frames, os.path.join(out, "reference_%d" % args.reference_samples),
                                      args.reference_samples, step)
        eval_renders.render_smaa_set(frames, os.path.join(out, "eevee_1"), os.path.join(out, "blender-smaa"),
                                     compositor, step)
    except render.RenderError as e:
        fail(4, str(e))
    print("crisp: eval renders done: %s (%.1f s)" % (out, time.perf_counter() - t_start), flush=True)


if __name__ == "__main__":
    main(_argv())
