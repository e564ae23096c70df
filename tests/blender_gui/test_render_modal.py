# SPDX-License-Identifier: GPL-2.0-or-later
# xvfb-screen: 640x400x24
# blender-args: --enable-event-simulate
"""Render with Crisp and Render Reference clicked in Blender's window (INVOKE_DEFAULT) render a frame per
timer tick: Blender keeps drawing between frames, Esc stops the run after the frame being rendered, and
the scene gets its settings back however the run ends. They used to block the window until the last
frame, with no way to stop short of killing Blender.

The Esc is simulated (Window.event_simulate, which needs --enable-event-simulate: Blender then ignores
real input, as a test wants)."""

import ctypes
import json
import os
import sys
import tempfile

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import gui_harness  # noqa: E402

import bpy  # noqa: E402

import crisp  # noqa: E402
from crisp import operators  # noqa: E402

bpy.context.preferences.view.show_splash = False
os.environ.setdefault("CRISP_LIBRARY", gui_harness.LIBRARY)
crisp.register()
TMP = tempfile.mkdtemp(prefix="crisp_modal_")


def settings(scene):
    """What a run changes while it renders and must put back."""
    return (scene.eevee.taa_render_samples, scene.render.filepath, scene.render.image_settings.file_format,
            bpy.context.view_layer.use_pass_z, scene.camera.data.shift_x, scene.frame_current)


def small_scene(name, first, last, method="fxaa"):
    scene = bpy.context.scene
    scene.render.resolution_x, scene.render.resolution_y, scene.render.resolution_percentage = 32, 18, 100
    scene.frame_start, scene.frame_end = first, last
    scene.frame_current = first
    scene.crisp.method = method
    scene.crisp.output_dir = os.path.join(TMP, name)
    scene.crisp.load_result = False
    scene.crisp.write_png = False
    return scene


def record(scene):
    path = os.path.join(scene.crisp.output_dir, "run.json")
    if not os.path.isfile(path):
        return {}
    with open(path) as f:
        try:
            return json.load(f)
        except ValueError:  # being replaced: read it on the next tick
            return {}


def invoke(operator):
    window = bpy.context.window_manager.windows[0]
    with bpy.context.temp_override(window=window):
        return operator("INVOKE_DEFAULT")


class Console:
    """What Blender prints (the operators' reports are printed as they are made, "Info: ...", "Error: ..."),
    captured at file descriptor 1 from start() until text(); Blender's C stdio and Python's both write there."""

    def __init__(self):
        self.libc = ctypes.CDLL(None)
        self.file = tempfile.TemporaryFile(mode="w+b")
        self.saved = None

    def _flush(self):
        sys.stdout.flush()
        self.libc.fflush(None)

    def start(self):
        self._flush()
        self.file.seek(0)
        self.file.truncate()
        self.saved = os.dup(1)
        os.dup2(self.file.fileno(), 1)

    def text(self):
        """What was printed since start(), also echoed to the real output."""
        self._flush()
        os.dup2(self.saved, 1)
        os.close(self.saved)
        self.file.seek(0)
        printed = self.file.read().decode(errors="replace")
        sys.stdout.write(printed)
        return printed


CONSOLE = Console()


def filtered(scene):
    folder = os.path.join(scene.crisp.output_dir, "filtered")
    return sorted(f for f in os.listdir(folder) if f.endswith(".exr")) if os.path.isdir(folder) else []


def wait_for_the_run_to_end():
    while operators._FrameByFrame.running is not None:
        yield 0.05


def clicked_render_draws_between_frames():
    """The click returns at once; Blender's timers (and so its drawing) run while frames are made; the run
    ends complete, with every frame filtered and the scene's settings as they were."""
    assert operators._FrameByFrame.running is None
    scene = small_scene("clicked", 1, 4, method="taa")
    before = settings(scene)
    CONSOLE.start()
    assert invoke(bpy.ops.crisp.render) == {"RUNNING_MODAL"}
    ticks_mid_run = 0
    while operators._FrameByFrame.running is not None:
        made = len(record(scene).get("frames", []))
        ticks_mid_run += 1 <= made < 4
        yield 0.05
    printed = CONSOLE.text()
    run = record(scene)
    assert run["status"] == "complete", run.get("status")
    assert [e["frame"] for e in run["frames"]] == [1, 2, 3, 4], run["frames"]
    assert filtered(scene) == ["frame_0001.exr", "frame_0002.exr", "frame_0003.exr", "frame_0004.exr"]
    assert ticks_mid_run >= 2, "Blender ran no timer between frames (%d ticks)" % ticks_mid_run
    assert settings(scene) == before, (settings(scene), before)
    assert "Info: Crisp: 4 frames filtered with taa into %s\n" % scene.crisp.output_dir in printed


