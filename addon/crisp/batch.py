# SPDX-License-Identifier: GPL-2.0-or-later
"""Headless Crisp driver, run inside Blender (this is what `crisp render` runs):

    blender -b [SCENE.blend] --factory-startup --python-exit-code 1 --python <repo>/addon/crisp/batch.py -- \\
        -o OUTDIR [--frames A-B] [--preroll N] [--shot A-B] [--resume] [--method NAME] [--set K=V ...]
        [--samples 1] [--reference-samples N] [--resolution WxH] [--scene-script test_scenes/NAME.py | NAME]
        [--scene-name NAME]
        [--plan-only] [--no-filter] [--no-png] [--threads N] [--library PATH] [--jitter blackman-harris|uniform]
        [--input-codec none|piz|zip] [--engine eevee|cycles]

Arguments (after Blender's `--`):
  -o, --output OUTDIR      where everything goes (created; must be writable); //NAME is NAME beside
                           the opened .blend, as in Blender
  --frames A-B | A         frame range (default: the scene's)
  --preroll N              a farm chunk: first render and filter the N frames before --frames (not
                           before the shot's first frame) to warm the temporal history; they are
                           rendered to a temporary folder, deleted afterwards, and never written to
                           input/ or filtered/ (an input already in input/ is read instead)
  --shot A-B | A           the whole shot a chunk belongs to (default with --preroll: the scene's
                           range): the pass plan is made over it and pre-roll stops at its start;
                           results go to run_AAAA-BBBB.json instead of run.json
  --resume                 start at the first frame whose input or outputs are missing
  --method NAME            none, fxaa, repair, taa, taa-improved, phlm, rsaa (default: the scene's Crisp
                           panel's Method when it was set in the .blend, else fxaa)
  --set K=V                a filter parameter, typed by the library's parameter table; repeatable; each
                           one replaces the panel's value of that parameter (panel_settings)
  --samples N              EEVEE samples of the input frames (default 1)
  --reference-samples N    also render OUTDIR/reference/ with N samples (default 0: none)
  --resolution WxH         override the render size (100 %)
  --scene-script PATH|NAME build the scene with a Python script first (NAME: test_scenes/NAME.py);
                           without it the .blend opened by Blender is used as is
  --scene-name NAME        the scene Blender was told to open (-S NAME before --python): checked to be
                           the open one, else exit 2 listing the file's scenes
  --plan-only              print the pass plan, write run.json, render nothing
  --no-filter              render the inputs only (no library needed)
  --no-png                 do not write filtered PNGs next to the EXRs
  --threads N              library threads (0: all cores)
  --library PATH           libcrisp.so to use (else $CRISP_LIBRARY, else <repo>/build/lib/libcrisp.so)
  --jitter DIST            sub-pixel jitter distribution of temporal methods (default: the panel's Jitter
                           when it was set in the .blend, else blackman-harris)
  --input-codec NAME       OpenEXR codec of input/ and reference/: none (fastest), piz or zip (about 4.5x
                           smaller at 0.1-0.2 s more a 1080p frame; all lossless, render.INPUT_CODECS);
                           default: the panel's Input Codec when it was set in the .blend, else none
  --no-panel               ignore the scene's Crisp panel: the command line and the library's defaults only
                           (the Flamenco job type passes it: its fields took the panel at submission)
  --engine eevee|cycles    renderer of the input frames (default eevee); cycles renders the same frames
                           cheaply (1 sample, 0.01 px box filter, no denoising) with its own Vector pass,
                           to check reconstructed motion against it

The scene's Crisp panel (scene.crisp, properties.py), as saved in the .blend, gives what the command
line leaves out: the method, jitter and input codec when the file set them, and the panel's parameters
of the method that runs (given or not) that differ from the library's defaults, under --set key by key.
A scene whose panel was never touched, or a run with --no-panel, runs fxaa with blackman-harris,
uncompressed inputs and the library's defaults where the command line says nothing. One line says
what came from the panel.

Writes OUTDIR/input/frame_NNNN.exr + .json, OUTDIR/filtered/frame_NNNN.exr (+ .png),
OUTDIR/reference/frame_NNNN.exr when asked, and OUTDIR/run.json (see pipeline.py), each through a
temporary name renamed into place. The opened .blend is never saved.

Exit codes: 0 done; 2 bad input (no camera, empty frame range, unwritable output, unknown method,
bad arguments); 3 library missing or failing; 4 render failed, a file could not be written, or
stopped by Ctrl-C, SIGTERM or SIGHUP (after the frame it was on); 5 a filter parameter's value
refused by the library (the panel's or --set's; crisp render exits 1 for it, as for a --set it refuses
before Blender starts).
Messages start with "crisp: error:".
"""

