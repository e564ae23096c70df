# SPDX-License-Identifier: GPL-2.0-or-later
"""Parity of the GLSL filters (shaders/*.glsl through addon/crisp/gpu_filters.py) with the library
(libcrisp through addon/crisp/native.py, ctypes): the same synthetic input buffers go to both, the
shader output is read back, and the differences must stay within the tolerances stated in TOLERANCES
and FLIP_FRACTION (why each is what it is: beside it). Each filter is also run on the rows uploaded
bottom-up, as the viewport holds them (rows_up, common.glsl "Row order"), and must give the library's
result all the same. Runs in Blender with a window under Xvfb."""

import contextlib
import ctypes
import math
import os
import random
import sys
import unittest

import numpy as np  # Blender's bundled numpy

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import gui_harness  # noqa: E402

from crisp import gpu_filters, native  # noqa: E402

W, H = 128, 96

# (max, mean) of |library - GPU| / scale over all RGBA values, scale = max(1, the largest |input value|
# within RADIUS pixels): the shaders mirror the reference path operation for operation, so what is
# left is float rounding of different functions (pow/sqrt/atan approximations, possible fma contraction,
# float vs double statistics), relative to the operands. Relative, because the noise input's +-Inf
# (sanitised to +-65504) spreads into its neighbours' outputs (REPAIR: values ~4000 that differ by up to
# 0.029, i.e. 4.4e-7 of 65504: rounding, not a changed decision).
# Measured on llvmpipe (Mesa 22.3), both row orders (max / mean): fxaa 6.6e-6 / 6.2e-9, repair 2.3e-6 /
# 5.5e-8, taa 1.3e-6 / 7.6e-8; tolerances ~3x above (repair's max: as fxaa's). Largest absolute
# difference: 0.0205 (repair noise, beside the sanitised Inf), else 7.1e-6.
TOLERANCES = {
    "fxaa": (2e-5, 5e-8),
    "repair": (2e-5, 2e-7),  # the thesis estimator's float atan on noise: mean 5.5e-8
    # Moving pixels' unjitter weights: Blackman-Harris in float here, double in C++; the largest mean is a
    # moving case with the rows up (Catmull-Rom taps summed in the mirrored order).
    "taa": (5e-6, 2e-7),
}
RADIUS = 4  # the farthest input an output mixes: REPAIR's rotated 5x5 mask, 2 sqrt(2) px, + 1 (bilinear)
# A decision flipped by one ulp at a threshold (FXAA's contrast/search ends, REPAIR's edge threshold T,
# the angle fold) on another driver's sqrt/atan: such values ("flipped": beyond the tolerance) may be at
# most this fraction, and each must stay within its channel's input range over the RADIUS window (both
# outcomes of the decision mix inputs from there; farther is a bug, not a flip). Every frame's output is
# checked, each against this fraction. Measured (llvmpipe, the worst frame of each case): taa's still
# pixels whose history lies on the edge of the clip box, where the last bit decides between averaging
# and not (gone with staticClip off): "hold 3, change at 9" 0.085% of the values, by up to 0.0023 of the
# local range, "darker at 9" 0.039%, "staticClip=True, change at 6" 0.031%; REPAIR beside the noise's
# sanitised Inf at 127x93, 0.025% (0.021 of the range); none in the other cases.
FLIP_FRACTION = 0.001


