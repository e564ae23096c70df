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


def run_scenarios(*scenarios, delay=0.5, timeout_s=300.0):
    """For what needs Blender's event loop between its steps (a modal operator): each scenario is a
    generator function that yields the seconds to wait before its next step, and raises (an assert)
    to fail. They run one after another from a timer once the window is up; exits 1 if any failed or
    ran past timeout_s."""
    import time

    import bpy
    queue, failed = list(scenarios), []
    current = {}

    def finish():
        print("%d passed, %d failed%s" % (len(scenarios) - len(failed), len(failed),
                                          ": " + ", ".join(failed) if failed else ""))
        sys.stdout.flush()
        sys.stderr.flush()
        os._exit(1 if failed else 0)

    def tick():
        if not current:
            if not queue:
                finish()
            scenario = queue.pop(0)
            current.update(name=scenario.__name__, steps=scenario(), deadline=time.monotonic() + timeout_s,
                           t0=time.monotonic())
            print("%s ..." % current["name"])
        try:
            if time.monotonic() > current["deadline"]:
                raise TimeoutError("%s ran past %.0f s" % (current["name"], timeout_s))
            return next(current["steps"])
        except StopIteration:
            print("%s ok (%.1f s)" % (current["name"], time.monotonic() - current["t0"]))
        except Exception:
            traceback.print_exc()
            failed.append(current["name"])
        current.clear()
        return 0.01

    bpy.app.timers.register(tick, first_interval=delay, persistent=True)  # a scenario may load a file