import argparse
import os
import re
import sys

ADDON_DIR = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
REPO_DIR = os.path.dirname(ADDON_DIR)
if ADDON_DIR not in sys.path:
    sys.path.insert(0, ADDON_DIR)


def _argv():
    return sys.argv[sys.argv.index("--") + 1:] if "--" in sys.argv else []


def make_parser():
    p = argparse.ArgumentParser(prog="batch.py", description="Crisp headless render driver (inside Blender)")
    p.add_argument("-o", "--output", required=True)
    p.add_argument("--frames", default="")
    p.add_argument("--preroll", type=int, default=None)  # None: not given (0 given still makes a chunk)
    p.add_argument("--shot", default="")
    p.add_argument("--resume", action="store_true")
    p.add_argument("--method", default=None)  # None: the panel's (panel_settings), else DEFAULT_METHOD
    p.add_argument("--set", dest="params", action="append", default=[], metavar="K=V")
    p.add_argument("--samples", type=int, default=1)
    p.add_argument("--reference-samples", type=int, default=0)
    p.add_argument("--resolution", default="")
    p.add_argument("--scene-script", default="")
    p.add_argument("--scene-name", default="")  # crisp render --scene-name: Blender's -S made it active
    p.add_argument("--plan-only", action="store_true")
    p.add_argument("--no-filter", action="store_true")
    p.add_argument("--no-png", action="store_true")
    p.add_argument("--threads", type=int, default=0)
    p.add_argument("--library", default="")
    p.add_argument("--jitter", default=None)  # None: the panel's, else DEFAULT_JITTER
    p.add_argument("--input-codec", default=None)  # None: the panel's (panel_codec), else none
    p.add_argument("--no-panel", action="store_true")
    p.add_argument("--engine", default="eevee")
    return p


DEFAULT_METHOD = "fxaa"
DEFAULT_JITTER = "blackman-harris"


def fail(code, message):
    print("crisp: error: " + message, file=sys.stderr, flush=True)
    sys.exit(code)


class Stopped(Exception):
    """A stop signal (SIGTERM, SIGHUP): the run ends after the frame it is on, as after Ctrl-C."""


def stop_on_signals():
    """Ctrl-C, SIGTERM and SIGHUP end the run as an exception, so its record says why it stopped and its
    pre-roll folder goes. Blender's own Ctrl-C handler only flags a render to stop and kills Blender at
    the second one (crisp passes its Ctrl-C on, so it comes twice): the first signal stops, others wait
    for that stop to finish. A signal Blender was started ignoring (nohup) stays ignored. Returns the
    run's should_cancel: it raises the stop again before each frame, as one raised in Python that Blender
    runs and reports itself (a frame change handler, a driver) goes no further."""
    import signal
    stopping = []

    def stop_exception():
        sig = stopping[0]
        return KeyboardInterrupt() if sig == signal.SIGINT else Stopped("stopped by %s" % signal.Signals(sig).name)

    def stop(sig, _frame):
        if stopping:
            return
        stopping.append(sig)
        raise stop_exception()

    def should_cancel():
        if stopping:
            raise stop_exception()
        return False
    for sig in (signal.SIGINT, signal.SIGTERM, signal.SIGHUP):
        if signal.getsignal(sig) != signal.SIG_IGN:
            signal.signal(sig, stop)
    return should_cancel


