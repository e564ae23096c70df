# SPDX-License-Identifier: GPL-2.0-or-later
"""1-sample EEVEE frame rendering with per-frame sub-pixel jitter, into multilayer float EXRs with a
JSON sidecar per frame. Every scene property touched is snapshotted and restored afterwards, even on
error or cancel (`Snapshot`).

Facts used (../../../shared/BLENDER.md, checked on Blender 3.4.1):
* 1 EEVEE sample sits exactly on the pixel centre; camera shift moves every sample point by
  (+dx, +dy) pixels (x right, y up) with shift = d / fit_size (fit_size = max(W, H) for sensor fit
  AUTO). The shift is set from Python right before each render and never keyframed.
* gi_cubemap_resolution '64': the world probe is re-rendered every frame; at the default 512 it costs
  ~1.4 s per frame on this machine, at 64 it is negligible (recorded in every sidecar).
* EEVEE 3.4 writes no Vector pass (the flag is accepted silently); EEVEE Next and Cycles do.
"""

import bisect
import collections
import functools
import itertools
import json
import math
import os
import socket
import time

import bpy

from . import exr_file, hashing
from . import plan as plan_mod

CUBEMAP_RESOLUTION = "64"
CUBEMAP_REASON = "the world probe is re-rendered per frame; 512 (default) costs ~1.4 s/frame, 64 ~0 s"
HALTON_PERIOD = 16
JITTER_DISTRIBUTIONS = ("blackman-harris", "uniform")
# The OpenEXR codecs the 1-sample renders (input/, reference/) may be stored with: the lossless ones, so a
# filter reads the same values whichever was chosen (and a frame stored with one is reused under another).
# Measured at 1920x1080, colour + depth (docs/farm.md "Disk"): none 41.5 MB, saved in 0.02-0.04 s and read
# by the library in 99 ms; piz 9.3 MB, 0.12 s, 162 ms; zip 8.9 MB, 0.20 s, 153 ms.
INPUT_CODECS = ("none", "piz", "zip")
# RSAA geometric sub-sample offsets in pixels (x right, y up): 8 points on two rotated squares, so
# every direction through the centre is cut. The filter's offset table must be built for this pattern.
RSAA_PATTERN = [(-0.375, -0.125), (0.125, -0.375), (0.375, 0.125), (-0.125, 0.375),
                (-0.25, 0.25), (0.25, 0.25), (0.25, -0.25), (-0.25, -0.25)]


class RenderError(RuntimeError):
    """A render could not be set up or produced no file; the message says what to change."""


class RenderFailed(RenderError):
    """Blender failed to render or save a frame that was set up right (a full disk, a folder made
    read-only meanwhile): not the input's fault."""


# ---- engines and capabilities --------------------------------------------------------------------

def eevee_engine(scene):
    """'BLENDER_EEVEE_NEXT' where the engine enum offers it (4.2, 4.3), else 'BLENDER_EEVEE'."""
    items = [i.identifier for i in scene.render.bl_rna.properties["engine"].enum_items]
    if "BLENDER_EEVEE_NEXT" in items:
        return "BLENDER_EEVEE_NEXT"
    if "BLENDER_EEVEE" in items:
        return "BLENDER_EEVEE"
    raise RenderError("this Blender offers no EEVEE engine (engines: %s)" % ", ".join(items))


# Cycles as a second renderer (validation of reconstructed motion against its Vector pass): cheap
# settings, and a 0.01 px box pixel filter so its one sample sits on the pixel centre (plus the
# jitter shift) like EEVEE's, which makes its Depth, Vector and CryptoObject values those of that point.
CYCLES_SETTINGS = {"device": "CPU", "use_denoising": False, "use_adaptive_sampling": False,
                   "pixel_filter_type": "BOX", "filter_width": 0.01, "max_bounces": 2, "seed": 0,
                   "use_animated_seed": False}
ENGINES = {"eevee": None, "cycles": "CYCLES"}  # None: EEVEE (EEVEE Next where offered)


def render_engine(scene, name="eevee"):
    """Engine identifier for a user-facing name ('eevee' or 'cycles')."""
    if name not in ENGINES:
        raise RenderError("unknown engine '%s' (known: %s)" % (name, ", ".join(ENGINES)))
    return ENGINES[name] or eevee_engine(scene)


def renderer_motion_pass(engine):
    """Whether the engine writes a Vector pass: EEVEE Next (4.2+) and Cycles do, EEVEE 3.x does not."""
    if engine == "CYCLES" or engine == "BLENDER_EEVEE_NEXT":
        return True
    return engine == "BLENDER_EEVEE" and bpy.app.version >= (4, 2, 0)


def check_blender_version():
    if bpy.app.version < (3, 4, 0):
        raise RenderError("Blender %s is not supported: Crisp needs 3.4 or newer" % bpy.app.version_string)


