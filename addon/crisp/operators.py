# SPDX-License-Identifier: GPL-2.0-or-later
"""Operators: Render with Crisp, Render reference, Compare, Update plan, Load result, Preview."""

import os

import bpy

from . import compositor, native, output_folder, pipeline, preferences, render
from . import properties as props


def _frames(scene):
    return pipeline.parse_frames("%d-%d" % (scene.frame_start, scene.frame_end))


def _done(op, scene, text):
    """The operator's last report: a warning when another scene writes to the same folder (an Output
    the user set in both), else information."""
    shared = output_folder.sharing(scene)
    if shared:
        op.report({"WARNING"}, "%s; note: scene %s writes to this folder too: set another Output in one of them "
                  "to keep both" % (text, ", ".join("'%s'" % n for n in shared)))
    else:
        op.report({"INFO"}, text)


def _fail(op, e):
    op.report({"ERROR"}, str(e))
    return {"CANCELLED"}


MAX_NOTES_REPORTED = 5


def _report_notes(op, notes):
    """The run's notes as warnings, each once and at most MAX_NOTES_REPORTED (a note made per frame, such as
    a kept PNG, would otherwise fill the Info editor); the console has them all. Returns how many."""
    distinct = list(dict.fromkeys(notes))
    for note in distinct[:MAX_NOTES_REPORTED]:
        op.report({"WARNING"}, "Crisp: " + note)
    if len(distinct) > MAX_NOTES_REPORTED:
        op.report({"WARNING"}, "Crisp: and %d more notes in the console" % (len(distinct) - MAX_NOTES_REPORTED))
    return len(distinct)


# Operators that change the file (the Output folder, the plan text, the compositor's node, an image)
# push one undo step of their own, so that Ctrl-Z takes back what they did, not the artist's edit before.
UNDOABLE = {"REGISTER", "UNDO"}


class CRISP_OT_plan(bpy.types.Operator):
    bl_idname = "crisp.plan"
    bl_label = "Update Plan"
    bl_options = UNDOABLE
    bl_description = "Work out which passes the chosen method needs on this scene, with reasons"

    def execute(self, context):
        scene, s = context.scene, context.scene.crisp
        try:
            the_plan, _ = pipeline.scene_plan(scene, s.method, list(_frames(scene)), context.view_layer)
        except (pipeline.InputError, render.RenderError, ValueError) as e:
            return _fail(self, e)
        s.plan_text = the_plan.describe()
        return {"FINISHED"}


class CRISP_OT_render(bpy.types.Operator):
    bl_idname = "crisp.render"
    bl_label = "Render with Crisp"
    bl_options = UNDOABLE
    bl_description = "Render the frame range at 1 sample with the planned passes and filter each frame"

    def execute(self, context):
        scene, s = context.scene, context.scene.crisp
        try:
            out = output_folder.out_dir(scene, writing=True)
        except output_folder.UnsavedFile as e:
            return _fail(self, e)
        wm = context.window_manager
        frames = list(_frames(scene))
        wm.progress_begin(0, len(frames))
        done, notes = [], []

        def log(text):
            print(text)
            if text.startswith("frame "):
                done.append(text)
                wm.progress_update(len(done))
            elif text.startswith("note: "):  # what the run leaves out or changes: for the artist, not the console only
                notes.append(text[len("note: "):])
        try:
            result = pipeline.run(scene, s.method, frames, out, params=props.changed_params(s, s.method),
                                  threads=preferences.threads(context), jitter_distribution=s.jitter_distribution,
                                  write_png=s.write_png, log=log, view_layer=context.view_layer)
            s.plan_text = "\n".join(
                ["plan for %s:" % s.method] + ["  + %s: %s" % (p, result["plan"]["reasons"][p])
                                               for p in result["plan"]["passes"]])
            if s.load_result:
                compositor.load_result(scene, os.path.join(out, "filtered"), frames[0], frames[-1])
        except (pipeline.InputError, render.RenderError, native.CrispError, OSError) as e:
            _report_notes(self, notes)  # what the run said before it failed still holds
            return _fail(self, e)
        finally:
            wm.progress_end()
        how = "copied unfiltered (method none)" if s.method == "none" else "filtered with %s" % s.method
        n = _report_notes(self, notes)
        _done(self, scene, "Crisp: %d frames %s into %s%s" % (len(result["frames"]), how, out, "; %d note%s in the "
              "Info editor" % (n, "s" * (n > 1)) if n else ""))
        return {"FINISHED"}


