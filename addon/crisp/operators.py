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
        # The plan holds without a camera or with non-square pixels, but the render would be refused:
        # say so now rather than when the artist renders.
        try:
            problem = render.camera_problem(scene, list(_frames(scene)))
            if problem:
                raise pipeline.InputError(problem)
            pipeline.check_camera_shifts(scene, [s.method])
        except pipeline.InputError as e:
            self.report({"WARNING"}, "Crisp: a render would be refused: %s" % e)
        return {"FINISHED"}


class _FrameByFrame:
    """An operator that renders the frame range through a generator, steps(context), which yields after each
    frame and returns the operator's result. Run from a script (EXEC_DEFAULT, also in background mode) it
    runs to the end in execute. Clicked (INVOKE_DEFAULT) it runs a frame per timer tick: Blender draws
    between frames (the progress, the frames written), takes no other input in any window (the other windows
    through CRISP_OT_hold_window), and Esc in any of them stops the run after
    the frame being rendered, as Blender's own animation render does. The steps record a stop the same way
    either way (run.json "cancelled at frame N")."""

    # ReferenceError: the scene deleted while the run waited between frames (render.Snapshot.restore).
    ERRORS = (pipeline.InputError, render.RenderError, native.CrispError, output_folder.UnsavedFile, OSError,
              ReferenceError)
    running = None  # the run going on in this Blender (one at a time: they would share the scene's settings)

    def _second_run(self):
        """The refusal of a run while another runs, or None."""
        if _FrameByFrame.running is None:
            return None
        return _fail(self, "a Crisp render is running already; press Esc to stop it")

    @staticmethod
    def clicked_run():
        """The clicked run still stepping (not yet closed), or None."""
        running = _FrameByFrame.running
        return running if running is not None and getattr(running, "_steps", None) is not None else None

    def execute(self, context):
        refused = self._second_run()
        if refused:
            return refused
        self.stop_asked = False
        _FrameByFrame.running = self
        try:
            return render.drain(self.steps(context))
        except self.ERRORS as e:
            return _fail(self, e)
        finally:
            _FrameByFrame.running = None

    def invoke(self, context, event):
        if bpy.app.background or context.window is None:
            return self.execute(context)
        refused = self._second_run()
        if refused:
            return refused
        self.stop_asked = False
        self._steps = self.steps(context)
        self._made, self._total = 0, len(_frames(context.scene))
        self._status(context, self._progress_text())
        wm = context.window_manager
        self._timer = wm.event_timer_add(0.01, window=context.window)
        wm.modal_handler_add(self)
        _FrameByFrame.running = self
        for window in wm.windows:  # the other windows take no input either, but Esc
            if window != context.window:
                with context.temp_override(window=window):
                    bpy.ops.crisp.hold_window("INVOKE_DEFAULT")
        return {"RUNNING_MODAL"}

    def ask_stop(self, context):
        """Esc: the run stops after the frame being rendered."""
        if not self.stop_asked:
            self.stop_asked = True
            self._status(context, "Crisp: stopping after this frame")

    def modal(self, context, event):
        if self._steps is None:  # stopped at once by a save or an undo (stop_now)
            self._end(context)
            return {"CANCELLED"}
        if event.type == "ESC" and event.value == "PRESS":
            self.ask_stop(context)
        if event.type != "TIMER":
            return {"RUNNING_MODAL"}  # no edits between frames: the scene holds the run's render settings
        try:
            next(self._steps)
            self._made += 1
            if not self.stop_asked:
                self._status(context, self._progress_text())
        except StopIteration as done:
            self._end(context)
            return done.value
        except self.ERRORS as e:
            self._end(context)
            return _fail(self, e)
        except BaseException:
            self._end(context)
            raise
        return {"RUNNING_MODAL"}

    def cancel(self, context):
        """Blender ends the operator (a file loaded, the window closed): the steps put the scene back and
        record the stop."""
        self._end(context)
        self._close_steps()

    def stop_now(self, why):
        """Stops the run between frames, at once: the steps put the scene back and record the stop
        (run.json "cancelled at frame N"); the next event ends the operator."""
        self._close_steps()
        self.report({"WARNING"}, "Crisp: %s stopped by %s" % (self.bl_label, why))

    def _close_steps(self):
        """Closes the steps between frames (they put the scene back and record the stop), once."""
        steps, self._steps = self._steps, None
        if steps is not None:
            try:
                steps.close()
            except self.ERRORS as e:
                print("Crisp: %s" % e)

    def _progress_text(self):
        return "Crisp: %s, %d of %d frames made; Esc stops after the frame being rendered" % (
            self.bl_label, self._made, self._total)

    def _end(self, context):
        context.window_manager.event_timer_remove(self._timer)
        self._status(context, None)
        _FrameByFrame.running = None

    @staticmethod
    def _status(context, text):
        if context.workspace is not None:
            context.workspace.status_text_set(text)


