# SPDX-License-Identifier: GPL-2.0-or-later
"""One Crisp run on a scene, shared by batch.py and the operators: check inputs, plan the passes,
render the 1-sample frames, filter them through the library, optionally render references, and write
OUTDIR/run.json. Layout:

    OUTDIR/input/frame_NNNN.exr (+ .json sidecar, + _subK.exr for RSAA)
    OUTDIR/filtered/frame_NNNN.exr (+ .png)
    OUTDIR/reference/frame_NNNN.exr          (when reference_samples > 0)
    OUTDIR/run.json                          (run_AAAA-BBBB.json for a chunk of a shot)

run.json is rewritten as each frame is made; its "status" says how the run ended: "complete",
"cancelled at frame N" or "cancelled at reference frame N" (should_cancel, a caller's stop),
"failed: <why>" (also "failed: KeyboardInterrupt", Ctrl-C, and "failed: stopped by SIGTERM", batch.py's
stop signals), "running" (also a run that was killed),
or "planned" (plan_only).

A farm chunk (issue 8, docs/farm.md) writes frames A..B of a shot and first renders and filters the
`preroll` frames before A (never before the shot's first frame) to warm the temporal history. Those
pre-roll inputs go to a private temporary folder that is deleted afterwards (an input already in
OUTDIR/input/ is read from there instead of rendered again), so input/ and filtered/ hold exactly the
frames some chunk owns and two chunks never write the same file. The pass plan of a chunk is made
over the whole shot so every chunk renders the same passes. With `resume`, a run starts at the
chunk's first frame with a missing output and takes its pre-roll before that frame (a method without
history makes only the frames that need it).
"""

import itertools
import json
import os
import shutil
import tempfile
import time

import bpy

from . import compositor
from . import native
from . import plan as plan_mod
from . import render


class InputError(RuntimeError):
    """Bad input from the user (scene, frames, method, output folder): nothing was rendered."""


def parse_frames(text, scene=None):
    """'A-B', 'A' or '' (the scene's range) -> range. Empty ranges are an InputError."""
    if not text:
        if scene is None:
            raise InputError("no frame range given")
        a, b = scene.frame_start, scene.frame_end
    else:
        try:
            dash = text.find("-", 1)  # a leading '-' is a sign; the CLI splits the same way (frame_range.h)
            a = int(text if dash < 0 else text[:dash])
            b = a if dash < 0 else int(text[dash + 1:])
        except ValueError:
            raise InputError("bad frame range '%s' (expected A-B or A)" % text)
    if b < a:
        raise InputError("frame range %d-%d is empty (end before start)" % (a, b))
    return range(a, b + 1)


# Blender's smallest render size (resolution_x/y, clamped there) and the library's largest.
MIN_RESOLUTION, MAX_RESOLUTION = 4, 65536


def parse_resolution(text):
    """'WxH' -> (w, h), each in [MIN_RESOLUTION, MAX_RESOLUTION], as the CLI checks it
    (cli/options.cpp checkResolutionOption); anything else is an InputError."""
    try:
        w, h = (int(v) for v in text.lower().split("x"))
    except ValueError:
        w = h = 0
    if not (MIN_RESOLUTION <= w <= MAX_RESOLUTION and MIN_RESOLUTION <= h <= MAX_RESOLUTION):
        raise InputError("bad --resolution '%s' (expected WxH, each %d to %d, e.g. 480x270)"
                         % (text, MIN_RESOLUTION, MAX_RESOLUTION))
    return w, h


def apply_resolution(scene, text):
    """Renders `scene` at the --resolution 'WxH' (parse_resolution), at 100 %."""
    w, h = parse_resolution(text)
    scene.render.resolution_x, scene.render.resolution_y = w, h
    scene.render.resolution_percentage = 100


def output_argument(text):
    """An -o folder of batch.py or batch_eval.py as an absolute path. One starting with // is relative to
    the opened .blend file's folder, as Blender reads its own -o (os.path would take it for the root
    folder, and Blender would then write the frames beside the .blend); refused without a saved .blend."""
    if text.startswith("//"):
        if not bpy.data.filepath:
            raise InputError("the output folder '%s' is relative to the .blend file, and no saved .blend file is "
                             "open: give a folder" % text)
        text = bpy.path.abspath(text)
    return os.path.abspath(text)


def check_output_dir(out_dir, subfolders=()):
    """Creates out_dir if needed and proves it writable, or raises InputError naming it; likewise when
    one of `subfolders`, where a run writes frames of that name, is a file (the user's own)."""
    if os.sep == "/" and "\\" in out_dir:
        # Blender reads it as a folder separator in a render's path: the renders went to another folder
        # ("shot\010" -> shot/010/), and the run failed with "Blender wrote no file".
        raise InputError("output folder '%s' has a backslash in its path, which Blender reads as a folder "
                         "separator: choose a path without one" % out_dir)
    if os.path.exists(out_dir) and not os.path.isdir(out_dir):
        raise InputError("output folder '%s' is a file, not a folder: choose another" % out_dir)
    for sub in subfolders:
        path = os.path.join(out_dir, sub)
        if os.path.exists(path) and not os.path.isdir(path):
            raise InputError("'%s' is a file, not a folder: Crisp writes the run's %s frames there; move it, or "
                             "choose another output folder" % (path, sub))
    try:
        os.makedirs(out_dir, exist_ok=True)
        # A probe of its own: farm chunks check one shared folder at the same time.
        fd, probe = tempfile.mkstemp(prefix=".crisp_write_test", dir=out_dir)
        with os.fdopen(fd, "w") as f:
            f.write("ok")
        os.remove(probe)
    except OSError as e:
        raise InputError("output folder '%s' is not writable: %s" % (out_dir, e.strerror or e))


