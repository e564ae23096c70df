# SPDX-License-Identifier: Apache-2.0
"""What the Python tests share: where the build is, and reading a frame's colour through libcrisp's C
API with ctypes (an independent path to the pixels, not the add-on's native.py), with the PSNR of
metrics.h on top. Not a test module (CTest runs tests/python/test_*.py)."""

import ctypes
import math
import os
import shutil
import subprocess
import tempfile

import numpy as np

SOURCE = os.environ.get("CRISP_SOURCE_DIR") or os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))
BUILD = os.environ.get("CRISP_BUILD_DIR") or os.path.join(SOURCE, "build")
CRISP = os.path.join(BUILD, "bin", "crisp")
LIBRARY = os.path.join(BUILD, "lib", "libcrisp.so")


def run_crisp(*args, ok=True):
    """Runs the built CLI with args (paths and numbers as text); with ok, asserts it exits 0 (its stderr
    as the message). Returns the CompletedProcess, output captured as text."""
    p = subprocess.run([CRISP, *map(str, args)], capture_output=True, text=True, timeout=120)
    if ok:
        assert p.returncode == 0, p.stderr
    return p


def needs_cli_and_blender():
    """pytest marks of a module that runs the built CLI with Blender: skipped where either is missing."""
    import pytest
    return [pytest.mark.skipif(not os.path.isfile(CRISP), reason="crisp CLI not built at %s" % CRISP),
            pytest.mark.skipif(shutil.which("blender") is None, reason="blender not installed")]


def addon_with_spinning_cube_ending(tmp_path, code):
    """A copy of this tree's add-on and test scenes whose spinning_cube script ends with `code`; returns
    the add-on folder, for CRISP_ADDON_DIR."""
    tree = os.path.join(str(tmp_path), "tree")
    for d in ("addon", "test_scenes"):
        shutil.copytree(os.path.join(SOURCE, d), os.path.join(tree, d))
    with open(os.path.join(tree, "test_scenes", "spinning_cube.py"), "a") as f:
        f.write("\n\n" + "".join(line + "  # noqa: E402\n" if line.startswith("import ") else line + "\n"
                                   for line in code.splitlines()))
    return os.path.join(tree, "addon")


def run_eval(args, prefix, timeout=900):
    """Runs `crisp eval ARGS -o OUT` into a new temporary folder OUT; returns (OUT, stdout, stderr) of a run
    that must succeed. The caller removes OUT."""
    out = tempfile.mkdtemp(prefix=prefix)
    p = subprocess.run([CRISP, "eval"] + args + ["-o", out], stdout=subprocess.PIPE, stderr=subprocess.PIPE,
                       timeout=timeout)
    assert p.returncode == 0, p.stderr.decode()[-3000:]
    return out, p.stdout.decode(), p.stderr.decode()


class Lib:
    """The three C API calls needed to read a frame's colour pass."""

    def __init__(self):
        self.lib = ctypes.CDLL(LIBRARY)
        self.lib.crispNewContext.restype = ctypes.c_void_p
        self.lib.crispLoadFrame.restype = ctypes.c_void_p
        self.lib.crispLoadFrame.argtypes = [ctypes.c_void_p, ctypes.c_char_p]
        self.lib.crispGetFramePass.restype = ctypes.c_void_p
        self.lib.crispGetFramePass.argtypes = [ctypes.c_void_p, ctypes.c_char_p, ctypes.POINTER(ctypes.c_int)]
        for f in ("crispGetFrameWidth", "crispGetFrameHeight"):
            getattr(self.lib, f).argtypes = [ctypes.c_void_p]
        self.lib.crispReleaseFrame.argtypes = [ctypes.c_void_p]
        self.ctx = self.lib.crispNewContext()

    def color(self, path):
        frame = self.lib.crispLoadFrame(self.ctx, path.encode())
        assert frame, "libcrisp could not load %s" % path
        try:
            w, h = self.lib.crispGetFrameWidth(frame), self.lib.crispGetFrameHeight(frame)
            fmt = ctypes.c_int()
            ptr = self.lib.crispGetFramePass(frame, b"color", ctypes.byref(fmt))
            assert ptr and fmt.value == 4, "no RGBA colour in %s" % path  # CRISP_FORMAT_FLOAT4
            return np.ctypeslib.as_array((ctypes.c_float * (w * h * 4)).from_address(ptr)).reshape(h, w, 4).copy()
        finally:
            self.lib.crispReleaseFrame(frame)


def display(linear):
    """metrics.h: linear RGB clamped to [0,1], sRGB-encoded (IEC 61966-2-1)."""
    c = np.clip(linear[..., :3].astype(np.float64), 0.0, 1.0)
    return np.where(c <= 0.0031308, 12.92 * c, 1.055 * np.power(c, 1 / 2.4) - 0.055)


def psnr(ref, test):
    mse = np.mean((display(ref) - display(test)) ** 2)
    return 100.0 if mse == 0 else min(100.0, 10 * math.log10(1.0 / mse))
