# SPDX-License-Identifier: GPL-2.0-or-later
"""The renders `crisp eval` needs, inside Blender (driven by batch_eval.py). Everything goes through
render.py's own functions (render_reference, render_frames) so eval measures exactly what the add-on
renders; this module only adds the grouping, the resume bookkeeping, the timing record and Blender's
compositor Anti-Aliasing (SMAA) baseline.

Layout under RENDERDIR (OUTDIR/renders):

    eevee_S/frame_NNNN.exr     S EEVEE samples, no jitter, colour only (S = 1 is also the input of the
                               methods that need nothing but colour, and of blender-smaa)
    jittered[-PASSES]/frame_NNNN.exr    1 sample, per-frame jitter, the passes of the temporal
                               methods that read exactly those (plan.render_set_name: "jittered" for
                               colour alone, "jittered-depth-motion", ...) (+ .json sidecar)
    unjittered-PASSES/frame_NNNN.exr  1 sample, no jitter, for the other methods that read more than
                               colour; with rsaa also the 8 geometry renders frame_NNNN_subK.exr
                               listed in the sidecar
    (one set per distinct plan, so a method's render time is that of the passes it reads)
    warp/frame_NNNN.exr        only where something moves: 1 sample, no jitter, the geometry of the
                               temporal error's warp W and disocclusion test at the pixel centres
                               (plan.TEMPORAL_ERROR: depth, motion, IDs; + .json sidecar); no
                               method reads it, so no method's render time includes it
    reference_N/frame_NNNN.exr the reference (N EEVEE samples)
    blender-smaa/frame_NNNN.exr  eevee_1 through Image -> Anti-Aliasing -> Composite
    <set>/times.json           {"NNNN": wall seconds of that frame's render}
    scene.json                 what was rendered, the plans, Blender version, SMAA settings

A frame counts as done when its EXR exists and times.json holds its time: an interrupted run resumes
with the frames still missing.
"""

import json
import os
import time

import bpy

from . import plan as plan_mod
from . import render

# BLENDER.md: in 3.4 the node's `threshold` maps to SMAA's threshold as 0.5 x value, so 0.2 is the
# 0.1 that SMAA (Jimenez et al. 2012) uses by default.
SMAA_THRESHOLD = 0.2


write_json = render.write_json  # through a temporary name; WriteFailed names the file


def read_json(path, default):
    try:
        with open(path) as f:
            return json.load(f)
    except (OSError, ValueError):
        return default


class TimeBook:
    """times.json of one render set: frame -> seconds, rewritten after each frame."""

    def __init__(self, folder):
        self.folder = folder
        os.makedirs(folder, exist_ok=True)
        self.path = os.path.join(folder, "times.json")
        self.times = read_json(self.path, {})

    def done(self, frame):
        return ("%04d" % frame) in self.times and os.path.isfile(os.path.join(self.folder, render.frame_name(frame)))

    def missing(self, frames):
        return [f for f in frames if not self.done(f)]

    def record(self, frame, seconds):
        self.times["%04d" % frame] = round(seconds, 5)
        write_json(self.path, self.times)


def group_plans(scene, methods, frames):
    """Plans of the library methods `methods` (names plan.py knows), grouped into render sets.

    Returns (plans, sets, unknown, facts): plans {method: Plan}; sets {set name: Plan} for the
    1-sample renders to make (one per distinct plan, plan.render_set_name, and "warp" where something moves: the
    temporal error's geometry); unknown: methods plan.py has no passes for (they get the plain
    1-sample frames); facts: plan.SceneFacts of the frame range."""
    engine = render.eevee_engine(scene)
    facts = plan_mod.scene_facts(scene, frames[0], frames[-1],
                                 renderer_motion_pass=render.renderer_motion_pass(engine))
    plans, unknown = {}, []
    for m in methods:
        if m not in plan_mod.METHOD_PASSES:
            unknown.append(m)
            continue
        plans[m] = plan_mod.make_plan(m, facts)
    sets = plan_mod.render_sets(list(plans.values()), facts)
    return plans, sets, unknown, facts


def input_set(plan):
    """Render set a method's input frames come from (plan.render_set_name)."""
    return plan_mod.render_set_name(plan)


def warm_up(scene, folder, the_plan=None, jitter_distribution="blackman-harris"):
    """One untimed 1-sample render: EEVEE compiles its shaders on the first render of a process
    (~10 s here), which would otherwise land on whichever render comes first; and again, ~1.3 s against
    ~0.05 s after, on the first render with other passes (an input set's plan), which would land on that
    set's first frame."""
    t0 = time.perf_counter()
    if the_plan is None:
        render.render_reference(scene, [scene.frame_current], folder, 1)
    else:
        render.render_frames(scene, the_plan, [scene.frame_current], folder, samples=1,
                             jitter_distribution=jitter_distribution)
    return time.perf_counter() - t0