def check_method(method, need_library):
    if method not in plan_mod.METHOD_PASSES:
        raise InputError("unknown method '%s' (known: %s)" % (method, ", ".join(plan_mod.METHOD_PASSES)))
    if need_library:
        types = native.filter_types()  # raises CrispError if the library is missing
        if method not in types:
            raise InputError("method '%s' is not in this libcrisp (it has: %s)" % (method, ", ".join(types)))


# The smallest filterSize when no library loads (the viewport's preview runs without one); with one, its
# own table's (temporal/jitter.cpp jitterParamSpecs), read once. Blender's Filter Size goes to 0.
FALLBACK_MIN_FILTER_SIZE = 0.01


def min_filter_size(method="taa"):
    """The smallest filterSize a temporal method takes: the loaded library's (native.param_spec, read
    once per library), else FALLBACK_MIN_FILTER_SIZE."""
    try:
        spec = native.param_spec(method, "filterSize")
    except native.CrispError:
        spec = None
    return float(spec["min"]) if spec is not None else FALLBACK_MIN_FILTER_SIZE


def __getattr__(name):
    """pipeline.MIN_FILTER_SIZE, the preview's floor of the scene's Filter Size (viewport.py reads it on each
    draw): min_filter_size() of the library loaded by then."""
    if name == "MIN_FILTER_SIZE":
        return min_filter_size()
    raise AttributeError("module %r has no attribute %r" % (__name__, name))


def with_scene_filter_size(scene, method, params):
    """params with a temporal method's filterSize, the width of the pixel filter its unjitter (and
    jitterWeighting) assume, set to the scene's Film > Filter Size, over which the frames are jittered
    and EEVEE's reference is filtered, when it is not the library's default and params do not set it
    (crisp render --set): the panel does not offer it, as it is that setting. Measured at 96x54 against
    64 samples at frame 16, filter size 2.5: taa 29.05 -> 32.47 dB on spinning_cube, phlm 19.27 -> 21.06
    dB on still_life; 0.75: taa 19.58 -> 20.55 dB on still_life."""
    if method not in plan_mod.TEMPORAL_METHODS or "filterSize" in (params or {}):
        return params
    spec = native.param_spec(method, "filterSize")
    if spec is None:
        return params
    size = max(float(scene.render.filter_size), float(spec["min"]))
    if abs(size - spec["default"]) < 1e-6:
        return params
    return dict(params or {}, filterSize=size)


def with_plan_params(method, params, the_plan):
    """params with what the plan asks of the filter (plan.NO_STILL_AVERAGE where the image changes with no
    motion), each where params do not set it (crisp render --set, the panel's). crisp filter does the same
    from the sidecars (cmd_filter.cpp applyPlanParams)."""
    if the_plan.still_average or method not in plan_mod.NO_STILL_AVERAGE:
        return params
    out = dict(params or {})
    for name, value in plan_mod.NO_STILL_AVERAGE[method].items():
        if name in out:
            continue
        if isinstance(value, str):  # another parameter's value: the one given, else its default
            value = out[value] if value in out else native.param_spec(method, value)["default"]
        out[name] = value
    return out


def check_camera_shifts(scene, methods):
    """The methods that shift the camera by sub-pixel amounts (the temporal ones' jitter, make_plan; rsaa's
    sub-samples, render_frames) need a scene where a shift moves the samples by whole pixels
    (render.shift_per_pixel: square pixels): an InputError naming them otherwise, before anything renders."""
    jittered = [m for m in methods if m in plan_mod.TEMPORAL_METHODS]
    subsampled = [m for m in methods if "subsamples" in plan_mod.METHOD_PASSES.get(m, ())]
    if not (jittered or subsampled):
        return
    try:
        render.shift_per_pixel(scene)
    except render.RenderError as e:
        raise InputError("%s, and %s" % (" and ".join(
            "%s render%s %s" % (", ".join(ms), "s" * (len(ms) == 1), what) for ms, what in (
                (jittered, "jittered frames"), (subsampled, "sub-samples by jittering the camera")) if ms), e))


def scene_plan(scene, method, frames, view_layer=None, engine_name="eevee"):
    engine = render.render_engine(scene, engine_name)
    # Over the whole span whatever the order (a list given backwards, as the Python API allows).
    facts = plan_mod.scene_facts(scene, min(frames), max(frames), view_layer=view_layer,
                                 renderer_motion_pass=render.renderer_motion_pass(engine))
    return plan_mod.make_plan(method, facts), facts