def camera_problem(scene, frames=None):
    """Why Crisp cannot render the scene through its camera, or None: no camera, a scene camera that is
    not a camera object (Crisp jitters the camera's shift and records its projection), also one that a
    timeline marker makes the scene camera within `frames` (all markers without frames), stereoscopy
    (Crisp renders and filters one view), a render size of no pixel (a small resolution's percentage),
    or another scene of its name (Blender renders a scene by name)."""
    same_name = [s for s in bpy.data.scenes if s.name == scene.name]
    if len(same_name) > 1:  # the file's own and one linked from another file: the render took the file's
        where = ["this file's own" if s.library is None else "one linked from '%s'" % s.library.filepath
                 for s in same_name]
        return ("%s scenes are named '%s' (%s): Blender renders a scene by its name, so Crisp could render the "
                "other one; rename this file's own scene" % (len(same_name), scene.name, " and ".join(where)))
    cam = scene.camera
    bound = _camera_markers(scene, frames)
    if cam is None and bound:  # Blender would make a marker's camera the scene camera as the frame changes
        return ("scene '%s' has no scene camera; timeline marker '%s' binds '%s', which Blender makes the scene camera "
                "as the frame changes, but Crisp starts from the scene camera: set it (Scene properties > Camera)"
                % (scene.name, bound[0].name, bound[0].camera.name))
    if cam is None:
        cameras = sorted(o.name for o in scene.objects if o.type == "CAMERA")
        if cameras:  # there is one, it is just not the scene's camera
            return ("scene '%s' has no scene camera, though it has the camera object%s %s: set one as the scene "
                    "camera (Scene properties > Camera)" % (scene.name, "s" if len(cameras) > 1 else "",
                                                             plan_mod.some_names(cameras, quote=True)))
        return "scene '%s' has no camera: add one and set it as the scene camera" % scene.name
    if cam.type != "CAMERA":
        return ("the scene camera '%s' is %s object, not a camera: Crisp jitters a camera's shift and records "
                "its projection; set a camera object as the scene camera" % (cam.name, _article(cam.type.lower())))
    for marker in bound:
        if marker.camera.type != "CAMERA":
            return ("timeline marker '%s' (frame %d) makes '%s' the scene camera, %s object, not a camera: Crisp "
                    "jitters a camera's shift and records its projection; bind a camera object to the marker"
                    % (marker.name, marker.frame, marker.camera.name, _article(marker.camera.type.lower())))
    if scene.render.use_multiview:
        return ("stereoscopy is on (Output properties > Stereoscopy): Crisp renders and filters one view; "
                "switch it off")
    if min(render_size(scene)) < 1:
        r = scene.render
        return ("scene '%s' renders %dx%d pixels (%dx%d at %d%%): raise the resolution or its percentage"
                % ((scene.name,) + render_size(scene) + (r.resolution_x, r.resolution_y, r.resolution_percentage)))
    return None


def _camera_markers(scene, frames):
    """The timeline markers bound to a camera that choose the scene camera on one of `frames` (the last
    at or before the first frame, else the first marker, as Blender takes it before every marker; and those
    after the first frame up to the last), or all of them without frames."""
    markers = sorted((m for m in scene.timeline_markers if m.camera is not None), key=lambda m: m.frame)
    frames = list(frames) if frames is not None else []
    if not frames:
        return markers
    first, last = min(frames), max(frames)
    before = [m for m in markers if m.frame <= first] or markers[:1]
    return before[-1:] + [m for m in markers if first < m.frame <= last and m not in before]


def _article(word):
    return ("an " if word[:1] in "aeiou" else "a ") + word


# ---- restoring what we touch ---------------------------------------------------------------------

class Snapshot:
    """Context manager: `set(owner, attr, value)` remembers the first old value of each property and
    everything is put back in reverse order on exit, whatever happened."""

    def __init__(self, scene):
        self.scene = scene
        self._saved = []
        self._seen = set()
        self._undo = []  # calls that put back what is not a property (an object's eye: hide_set)
        self._after = []  # calls that put back a property only they can set (restore_after)

    def remember(self, owner, attr):
        """Records a value that setting another property may change as a side effect."""
        self.set(owner, attr, getattr(owner, attr))

    def _first(self, owner, attr):
        """Whether owner.attr is registered for the first time (and registers it)."""
        key = (owner.as_pointer() if hasattr(owner, "as_pointer") else id(owner), attr)
        if key in self._seen:
            return False
        self._seen.add(key)
        return True

    def set(self, owner, attr, value):
        if self._first(owner, attr):
            self._saved.append((owner, attr, getattr(owner, attr), self._of_scene(owner)))
        if getattr(owner, attr) != value:
            setattr(owner, attr, value)

    def undo_later(self, calls):
        """Calls made on restore, last first, before the properties are put back."""
        self._undo += calls

    def restore_after(self, owner, attr, call):
        """A property that setting it back takes more than a value (call() puts it back, once the others
        are back): set() leaves it to call, which restore makes after the properties, before a last pass
        over them (in case call changed one as a side effect)."""
        if self._first(owner, attr):
            self._after.append(call)

    def __enter__(self):
        self._frame = (self.scene.frame_current, self.scene.frame_subframe)
        return self

    def _of_scene(self, owner):
        """Whether owner is the scene's own data (its render settings, view layers): freed with it."""
        id_data = getattr(owner, "id_data", None)
        return id_data is not None and id_data.as_pointer() == self.scene.as_pointer()

    def _scene_gone(self):
        try:
            self.scene.name
        except ReferenceError:
            return True
        return False

    def restore(self):
        """Puts every value back. Two passes: some values are only valid once another one is back
        (an 8-bit colour depth is refused while the file format is still EXR); then the restore_after
        calls and one more pass. The scene deleted (or read again by an undo) while a clicked run waited
        between frames: its own data went with it and the Python objects of that data point at freed
        memory, so only the values of other data (a camera's shift, an animation curve) are put back."""
        errors, undo_errors = {}, {}
        gone = self._scene_gone()
        if gone:  # the calls hide objects again in the scene's view layers and layer collections
            self._undo.clear()
            self._saved = [entry for entry in self._saved if not entry[3]]
        for call in reversed(self._undo):
            try:
                call()
            except Exception as e:  # keep restoring the rest
                undo_errors["viewport visibility"] = str(e)
        self._undo.clear()
        after, self._after = ([] if gone else self._after), []  # (all of them put back the scene's own data)

        def sweep():
            errors.clear()
            for owner, attr, value, _ in reversed(self._saved):
                try:
                    if getattr(owner, attr) != value:
                        setattr(owner, attr, value)
                except Exception as e:  # keep restoring the rest
                    errors[attr] = str(e)
        sweep()
        sweep()
        if after:
            for call in reversed(after):
                try:
                    call()
                except Exception as e:  # keep restoring the rest
                    undo_errors["restore"] = str(e)
            sweep()
        errors.update({attr: "still %r, not %r" % (getattr(o, attr), v) for o, attr, v, _ in self._saved
                       if attr not in errors and getattr(o, attr) != v})
        errors.update(undo_errors)
        self._saved.clear()
        self._seen.clear()
        if not gone:
            self.scene.frame_set(self._frame[0], subframe=self._frame[1])
        return ["%s: %s" % kv for kv in errors.items()]

    def __exit__(self, *exc):
        errors = self.restore()
        if errors and exc[0] is None:
            raise RenderError("could not restore: " + "; ".join(errors))
        return False


