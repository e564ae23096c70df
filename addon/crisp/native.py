# SPDX-License-Identifier: GPL-2.0-or-later
"""Every call into libcrisp goes through this module (ctypes).

The library is loaded lazily, on first use, from (in order): the add-on preference "library path",
$CRISP_LIBRARY, then <repo>/build/lib/libcrisp.so relative to this file. Every signature is declared
once in SIGNATURES; every call is followed by crispGetError and a failure raises CrispError. If the
library cannot be loaded, the add-on still registers and `status()` says why.
"""

import ctypes
import hashlib
import json
import math
import numbers
import os
import reprlib
import struct
import threading
import time

# Mirrors of the C enums in native/include/crisp/crisp.h.
FORMAT_FLOAT, FORMAT_FLOAT2, FORMAT_FLOAT3, FORMAT_FLOAT4, FORMAT_UINT = 1, 2, 3, 4, 5
# RSAA's packed sub-sample record (80 bytes per pixel: float32 depth[8], int16 normal x[8], y[8], z[8]).
FORMAT_RSAA_SUBSAMPLES = 6
# 4-byte words per pixel.
FORMAT_CHANNELS = {FORMAT_FLOAT: 1, FORMAT_FLOAT2: 2, FORMAT_FLOAT3: 3, FORMAT_FLOAT4: 4, FORMAT_UINT: 1,
                   FORMAT_RSAA_SUBSAMPLES: 20}
# What a C int and a float32 hold (ctypes wraps or rounds to infinity beyond them).
C_INT_MIN, C_INT_MAX = -2 ** 31, 2 ** 31 - 1
FLOAT32_MAX = 3.4028234663852886e38
ERROR_NAMES = {0: "none", 1: "unknown", 2: "invalid argument", 3: "invalid operation", 4: "out of memory",
               5: "I/O", 6: "invalid data"}


class CrispError(RuntimeError):
    """Any failure of the native library (or of loading it). `detail`: the library's own message (the
    text without the call and error kind), for showing to artists."""

    def __init__(self, text, detail=None):
        super().__init__(text)
        self.detail = detail or text


def _refused(detail, call=None):
    """The CrispError of a value refused here before it reaches the library, worded as the library's own
    (call(): "crispX: invalid argument error: ...") where it stands for a call's refusal."""
    return CrispError(("%s: invalid argument error: %s" % (call, detail)) if call else "invalid argument: " + detail,
                      detail)


def _check_view(what, call, fmt, width, height):
    """A view's format and size that ctypes would wrap (a format of 2**32 + 4 reached the library as 4, a
    width of 2**64 + 2 as 2) are refused here, as given. what: "image 'color'" or "file 'x.exr'"."""
    if not (isinstance(fmt, numbers.Integral) and C_INT_MIN <= fmt <= C_INT_MAX):
        raise _refused("%s: unknown format %s" % (what, fmt), call)
    if not all(isinstance(n, numbers.Integral) and 0 <= n < 2 ** 64 for n in (width, height)):
        raise _refused("%s: size %sx%s is out of range [1, 65536]" % (what, width, height), call)


class Metrics(ctypes.Structure):
    _fields_ = [(n, ctypes.c_double) for n in ("mse", "rmse", "psnr", "snr", "ssim", "flip")]