def _write_json(path, data):
    if os.path.dirname(path):
        os.makedirs(os.path.dirname(path), exist_ok=True)
    render.write_json(path, data)


def _read_json(path):
    try:
        with open(path) as f:
            data = json.load(f)
        return data if isinstance(data, dict) else None
    except (OSError, ValueError):
        return None


def _png_records_dir(folder):
    return os.path.join(folder, ".crisp")


def _png_record_path(png):
    return os.path.join(_png_records_dir(os.path.dirname(png)), os.path.basename(png) + ".json")


def _png_record(png):
    """What a run knows of a PNG it wrote (filtered/.crisp/<name>.png.json): a PNG changed since, or
    never written by a run, is not its own."""
    st = os.stat(png)
    return {"size": st.st_size, "mtime_ns": st.st_mtime_ns}


def _drop_stale_png(png, log):
    """A run without PNGs: the filtered PNG an earlier run wrote shows that run's result (and Preview
    Frame prefers it to the EXR), so it goes; one the user made or changed is kept, and named."""
    record = _png_record_path(png)
    try:
        if _read_json(record) == _png_record(png):
            os.remove(png)
            os.remove(record)
            log("info: removed %s, written by an earlier run" % png)
            return
    except OSError:
        pass
    log("note: kept %s (not written by Crisp, or changed since): it does not show this run's result" % png)


def made_with(scene, method, params, samples, reference_samples, jitter, engine, filter_frames, scene_key,
              exr=None):
    """What makes a frame's outputs what they are, recorded in its input sidecar ("made_with"): a resume
    makes again every frame made otherwise, also by another build of the library. scene_key None
    (unknown: a scene edited in this session) matches any. exr: how the filtered EXRs are stored
    (native.exr_storage; None: native.CRISP_EXR, recorded as such, as OpenEXR's defaults store them too)."""
    making = {"scene": scene.name, "scene_key": scene_key, "resolution": list(render.render_size(scene)),
              "method": method if filter_frames else None, "params": native.canonical_param_texts(method, params),
              "samples": samples, "reference_samples": reference_samples, "jitter_distribution": jitter,
              "engine": engine, "library": native.load().digest if filter_frames else None}
    if filter_frames:  # always: a resume compares only the keys the run it makes has
        making["exr"] = list(exr or native.CRISP_EXR)
    return making


def same_making(recorded, wanted):
    """Whether a sidecar's made_with (or None: an older build's frame) matches wanted; the differences
    as text otherwise."""
    if not isinstance(recorded, dict):
        return False, "made by an older build"
    differences = []
    for key, value in wanted.items():
        there = recorded.get(key)
        if key == "scene_key" and (there is None or value is None):
            continue
        if there != value:
            differences.append("%s %s there, %s here" % (key, json.dumps(there), json.dumps(value)))
    return not differences, "; ".join(differences)


def older_than_input(input_dir, f, outputs):
    """The outputs of frame f older than its input's sidecar. Outputs are written after their input, so
    such an output is an earlier run's, left when a later run stopped between writing the input and it."""
    sidecar = os.path.join(input_dir, render.frame_name(f, ".json"))
    if not os.path.isfile(sidecar):
        return []
    rendered = os.path.getmtime(sidecar)
    return [p for p in outputs if os.path.getmtime(p) < rendered]


PREROLL_PREFIX = "crisp-preroll-"


def _preroll_prefix(pid):
    return "%s%d-%s-" % (PREROLL_PREFIX, pid, render.host_tag())


def remove_stale_preroll_dirs(log):
    """Removes the pre-roll folders that runs of this host left when they were killed without a chance to
    clean up (kill -9, a crash, the OOM killer): those named with a process that no longer runs, untouched
    for a minute. A pre-roll folder holds a chunk's worth of full-size EXRs; each killed chunk would keep
    one on the worker's disk."""
    folder = tempfile.gettempdir()
    try:
        names = os.listdir(folder)
    except OSError:
        return
    for name in names:
        pid = name[len(PREROLL_PREFIX):].split("-", 1)[0] if name.startswith(PREROLL_PREFIX) else ""
        if not pid.isdigit() or not name.startswith(_preroll_prefix(int(pid))):
            continue
        path = os.path.join(folder, name)
        if os.path.isdir(path) and render.left_by_a_killed_run(path, int(pid)):
            shutil.rmtree(path, ignore_errors=True)
            log("note: removed %s, the pre-roll folder of a run that was killed" % path)


def chunk_run(frames, shot_first, preroll, is_complete=None):
    """(pre-roll frames, frames to write) of a chunk: with is_complete (resume) the frames to write start
    at the first frame that is not complete, and the pre-roll is the `preroll` frames before that one,
    never before shot_first (a sequential run of the shot starts there)."""
    todo = list(frames)
    if is_complete is not None:
        while todo and is_complete(todo[0]):
            todo.pop(0)
    first = todo[0] if todo else frames[-1] + 1
    return list(range(max(shot_first, first - max(preroll, 0)), first)) if todo else [], todo


def run(*args, **kwargs):
    """iter_run to its end: the run.json dictionary."""
    return render.drain(iter_run(*args, **kwargs))


