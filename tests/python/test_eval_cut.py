# SPDX-License-Identifier: Apache-2.0
"""`crisp eval` on a shot with a camera cut: still_life saved as a .blend with a second camera bound
to a timeline marker at frame 3 (64x36, frames 1-4, reference 4 samples). The scene facts list the
cut; no entry's temporal error is measured across it (frame 3 has none, as frame 1) and the report
says so; taa's history starts over there, so its frames 3-4 equal `crisp filter` over the jittered
frames 3-4 alone.
Needs Blender and the built CLI and library (CRISP_BUILD_DIR)."""

import json
import math
import os
import shutil
import subprocess
import tempfile

import numpy as np
import pytest

from crisp_test_util import CRISP, LIBRARY, SOURCE, Lib

pytestmark = [
    pytest.mark.skipif(not os.path.isfile(CRISP), reason="crisp CLI not built at %s" % CRISP),
    pytest.mark.skipif(not os.path.isfile(LIBRARY), reason="libcrisp not built at %s" % LIBRARY),
    pytest.mark.skipif(shutil.which("blender") is None, reason="blender not installed"),
]

# tests/blender/harness.py cut_scene, saved as a .blend.
MAKE_CUT = """
import sys
sys.path[:0] = [%r]
import bpy, harness
harness.cut_scene(3, 4)
bpy.ops.wm.save_as_mainfile(filepath=%r)
"""


@pytest.fixture(scope="module")
def evaluated():
    tmp = tempfile.mkdtemp(prefix="crisp_eval_cut_")
    blend = os.path.join(tmp, "cut.blend")
    p = subprocess.run(["blender", "-b", "--factory-startup", "--python-exit-code", "1", "--python-expr",
                        MAKE_CUT % (os.path.join(SOURCE, "tests", "blender"), blend)],
                       stdout=subprocess.PIPE, stderr=subprocess.STDOUT, timeout=300)
    assert p.returncode == 0 and os.path.isfile(blend), p.stdout.decode()[-2000:]
    out = os.path.join(tmp, "eval")
    p = subprocess.run([CRISP, "eval", "--scene", blend, "--resolution", "64x36", "--frames", "1-4",
                        "--reference-samples", "4", "--curve", "1", "--methods", "taa,fxaa", "--quiet", "-o", out],
                       stdout=subprocess.PIPE, stderr=subprocess.PIPE, timeout=600)
    assert p.returncode == 0, p.stderr.decode()[-3000:]
    with open(os.path.join(tmp, "eval_stderr.txt"), "wb") as f:  # what --quiet left on stderr
        f.write(p.stderr)
    yield tmp, out
    shutil.rmtree(tmp, ignore_errors=True)


def measured(v):
    return v is not None and math.isfinite(v)


def test_no_temporal_error_across_the_cut(evaluated):
    _, out = evaluated
    scene = json.load(open(os.path.join(out, "results.json")))["scenes"][0]
    assert scene["facts"]["camera_cuts"] == [3]
    assert "camera cuts (frames 3)" in scene["temporal_error_warp"]
    for m in scene["methods"]:
        te = {f["frame"]: f["temporal_error"] for f in m["frames"]}
        assert not measured(te[1]) and not measured(te[3]), (m["name"], te)
        assert measured(te[2]) and measured(te[4]), (m["name"], te)


def test_taa_starts_over_at_the_cut(evaluated):
    tmp, out = evaluated
    taa_set = json.load(open(os.path.join(out, "renders", "scene.json")))["inputs"]["taa"]
    inputs = [os.path.join(out, "renders", taa_set, "frame_%04d.exr" % f) for f in (3, 4)]
    alone = os.path.join(tmp, "alone")
    p = subprocess.run([CRISP, "filter", "-m", "taa", "--quiet", "-o", alone] + inputs,
                       stdout=subprocess.PIPE, stderr=subprocess.PIPE, timeout=120)
    assert p.returncode == 0, p.stderr.decode()
    lib = Lib()
    for f in (3, 4):
        name = "frame_%04d.exr" % f
        assert np.array_equal(lib.color(os.path.join(out, "methods", "taa", name)), lib.color(os.path.join(alone, name)))


def test_quiet_still_says_where_the_history_starts_over(evaluated):
    """--quiet hides progress and notes, not warnings: the line saying where a temporal method's history
    starts over (docs/farm.md tells users to look for it) was hidden by eval's and render's --quiet."""
    tmp, _ = evaluated
    said = open(os.path.join(tmp, "eval_stderr.txt")).read()
    assert "crisp eval: taa frame 3: history starts over (camera 'CamB' after " in said, said
    assert "fxaa frame" not in said, said  # a spatial method has no history
    # crisp render --quiet drops Blender's and the driver's output, but not this line of the add-on's log.
    out = os.path.join(tmp, "render")
    p = subprocess.run([CRISP, "render", "--scene", os.path.join(tmp, "cut.blend"), "--resolution", "32x18",
                        "--frames", "2-3", "--method", "taa", "--quiet", "-o", out],
                       stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, timeout=600)
    assert p.returncode == 0, p.stderr[-3000:]
    assert "frame 3: temporal history restarts (camera 'CamB' after " in p.stderr, p.stderr
    assert p.stdout == "" and "frame 2" not in p.stderr, p.stdout + p.stderr  # no progress
