# SPDX-License-Identifier: GPL-2.0-or-later
"""GPU versions of the Crisp filters (fxaa, repair, taa) for the viewport preview.

The GLSL lives in the repository's `shaders/` (one file per filter, twin of native/filters/*.cpp, plus
common.glsl and fullscreen_vert.glsl). It is looked up in `<add-on>/shaders/` first (a packaged add-on
bundles a copy there) and then in `<repo>/shaders/` next to `addon/`; CRISP_SHADER_DIR overrides both.
Every pass is built with gpu.shader.create_from_info (required on 4.x's Metal/Vulkan backends, present
in 3.4): this module declares each pass's samplers, push constants and outputs in PASSES; the GLSL
file holds the functions, guarded by one macro per pass.

Needs a window (the gpu module refuses background mode). Textures are RGBA32F; each filter owns its
targets, allocated for one size and kept until the size changes, and taa keeps two history textures
between runs (ping-pong) until reset(), a size change or a new clipSpace (as the library: taa.cpp).

Parameters are checked by the library itself (native.check_params) before a GpuFilter takes them: values it
rejects (an even patchSize, feedbackMin > feedbackMax) raise GpuParamsError with its message and are never
run. A texture whose row 0 is the bottom of the picture (the viewport's) needs rows_up=True: see
common.glsl "Row order".
"""

import functools
import os
import struct

import gpu
from gpu_extras.batch import batch_for_shader

METHODS = ("fxaa", "repair", "taa")

# Parameter names and defaults of the C++ kernels (the library's crispGetFilterInfo tables). Enum-valued
# parameters are passed to GLSL as int indices into their choices.
CHOICES = {
    "mask": ("gauss5", "box3"),
    "angleEstimator": ("regression", "thesis"),
    "jitterWeighting": ("none", "blackman-harris"),
    "historyFilter": ("catmull-rom", "bilinear"),
    "clipSpace": ("ycocg", "rgb"),
    "unjitter": ("none", "nearest", "blackman-harris"),
}
DEFAULTS = {
    "fxaa": {"edgeThreshold": 0.166, "edgeThresholdMin": 0.0833, "subpix": 0.75},
    "repair": {"kappa": 0.0, "patchSize": 5, "mask": "gauss5", "angleEstimator": "regression"},
    "taa": {"jitterX": 0.0, "jitterY": 0.0, "jitterWeighting": "none", "filterSize": 1.5,
            "historyFilter": "catmull-rom", "clipSpace": "rgb", "feedbackMin": 0.7, "feedbackMax": 0.85,
            "sharpen": 0.0, "staticAccumulation": True, "maxSamples": 128, "holdPeriod": 16, "holdRelease": 0.002,
            "varianceClip": 1.0,
            "resampleDamping": 0.3,
            "staticClip": True, "unjitter": "blackman-harris"},
}
# The library's parameters the GPU versions leave out, and why. With DEFAULTS they make up the library's
# whole table (test_gpu_parity.py: test_parameter_tables_match_the_library), so a parameter the library
# gains is never dropped unnoticed.
_ONE_PATH = "picks the library's scalar reference path; a shader has one path"
NOT_ON_GPU = {
    "fxaa": {"reference": _ONE_PATH},
    "repair": {"reference": _ONE_PATH},
    "taa": {"reference": _ONE_PATH,
            "depthTolerance": "the viewport has no depth pass, so taa.glsl has no disocclusion test"},
}