def esc_stops_after_the_frame_being_rendered():
    """Esc pressed after the first frame: the run stops after the frame being rendered, says so in run.json
    and in its report, writes no later frame, and leaves the scene as it was."""
    assert operators._FrameByFrame.running is None
    scene = small_scene("esc", 1, 8)
    before = settings(scene)
    CONSOLE.start()
    assert invoke(bpy.ops.crisp.render) == {"RUNNING_MODAL"}
    while len(record(scene).get("frames", [])) < 1:
        yield 0.02
    bpy.context.window_manager.windows[0].event_simulate(type="ESC", value="PRESS")
    yield from wait_for_the_run_to_end()
    printed = CONSOLE.text()
    run = record(scene)
    made = [e["frame"] for e in run["frames"]]
    assert 1 <= len(made) <= 3 and run["status"] == "cancelled at frame %d" % (made[-1] + 1), run
    assert filtered(scene) == ["frame_%04d.exr" % f for f in made], filtered(scene)
    assert settings(scene) == before, (settings(scene), before)
    assert "filtered with fxaa into %s (stopped before frame %d)" % (scene.crisp.output_dir, made[-1] + 1) in printed


def a_second_run_is_refused_while_one_runs():
    """The window takes no clicks during a run, but a script (or another window) could start a second run on
    the same scene's settings: it is refused, and the first one goes on to the end."""
    assert operators._FrameByFrame.running is None
    scene = small_scene("twice", 1, 3)
    assert invoke(bpy.ops.crisp.render) == {"RUNNING_MODAL"}
    yield 0.05
    for second in (lambda: invoke(bpy.ops.crisp.render_reference), bpy.ops.crisp.render):
        try:
            second()
        except RuntimeError as e:  # an operator's error report, raised to the script that called it
            assert "a Crisp render is running already; press Esc to stop it" in str(e), e
        else:
            raise AssertionError("a second run started")
    yield from wait_for_the_run_to_end()
    assert record(scene)["status"] == "complete"


def reference_render_stops_on_esc():
    """Render Reference, clicked, also runs a frame per tick and stops on Esc, with the scene put back."""
    assert operators._FrameByFrame.running is None
    scene = small_scene("reference", 1, 8)
    scene.crisp.reference_samples = 2
    before = settings(scene)
    folder = os.path.join(scene.crisp.output_dir, "reference")
    CONSOLE.start()
    assert invoke(bpy.ops.crisp.render_reference) == {"RUNNING_MODAL"}
    while not (os.path.isdir(folder) and os.listdir(folder)):
        yield 0.02
    bpy.context.window_manager.windows[0].event_simulate(type="ESC", value="PRESS")
    yield from wait_for_the_run_to_end()
    printed = CONSOLE.text()
    made = sorted(f for f in os.listdir(folder) if f.endswith(".exr"))
    assert 1 <= len(made) <= 3, made
    assert settings(scene) == before, (settings(scene), before)
    assert "Info: Crisp: %d reference frame%s at 2 samples" % (len(made), "s" * (len(made) > 1)) in printed
    assert "(stopped at frame %d)" % (len(made) + 1) in printed