def chart(x, y, t=0.0):
    """A rotated-edge chart, point-sampled at continuous position (x, y) (pixels, y down): a dark disc with
    a bright rotated square inside, thin rotated lines and an HDR stripe; t rotates it a little."""
    cx, cy = W * 0.5, H * 0.5
    dx, dy = x - cx, y - cy
    r = math.hypot(dx, dy)
    a = math.radians(17.0 + t)
    u, v = dx * math.cos(a) + dy * math.sin(a), -dx * math.sin(a) + dy * math.cos(a)
    if abs(u) < 18 and abs(v) < 14:
        return (0.9, 0.8, 0.3)
    if r < 40:
        return (0.05, 0.1, 0.4)
    # thin lines at 5 and 60 degrees
    for ang, off in ((5.0, 0.0), (60.0, 10.0)):
        b = math.radians(ang)
        if abs(-(x - 20) * math.sin(b) + (y - 20 - off) * math.cos(b)) < 0.6:
            return (1.0, 1.0, 1.0)
    if 100 < x + 0.3 * y < 104:
        return (4.0, 3.0, 2.0)  # HDR
    return (0.2, 0.25, 0.2)


def chart_image(jx=0.0, jy=0.0):
    out = []
    for y in range(H):
        for x in range(W):
            out.extend(chart(x + 0.5 + jx, y + 0.5 + jy))
            out.append(1.0)
    return out


def noise_image(seed=7):
    rng = random.Random(seed)
    out = []
    for i in range(W * H):
        c = [rng.random() ** 2 * (3.0 if i % 97 == 0 else 1.0) for _ in range(3)]
        out.extend(c + [rng.random()])
    # non-finite input must be sanitised the same way on both sides
    out[4 * 10 + 0] = float("nan")
    out[4 * 500 + 1] = float("inf")
    out[4 * 900 + 2] = float("-inf")
    return out


def shaded_image(seed=3):
    """A render's flat areas and soft shading: the left half one colour with float-rounding noise (values
    a few 1e-7 apart, as a render's flat wall: Sobel values of ~1e-7 that round to exactly 0 on one side
    and not on the other), the right half a radial falloff whose gradient takes every value from 0 up,
    so that some lie near REPAIR's threshold T, with a bright disc for edges."""
    rng = random.Random(seed)
    out = []
    for y in range(H):
        for x in range(W):
            if x < W // 2:
                v = 0.2 * (1.0 + 3e-7 * (2.0 * rng.random() - 1.0))
                c = (v, v * 1.1, v * 0.9)
            else:
                d = math.hypot(x - 0.75 * W, y - 0.5 * H) / (0.5 * H)
                v = 0.05 + 0.8 * max(0.0, 1.0 - d * d)
                c = (1.0, 0.9, 0.6) if d < 0.3 else (v, v * 0.8, v * 0.6)
            out.extend(c + (1.0,))
    return out


def library_filter(method, frames, params, every=False):
    """Runs the library on each frame in turn (one filter object: taa history carries over); frames is a
    list of (rgba list, per-frame params). Returns the last output as a flat list (every: each frame's)."""
    with native.Context() as ctx:
        f = native.Filter(ctx, method)
        try:
            for k, v in params.items():
                f.set_param(k, v)
            out = (ctypes.c_float * (W * H * 4))()
            outputs = []
            for rgba, extra in frames:
                extra = dict(extra)
                motion = extra.pop("motion", None)
                buf = (ctypes.c_float * (W * H * 4))(*rgba)
                for k, v in extra.items():
                    f.set_param(k, v)
                f.set_image("color", ctypes.addressof(buf), native.FORMAT_FLOAT4, W, H)
                if motion is not None:
                    mbuf = (ctypes.c_float * (W * H * 4))(*motion)
                    f.set_image("motion", ctypes.addressof(mbuf), native.FORMAT_FLOAT4, W, H)
                f.set_image("output", ctypes.addressof(out), native.FORMAT_FLOAT4, W, H)
                f.commit()
                f.execute()
                outputs.append(list(out))
            return outputs if every else outputs[-1]
        finally:
            f.close()


def mirrored(rgba):
    """A flat RGBA image with its rows in the other order."""
    rows = [rgba[y * W * 4:(y + 1) * W * 4] for y in range(H)]
    return [v for row in reversed(rows) for v in row]