# Resources of each GLSL file (declared for every pass of the file) and each pass's macro, entry and
# outputs. Push constants: (type, name); bool parameters are INT 0/1.
FILES = {
    "fxaa": {
        "samplers": ("colorImage", "lumaImage"),
        "push": (("FLOAT", "edgeThreshold"), ("FLOAT", "edgeThresholdMin"), ("FLOAT", "subpix"), ("INT", "rowsUp")),
    },
    "repair": {
        "samplers": ("colorImage", "greyImage", "gradientImage", "statsImage"),
        "push": (("FLOAT", "kappa"), ("INT", "patchSize"), ("INT", "mask"), ("INT", "angleEstimator"),
                 ("INT", "rowsUp")),
    },
    "taa": {
        "samplers": ("colorImage", "historyImage", "motionImage", "markImage"),
        "push": (("FLOAT", "jitterX"), ("FLOAT", "jitterY"), ("INT", "jitterWeighting"), ("FLOAT", "filterSize"),
                 ("INT", "historyFilter"), ("INT", "clipSpace"), ("FLOAT", "feedbackMin"),
                 ("FLOAT", "feedbackMax"), ("FLOAT", "sharpen"), ("INT", "staticAccumulation"),
                 ("INT", "maxSamples"), ("INT", "holdPeriod"), ("INT", "holdLimit"), ("FLOAT", "varianceClip"),
                 ("FLOAT", "resampleDamping"), ("INT", "staticClip"), ("INT", "unjitter"), ("INT", "hasHistory"),
                 ("INT", "hasMotion"), ("INT", "holdWindowEnd"), ("INT", "holdWindowsFresh")),
    },
}
PASSES = {
    "fxaa_luma": ("fxaa", "FXAA_LUMA_PASS", "fxaaLumaPass", (("FLOAT", "lumaOut"),)),
    "fxaa_resolve": ("fxaa", "FXAA_RESOLVE_PASS", "fxaaResolvePass", (("VEC4", "fragColor"),)),
    "repair_grey": ("repair", "REPAIR_GREY_PASS", "repairGreyPass", (("FLOAT", "greyOut"),)),
    "repair_gradient": ("repair", "REPAIR_GRADIENT_PASS", "repairGradientPass", (("FLOAT", "gradientOut"),)),
    "repair_stats": ("repair", "REPAIR_STATS_PASS", "repairStatsPass", (("VEC4", "statsOut"),)),
    "repair_reduce": ("repair", "REPAIR_REDUCE_PASS", "repairReducePass", (("VEC4", "statsOut"),)),
    "repair_resolve": ("repair", "REPAIR_RESOLVE_PASS", "repairResolvePass", (("VEC4", "fragColor"),)),
    "taa_resolve": ("taa", "TAA_RESOLVE_PASS", "taaResolvePass",
                    (("VEC4", "historyOut"), ("VEC4", "fragColor"), ("VEC4", "markOut"))),
    "taa_sharpen": ("taa", "TAA_SHARPEN_PASS", "taaSharpenPass", (("VEC4", "fragColor"),)),
    # Viewport preview (common.glsl only): the colour-managed view decoded to linear by the sRGB curve, and
    # the filtered texture drawn at a pixel offset for the 3D view's overlay buffer (see DISPLAY_SOURCE).
    "decode": (None, "DECODE_PASS", "decodePass", (("VEC4", "fragColor"),)),
    "display": (None, "DISPLAY_PASS", "displayPass", (("VEC4", "fragColor"),)),
}

DISPLAY_SOURCE = """
#ifdef DECODE_PASS
void decodePass() {
  vec4 c = texelFetch(colorImage, fragmentPixel(), 0);
  fragColor = vec4(srgbDecode(c.r), srgbDecode(c.g), srgbDecode(c.b), c.a);
}
#endif
#ifdef DISPLAY_PASS
// A POST_PIXEL handler draws into the 3D view's overlay buffer. Blender (3.4, and 4.x) merges it over the
// view in "display linear" space, defined as display value ^ 2.2 (the OCIO display shader: overlay merge,
// then pow(1 / 2.2)); the buffer is sRGB8 and encodes/decodes exactly around storage. So the display value
// v = srgbEncode(filtered) is written as v ^ 2.2, and shows as v (up to 8-bit rounding). Measured by
// tests/blender_gui/test_viewport_preview.py: writing the linear value instead showed flat areas up to
// 5/255 too bright in the darks.
void displayPass() {
  vec4 c = texelFetch(colorImage, fragmentPixel() - offset, 0);
  vec3 v = vec3(srgbEncode(c.r), srgbEncode(c.g), srgbEncode(c.b));
  fragColor = vec4(pow(v, vec3(2.2)), 1.0);
}
#endif
"""


class GpuFilterError(RuntimeError):
    """A shader that does not build, a missing shader file, or a GPU module that is unavailable."""


class GpuParamsError(GpuFilterError):
    """Parameter values the library rejects (its message); the filter keeps its previous ones."""