def named_scene(name):
    """The scene to run: the one Blender opened the file at, which `crisp render --scene-name` chose with
    Blender's -S; that option only warns of a name the file lacks and opens the saved scene, so a name that
    is not the open scene's fails here, listing the file's scenes."""
    import bpy
    scene = bpy.context.scene
    if name and scene.name != name:
        fail(2, "no scene '%s' in %s (its scenes: %s)" % (name, bpy.data.filepath or "this file",
                                                         ", ".join("'%s'" % s.name for s in bpy.data.scenes)))
    return scene


def active_scene_line(scene, name):
    """Blender opens a .blend at the scene it was saved with: the line that says which, when the file holds
    others and --scene-name (name) did not choose it; else None. crisp render and crisp eval say it."""
    import bpy
    from crisp import plan
    others = sorted(s.name for s in bpy.data.scenes if s != scene and s.library is None)
    if not others or name:
        return None
    return ("crisp: scene '%s', the file's active scene (others: %s; --scene-name NAME renders another)"
            % (scene.name, plan.some_names(others, quote=True)))


def scene_script_path(text):
    if os.path.isfile(text):
        return os.path.abspath(text)
    named = os.path.join(REPO_DIR, "test_scenes", text + ("" if text.endswith(".py") else ".py"))
    if os.path.isfile(named):
        return named
    known = sorted(f[:-3] for f in os.listdir(os.path.join(REPO_DIR, "test_scenes"))
                   if f.endswith(".py") and f != "common.py")
    fail(2, "scene script '%s' not found (bundled scenes: %s)" % (text, ", ".join(known)))


def imported_modules(path):
    """The modules a Python file's import statements name ("import a, b", "from a import b"), indented too."""
    names = []
    try:
        with open(path) as f:
            lines = f.read().splitlines()
    except OSError:
        return names
    for line in lines:
        words = line.split(None, 1)
        if len(words) < 2 or words[0] not in ("import", "from"):
            continue
        listed = words[1].split(" import")[0] if words[0] == "from" else words[1]
        names += [name.split()[0] for name in listed.split(",") if name.split()]
    return names


def scene_key(script_path):
    """What the scene is made of, for reuse checks (pipeline.run scene_key): a hash of the bundled
    scene's script, the test_scenes/common.py it imports and the other bundled scenes it imports
    (light_switch: still_life), or of the .blend Blender opened (as saved: call before anything changes
    the scene), of the library .blend files it links (an edited linked set or character renders other
    frames; a resume kept the old ones) and of the other files it reads (external_files: an edited
    texture); None for an unsaved scene."""
    import hashlib
    import bpy
    if script_path:
        files = [script_path, os.path.join(os.path.dirname(script_path), "common.py")]
        for path in files:  # grows: the scenes imported, through theirs (as cli/blender.cpp sceneFingerprint)
            for module in imported_modules(path):
                other = os.path.join(os.path.dirname(script_path), module + ".py")
                if os.path.isfile(other) and other not in files:
                    files.append(other)
    elif bpy.data.filepath:
        files = [bpy.data.filepath]
    else:
        return None
    h = hashlib.sha256()
    for path in files:
        if os.path.isfile(path):
            _hash_file(h, path)
    # The libraries (also those linked through others), by content in a fixed order: a file of none hashes
    # as before. One missing is named as such (Blender renders without its data).
    # (Blender keeps each library's path relative to the opened file, nested ones too.)
    libraries = sorted({os.path.normpath(bpy.path.abspath(lib.filepath)) for lib in bpy.data.libraries})
    for path in libraries:
        h.update(b"\0library\0")
        if os.path.isfile(path):
            _hash_file(h, path)
        else:
            h.update(b"missing:" + path.encode("utf-8", "surrogateescape"))
    if not script_path:
        # By size and modification time, as make and rsync tell a changed file (and crisp filter its
        # inputs): a shot's textures and plates may be gigabytes, read again by every farm task. A file of
        # none hashes as before.
        for name, path in external_files(libraries):
            try:
                st = os.stat(path)
                seen = "%d %d" % (st.st_size, st.st_mtime_ns)
            except OSError:
                seen = "missing"
            h.update(("\0file\0%s\0%s" % (name, seen)).encode("utf-8", "surrogateescape"))
    return "sha256:" + h.hexdigest()[:16]