# ---- jitter ----------------------------------------------------------------------------------------

def halton(index, base):
    """Radical inverse of `index` in `base` (index >= 1 gives a value in (0, 1))."""
    f, r = 1.0, 0.0
    while index > 0:
        f /= base
        r += f * (index % base)
        index //= base
    return r


@functools.lru_cache(maxsize=16)
def _blackman_harris_table(width, n=1024):
    """Table of the inverse CDF of a Blackman-Harris window spanning [-width/2, width/2] pixels
    (Harris 1978, 4-term window a0..a3 = 0.35875, 0.48829, 0.14128, 0.01168), kept for the widths asked
    last: taa's viewport preview asks at every redraw with the scene's filter size, which a dragged
    Filter Size slider changes at each step (kept for every width, the tables grew the session by
    ~80 kB per value)."""
    xs = [-0.5 + i / n for i in range(n + 1)]
    w = [0.35875 - 0.48829 * math.cos(2 * math.pi * (x + 0.5)) + 0.14128 * math.cos(4 * math.pi * (x + 0.5))
         - 0.01168 * math.cos(6 * math.pi * (x + 0.5)) for x in xs]
    cdf = [0.0]
    for i in range(n):
        cdf.append(cdf[-1] + 0.5 * (w[i] + w[i + 1]))
    total = cdf[-1]
    cdf = [c / total for c in cdf]
    return [x * width for x in xs], cdf


def jitter_offset(frame, distribution="blackman-harris", filter_size=1.5, period=HALTON_PERIOD):
    """Sub-pixel offset (dx, dy) in pixels (x right, y up) of `frame`, from Halton(2,3) point
    (frame mod period) + 1. 'uniform': the point minus 0.5 (inside the pixel). 'blackman-harris':
    each coordinate through the inverse CDF of a Blackman-Harris window spanning
    [-filter_size, filter_size] pixels, the distribution EEVEE 3.x gives its own samples, so averages
    converge to its reference. EEVEE's filter_size is the window's HALF width (its table spans
    [-2, 2] x filter_size, applied as an NDC shift, i.e. halved in pixels): measured on still_life
    240x135, the mean of 8 such 1-sample renders matches EEVEE's 8-sample render to 31.6 dB, with a
    window of total width filter_size to only 23.6 dB (native/temporal/jitter.h says the same)."""
    index = frame % period + 1
    u, v = halton(index, 2), halton(index, 3)
    if distribution == "uniform":
        return u - 0.5, v - 0.5, index
    if distribution != "blackman-harris":
        raise RenderError("unknown jitter distribution '%s' (known: %s)" % (distribution, ", ".join(JITTER_DISTRIBUTIONS)))
    if filter_size <= 1e-6:
        return 0.0, 0.0, index
    xs, cdf = _blackman_harris_table(2.0 * filter_size)

    def inv(p):
        i = min(max(bisect.bisect_right(cdf, p) - 1, 0), len(cdf) - 2)
        t = (p - cdf[i]) / (cdf[i + 1] - cdf[i]) if cdf[i + 1] > cdf[i] else 0.0
        return xs[i] + t * (xs[i + 1] - xs[i])
    return inv(u), inv(v), index


render_size = plan_mod.render_size


def shift_per_pixel(scene):
    """Camera shift that moves the samples by one pixel, or RenderError if the setup is not covered."""
    r = scene.render
    if abs(r.pixel_aspect_x - r.pixel_aspect_y) > 1e-6:
        raise RenderError("jitter needs square pixels (pixel aspect is %g:%g)" % (r.pixel_aspect_x, r.pixel_aspect_y))
    w, h = render_size(scene)
    fit = scene.camera.data.sensor_fit
    size = {"AUTO": max(w, h), "HORIZONTAL": w, "VERTICAL": h}[fit]
    return 1.0 / size


# ---- the sidecar ---------------------------------------------------------------------------------

def _matrix(m):
    return [[float(v) for v in row] for row in m]


def camera_matrices(scene, depsgraph):
    cam = scene.camera
    return _matrix(cam.matrix_world.inverted()), _matrix(plan_mod.camera_projection(cam, depsgraph, scene))


def shift_curves(camera_data):
    """The unmuted F-curves (of its action and NLA strips) and drivers that animate a camera's shift."""
    return [fc for fc in plan_mod.animation_curves(camera_data)
            if fc.data_path in ("shift_x", "shift_y") and not fc.mute]