def scene_notes(scene, frames, view_layer, made="rendered and filtered", method=None):
    """What Crisp's renders of `frames` (a run's with `method`, or with made="rendered" the reference's)
    leave out or change of the scene's own render settings, as texts for the artist: the engine, the frame
    step, the other view layers, motion blur, the render region, the sequencer."""
    notes = []
    user_engine = scene.render.engine
    if user_engine not in ("BLENDER_EEVEE", "BLENDER_EEVEE_NEXT"):
        notes.append("the scene's engine is %s; Crisp renders with EEVEE and puts %s back afterwards"
                     % (user_engine, user_engine))
    if scene.frame_step != 1:
        # Only a temporal filter needs them all; Crisp renders every frame of the range for any method.
        why = ("%s's history needs every frame, so " % method if method in plan_mod.TEMPORAL_METHODS
               else "Crisp renders every frame of the range: ")
        notes.append("the scene's frame step %d is not used: %seach frame of %d-%d is %s"
                     % (scene.frame_step, why, frames[0], frames[-1], made))
    others = [layer.name for layer in scene.view_layers if layer.use and layer != view_layer]
    # Blender's own render makes each of them (F12 only the window's with Render Single Layer; a command-line
    # render, as crisp render's, all of them whatever that flag says)
    if others and not (scene.render.use_single_layer and not bpy.app.background):
        notes.append("only the view layer '%s' is %s, not %s: to filter another, make it the window's view "
                     "layer and render again into another Output folder"
                     % (view_layer.name, made, ", ".join("'%s'" % name for name in others)))
    if scene.eevee.use_motion_blur or scene.render.use_motion_blur:
        notes.append("the scene's motion blur is off in Crisp's renders (a blurred sample cannot be reprojected, "
                     "and the reference would blur differently); it is back on afterwards")
    if scene.render.use_border:
        does = "renders" if made == "rendered" else "renders and filters"
        notes.append("the render region is not used: Crisp %s the whole frame, %dx%d (a filter needs the pixels "
                     "around the region's edges)%s" % ((does,) + render.render_size(scene) + (
                         "; crop the filtered frames to the region afterwards" if scene.render.use_crop_to_border
                         else "",)))
    editor = scene.sequence_editor
    strips = (editor.strips if hasattr(editor, "strips") else editor.sequences) if editor else ()  # 'strips': 4.4+
    if scene.render.use_sequencer and any(strip.type != "SOUND" for strip in strips):  # Blender's rule for the edit
        notes.append("the scene's sequencer strips are not applied to Crisp's frames: Crisp renders the scene "
                     "through its camera, as with Post Processing > Sequencer off")
    return notes