def shader_dirs():
    """Where the GLSL files are looked for: $CRISP_SHADER_DIR; beside the add-on's real folder (a link
    into Blender's add-ons folder is followed to the checkout: its shaders/; an installed add-on in
    share/crisp/addon/crisp: share/crisp/shaders); beside the loaded library (a copied or zipped add-on
    given the library's path: build/lib -> the checkout's shaders/, lib -> share/crisp/shaders)."""
    from . import native
    here = os.path.dirname(os.path.realpath(__file__))
    dirs = []
    if os.environ.get("CRISP_SHADER_DIR"):
        dirs.append(os.environ["CRISP_SHADER_DIR"])
    dirs += [os.path.join(here, "shaders"), os.path.normpath(os.path.join(here, "..", "..", "shaders"))]
    try:
        library = native.load().path  # loaded already when a filter checked its settings; else now
    except native.CrispError:
        library = None
    if library is not None:
        lib = os.path.dirname(os.path.realpath(library))
        dirs += [os.path.normpath(os.path.join(lib, "..", "share", "crisp", "shaders")),
                 os.path.normpath(os.path.join(lib, "..", "..", "shaders"))]
    return list(dict.fromkeys(dirs))


def shader_source(name):
    for d in shader_dirs():
        path = os.path.join(d, name)
        if os.path.isfile(path):
            with open(path, encoding="utf-8") as f:
                return f.read()
    raise GpuFilterError("shader %s not found in %s" % (name, ", ".join(shader_dirs())))


_shaders = {}
_batch = {}


def shader(pass_name):
    """The built shader of one pass (cached for the session)."""
    if pass_name in _shaders:
        return _shaders[pass_name]
    file_key, macro, entry, outputs = PASSES[pass_name]
    info = gpu.types.GPUShaderCreateInfo()
    info.vertex_in(0, "VEC2", "pos")
    if file_key is None:
        samplers, push, body = ("colorImage",), (("IVEC2", "offset"),), DISPLAY_SOURCE
    else:
        samplers, push = FILES[file_key]["samplers"], FILES[file_key]["push"]
        body = shader_source(file_key + ".glsl")
    for slot, name in enumerate(samplers):
        info.sampler(slot, "FLOAT_2D", name)
    for kind, name in push:
        info.push_constant(kind, name)
    for slot, (kind, name) in enumerate(outputs):
        info.fragment_out(slot, kind, name)
    info.vertex_source(shader_source("fullscreen_vert.glsl"))
    info.fragment_source("#define %s\n%s\n%s\nvoid main() { %s(); }\n" % (macro, shader_source("common.glsl"), body,
                                                                         entry))
    try:
        built = gpu.shader.create_from_info(info)
    except Exception as e:  # Blender prints the compiler log to stderr; name the pass here
        raise GpuFilterError("building shader pass %s failed: %s" % (pass_name, e)) from e
    _shaders[pass_name] = built
    return built


def _fullscreen_batch(sh):
    key = id(sh)
    if key not in _batch:
        # One triangle covering the target; fragments address pixels by gl_FragCoord.
        _batch[key] = batch_for_shader(sh, "TRIS", {"pos": ((-1.0, -1.0), (3.0, -1.0), (-1.0, 3.0))})
    return _batch[key]


class Target:
    """A render target: one or more RGBA32F/R32F textures behind one framebuffer."""

    def __init__(self, width, height, formats=("RGBA32F",)):
        self.width, self.height = width, height
        self.textures = [gpu.types.GPUTexture((width, height), format=f) for f in formats]
        self.framebuffer = gpu.types.GPUFrameBuffer(color_slots=tuple(self.textures))

    @property
    def texture(self):
        return self.textures[0]

    def read(self, slot=0, channels=4):
        """The texture's pixels as a flat list of floats, row 0 first."""
        with self.framebuffer.bind():
            buf = self.framebuffer.read_color(0, 0, self.width, self.height, channels, slot, "FLOAT")
        buf.dimensions = self.width * self.height * channels
        return list(buf)


def run_pass(pass_name, target, samplers, constants=()):
    """Draws one pass into `target` (every texel once)."""
    sh = shader(pass_name)
    batch = _fullscreen_batch(sh)
    with target.framebuffer.bind():
        gpu.state.viewport_set(0, 0, target.width, target.height)
        gpu.state.blend_set("NONE")
        gpu.state.depth_test_set("NONE")
        sh.bind()
        for name, tex in samplers.items():
            sh.uniform_sampler(name, tex)
        for kind, name, value in constants:
            try:
                if kind == "INT":
                    sh.uniform_int(name, int(value))
                else:
                    sh.uniform_float(name, float(value))
            except ValueError:
                pass  # declared for the whole file, unused by (so compiled out of) this pass
        batch.draw(sh)