def object_table(scene, view_layer):
    """The sidecar's objects by Cryptomatte hash: each visible object, and each instanced source that
    renders once (instances of one source share its ID, so their transforms cannot be told apart in
    the ID pass: those are left out, and motion reconstruction treats their pixels as still). A source
    that is also a visible object shares that object's ID: the object's matrix is listed, for both.
    Visible objects of one name (a linked one and a local one: Cryptomatte hashes the name alone) share
    an ID too, and are left out like instances. Objects that may deform also carry
    plan.geometry_record."""
    out = {}
    layer = view_layer or scene.view_layers[0]
    instances = plan_mod.rendered_instances(layer)
    visible = plan_mod.visible_objects(scene, view_layer)
    counts = collections.Counter(source.name for source, _, _ in instances)
    # The objects of each name, visible or instanced (one object may be both): more than one, one ID.
    objects_named = collections.defaultdict(set)
    for ob in visible + [source for source, _, _ in instances]:
        objects_named[ob.name].add(ob.name_full)
    for source, _, m in instances:
        key = hashing.cryptomatte_hex(source.name)
        if counts[source.name] == 1 and key not in out:
            out[key] = {"name": source.name, "matrix_world": _matrix(m),
                        **plan_mod.geometry_record(source, layer.depsgraph)}
    for ob in visible:
        out[hashing.cryptomatte_hex(ob.name)] = {"name": ob.name, "matrix_world": _matrix(ob.matrix_world),
                                                 **plan_mod.geometry_record(ob, layer.depsgraph)}
    for name, objects in objects_named.items():
        if len(objects) > 1:
            out.pop(hashing.cryptomatte_hex(name), None)
    return out


def render_settings(scene, engine, samples, codec="none"):
    r = scene.render
    w, h = render_size(scene)
    extra = {"cycles": dict(CYCLES_SETTINGS, samples=samples)} if engine == "CYCLES" else {}
    return {**extra, "engine": engine, "samples": samples, "resolution": [w, h], "pixel_aspect": [r.pixel_aspect_x, r.pixel_aspect_y],
            "filter_size": r.filter_size, "film_transparent": r.film_transparent,
            "gi_cubemap_resolution": scene.eevee.gi_cubemap_resolution, "gi_cubemap_reason": CUBEMAP_REASON,
            "view_transform": scene.view_settings.view_transform, "fps": r.fps / r.fps_base,
            "motion_blur": False, "exr": "multilayer float32, codec %s, linear scene-referred" % codec.upper()}


# ---- temporary files ------------------------------------------------------------------------------

def host_tag():
    """This host's name as temporary names hold it: at most 64 bytes of [A-Za-z0-9_.-], others as _
    (io/temporary_file.cpp hostTag)."""
    name = socket.gethostname() or "host"
    return "".join(c if c.isascii() and (c.isalnum() or c in "_.-") else "_" for c in name)[:64]


_temporaries = itertools.count()


def temporary_path(path):
    """Where a file goes until it is whole, then renamed into place: hidden beside it and named by host,
    process and call as the library names its own (io/temporary_file.h), ".<stem>.tmp-<host>-<pid>-<n><ext>",
    so two runs writing one file (a farm task run twice at once) never write the same temporary, and
    one that a killed run left can be told from one being written (remove_stale_temporaries)."""
    folder, name = os.path.split(path)
    stem, ext = os.path.splitext(name)
    return os.path.join(folder, ".%s.tmp-%s-%d-%d%s" % (stem[:64], host_tag(), os.getpid(), next(_temporaries), ext))


def process_gone(pid):
    """Whether no process of this host has that id (one we may not signal is running)."""
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return True
    except OSError:
        pass
    return False


def left_by_a_killed_run(path, pid):
    """Whether path, named by process pid of this host, is what a run killed without a chance to clean up
    left (kill -9, a crash): that process no longer runs and the path has not changed for a minute."""
    if pid == os.getpid() or not process_gone(pid):
        return False
    try:
        return time.time() - os.path.getmtime(path) >= 60
    except OSError:
        return False


def remove_stale_temporaries(folder):
    """Removes from folder the temporary files (temporary_path, and the library's) that a process of this
    host left when it was killed without a chance to clean up (kill -9, a crash): its process no longer
    runs and the file is a minute old, as `crisp filter` does (io/temporary_file.h). Returns their names."""
    marker = ".tmp-%s-" % host_tag()
    removed = []
    try:
        names = os.listdir(folder)
    except OSError:
        return removed
    for name in names:
        at = name.rfind(marker)
        if not name.startswith(".") or at <= 0:
            continue
        pid, _, n = name[at + len(marker):].partition("-")
        if not (pid.isdigit() and n.split(".", 1)[0].isdigit()):
            continue
        path = os.path.join(folder, name)
        if os.path.isfile(path) and left_by_a_killed_run(path, int(pid)):
            try:
                os.remove(path)
                removed.append(name)
            except OSError:
                pass
    return removed


class WriteFailed(OSError):
    """A file of ours could not be written (a full disk, a folder in its place): "cannot write PATH: why"."""


def write_json(path, data):
    """Writes data as JSON through a temporary name renamed into place; on failure the temporary is
    removed and WriteFailed names the file."""
    tmp = temporary_path(path)
    try:
        with open(tmp, "w") as f:
            json.dump(data, f, indent=1)
        os.replace(tmp, path)
    except BaseException as e:
        try:
            os.remove(tmp)
        except OSError:
            pass
        if isinstance(e, OSError):
            raise WriteFailed(e.errno, "cannot write %s: %s" % (path, e.strerror or e)) from e
        raise


# ---- rendering -------------------------------------------------------------------------------------

def checked_codec(codec):
    """codec (INPUT_CODECS, any case) in lower case; a RenderError naming the known ones otherwise."""
    name = codec.lower() if isinstance(codec, str) else None
    if name not in INPUT_CODECS:
        raise RenderError("input codec %r is not one of: %s (lossless, so the filters read the values rendered)"
                          % (codec, ", ".join(INPUT_CODECS)))
    return name


