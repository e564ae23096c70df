# SPDX-License-Identifier: Apache-2.0
"""RSAA end to end (issue 5): `crisp render --method rsaa` in the real Blender renders the 8 geometric
sub-samples beside the 1-sample frame and filters it through the add-on (native.py, libcrisp);
`crisp filter -m rsaa` on the same input gives the same image bit for bit; missing sub-samples and a
sidecar without the list are clear errors; the plan renders no geometry when no object is visible.

Needs Blender and the built CLI and library (CRISP_BUILD_DIR). Tiny: 96x54, one frame."""

import json
import os
import shutil
import subprocess
import sys
import tempfile

import numpy as np
import pytest

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from crisp_test_util import CRISP, LIBRARY, SOURCE, Lib, display, needs_cli_and_blender, run_eval  # noqa: E402

sys.path.insert(0, os.path.join(SOURCE, "addon", "crisp"))
import plan  # noqa: E402

pytestmark = needs_cli_and_blender()


def env():
    e = dict(os.environ)
    e["CRISP_LIBRARY"] = LIBRARY  # the add-on filters with this build's library
    return e


@pytest.fixture(scope="module")
def rendered():
    out = tempfile.mkdtemp(prefix="crisp_rsaa_")
    p = subprocess.run([CRISP, "render", "--scene", "spinning_cube", "--method", "rsaa", "--resolution", "96x54",
                        "--frames", "1-1", "--reference-samples", "16", "-q", "-o", out],
                       stdout=subprocess.PIPE, stderr=subprocess.PIPE, env=env(), timeout=600)
    assert p.returncode == 0, p.stderr.decode()[-3000:]
    yield out
    shutil.rmtree(out, ignore_errors=True)


def filter_cli(inputs, out):
    return subprocess.run([CRISP, "filter", "-m", "rsaa", "-q", "-o", out] + inputs, stdout=subprocess.PIPE,
                          stderr=subprocess.PIPE, env=env(), timeout=120)


def test_render_writes_subsamples_and_filters_edges(rendered):
    side = json.load(open(os.path.join(rendered, "input", "frame_0001.json")))
    files = [s["file"] for s in side["subsamples"]]
    assert files == ["frame_0001_sub%d.exr" % k for k in range(8)]
    for f in files:
        assert os.path.isfile(os.path.join(rendered, "input", f))
    run = json.load(open(os.path.join(rendered, "run.json")))
    assert run["plan"]["passes"] == ["color", "depth", "normal", "subsamples"]
    assert run["frames"][0]["filter_s"] > 0
    # The eight geometry renders are part of the frame's cost: run.json gives them apart from its render.
    assert run["frames"][0]["geometry_render_s"] == round(sum(s["render_s"] for s in side["subsamples"]), 4) > 0
    lib = Lib()
    src = lib.color(os.path.join(rendered, "input", "frame_0001.exr"))
    out = lib.color(os.path.join(rendered, "filtered", "frame_0001.exr"))
    ref = lib.color(os.path.join(rendered, "reference", "frame_0001.exr"))
    changed = np.any(out[..., :3] != src[..., :3], axis=-1)
    # Only pixels on geometric edges are resampled: some, but few.
    assert 0.002 < changed.mean() < 0.2, changed.mean()
    err_in = np.mean((display(src) - display(ref)) ** 2, axis=-1)[changed].mean()
    err_out = np.mean((display(out) - display(ref)) ** 2, axis=-1)[changed].mean()
    assert err_out < 0.5 * err_in, (err_in, err_out)


def test_cli_filter_equals_the_addon(rendered):
    out = tempfile.mkdtemp(prefix="crisp_rsaa_cli_")
    try:
        p = filter_cli([os.path.join(rendered, "input", "frame_0001.exr")], out)
        assert p.returncode == 0, p.stderr.decode()
        lib = Lib()
        a = lib.color(os.path.join(out, "frame_0001.exr"))
        b = lib.color(os.path.join(rendered, "filtered", "frame_0001.exr"))
        assert np.array_equal(a, b)
    finally:
        shutil.rmtree(out, ignore_errors=True)