class CRISP_OT_hold_window(bpy.types.Operator):
    """Takes the input of a window other than the one a clicked run was started in, until the run ends: an
    edit there would go into an undo step while the scene holds the run's render settings. Esc there stops
    the run as in the run's own window."""
    bl_idname = "crisp.hold_window"
    bl_label = "Crisp Render Running"
    bl_options = {"INTERNAL"}
    holding = []  # timers of the windows held, for unregister(), which frees these without cancel()

    def invoke(self, context, event):
        self._run = _FrameByFrame.running
        if self._run is None:
            return {"CANCELLED"}
        self._timer = context.window_manager.event_timer_add(0.1, window=context.window)
        CRISP_OT_hold_window.holding.append(self._timer)
        context.window_manager.modal_handler_add(self)
        return {"RUNNING_MODAL"}

    def modal(self, context, event):
        if _FrameByFrame.running is not self._run:
            self.cancel(context)
            return {"CANCELLED"}
        if event.type == "ESC" and event.value == "PRESS":
            self._run.ask_stop(context)
        return {"RUNNING_MODAL"}

    def cancel(self, context):
        if self._timer in CRISP_OT_hold_window.holding:
            CRISP_OT_hold_window.holding.remove(self._timer)
            context.window_manager.event_timer_remove(self._timer)
        _FrameByFrame._status(context, None)  # an Esc here may have said "stopping" in this window's workspace


def _stopped_note(result):
    """' (stopped before frame N)' for a run stopped by Esc (run.json "cancelled at frame N"), else ''."""
    status = result.get("status", "")
    return " (stopped before %s)" % status[len("cancelled at "):] if status.startswith("cancelled at ") else ""


class CRISP_OT_render(_FrameByFrame, bpy.types.Operator):
    bl_idname = "crisp.render"
    bl_label = "Render with Crisp"
    bl_options = UNDOABLE
    bl_description = ("Render the frame range at 1 sample with the planned passes and filter each frame "
                      "(Esc stops after the frame being rendered)")

    def steps(self, context):
        scene, s = context.scene, context.scene.crisp
        out = output_folder.out_dir(scene, writing=True)
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
            result = yield from pipeline.iter_run(
                scene, s.method, frames, out, params=props.changed_params(s, s.method),
                threads=preferences.threads(context), jitter_distribution=s.jitter_distribution,
                write_png=s.write_png, log=log, view_layer=context.view_layer, should_cancel=lambda: self.stop_asked,
                input_codec=s.input_codec)
            s.plan_text = "\n".join(
                ["plan for %s:" % s.method] + ["  + %s: %s" % (p, result["plan"]["reasons"][p])
                                               for p in result["plan"]["passes"]])
            made = [e["frame"] for e in result["frames"]]
            if s.load_result and made:
                filtered = os.path.join(out, "filtered")
                compositor.load_result(scene, filtered, frames[0], made[-1], layer=result["view_layer"])
                unwired = compositor.output_note(scene, filtered, after_run=True)
                if unwired:
                    log("note: " + unwired)
        except self.ERRORS:
            _report_notes(self, notes)  # what the run said before it failed still holds
            raise
        finally:
            wm.progress_end()
        how = "copied unfiltered (method none)" if s.method == "none" else "filtered with %s" % s.method
        n = _report_notes(self, notes)
        count = len(result["frames"])
        _done(self, scene, "Crisp: %d frame%s %s into %s%s%s" % (
            count, "s" * (count != 1), how, out, _stopped_note(result),
            "; %d note%s in the Info editor" % (n, "s" * (n > 1)) if n else ""))
        return {"FINISHED"}