def bottom_up(frames):
    """The frames as a texture with row 0 at the bottom holds them (the viewport's order): rows reversed,
    taa's jitterY and motion's y along the texture's rows, i.e. negated (common.glsl "Row order")."""
    out = []
    for rgba, extra in frames:
        extra = dict(extra)
        if "jitterY" in extra:
            extra["jitterY"] = -extra["jitterY"]
        if "motion" in extra:
            motion = list(extra["motion"])
            motion[1::4] = [-v for v in motion[1::4]]
            extra["motion"] = mirrored(motion)
        out.append((mirrored(rgba), extra))
    return out


def gpu_filter(method, frames, params, rows_up=False):
    """The GPU's output of each frame, row 0 at the top; rows_up: run on the frames uploaded bottom-up."""
    g = gpu_filters.GpuFilter(method, params, rows_up=rows_up)
    outputs = []
    for rgba, extra in bottom_up(frames) if rows_up else frames:
        extra = dict(extra)
        motion = extra.pop("motion", None)
        g.set_params(extra)
        tex = gpu_filters.texture_from_rgba(W, H, rgba)
        g.run(tex, W, H, motion=None if motion is None else gpu_filters.texture_from_rgba(W, H, motion))
        out = g.output.read()
        outputs.append(mirrored(out) if rows_up else out)
    return outputs


def input_extremes(frames):
    """Per RGBA value: the largest |input| over the RGBA values of the RADIUS window around its pixel, and
    its channel's input range (max - min) there; over all frames, sanitised as the filters read them."""
    size = 2 * RADIUS + 1
    magnitude, spread = np.zeros((H, W, 4)), np.zeros((H, W, 4))
    for rgba, _ in frames:
        a = np.clip(np.nan_to_num(np.asarray(rgba, dtype=np.float64).reshape(H, W, 4), nan=0.0, posinf=65504.0,
                                  neginf=-65504.0), -65504.0, 65504.0)
        padded = np.pad(a, ((RADIUS, RADIUS), (RADIUS, RADIUS), (0, 0)), mode="edge")
        windows = [padded[dy:dy + H, dx:dx + W] for dy in range(size) for dx in range(size)]
        lo, hi = np.min(windows, axis=0), np.max(windows, axis=0)
        magnitude = np.maximum(magnitude, np.maximum(np.abs(lo), np.abs(hi)).max(axis=2, keepdims=True))
        spread = np.maximum(spread, hi - lo)
    return magnitude.ravel(), spread.ravel()


def differences(ref, got, frames, tolerance):
    """(max |d|, max |d| / scale, mean |d| / scale of the values within tolerance, fraction flipped, the
    flipped values' largest |d| / their channel's input range over the window)."""
    magnitude, spread = input_extremes(frames)
    d = np.abs(np.asarray(ref, dtype=np.float64) - np.asarray(got, dtype=np.float64))
    relative = d / np.maximum(1.0, magnitude)
    kept = relative <= tolerance  # NaN is never kept
    flipped = ~kept
    worst_flip = float(np.max(np.where(flipped, d / np.maximum(spread, 1e-30), 0.0))) if flipped.any() else 0.0
    if np.isnan(d).any():
        worst_flip = math.inf
    return float(np.nanmax(d)), float(np.nanmax(relative)), float(relative[kept].mean()), float(flipped.mean()), \
        worst_flip


def taa_frames(n):
    """n frames of the chart jittered by Halton(2,3) (uniform in the pixel), zero motion."""
    def radical_inverse(i, base):
        r, f = 0.0, 1.0 / base
        while i:
            r += (i % base) * f
            i //= base
            f /= base
        return r
    frames = []
    for k in range(n):
        jx, jy = radical_inverse(k + 1, 2) - 0.5, radical_inverse(k + 1, 3) - 0.5
        frames.append((chart_image(jx, jy), {"jitterX": jx, "jitterY": jy}))
    return frames