def copy_frame(rendered, prefix):
    """A new folder with a copy of frame 1's files (frame, sidecar, sub-samples; times kept); returns
    the folder and the frame's path in it."""
    work = tempfile.mkdtemp(prefix=prefix)
    src = os.path.join(rendered, "input")
    for name in os.listdir(src):
        if name.startswith("frame_0001"):
            shutil.copy2(os.path.join(src, name), work)
    return work, os.path.join(work, "frame_0001.exr")


def test_missing_subsample_and_list_are_clear_errors(rendered):
    work, frame = copy_frame(rendered, "crisp_rsaa_bad_")
    try:
        os.remove(os.path.join(work, "frame_0001_sub5.exr"))
        p = filter_cli([frame], os.path.join(work, "out"))
        assert p.returncode != 0 and "frame_0001_sub5.exr" in p.stderr.decode(), p.stderr.decode()
        side_path = os.path.join(work, "frame_0001.json")
        side = json.load(open(side_path))
        del side["subsamples"]
        json.dump(side, open(side_path, "w"))
        p = filter_cli([frame], os.path.join(work, "out"))
        assert p.returncode != 0 and "not rendered for rsaa" in p.stderr.decode(), p.stderr.decode()
    finally:
        shutil.rmtree(work, ignore_errors=True)


def test_resume_remakes_the_output_after_a_subsample_changed(rendered):
    """An rsaa output's stamp records the sub-sample files its sidecar lists: a resume keeps the
    output while they are unchanged and makes it again after one is rendered again (here: its
    modification time moved)."""
    work, frame = copy_frame(rendered, "crisp_rsaa_resume_")
    try:
        out = os.path.join(work, "out")
        output = os.path.join(out, "frame_0001.exr")

        def resume():
            return subprocess.run([CRISP, "filter", "-m", "rsaa", "--resume", "-o", out, frame],
                                  stdout=subprocess.PIPE, stderr=subprocess.PIPE, env=env(), timeout=120)

        p = resume()
        assert p.returncode == 0, p.stderr.decode()
        made = os.stat(output).st_mtime_ns
        p = resume()
        assert p.returncode == 0 and "nothing to do" in p.stdout.decode(), (p.stdout.decode(), p.stderr.decode())
        assert os.stat(output).st_mtime_ns == made
        sub = os.path.join(work, "frame_0001_sub3.exr")
        st = os.stat(sub)
        os.utime(sub, ns=(st.st_atime_ns, st.st_mtime_ns + 10**9))
        p = resume()
        assert p.returncode == 0, p.stderr.decode()
        assert "was made from another version of '%s'" % frame in p.stderr.decode(), p.stderr.decode()
        assert os.stat(output).st_mtime_ns != made
    finally:
        shutil.rmtree(work, ignore_errors=True)


def test_plan_renders_no_geometry_without_visible_objects():
    empty = plan.make_plan("rsaa", plan.SceneFacts(frame_start=1, frame_end=1, visible_objects=[]))
    assert empty.passes == ["color"]
    for q in ("depth", "normal", "subsamples"):
        assert "no visible object" in empty.skipped[q]
    one = plan.make_plan("rsaa", plan.SceneFacts(frame_start=1, frame_end=1, visible_objects=["Cube"]))
    assert one.passes == ["color", "depth", "normal", "subsamples"]