class CRISP_OT_render_reference(_FrameByFrame, bpy.types.Operator):
    bl_idname = "crisp.render_reference"
    bl_label = "Render Reference"
    bl_options = UNDOABLE
    bl_description = ("Render the frame range with the reference sample count (no jitter, colour only; "
                      "Esc stops after the frame being rendered)")

    def steps(self, context):
        scene, s = context.scene, context.scene.crisp
        out = os.path.join(output_folder.out_dir(scene, writing=True), "reference")
        pipeline.check_output_dir(out)
        frames = list(_frames(scene))
        # What the reference leaves out of the scene's own render, as Render with Crisp says it.
        _report_notes(self, pipeline.scene_notes(scene, frames, render.default_view_layer(scene, context.view_layer),
                                                 made="rendered"))
        infos = yield from render.iter_render_reference(scene, frames, out, s.reference_samples,
                                                        view_layer=context.view_layer,
                                                        should_cancel=lambda: self.stop_asked, codec=s.input_codec)
        mean = sum(i["render_s"] for i in infos) / max(len(infos), 1)
        stopped = " (stopped at frame %d)" % frames[len(infos)] if len(infos) < len(frames) else ""
        _done(self, scene, "Crisp: %d reference frame%s at %d samples (%.2f s/frame)%s"
              % (len(infos), "s" * (len(infos) != 1), s.reference_samples, mean, stopped))
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
        # A mean over frames of several runs (another method, other settings) or with frames left out
        # is not one run's figure: said as Load into Compositor says it.
        warnings = pipeline.sequence_warnings(out, _frames(scene))
        if res["no_reference"]:
            warnings.append("%s no reference frame (Render Reference)"
                            % pipeline.listed_frames(res["no_reference"], ("has", "have")))
        if warnings:
            s.last_compare += " (not one run: see the warning)"
            self.report({"WARNING"}, "Crisp: " + "; ".join(warnings))
        return {"FINISHED"}


class CRISP_OT_load_result(bpy.types.Operator):
    bl_idname = "crisp.load_result"
    bl_label = "Load into Compositor"
    bl_options = UNDOABLE
    bl_description = ("Load the filtered sequence into this scene's compositor node group 'Crisp Result: <scene>', "
                      "linked into Composite where that takes the render straight (Blender's default compositor)")

    def execute(self, context):
        scene = context.scene
        try:
            out = output_folder.out_dir(scene, writing=False)
            filtered = os.path.join(out, "filtered")
            compositor.load_result(scene, filtered, scene.frame_start, scene.frame_end,
                                   layer=render.default_view_layer(scene, context.view_layer).name)
        except (OSError, output_folder.UnsavedFile) as e:
            return _fail(self, e)
        warnings = pipeline.sequence_warnings(out, list(range(scene.frame_start, scene.frame_end + 1)))
        if warnings:  # loaded all the same: the user sees what they have, and why it may not be one run
            self.report({"WARNING"}, "Crisp: " + "; ".join(warnings))
        unwired = compositor.output_note(scene, filtered)
        if unwired:  # the artist's tree, not rewired: how to connect it
            self.report({"WARNING"}, "Crisp: " + unwired)
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


CLASSES = (CRISP_OT_plan, CRISP_OT_render, CRISP_OT_render_reference, CRISP_OT_hold_window, CRISP_OT_compare,
           CRISP_OT_load_result, CRISP_OT_preview)


@bpy.app.handlers.persistent
def _stop_before_save(*_args):
    _stop_clicked_run("a save (the file keeps the scene's own settings)")


@bpy.app.handlers.persistent
def _stop_before_undo(*_args):
    _stop_clicked_run("an undo or redo")


def _stop_clicked_run(why):
    """A save, undo or redo during a clicked run: made in another window (the run's own takes no input) or
    by a script. The scene holds the run's render settings between frames, so the save would write them
    into the file, and an undo would read the scene again under the run: it stops first."""
    running = _FrameByFrame.clicked_run()
    if running is not None:
        running.stop_now(why)


_HANDLERS = ((bpy.app.handlers.save_pre, _stop_before_save), (bpy.app.handlers.undo_pre, _stop_before_undo),
             (bpy.app.handlers.redo_pre, _stop_before_undo))


def register():
    for c in CLASSES:
        bpy.utils.register_class(c)
    for handlers, handler in _HANDLERS:
        handlers.append(handler)


def unregister():
    for handlers, handler in _HANDLERS:
        if handler in handlers:
            handlers.remove(handler)
    # Blender frees a running operator of a class unregistered (the add-on disabled in the Preferences
    # window during a clicked run) without calling its cancel(): the run would keep the scene's render
    # settings and run.json "running", and every later run would be refused as one already running.
    running = _FrameByFrame.clicked_run()
    if running is not None:
        try:
            running.cancel(bpy.context)
        except Exception as e:  # the classes go all the same
            print("Crisp: stopping the run: %s" % e)
        _FrameByFrame.running = None
    for timer in CRISP_OT_hold_window.holding:
        bpy.context.window_manager.event_timer_remove(timer)
    CRISP_OT_hold_window.holding.clear()
    for c in reversed(CLASSES):
        bpy.utils.unregister_class(c)