def changing_frames(n, change, period=3):
    """n frames of the chart jittered through `period` Halton points (a periodic input), the right half 0.3
    brighter from frame `change` on: a persistent change inside held pixels' boxes along the new edge."""
    jittered = taa_frames(period)
    frames = []
    for k in range(n):
        image, params = jittered[k % period]
        if k >= change:
            image = list(image)
            for i in range(0, len(image), 4):
                if (i // 4) % W >= W // 2:
                    for c in range(3):
                        image[i + c] += 0.3
        frames.append((image, params))
    return frames


def moving_frames(n, vx, vy, **params):
    """n frames of the chart sliding by (vx, vy) px per frame (y down); motion = previous - current."""
    motion = [-vx, -vy, 0.0, 0.0] * (W * H)
    return [(chart_image(-vx * k, -vy * k), dict(params, motion=motion)) for k in range(n)]


# Jitter up to +-2.3 px: the unjittered 3x3 shifts by 1 and 2 px (temporal/jitter.cpp unjitterFor).
WIDE_JITTERS = ((1.3, -0.8), (-1.6, 0.4), (0.2, 1.9), (-0.6, -1.4), (2.3, 0.1), (0.4, 0.4))


def swirl_frames(n):
    """n frames of the chart at WIDE_JITTERS with a motion field that varies from pixel to pixel (a turn
    about the centre, up to about 1 px per frame at the corners): each pixel reprojects from elsewhere,
    and the motion is read at the shifted pixel."""
    cx, cy = W * 0.5, H * 0.5
    motion = []
    for y in range(H):
        for x in range(W):
            motion += [0.012 * (y + 0.5 - cy), -0.012 * (x + 0.5 - cx), 0.0, 0.0]
    return [(chart_image(jx, jy), {"jitterX": jx, "jitterY": jy, "motion": motion})
            for jx, jy in WIDE_JITTERS[:n]]


def with_alpha(frames):
    """The frames with an alpha that varies across the image."""
    out = []
    for rgba, params in frames:
        rgba = list(rgba)
        for i in range(W * H):
            rgba[4 * i + 3] = 0.25 + 0.7 * ((i % W) * 7 + (i // W) * 3) % 11 / 10.0
        out.append((rgba, params))
    return out


def colour_of_preview(ref, got):
    """The preview's output with the library's alpha: the library filters a transparent render's alpha
    (native/filters/temporal_alpha.h, kept in [0, 1]) where the preview, which draws opaque, passes the
    input's through, so only the colour is compared."""
    assert all(0.0 <= a <= 1.0 for a in ref[3::4]), "the library's filtered alpha is in [0, 1]"
    got = list(got)
    got[3::4] = ref[3::4]
    return got


@contextlib.contextmanager
def image_size(width, height):
    """The images of the cases inside at another size (W and H are read by every helper above)."""
    global W, H
    saved = W, H
    W, H = width, height
    try:
        yield
    finally:
        W, H = saved


RESULTS = []


class GpuParity(unittest.TestCase):
    @classmethod
    def setUpClass(cls):
        os.environ.setdefault("CRISP_LIBRARY", gui_harness.LIBRARY)
        native.load()

    def check(self, label, method, frames, params, rows_up=False, colour_only=False):
        """Every frame's output (a first frame's reset path too), each within the tolerances; the figures
        printed are the worst over the frames. colour_only: the library filters a transparent render's alpha
        (native/filters/temporal_alpha.h) where the preview, which draws opaque, passes the input's through;
        the alphas are checked to be those and the colour is compared."""
        refs = library_filter(method, frames, params, every=True)
        gots = gpu_filter(method, frames, params, rows_up)
        self.assertEqual(len(refs), len(gots))
        tol_max, tol_mean = TOLERANCES[method]
        worst = [0.0] * 5
        for k, (ref, got) in enumerate(zip(refs, gots)):
            self.assertEqual(len(ref), len(got))
            if colour_only:
                inp = np.clip(np.nan_to_num(np.asarray(frames[k][0][3::4], dtype=np.float64), nan=0.0,
                                            posinf=65504.0, neginf=-65504.0), -65504.0, 65504.0)
                self.assertTrue(np.allclose(got[3::4], inp, rtol=0, atol=1e-6), "the preview's alpha is the input's")
                if k > 0:  # the first frame's filtered alpha is the input's mix, not the input
                    self.assertGreater(float(np.abs(np.asarray(ref[3::4]) - inp).max()), 0.01,
                                       "the library filters the alpha")
                got = colour_of_preview(ref, got)
            figures = differences(ref, got, frames[:k + 1], tol_max)
            worst = [max(a, b) for a, b in zip(worst, figures)]
        mx, rel_max, rel_mean, flipped, worst_flip = worst
        ref, inp = refs[-1], frames[-1][0]
        changed = sum(1 for i in range(0, len(ref), 4) if abs(ref[i] - inp[i]) > 1e-6
                      and not math.isnan(inp[i]))
        label += " (rows up)" if rows_up else ""
        line = ("parity %-38s max %.3g (relative %.3g, mean %.3g) flipped %.4f%% (worst %.3g of the local range); "
                "library changed %d of %d pixels" % (label, mx, rel_max, rel_mean, 100 * flipped, worst_flip,
                                                      changed, W * H))
        print(line, file=sys.stderr)
        RESULTS.append(line)
        self.assertGreater(changed, 50, "the input must exercise the filter")
        self.assertLessEqual(flipped, FLIP_FRACTION, line)
        self.assertLessEqual(worst_flip, 1.0, line + ": a flipped value beyond the inputs it can mix")
        # Values that did not flip a decision must match to float rounding.
        self.assertLessEqual(rel_mean, tol_mean, line)

    def test_fxaa_chart(self):
        self.check("fxaa chart", "fxaa", [(chart_image(), {})], {})

    def test_fxaa_noise_params(self):
        self.check("fxaa noise subpix=1", "fxaa", [(noise_image(), {})], {"subpix": 1.0, "edgeThreshold": 0.1})

    def test_repair_chart(self):
        self.check("repair chart", "repair", [(chart_image(), {})], {})

    def test_repair_chart_box3_kappa(self):
        self.check("repair chart box3 kappa=-1", "repair", [(chart_image(), {})], {"mask": "box3", "kappa": -1.0})

    def test_repair_shaded_with_flat_areas(self):
        # REPAIR's threshold counts the non-black gradient pixels: it counted the exactly non-zero ones, and
        # which of a flat area's ~1e-7 Sobel values round to 0 differs between the two sides (0.86 % of the
        # values of a 528x297 viewport image beyond the tolerance).
        with image_size(264, 150):
            self.check("repair shaded 264x150", "repair", [(shaded_image(), {})], {})

    def test_repair_noise_thesis(self):
        self.check("repair noise thesis n=7", "repair", [(noise_image(), {})],
                   {"angleEstimator": "thesis", "patchSize": 7})

    def test_taa_static_8_frames(self):
        self.check("taa 8 frames jittered", "taa", taa_frames(8), {})

    def test_taa_hold(self):
        # taa.cpp "Hold": with a period of 3 the static pixels stop averaging from the 4th frame; the
        # sharpen pass then reads the held history.
        self.check("taa 8 frames hold 3", "taa", taa_frames(8), {"holdPeriod": 3})
        self.check("taa 8 frames hold 3 sharpen", "taa", taa_frames(8), {"holdPeriod": 3, "sharpen": 0.5})

    def test_taa_hold_release(self):
        # taa.cpp "Hold", temporal/hold_release.h: windows of 3 frames; the change at frame 9 differs from the
        # baseline in the windows closed at frames 11 and 14, which releases the held pixels it reaches.
        frames = changing_frames(20, 9)
        params = {"holdPeriod": 3}
        self.check("taa 20 frames hold 3, change at 9", "taa", frames, params)
        never = library_filter("taa", frames, dict(params, holdRelease=1.0))
        released = library_filter("taa", frames, params)
        self.assertGreater(max(abs(a - b) for a, b in zip(never, released)), 0.01,
                           "the change must release held pixels")
        # The limit gpu_filters.py passes, as temporal::holdWindowLimit computes it (HoldRelease unit tests).
        self.assertEqual(gpu_filters.hold_window_limit(0.002, 16), 8)
        self.assertEqual(gpu_filters.hold_window_limit(1.0, 127), 255 * 127)
        self.assertEqual(gpu_filters.hold_window_limit(-1.0, 16), 0)
        self.assertEqual(gpu_filters.hold_window_limit(float("nan"), 16), 255 * 16)

    def test_taa_ycocg_sharpen_bh(self):
        self.check("taa 6 frames ycocg sharpen bh", "taa", taa_frames(6),
                   {"clipSpace": "ycocg", "sharpen": 0.5, "jitterWeighting": "blackman-harris"})

    def test_taa_moving_catmull_rom(self):
        self.check("taa 5 frames moving c-rom", "taa", moving_frames(5, 0.6, 0.35), {})

    def test_taa_moving_bilinear_rgb(self):
        self.check("taa 5 frames moving bilin", "taa", moving_frames(5, -0.45, 0.8),
                   {"historyFilter": "bilinear", "clipSpace": "rgb", "varianceClip": 0.0})

    def test_taa_moving_unjitter_wide_jitter(self):
        frames = [(img, dict(params, jitterX=jx, jitterY=jy))
                  for (img, params), (jx, jy) in zip(moving_frames(5, 0.6, 0.35), WIDE_JITTERS)]
        self.check("taa 5 frames moving unjitter", "taa", frames, {})

    def test_taa_clip_space_change_resets_history(self):
        # taa.cpp Kernel::run: the history is stored in the clip space, so a new clipSpace starts it over.
        # (Switched at frame 3: from frame 4, Halton frame 5, the chart meets FLIP_FRACTION's ties.)
        frames = [(img, dict(params, clipSpace="rgb" if k < 3 else "ycocg"))
                  for k, (img, params) in enumerate(taa_frames(7))]
        self.check("taa 3 frames rgb, 4 ycocg", "taa", frames, {})

    def test_rows_up_fxaa(self):
        # FXAA's tie-breaks (towards the row above, the lower search end, a horizontal edge on equal sums)
        # are not mirror-symmetric: the chart's one-pixel lines and the noise's dark pixels hit them.
        self.check("fxaa chart", "fxaa", [(chart_image(), {})], {}, rows_up=True)
        self.check("fxaa noise subpix=1", "fxaa", [(noise_image(), {})], {"subpix": 1.0, "edgeThreshold": 0.1},
                   rows_up=True)

    def test_rows_up_repair(self):
        # The thesis estimator's beta1 / alpha1 keeps its sign when the rows are reversed.
        self.check("repair chart thesis", "repair", [(chart_image(), {})], {"angleEstimator": "thesis"},
                   rows_up=True)
        self.check("repair noise thesis n=7", "repair", [(noise_image(), {})],
                   {"angleEstimator": "thesis", "patchSize": 7}, rows_up=True)
        self.check("repair chart", "repair", [(chart_image(), {})], {}, rows_up=True)

    def test_rows_up_taa(self):
        # taa works in texel coordinates: the jitter's and motion's y along the texture's rows.
        self.check("taa 8 frames jittered", "taa", taa_frames(8), {}, rows_up=True)
        self.check("taa 5 frames moving c-rom", "taa", moving_frames(5, 0.6, 0.35), {}, rows_up=True)

    def test_rejected_params_are_not_taken(self):
        # The library's own checks (native.check_params), its message, the previous values kept.
        for method, bad, reason in (("repair", {"patchSize": 6}, "must be odd"),
                                    ("taa", {"feedbackMin": 0.9, "feedbackMax": 0.8}, "must not exceed"),
                                    ("fxaa", {"subpix": 2.0}, "out of range")):
            g = gpu_filters.GpuFilter(method)
            before = dict(g.params)
            with self.assertRaises(gpu_filters.GpuParamsError) as caught:
                g.set_params(bad)
            self.assertIn(reason, str(caught.exception))
            self.assertEqual(g.params, before)
            with self.assertRaises(gpu_filters.GpuParamsError):
                gpu_filters.GpuFilter(method, bad)

    def test_taa_unjitter_modes(self):
        # Wide jitter, so that 'nearest' shifts the 3x3 and 'none' takes the jittered centre as it is.
        # In YCoCg, 'none' outputs a first frame's input as it is, not its round trip through YCoCg.
        frames = [(chart_image(jx, jy), {"jitterX": jx, "jitterY": jy}) for jx, jy in WIDE_JITTERS]
        for mode in ("none", "nearest"):
            for space in ("rgb", "ycocg"):
                self.check("taa 6 frames unjitter=%s %s" % (mode, space), "taa", frames,
                           {"unjitter": mode, "clipSpace": space})

    def test_taa_static_switches(self):
        for params in ({"staticAccumulation": False}, {"maxSamples": 3},
                       {"jitterWeighting": "blackman-harris", "filterSize": 0.8}):
            self.check("taa 8 frames %s" % params, "taa", taa_frames(8), params)
        # A change the still pixels' history must be clipped to (staticClip on) or averaged into (off).
        for clip in (True, False):
            self.check("taa 12 frames staticClip=%s, change at 6" % clip, "taa", changing_frames(12, 6),
                       {"staticClip": clip, "holdPeriod": 0})

    def test_taa_hold_release_darkening(self):
        # As test_taa_hold_release with the right half 0.15 darker from frame 9: the release's other side.
        frames = [(img if k < 9 else [v - 0.15 if i % 4 < 3 and (i // 4) % W >= W // 2 else v
                                      for i, v in enumerate(img)], params)
                  for k, (img, params) in enumerate(changing_frames(20, 99))]
        self.check("taa 20 frames hold 3, darker at 9", "taa", frames, {"holdPeriod": 3})

    def test_taa_alpha_and_non_finite_input(self):
        self.check("taa 6 frames varying alpha", "taa", with_alpha(taa_frames(6)), {}, colour_only=True)
        noisy = [(noise_image(seed=k), params) for k, (_, params) in enumerate(taa_frames(4))]
        self.check("taa 4 frames noise NaN/Inf", "taa", noisy, {}, colour_only=True)

    def test_taa_motion_varying_per_pixel(self):
        self.check("taa 5 frames swirl c-rom", "taa", swirl_frames(5), {})
        self.check("taa 6 frames swirl maxSamples=2", "taa", swirl_frames(6), {"maxSamples": 2})
        self.check("taa 5 frames swirl bilinear", "taa", swirl_frames(5), {"historyFilter": "bilinear"})

    def test_odd_image_size(self):
        # A width that is not a multiple of 4 (repair's 4x4 reduction) and odd dimensions.
        with image_size(127, 93):
            self.check("fxaa chart 127x93", "fxaa", [(chart_image(), {})], {})
            self.check("repair chart 127x93", "repair", [(chart_image(), {})], {})
            self.check("repair noise 127x93", "repair", [(noise_image(), {})], {"angleEstimator": "thesis"})
            self.check("taa 6 frames 127x93", "taa", taa_frames(6), {})
            self.check("taa 5 frames moving 127x93", "taa", moving_frames(5, 0.6, 0.35), {}, rows_up=True)

    def test_parameter_tables_match_the_library(self):
        # gpu_filters' hand copy of the library's tables (crispGetFilterInfo): the same names (those left
        # out are listed with a reason), defaults and choices.
        for method in gpu_filters.METHODS:
            library = {p["name"]: p for p in native.filter_info(method)["params"]}
            ours, left_out = gpu_filters.DEFAULTS[method], gpu_filters.NOT_ON_GPU[method]
            self.assertEqual(set(ours) & set(left_out), set(), method)
            self.assertEqual(set(ours) | set(left_out), set(library), method + ": a parameter the GPU version "
                             "neither has nor lists in NOT_ON_GPU")
            for name, value in ours.items():
                self.assertAlmostEqual(value, library[name]["default"], places=6, msg=(method, name)) \
                    if isinstance(value, float) else self.assertEqual(value, library[name]["default"], (method, name))
                if "choices" in library[name]:
                    self.assertEqual(set(gpu_filters.CHOICES[name]), set(library[name]["choices"]), (method, name))

    def test_params_the_other_cases_leave_at_default(self):
        # Every parameter the preview takes from the panel at a value other than its default at least
        # once (the cases above leave these at theirs), so a shader that used its default in place of
        # the push constant fails here.
        self.check("fxaa chart edgeThresholdMin=0.3", "fxaa", [(chart_image(), {})],
                   {"edgeThresholdMin": 0.3, "edgeThreshold": 0.05})
        # feedbackMin/Max and resampleDamping act on the pixels that do not average: moving ones.
        self.check("taa 5 frames moving feedback, damping", "taa", moving_frames(5, 0.6, 0.35),
                   {"feedbackMin": 0.3, "feedbackMax": 0.95, "resampleDamping": 0.9})
        # holdRelease 1: held pixels are never released (test_taa_hold_release: that differs).
        self.check("taa 20 frames hold 3, holdRelease=1", "taa", changing_frames(20, 9),
                   {"holdPeriod": 3, "holdRelease": 1.0})

    def test_tiny_images_and_non_finite_values(self):
        # Images smaller than every filter's footprint, all of whose pixels are at a border, holding
        # +-Inf, NaN and HDR values: every value within the tolerance, none let through as a flipped
        # decision (in the cases above the few non-finite pixels fit in FLIP_FRACTION, so a shader that
        # sanitised Inf to another value than kMaxColor passed).
        specials = (float("inf"), 0.25, float("-inf"), 1.0, float("nan"), 5.0, 0.5, float("nan"), 0.02, 3.0, 0.7,
                    float("inf"))
        for width, height in ((1, 1), (2, 3), (3, 2)):
            with image_size(width, height):
                image = [specials[(i * 5 + k) % len(specials)] for i in range(W * H) for k in range(4)]
                for method, frames in (("fxaa", [(image, {})]), ("repair", [(image, {})]),
                                       ("taa", [(image, {"jitterX": jx, "jitterY": jy})
                                                for jx, jy in ((0.3, -0.2), (-0.4, 0.1), (0.1, 0.45))])):
                    for rows_up in (False, True):
                        refs = library_filter(method, frames, {}, every=True)
                        gots = gpu_filter(method, frames, {}, rows_up)
                        for k, (ref, got) in enumerate(zip(refs, gots)):
                            if method == "taa":
                                got = colour_of_preview(ref, got)
                            figures = differences(ref, got, frames[:k + 1], TOLERANCES[method][0])
                            self.assertEqual(figures[3], 0.0, "%s %dx%d frame %d%s: %s" % (
                                method, W, H, k, " (rows up)" if rows_up else "", figures))

    def test_taa_half_still_footprint(self):
        # The top half still, the bottom half moving: static pixels near the boundary must not use the
        # footprint box (taa.cpp stillFootprint), the rest must.
        frames = []
        for k, (img, params) in enumerate(taa_frames(6)):
            motion = [0.0, 0.0, 0.0, 0.0] * (W * (H // 2)) + [0.4, -0.3, 0.0, 0.0] * (W * (H - H // 2))
            frames.append((img, dict(params, motion=motion)))
        self.check("taa 6 frames half still", "taa", frames, {})


if __name__ == "__main__":
    gui_harness.run(GpuParity)