_NUMBERED = re.compile(r"^(.*?)(\d+)(\.[^.\d][^.]*)?$")  # name, frame number, extension: seq.0001.png, .jp2


def external_files(libraries=()):
    """[(name, absolute path)] of the files outside the .blend that Blender reads (bpy.utils.blend_paths:
    images, movie clips, caches, volumes, fonts, sounds, of linked data too), sorted, each file once:
    every file of an image or movie clip sequence (beside the first, in its folder) and every tile of a
    UDIM image;
    not packed files (in the .blend), folders, nor the libraries given (hashed by content). The name is
    the path relative to the .blend's folder (also of a file beside it, ../tex/a.png), so a moved project
    keeps its names."""
    import bpy
    from crisp import compositor
    paths = {os.path.normpath(p) for p in bpy.utils.blend_paths(absolute=True, packed=False, local=False)}
    # Crisp's own filtered frames, loaded into the compositor or previewed, which every run rewrites; the
    # renders Crisp filters do not read them (it renders without the compositor, render.py).
    own = {compositor.frames_image(g) for g in bpy.data.node_groups if compositor.FOLDER_TAG in g}
    own.update(i for i in bpy.data.images if i.get(compositor.PREVIEW_TAG))
    for image in bpy.data.images:
        if image.source not in ("FILE", "SEQUENCE", "TILED") or image.packed_file is not None or not image.filepath:
            continue
        first = os.path.normpath(bpy.path.abspath(image.filepath, library=image.library))
        if image in own:
            paths.discard(first)
        elif image.source == "TILED":  # "<UDIM>" (1001...) or "<UVTILE>" (u1_v1...) in the name
            paths.discard(first)
            paths.update(first.replace("<UDIM>", str(t.number)).replace(
                "<UVTILE>", "u%d_v%d" % ((t.number - 1001) % 10 + 1, (t.number - 1001) // 10 + 1))
                for t in image.tiles)
        elif image.source == "SEQUENCE":
            paths.update(_sequence_files(first))
    for clip in bpy.data.movieclips:  # a plate as numbered images: blend_paths gives its first file alone
        if clip.source == "SEQUENCE" and clip.filepath:
            paths.update(_sequence_files(os.path.normpath(bpy.path.abspath(clip.filepath, library=clip.library))))
    paths.difference_update(os.path.normpath(p) for p in libraries)
    home = os.path.dirname(os.path.abspath(bpy.data.filepath)) if bpy.data.filepath else None

    def name(path):
        if home is None:
            return path
        try:
            return os.path.relpath(path, home)  # //../tex/a.png too: a moved project keeps its names
        except ValueError:  # another drive (Windows)
            return path
    # Files only: a folder (a fluid cache's, made when the file loads) changes its time with what is in it.
    return sorted((name(p), p) for p in paths if not os.path.isdir(p))


def _sequence_files(first):
    """The files of the numbered sequence whose first file is `first` (seq.0001.png: seq.NNNN.png beside it)."""
    def stem_and_extension(name):
        match = _NUMBERED.match(name)
        return match and (match.group(1), match.group(3))
    folder, numbered = os.path.split(first)
    want = stem_and_extension(numbered)
    if not want or not os.path.isdir(folder):
        return []
    return [os.path.join(folder, f) for f in os.listdir(folder) if stem_and_extension(f) == want]


def _hash_file(h, path):
    with open(path, "rb") as f:
        for chunk in iter(lambda: f.read(1 << 20), b""):  # a .blend may be large
            h.update(chunk)


class PanelError(Exception):
    """A setting of the scene's Crisp panel, or a --set over it, that cannot run. exit: 2 for what crisp
    render would call a usage error (an unknown method, a camera parameter for rsaa), 5 for a value the
    library refuses; crisp render exits 2 and 1 for them, as when it refuses the same on its command line
    before Blender starts."""

    def __init__(self, message, exit=2):
        super().__init__(message)
        self.exit = exit


def panel_settings(scene, method, jitter, given, use_panel=True):
    """The run's method, jitter and parameters, with what the command line leaves out taken from the
    scene's Crisp panel (scene.crisp, properties.py) as the opened .blend saved it: method and jitter
    (None: not given) when the file set them (is_property_set: a panel never touched keeps fxaa and
    blackman-harris, as before the panel was read), and the panel's parameters of the method that runs,
    whichever gave it, that differ from the library's defaults (properties.changed_params, what the
    panel's own render and the Flamenco job type send), each replaced by a --set of that name (given:
    {name: text}). Returns (method, jitter, params, from_panel): from_panel names what the panel gave,
    {"method": bool, "jitter": bool, "params": {name: text}}. The add-on's scene settings are registered
    here (Blender started with --factory-startup has no add-on), so the file's values show. use_panel
    False (--no-panel): the command line and the defaults only."""
    import bpy
    from crisp import native, properties
    from_panel = {"method": False, "jitter": False, "params": {}}
    if not use_panel:
        return method or DEFAULT_METHOD, jitter or DEFAULT_JITTER, dict(given), from_panel
    if "crisp" not in bpy.types.Scene.bl_rna.properties:
        properties.register()  # reads the library's tables, when it loads, for the methods' parameters
    settings = scene.crisp
    if method is None and settings.is_property_set("method"):
        method = settings.method
        if not method:  # a number this add-on's list does not hold (a method of a newer library)
            raise PanelError("the scene's Crisp panel (%s) has a method this library does not offer (saved as "
                             "number %s): choose one in the panel, or give --method"
                             % (panel_source(), settings.get("method")))
        from_panel["method"] = True
    if jitter is None and settings.is_property_set("jitter_distribution"):
        jitter = settings.jitter_distribution
        from_panel["jitter"] = True
    method = method or DEFAULT_METHOD
    jitter = jitter or DEFAULT_JITTER
    panel = {k: native.param_text(v) for k, v in properties.changed_params(settings, method).items()}
    from_panel["params"] = {k: v for k, v in panel.items() if k not in given}
    return method, jitter, dict(panel, **given), from_panel


def panel_codec(scene, codec, use_panel=True):
    """(the input codec, whether the scene's Crisp panel gave it): codec (None: not given) in lower case,
    else the panel's Input Codec when the opened .blend set it, else render.INPUT_CODECS[0]. After
    panel_settings, which registers the panel's settings."""
    from crisp import render
    if codec is not None or not use_panel:  # (without the panel its settings may not be registered)
        return (codec or render.INPUT_CODECS[0]).lower(), False
    settings = scene.crisp
    if settings.is_property_set("input_codec"):
        if not settings.input_codec:  # a number this add-on's menu does not hold (a newer add-on's codec)
            raise PanelError("the scene's Crisp panel (%s) has an input codec this add-on does not offer (saved as "
                             "number %s): choose one in the panel, or give --input-codec (%s)"
                             % (panel_source(), settings.get("input_codec"), ", ".join(render.INPUT_CODECS)))
        return settings.input_codec, True
    return render.INPUT_CODECS[0], False


def panel_source():
    """The file a panel's settings come from, for messages: the .blend's name."""
    import bpy
    return os.path.basename(bpy.data.filepath) or "the unsaved scene"


def check_panel_params(method, params, from_panel, given, way_out="override them with --set"):
    """The library's verdict on the run's parameters before anything renders, saying where the ones it
    names came from: PanelError naming the scene's Crisp panel when they are the panel's, else --set's
    (a --set crisp render could not check before Blender started, not knowing the method:
    cmd_render.cpp checks the command line's own values when it names the method or the scene is a
    bundled one, whose panel is never set), or both (a rule between parameters). way_out: the other
    way out of a refused panel value than the panel itself (crisp eval has no --set: --no-panel)."""
    from crisp import native, properties
    panel = from_panel["params"]
    camera = sorted(set(given) & properties.RSAA_CAMERA_PARAMS) if method == "rsaa" else []
    if camera:  # as cmd_render.cpp refuses them with --method rsaa
        raise PanelError("--set %s: rsaa takes its camera from each frame's sidecar (the camera the frame was "
                         "rendered with), which replaces any value set here" % camera[0])
    bad = native.check_params(method, params) if params else None
    if not bad:
        return

    prefix = "filter '%s': " % method  # the library's; the messages below name the method themselves
    bad = bad[len(prefix):] if bad.startswith(prefix) else bad

    def named(values):  # those the library's message names ('feedbackMin'), or all when it names none
        return {k: v for k, v in values.items() if "'%s'" % k in bad}
    from_set, from_file = named(given), named(panel)
    if not from_set and not from_file:
        from_set, from_file = given, panel
    listed = lambda values: ", ".join("%s=%s" % kv for kv in values.items())  # noqa: E731
    if from_file and not from_set:
        raise PanelError("%s's parameters from the scene's Crisp panel (%s: %s) are refused: %s; change them in the "
                         "panel (Render Properties > Crisp) or %s"
                         % (method, panel_source(), listed(from_file), bad, way_out), exit=5)
    sources = ["--set " + listed(from_set)]
    if from_file:
        sources.append("the scene's Crisp panel (%s: %s)" % (panel_source(), listed(from_file)))
    raise PanelError("%s: %s (parameters from %s)" % (method, bad, " and ".join(sources)), exit=5)


def panel_line(method, jitter, from_panel, command="render", jitters=None, codec=None):
    """The line saying what came from the panel ("" when nothing did), starting with the command's name:
    the jitter only when it is used (jitters; default: for a method that jitters, as crisp render runs
    one method), the input codec when from_panel["input_codec"], the parameters by name."""
    from crisp import plan as plan_mod
    if jitters is None:
        jitters = method in plan_mod.TEMPORAL_METHODS
    parts = []
    if from_panel["method"]:
        parts.append("method " + method)
    if from_panel["jitter"] and jitters:
        parts.append("jitter " + jitter)
    if from_panel.get("input_codec"):
        parts.append("input codec " + codec)
    params = from_panel["params"]
    if params:
        parts.append("%d parameter%s (%s)" % (len(params), "s" * (len(params) != 1),
                                              ", ".join("%s=%s" % kv for kv in params.items())))
    if not parts:
        return ""
    listed = parts[0] if len(parts) == 1 else ", ".join(parts[:-1]) + " and " + parts[-1]
    return "%s: %s from the scene's Crisp panel (%s)" % (command, listed, panel_source())


def main(argv):
    import runpy
    import bpy
    from crisp import native, pipeline, render

    class ArgError(Exception):
        pass

    stopped = stop_on_signals()
    parser = make_parser()
    parser.error = lambda msg: fail(2, msg)  # argparse would exit 2 with usage; keep one message style
    args = parser.parse_args(argv)
    if args.library:
        os.environ["CRISP_LIBRARY"] = os.path.abspath(args.library)
    if args.samples < 1 or args.reference_samples < 0:
        fail(2, "--samples must be >= 1 and --reference-samples >= 0")
    if args.preroll is not None and args.preroll < 0:
        fail(2, "--preroll must be >= 0 frames, got %d" % args.preroll)
    if args.jitter is not None and args.jitter not in render.JITTER_DISTRIBUTIONS:
        fail(2, "unknown --jitter '%s' (known: %s)" % (args.jitter, ", ".join(render.JITTER_DISTRIBUTIONS)))
    if args.input_codec is not None and args.input_codec.lower() not in render.INPUT_CODECS:
        fail(2, "unknown --input-codec '%s' (known: %s; all lossless)" % (args.input_codec,
                                                                         ", ".join(render.INPUT_CODECS)))
    if args.engine not in render.ENGINES:
        fail(2, "unknown --engine '%s' (known: %s)" % (args.engine, ", ".join(render.ENGINES)))
    params = {}
    for kv in args.params:
        if "=" not in kv:
            fail(2, "--set needs K=V, got '%s'" % kv)
        k, v = kv.split("=", 1)
        params[k.strip()] = v.strip()

    key = scene_key(scene_script_path(args.scene_script) if args.scene_script else None)
    if args.scene_script:
        path = scene_script_path(args.scene_script)
        sys.path.insert(0, os.path.dirname(path))
        runpy.run_path(path, run_name="__main__")
    scene = named_scene(args.scene_name)
    if args.resolution:
        try:
            pipeline.apply_resolution(scene, args.resolution)
        except pipeline.InputError as e:
            fail(2, str(e))

    try:
        given = params
        method, jitter, params, from_panel = panel_settings(scene, args.method, args.jitter, given,
                                                            use_panel=not args.no_panel)
        codec, from_panel["input_codec"] = panel_codec(scene, args.input_codec, use_panel=not args.no_panel)
        if not args.no_filter:
            check_panel_params(method, params, from_panel, given)
    except PanelError as e:
        fail(e.exit, str(e))
    except native.CrispError as e:
        fail(3, str(e))
    said = panel_line(method, jitter, from_panel, codec=codec)
    if said:
        print(said, flush=True)
    said = active_scene_line(scene, args.scene_name)
    if said:
        print(said, flush=True)

    try:
        out = pipeline.output_argument(args.output)
        frames = pipeline.parse_frames(args.frames, scene)
        # A chunk of a shot: the shot given, or the scene's range when only a pre-roll is asked for, also
        # --preroll 0 (a spatial method's chunk, or the first one): its record and plan are a chunk's.
        shot = pipeline.parse_frames(args.shot, scene) if args.shot or args.preroll is not None else None
        pipeline.run(scene, method, frames, out, params=params,
                     samples=args.samples, reference_samples=args.reference_samples, plan_only=args.plan_only,
                     filter_frames=not args.no_filter, threads=args.threads, jitter_distribution=jitter,
                     write_png=not args.no_png, log=lambda s: print(s, flush=True), engine_name=args.engine,
                     preroll=args.preroll or 0, shot=shot, resume=args.resume, scene_key=key,
                     should_cancel=stopped, input_codec=codec)
    except pipeline.InputError as e:
        fail(2, str(e))
    except render.RenderFailed as e:
        fail(4, str(e))
    except render.RenderError as e:
        fail(2 if "camera" in str(e) or "frame" in str(e) else 4, str(e))
    except native.CrispError as e:
        fail(3, str(e))
    except render.WriteFailed as e:  # a file of ours that could not be written (run.json on a full disk, say)
        fail(4, str(e.strerror))
    except OSError as e:  # any other file error: named, not a traceback
        where = e.filename2 or e.filename
        fail(4, "%s: %s" % (where, e.strerror or e) if where else str(e))
    print("crisp: done: %s" % out, flush=True)


if __name__ == "__main__":
    try:
        main(_argv())
    except KeyboardInterrupt:  # during the run (its record says so), or while the scene is made before it
        fail(4, "stopped by Ctrl-C (SIGINT)")
    except Stopped as e:
        fail(4, str(e))