def holds_renders(folder):
    """Whether a run rendered anything into folder: an EXR anywhere under it (not a hidden one, the
    temporary name of a render that did not finish), as crisp eval tells (cmd_eval.cpp holdsRenders)."""
    return any(f.endswith(".exr") and not f.startswith(".") for _, _, files in os.walk(folder) for f in files)


def render_curve_set(scene, frames, folder, samples, step):
    book = TimeBook(folder)
    for f in frames:
        if book.done(f):
            step(os.path.basename(folder), f, samples, skipped=True)
            continue
        info = render.render_reference(scene, [f], folder, samples)[0]
        book.record(f, info["render_s"])
        step(os.path.basename(folder), f, samples)


def input_frames_to_render(scene, the_plan, frames, folder, jitter_distribution):
    """The frames of an input set that are missing, or were rendered with other passes or settings (an
    earlier run with other methods: reusing them would hand a method fewer passes)."""
    book = TimeBook(folder)
    engine = render.eevee_engine(scene)
    return [f for f in frames
            if not (book.done(f) and render.reusable_input(scene, engine, folder, f, the_plan, 1, jitter_distribution))]


def render_input_set(scene, the_plan, frames, folder, jitter_distribution, step):
    """Renders the frames of one input set that input_frames_to_render lists."""
    to_render = input_frames_to_render(scene, the_plan, frames, folder, jitter_distribution)
    book = TimeBook(folder)
    for f in frames:
        if f not in to_render:
            step(os.path.basename(folder), f, 1, skipped=True)
            continue
        info = render.render_frames(scene, the_plan, [f], folder, samples=1,
                                    jitter_distribution=jitter_distribution)[0]
        book.record(f, info["render_s"])
        step(os.path.basename(folder), f, 1)


class SmaaCompositor:
    """Blender's compositor Anti-Aliasing node (SMAA 1x) on a loaded image, in a scene of its own with
    no camera and no Render Layers node, so rendering it runs the compositor only (BLENDER.md)."""

    def __init__(self, threshold=SMAA_THRESHOLD):
        self.scene = bpy.data.scenes.new("CrispEvalSMAA")
        s = self.scene
        s.use_nodes = True
        s.render.use_compositing = True
        s.render.use_sequencer = False
        s.render.resolution_percentage = 100
        s.render.use_file_extension = False
        s.render.image_settings.file_format = "OPEN_EXR"
        s.render.image_settings.color_depth = "32"
        s.render.image_settings.exr_codec = "NONE"
        s.render.image_settings.color_mode = "RGBA"
        tree = s.node_tree
        tree.nodes.clear()
        self.image_node = tree.nodes.new("CompositorNodeImage")
        self.aa = tree.nodes.new("CompositorNodeAntiAliasing")
        self.aa.threshold = threshold
        comp = tree.nodes.new("CompositorNodeComposite")
        tree.links.new(self.image_node.outputs["Image"], self.aa.inputs["Image"])
        tree.links.new(self.aa.outputs["Image"], comp.inputs["Image"])

    def settings(self):
        return {"node": "CompositorNodeAntiAliasing", "threshold": self.aa.threshold,
                "smaa_threshold": 0.5 * self.aa.threshold, "contrast_limit": self.aa.contrast_limit,
                "corner_rounding": self.aa.corner_rounding,
                "note": "Blender 3.4 maps the node's threshold to SMAA's as 0.5 x value (BLENDER.md); "
                        "0.2 is SMAA's usual 0.1"}

    def run(self, src, dst):
        """Returns the wall seconds of the compositor render (image load + SMAA + write)."""
        tmp = render.temporary_path(dst)
        t0 = time.perf_counter()
        img = bpy.data.images.load(src, check_existing=False)
        try:
            self.image_node.image = img
            self.scene.render.resolution_x, self.scene.render.resolution_y = img.size[0], img.size[1]
            self.scene.render.filepath = tmp
            bpy.ops.render.render(write_still=True, scene=self.scene.name)
        finally:
            self.image_node.image = None
            bpy.data.images.remove(img)
        dt = time.perf_counter() - t0
        if not os.path.isfile(tmp):
            raise render.RenderError("the compositor wrote no file for %s (expected %s)" % (src, tmp))
        os.replace(tmp, dst)
        return dt


def render_smaa_set(frames, source_folder, folder, compositor, step):
    book = TimeBook(folder)
    for f in frames:
        if book.done(f):
            step("blender-smaa", f, 1, skipped=True)
            continue
        seconds = compositor.run(os.path.join(source_folder, render.frame_name(f)),
                                 os.path.join(folder, render.frame_name(f)))
        book.record(f, seconds)
        step("blender-smaa", f, 1)