_vp, _cp, _int, _sz, _f = ctypes.c_void_p, ctypes.c_char_p, ctypes.c_int, ctypes.c_size_t, ctypes.c_float
# name: (restype, argtypes). The one table of the C API this add-on uses.
SIGNATURES = {
    "crispGetVersion": (_int, []),
    "crispGetVersionString": (_cp, []),
    "crispGetError": (_int, [ctypes.POINTER(_cp)]),
    "crispNewContext": (_vp, []),
    "crispReleaseContext": (None, [_vp]),
    "crispSetContextInt": (None, [_vp, _cp, _int]),
    "crispCommitContext": (None, [_vp]),
    "crispGetFilterTypes": (_cp, []),
    "crispNewFilter": (_vp, [_vp, _cp]),
    "crispReleaseFilter": (None, [_vp]),
    "crispSetFilterImage": (None, [_vp, _cp, _vp, _int, _sz, _sz, _sz, _sz]),
    "crispUnsetFilterImage": (None, [_vp, _cp]),
    "crispSetFilterInt": (None, [_vp, _cp, _int]),
    "crispSetFilterFloat": (None, [_vp, _cp, _f]),
    "crispSetFilterBool": (None, [_vp, _cp, _int]),
    "crispSetFilterString": (None, [_vp, _cp, _cp]),
    "crispGetFilterDoc": (_cp, [_vp]),
    "crispGetFilterInfo": (_cp, [_vp]),
    "crispCommitFilter": (None, [_vp]),
    "crispExecuteFilter": (None, [_vp]),
    "crispResetFilter": (None, [_vp]),
    "crispLoadFrame": (_vp, [_vp, _cp]),
    "crispReleaseFrame": (None, [_vp]),
    "crispGetFrameWidth": (_int, [_vp]),
    "crispGetFrameHeight": (_int, [_vp]),
    "crispGetFrameNonFiniteColour": (ctypes.c_longlong, [_vp]),
    "crispGetFramePasses": (_cp, [_vp]),
    "crispGetFramePass": (_vp, [_vp, _cp, ctypes.POINTER(_int)]),
    "crispWriteImage": (None, [_vp, _cp, _vp, _int, _sz, _sz, _sz, _sz]),
    "crispWriteImageEXR": (None, [_vp, _cp, _vp, _int, _sz, _sz, _sz, _sz, _int, _cp]),
    "crispReconstructFrameMotion": (None, [_vp, _vp, _cp, _cp]),
    "crispAttachFrameSubsamples": (None, [_vp, _vp, _vp]),
    "crispCompareImages": (None, [_vp, _vp, _vp, _int, _sz, _sz, _vp, ctypes.POINTER(Metrics)]),
}
# The C API this add-on is written for (crisp.h CRISP_VERSION_MAJOR, _MINOR): a library of another major
# version may differ in what a call means (crisp.h: CrispMetrics grows only with a new major), and one of
# an older minor version may lack a filter, parameter or pass this add-on sends.
API_VERSION = (0, 2)  # 0.2: crispWriteImageEXR
# Calls that do not record errors (and crispGetError itself).
_NO_CHECK = {"crispGetError", "crispGetVersion", "crispGetVersionString", "crispGetFilterTypes"}

_preference_path = ""   # set by preferences.py
_lib = None             # the loaded _Library, or None
_load_error = None      # why loading failed (string), or None
_failed_key = None      # the candidate files (_candidates_key) when loading failed: unchanged, no retry


def repo_library_path():
    # realpath: the add-on linked into Blender's add-ons folder still finds its checkout's build.
    here = os.path.dirname(os.path.realpath(__file__))
    return os.path.normpath(os.path.join(here, "..", "..", "build", "lib", "libcrisp.so"))


def candidate_paths():
    out = []
    if _preference_path:
        out.append(("preference", os.path.abspath(os.path.expanduser(_preference_path))))
    if os.environ.get("CRISP_LIBRARY"):
        # abspath: dlopen reads a name without a slash as one to search for, not as the file checked here.
        out.append(("$CRISP_LIBRARY", os.path.abspath(os.environ["CRISP_LIBRARY"])))
    out.append(("repository build", repo_library_path()))
    return out


def set_preference_path(path):
    """Changing the path forgets a failed load so the next use retries."""
    global _preference_path, _lib, _load_error
    if path != _preference_path:
        _preference_path = path or ""
        if _lib is None:
            _load_error = None


def preference_note():
    """What the preferences' library path does not do yet, or None: no file there, or (a library
    loaded from elsewhere, which a process cannot unload) a restart of Blender to load it."""
    if not _preference_path:
        return None
    path = os.path.abspath(os.path.expanduser(_preference_path))
    if not os.path.isfile(path):
        return "no file at %s" % path
    if _lib is not None and os.path.realpath(_lib.path) != os.path.realpath(path):
        return "restart Blender to load %s (the library loaded from %s stays until then)" % (path, _lib.path)
    return None


