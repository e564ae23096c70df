# SPDX-License-Identifier: GPL-2.0-or-later
"""Running unittest inside Blender WITH a window (the gpu module refuses background mode, BLENDER.md):
the test file registers its cases with run(); they start from a bpy.app.timers callback once the
window exists, and the process exits with 0/1 through os._exit (no window-manager shutdown to hang)."""

import os
import sys
import traceback

HERE = os.path.dirname(os.path.abspath(__file__))
SOURCE_DIR = os.environ.get("CRISP_SOURCE_DIR") or os.path.dirname(os.path.dirname(HERE))
BUILD_DIR = os.environ.get("CRISP_BUILD_DIR") or os.path.join(SOURCE_DIR, "build")
ADDON_DIR = os.path.join(SOURCE_DIR, "addon")
LIBRARY = os.environ.get("CRISP_LIBRARY") or os.path.join(BUILD_DIR, "lib", "libcrisp.so")
for p in (ADDON_DIR, os.path.join(SOURCE_DIR, "tests", "blender")):
    if p not in sys.path:
        sys.path.insert(0, p)


def run(*cases, delay=0.5, ready=None, wait_s=60.0):
    """Runs the cases from a timer once Blender's window is up, and once ready() (if given) is true or
    wait_s has passed (a loaded machine handles the screen late); exits 1 on failure or error."""
    import time

    import bpy
    deadline = time.monotonic() + wait_s

    def start():
        if ready is not None and not ready() and time.monotonic() < deadline:
            return 0.1  # the timer fires again after the window manager's next pass
        code = 1
        try:
            import harness  # tests/blender/harness.py: unittest with timings, exits with sys.exit
            harness.run(*cases)
        except SystemExit as e:
            code = int(e.code or 0)
        except Exception:
            traceback.print_exc()
        sys.stdout.flush()
        sys.stderr.flush()
        os._exit(code)

    bpy.app.timers.register(start, first_interval=delay)
