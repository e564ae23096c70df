# SPDX-License-Identifier: GPL-2.0-or-later
"""Shared set-up of the headless Blender tests: paths from CRISP_SOURCE_DIR / CRISP_BUILD_DIR, the
add-on on sys.path, running unittest inside Blender and exiting non-zero on failure."""

import os
import subprocess
import sys
import time
import unittest

HERE = os.path.dirname(os.path.abspath(__file__))
SOURCE_DIR = os.environ.get("CRISP_SOURCE_DIR") or os.path.dirname(os.path.dirname(HERE))
BUILD_DIR = os.environ.get("CRISP_BUILD_DIR") or os.path.join(SOURCE_DIR, "build")
ADDON_DIR = os.path.join(SOURCE_DIR, "addon")
SCENES_DIR = os.path.join(SOURCE_DIR, "test_scenes")
BATCH = os.path.join(ADDON_DIR, "crisp", "batch.py")
LIBRARY = os.environ.get("CRISP_LIBRARY") or os.path.join(BUILD_DIR, "lib", "libcrisp.so")
for p in (ADDON_DIR, SCENES_DIR, HERE):
    if p not in sys.path:
        sys.path.insert(0, p)

SCENES = ["still_life", "spinning_cube", "camera_dolly", "ghosting", "hairball", "foliage", "shiny", "light_switch"]


def library_usable():
    """(ok, why): the library loads and reads frames (its EXR reader may not have landed yet)."""
    if not os.path.isfile(LIBRARY):
        return False, "no library at %s" % LIBRARY
    os.environ["CRISP_LIBRARY"] = LIBRARY
    from crisp import native
    try:
        native.load()
    except native.CrispError as e:
        return False, str(e)
    return True, LIBRARY


def build_scene(name):
    import importlib
    return importlib.import_module(name).build()


def cut_scene(cut_frame, last_frame):
    """still_life over frames 1..last_frame with a second camera ("CamB", elsewhere and with another lens)
    bound to a timeline marker at cut_frame: a camera cut. The scene's camera stays the first."""
    import common  # test_scenes/common.py
    scene = build_scene("still_life")
    scene.frame_start, scene.frame_end = 1, last_frame
    first = scene.camera
    second = common.camera((3.5, -4.0, 2.0), (0, 0.3, 0.6), lens=40, name="CamB")
    scene.camera = first
    scene.timeline_markers.new("A", frame=1).camera = first
    scene.timeline_markers.new("B", frame=cut_frame).camera = second
    return scene


def blender_batch(args, blend=None, env=None, timeout=300):
    """Runs batch.py in a fresh Blender; returns (returncode, stdout + stderr)."""
    cmd = [sys.argv[0] if sys.argv and sys.argv[0].endswith("blender") else "blender", "-b"]
    if blend:
        cmd.append(blend)
    cmd += ["--factory-startup", "--python-exit-code", "1", "--python", BATCH, "--"] + list(args)
    e = dict(os.environ)
    e.update(env or {})
    p = subprocess.run(cmd, stdout=subprocess.PIPE, stderr=subprocess.STDOUT, env=e, timeout=timeout)
    return p.returncode, p.stdout.decode("utf-8", "replace")


def run(*cases):
    """Runs the test cases, prints timings and 'N passed, N failed', exits 1 on failure."""
    suite = unittest.TestSuite()
    loader = unittest.TestLoader()
    if os.environ.get("CRISP_TEST_PATTERN"):  # a developer's run of some tests: unittest's -k pattern
        loader.testNamePatterns = ["*%s*" % os.environ["CRISP_TEST_PATTERN"]]
    for c in cases:
        suite.addTests(loader.loadTestsFromTestCase(c))

    class Timed(unittest.TextTestResult):
        def startTest(self, test):
            self._t0 = time.perf_counter()
            super().startTest(test)

        def stopTest(self, test):
            print("  [%.2f s] %s" % (time.perf_counter() - self._t0, test.id()), file=sys.stderr, flush=True)
            super().stopTest(test)

    result = unittest.TextTestRunner(verbosity=2, resultclass=Timed, stream=sys.stderr).run(suite)
    failed = len(result.failures) + len(result.errors)
    passed = result.testsRun - failed - len(result.skipped)
    print("%d passed, %d failed%s" % (passed, failed, ", %d skipped" % len(result.skipped) if result.skipped else ""),
          flush=True)
    sys.exit(1 if failed else 0)