def disabling_the_add_on_mid_run_ends_it():
    """The add-on disabled during a run (in the Preferences window, which takes input while the run's window
    does not): Blender frees the running operator without calling its cancel(). The run is closed first:
    the scene gets its settings back, run.json says where it stopped, and the add-on enabled again renders
    (it used to refuse every run as 'a Crisp render is running already')."""
    assert operators._FrameByFrame.running is None
    scene = small_scene("disabled", 1, 8)
    before = settings(scene)
    out = scene.crisp.output_dir
    assert invoke(bpy.ops.crisp.render) == {"RUNNING_MODAL"}
    while not os.path.isfile(os.path.join(out, "filtered", "frame_0001.exr")):
        yield 0.02
    crisp.unregister()
    yield 0.2
    crisp.register()
    assert operators._FrameByFrame.running is None
    assert settings(scene) == before, (settings(scene), before)
    with open(os.path.join(out, "run.json")) as f:
        status = json.load(f)["status"]
    assert status.startswith("cancelled at frame "), status
    scene.crisp.output_dir = os.path.join(TMP, "enabled_again")
    assert invoke(bpy.ops.crisp.render) == {"RUNNING_MODAL"}
    yield from wait_for_the_run_to_end()
    assert record(scene)["status"] == "complete", record(scene)


def the_scene_deleted_mid_run_ends_it():
    """The run's scene deleted between frames (by a script, or in another window): the run ends with an
    error report, not an exception out of the operator, and its restore touches nothing of the freed scene
    (writing into it could crash Blender) while what other data holds (the camera's jittered shift) is put
    back."""
    assert operators._FrameByFrame.running is None
    scene = small_scene("deleted", 1, 8, method="taa")
    camera = scene.camera.data
    shift = camera.shift_x
    other = bpy.data.scenes.new("Other")
    out = scene.crisp.output_dir
    raised, hook = [], sys.excepthook  # Blender prints an exception out of an operator through it
    sys.excepthook = lambda *exc: raised.append(exc[1]) or hook(*exc)
    try:
        assert invoke(bpy.ops.crisp.render) == {"RUNNING_MODAL"}
        while not os.path.isfile(os.path.join(out, "filtered", "frame_0001.exr")):
            yield 0.02
        bpy.context.window_manager.windows[0].scene = other
        bpy.data.scenes.remove(scene)
        yield from wait_for_the_run_to_end()
    finally:
        sys.excepthook = hook
    assert not raised, raised
    assert camera.shift_x == shift, (camera.shift_x, shift)
    with open(os.path.join(out, "run.json")) as f:
        status = json.load(f)["status"]
    assert status == "failed: StructRNA of type Scene has been removed", status


def saved_file_settings(blend):
    """settings() of the scene of a saved file, read by another Blender."""
    import subprocess
    expr = ("import bpy; s = bpy.context.scene; print('SETTINGS', repr((s.eevee.taa_render_samples, "
            "s.render.filepath, s.render.image_settings.file_format, s.view_layers[0].use_pass_z, "
            "s.camera.data.shift_x, s.frame_current)))")
    out = subprocess.run([bpy.app.binary_path, "-b", "--factory-startup", blend, "--python-expr", expr],
                         capture_output=True, text=True).stdout
    return eval(next(line for line in out.splitlines() if line.startswith("SETTINGS "))[len("SETTINGS "):])


def a_save_or_an_undo_mid_run_stops_it_first():
    """Only the run's window takes no input: a save or an undo in another window (or by a script) during
    a run wrote the run's render settings into the file (1 sample, its EXR format and temporary path, its
    passes), or read the scene again under the run (which then failed on a removed scene). The run now
    stops first, with the scene's settings back: the file holds the user's, and run.json says where the
    run stopped."""
    assert operators._FrameByFrame.running is None
    blend = os.path.join(TMP, "saved_mid_run.blend")
    bpy.ops.wm.save_as_mainfile(filepath=blend)
    for name, act in (("save", lambda: bpy.ops.wm.save_mainfile()), ("undo", lambda: bpy.ops.ed.undo())):
        scene = small_scene("stopped_by_" + name, 1, 8, method="taa")
        bpy.ops.ed.undo_push(message="before the run")
        before = settings(scene)
        out = scene.crisp.output_dir
        assert invoke(bpy.ops.crisp.render) == {"RUNNING_MODAL"}
        while not os.path.isfile(os.path.join(out, "filtered", "frame_0001.exr")):
            yield 0.02
        with bpy.context.temp_override(window=bpy.context.window_manager.windows[0]):
            act()
        yield from wait_for_the_run_to_end()
        with open(os.path.join(out, "run.json")) as f:
            status = json.load(f)["status"]
        assert status.startswith("cancelled at frame "), (name, status)
        assert settings(bpy.context.scene) == before, (name, settings(bpy.context.scene), before)
        if name == "save":
            assert saved_file_settings(blend) == before, (saved_file_settings(blend), before)