def _remember_hidden(snap, owner, attr, reveal):
    """Registers owner.attr (an enum) with the snapshot. A value Blender's menu no longer lists reads ""
    and cannot be set back as such, so the run ended with "could not restore" and the value was lost:
    B44 or B44A as EXR codec, which the menu lists at half float only, after the Color Depth or File
    Format changed; RGBA as an FFmpeg output's Color after its codec changed to one without alpha
    (H.264). reveal: the (owner, attr, value) settings under which it is listed, in order; they are
    switched through snap (which puts them back), the value is read, and once the rest is back it is put
    back under them the same way (the pass after that puts back what the switch reset, as FFmpeg's
    container). Without reveal, a hidden value is left as the run leaves it."""
    if getattr(owner, attr) != "":
        snap.remember(owner, attr)
        return
    for o, a, value in reveal:
        snap.set(o, a, value)
    hidden = getattr(owner, attr)

    def put_back():
        if not hidden:
            return
        before = [(o, a, getattr(o, a)) for o, a, _ in reveal]
        for o, a, value in reveal:
            setattr(o, a, value)
        setattr(owner, attr, hidden)
        for o, a, value in before:  # in the same order: an 8-bit depth only once the format is back
            setattr(o, a, value)
    snap.restore_after(owner, attr, put_back)


def _prepare(snap, scene, view_layer, engine, samples, flags, file_format="OPEN_EXR_MULTILAYER", codec="none"):
    r = scene.render
    snap.set(r, "engine", engine)
    snap.set(scene.eevee, "taa_render_samples", samples)
    if engine == "CYCLES":
        snap.set(scene.cycles, "samples", samples)
        for attr, value in CYCLES_SETTINGS.items():
            snap.set(scene.cycles, attr, value)
    snap.set(scene.eevee, "gi_cubemap_resolution", CUBEMAP_RESOLUTION)
    snap.set(scene.eevee, "use_motion_blur", False)
    snap.set(r, "use_motion_blur", False)
    snap.set(r, "use_compositing", False)
    snap.set(r, "use_sequencer", False)
    # Only view_layer, which need not be the context's: "single layer" would render the context's.
    snap.set(r, "use_single_layer", False)
    for layer in scene.view_layers:
        snap.set(layer, "use", layer.name == view_layer.name)
    snap.set(r, "use_stamp", False)
    snap.set(r, "use_border", False)
    snap.set(r, "use_file_extension", False)
    # Switching the format back to FFmpeg resets a movie without audio to an MKV container and its H.264
    # preset: remembered before the switch, so they are put back after it.
    for prop in r.ffmpeg.bl_rna.properties:
        if not prop.is_readonly:
            snap.remember(r.ffmpeg, prop.identifier)
    settings = r.image_settings
    # file_format changes these as a side effect; each may hold a value its menu hides (_remember_hidden).
    snap.remember(settings, "color_depth")
    _remember_hidden(snap, settings, "color_mode",
                     [(r.ffmpeg, "codec", "PNG")] if settings.file_format == "FFMPEG" else [])
    _remember_hidden(snap, settings, "exr_codec",
                     [(settings, "file_format", "OPEN_EXR"), (settings, "color_depth", "16")])
    snap.set(settings, "file_format", file_format)
    snap.set(settings, "color_depth", "32")
    snap.set(settings, "exr_codec", codec.upper())
    snap.set(settings, "color_mode", "RGBA")
    snap.set(settings, "use_preview", False)  # an EXR's preview: a JPEG beside each temporary name
    for prop in view_layer.bl_rna.properties:
        if prop.identifier.startswith("use_pass_"):
            snap.set(view_layer, prop.identifier, prop.identifier in flags or prop.identifier == "use_pass_combined")
    for prop in view_layer.eevee.bl_rna.properties:
        if prop.identifier.startswith("use_pass_"):
            snap.set(view_layer.eevee, prop.identifier, False)
    if "use_pass_cryptomatte_object" in flags:
        snap.set(view_layer, "pass_cryptomatte_depth", 2)  # one EXR layer: rank 0 is all a 1-sample pixel has
    _leave_out_aovs(snap, scene, view_layer)


def _leave_out_aovs(snap, scene, view_layer):
    """Removes the view layer's AOVs for the renders and puts them back afterwards (their names, types,
    order and the active one). No filter reads them, and EEVEE renders the scene once more per sample for
    each: four made a 960x540 still_life frame about 4 times slower to render and 5 times larger on disk.
    Blender 3.4 has no switch for an AOV and no remove in the collection's API, only the operator, which
    removes the active one; an AOV named as a pass (a "Depth" AOV beside the Z pass) made rsaa's renders
    crash Blender, so naming them out of the way is no way either. The compositor's links from their
    Render Layers sockets stay (the sockets are hidden meanwhile)."""
    if not len(view_layer.aovs):
        return
    active, removed = view_layer.active_aov_index, []

    def put_back():
        # Removed from the last: what is left (if a removal failed) is the first ones, so adding back in
        # the reverse order of removal keeps the order.
        for name, kind in reversed(removed):
            aov = view_layer.aovs.add()
            # The type first: named first, a value AOV would be a colour one for a moment, and the Render
            # Layers node would make its socket again, dropping the compositor's links from it.
            aov.type = kind
            aov.name = name
        removed.clear()
        view_layer.active_aov_index = min(active, len(view_layer.aovs) - 1)

    snap.restore_after(view_layer, "aovs", put_back)
    with bpy.context.temp_override(scene=scene, view_layer=view_layer):
        for n in range(len(view_layer.aovs), 0, -1):
            last = view_layer.aovs[n - 1]
            view_layer.active_aov_index = n - 1
            entry = (last.name, last.type)
            bpy.ops.scene.view_layer_remove_aov()
            if len(view_layer.aovs) != n - 1:
                raise RuntimeError("Blender did not remove the AOV '%s' for Crisp's renders" % entry[0])
            removed.append(entry)