def _float32(x):
    return struct.unpack("f", struct.pack("f", x))[0]


def hold_window_limit(hold_release, period):
    """temporal/hold_release.h holdWindowLimit, in float32 operation by operation as the C++ (so the GPU
    compiler cannot contract or regroup it)."""
    release = min(hold_release, 1.0)
    if not release >= 0.0:
        release = 0.0 if release < 0.0 else 1.0  # NaN: never
    return int(_float32(_float32(_float32(release) * 255.0) * float(period)))


def _choice_index(name, value):
    return CHOICES[name].index(value) if isinstance(value, str) else int(value)


def _constants(file_key, params):
    out = []
    for kind, name in FILES[file_key]["push"]:
        if name not in params:
            continue
        v = params[name]
        if name in CHOICES:
            v = _choice_index(name, v)
        out.append((kind, name, v))
    return out


def library_check(method, params):
    """None when the library accepts params for method, else its message (native.check_params). Without
    the library there is nothing to check against: the add-on then offers only the defaults (properties.py).
    The viewport asks on every redraw with the same settings: the answers are remembered by value."""
    from . import native
    try:
        library = native.load().path
    except native.CrispError:
        return None
    named = {k: CHOICES[k][v] if k in CHOICES and not isinstance(v, str) else v for k, v in params.items()}
    return _checked(library, method, tuple(sorted(named.items())))


@functools.lru_cache(maxsize=64)
def _checked(library, method, items):
    """library_check's answer for the library loaded from `library` (another one may answer otherwise)."""
    from . import native
    return native.check_params(method, dict(items))


def texture_from_rgba(width, height, values):
    """An RGBA32F texture from a flat list of width*height*4 floats (row 0 = texture row 0)."""
    buf = gpu.types.Buffer("FLOAT", width * height * 4, values)
    return gpu.types.GPUTexture((width, height), format="RGBA32F", data=buf)