# A scene with no visible object: Blender's startup file without its cube, a world with a checker
# texture (hard colour edges that FXAA, and so rsaa's default textureAA, would blend).
NOTHING_VISIBLE = """
import bpy, sys
bpy.data.objects.remove(bpy.data.objects["Cube"])
w = bpy.context.scene.world
w.use_nodes = True
checker = w.node_tree.nodes.new("ShaderNodeTexChecker")
checker.inputs["Scale"].default_value = 40.0
w.node_tree.links.new(checker.outputs["Color"], w.node_tree.nodes["Background"].inputs["Color"])
bpy.context.scene.eevee.gi_cubemap_resolution = "64"
bpy.ops.wm.save_as_mainfile(filepath=sys.argv[-1])
"""


@pytest.fixture(scope="module")
def nothing_visible():
    """The .blend of NOTHING_VISIBLE."""
    work = tempfile.mkdtemp(prefix="crisp_rsaa_empty_")
    blend = os.path.join(work, "nothing.blend")
    p = subprocess.run(["blender", "-b", "--factory-startup", "--python-exit-code", "1", "--python-expr",
                        NOTHING_VISIBLE, "--", blend], stdout=subprocess.PIPE, stderr=subprocess.STDOUT, timeout=300)
    assert p.returncode == 0, p.stdout.decode()[-3000:]
    yield blend
    shutil.rmtree(work, ignore_errors=True)


def test_eval_of_a_scene_with_nothing_visible_keeps_the_colour(nothing_visible):
    """With no visible object the plan renders no geometry, and rsaa keeps every colour, as the add-on
    filters it (native.FrameFilter): crisp eval did run rsaa on those frames and reported it failed
    (no sub-sample list in the sidecar)."""
    out = None
    try:
        out, _, _ = run_eval(["--scene", nothing_visible, "--frames", "1-1", "--resolution", "32x18", "-m", "rsaa",
                              "--reference-samples", "2", "--curve", "1", "-q"], "crisp_rsaa_empty_eval_")
        results = json.load(open(os.path.join(out, "results.json")))
        entry = next(m for m in results["scenes"][0]["methods"] if m["name"] == "rsaa")
        assert entry["error"] is None, entry["error"]
        assert entry["input"] == "eevee_1"
        lib = Lib()
        src = lib.color(os.path.join(out, "renders", "eevee_1", "frame_0001.exr"))
        assert np.array_equal(lib.color(os.path.join(out, "methods", "rsaa", "frame_0001.exr")), src)
        assert not np.array_equal(lib.color(os.path.join(out, "methods", "none", "frame_0001.exr"))[..., :3],
                                  np.broadcast_to(src[:1, :1, :3], src[..., :3].shape))  # a textured world
    finally:
        if out:
            shutil.rmtree(out, ignore_errors=True)


def test_cli_filter_of_a_frame_rendered_without_geometry_says_why(nothing_visible):
    """crisp render --method rsaa with nothing visible keeps the colour and writes no sub-samples; crisp
    filter -m rsaa on its frames said they were "not rendered for rsaa" and to render them with
    crisp render --method rsaa, which is what made them. It now names the reason and what to use."""
    out = tempfile.mkdtemp(prefix="crisp_rsaa_empty_render_")
    try:
        p = subprocess.run([CRISP, "render", "--scene", nothing_visible, "--method", "rsaa", "--resolution", "32x18",
                            "--frames", "1-1", "-q", "-o", out], stdout=subprocess.PIPE, stderr=subprocess.PIPE,
                           env=env(), timeout=600)
        assert p.returncode == 0, p.stderr.decode()[-3000:]
        frame = os.path.join(out, "input", "frame_0001.exr")
        assert not os.path.exists(os.path.join(out, "input", "frame_0001_sub0.exr"))
        lib = Lib()
        assert np.array_equal(lib.color(os.path.join(out, "filtered", "frame_0001.exr")), lib.color(frame))
        p = filter_cli([frame], os.path.join(out, "again"))
        err = p.stderr.decode()
        assert p.returncode == 1 and "rendered for rsaa with no visible object" in err and "-m none" in err, err
        assert "not rendered for rsaa" not in err, err
    finally:
        shutil.rmtree(out, ignore_errors=True)