def iter_run(scene, method, frames, out_dir, params=None, samples=1, reference_samples=0, plan_only=False,
             filter_frames=True, threads=0, jitter_distribution="blackman-harris", write_png=True, log=print,
             view_layer=None, should_cancel=None, engine_name="eevee", preroll=0, shot=None, resume=False,
             scene_key=None, input_codec="none"):
    """A generator: yields after each frame rendered (render.iter_render_frames' info, also of pre-roll
    and reference frames) and returns the run.json dictionary (also written to out_dir/run.json); closed
    between frames, it records the run as cancelled at the next frame. engine_name: 'eevee', or
    'cycles' to render the same frames with Cycles (cheap settings, its own Vector pass) for checks.
    A chunk of a shot: shot (a range holding frames; the plan is made over it), preroll (frames before
    the chunk filtered but not written), resume (start at the first frame with a missing output); the
    result then goes to run_AAAA-BBBB.json so concurrent chunks never write the same file.
    scene_key: what the scene file holds (batch.py scene_key), or None when unknown (a scene edited in
    this session); with it, frames of another scene file are never reused or resumed. input_codec: the
    OpenEXR codec of the frames this run renders into input/ and reference/ (render.INPUT_CODECS, all
    lossless: frames kept from a run with another stay as they are; each sidecar says which). out_dir:
    a folder; one starting with // is relative to the saved .blend file, as Blender reads it
    (output_argument)."""
    frames = list(frames)
    given = params
    # Before anything uses it: os.path reads "//x" as the root folder's x, where Blender renders beside
    # the .blend, so the run made folders under / and then found no frame where it looked.
    out_dir = output_argument(out_dir)
    if not frames:
        raise InputError("no frames to render (empty frame range)")
    if preroll < 0:
        raise InputError("pre-roll must be >= 0 frames, got %d" % preroll)
    try:
        input_codec = render.checked_codec(input_codec)  # before anything is rendered
    except render.RenderError as e:
        raise InputError(str(e)) from None
    shot = list(shot) if shot is not None else None
    if shot is not None and (not shot or frames[0] < shot[0] or frames[-1] > shot[-1]):
        raise InputError("frames %d-%d are not inside the shot %s" % (
            frames[0], frames[-1], "%d-%d" % (shot[0], shot[-1]) if shot else "(empty)"))
    render.check_blender_version()
    # The frames rendered: these and their pre-roll (chunk_run).
    problem = render.camera_problem(scene, [max((shot or frames)[0], frames[0] - preroll)] + frames)
    if problem:
        raise InputError(problem)
    check_method(method, need_library=filter_frames and not plan_only)
    if filter_frames and not plan_only:
        params = with_scene_filter_size(scene, method, params)
    if filter_frames and not plan_only and params:
        # Every rule the library checks, also those between parameters (an odd patchSize, feedbackMin
        # <= feedbackMax) that a commit finds, before a frame is rendered rather than after the first.
        bad = native.check_params(method, params)
        if bad:
            if "'filterSize'" in bad and "filterSize" not in (given or {}):
                bad += " (filterSize is the scene's Film > Filter Size, %g px)" % scene.render.filter_size
            raise InputError("%s: %s" % (method, bad))
    check_camera_shifts(scene, [method])
    writes = [] if plan_only else ["input"] + ["filtered"] * filter_frames + ["reference"] * bool(reference_samples)
    check_output_dir(out_dir, writes)
    user_engine = scene.render.engine
    engine = render.render_engine(scene, engine_name)
    view_layer = render.default_view_layer(scene, view_layer)  # one layer planned and rendered
    for note in scene_notes(scene, frames, view_layer, method=method):
        log("note: " + note)
    the_plan, facts = scene_plan(scene, method, shot or frames, view_layer, engine_name)
    log(the_plan.describe())
    if filter_frames and not plan_only:
        params = with_plan_params(method, params, the_plan)
    shared = facts.shared_id_movers
    if the_plan.motion_source == "reconstruct" and shared and filter_frames:
        names = plan_mod.some_names(shared, quote=True)
        verbs = ("move", "render") if len(shared) > 1 else ("moves", "renders")
        log("note: %s %s but %s more than once (instances of one source share its object ID, as do objects of "
            "one name from different files), so the sidecars cannot tell the copies' transforms apart and motion "
            "reconstruction treats their pixels as still: %s may leave a trail behind them; for exact motion make "
            "the moving copies real objects (Object > Apply > Make Instances Real), or rename a local object "
            "that has a linked one's name" % (names, verbs[0], verbs[1], method))
    deforming = facts.deforming_objects
    if the_plan.motion_source == "reconstruct" and deforming and filter_frames:
        # native/motion/reconstruct.h: a pixel moves with its object's transform, not its vertices'.
        names = plan_mod.some_names(deforming, quote=True)
        log("note: %s deform%s (shape keys, an armature, modifiers): motion reconstruction is rigid, so their "
            "pixels get their object's motion, not the deformation's: %s may leave a trail behind what deforms"
            % (names, "s" if len(deforming) == 1 else "", method))
    legacy_eevee = engine == "BLENDER_EEVEE" and bpy.app.version < (4, 2, 0)  # the EEVEE whose probe this is
    if legacy_eevee and scene.eevee.gi_cubemap_resolution != render.CUBEMAP_RESOLUTION:
        # "info", not "note": Blender's default is 512, so nearly every scene would warn of it, and there is
        # nothing the artist can do about it but bake a light cache.
        log("info: the world's reflection probe is rendered at %s px, not the scene's %s (Indirect Lighting > Cubemap "
            "Size): it is rendered again for every frame, which at 512 px costs about 1.4 s on 2 cores; sharp "
            "reflections of a detailed world look blurrier than in Blender's own render (a baked light cache is used "
            "as baked)" % (render.CUBEMAP_RESOLUTION, scene.eevee.gi_cubemap_resolution))
    if scene.render.film_transparent and filter_frames and method == "rsaa":
        # rsaa's resampling fetches colour and alpha together (an outline against the film is a geometric edge).
        log("note: the film is transparent: rsaa anti-aliases colour and alpha together on geometric edges (an "
            "object's outline too); elsewhere it changes the colour only, and the alpha keeps the 1-sample render's")
    elif scene.render.film_transparent and filter_frames and method in plan_mod.TEMPORAL_METHODS:
        # The library filters the alpha with taa's kernel once it is below 1 (native/filters/temporal_alpha.h).
        log("note: the film is transparent: %s anti-aliases the alpha as well as the colour, with the same motion "
            "and jitter" % method)
    elif scene.render.film_transparent and filter_frames and method != "none":
        log("note: the film is transparent: %s anti-aliases the colour, not the alpha, which keeps the 1-sample "
            "render's hard edges; for clean edges, use a temporal method or render the background in the scene "
            "(Film > Transparent off)" % method)
    # Read before any render: the renders set the scene's image settings to their own while they run.
    exr = native.exr_storage(scene.render.image_settings) if filter_frames else None
    if exr is not None:
        log("info: the filtered EXRs are stored as the scene's Output properties say: %s, %s (Color Depth, Codec)"
            % ("half float" if exr[0] == 16 else "full float", exr[1].upper()))
    if compositor.changes_the_image(scene, os.path.join(out_dir, "filtered")):
        log("note: the scene's compositor is not applied to Crisp's frames (they are filtered as rendered); "
            "apply it to the filtered frames through the 'Crisp Result' node group")
    result = {"blender_version": bpy.app.version_string, "method": method, "params": dict(params or {}),
              "scene": scene.name, "view_layer": view_layer.name, "frames_requested": [frames[0], frames[-1]],
              "samples": samples,
              "engine": engine, "user_engine": user_engine,
              "plan": the_plan.to_json(), "facts": {"camera_moves": facts.camera_moves,
                                                   "moving_objects": facts.moving_objects,
                                                   "deforming_objects": facts.deforming_objects,
                                                   "visible_objects": facts.visible_objects,
                                                   "camera_cuts": facts.camera_cuts,
                                                   "shared_id_movers": facts.shared_id_movers,
                                                   "image_changes": facts.image_changes},
              "jitter_distribution": jitter_distribution if the_plan.jitter else "none",
              "input_codec": input_codec, "gi_cubemap_resolution": render.CUBEMAP_RESOLUTION, "frames": []}
    if filter_frames:
        result["exr"] = dict(zip(("depth", "codec"), exr or native.CRISP_EXR))
    if len(frames) > 2 and len({b - a for a, b in zip(frames, frames[1:])}) > 1:
        # frames_requested is the first and last frame; a list out of order or with uneven gaps (the Python
        # API takes any) is not that range, so it is recorded as given.
        result["frame_list"] = frames
    if native._lib is not None or (filter_frames and not plan_only):
        ok, text = native.status()
        result["library"] = text
    run_json = os.path.join(out_dir, "run.json" if shot is None else "run_%04d-%04d.json" % (frames[0], frames[-1]))
    if plan_only:
        # A record of frames made there is not replaced by a plan of none (a plan asked of a farm job's
        # folder would lose its chunks' records, and their status).
        before = _read_json(run_json)
        if before is not None and before.get("status") != "planned":
            log("note: kept %s, the record of a run (status: %s); the plan is not written" % (
                run_json, before.get("status")))
        else:
            _write_json(run_json, dict(result, status="planned"))
        return result

    stamp = made_with(scene, method, params, samples, reference_samples,
                      jitter_distribution if the_plan.jitter else "none", engine, filter_frames, scene_key, exr)
    previous_record = _read_json(run_json) if resume else None

    input_dir = os.path.join(out_dir, "input")
    filtered_dir = os.path.join(out_dir, "filtered")
    frame_filter = None
    if filter_frames:
        os.makedirs(filtered_dir, exist_ok=True)
        if write_png:  # the PNG records' folder, before any frame: a file in the way stops the run here
            try:
                os.makedirs(_png_records_dir(filtered_dir), exist_ok=True)
            except OSError as e:
                raise InputError("cannot make the folder %s: %s" % (_png_records_dir(filtered_dir), e.strerror or e))

    def on_frame(f, info):
        entry = {"frame": f, "render_s": round(info["render_s"], 4), "jitter": info["jitter"]}
        if "geometry_render_s" in info:  # rsaa's sub-samples: eight more renders, part of the frame's cost
            entry["geometry_render_s"] = round(info["geometry_render_s"], 4)
        if frame_filter is not None:
            out_exr = os.path.join(filtered_dir, render.frame_name(f))
            png = os.path.join(filtered_dir, render.frame_name(f, ".png"))
            # The PNG, through the scene's colour management as its own PNGs, is made while the library
            # writes the EXR.
            times = frame_filter.run(info["exr"], [out_exr], while_writing=(lambda: render.write_display_png(
                scene, *frame_filter.output_bottom_up(), png)) if write_png else None, exr=exr)
            if write_png:
                _write_json(_png_record_path(png), _png_record(png))
            elif os.path.isfile(png):
                _drop_stale_png(png, log)
            entry.update({k: round(v, 4) for k, v in times.items()})
            if frame_filter.restart_reason:
                entry["history_restarted"] = frame_filter.restart_reason
                log("frame %d: temporal history restarts (%s)" % (f, frame_filter.restart_reason))
        result["frames"].append(entry)
        record("running")  # a run killed later still says how far it got
        geometry = ", geometry %.3f s" % info["geometry_render_s"] if "geometry_render_s" in info else ""
        log("frame %d: render %.3f s%s%s" % (f, info["render_s"], geometry, ", load %.3f s, filter %.3f s, write %.3f s"
                                             % (entry["load_s"], entry["filter_s"], entry["write_s"])
                                             if "filter_s" in entry else ""))

    reference_dir = os.path.join(out_dir, "reference")

    def is_complete(f):
        outs = [os.path.join(reference_dir, render.frame_name(f))] if reference_samples else []
        if filter_frames:
            outs += [os.path.join(filtered_dir, render.frame_name(f, ext)) for ext in ((".exr", ".png") if write_png
                                                                                     else (".exr",))]
        if not (render.input_complete(input_dir, f) and all(os.path.isfile(p) for p in outs)):
            return False
        older = older_than_input(input_dir, f, outs)
        if older:
            log("frame %d: %s older than its input (a run stopped before writing it): making it again"
                % (f, ", ".join(map(os.path.basename, older))))
            return False
        side = render.read_sidecar(input_dir, f)
        same, why = same_making(side.get("made_with"), stamp)
        if same and side.get("passes") != list(the_plan.passes):
            # The plan is made over the shot: the same settings with another --shot may plan other passes.
            same, why = False, "passes %s there, %s here" % (json.dumps(side.get("passes")),
                                                             json.dumps(list(the_plan.passes)))
        if not same:
            log("frame %d was made with other settings (%s): making it again" % (f, why))
        return same

    # Pre-roll warms temporal history: nothing to warm without a filter or for a spatial method.
    warms = filter_frames and method in plan_mod.TEMPORAL_METHODS
    preroll_frames, todo = chunk_run(frames, (shot or frames)[0], preroll if warms else 0,
                                     is_complete if resume else None)
    if resume and not warms and todo:
        # Without a history each frame's outputs stand alone: the resume makes only the frames that need
        # it, also after the first, and keeps the others (as crisp filter's resume of a spatial method).
        kept_after = [f for f in todo[1:] if is_complete(f)]
        todo = [f for f in todo if f not in kept_after]
        if kept_after:
            log("frames kept (complete, made with these settings): %s" % ", ".join(map(str, kept_after)))
    reused = [f for f in preroll_frames if render.reusable_input(scene, engine, input_dir, f, the_plan, samples,
                                                                     jitter_distribution, scene_key)]
    result["chunk"] = {"shot": [shot[0], shot[-1]] if shot else None, "preroll": preroll,
                       "preroll_frames": [preroll_frames[0], preroll_frames[-1]] if preroll_frames else None,
                       "preroll_reused": reused,
                       # A run resumed: one that keeps frames made before it (with --resume alone, as the job
                       # type passes to every task, a run that finds nothing to keep starts afresh).
                       "resumed_at": todo[0] if resume and todo and len(todo) < len(frames) else None}
    if not todo:
        log("every output of frames %d-%d exists; nothing to do" % (frames[0], frames[-1]))
    elif warms and not preroll_frames and todo[0] not in facts.camera_cuts and (not shot or todo[0] > shot[0]) \
            and os.path.isfile(os.path.join(filtered_dir, render.frame_name(todo[0] - 1))):
        log("note: %s's history starts again at frame %d, from one sample: frame %d in %s was filtered with the "
            "frames before it, so the sequence may jump there; to continue it, render from the shot's first frame "
            "or with a pre-roll (crisp render --preroll N)" % (method, todo[0], todo[0] - 1, filtered_dir))

    def on_preroll(f, info):
        frame_filter.run(info["exr"], [])
        log("frame %d: pre-roll (filtered, not written)" % f)

    def record(status):
        """Writes run.json as it stands: this run's frames and, after a resume, the complete frames it
        kept (their entries from the record before, when it has them), and how the run ended."""
        written = dict(result, status=status)
        if resume:
            kept = [f for f in frames if f not in todo]  # complete with these settings (is_complete)

            def merged(before, now):
                # A record edited by hand (or by another tool) may hold anything: entries without a frame
                # number are left out, as is a list that is not one.
                before = {e["frame"]: e for e in (before if isinstance(before, list) else [])
                          if isinstance(e, dict) and isinstance(e.get("frame"), int)}
                # In frame order: a spatial resume keeps frames after those it makes.
                return sorted([before.get(f, {"frame": f}) for f in kept] + now, key=lambda e: e["frame"])

            previous = previous_record or {}
            written["frames"] = merged(previous.get("frames", []), result["frames"])
            if reference_samples:
                before = previous.get("reference")
                before = before.get("frames", []) if isinstance(before, dict) and \
                    before.get("samples") == reference_samples else []
                now = dict(result.get("reference", {"samples": reference_samples, "frames": []}))
                now["frames"] = merged(before, now["frames"])
                written["reference"] = now
        _write_json(run_json, written)
        return written

    def ended():
        """How a run that raised nothing ended: complete, or cancelled at the first frame it did not make."""
        made = {e["frame"] for e in result["frames"]}
        made_refs = {e["frame"] for e in result.get("reference", {}).get("frames", [])} if reference_samples else made
        stopped = [f for f in todo if f not in made]
        stopped_refs = [f for f in todo if f not in made_refs]
        return ("cancelled at frame %d" % stopped[0] if stopped else
                "cancelled at reference frame %d" % stopped_refs[0] if stopped_refs else "complete")

    # Temporary files of a run on this host that was killed mid-write (kill -9, a crash).
    for folder in (out_dir, input_dir, filtered_dir, _png_records_dir(filtered_dir), reference_dir):
        stale = render.remove_stale_temporaries(folder)
        if stale:
            log("note: removed %d temporary file(s) an interrupted run left in %s (first: %s)"
                % (len(stale), folder, stale[0]))
    # From here on run.json describes this run, also one that fails or is stopped ("status").
    record("running")
    t0 = time.perf_counter()
    preroll_dir = None
    if preroll_frames:
        remove_stale_preroll_dirs(log)
    try:
        try:
            if filter_frames:  # made here, so that whatever stops the run before its end releases it (finally)
                frame_filter = native.FrameFilter(method, params, threads, the_plan.passes)
            # Contiguous and in order, so the history sees them as a sequential run would.
            for from_input, group in itertools.groupby(preroll_frames, key=lambda f: f in reused):
                group = list(group)
                if from_input:
                    for f in group:
                        on_preroll(f, {"exr": os.path.join(input_dir, render.frame_name(f))})
                    continue
                # Named by this process, so a later run can tell it was left by a killed one.
                preroll_dir = preroll_dir or tempfile.mkdtemp(prefix=_preroll_prefix(os.getpid()))
                yield from render.iter_render_frames(scene, the_plan, group, preroll_dir, samples=samples,
                                                     jitter_distribution=jitter_distribution, view_layer=view_layer,
                                                     on_frame=on_preroll, should_cancel=should_cancel,
                                                     engine=engine if engine == "CYCLES" else None, made_with=stamp)
            if todo:
                yield from render.iter_render_frames(scene, the_plan, todo, input_dir, samples=samples,
                                                     jitter_distribution=jitter_distribution, view_layer=view_layer,
                                                     on_frame=on_frame, should_cancel=should_cancel,
                                                     engine=engine if engine == "CYCLES" else None, made_with=stamp,
                                                     codec=input_codec)
        finally:
            if frame_filter is not None:
                frame_filter.close()
            if preroll_dir:
                shutil.rmtree(preroll_dir, ignore_errors=True)
        result["total_s"] = round(time.perf_counter() - t0, 3)
        if reference_samples and todo:
            result["reference"] = {"samples": reference_samples, "frames": []}

            def on_reference(f, info):
                result["reference"]["frames"].append({"frame": f, "render_s": round(info["render_s"], 4)})

            yield from render.iter_render_reference(scene, todo, reference_dir, reference_samples,
                                                    view_layer=view_layer, on_frame=on_reference,
                                                    should_cancel=should_cancel, codec=input_codec)
    except GeneratorExit:  # closed between frames (an operator Blender ended): as a stop by should_cancel
        result.setdefault("total_s", round(time.perf_counter() - t0, 3))
        try:
            record(ended())
        except OSError:
            pass
        raise
    except BaseException as e:  # also KeyboardInterrupt: the record says the run did not finish
        try:
            record("failed: %s" % (str(e) or type(e).__name__))
        except OSError:
            pass  # the folder itself failing: the error that stopped the run is the one to report
        raise
    return record(ended())