def another_window_takes_no_input_but_esc():
    """A second window during a run: a key there does nothing (it would go into an undo step while the scene
    holds the run's settings: Ctrl-Z after the run brought them back), and Esc there stops the run as in the
    run's own window. (Before: 'A' selected everything there, and the run went on to the end.)"""
    assert operators._FrameByFrame.running is None
    with bpy.context.temp_override(window=bpy.context.window_manager.windows[0]):
        bpy.ops.wm.window_new()
    yield 0.5
    second = bpy.context.window_manager.windows[-1]
    view = max((a for a in second.screen.areas if a.type == "VIEW_3D"), key=lambda a: a.width * a.height)
    for obj in bpy.context.scene.objects:
        obj.select_set(False)
    scene = small_scene("second_window", 1, 8)
    before = settings(scene)
    assert invoke(bpy.ops.crisp.render) == {"RUNNING_MODAL"}
    while len(record(scene).get("frames", [])) < 1:
        yield 0.02
    second.event_simulate(type="MOUSEMOVE", value="NOTHING", x=view.x + view.width // 2, y=view.y + view.height // 2)
    second.event_simulate(type="A", value="PRESS")
    second.event_simulate(type="A", value="RELEASE")
    yield 0.1
    second.event_simulate(type="ESC", value="PRESS")
    yield from wait_for_the_run_to_end()
    run = record(scene)
    assert run["status"] == "cancelled at frame %d" % (run["frames"][-1]["frame"] + 1) and len(run["frames"]) <= 4, run
    assert not any(obj.select_get() for obj in scene.objects), [o.name for o in scene.objects if o.select_get()]
    assert settings(scene) == before, (settings(scene), before)
    yield 0.3  # the second window's hold ends at its next tick: it takes input again
    second.event_simulate(type="MOUSEMOVE", value="NOTHING", x=view.x + view.width // 2, y=view.y + view.height // 2)
    second.event_simulate(type="A", value="PRESS")
    second.event_simulate(type="A", value="RELEASE")
    yield 0.3
    assert all(obj.select_get() for obj in scene.objects if obj.visible_get()), "the window takes input again"
    with bpy.context.temp_override(window=second):
        bpy.ops.wm.window_close()
    yield 0.3


def a_file_loaded_mid_run_ends_it():
    """Blender ends a running operator when a file is loaded: the run is recorded as stopped, and the
    loaded file renders nothing more."""
    assert operators._FrameByFrame.running is None
    scene = small_scene("loaded", 1, 8)
    out = scene.crisp.output_dir
    assert invoke(bpy.ops.crisp.render) == {"RUNNING_MODAL"}
    while not os.path.isfile(os.path.join(out, "filtered", "frame_0001.exr")):
        yield 0.02
    window = bpy.context.window_manager.windows[0]
    with bpy.context.temp_override(window=window):
        bpy.ops.wm.read_homefile(use_empty=False)
    yield 0.5
    assert operators._FrameByFrame.running is None
    with open(os.path.join(out, "run.json")) as f:
        run = json.load(f)
    assert run["status"].startswith("cancelled at frame "), run["status"]
    assert run["total_s"] > 0, "as a run stopped by Esc records it"
    made = sorted(f for f in os.listdir(os.path.join(out, "filtered")) if f.endswith(".exr"))
    yield 1.0
    assert sorted(f for f in os.listdir(os.path.join(out, "filtered")) if f.endswith(".exr")) == made


gui_harness.run_scenarios(clicked_render_draws_between_frames, esc_stops_after_the_frame_being_rendered,
                          a_second_run_is_refused_while_one_runs, reference_render_stops_on_esc,
                          disabling_the_add_on_mid_run_ends_it, a_save_or_an_undo_mid_run_stops_it_first,
                          another_window_takes_no_input_but_esc, a_file_loaded_mid_run_ends_it,
                          the_scene_deleted_mid_run_ends_it)