def _render_to(scene, path):
    """Renders the current frame (the view layer _prepare left on) to `path` through a temporary name,
    renamed once complete."""
    tmp = temporary_path(path)
    scene.render.filepath = tmp
    t0 = time.perf_counter()
    try:
        try:
            bpy.ops.render.render(write_still=True, scene=scene.name)
        except RuntimeError as e:  # Blender's own failure to render or write (a read-only folder, a full disk)
            raise RenderFailed("Blender could not render frame %d to %s: %s"
                              % (scene.frame_current, tmp, str(e).strip().splitlines()[-1] if str(e).strip() else e))
        dt = time.perf_counter() - t0
        if not os.path.isfile(tmp):
            raise RenderFailed("Blender wrote no file for frame %d (expected %s)" % (scene.frame_current, tmp))
        broken = exr_file.incomplete(tmp)
        if broken:  # a disk that filled up while Blender wrote: it says nothing, and the file must not take the name
            raise RenderFailed("Blender wrote an incomplete file for frame %d (%s: %s); is the disk full?"
                               % (scene.frame_current, path, broken))
        os.replace(tmp, path)
    except BaseException:  # also a stop signal, which arrives as the render returns: no temporary left
        if os.path.exists(tmp):
            os.remove(tmp)
        raise
    return dt


def write_display_png(scene, pixels, size, png_path):
    """png_path: linear premultiplied RGBA float pixels (rows from the bottom, as FrameFilter's
    output_bottom_up gives them; `size` (width, height)) as the scene's own PNGs show them, through its
    colour management (view transform, look, exposure, gamma and display, or its output's override),
    8-bit RGBA, written through a temporary name. The library's PNGs are a plain sRGB encoding of the
    linear values, which matches Blender's only for the Standard view without a look. The pixels are
    given, not the EXR just written loaded back: decoding it took a third of the PNG's time at 1920x1080;
    the PNG is the same (test_addon.py, test_png_of_the_output_equals_the_png_of_its_exr)."""
    settings = scene.render.image_settings
    saved = [(attr, getattr(settings, attr)) for attr in ("file_format", "color_mode", "color_depth",
                                                           "compression", "exr_codec")]
    # A float image holds linear premultiplied pixels, as one loaded from an EXR does.
    image = bpy.data.images.new("Crisp PNG", size[0], size[1], alpha=True, float_buffer=True)
    tmp = temporary_path(png_path)
    try:
        image.pixels.foreach_set(pixels)
        settings.file_format = "PNG"
        settings.color_mode, settings.color_depth = "RGBA", "8"
        image.save_render(tmp, scene=scene)
        os.replace(tmp, png_path)
    finally:
        bpy.data.images.remove(image)
        if os.path.exists(tmp):
            os.remove(tmp)
        for attr, value in saved:  # the file format first: setting it changes the others
            setattr(settings, attr, value)


def frame_name(frame, ext=".exr"):
    return "frame_%04d%s" % (frame, ext)


def _checked_inputs(scene, frames, view_layer):
    """What every render needs before it touches the scene: a supported Blender, a camera (camera_problem),
    a frame, and a view layer of this scene. Returns (frames as a list, view layer)."""
    check_blender_version()
    frames = list(frames)
    problem = camera_problem(scene, frames)
    if problem:
        raise RenderError(problem)
    if not frames:
        raise RenderError("no frames to render (empty frame range)")
    return frames, default_view_layer(scene, view_layer)


def default_view_layer(scene, view_layer=None):
    """The view layer to plan and render: the one given, else the context's if it is this scene's and
    renders (its "use" is on), else the first that renders, else the first."""
    if view_layer is not None and view_layer.name in scene.view_layers:
        return scene.view_layers[view_layer.name]
    context = getattr(bpy.context, "view_layer", None)
    if context is not None and context.name in scene.view_layers and scene.view_layers[context.name].use:
        return scene.view_layers[context.name]
    return next((layer for layer in scene.view_layers if layer.use), scene.view_layers[0])


def drain(steps):
    """Runs a generator of steps (iter_render_frames, pipeline.iter_run, ...) to its end and returns its value:
    the blocking call that scripts and batch runs make. The operators step them a frame per timer tick."""
    while True:
        try:
            next(steps)
        except StopIteration as done:
            return done.value


def render_frames(*args, **kwargs):
    """iter_render_frames to its end: the list of infos."""
    return drain(iter_render_frames(*args, **kwargs))


