# SPDX-License-Identifier: GPL-2.0-or-later
"""Parity of the GLSL filters (shaders/*.glsl through addon/crisp/gpu_filters.py) with the library
(libcrisp through addon/crisp/native.py, ctypes): the same synthetic input buffers go to both, the
shader output is read back, and the max / mean absolute differences must stay within the tolerances
stated in TOLERANCES (why each is what it is: beside it). Runs in Blender with a window under Xvfb."""

import ctypes
import math
import os
import random
import sys
import unittest

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import gui_harness  # noqa: E402

from crisp import gpu_filters, native  # noqa: E402

W, H = 128, 96

# (max abs, mean abs) over all RGBA values. The shaders mirror the reference path operation for
# operation, so what is left is float rounding of different functions (pow/sqrt/atan approximations,
# possible fma contraction, float vs double statistics), i.e. ~1e-6 of values in [0, 2]. A decision
# flipped by one ulp at a threshold (FXAA's contrast/search ends, REPAIR's edge threshold T, the angle
# fold) moves one pixel by up to the local contrast; such values ("flipped": beyond the method's max
# tolerance) must stay under FLIP_FRACTION, and all other values must meet TOLERANCES.
# Measured on llvmpipe (Mesa 22.3): fxaa <= 7.1e-6 / 8e-9, repair <= 6.7e-6 / 1.4e-8 (one case with
# 0.05% flipped values), taa <= 1.4e-6 / 6.2e-8 (the unjitter weights are float here, double-rounded in
# C++); tolerances ~3x above.
TOLERANCES = {
    "fxaa": (2e-5, 5e-8),
    "repair": (2e-5, 2e-7),  # the thesis estimator's float atan on noise: 7.3e-8
    "taa": (5e-6, 1e-7),  # moving pixels' unjitter weights: Blackman-Harris in float here, double in C++
}
FLIP_FRACTION = 0.001   # at most this fraction of values may flip (measured: 0.055% in one case, 0 elsewhere)


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


def library_filter(method, frames, params):
    """Runs the library on each frame in turn (one filter object: taa history carries over); frames is a
    list of (rgba list, per-frame params). Returns the last output as a flat list."""
    with native.Context() as ctx:
        f = native.Filter(ctx, method)
        try:
            for k, v in params.items():
                f.set_param(k, v)
            out = (ctypes.c_float * (W * H * 4))()
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
            return list(out)
        finally:
            f.close()


def gpu_filter(method, frames, params):
    g = gpu_filters.GpuFilter(method, params)
    for rgba, extra in frames:
        extra = dict(extra)
        motion = extra.pop("motion", None)
        g.set_params(extra)
        tex = gpu_filters.texture_from_rgba(W, H, rgba)
        g.run(tex, W, H, motion=None if motion is None else gpu_filters.texture_from_rgba(W, H, motion))
    return g.output.read()


def differences(a, b, flip_threshold):
    diffs = [abs(x - y) for x, y in zip(a, b)]
    kept = [d for d in diffs if d <= flip_threshold]
    return max(diffs), sum(diffs) / len(diffs), 1.0 - len(kept) / len(diffs), max(kept), sum(kept) / len(kept)


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


def moving_frames(n, vx, vy, **params):
    """n frames of the chart sliding by (vx, vy) px per frame (y down); motion = previous - current."""
    motion = [-vx, -vy, 0.0, 0.0] * (W * H)
    return [(chart_image(-vx * k, -vy * k), dict(params, motion=motion)) for k in range(n)]


RESULTS = []


class GpuParity(unittest.TestCase):
    @classmethod
    def setUpClass(cls):
        os.environ.setdefault("CRISP_LIBRARY", gui_harness.LIBRARY)
        native.load()

    def check(self, label, method, frames, params):
        ref = library_filter(method, frames, params)
        got = gpu_filter(method, frames, params)
        self.assertEqual(len(ref), len(got))
        inp = frames[-1][0]
        changed = sum(1 for i in range(0, len(ref), 4) if abs(ref[i] - inp[i]) > 1e-6
                      and not math.isnan(inp[i]))
        tol_max, tol_mean = TOLERANCES[method]
        mx, mean, flipped, kept_max, kept_mean = differences(ref, got, tol_max)
        line = "parity %-28s max %.3g mean %.3g flipped %.4f%% (library changed %d of %d pixels)" % (
            label, mx, mean, 100 * flipped, changed, W * H)
        print(line, file=sys.stderr)
        RESULTS.append(line)
        self.assertGreater(changed, 50, "the input must exercise the filter")
        self.assertLessEqual(flipped, FLIP_FRACTION, line)
        # Values that did not flip a decision must match to float rounding.
        self.assertLessEqual(kept_mean, tol_mean, line)

    def test_fxaa_chart(self):
        self.check("fxaa chart", "fxaa", [(chart_image(), {})], {})

    def test_fxaa_noise_params(self):
        self.check("fxaa noise subpix=1", "fxaa", [(noise_image(), {})], {"subpix": 1.0, "edgeThreshold": 0.1})

    def test_repair_chart(self):
        self.check("repair chart", "repair", [(chart_image(), {})], {})

    def test_repair_chart_box3_kappa(self):
        self.check("repair chart box3 kappa=-1", "repair", [(chart_image(), {})], {"mask": "box3", "kappa": -1.0})

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

    def test_taa_ycocg_sharpen_bh(self):
        self.check("taa 6 frames ycocg sharpen bh", "taa", taa_frames(6),
                   {"clipSpace": "ycocg", "sharpen": 0.5, "jitterWeighting": "blackman-harris"})

    def test_taa_moving_catmull_rom(self):
        self.check("taa 5 frames moving c-rom", "taa", moving_frames(5, 0.6, 0.35), {})

    def test_taa_moving_bilinear_rgb(self):
        self.check("taa 5 frames moving bilin", "taa", moving_frames(5, -0.45, 0.8),
                   {"historyFilter": "bilinear", "clipSpace": "rgb", "varianceClip": 0.0})

    def test_taa_moving_unjitter_wide_jitter(self):
        # Jitter up to +-2.3 px shifts the unjittered 3x3 by 1 and 2 px (taa.cpp setUnjitter).
        jitters = ((1.3, -0.8), (-1.6, 0.4), (0.2, 1.9), (-0.6, -1.4), (2.3, 0.1))
        frames = [(img, dict(params, jitterX=jx, jitterY=jy))
                  for (img, params), (jx, jy) in zip(moving_frames(5, 0.6, 0.35), jitters)]
        self.check("taa 5 frames moving unjitter", "taa", frames, {})

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