class _Library:
    def __init__(self, path):
        self.path = path
        self.digest = _file_digest(path)  # the build that filters (a resume remakes frames another made)
        self.param_specs = {}  # (method, name): the row of its parameter table (param_spec), read once
        self.dll = ctypes.CDLL(path)
        self.fns = {}
        missing = []
        for name, (res, args) in SIGNATURES.items():
            try:
                fn = getattr(self.dll, name)
            except AttributeError:
                missing.append(name)
                continue
            fn.restype, fn.argtypes = res, args
            self.fns[name] = fn
        # The version first: a library of another major version may lack or rename calls, and its version
        # says more of what to do than the list of names it lacks.
        if "crispGetVersion" in self.fns and "crispGetVersionString" in self.fns:
            version = self.fns["crispGetVersion"]()
            have = (version // 10000, version // 100 % 100)
            if have[0] != API_VERSION[0] or have[1] < API_VERSION[1]:
                raise OSError("it is libcrisp %s; this add-on needs %d.x, at least %d.%d (build the library of the "
                              "add-on's own checkout)" % (self.fns["crispGetVersionString"]().decode("utf-8", "replace"),
                                                          API_VERSION[0], API_VERSION[0], API_VERSION[1]))
        if missing:
            raise OSError("%s lacks %s (an older libcrisp?)" % (path, ", ".join(missing)))

    def call(self, name, *args):
        result = self.fns[name](*args)
        if name not in _NO_CHECK:
            msg = _cp()
            code = self.fns["crispGetError"](ctypes.byref(msg))
            if code:
                text = msg.value.decode("utf-8", "replace") if msg.value else "(no message)"
                raise CrispError("%s: %s error: %s" % (name, ERROR_NAMES.get(code, code), text), text)
        return result


def _file_digest(path):
    h = hashlib.blake2b(digest_size=8)
    with open(path, "rb") as f:
        for block in iter(lambda: f.read(1 << 20), b""):
            h.update(block)
    return "blake2b:" + h.hexdigest()


def _candidates_key():
    """Each candidate path with its file's modification time and size (None where there is no file): a
    failed load is tried again only when one of these changes."""
    key = []
    for origin, path in candidate_paths():
        try:
            st = os.stat(path)
            key.append((origin, path, st.st_mtime_ns, st.st_size))
        except OSError:
            key.append((origin, path, None, None))
    return tuple(key)


def load():
    """The library, loading it on first use. Raises CrispError saying where it looked. A failure is
    remembered while the candidate paths and their files stay the same: the panel, the method menu and
    the preview call this on every redraw, and each retry hashed the file (_file_digest) and dlopen'ed it
    again. A changed path (preferences, $CRISP_LIBRARY) or a rebuilt file is tried."""
    global _lib, _load_error, _failed_key
    if _lib is not None:
        return _lib
    key = _candidates_key()
    if _load_error is not None and key == _failed_key:
        raise CrispError(_load_error)
    tried = []
    for origin, path in candidate_paths():
        if not os.path.isfile(path):
            tried.append("%s %s: no such file" % (origin, path))
            if origin != "repository build":
                break  # an explicit path that is wrong is an error, not a reason to fall through
            continue
        try:
            _lib = _Library(path)
            _load_error = None
            return _lib
        except OSError as e:
            tried.append("%s %s: %s" % (origin, path, e))
            break
    # What to change: the last path tried (an explicit one that is wrong stops the search), else where to
    # give one.
    preferences = "the add-on's preferences (Edit > Preferences > Add-ons > Crisp)"
    where = {"preference": "Correct the path in " + preferences,
             "$CRISP_LIBRARY": "Correct $CRISP_LIBRARY, or set the path in %s, which comes first" % preferences}
    _load_error = "libcrisp not loaded; %s. %s" % ("; ".join(tried), where.get(
        origin, "Set its path in %s or in $CRISP_LIBRARY" % preferences))
    _failed_key = key
    raise CrispError(_load_error)


def status():
    """(ok, text) for the panel: the loaded library and version, or why it is not there."""
    try:
        lib = load()
    except CrispError as e:
        return False, str(e)
    return True, "libcrisp %s (%s)" % (lib.call("crispGetVersionString").decode(), lib.path)


def call(name, *args):
    return load().call(name, *args)


def _b(s):
    # As the file system encodes names (UTF-8, and a name that is not UTF-8 as the bytes it was read from).
    b = os.fsencode(s) if isinstance(s, str) else s
    if isinstance(b, bytes) and b"\0" in b:  # C would read it only up to the NUL: another name
        detail = "%r contains a NUL character" % (s,)
        raise _refused(detail)
    return b


def filter_types():
    return [t for t in call("crispGetFilterTypes").decode().split(",") if t]


def filter_info(method):
    """{"type", "images": [...], "params": [...]} of a filter, from the library itself."""
    with Context() as ctx:
        f = Filter(ctx, method)
        try:
            return f.info()
        finally:
            f.close()


def param_spec(method, name):
    """The row of the loaded library's parameter table for a method's parameter ({"name", "type",
    "default", "min", "max", ...}), or None if the method has no such parameter. Read from the library
    once and kept with it: the viewport asks on every draw."""
    lib = load()
    key = (method, name)
    if key not in lib.param_specs:
        lib.param_specs[key] = next((p for p in filter_info(method)["params"] if p["name"] == name), None)
    return lib.param_specs[key]


def check_params(method, params):
    """None when the library accepts `params` ({name: value}) for `method`, else its message saying why
    not: the library's own checks (ranges, choices, rules between parameters such as an odd patchSize),
    run by setting them on a filter and committing it on 1x1 images of zeros bound to every image it
    requires (and rsaa's sub-samples record), about 0.1 ms."""
    with Context(threads=1) as ctx:
        try:
            f = Filter(ctx, method)
        except CrispError as e:  # a method this library does not have: its message, as for a parameter
            return e.detail
        try:
            for k, v in params.items():
                f.set_param(k, v)
            buffers = []
            for role in f.info()["images"]:
                if not (role["required"] or role["name"] == "subsamples"):
                    continue
                if role["name"] == "subsamples":
                    fmt, words = FORMAT_RSAA_SUBSAMPLES, role["maxChannels"]
                elif role["uint"]:
                    fmt, words = FORMAT_UINT, 1
                else:
                    fmt = words = role["maxChannels"]  # FORMAT_FLOATn is n
                buffers.append((ctypes.c_float * max(words, 4))())
                f.set_image(role["name"], ctypes.addressof(buffers[-1]), fmt, 1, 1)
            f.commit()
        except CrispError as e:
            return e.detail
        finally:
            f.close()
    return None


# ---- objects with owned handles ----------------------------------------------------------------

class _Owner:
    """An object that owns a library handle (self.handle) and releases it by the library function named
    _RELEASE in close(), at the end of a `with`, or when collected without close() (a script that drops
    it, or an exception between making and closing it), as a Python file closes itself."""

    _RELEASE = None  # "crispRelease...", set by each subclass

    def close(self):
        if self.handle:
            call(self._RELEASE, self.handle)
            self.handle = None

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        self.close()

    def __del__(self):
        try:
            self.close()
        except Exception:  # a constructor that failed before the handle existed; interpreter exit
            pass


class Context(_Owner):
    _RELEASE = "crispReleaseContext"

    def __init__(self, threads=0):
        if threads and not (isinstance(threads, numbers.Real) and float(threads).is_integer()):
            # int() would truncate it: 0.5 made 0, all cores
            raise _refused("context parameter 'numThreads' takes a whole number, not '%s'" % threads)
        if threads and not C_INT_MIN <= int(threads) <= C_INT_MAX:  # ctypes would wrap it (2**32 + 2 to 2)
            detail = "context parameter 'numThreads' = %d is out of range (not a C int)" % int(threads)
            raise _refused(detail, "crispSetContextInt")
        self.handle = call("crispNewContext")
        try:
            if threads:
                call("crispSetContextInt", self.handle, b"numThreads", int(threads))
            call("crispCommitContext", self.handle)
        except BaseException:  # the caller gets no object to close: release the handle here
            self.close()
            raise


class Filter(_Owner):
    _RELEASE = "crispReleaseFilter"

    def __init__(self, context, method):
        self.method = method
        self.handle = call("crispNewFilter", context.handle, _b(method))
        self._param_types = None

    def doc(self):
        return (call("crispGetFilterDoc", self.handle) or b"").decode("utf-8", "replace")

    def info(self):
        """The filter's image and parameter tables (crispGetFilterInfo) as Python objects."""
        return json.loads(call("crispGetFilterInfo", self.handle).decode("utf-8"))

    def set_param(self, name, value):
        """Sets by the type the filter declares; a text value (from --set K=V) is parsed to it."""
        if self._param_types is None:
            self._param_types = {p["name"]: p["type"] for p in self.info()["params"]}
        kind = self._param_types.get(name)
        if kind is None:  # unknown: the library names it in its error
            kind = {bool: "bool", int: "int", float: "float"}.get(type(value), "string")
            if isinstance(value, str):
                kind = _infer_kind(value)
        if isinstance(value, str) and kind in ("bool", "int", "float"):
            value = _parsed_text(name, kind, value)
        if kind in ("int", "float") and name in self._param_types:  # an unknown name: the library's error
            self._check_representable(name, kind, value)
        if kind == "bool":
            try:  # bool() took None, 0.5, NaN and [0]; True, False, 0, 1 and numpy's bools stay
                either = value in (0, 1)
            except (TypeError, ValueError):  # an array of several values
                either = False
            if not either:
                raise _refused("parameter '%s' takes true or false, not '%s'" % (name, value))
            call("crispSetFilterBool", self.handle, _b(name), int(bool(value)))
        elif kind == "int":
            call("crispSetFilterInt", self.handle, _b(name), int(value))
        elif kind == "float":
            call("crispSetFilterFloat", self.handle, _b(name), float(value))
        else:
            call("crispSetFilterString", self.handle, _b(name), _b(str(value)))

    def _check_representable(self, name, kind, value):
        """A value ctypes cannot pass as given is refused here, as typed: one that is not a number
        (None), a fraction for an int (int() truncated 5.7 to 5; NaN and Inf raised ValueError), and, in
        the library's words, an int beyond C int's range (ctypes wraps 2**32 + 5 to 5) or a float beyond
        float32's (ctypes rounds it to infinity). A number is any numbers.Real: numpy's scalars too."""
        number = isinstance(value, numbers.Real)
        whole = isinstance(value, numbers.Integral) or (number and float(value).is_integer())
        if not number or (kind == "int" and not whole):
            wanted = "a whole number" if kind == "int" else "a number"
            detail = "parameter '%s' takes %s, not '%s'" % (name, wanted, value)
            raise _refused(detail)
        if kind == "int":
            fits = C_INT_MIN <= int(value) <= C_INT_MAX
        else:
            try:
                fits = not math.isfinite(float(value)) or abs(float(value)) <= FLOAT32_MAX
            except OverflowError:  # an int beyond any double (10 ** 400)
                fits = False
        if fits:
            return
        spec = next((p for p in self.info()["params"] if p["name"] == name), {})
        detail = "filter '%s': parameter '%s' = %s is out of range [%s, %s]" % (
            self.method, name, value, spec.get("min"), spec.get("max"))
        raise _refused(detail, "crispSetFilter" + kind.capitalize())

    def set_image(self, name, ptr, fmt, width, height):
        _check_view("image '%s'" % name, "crispSetFilterImage", fmt, width, height)
        call("crispSetFilterImage", self.handle, _b(name), ptr, fmt, width, height, 0, 0)

    def unset_image(self, name):
        call("crispUnsetFilterImage", self.handle, _b(name))

    def commit(self):
        call("crispCommitFilter", self.handle)

    def execute(self):
        call("crispExecuteFilter", self.handle)

    def reset(self):
        call("crispResetFilter", self.handle)


def param_text(value):
    """One parameter value as `crisp render --set K=V` reads it: a bool true/false, a float the shortest
    decimal that is the same float32 (the panel's and the library's type), anything else as it is."""
    if isinstance(value, bool):
        return "true" if value else "false"
    if isinstance(value, float):
        single = struct.unpack("f", struct.pack("f", value))[0]
        for digits in range(1, 10):
            text = "%.*g" % (digits, single)
            if struct.unpack("f", struct.pack("f", float(text)))[0] == single:
                return text
    return str(value)


def canonical_param_texts(method, params):
    """params ({name: value or --set text}) as param_text gives them, a text first read as the
    parameter's type: the panel's 0.9900000095367432 and --set's "0.99" (or "0.990") are the same
    "0.99", "1" and "true" of a bool the same "true". A text that is not of its type stays as it is."""
    kinds = {}
    if params:
        try:
            kinds = {p["name"]: p["type"] for p in filter_info(method)["params"]}
        except CrispError:  # no library, or not its method: the texts as they are
            pass
    out = {}
    for name, value in (params or {}).items():
        kind = kinds.get(name)
        if isinstance(value, str) and kind in ("bool", "int", "float"):
            try:
                value = _parsed_text(name, kind, value)
            except CrispError:
                pass
        out[name] = param_text(value)
    return out


def _parsed_text(name, kind, text):
    """A --set K=V text as the parameter's type; text that is not one is refused, naming the parameter
    (a bool takes true/false, yes/no, on/off or 1/0 in any case, as `crisp filter --set` does)."""
    t = text.strip()
    try:
        if kind == "bool":
            low = t.lower()
            if low in ("1", "true", "yes", "on"):
                return True
            if low in ("0", "false", "no", "off"):
                return False
            raise ValueError(t)
        return int(t) if kind == "int" else float(t)
    except ValueError:
        detail = "parameter '%s' takes %s, not '%s'" % (
            name, {"bool": "true or false", "int": "a whole number", "float": "a number"}[kind], text)
        raise _refused(detail) from None


def _infer_kind(text):
    t = text.strip().lower()
    if t in ("true", "false", "yes", "no", "on", "off"):
        return "bool"
    try:
        int(t)
        return "int"
    except ValueError:
        pass
    try:
        float(t)
        return "float"
    except ValueError:
        return "string"


class Frame(_Owner):
    """A multilayer EXR (or plain image) read by the library; passes stay owned by the frame."""

    _RELEASE = "crispReleaseFrame"

    def __init__(self, context, path):
        self.path = path
        self.handle = call("crispLoadFrame", context.handle, _b(path))
        self.width = call("crispGetFrameWidth", self.handle)
        self.height = call("crispGetFrameHeight", self.handle)

    def passes(self):
        return [p for p in call("crispGetFramePasses", self.handle).decode().split(",") if p]

    def pass_pointer(self, role):
        fmt = ctypes.c_int(0)
        ptr = call("crispGetFramePass", self.handle, _b(role), ctypes.byref(fmt))
        return ptr, fmt.value

    def reconstruct_motion(self, context, previous_sidecar, next_sidecar=None):
        """Adds a "motion" pass rebuilt from depth, IDs and the sidecars (this frame's own beside its
        EXR, and the previous frame's): EEVEE 3.4 writes no Vector pass."""
        call("crispReconstructFrameMotion", context.handle, self.handle, _b(previous_sidecar),
             _b(next_sidecar) if next_sidecar else None)

    def attach_subsamples(self, context, frame_filter=None):
        """RSAA: adds the pass "subsamples" (packed records, what the filter reads) and sub0..sub7
        (float4) from the frame_NNNN_subK.exr files its sidecar lists and, with a filter, sets the
        filter's camera parameters from the sidecar (crispAttachFrameSubsamples)."""
        call("crispAttachFrameSubsamples", context.handle, self.handle,
             frame_filter.handle if frame_filter is not None else None)

    def pass_values(self, role):
        """The pass as a flat Python list (row 0 = top), and its channel count."""
        ptr, fmt = self.pass_pointer(role)
        n = self.width * self.height * FORMAT_CHANNELS[fmt]
        ctype = ctypes.c_uint32 if fmt == FORMAT_UINT else ctypes.c_float
        return list((ctype * n).from_address(ptr)), FORMAT_CHANNELS[fmt]


# How crispWriteImage stores an .exr, as (bit depth, codec): Crisp's own float ZIP.
CRISP_EXR = (32, "zip")


def write_image(context, path, ptr, fmt, width, height, exr=None):
    """Writes .exr or .png by extension. exr: (bit depth 16 or 32, codec such as "zip" or "dwaa") of an
    .exr, as Blender's Color Depth and Codec (exr_storage); None: CRISP_EXR."""
    _check_view("file '%s'" % path, "crispWriteImage", fmt, width, height)
    if exr is not None and path.lower().endswith(".exr"):
        call("crispWriteImageEXR", context.handle, _b(path), ptr, fmt, width, height, 0, 0, int(exr[0]), _b(exr[1]))
    else:
        call("crispWriteImage", context.handle, _b(path), ptr, fmt, width, height, 0, 0)


def exr_storage(image_settings):
    """The (bit depth, codec) write_image takes, from a scene's render.image_settings when its File Format
    is OpenEXR (single or multilayer), as Blender would store its own render; None (CRISP_EXR) otherwise."""
    if getattr(image_settings, "file_format", "") not in ("OPEN_EXR", "OPEN_EXR_MULTILAYER"):
        return None
    depth, codec = image_settings.color_depth, image_settings.exr_codec
    if not codec:
        # B44 or B44A, which Blender's menu lists at half float only: chosen there and the depth set to full
        # float since, the codec reads "" and Blender still writes it (float channels stored uncompressed
        # inside it). It reads at 16 bits, and the depth goes back at once.
        image_settings.color_depth = "16"
        try:
            codec = image_settings.exr_codec
        finally:
            image_settings.color_depth = depth
    return (16 if depth == "16" else 32, str(codec).lower())


def compare_images(context, reference_path, test_path):
    """PSNR/SSIM/... of a test image against a reference, both read by the library."""
    with Frame(context, reference_path) as ref, Frame(context, test_path) as test:
        if (ref.width, ref.height) != (test.width, test.height):
            raise CrispError("compare: %s is %dx%d but %s is %dx%d" % (reference_path, ref.width, ref.height,
                                                                      test_path, test.width, test.height))
        for path, frame in ((reference_path, ref), (test_path, test)):  # as `crisp compare` refuses them
            bad = call("crispGetFrameNonFiniteColour", frame.handle)
            if bad:
                raise CrispError("compare: %s has %d non-finite colour values (NaN or Inf): it has no error to "
                                 "measure" % (path, bad))
        rp, rf = ref.pass_pointer("color")
        tp, tf = test.pass_pointer("color")
        if rf != tf:
            raise CrispError("compare: colour formats differ (%d vs %d)" % (rf, tf))
        m = Metrics()
        call("crispCompareImages", context.handle, rp, tp, rf, ref.width, ref.height, None, ctypes.byref(m))
        return {n: getattr(m, n) for n, _ in Metrics._fields_}


# The sub-samples as the filter reads them: one packed record per pixel (the float4 passes
# sub0..sub7 that crispAttachFrameSubsamples also adds are not bound).
SUBSAMPLE_PASSES = ("subsamples",)


def _alongside(background, foreground):
    """Runs background() on a thread of its own and foreground() on this one; returns when both have
    ended, raising background's error, if any, else foreground's."""
    errors = []

    def work():
        try:
            background()
        except BaseException as e:  # handed to the caller below
            errors.append(e)
    worker = threading.Thread(target=work, name="crisp-write")
    worker.start()
    try:
        foreground()
    finally:
        worker.join()
        if errors:
            raise errors[0]


class _Sidecar(dict):
    """A frame's sidecar as read, and its path for messages."""
    path = ""


def _bad_sidecar(side, what):
    return CrispError("sidecar '%s': %s" % (side.path, what))


def _read_sidecar(path):
    """A frame's JSON sidecar, or a CrispError naming the file and what is wrong with it (in the library's
    words: "sidecar 'P': ...") for one cut short, not JSON, or not a JSON object."""
    try:
        with open(path, "rb") as fh:
            side = json.loads(fh.read().decode("utf-8"))
    except (OSError, ValueError, RecursionError) as e:  # UnicodeDecodeError and JSONDecodeError are ValueErrors;
        # RecursionError: lists nested deeper than Python's stack
        raise CrispError("sidecar '%s': cannot be read (%s)" % (path, e)) from None
    if not isinstance(side, dict):
        raise CrispError("sidecar '%s': is not a JSON object" % path)
    side = _Sidecar(side)
    side.path = path
    return side


class FrameFilter:
    """Filters a sequence of frames with one filter object (so temporal history carries over)."""

    def __init__(self, method, params=None, threads=0, passes=("color",)):
        self.context = Context(threads)
        self.filter = None
        try:
            self._start(method, params, passes)
        except BaseException:  # the caller gets no object to close: release the handles here
            self.close()
            raise

    def _start(self, method, params, passes):
        if method == "rsaa" and "subsamples" not in passes:
            # The plan rendered no geometry (no visible object, no geometric edge): colour as is, and
            # rsaa's parameters (checked against rsaa, pipeline.run) have nothing to set.
            method, params = "none", None
        self.filter = Filter(self.context, method)
        self.passes = [p for p in passes if p != "subsamples"]
        # RSAA's geometric sub-samples: separate files listed in each frame's sidecar.
        self.subsamples = "subsamples" in passes
        for k, v in (params or {}).items():
            self.filter.set_param(k, v)
        # Temporal filters take each frame's sub-pixel jitter from its sidecar, as `crisp filter` does.
        info = self.filter.info()
        self._takes_jitter = any(p["name"] == "jitterX" for p in info["params"])
        # A frame without a sidecar is filtered with the jitter set before the first frame (params, else
        # the default: none), as `crisp filter` does (cli/files.cpp bindJitter), not the last frame's.
        defaults = {p["name"]: p.get("default") for p in info["params"]}
        self._base_jitter = tuple(float((params or {}).get(k, defaults.get(k) or 0.0)) for k in ("jitterX", "jitterY"))
        # The passes bound to the filter: those it has an image for. Others in the plan serve the
        # frame itself (object IDs that motion reconstruction reads, for a filter that reads none).
        self._roles = {i["name"] for i in info["images"]}
        self._out = None
        self._zero_motion = None
        self._shape = None
        self._previous_sidecar = None
        self._last_shot = None  # (frame, camera) of the last frame filtered, from its sidecar
        self.restart_reason = None  # why the last frame's history restarted (None: it carried over)

    def _continue_or_restart(self, side):
        """A temporal filter's history carries over only to the next frame of the same camera: a gap in
        the frame numbers (frames rendered out of order, a frame step, a second run's frames) or
        another camera (a cut at a timeline marker) restarts it, with zero motion for the frame. Frames
        without a sidecar (side None) say nothing and carry over."""
        self.restart_reason = None
        if side is None:  # its position unknown: the next frame is not compared with an older one (as the CLI)
            self._last_shot = None
            return
        frame, camera = side.get("frame"), side.get("camera")
        name = camera.get("name") if isinstance(camera, dict) else None
        # What is not a frame number or a camera name says nothing, as the key left out (the library's
        # reader names it where it needs it: motion rebuilt from the sidecar).
        shot = (frame if isinstance(frame, int) and not isinstance(frame, bool) else None,
                name if isinstance(name, str) else None)
        last, self._last_shot = self._last_shot, shot
        if last is None or shot[0] is None:
            return
        if shot[1] and last[1] and shot[1] != last[1]:  # sidecars of older builds name no camera
            self.restart_reason = "camera '%s' after '%s'" % (shot[1], last[1])
        elif last[0] is not None and shot[0] != last[0] + 1:  # the last frame's position may be unknown
            self.restart_reason = "frame %d after frame %d" % (shot[0], last[0])
        if self.restart_reason:
            self.filter.reset()
            self._previous_sidecar = None

    def _bind_motion(self, frame, sidecar, present):
        """Motion from the frame's Vector pass if it has one, else reconstructed from the previous
        frame's sidecar; the first frame (nothing to reproject from) gets zero motion."""
        previous, self._previous_sidecar = self._previous_sidecar, (sidecar if os.path.exists(sidecar) else None)
        if "motion" not in present:
            if previous is None or self._previous_sidecar is None:
                w, h = frame.width, frame.height
                if self._zero_motion is None or len(self._zero_motion) != w * h * 4:
                    self._zero_motion = (ctypes.c_float * (w * h * 4))()
                self.filter.set_image("motion", ctypes.addressof(self._zero_motion), FORMAT_FLOAT4, w, h)
                return
            frame.reconstruct_motion(self.context, previous)
        ptr, fmt = frame.pass_pointer("motion")
        self.filter.set_image("motion", ptr, fmt, frame.width, frame.height)

    def _bind_jitter(self, side):
        """jitterX / jitterY of this frame from its sidecar (y up there, down in the library)."""
        if side is None:
            self.filter.set_param("jitterX", self._base_jitter[0])
            self.filter.set_param("jitterY", self._base_jitter[1])
            return
        jitter = side.get("jitter", {})
        if not isinstance(jitter, dict):  # false, [], 0 too: the library's reader refuses them alike
            raise _bad_sidecar(side, "key 'jitter' is not a JSON object")
        for key, name, sign in (("x", "jitterX", 1.0), ("y", "jitterY", -1.0)):
            value = jitter.get(key, 0.0)
            try:  # an int of 400 digits overflows float()
                number = float(value) if isinstance(value, (int, float)) and not isinstance(value, bool) else None
            except OverflowError:
                number = None
            if number is None or not math.isfinite(number):
                raise _bad_sidecar(side, "key 'jitter.%s' is not a finite number (%s)"
                                   % (key, reprlib.repr(value)))
            self.filter.set_param(name, sign * number)

    def run(self, input_path, output_paths, while_writing=None, exr=None):
        """Loads one frame, filters it, writes it to each path (.exr, stored as exr says (write_image),
        and/or .png). while_writing(), if
        given, is called on this thread while another writes the files (the library's call releases
        Python's lock), and may read the output (output_bottom_up); both have ended when run returns,
        which raises the writer's error, if any, else while_writing's.
        Returns seconds spent {"load_s", "filter_s" (commit + execute), "write_s"}."""
        t0 = time.perf_counter()
        with Frame(self.context, input_path) as frame:
            try:
                w, h = frame.width, frame.height
                if self._shape != (w, h):
                    self._out = (ctypes.c_float * (w * h * 4))()
                    self._shape = (w, h)
                if self.subsamples:
                    frame.attach_subsamples(self.context, self.filter)
                    self.passes += [p for p in SUBSAMPLE_PASSES if p not in self.passes]
                present = set(frame.passes())
                sidecar = os.path.splitext(input_path)[0] + ".json"
                side = None  # the sidecar, read once, for the filters that keep history
                if self._takes_jitter and os.path.exists(sidecar):
                    side = _read_sidecar(sidecar)
                if self._takes_jitter:
                    self._continue_or_restart(side)
                for role in self.passes:
                    if role not in self._roles:
                        continue
                    if role == "motion":
                        self._bind_motion(frame, sidecar, present)
                        continue
                    # A pass the frame lacks raises here, with the library's reason: absent (naming the
                    # passes found) or held unusable (an ID pass stored as half float).
                    ptr, fmt = frame.pass_pointer(role)
                    self.filter.set_image(role, ptr, fmt, w, h)
                self.filter.set_image("output", ctypes.addressof(self._out), FORMAT_FLOAT4, w, h)
                if self._takes_jitter:
                    self._bind_jitter(side)
                t1 = time.perf_counter()
                self.filter.commit()
                self.filter.execute()
                t2 = time.perf_counter()
            finally:
                # Between frames the filter holds no image: none points into the frame freed here
                # (its passes, the sub-samples attach_subsamples bound) or into an output replaced
                # at a new size. Whatever runs it next binds a frame first.
                for role in self._roles:
                    self.filter.unset_image(role)
        def write():
            for p in output_paths:
                write_image(self.context, p, ctypes.addressof(self._out), FORMAT_FLOAT4, w, h, exr)
        if while_writing is None:
            write()
        else:
            _alongside(write, while_writing)
        return {"load_s": t1 - t0, "filter_s": t2 - t1, "write_s": time.perf_counter() - t2}

    def output_bottom_up(self):
        """The last frame's output as a flat float32 numpy array of RGBA rows from the bottom, as Blender's
        images hold pixels, and its (width, height). Image.pixels.foreach_set copies such an array in 3 ms
        at 1920x1080; a memoryview of the same floats took 121 ms, element by element."""
        import numpy  # Blender's Python has it; the library's other callers need not
        w, h = self._shape
        return numpy.frombuffer(self._out, dtype=numpy.float32).reshape(h, w * 4)[::-1].ravel(), (w, h)

    def close(self):
        if self.filter is not None:
            self.filter.close()
        self.context.close()