def iter_render_frames(scene, the_plan, frames, out_dir, samples=1, jitter_distribution="blackman-harris",
                       view_layer=None, on_frame=None, should_cancel=None, engine=None, made_with=None, codec="none"):
    """Renders `frames` of `scene` into out_dir/frame_NNNN.exr + .json with the plan's passes, stored with
    `codec` (INPUT_CODECS); the sidecar records made_with (what the frame's outputs are made with,
    pipeline.made_with) when given.
    A generator: yields each frame's info once it is made, and returns the list of infos.

    on_frame(frame, info) is called after each frame (info: dict with render_s, paths, and rsaa's
    geometry_render_s); it may raise to stop. should_cancel() -> True stops after the current frame.
    The scene is restored on return, error, cancel or close() (the render settings stay in place while
    the generator waits between frames). engine: None (EEVEE) or 'CYCLES' (see CYCLES_SETTINGS)."""
    frames, view_layer = _checked_inputs(scene, frames, view_layer)
    codec = checked_codec(codec)
    engine = engine or eevee_engine(scene)
    os.makedirs(out_dir, exist_ok=True)
    infos = []
    with Snapshot(scene) as snap:
        # The camera of each frame (timeline markers may switch cameras): its shift as the user left
        # it, registered once for the restore. The jitter is added to the shift of the frame: the user's,
        # or what the animation or a driver makes it at that frame. The render evaluates the animation
        # again and would put an animated shift back over the jitter, so the curves that animate it are
        # muted from the frame's frame_set to the next.
        user_shifts = {}

        def frame_camera():
            data = scene.camera.data
            if data.name not in user_shifts:
                curves = shift_curves(data)
                user_shifts[data.name] = (data, (data.shift_x, data.shift_y), curves)
                snap.set(data, "shift_x", data.shift_x)
                snap.set(data, "shift_y", data.shift_y)
                for curve in curves:
                    snap.remember(curve, "mute")
            data, _, curves = user_shifts[data.name]
            for curve in curves:
                curve.mute = True
            return data, (data.shift_x, data.shift_y)

        def unjittered_cameras():  # before frame_set, which then animates the shifts that are animated
            for data, (x, y), curves in user_shifts.values():
                data.shift_x, data.shift_y = x, y
                for curve in curves:
                    curve.mute = False

        cam_data, base_shift = frame_camera()
        snap.set(scene.render, "filepath", scene.render.filepath)
        _prepare(snap, scene, view_layer, engine, samples, set(the_plan.render_flags()), codec=codec)
        # The sidecars' object matrices and geometry: what renders but is hidden in the viewport (an
        # object, a modifier reading another object) is not evaluated there.
        snap.undo_later(plan_mod.show_in_viewport(scene, view_layer) + plan_mod.show_render_modifiers(scene))
        filter_size = scene.render.filter_size
        for f in frames:
            if should_cancel and should_cancel():
                break
            unjittered_cameras()
            scene.frame_set(f)
            cam_data, base_shift = frame_camera()
            unit = shift_per_pixel(scene) if the_plan.jitter else 0.0
            depsgraph = bpy.context.evaluated_depsgraph_get()
            depsgraph.update()
            view, proj_plain = camera_matrices(scene, depsgraph)
            dx = dy = 0.0
            index = 0
            if the_plan.jitter:
                dx, dy, index = jitter_offset(f, jitter_distribution, filter_size)
                cam_data.shift_x = base_shift[0] + dx * unit
                cam_data.shift_y = base_shift[1] + dy * unit
                depsgraph.update()
            _, proj = camera_matrices(scene, depsgraph)
            path = os.path.join(out_dir, frame_name(f))
            render_s = _render_to(scene, path)
            sidecar = {
                "frame": f, "file": os.path.basename(path),
                "jitter": {"x": dx, "y": dy, "units": "pixels, x right, y up", "enabled": the_plan.jitter,
                           "sequence": "halton(2,3)", "index": index, "period": HALTON_PERIOD,
                           "distribution": jitter_distribution if the_plan.jitter else "none",
                           "filter_size": filter_size if jitter_distribution == "blackman-harris" else None},
                "camera": {"name": scene.camera.name_full, "matrix_world": _matrix(scene.camera.matrix_world),
                           "view": view, "projection": proj, "projection_unjittered": proj_plain,
                           "type": cam_data.type, "base_shift": list(base_shift)},
                "objects": object_table(scene, view_layer),
                "passes": list(the_plan.passes), "render_flags": the_plan.render_flags(),
                "render_settings": render_settings(scene, engine, samples, codec),
                "blender_version": bpy.app.version_string, "render_s": render_s,
            }
            if made_with is not None:
                sidecar["made_with"] = made_with
            if not the_plan.still_average:  # what crisp filter then sets, as the add-on does (with_plan_params)
                sidecar["history"] = {"still_average": False, "note": the_plan.history_note,
                                      "params": plan_mod.NO_STILL_AVERAGE}
            if "subsamples" in the_plan.passes:
                sidecar["subsamples"] = _render_subsamples(snap, scene, view_layer, f, out_dir, base_shift,
                                                           shift_per_pixel(scene), dx, dy)
                cam_data.shift_x, cam_data.shift_y = base_shift
            write_json(os.path.join(out_dir, frame_name(f, ".json")), sidecar)
            if "subsamples" not in the_plan.passes:
                _remove_subsamples(out_dir, f)
            info = {"frame": f, "render_s": render_s, "exr": path, "jitter": [dx, dy]}
            if "subsamples" in sidecar:  # rsaa's eight geometry renders, apart from the frame's own
                info["geometry_render_s"] = sum(s["render_s"] for s in sidecar["subsamples"])
            infos.append(info)
            if on_frame:
                on_frame(f, info)
            yield info
    return infos


def _subsample_path(out_dir, frame, k):
    return os.path.join(out_dir, "frame_%04d_sub%d.exr" % (frame, k))


def _remove_subsamples(out_dir, frame):
    """An earlier rsaa render's sub-samples of a frame just rendered anew without them: its sidecar no
    longer lists them, and they belong to the picture that frame replaced (8 renders' worth of disk)."""
    for k in range(len(RSAA_PATTERN)):
        try:
            os.remove(_subsample_path(out_dir, frame, k))
        except FileNotFoundError:
            pass


# EEVEE effects that shade the Combined pass only, off for rsaa's geometry renders (which EEVEE 3.4 shades in
# full, _render_subsamples): ambient occlusion, screen-space reflections, bloom, soft shadows, shadow maps at their
# smallest, volumetric lighting. Measured (480x270, 2 frames, 8 renders each): with AO, SSR and bloom on, the
# renders took 3.3 -> 1.0 s a frame (still_life), 6.7 -> 2.3 (shiny), 5.1 -> 1.6 (foliage); depth and normal
# were bit-identical but for one pixel of shiny's normal (1.2e-4: SSR stores normals at another precision).
GEOMETRY_ONLY_EEVEE = (("use_gtao", False), ("use_ssr", False), ("use_bloom", False), ("use_soft_shadows", False),
                       ("shadow_cube_size", "64"), ("shadow_cascade_size", "64"), ("use_volumetric_lights", False))