class GpuFilter:
    """One filter on the GPU: run(color_texture) -> the output texture (RGBA32F, owned by the filter)."""

    def __init__(self, method, params=None, rows_up=False):
        """rows_up: the textures run() gets have row 0 at the bottom of the picture (common.glsl)."""
        if method not in METHODS:
            raise GpuFilterError("no GPU version of filter '%s' (have: %s)" % (method, ", ".join(METHODS)))
        self.method = method
        self.rows_up = rows_up
        self.params = dict(DEFAULTS[method])
        self.set_params(params or {})
        self.size = None
        self.frames = 0  # taa: frames since reset
        self.hold_windows_period = 0  # taa: the holdPeriod the mark textures' windows are kept for
        self.history_space = None  # taa: the clipSpace the history is stored in
        for name in [p for p in PASSES if p.startswith(method + "_")]:
            shader(name)  # build now, so a broken shader fails here and not mid-redraw

    def set_params(self, params):
        """Takes the values if the library accepts them all (with the others in use), else raises
        GpuParamsError and keeps the previous ones."""
        for k in params:
            if k not in DEFAULTS[self.method]:
                raise GpuFilterError("filter '%s' has no parameter '%s' on the GPU (has: %s)"
                                     % (self.method, k, ", ".join(DEFAULTS[self.method])))
        merged = dict(self.params, **params)
        if merged == self.params:
            return
        why = library_check(self.method, merged)
        if why is not None:
            raise GpuParamsError(why)
        self.params = merged

    def reset(self):
        """taa: forget the history (the next run is a first frame)."""
        self.frames = 0

    def _allocate(self, width, height):
        if self.size == (width, height):
            return
        self.size = (width, height)
        self.frames = 0
        self.output = Target(width, height)
        if self.method == "fxaa":
            self.luma = Target(width, height, ("R32F",))
        elif self.method == "repair":
            self.grey = Target(width, height, ("R32F",))
            self.gradient = Target(width, height, ("R32F",))
            # The 4x4 -> 1 reduction tree of the threshold statistics, down to 1x1.
            self.stats = []
            w, h = width, height
            while True:
                w, h = (w + 3) // 4, (h + 3) // 4
                self.stats.append(Target(w, h))
                if w == 1 and h == 1:
                    break
        elif self.method == "taa":
            # history[i], the output and mark[i] share a framebuffer (MRT: history at slot 0, output at
            # slot 1, mark at slot 2: taa.cpp's historyState, feedback-since-reset + 2 x frames since reset, then
            # the hold's windows, taa.glsl stepHoldWindow).
            self.history_tex = [gpu.types.GPUTexture((width, height), format="RGBA32F") for _ in range(2)]
            self.mark_tex = [gpu.types.GPUTexture((width, height), format="RGBA32F") for _ in range(2)]
            self.history_fb = [gpu.types.GPUFrameBuffer(color_slots=(t, self.output.texture, m))
                               for t, m in zip(self.history_tex, self.mark_tex)]
            self.current = 0
            self.zero_motion = gpu.types.GPUTexture((width, height), format="RGBA32F")

    def run(self, color, width, height, motion=None):
        """Filters the RGBA32F texture `color` (width x height); returns the output texture.
        motion (taa only): an RGBA32F texture of pixel offsets previous - current, or None (static)."""
        self._allocate(width, height)
        p = dict(self.params, rowsUp=1 if self.rows_up else 0)
        if self.method == "fxaa":
            run_pass("fxaa_luma", self.luma, {"colorImage": color})
            run_pass("fxaa_resolve", self.output, {"colorImage": color, "lumaImage": self.luma.texture},
                     _constants("fxaa", p))
        elif self.method == "repair":
            run_pass("repair_grey", self.grey, {"colorImage": color})
            run_pass("repair_gradient", self.gradient, {"greyImage": self.grey.texture}, _constants("repair", p))
            run_pass("repair_stats", self.stats[0], {"gradientImage": self.gradient.texture})
            for lower, upper in zip(self.stats, self.stats[1:]):
                run_pass("repair_reduce", upper, {"statsImage": lower.texture})
            run_pass("repair_resolve", self.output,
                     {"colorImage": color, "gradientImage": self.gradient.texture,
                      "statsImage": self.stats[-1].texture}, _constants("repair", p))
        else:
            self._run_taa(color, width, height, motion)
        return self.output.texture

    def _run_taa(self, color, width, height, motion):
        p = dict(self.params)
        space = _choice_index("clipSpace", p["clipSpace"])
        if self.frames > 0 and space != self.history_space:
            self.reset()  # the history is stored in the clip space (taa.cpp Kernel::run)
        self.history_space = space
        p["hasHistory"] = 1 if self.frames > 0 else 0
        p["hasMotion"] = 1 if motion is not None else 0
        # The hold's windows (temporal/hold_release.h): aligned on the frames since reset, restarted for a
        # new period (as taa.cpp Kernel::run).
        period = int(p["holdPeriod"])
        p["holdWindowEnd"] = 1 if period > 0 and (self.frames + 1) % period == 0 else 0
        p["holdWindowsFresh"] = 1 if period != self.hold_windows_period else 0
        p["holdLimit"] = hold_window_limit(float(p["holdRelease"]), period)
        self.hold_windows_period = period
        for b in ("staticAccumulation", "staticClip"):
            p[b] = 1 if p[b] else 0
        previous, nxt = self.history_tex[self.current], 1 - self.current
        target = Target.__new__(Target)
        target.width, target.height = width, height
        target.framebuffer = self.history_fb[nxt]
        samplers = {"colorImage": color, "historyImage": previous, "motionImage": motion or self.zero_motion,
                    "markImage": self.mark_tex[self.current]}
        run_pass("taa_resolve", target, samplers, _constants("taa", p))
        if float(p["sharpen"]) > 0.0:
            run_pass("taa_sharpen", self.output, {"colorImage": color, "historyImage": self.history_tex[nxt],
                                                  "motionImage": self.zero_motion, "markImage": self.mark_tex[nxt]},
                     _constants("taa", p))
        self.current = nxt
        self.frames += 1

    def history(self):
        """taa: the history written by the last run (flat RGBA floats)."""
        t = Target.__new__(Target)
        t.width, t.height = self.size
        t.framebuffer = gpu.types.GPUFrameBuffer(color_slots=self.history_tex[self.current])
        return t.read()


def draw_display(texture, width, height, x=0, y=0):
    """Draws `texture` (linear RGBA) into the bound framebuffer's pixels [x, x+width) x [y, y+height), opaque, as
    the 3D view's overlay buffer wants it (DISPLAY_PASS)."""
    sh = shader("display")
    batch = _fullscreen_batch(sh)
    gpu.state.viewport_set(x, y, width, height)
    sh.bind()
    sh.uniform_sampler("colorImage", texture)
    sh.uniform_int("offset", (x, y))
    batch.draw(sh)