def listed_frames(fs, verb):
    """"frame 3 is", "frames 3, 4 are" (verb: its singular and plural), at most six frames named."""
    names = ", ".join(map(str, fs[:6])) + (" and %d more" % (len(fs) - 6) if len(fs) > 6 else "")
    return ("frame %s %s" if len(fs) == 1 else "frames %s %s") % (names, verb[len(fs) > 1])


def _same_making_both_ways(a, b):
    """Two frames' made_with alike (same_making each way: a scene_key one of them lacks, a run from this
    session's edited scene, matches); two frames of older builds (no record) alike too."""
    if not isinstance(a, dict) or not isinstance(b, dict):
        return a == b
    return same_making(a, b)[0] and same_making(b, a)[0]


def sequence_warnings(out_dir, frames):
    """Why out_dir/filtered/ does not hold one run's sequence of `frames`, as texts ([] when it does):
    frames missing, made otherwise than the first (another method or settings: each input sidecar's
    made_with), or older than their input (a run stopped between writing a frame's input and its
    output left an earlier run's frame there)."""
    input_dir, filtered_dir = os.path.join(out_dir, "input"), os.path.join(out_dir, "filtered")
    missing, other, older = [], [], []
    first = None
    for f in frames:
        out = os.path.join(filtered_dir, render.frame_name(f))
        if not os.path.isfile(out):
            missing.append(f)
            continue
        making = render.read_sidecar(input_dir, f).get("made_with")
        if first is None:
            first = (f, making)
        elif not _same_making_both_ways(making, first[1]):
            other.append(f)
        if older_than_input(input_dir, f, [out]):
            older.append(f)
    out = []
    if missing:
        out.append("%s no filtered image" % listed_frames(missing, ("has", "have")))
    if other:
        out.append("%s made with other settings than frame %d" % (listed_frames(other, ("was", "were")), first[0]))
    if older:
        out.append("%s older than its input (a run stopped before writing it: render again, or resume)"
                   % listed_frames(older, ("is", "are")))
    return out


def compare_dirs(test_dir, reference_dir, frames, threads=0):
    """Metrics of test_dir/frame_NNNN.exr against reference_dir/frame_NNNN.exr, per frame and mean;
    "no_reference": the frames with a test image and no reference image (not measured)."""
    rows, no_reference = [], []
    with native.Context(threads) as ctx:
        for f in frames:
            t = os.path.join(test_dir, render.frame_name(f))
            r = os.path.join(reference_dir, render.frame_name(f))
            if not (os.path.isfile(t) and os.path.isfile(r)):
                if os.path.isfile(t):
                    no_reference.append(f)
                continue
            m = native.compare_images(ctx, r, t)
            m["frame"] = f
            rows.append(m)
    if not rows:
        raise InputError("nothing to compare: no frame has both %s and %s" % (test_dir, reference_dir))
    mean = {k: sum(r[k] for r in rows) / len(rows) for k in ("psnr", "ssim", "rmse", "flip")}
    return {"frames": rows, "mean": mean, "no_reference": no_reference}