class CRISP_OT_render_reference(bpy.types.Operator):
    bl_idname = "crisp.render_reference"
    bl_label = "Render Reference"
    bl_options = UNDOABLE
    bl_description = "Render the frame range with the reference sample count (no jitter, colour only)"

    def execute(self, context):
        scene, s = context.scene, context.scene.crisp
        try:
            out = os.path.join(output_folder.out_dir(scene, writing=True), "reference")
            pipeline.check_output_dir(out)
            infos = render.render_reference(scene, _frames(scene), out, s.reference_samples,
                                            view_layer=context.view_layer)
        except (pipeline.InputError, render.RenderError, output_folder.UnsavedFile, OSError) as e:
            return _fail(self, e)
        mean = sum(i["render_s"] for i in infos) / max(len(infos), 1)
        _done(self, scene, "Crisp: %d reference frames at %d samples (%.2f s/frame)"
              % (len(infos), s.reference_samples, mean))
        return {"FINISHED"}


class CRISP_OT_compare(bpy.types.Operator):
    bl_idname = "crisp.compare"
    bl_label = "Compare"
    bl_options = UNDOABLE
    bl_description = "PSNR and SSIM of the filtered frames against the reference frames (through libcrisp)"

    def execute(self, context):
        scene, s = context.scene, context.scene.crisp
        try:
            out = output_folder.out_dir(scene, writing=False)
            res = pipeline.compare_dirs(os.path.join(out, "filtered"), os.path.join(out, "reference"),
                                        _frames(scene), preferences.threads(context))
        except (pipeline.InputError, native.CrispError, output_folder.UnsavedFile) as e:
            return _fail(self, e)
        s.last_psnr, s.last_ssim = res["mean"]["psnr"], res["mean"]["ssim"]
        s.last_compare = "%d frames: PSNR %.2f dB, SSIM %.4f" % (len(res["frames"]), s.last_psnr, s.last_ssim)
        self.report({"INFO"}, "Crisp: " + s.last_compare)
        return {"FINISHED"}


class CRISP_OT_load_result(bpy.types.Operator):
    bl_idname = "crisp.load_result"
    bl_label = "Load into Compositor"
    bl_options = UNDOABLE
    bl_description = "Load the filtered sequence into this scene's compositor node group 'Crisp Result: <scene>'"

    def execute(self, context):
        scene = context.scene
        try:
            out = output_folder.out_dir(scene, writing=False)
            compositor.load_result(scene, os.path.join(out, "filtered"), scene.frame_start, scene.frame_end)
        except (OSError, output_folder.UnsavedFile) as e:
            return _fail(self, e)
        warnings = pipeline.sequence_warnings(out, list(range(scene.frame_start, scene.frame_end + 1)))
        if warnings:  # loaded all the same: the user sees what they have, and why it may not be one run
            self.report({"WARNING"}, "Crisp: " + "; ".join(warnings))
        return {"FINISHED"}


class CRISP_OT_preview(bpy.types.Operator):
    bl_idname = "crisp.preview"
    bl_label = "Preview Frame"
    bl_options = UNDOABLE
    bl_description = "Show the current frame's filtered image in the Image Editor"

    def execute(self, context):
        scene = context.scene
        try:
            folder = os.path.join(output_folder.out_dir(scene, writing=False), "filtered")
        except output_folder.UnsavedFile as e:
            return _fail(self, e)
        path = os.path.join(folder, render.frame_name(scene.frame_current, ".png"))
        if not os.path.isfile(path):
            path = os.path.join(folder, render.frame_name(scene.frame_current))
        try:
            compositor.preview(path, context)
        except OSError as e:
            return _fail(self, e)
        return {"FINISHED"}


CLASSES = (CRISP_OT_plan, CRISP_OT_render, CRISP_OT_render_reference, CRISP_OT_compare, CRISP_OT_load_result,
           CRISP_OT_preview)


def register():
    for c in CLASSES:
        bpy.utils.register_class(c)


def unregister():
    for c in reversed(CLASSES):
        bpy.utils.unregister_class(c)