def _render_subsamples(snap, scene, view_layer, frame, out_dir, base_shift, unit, dx, dy):
    """RSAA's geometric sub-samples: depth + normal renders at RSAA_PATTERN offsets (around the
    frame's own jitter), with a plain grey material override (meant to make shading cost nothing, but
    EEVEE 3.4 ignores a view layer's override: they are shaded in full), at one sample whatever the
    frame's (--samples): rsaa reads a point sample of depth and normal, and EEVEE takes both from the
    first sample alone (BLENDER.md), so more samples cost time and change no value."""
    mat = bpy.data.materials.get("CrispGeometryOnly") or bpy.data.materials.new("CrispGeometryOnly")
    settings = [(view_layer, "material_override", mat), (view_layer, "use_pass_cryptomatte_object", False),
                (view_layer, "use_pass_diffuse_color", False), (scene.eevee, "taa_render_samples", 1)]
    if scene.render.engine == "CYCLES":
        settings.append((scene.cycles, "samples", 1))
    else:
        settings += [(scene.eevee, prop, value) for prop, value in GEOMETRY_ONLY_EEVEE if hasattr(scene.eevee, prop)]
    for owner, prop, _ in settings:  # registers the user's values for the final restore
        snap.set(owner, prop, getattr(owner, prop))
    main = [(owner, prop, getattr(owner, prop)) for owner, prop, _ in settings]
    for owner, prop, value in settings:
        setattr(owner, prop, value)
    out = []
    cam = scene.camera.data
    try:
        for k, (ox, oy) in enumerate(RSAA_PATTERN):
            cam.shift_x = base_shift[0] + (dx + ox) * unit
            cam.shift_y = base_shift[1] + (dy + oy) * unit
            path = _subsample_path(out_dir, frame, k)
            out.append({"offset": [ox, oy], "file": os.path.basename(path), "render_s": _render_to(scene, path)})
    finally:
        for owner, prop, value in main:  # back to the main frames' settings
            setattr(owner, prop, value)
    return out


def render_reference(*args, **kwargs):
    """iter_render_reference to its end: [{frame, render_s, exr}]."""
    return drain(iter_render_reference(*args, **kwargs))


def iter_render_reference(scene, frames, out_dir, samples, view_layer=None, on_frame=None, should_cancel=None,
                          codec="none"):
    """The same frames with `samples` EEVEE samples, no jitter, colour only, into out_dir/frame_NNNN.exr
    (plain RGBA float EXR, stored with `codec`, INPUT_CODECS). A generator like iter_render_frames:
    yields each frame's info, returns [{frame, render_s, exr}]. Hook for the sample curve (issue 3 item
    5): call this once per sample count and keep each render_s."""
    frames, view_layer = _checked_inputs(scene, frames, view_layer)
    codec = checked_codec(codec)
    engine = eevee_engine(scene)
    os.makedirs(out_dir, exist_ok=True)
    infos = []
    with Snapshot(scene) as snap:
        snap.set(scene.render, "filepath", scene.render.filepath)
        _prepare(snap, scene, view_layer, engine, samples, {"use_pass_combined"}, file_format="OPEN_EXR",
                 codec=codec)
        for f in frames:
            if should_cancel and should_cancel():
                break
            scene.frame_set(f)
            path = os.path.join(out_dir, frame_name(f))
            info = {"frame": f, "render_s": _render_to(scene, path), "exr": path, "samples": samples}
            infos.append(info)
            if on_frame:
                on_frame(f, info)
            yield info
    return infos


# ---- reusing earlier renders ----------------------------------------------------------------------

def input_complete(input_dir, f):
    # render_frames writes the EXR and rsaa's sub-samples before the sidecar, all renamed into place: a
    # sidecar means they are whole, unless one was lost since (the sidecar lists the sub-samples).
    if not all(os.path.isfile(os.path.join(input_dir, frame_name(f, ext))) for ext in (".exr", ".json")):
        return False
    subsamples = read_sidecar(input_dir, f).get("subsamples") or []
    return isinstance(subsamples, list) and all(
        isinstance(s, dict) and os.path.isfile(os.path.join(input_dir, str(s.get("file") or "."))) for s in subsamples)


def read_sidecar(input_dir, f):
    """Frame f's sidecar as a dict ({} if missing or unreadable)."""
    try:
        with open(os.path.join(input_dir, frame_name(f, ".json"))) as fh:
            side = json.load(fh)
        return side if isinstance(side, dict) else {}
    except (OSError, ValueError):
        return {}


def reusable_input(scene, engine, input_dir, f, the_plan, samples, jitter_distribution, scene_key=None):
    """Whether input/frame f was rendered as this run would render it (same passes, size, samples, jitter
    and plan history, and with scene_key given the same scene file: its sidecar's made_with), so it can be
    read instead of rendered again (a pre-roll, eval's input sets); stale or foreign inputs are not."""
    if not input_complete(input_dir, f):
        return False
    side = read_sidecar(input_dir, f)
    try:
        jitter = side["jitter"]
        settings = side["render_settings"]
        return (side["passes"] == list(the_plan.passes) and settings["samples"] == samples
                and settings["engine"] == engine and settings["resolution"] == list(render_size(scene))
                and jitter["distribution"] == (jitter_distribution if the_plan.jitter else "none")
                # what crisp filter reads of the plan (the still average): a frame of an older build or plan
                and (side.get("history") or {}).get("still_average", True) == the_plan.still_average
                and (scene_key is None or (side.get("made_with") or {}).get("scene_key") == scene_key))
    except (KeyError, TypeError, AttributeError):
        return False
