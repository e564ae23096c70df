# SPDX-License-Identifier: Apache-2.0
"""The `crisp` CLI end to end on real files: filter, compare, info, synth, help, and bad input.

Every failure must exit non-zero with a message naming the file, pass or parameter, and leave no
partial output under a final name (nor touch existing files)."""
import glob
import json
import os
import pathlib
import re
import shutil
import signal
import subprocess
import time

import pytest

from crisp_test_util import addon_with_spinning_cube_ending
from crisp_test_util import run_crisp as run

BUILD = pathlib.Path(os.environ.get("CRISP_BUILD_DIR", pathlib.Path(__file__).resolve().parents[2] / "build"))
CRISP = BUILD / "bin" / "crisp"


@pytest.fixture(scope="module")
def chart(tmp_path_factory):
    d = tmp_path_factory.mktemp("chart")
    run("synth", "-o", d, "--size", "97x61")
    return d


def test_synth_filter_compare_roundtrip(chart, tmp_path):
    out = tmp_path / "out"
    run("filter", "--method", "repair", "--set", "kappa=-1", "--png", chart / "chart_1spp.exr", "-o", out)
    assert (out / "chart_1spp.exr").is_file() and (out / "chart_1spp.png").is_file()
    js = tmp_path / "m.json"
    p = run("compare", "--reference", chart / "chart_reference.exr", chart / "chart_reference.exr",
            "--test", chart / "chart_1spp.exr", out / "chart_1spp.exr", "--json", js, "--maps", tmp_path / "maps")
    data = json.loads(js.read_text())
    assert [f["test"] for f in data["frames"]] == [str(chart / "chart_1spp.exr"), str(out / "chart_1spp.exr")]
    for f in data["frames"]:
        for k in ("mse", "psnr", "ssim", "snr", "rmse", "flip"):
            assert isinstance(f[k], float)
    unfiltered, filtered = data["frames"]
    assert data["mean"]["psnr"] == pytest.approx((unfiltered["psnr"] + filtered["psnr"]) / 2, rel=1e-6)
    assert "mean" in p.stdout
    # the two tests share a name, so each map takes its folder's name too
    assert sorted(f["maps"] for f in data["frames"]) == sorted(
        str(tmp_path / "maps" / (d.name + "_chart_1spp")) for d in (chart, out))
    for f in data["frames"]:
        assert os.path.isfile(f["maps"] + ".ssim.exr") and os.path.isfile(f["maps"] + ".flip.png")


def test_edge_mask_restricts_compare(chart, tmp_path):
    js_all, js_edges = tmp_path / "a.json", tmp_path / "e.json"
    args = ["--reference", chart / "chart_reference.exr", "--test", chart / "chart_1spp.exr"]
    run("compare", *args, "--json", js_all)
    run("compare", *args, "--mask", chart / "chart_edges.exr", "--json", js_edges)
    whole = json.loads(js_all.read_text())["frames"][0]
    edges = json.loads(js_edges.read_text())["frames"][0]
    assert edges["pixels"] < whole["pixels"] == 97 * 61
    assert edges["psnr"] < whole["psnr"]  # all the error sits on edge pixels


def test_info_lists_passes_and_missing(chart):
    p = run("info", chart / "chart_1spp.exr")
    assert "passes: color" in p.stdout
    assert "fxaa" in p.stdout and "ready" in p.stdout


def test_help_prints_parameter_tables():
    p = run("help", "repair")
    assert "| `kappa` | float |" in p.stdout
    assert "--method" in run("help", "filter").stdout
    assert run("--help").returncode == 0


@pytest.mark.parametrize("args, code, words", [
    (["filter", "--method", "nope", "IN", "-o", "OUT"], 2, ["--method: unknown method 'nope'", "rsaa"]),
    (["help", "nosuch"], 2, ["'nosuch' is neither a command", "filter", "phlm"]),
    (["filter", "--method", "repair", "--set", "kapa=1", "IN", "-o", "OUT"], 1, ["unknown parameter 'kapa'"]),
    (["filter", "--method", "repair", "--set", "kappa=9", "IN", "-o", "OUT"], 1, ["'kappa' = 9", "out of range"]),
    (["filter", "--method", "repair", "--set", "kappa", "IN", "-o", "OUT"], 2, ["KEY=VALUE"]),
    (["filter", "--method", "fxaa", "IN"], 2, ["--output"]),
    (["filter", "--method", "fxaa", "--bogus", "IN", "-o", "OUT"], 2, ["unknown option '--bogus'"]),
    (["compare", "--reference", "IN", "--test", "IN", "IN"], 2, ["paired in order"]),
    (["frobnicate"], 2, ["unknown command 'frobnicate'"]),
    (["eval", "--scene", "still_life", "--jitter", "halton", "-o", "OUT"], 2,
     ["--jitter: unknown distribution 'halton'", "blackman-harris, uniform"]),
    (["render", "--scene", "still_life", "--jitter", "halton", "-o", "OUT"], 2,
     ["--jitter: unknown distribution 'halton'"]),
    # Blender reads a backslash in a render's path as a folder separator (the renders would go elsewhere).
    (["render", "--scene", "still_life", "-o", "OUT\\010", "--blender", "NOBLENDER"], 2,
     ["-o '", "010' has a backslash in its path"]),
    (["eval", "--scene", "still_life", "-o", "OUT\\010", "--blender", "NOBLENDER"], 2,
     ["has a backslash in its path"]),
    # Lossy codecs are not offered for the renders the filters read.
    (["render", "--scene", "still_life", "--input-codec", "dwaa", "-o", "OUT", "--blender", "NOBLENDER"], 2,
     ["--input-codec: unknown codec 'dwaa' (known: none, piz, zip; lossless"]),
    # Before its settings file is written: a folder made by a refused size would refuse the right one.
    (["eval", "--scene", "still_life", "--resolution", "64x36x", "-o", "OUT"], 2, ["bad --resolution '64x36x'"]),
    (["eval", "--scene", "still_life", "--frames", "5-3", "-o", "OUT", "--blender", "NOBLENDER"], 2,
     ["--frames expects A-B or A", "got '5-3'"]),
    # What batch.py would refuse, said before Blender starts (NOBLENDER: none is there to start).
    (["render", "--scene", "still_life", "--frames", "5-3", "-o", "OUT", "--blender", "NOBLENDER"], 2,
     ["--frames expects A-B or A", "got '5-3'"]),
    (["render", "--scene", "still_life", "--frames", "1-x", "-o", "OUT", "--blender", "NOBLENDER"], 2,
     ["--frames", "got '1-x'"]),
    (["render", "--scene", "still_life", "--shot", "9-1", "-o", "OUT", "--blender", "NOBLENDER"], 2,
     ["--shot expects A-B or A", "got '9-1'"]),
    (["filter", "-m", "fxaa", "--exr-depth", "8", "IN", "-o", "OUT"], 2, ["--exr-depth expects 16 or 32, got '8'"]),
    (["filter", "-m", "fxaa", "--exr-codec", "lzw", "IN", "-o", "OUT"], 2,
     ["--exr-codec: unknown EXR compression 'lzw' (known: none, zip, zips, piz, pxr24, rle, b44, b44a, dwaa, dwab)"]),
    (["render", "--scene", "still_life", "--resolution", "0x36", "-o", "OUT", "--blender", "NOBLENDER"], 2,
     ["bad --resolution '0x36'"]),
    # Blender's smallest render size is 4 (it would render 4x4 and say nothing).
    (["render", "--scene", "still_life", "--resolution", "3x36", "-o", "OUT", "--blender", "NOBLENDER"], 2,
     ["bad --resolution '3x36'", "each 4 to 65536"]),
    (["render", "--scene", "still_life", "--preroll", "-1", "-o", "OUT", "--blender", "NOBLENDER"], 2,
     ["--preroll expects a whole number in [0, "]),
    (["render", "--scene", "still_life", "--samples", "0", "-o", "OUT", "--blender", "NOBLENDER"], 2,
     ["--samples expects a whole number in [1, "]),
    (["render", "--scene", "still_life", "--reference-samples", "many", "-o", "OUT", "--blender", "NOBLENDER"], 2,
     ["--reference-samples expects a whole number", "got 'many'"]),
    (["render", "--scene", "still_life", "--threads", "-2", "-o", "OUT", "--blender", "NOBLENDER"], 2,
     ["--threads expects a whole number"]),
    # Blender's "beside the .blend", which a bundled scene has not.
    (["render", "--scene", "still_life", "-o", "//crisp_out", "--blender", "NOBLENDER"], 2,
     ["-o '//crisp_out' is relative to the .blend file", "'still_life' is no .blend file"]),
    (["eval", "--scene", "still_life", "-o", "//crisp_out", "--blender", "NOBLENDER"], 2,
     ["-o '//crisp_out' is relative to the .blend file"]),
    # Rules a commit checks between parameters (an odd patchSize, feedbackMin <= feedbackMax): said before
    # Blender renders anything, not as a failed method in the report of a run that exits 0.
    (["eval", "--scene", "still_life", "--methods", "fxaa,repair:patchSize=4", "-o", "OUT", "--blender", "NOBLENDER"],
     2, ["--methods 'repair:patchSize=4'", "'patchSize' = 4 must be odd"]),
    (["eval", "--scene", "still_life", "--methods", "taa:feedbackMin=0.9:feedbackMax=0.5", "-o", "OUT", "--blender",
      "NOBLENDER"], 2, ["--methods 'taa:feedbackMin=0.9:feedbackMax=0.5'", "feedbackMin"]),
    (["render", "--scene", "still_life", "-m", "repair", "--set", "patchSize=4", "-o", "OUT", "--blender", "NOBLENDER"],
     1, ["'patchSize' = 4 must be odd"]),
    # blender-smaa is known (always measured) but takes no settings; an empty list (an unset shell variable)
    # is no method, not an evaluation of none alone (--methods none asks for that).
    (["eval", "--scene", "still_life", "--methods", "blender-smaa:threshold=0.1", "-o", "OUT", "--blender", "NOBLENDER"],
     2, ["--methods 'blender-smaa:threshold=0.1': blender-smaa takes no settings"]),
    (["eval", "--scene", "still_life", "--methods", "", "-o", "OUT", "--blender", "NOBLENDER"], 2,
     ["--methods '' names no method"]),
    (["eval", "--scene", "still_life", "--methods", ",", "-o", "OUT", "--blender", "NOBLENDER"], 2,
     ["--methods ',' names no method"]),
])
def test_usage_and_parameter_errors(chart, tmp_path, args, code, words):
    place = {"IN": str(chart / "chart_1spp.exr"), "OUT": str(tmp_path / "out"), "NOBLENDER": str(tmp_path / "none"),
             "OUT\\010": str(tmp_path / "out") + "\\010"}
    args = [place.get(a, a) for a in args]
    p = run(*args, ok=False)
    assert p.returncode == code, p.stderr
    for w in words:
        assert w in p.stderr
    assert not (tmp_path / "out" / "chart_1spp.exr").exists()
    if args[0] in ("eval", "render"):
        assert not (tmp_path / "out").exists() and not (tmp_path / "out\\010").exists()  # refused before anything


def test_eval_output_relative_to_the_blend_file_is_beside_it(tmp_path):
    """crisp eval -o //NAME makes NAME beside the .blend, as Blender reads // (and as the renders it starts
    write there): it was made at the root folder, /NAME, while Blender wrote beside the .blend."""
    blend = tmp_path / "my shot" / "shot.blend"
    blend.parent.mkdir()
    blend.write_bytes(b"BLENDER")  # never opened: no Blender is there to start
    name = "crisp_eval_%d" % os.getpid()
    # --no-panel: reading the panel needs Blender before the folder is made (test_eval_stops_before_...)
    p = run("eval", "--scene", blend, "--frames", "1", "-o", "//" + name, "--blender", tmp_path / "none",
            "--no-panel", ok=False)
    assert p.returncode != 0
    assert (blend.parent / name).is_dir(), p.stderr
    assert not os.path.exists("/" + name), "made at the root folder"


@pytest.mark.skipif(shutil.which("blender") is None, reason="blender not installed")
def test_eval_of_jittered_methods_on_non_square_pixels_is_refused_before_rendering(tmp_path):
    """taa jitters, rsaa's sub-samples shift the camera: both need square pixels. crisp eval rendered the
    1-sample frames first and then failed as a render failure, naming no method."""
    blend = tmp_path / "wide_pixels.blend"
    subprocess.run(["blender", "-b", "--factory-startup", "--python-expr",
                    "import bpy; r = bpy.context.scene.render; r.pixel_aspect_x = 2; "
                    "bpy.ops.wm.save_as_mainfile(filepath=%r)" % str(blend)], capture_output=True, check=True)
    out = tmp_path / "out"
    p = run("eval", "--scene", blend, "--frames", "1-2", "--methods", "fxaa,taa,rsaa", "--resolution", "16x8",
            "--reference-samples", "1", "--warmup", "1", "-o", out, ok=False)
    assert p.returncode == 2, p.stderr
    log = (out / "logs" / "blender.log").read_text()
    assert "taa renders jittered frames and rsaa renders sub-samples by jittering the camera, and jitter needs " \
           "square pixels (pixel aspect is 2:1)" in log, p.stderr
    assert not list(out.rglob("*.exr"))


@pytest.mark.skipif(shutil.which("blender") is None, reason="blender not installed")
def test_eval_that_renders_nothing_leaves_no_settings(tmp_path):
    """eval_settings.json makes a later run into the folder match this one; a run that renders nothing
    (a bad CRISP_EVAL_FILTER_SIZE refused by the CLI, a frame range Blender refuses) must not leave it,
    or the corrected command would be refused."""
    out = tmp_path / "out"
    p = subprocess.run([str(CRISP), "eval", "--scene", "still_life", "-o", str(out)], capture_output=True, text=True,
                       env=dict(os.environ, CRISP_EVAL_FILTER_SIZE="abc"), timeout=60)
    assert p.returncode == 2 and "bad CRISP_EVAL_FILTER_SIZE 'abc'" in p.stderr, p.stderr
    assert not out.exists()
    p = run("eval", "--scene", "still_life", "--frames", "5-3", "--resolution", "64x36", "-o", out, ok=False)
    assert p.returncode == 2 and "5-3" in p.stderr, p.stderr
    assert not (out / "eval_settings.json").exists()
    # A warm-up longer than the scene's own range (no --frames): refused by the driver before it renders.
    p = run("eval", "--scene", "still_life", "--warmup", "16", "--resolution", "64x36", "-o", out, ok=False)
    assert p.returncode == 2 and "--warmup 16 leaves none of the 16 frames (1-16)" in p.stderr, p.stderr
    assert not (out / "eval_settings.json").exists() and not list(out.rglob("*.exr"))


@pytest.mark.skipif(shutil.which("blender") is None, reason="blender not installed")
def test_an_eval_stopped_before_its_first_render_does_not_lock_the_folder(tmp_path):
    """Ctrl-C (SIGINT to the terminal's process group) once the settings file is written and before any
    render: the corrected command (another size) runs, where it was refused for renders never made."""
    out = tmp_path / "out"
    args = ["eval", "--scene", "still_life", "--frames", "1-1", "--methods", "fxaa", "--reference-samples", "2",
            "--curve", "1", "--quiet", "-o", str(out)]
    # A size whose first render takes seconds: Blender acts on a stop only once it has started.
    p = subprocess.Popen([str(CRISP), *args, "--resolution", "1920x1080"], stdout=subprocess.DEVNULL,
                         stderr=subprocess.DEVNULL, start_new_session=True)
    deadline = time.monotonic() + 60
    while not (out / "eval_settings.json").exists() and p.poll() is None and time.monotonic() < deadline:
        time.sleep(0.002)
    os.killpg(p.pid, signal.SIGINT)
    p.wait(timeout=60)
    assert (out / "eval_settings.json").exists(), "the run was stopped before it wrote its settings: nothing tested"
    assert not [f for f in out.rglob("*.exr") if not f.name.startswith(".")], "stopped too late: it rendered"
    run(*args, "--resolution", "64x36")
    assert json.loads((out / "eval_settings.json").read_text())["resolution"] == "64x36"
    assert (out / "report.html").is_file()


def slow_frames_env(tmp_path):
    """The environment of a crisp run whose spinning_cube takes 0.3 s a frame change (a slow frame change
    handler): long enough to act on it part-way."""
    return dict(os.environ, CRISP_ADDON_DIR=addon_with_spinning_cube_ending(
        tmp_path, "import bpy\nimport time\nbpy.app.handlers.frame_change_pre.append(lambda *_: time.sleep(0.3))\n"))


@pytest.mark.skipif(shutil.which("blender") is None, reason="blender not installed")
def test_an_eval_stopped_while_it_renders_says_how_far_it_came_and_resumes(tmp_path):
    """Ctrl-C (SIGINT to the terminal's process group) part-way through the renders: Blender stops after
    the render it is on and crisp eval says so, also with --quiet, naming how many renders are done and the
    folder they are kept in, and ends by the signal; the same command then goes on from them: it renders
    only the rest (its progress calls the others done before) and writes its report. A scene whose frame
    change handler is slow (spinning_cube, 0.3 s a frame) makes the run long enough to stop part-way."""
    env = slow_frames_env(tmp_path)
    out = tmp_path / "out"
    args = [str(CRISP), "eval", "--scene", "spinning_cube", "--frames", "1-4", "--resolution", "64x36", "--methods",
            "fxaa", "--reference-samples", "2", "--curve", "1", "-o", str(out)]
    p = subprocess.Popen([*args, "--quiet"], stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, env=env,
                         start_new_session=True)
    times = out / "renders" / "eevee_1" / "times.json"
    deadline = time.monotonic() + 120
    while not times.exists() and p.poll() is None and time.monotonic() < deadline:
        time.sleep(0.01)
    assert p.poll() is None, "the run ended before it was stopped: " + p.communicate()[1][-2000:]
    os.killpg(p.pid, signal.SIGINT)
    _, err = p.communicate(timeout=60)
    assert p.returncode == -signal.SIGINT, err
    said = re.search(r"crisp eval: stopped by Ctrl-C \(SIGINT\) after the render it was on: (\d+) of (\d+) renders "
                     r"are done, and the same command goes on from them \(renders in (.*)\)\n", err)
    assert said, err
    done, total = int(said.group(1)), int(said.group(2))
    assert said.group(3) == str(out / "renders")
    recorded = sum(len(json.loads(t.read_text())) for t in (out / "renders").glob("*/times.json"))
    assert 0 < done == recorded < total, (done, recorded, total)
    assert not [f for f in out.rglob("*") if f.name.startswith(".")], "a temporary file was left"
    again = subprocess.run(args, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, env=env, timeout=300)
    assert again.returncode == 0, again.stderr[-3000:]
    progress = [line for line in again.stderr.splitlines() if line.startswith("render ")]
    assert len(progress) == total and sum("(done before)" in line for line in progress) == done, again.stderr
    assert (out / "report.html").is_file()


@pytest.mark.skipif(shutil.which("blender") is None, reason="blender not installed")
def test_a_second_eval_into_a_folder_in_use_is_refused(tmp_path):
    """Two crisp evals into one folder would render the same frames twice and rewrite each other's
    records: the second is refused while the first runs, before it writes anything there (the first's
    settings file is untouched, even by other settings), and the first goes on to its report."""
    env = slow_frames_env(tmp_path)
    out = tmp_path / "out"
    args = [str(CRISP), "eval", "--scene", "spinning_cube", "--frames", "1-2", "--methods", "fxaa",
            "--reference-samples", "2", "--curve", "1", "--quiet", "-o", str(out)]
    first = subprocess.Popen([*args, "--resolution", "64x36"], stdout=subprocess.PIPE, stderr=subprocess.PIPE,
                             text=True, env=env)
    try:
        settings = out / "eval_settings.json"
        deadline = time.monotonic() + 60
        while not settings.exists() and first.poll() is None and time.monotonic() < deadline:
            time.sleep(0.01)
        written = settings.read_text()
        # The first renders for seconds more (Blender starts, then 8 renders of 0.3 s or more each).
        assert first.poll() is None, "the first run ended before the second started: nothing tested"
        second = subprocess.run([*args, "--resolution", "48x32"], capture_output=True, text=True, env=env, timeout=60)
        assert second.returncode == 2, second.stderr
        assert ("'%s' is the output folder of another crisp eval still running; wait for it to end or use another "
                "-o folder" % out) in second.stderr
        assert settings.read_text() == written
        _, err = first.communicate(timeout=300)
    finally:
        if first.poll() is None:
            first.kill()
    assert first.returncode == 0, err[-3000:]
    assert (out / "report.html").is_file()


def test_eval_refuses_a_filter_size_a_temporal_method_refuses_before_rendering(tmp_path):
    """A temporal method filters with the renders' Film > Filter Size (their sidecars), which
    CRISP_EVAL_FILTER_SIZE sets: a size it refuses (above 4 px) is refused before Blender starts,
    as bad --methods settings are, naming the variable, not after every render; a method whose settings
    give filterSize, or a spatial one, is not refused. The 'Blender' here fails at once: reaching it
    means the CLI let the run through."""
    wrapper = tmp_path / "blender-wrapper"
    wrapper.write_text("#!/bin/sh\nexit 3\n")
    wrapper.chmod(0o755)
    out = tmp_path / "out"

    def ev(methods):
        return subprocess.run([str(CRISP), "eval", "--scene", "still_life", "--frames", "1-2", "--resolution", "16x8",
                               "--methods", methods, "--quiet", "--blender", str(wrapper), "-o", str(out)],
                              capture_output=True, text=True, env=dict(os.environ, CRISP_EVAL_FILTER_SIZE="5"),
                              timeout=60)
    for methods in ("fxaa,taa", "phlm", "taa-improved"):
        p = ev(methods)
        assert p.returncode == 2 and "CRISP_EVAL_FILTER_SIZE 5" in p.stderr and "Blender failed" not in p.stderr, \
            (methods, p.stderr)
        assert "filterSize=" in p.stderr, p.stderr
        assert not out.exists(), methods
    for methods in ("fxaa", "taa:filterSize=1.5"):
        p = ev(methods)
        assert "Blender failed (exit 3)" in p.stderr and "CRISP_EVAL_FILTER_SIZE" not in p.stderr, (methods, p.stderr)


@pytest.mark.skipif(shutil.which("blender") is None, reason="blender not installed")
def test_eval_refuses_a_scenes_filter_size_a_temporal_method_refuses_before_rendering(tmp_path):
    """A temporal method filters with the renders' Film > Filter Size (their sidecars): a .blend whose
    Filter Size is above what it takes (4 px) failed only at the method step, after every render. The
    driver refuses it before the first render, naming the size and the methods; a method whose settings
    give filterSize, or a spatial one, is let through (that run renders and measures one tiny frame)."""
    blend = tmp_path / "wide_filter.blend"
    subprocess.run(["blender", "-b", "--factory-startup", "--python-exit-code", "1", "--python-expr",
                    "import bpy; bpy.context.scene.render.filter_size = 5; "
                    "bpy.ops.wm.save_as_mainfile(filepath=%r)" % str(blend)], capture_output=True, check=True)
    for methods, named in (("fxaa,taa", "taa"), ("phlm,taa-improved,taa:filterSize=2", "phlm, taa-improved")):
        out = tmp_path / ("out-" + methods.split(",")[0])
        p = run("eval", "--scene", blend, "--frames", "1-2", "--methods", methods, "--resolution", "16x8",
                "--reference-samples", "2", "--curve", "1", "-o", out, ok=False)
        assert p.returncode == 2, p.stderr
        assert "the scene's Film > Filter Size 5 px is above 4 px, the largest %s filter" % named in p.stderr, \
            p.stderr
        assert "filterSize=" in p.stderr and "CRISP_EVAL_FILTER_SIZE" in p.stderr, p.stderr  # the ways out
        assert not list(out.rglob("*.exr")) and not (out / "eval_settings.json").exists()
    out = tmp_path / "out"
    p = run("eval", "--scene", blend, "--frames", "1-1", "--methods", "fxaa,taa:filterSize=1.5", "--resolution",
            "16x8", "--reference-samples", "2", "--curve", "1", "--quiet", "-o", out)
    assert (out / "methods" / "taa:filterSize=1.5" / "frame_0001.exr").is_file(), sorted(out.rglob("*"))


def test_eval_settings_take_a_size_however_it_is_spelled(tmp_path):
    """eval_settings.json refuses a run into a folder rendered at another size; 64X36 and 064x36 are the
    size 64x36 (both pass the --resolution check and Blender renders them alike), not other settings.
    The 'Blender' here renders a frame and fails, so the folder holds a render and keeps its settings."""
    wrapper = tmp_path / "blender-wrapper"
    wrapper.write_text('#!/bin/sh\nwhile [ "$1" != "-o" ]; do shift; done\nmkdir -p "$2/eevee_1"\n'
                       'touch "$2/eevee_1/frame_0001.exr"\nexit 3\n')
    wrapper.chmod(0o755)
    out = tmp_path / "out"
    for size in ("64X36", "064x36", "64x36"):
        p = run("eval", "--scene", "still_life", "--frames", "1", "--methods", "fxaa", "--quiet", "--resolution", size,
                "--blender", wrapper, "-o", out, ok=False)
        assert "Blender failed (exit 3)" in p.stderr and "other settings" not in p.stderr, (size, p.stderr)
    p = run("eval", "--scene", "still_life", "--frames", "1", "--methods", "fxaa", "--quiet", "--resolution", "48x27",
            "--blender", wrapper, "-o", out, ok=False)
    assert p.returncode == 2 and 'resolution "64x36" there, "48x27" here' in p.stderr, p.stderr


def report_links_missing(out):
    """The files out/results.json names (frames, crops, the pictures of its methods) that are not there."""
    if not (out / "results.json").exists():
        return []
    missing = []
    for scene in json.loads((out / "results.json").read_text())["scenes"]:
        named = [f for c in scene["crops"] for files in c["files"].values() for f in files]
        named += [f["file"] for e in scene["methods"] + scene["eevee_curve"] for f in e["frames"] if f.get("file")]
        named += ["images/full/%s.png" % e["name"] for e in scene["methods"] if not e["error"]]
        missing += [f for f in named if not (out / f).exists()]
    return missing


@pytest.mark.skipif(shutil.which("blender") is None, reason="blender not installed")
def test_a_rerun_failing_while_it_measures_leaves_no_report_of_missing_pictures(tmp_path):
    """A rerun removed the last run's pictures as it began to measure and kept its report.html and
    results.json: one stopped there (Ctrl-C, or here an unreadable method frame) left a report whose images
    were gone. Now no report is left; the next run makes it whole again."""
    out = tmp_path / "out"
    args = ["eval", "--scene", "still_life", "--frames", "1-1", "--methods", "fxaa", "--resolution", "48x27",
            "--reference-samples", "2", "--curve", "1", "--quiet", "-o", out]
    run(*args)
    assert (out / "report.html").is_file() and not report_links_missing(out)
    frame = out / "methods" / "fxaa" / "frame_0001.exr"
    frame.write_bytes(b"not an EXR")  # taken as done (its input unchanged), read only once measuring began
    p = run(*args, ok=False)
    assert p.returncode != 0 and str(frame) in p.stderr, p.stderr
    assert not (out / "images" / "full" / "fxaa.png").exists(), "failed before the pictures went: nothing tested"
    assert not (out / "report.html").exists() and not (out / "results.csv").exists(), p.stderr
    assert not report_links_missing(out)
    frame.unlink()
    # The list of the pictures to remove, as a run stopped after withdrawing it leaves it: the next run removes them.
    (out / "images" / "full" / "gone.png").write_bytes(b"")
    (out / ".results_withdrawn.json").write_text(json.dumps({"scenes": [{"methods": [{"name": "gone"}]}]}))
    run(*args)
    assert (out / "report.html").is_file() and (out / "results.json").is_file() and not report_links_missing(out)
    assert not (out / ".results_withdrawn.json").exists() and not (out / "images" / "full" / "gone.png").exists()


def _method_child_of(pid):
    """A process crisp eval forked to run a method (its executable is crisp), or None."""
    for children in glob.glob("/proc/%d/task/*/children" % pid):
        try:
            with open(children) as f:
                kids = [int(k) for k in f.read().split()]
        except OSError:
            continue
        for kid in kids:
            try:
                if os.path.realpath("/proc/%d/exe" % kid) == os.path.realpath(str(CRISP)):
                    return kid
            except OSError:
                pass
    return None


def _running(pid):
    try:
        with open("/proc/%d/stat" % pid) as f:
            return f.read().rsplit(")", 1)[1].split()[0] not in ("Z", "X")  # an unreaped zombie has stopped
    except OSError:
        return False


@pytest.mark.skipif(shutil.which("blender") is None, reason="blender not installed")
def test_a_stopped_eval_leaves_no_method_writing(tmp_path):
    """kill PID (a farm cancelling its task) stops crisp eval with the method it is running: eval runs each
    method in a child process, which must not go on alone writing into the folder after crisp has exited
    (Blender does not: blender.cpp). crisp eval says once, also with --quiet, that it stopped and where the
    frames made are kept. The renders are made first; the second run only runs the methods."""
    out = tmp_path / "out"
    args = ["eval", "--scene", "still_life", "--resolution", "1920x1080", "--frames", "1-4", "--methods", "repair",
            "--reference-samples", "1", "--curve", "1", "--quiet", "-o", str(out)]
    run(*args)
    shutil.rmtree(out / "methods")
    err = tmp_path / "stderr"
    with open(err, "w") as f:
        p = subprocess.Popen([str(CRISP), *args], stdout=subprocess.DEVNULL, stderr=f)
    child, deadline = None, time.monotonic() + 120
    while child is None and p.poll() is None and time.monotonic() < deadline:
        child = _method_child_of(p.pid)
        time.sleep(0.005)
    assert child, "no method process seen"
    p.send_signal(signal.SIGTERM)
    assert p.wait(timeout=60) == -signal.SIGTERM
    deadline = time.monotonic() + 1.0
    while _running(child) and time.monotonic() < deadline:
        time.sleep(0.01)
    assert not _running(child), "the method process went on after crisp eval was stopped"
    listing = sorted((f.name, f.stat().st_size) for f in (out / "methods").rglob("*"))
    time.sleep(1.0)
    assert sorted((f.name, f.stat().st_size) for f in (out / "methods").rglob("*")) == listing
    said = err.read_text()
    assert said.count("crisp eval: stopped by") == 1, said
    assert re.search(r"(^|\n)crisp eval: stopped by SIGTERM while it ran method '(none|repair)': the frames made are "
                     r"kept in %s, and the same command goes on from them\n" % re.escape(str(out / "methods")), said), said


@pytest.mark.skipif(shutil.which("blender") is None, reason="blender not installed")
def test_render_passes_a_negative_frame_range_to_blender(tmp_path):
    """Blender frames may be negative; '-2-1' reaches batch.py as one value (--frames=-2-1), not as an
    option of its own."""
    out = tmp_path / "out"
    run("render", "--scene", "still_life", "--frames", "-2-1", "--plan", "--quiet", "-o", out)
    assert json.loads((out / "run.json").read_text())["frames_requested"] == [-2, 1]


def test_bad_files_name_the_file_and_write_nothing(chart, tmp_path):
    good = (chart / "chart_1spp.exr").read_bytes()
    cases = {
        "truncated.exr": good[: len(good) // 2],
        "corrupt.exr": good[:40] + bytes(b ^ 0x5A for b in good[40:400]) + good[400:],
        "empty.exr": b"",
        "text.exr": b"this is not an image\n",
    }
    out = tmp_path / "out"
    for name, data in cases.items():
        f = tmp_path / name
        f.write_bytes(data)
        p = run("filter", "--method", "fxaa", f, "-o", out, ok=False)
        assert p.returncode == 1, (name, p.stderr)
        assert name in p.stderr, (name, p.stderr)
        assert not (out / (f.stem + ".exr")).exists(), name
        assert not out.exists(), name  # the folder the run made is not left behind empty
    p = run("filter", "--method", "fxaa", tmp_path / "missing.exr", "-o", out, ok=False)
    assert p.returncode == 1 and "missing.exr" in p.stderr
    assert not out.exists()
    # A folder that was there before stays, also when the run left it empty.
    out.mkdir()
    p = run("filter", "--method", "fxaa", tmp_path / "truncated.exr", "-o", out / "a" / "b", ok=False)
    assert p.returncode == 1
    assert [x.name for x in out.iterdir()] == []  # no temporary files, no a/b
    # The folders are made as the path names them: one that existed is never removed, one made on
    # the way ("nothere" in nothere/../out) is, and a failure to create the folder is an error, not
    # a crash.
    p = run("filter", "--method", "fxaa", tmp_path / "truncated.exr", "-o", tmp_path / "nothere" / ".." / "out",
            ok=False)
    assert p.returncode == 1 and out.is_dir() and not (tmp_path / "nothere").exists()
    p = run("filter", "--method", "fxaa", tmp_path / "truncated.exr", "-o", out / "new" / "." / "deeper" / "", ok=False)
    assert p.returncode == 1 and not (out / "new").exists()
    dangling = tmp_path / "dangling"
    dangling.symlink_to(tmp_path / "nowhere")
    p = run("filter", "--method", "fxaa", chart / "chart_1spp.exr", "-o", dangling, ok=False)
    assert p.returncode == 1 and "cannot create output folder" in p.stderr and dangling.is_symlink(), p.stderr
    p = run("filter", "--method", "fxaa", chart / "chart_1spp.exr", "-o", tmp_path / "empty.exr" / "sub", ok=False)
    assert p.returncode == 1 and "cannot create output folder" in p.stderr, p.stderr


def test_temporary_files_of_a_killed_run_are_removed(chart, tmp_path):
    """kill -9 mid-write leaves '.<name>.tmp-<host>-<pid>-<n><ext>'; the next run on
    this host removes those whose process is gone and that are a minute old, no other."""
    import socket
    import sys
    host = re.sub(r"[^A-Za-z0-9_.-]", "_", socket.gethostname())[:64]
    gone = subprocess.run([sys.executable, "-c", "import os; print(os.getpid())"],
                          capture_output=True, text=True, check=True)
    dead = int(gone.stdout)
    out = tmp_path / "out"
    (out / ".crisp").mkdir(parents=True)
    old = 1_000_000_000  # 2001: long untouched
    stale = [out / f".chart_1spp.tmp-{host}-{dead}-0.exr", out / ".crisp" / f".chart_1spp.tmp-{host}-{dead}-3.json",
             out / f".result.tmp-{host}-{dead}-7"]                 # a target without an extension
    kept = [out / f".chart_1spp.tmp-{host}-{os.getpid()}-0.exr",   # its process still runs
            out / f".chart_1spp.tmp-otherhost-{dead}-0.exr",       # another machine's
            out / f".chart_1spp.tmp-{host}-{dead}-1.png",          # written just now
            out / f"chart_1spp.tmp-{host}-{dead}-0.exr",           # not hidden: not ours
            out / f".notes.tmp-{host}-{dead}-x.txt",               # not our pattern
            out / f".chart_1spp.tmp-{host}-{dead}-0.exr.bak",      # a copy of one: not ours
            out / f".chart_1spp.tmp-{host}-{dead}-0."]
    for f in stale + kept:
        f.write_bytes(b"half an image")
        if f != kept[2]:
            os.utime(f, (old, old))
    p = run("filter", "--method", "fxaa", chart / "chart_1spp.exr", "-o", out)
    assert "removed 2 temporary file(s)" in p.stderr and "removed 1 temporary file(s)" in p.stderr, p.stderr
    assert [f.name for f in stale if f.exists()] == []
    assert [f.name for f in kept if not f.exists()] == []
    assert (out / "chart_1spp.exr").is_file()


def test_mismatched_sizes_are_named(chart, tmp_path):
    small = tmp_path / "small"
    run("synth", "-o", small, "--size", "31x17")
    p = run("compare", "--reference", chart / "chart_reference.exr", "--test", small / "chart_1spp.exr", ok=False)
    assert p.returncode == 1
    assert "97x61" in p.stderr and "31x17" in p.stderr and "chart_1spp.exr" in p.stderr


def test_size_change_mid_sequence_is_reported(chart, tmp_path):
    small = tmp_path / "small"
    run("synth", "-o", small, "--size", "31x17")
    a, b = tmp_path / "a.exr", tmp_path / "b.exr"
    shutil.copy(chart / "chart_1spp.exr", a)
    shutil.copy(small / "chart_1spp.exr", b)
    out = tmp_path / "out"
    p = run("filter", "-q", "--method", "taa", a, b, "-o", out)  # a cut: carries on
    assert "warning" in p.stderr and "b.exr" in p.stderr and "31x17" in p.stderr and "97x61" in p.stderr
    assert "taa starts over at the new size" in p.stderr
    assert (out / "a.exr").is_file() and (out / "b.exr").is_file()
    # A spatial method has no history to start over: the warning says what is odd, nothing more.
    p = run("filter", "-q", "--method", "fxaa", a, b, "-o", tmp_path / "spatial")
    assert "'%s' is 31x17, the frames before it 97x61\n" % b in p.stderr and "starts over" not in p.stderr
    a2 = tmp_path / "a2.exr"
    shutil.copy(a, a2)
    p = run("filter", "-q", "--method", "taa", a, a2, "-o", tmp_path / "same")
    assert "warning" not in p.stderr


def test_a_pass_missing_mid_sequence_is_reported(chart, tmp_path):
    """A frame without an optional pass the frame before had (here depth, a top-level Z channel) is
    filtered without it, with a warning naming the file and the pass; frames that keep their passes
    give none."""
    a, b, c = tmp_path / "a.exr", tmp_path / "b.exr", tmp_path / "c.exr"
    subprocess.run(["oiiotool", str(chart / "chart_1spp.exr"), "--ch", "R,G,B,A,Z=0.5", "-o", str(a)], check=True)
    shutil.copy(chart / "chart_1spp.exr", b)
    shutil.copy(a, c)
    assert "depth" in run("info", a).stdout and "depth" not in run("info", b).stdout.split("passes:")[1].split("\n")[0]
    p = run("filter", "-q", "--method", "taa", a, b, c, "-o", tmp_path / "out")
    assert "warning" in p.stderr and "b.exr" in p.stderr and "'depth'" in p.stderr, p.stderr
    assert "c.exr" not in p.stderr  # depth coming back is no loss
    p = run("filter", "-q", "--method", "taa", a, c, "-o", tmp_path / "same")
    assert "warning" not in p.stderr


def test_passes_in_any_part_of_a_multi_part_exr_are_read(chart, tmp_path):
    """A multi-part EXR's passes are read from whichever part holds them (colour first or later, a
    depth part): the frame and the output are those of the same channels in one part. A part
    holding nothing read is listed by info; a pass in two parts is refused naming the file, the
    pass and the parts, before anything is written."""
    colour = str(chart / "chart_1spp.exr")
    z, one_part = tmp_path / "z.exr", tmp_path / "one_part.exr"
    subprocess.run(["oiiotool", colour, "--ch", "Z=0.5", "--attrib", "oiio:subimagename", "depth", "-o", str(z)],
                   check=True)
    subprocess.run(["oiiotool", colour, "--ch", "R,G,B,A,Z=0.5", "-o", str(one_part)], check=True)
    colour_first, colour_later = tmp_path / "colour_first.exr", tmp_path / "colour_later.exr"
    subprocess.run(["oiiotool", colour, str(z), "--siappend", "-o", str(colour_first)], check=True)
    subprocess.run(["oiiotool", str(z), colour, "--siappend", "-o", str(colour_later)], check=True)
    run("filter", "-q", "--method", "taa", one_part, "-o", tmp_path / "ref")
    for f in (colour_first, colour_later):
        info = run("info", f).stdout
        assert "passes: color,depth\n" in info and "not read" not in info, info
        p = run("filter", "-q", "--method", "taa", f, "-o", tmp_path / f.stem)
        assert "warning" not in p.stderr, p.stderr
        assert same_pixels([tmp_path / f.stem / (f.stem + ".exr")], [tmp_path / "ref" / "one_part.exr"]), f
    # A part holding nothing read here.
    extra = tmp_path / "extra.exr"
    subprocess.run(["oiiotool", str(colour_first), "-i", colour, "--chnames", "diffuse.R,diffuse.G,diffuse.B,diffuse.A",
                    "--attrib", "oiio:subimagename", "diffuse", "--siappendall", "-o", str(extra)], check=True)
    assert "not read: part 3 of 3 ('diffuse') (channels: diffuse.R, diffuse.G, diffuse.B, diffuse.A)" in \
        run("info", extra).stdout
    # Z in two parts beside a colour part holding none: which is the depth is unclear.
    twice = tmp_path / "twice.exr"
    subprocess.run(["oiiotool", colour, str(z), str(z), "--attrib", "oiio:subimagename", "depth2", "--siappendall",
                    "-o", str(twice)], check=True)
    p = run("filter", "-q", "--method", "taa", twice, "-o", tmp_path / "twice", ok=False)
    assert p.returncode == 1
    assert "'%s' has a Z channel in more than one part (part 2 of 3 ('depth'), part 3 of 3 ('depth2'))" % twice \
        in p.stderr, p.stderr
    assert not (tmp_path / "twice").exists()


def exr_windows(path):
    """(x, y, width, height) of the data window, then of the display window, as OpenImageIO reads them."""
    fields = " ".join("{TOP.%s}" % f for f in ("x", "y", "width", "height", "full_x", "full_y", "full_width",
                                                "full_height"))
    p = subprocess.run(["oiiotool", str(path), "--echo", fields], capture_output=True, text=True, check=True)
    return tuple(int(v) for v in p.stdout.split())


def same_pixels(a, b):
    """oiiotool --diff of two images, each a file and the oiiotool ops on it (over the data windows'
    union, 0 outside each)."""
    return subprocess.run(["oiiotool", *map(str, a), *map(str, b), "--diff"], capture_output=True).returncode == 0


def test_filter_output_keeps_the_input_exr_windows(chart, tmp_path):
    """An EXR whose data window is offset from its display window (oiiotool --crop, a compositor's
    bounding box), or whose display window is not at origin 0, is filtered in its display window and
    written back into the same windows: each output pixel lies where its input pixel lay, in viewers
    that place the data window and in those that show it alone. Overscan is clipped to the display
    window (the filters see no more); a PNG holds the display window."""
    src = chart / "chart_1spp.exr"
    run("filter", "-q", "--method", "fxaa", src, "-o", tmp_path / "whole")
    whole = tmp_path / "whole" / "chart_1spp.exr"
    cropped, shifted, overscan = tmp_path / "cropped.exr", tmp_path / "shifted.exr", tmp_path / "overscan.exr"
    subprocess.run(["oiiotool", str(src), "--crop", "71x49+13+6", "-o", str(cropped)], check=True)
    subprocess.run(["oiiotool", str(src), "--origin", "+30+20", "--fullsize", "97x61+30+20", "-o", str(shifted)],
                   check=True)
    subprocess.run(["oiiotool", str(src), "--crop", "101x65-2-2", "-o", str(overscan)], check=True)
    out = tmp_path / "out"
    run("filter", "-q", "--method", "fxaa", "--png", cropped, shifted, overscan, "-o", out)
    assert exr_windows(cropped) == (13, 6, 71, 49, 0, 0, 97, 61)
    assert exr_windows(out / "cropped.exr") == exr_windows(cropped)
    assert exr_windows(shifted) == (30, 20, 97, 61, 30, 20, 97, 61)
    assert exr_windows(out / "shifted.exr") == exr_windows(shifted)
    assert exr_windows(out / "overscan.exr") == (0, 0, 97, 61, 0, 0, 97, 61)
    # The same frame in a moved display window: the same output, moved with it.
    assert same_pixels([out / "shifted.exr"], [whole, "--origin", "+30+20", "--fullsize", "97x61+30+20"])
    assert not same_pixels([out / "shifted.exr"], [whole])
    assert same_pixels([out / "overscan.exr"], [whole])
    # Away from the crop's edges (which border the reader's transparent fill) the output is the
    # whole frame's, pixel for pixel, at the same place.
    assert same_pixels([out / "cropped.exr", "--crop", "41x19+28+21"], [whole, "--crop", "41x19+28+21"])
    assert not same_pixels([out / "cropped.exr"], [whole])
    for name in ("cropped", "shifted"):
        assert exr_windows(out / (name + ".png")) == (0, 0, 97, 61, 0, 0, 97, 61)


def exr_storage(path):
    """(pixel type, compression) of an EXR as OpenImageIO reads its header."""
    p = subprocess.run(["oiiotool", "--info", "-v", str(path)], capture_output=True, text=True, check=True)
    kind = p.stdout.split("channel, ", 1)[1].split()[0]
    return kind, p.stdout.split('compression: "', 1)[1].split('"', 1)[0]


def test_filter_writes_exrs_at_the_depth_and_codec_asked(chart, tmp_path):
    """--exr-depth and --exr-codec store the output EXRs as Blender's Color Depth and Codec do (its
    upper-case names taken too); the default stays float ZIP. The PNG does not change with them. A run
    resumed with other EXR settings makes its outputs again, saying why."""
    run("filter", "-m", "fxaa", "--png", chart / "chart_1spp.exr", "-o", tmp_path / "float")
    run("filter", "-m", "fxaa", "--png", "--exr-depth", "16", "--exr-codec", "DWAA", chart / "chart_1spp.exr",
        "-o", tmp_path / "half")
    assert exr_storage(tmp_path / "float" / "chart_1spp.exr") == ("float", "zip")
    assert exr_storage(tmp_path / "half" / "chart_1spp.exr") == ("half", "dwaa")
    assert same_pixels([tmp_path / "float" / "chart_1spp.png"], [tmp_path / "half" / "chart_1spp.png"])
    # dwaa is lossy: close, not equal (a few edge pixels of the chart move by 0.02-0.1)
    half, full = tmp_path / "half" / "chart_1spp.exr", tmp_path / "float" / "chart_1spp.exr"
    assert not same_pixels([half], [full])
    assert subprocess.run(["oiiotool", str(half), str(full), "--fail", "0.1", "--diff"],
                          capture_output=True).returncode == 0
    p = run("filter", "-m", "fxaa", "--png", "--exr-codec", "piz", "--resume", chart / "chart_1spp.exr",
            "-o", tmp_path / "half")
    assert 'was written as another EXR ({"codec":"dwaa","depth":16}, now {"codec":"piz","depth":32})' in p.stderr
    assert exr_storage(half) == ("float", "piz")


def test_rerun_without_png_leaves_no_stale_png(chart, tmp_path):
    out = tmp_path / "out"
    run("filter", "--method", "fxaa", "--png", chart / "chart_1spp.exr", "-o", out)
    assert (out / "chart_1spp.png").is_file()
    p = run("filter", "--method", "repair", chart / "chart_1spp.exr", "-o", out)
    assert not (out / "chart_1spp.png").exists(), "the PNG showed fxaa's result beside repair's EXR"
    assert "removed 1 PNG" in p.stderr
    assert run("filter", "-q", "--method", "fxaa", "--png", chart / "chart_1spp.exr", "-o", out).stderr == ""
    assert run("filter", "-q", "--method", "fxaa", chart / "chart_1spp.exr", "-o", out).stderr == ""
    assert not (out / "chart_1spp.png").exists()
    # A PNG this command did not write is kept and named, on every run (the EXR's stamp of the first
    # run says nothing of the PNG).
    other = tmp_path / "other"
    other.mkdir()
    (other / "chart_1spp.png").write_bytes(b"mine")
    for _ in range(2):
        p = run("filter", "--method", "fxaa", chart / "chart_1spp.exr", "-o", other)
        assert (other / "chart_1spp.png").read_bytes() == b"mine"
        assert "kept" in p.stderr and "chart_1spp.png" in p.stderr
    # Nor is one it wrote that the user changed since.
    run("filter", "--method", "fxaa", "--png", chart / "chart_1spp.exr", "-o", other)
    (other / "chart_1spp.png").write_bytes(b"painted over")
    p = run("filter", "--method", "repair", chart / "chart_1spp.exr", "-o", other)
    assert (other / "chart_1spp.png").read_bytes() == b"painted over"
    assert "kept" in p.stderr


def test_a_file_in_the_way_of_the_stamps_fails_before_any_output(chart, tmp_path):
    out = tmp_path / "out"
    out.mkdir()
    (out / ".crisp").write_text("not a folder")
    p = run("filter", "--method", "fxaa", chart / "chart_1spp.exr", "-o", out, ok=False)
    assert p.returncode == 1 and ".crisp" in p.stderr
    assert sorted(os.listdir(out)) == [".crisp"]


def test_existing_output_survives_a_failed_run(chart, tmp_path):
    out = tmp_path / "out"
    run("filter", "--method", "fxaa", chart / "chart_1spp.exr", "-o", out)
    before = (out / "chart_1spp.exr").read_bytes()
    bad = tmp_path / "chart_1spp.exr"  # same name as the existing output, but corrupt
    bad.write_bytes(b"\x76\x2f\x31\x01" + b"\x00" * 64)
    p = run("filter", "--method", "fxaa", bad, "-o", out, ok=False)
    assert p.returncode == 1
    assert (out / "chart_1spp.exr").read_bytes() == before


def test_refuses_to_overwrite_inputs(chart, tmp_path):
    src = tmp_path / "in"
    run("synth", "-o", src, "--size", "8x8")
    p = run("filter", "--method", "fxaa", src / "chart_1spp.exr", "-o", src, ok=False)
    assert p.returncode == 2 and "overwrite an input" in p.stderr
    p = run("filter", "--method", "fxaa", src / "chart_1spp.exr", src / "chart_1spp.png", "-o", tmp_path / "o", ok=False)
    assert p.returncode == 2 and "overwrite each other" in p.stderr
    # A PNG input filtered into its own folder: its output is an EXR, and only --png would replace it.
    pngs = tmp_path / "pngs"
    pngs.mkdir()
    shutil.copy(src / "chart_1spp.png", pngs / "a.png")
    before = (pngs / "a.png").read_bytes()
    run("filter", "-q", "--method", "fxaa", pngs / "a.png", "-o", pngs)
    assert (pngs / "a.exr").is_file() and (pngs / "a.png").read_bytes() == before
    p = run("filter", "--method", "fxaa", "--png", pngs / "a.png", "-o", pngs, ok=False)
    assert p.returncode == 2 and "overwrite an input" in p.stderr, p.stderr
    assert (pngs / "a.png").read_bytes() == before


def test_tiny_and_odd_sizes(tmp_path):
    for size in ("1x1", "2x3", "17x9"):
        d = tmp_path / size
        run("synth", "-o", d, "--size", size)
        for m in ("none", "fxaa", "repair", "taa"):
            run("filter", "-q", "--method", m, d / "chart_1spp.exr", "-o", d / m)
            assert (d / m / "chart_1spp.exr").is_file()


def test_synth_checks_every_output_name_before_writing(tmp_path):
    # A folder named like its last file: said before any write, so no partial chart is left.
    keep = tmp_path / "keep"
    (keep / "chart_edges.exr").mkdir(parents=True)
    p = run("synth", "-o", keep, "--size", "8x8", ok=False)
    assert p.returncode == 1 and "chart_edges.exr" in p.stderr and "folder" in p.stderr, p.stderr
    assert sorted(x.name for x in keep.iterdir()) == ["chart_edges.exr"]
    run("synth", "-o", tmp_path / "fresh" / "deeper", "--size", "8x8")
    assert sorted(x.name for x in (tmp_path / "fresh" / "deeper").iterdir()) == [
        "chart_1spp.exr", "chart_1spp.png", "chart_edges.exr", "chart_reference.exr", "chart_reference.png"]


@pytest.mark.skipif(shutil.which("blender") is None, reason="blender not installed")
def test_quiet_render_drops_progress_but_not_blenders_errors(tmp_path):
    # Blender reports an unreadable .blend on stdout, which --quiet otherwise drops.
    bad = tmp_path / "bad.blend"
    bad.write_bytes(b"not a blend file\n" * 64)
    p = run("render", "--scene", bad, "--frames", "1-2", "--method", "taa", "--quiet", "-o", tmp_path / "out",
            ok=False)
    assert p.returncode == 1 and p.stdout == ""
    assert "Error" in p.stderr and str(bad) in p.stderr, p.stderr
    # --plan's output is what was asked for: --quiet keeps it.
    p = run("render", "--scene", "spinning_cube", "--method", "taa", "--plan", "--quiet", "-o", tmp_path / "plan")
    assert "plan for taa:" in p.stdout


@pytest.mark.parametrize("command", ["render", "eval"])
def test_a_missing_blender_is_named_on_stderr(tmp_path, command):
    # Both commands start Blender through one launcher; its exec failure must reach the terminal,
    # not the capture (render --quiet) or the log (eval).
    args = ["--method", "taa"] if command == "render" else ["--methods", "taa"]
    p = run(command, "--scene", "spinning_cube", "--frames", "1-2", *args, "--quiet", "--blender",
            tmp_path / "no-blender", "-o", tmp_path / "out", ok=False)
    assert p.returncode == 1 and p.stdout == "", p.stdout
    assert "cannot run Blender '%s'" % (tmp_path / "no-blender") in p.stderr, p.stderr
    if command == "eval":
        assert (tmp_path / "out" / "logs" / "blender.log").read_text() == ""
        # Nothing was rendered: the folder is not locked to this run's settings, and the corrected command
        # (another size too) gets as far as Blender again.
        assert not (tmp_path / "out" / "eval_settings.json").exists()
        p = run(command, "--scene", "spinning_cube", "--frames", "1-2", *args, "--quiet", "--resolution", "64x36",
                "--blender", tmp_path / "no-blender", "-o", tmp_path / "out", ok=False)
        assert "cannot run Blender" in p.stderr and "other settings" not in p.stderr, p.stderr


def test_eval_warns_of_curve_points_the_reference_is_no_better_than(tmp_path):
    """A curve point at or above the reference's sample count is measured against a reference no better than
    itself (the same count: 100 dB): said before anything runs. Points below it, as the default curve's, are not."""
    base = ["eval", "--scene", "spinning_cube", "--frames", "1-2", "--methods", "none", "--quiet", "--blender",
            tmp_path / "no-blender"]
    p = run(*base, "--reference-samples", "4", "--curve", "1,4,8", "-o", tmp_path / "a", ok=False)
    assert "eval: warning: EEVEE at 4, 8 sample(s) is measured against a reference of 4" in p.stderr, p.stderr
    for more in (["--reference-samples", "4", "--curve", "1,2"], ["--reference-samples", "4"]):
        p = run(*base, *more, "-o", tmp_path / "b", ok=False)
        assert "cannot run Blender" in p.stderr and "warning" not in p.stderr, p.stderr


@pytest.mark.parametrize("command", ["render", "eval"])
def test_a_blender_that_exits_127_is_not_taken_for_a_missing_one(tmp_path, command):
    # A wrapper script starts (exec succeeds) and then fails with 127 itself: its own message must
    # reach the user (render --quiet shows the end of what it printed, eval points at its log).
    wrapper = tmp_path / "blender-wrapper"
    wrapper.write_text("#!/bin/sh\necho 'wrapper: no blender behind me' >&2\nexit 127\n")
    wrapper.chmod(0o755)
    args = ["--method", "taa"] if command == "render" else ["--methods", "taa"]
    p = run(command, "--scene", "spinning_cube", "--frames", "1-2", *args, "--quiet", "--blender", wrapper,
            "-o", tmp_path / "out", ok=False)
    assert p.returncode == 1 and "cannot run Blender" not in p.stderr, p.stderr
    if command == "render":
        assert "wrapper: no blender behind me" in p.stderr, p.stderr
    else:
        assert "Blender failed (exit 127)" in p.stderr, p.stderr
        assert "no blender behind me" in (tmp_path / "out" / "logs" / "blender.log").read_text()


def test_jitter_distributions_match_the_add_ons():
    """The CLI checks --jitter before Blender starts: its list must be the add-on's."""
    import ast
    source = pathlib.Path(__file__).resolve().parents[2] / "addon" / "crisp" / "render.py"
    tree = ast.parse(source.read_text())
    addon = next(ast.literal_eval(n.value) for n in tree.body if isinstance(n, ast.Assign)
                 and any(getattr(t, "id", None) == "JITTER_DISTRIBUTIONS" for t in n.targets))
    p = run("eval", "--scene", "still_life", "--jitter", "x", "-o", "/nonexistent/never", ok=False)
    known = p.stderr.split("(known: ")[1].split(")")[0].split(", ")
    assert p.returncode == 2 and sorted(known) == sorted(addon), (known, addon)


def test_an_interrupted_rewrite_is_not_kept_by_resume(chart, tmp_path):
    """The settings record of an output goes before the output is replaced: a run stopped between
    the two (here the PNG's record cannot be put in place, after the EXR and the PNG were; a folder
    in the place of an output itself is refused before the run starts) leaves no record, so --resume
    with the first settings makes the frame again instead of keeping the second run's pixels."""
    out = tmp_path / "out"
    src = chart / "chart_1spp.exr"
    run("filter", "-q", "-m", "fxaa", "-o", out, src)
    first = tmp_path / "first.exr"
    shutil.copy(out / "chart_1spp.exr", first)
    (out / ".crisp" / "chart_1spp.png.stamp").mkdir()  # the PNG record's rename fails
    p = run("filter", "-q", "-m", "fxaa", "--set", "subpix=0", "--png", "-o", out, src, ok=False)
    assert p.returncode == 1 and "chart_1spp.png.stamp" in p.stderr, p.stderr
    assert not (out / ".crisp" / "chart_1spp.json").exists()
    (out / ".crisp" / "chart_1spp.png.stamp").rmdir()
    p = run("filter", "-m", "fxaa", "--resume", "-o", out, src)
    assert "nothing to do" not in p.stdout, p.stdout
    # the same pixels (not bytes: OpenEXR's threaded writer may order its chunks differently)
    js = tmp_path / "same.json"
    run("compare", "-q", "-r", first, "-t", out / "chart_1spp.exr", "--json", js)
    assert json.loads(js.read_text())["frames"][0]["mse"] == 0.0


def test_long_file_names_get_their_records(chart, tmp_path):
    """A stem near the 255-byte name limit still gets its outputs, PNG stamp and settings record:
    the temporary names are shortened, not the stem longer than the limit allows."""
    src = tmp_path / "in"
    src.mkdir()
    stem = "f" * 238
    shutil.copy(chart / "chart_1spp.exr", src / (stem + ".exr"))
    out = tmp_path / "out"
    run("filter", "-q", "-m", "fxaa", "--png", "-o", out, src / (stem + ".exr"))
    assert sorted(os.listdir(out)) == [".crisp", stem + ".exr", stem + ".png"]
    assert sorted(os.listdir(out / ".crisp")) == [stem + ".json", stem + ".png.stamp"]


def test_compare_warns_when_a_reference_is_paired_with_another_frames_test(chart, tmp_path):
    """Files are paired in the order given: a sequence listed in another order for --test than for
    --reference compares frame 1 with frame 2 and the other way round. The figures are still given
    (comparing neighbouring frames is a use), with a warning naming the first crossed pair."""
    ref, test = tmp_path / "ref", tmp_path / "test"
    ref.mkdir()
    test.mkdir()
    for name, source in (("frame_0001.exr", "chart_reference.exr"), ("frame_0002.exr", "chart_1spp.exr")):
        shutil.copy(chart / source, ref / name)
        shutil.copy(chart / source, test / name)
    p = run("compare", "-q", "-r", ref / "frame_0001.exr", ref / "frame_0002.exr",
            "-t", test / "frame_0002.exr", test / "frame_0001.exr")
    assert ("warning: files are paired in the order given: reference '%s' is paired with test '%s', though test "
            "'%s' has its name (2 such pairs)" % (ref / "frame_0001.exr", test / "frame_0002.exr",
                                                  test / "frame_0001.exr")) in p.stderr, p.stderr
    p = run("compare", "-q", "-r", ref / "frame_0001.exr", ref / "frame_0002.exr",
            "-t", test / "frame_0001.exr", test / "frame_0002.exr")
    assert "warning" not in p.stderr
    # Names that match no test's are no sign of a mix-up.
    p = run("compare", "-q", "-r", chart / "chart_reference.exr", "-t", test / "frame_0001.exr")
    assert "warning" not in p.stderr


def test_compare_refuses_maps_and_json_that_would_replace_files(chart, tmp_path):
    ref, test = chart / "chart_reference.exr", chart / "chart_1spp.exr"
    a, b = tmp_path / "a", tmp_path / "b"
    for d in (a, b):
        d.mkdir()
        shutil.copy(test, d / "frame.exr")
    run("compare", "-q", "-r", ref, ref, "-t", a / "frame.exr", b / "frame.exr", "--maps", tmp_path / "maps")
    assert sorted(os.listdir(tmp_path / "maps")) == sorted(d + s for d in ("a_frame", "b_frame")
                                                           for s in (".error.exr", ".ssim.exr", ".flip.exr", ".flip.png"))
    victim = a / "frame.error.exr"  # a test file that frame.exr's error map would replace
    shutil.copy(test, victim)
    before = victim.read_bytes()
    p = run("compare", "-r", ref, ref, "-t", victim, a / "frame.exr", "--maps", a, ok=False)
    assert p.returncode == 2 and "is an input file" in p.stderr, p.stderr
    p = run("compare", "-r", ref, "-t", a / "frame.exr", "--json", a / "frame.exr", ok=False)
    assert p.returncode == 2 and "--json" in p.stderr, p.stderr
    assert victim.read_bytes() == before and (a / "frame.exr").read_bytes() == test.read_bytes()


def test_compare_json_may_go_into_the_maps_folder_it_makes(chart, tmp_path):
    ref, test = chart / "chart_reference.exr", chart / "chart_1spp.exr"
    maps = tmp_path / "new" / "maps"
    run("compare", "-q", "-r", ref, "-t", test, "--maps", maps, "--json", maps / "figures.json")
    assert json.loads((maps / "figures.json").read_text())["frames"][0]["test"] == str(test)
    # A run that fails (a test file that is not there) leaves no folder it made behind.
    p = run("compare", "-q", "-r", ref, "-t", tmp_path / "missing.exr", "--maps", tmp_path / "other" / "maps",
            "--json", tmp_path / "other" / "maps" / "figures.json", ok=False)
    assert p.returncode == 1 and "missing.exr" in p.stderr, p.stderr
    assert not (tmp_path / "other").exists()


def test_a_text_file_that_cannot_be_written_whole_keeps_the_old_one(chart, tmp_path):
    """--json on a full disk (a file size limit, RLIMIT_FSIZE, with SIGXFSZ ignored so that the write
    fails with EFBIG): an error naming the file, the old file's bytes kept, no temporary file left."""
    import resource
    import signal

    js = tmp_path / "figures.json"
    js.write_text("the previous run's figures\n")

    def small_disk():
        signal.signal(signal.SIGXFSZ, signal.SIG_IGN)
        resource.setrlimit(resource.RLIMIT_FSIZE, (64, 64))

    p = subprocess.run([str(CRISP), "compare", "-q", "-r", str(chart / "chart_reference.exr"), "-t",
                        str(chart / "chart_1spp.exr"), "--json", str(js)], capture_output=True, text=True,
                       timeout=120, preexec_fn=small_disk)
    assert p.returncode == 1 and "cannot write" in p.stderr and str(js) in p.stderr, p.stderr
    assert js.read_text() == "the previous run's figures\n"
    assert os.listdir(tmp_path) == ["figures.json"], os.listdir(tmp_path)
    run("compare", "-q", "-r", chart / "chart_reference.exr", "-t", chart / "chart_1spp.exr", "--json", js)
    assert len(js.read_bytes()) > 64, "the figures must not fit the limit, or this tests nothing"


def test_a_half_float_id_pass_fails_only_methods_that_read_ids(chart, tmp_path):
    """An ID pass stored as half float cannot hold the hashes: crisp filter refuses it for a method
    that reads IDs, naming the pass and the file, and filters the frame for one that does not;
    crisp info says so and goes on to the next file after one it cannot read."""
    L = "ViewLayer"
    half = tmp_path / "half_ids.exr"
    crypto = ["%s.CryptoObject00.%s" % (L, c) for c in "rgba"]
    subprocess.run(["oiiotool", str(chart / "chart_1spp.exr"), "--ch", "R,G,B,A,R,G,B,A", "--chnames",
                    ",".join(["%s.Combined.%s" % (L, c) for c in "RGBA"] + crypto), "-d", "float",
                    *[a for c in crypto for a in ("-d", c + "=half")], "-o", str(half)],
                   check=True, capture_output=True)
    p = run("filter", "--method", "taa-improved", half, "-o", tmp_path / "ids", ok=False)
    assert p.returncode == 1 and "pass '%s.CryptoObject00'" % L in p.stderr and "half_ids.exr" in p.stderr, p.stderr
    assert "object IDs would be lost" in p.stderr, p.stderr
    assert not list((tmp_path / "ids").glob("*.exr"))
    run("filter", "--method", "fxaa", half, "-o", tmp_path / "no_ids")
    assert (tmp_path / "no_ids" / "half_ids.exr").is_file()
    p = run("info", tmp_path / "missing.exr", half, ok=False)
    assert p.returncode == 1 and "missing.exr\n  error: cannot read" in p.stdout, p.stdout
    assert "unusable: id (pass '%s.CryptoObject00'" % L in p.stdout, p.stdout
    lines = {l.split()[0]: l for l in p.stdout.splitlines() if l.startswith("    ")}
    assert "missing: id (unusable)" in lines["taa-improved"] and "ready" in lines["fxaa"], p.stdout
    assert "1 of 2 files could not be read" in p.stderr, p.stderr


def test_render_checks_the_method_and_its_settings_before_blender(tmp_path):
    """crisp render (and --plan, which renders nothing) refuses a bad --set as crisp filter does,
    before Blender starts: nothing is written."""
    for method, kv, message in (("taa", "bogus=1", "filter 'taa': unknown parameter 'bogus'"),
                                ("taa", "feedbackMin=nan", "'feedbackMin' = nan is out of range"),
                                (None, "kappa=1", "filter 'fxaa': unknown parameter 'kappa'")):
        for plan in ((), ("--plan",)):
            out = tmp_path / "out"
            p = run("render", "--scene", "still_life", "-o", out, *plan, *(("-m", method) if method else ()),
                    "--set", kv, "--blender", tmp_path / "no_blender_here", ok=False)
            assert p.returncode == 1 and message in p.stderr, p.stderr
            assert not out.exists()
    # What batch.py and the add-on accept passes: blanks around KEY and VALUE, a bool in any case.
    # (It then gets as far as starting Blender, which is not there.)
    p = run("render", "--scene", "still_life", "-o", tmp_path / "out", "--plan", "-m", "fxaa", "--set", "reference=True",
            "--set", " subpix = 0.5 ", "--blender", tmp_path / "no_blender_here", ok=False)
    assert "cannot run Blender" in p.stderr and "parameter" not in p.stderr, p.stderr
    # rsaa's camera comes from the frame's sidecar: refused as crisp filter refuses it.
    p = run("render", "--scene", "still_life", "-o", tmp_path / "out", "-m", "rsaa", "--set", "proj00=2",
            "--blender", tmp_path / "no_blender_here", ok=False)
    assert p.returncode == 2 and "--set proj00: rsaa takes its camera from each frame's sidecar" in p.stderr, p.stderr


def test_info_checks_rsaa_as_filter_does(chart, tmp_path):
    """rsaa needs its sidecar's sub-sample renders; `info` says so for a frame without one, as
    `filter -m rsaa` refuses it."""
    p = run("info", chart / "chart_1spp.exr")
    line = next(l for l in p.stdout.splitlines() if l.strip().startswith("rsaa"))
    assert "missing" in line and "sidecar" in line, line
    p = run("filter", "-q", "-m", "rsaa", "-o", tmp_path / "o", chart / "chart_1spp.exr", ok=False)
    assert p.returncode == 1 and "sidecar" in p.stderr


def test_a_missing_input_fails_before_the_output_folder_is_made(chart, tmp_path):
    out = tmp_path / "new" / "out"
    p = run("filter", "--method", "fxaa", chart / "chart_1spp.exr", tmp_path / "missing.exr", "-o", out, ok=False)
    assert p.returncode == 1 and "missing.exr" in p.stderr and "no such file" in p.stderr, p.stderr
    assert not (tmp_path / "new").exists()  # nothing made, not even the folder


def test_non_finite_colour_is_reported_per_file(chart, tmp_path):
    bad = tmp_path / "nan.exr"
    # Every colour value negative, then its square root: NaN in R, G, B; alpha stays finite.
    subprocess.run(["oiiotool", str(chart / "chart_1spp.exr"), "--subc", "1", "--powc", "0.5", "-o", str(bad)],
                   check=True, capture_output=True)
    p = run("filter", "--method", "fxaa", chart / "chart_1spp.exr", bad, "-o", tmp_path / "out")
    warnings = [line for line in p.stderr.splitlines() if "non-finite" in line]
    assert len(warnings) == 1 and "nan.exr" in warnings[0], p.stderr
    assert " %d non-finite colour values" % (97 * 61 * 3) in warnings[0], warnings[0]
    assert (tmp_path / "out" / "nan.exr").exists()  # still filtered, as the library reads it
    # compare has no figure to give for it: refused, naming the file, writing no --json.
    p = run("compare", "-r", chart / "chart_reference.exr", "-t", bad, "--json", tmp_path / "m.json", ok=False)
    assert p.returncode == 1 and "'%s' has %d non-finite colour values" % (bad, 97 * 61 * 3) in p.stderr, p.stderr
    assert not (tmp_path / "m.json").exists()
    p = run("compare", "-r", bad, "-t", chart / "chart_1spp.exr", ok=False)
    assert p.returncode == 1 and "nan.exr" in p.stderr, p.stderr
    # info, which says what a file holds, says it too (and nothing of a finite file).
    assert "non-finite colour values: %d" % (97 * 61 * 3) in run("info", bad).stdout
    assert "non-finite" not in run("info", chart / "chart_1spp.exr").stdout


def test_colour_beyond_half_float_range_is_reported_per_file(chart, tmp_path):
    """The library clamps finite colour to +-65504 (the GLSL preview's half floats): filter warns, per
    file, and info says it, as for non-finite values; a file within range gets no word of it."""
    bright = tmp_path / "bright.exr"
    subprocess.run(["oiiotool", "--pattern", "constant:color=1e5,0.5,-2e5", "97x61", "3", "-d", "float",
                    "-o", str(bright)], check=True, capture_output=True)
    p = run("filter", "--method", "fxaa", chart / "chart_1spp.exr", bright, "-o", tmp_path / "out")
    warnings = [line for line in p.stderr.splitlines() if "65504" in line]
    assert len(warnings) == 1 and "bright.exr" in warnings[0], p.stderr
    assert " %d colour values beyond +-65504" % (97 * 61 * 2) in warnings[0], warnings[0]
    assert "colour values beyond +-65504: %d" % (97 * 61 * 2) in run("info", bright).stdout
    assert "65504" not in run("info", chart / "chart_1spp.exr").stdout


def test_a_one_channel_mask_is_read_whatever_its_name(chart, tmp_path):
    """compare --mask takes the mask's first channel: a one-channel file's whatever its name, the
    same pixels as the RGB edge mask's R."""
    args = ["--reference", chart / "chart_reference.exr", "--test", chart / "chart_1spp.exr"]
    run("compare", *args, "--mask", chart / "chart_edges.exr", "--json", tmp_path / "rgb.json")
    rgb = json.loads((tmp_path / "rgb.json").read_text())["frames"][0]
    for name in ("R", "mask", "Depth.Z"):
        one = tmp_path / ("edges_%s.exr" % name)
        subprocess.run(["oiiotool", str(chart / "chart_edges.exr"), "--ch", "%s=R" % name, "-o", str(one)],
                       check=True, capture_output=True)
        js = tmp_path / ("%s.json" % name)
        run("compare", *args, "--mask", one, "--json", js)
        frame = json.loads(js.read_text())["frames"][0]
        assert (frame["pixels"], frame["psnr"]) == (rgb["pixels"], rgb["psnr"]), name
    assert rgb["pixels"] < 97 * 61
    deep = tmp_path / "deep_mask.exr"  # a deep one-channel file is refused as readFrame refuses one
    subprocess.run(["oiiotool", "--pattern", "constant:color=1", "97x61", "1", "--chnames", "Z", "--deepen",
                    "-o", str(deep)], check=True, capture_output=True)
    p = run("compare", *args, "--mask", deep, ok=False)
    assert p.returncode == 1 and "mask '%s' is a deep image" % deep in p.stderr, p.stderr


NOBODY = ["setpriv", "--reuid=65534", "--regid=65534", "--clear-groups"]


@pytest.fixture
def as_nobody():
    """(the command prefix that runs a program as nobody, a folder nobody may enter): root reads and
    writes every file, so the checks of permissions run as nobody. Skipped unless root."""
    import tempfile
    if os.geteuid() != 0 or not shutil.which("setpriv"):
        pytest.skip("needs root to run crisp as nobody")
    if subprocess.run(NOBODY + [str(CRISP), "help"], capture_output=True).returncode != 0:
        pytest.skip("nobody cannot run %s (a folder on its path is private)" % CRISP)
    d = pathlib.Path(tempfile.mkdtemp())
    d.chmod(0o755)
    yield NOBODY, d
    shutil.rmtree(d)


def test_an_unreadable_input_is_named_with_the_reason(chart, as_nobody):
    nobody, d = as_nobody
    f = d / "locked.exr"
    shutil.copy(chart / "chart_1spp.exr", f)
    f.chmod(0)
    p = subprocess.run(nobody + [str(CRISP), "filter", "--method", "fxaa", str(f), "-o", str(d / "out")],
                       capture_output=True, text=True, timeout=60)
    assert p.returncode == 1, p.stderr
    assert "cannot read '%s': Permission denied" % f in p.stderr, p.stderr
    assert not (d / "out").exists()


def test_a_resume_takes_minus_zero_for_zero(chart, tmp_path):
    """A --set value is stamped as the filter holds it (canonicalParamText), so a resume with 0.0, -0 or
    0e3 keeps what 0 made; -0 was stamped apart from 0 and made the outputs again."""
    out = tmp_path / "out"
    run("filter", "-m", "taa", "--set", "jitterX=0", chart / "chart_1spp.exr", "-o", out)
    for spelling in ("0.0", "-0", "0e3"):
        p = run("filter", "-m", "taa", "--set", "jitterX=" + spelling, "--resume", chart / "chart_1spp.exr", "-o", out)
        assert "nothing to do" in p.stdout, (spelling, p.stderr)


def test_an_exr_beside_its_input_that_crisp_did_not_write_is_not_replaced(chart, tmp_path):
    """-o the inputs' folder, the inputs TIFFs beside Blender's multilayer EXRs of the same frames: the
    output replaced the EXR (its depth lost) without a word; only inputs were protected. It is refused
    (exit 2) and the EXR is left as it was. An output crisp filter wrote there itself is made again."""
    shot = tmp_path / "shot"
    shot.mkdir()
    shutil.copy(chart / "chart_1spp.exr", shot / "frame_0001.exr")
    subprocess.run(["oiiotool", str(chart / "chart_1spp.exr"), "-d", "uint16", "-o", str(shot / "frame_0001.tif")],
                   check=True, capture_output=True)
    before = (shot / "frame_0001.exr").read_bytes()
    p = run("filter", "-m", "fxaa", shot / "frame_0001.tif", "-o", shot, ok=False)
    assert p.returncode == 2, p.stderr
    assert ("output '%s' would replace a file beside the input '%s' that crisp filter did not write"
            % (shot / "frame_0001.exr", shot / "frame_0001.tif")) in p.stderr, p.stderr
    # Given from inside the folder too (an input without a folder, -o .).
    p = subprocess.run([str(CRISP), "filter", "-m", "fxaa", "frame_0001.tif", "-o", "."], cwd=shot,
                       capture_output=True, text=True, timeout=60)
    assert p.returncode == 2 and "would replace a file beside the input 'frame_0001.tif'" in p.stderr, p.stderr
    assert (shot / "frame_0001.exr").read_bytes() == before
    (shot / "frame_0001.exr").unlink()
    run("filter", "-m", "fxaa", shot / "frame_0001.tif", "-o", shot)
    made = (shot / "frame_0001.exr").read_bytes()
    run("filter", "-m", "none", shot / "frame_0001.tif", "-o", shot)  # its own output, stamped: replaced
    assert (shot / "frame_0001.exr").read_bytes() != made
    # With --png, the artist's PNG of that frame likewise; one --png wrote is made again.
    shutil.copy(shot / "frame_0001.tif", shot / "frame_0001.png")
    artists = (shot / "frame_0001.png").read_bytes()
    p = run("filter", "-m", "fxaa", "--png", shot / "frame_0001.tif", "-o", shot, ok=False)
    assert p.returncode == 2 and "output '%s' would replace" % (shot / "frame_0001.png") in p.stderr, p.stderr
    assert (shot / "frame_0001.png").read_bytes() == artists
    (shot / "frame_0001.png").unlink()
    run("filter", "-m", "fxaa", "--png", shot / "frame_0001.tif", "-o", shot)
    run("filter", "-m", "none", "--png", shot / "frame_0001.tif", "-o", shot)


def test_a_stamps_folder_of_another_user_fails_before_any_output(chart, as_nobody):
    """OUT/.crisp made by another user (a farm's workers under other accounts), OUT writable: crisp filter
    wrote the first output and then stopped at its stamp, leaving an output without one. It stops first."""
    nobody, d = as_nobody
    out = d / "out"
    (out / ".crisp").mkdir(parents=True)
    out.chmod(0o777)
    (out / ".crisp").chmod(0o755)
    shutil.copy(chart / "chart_1spp.exr", d / "a.exr")
    (d / "a.exr").chmod(0o644)
    p = subprocess.run(nobody + [str(CRISP), "filter", "--method", "fxaa", str(d / "a.exr"), "-o", str(out)],
                       capture_output=True, text=True, timeout=60)
    assert p.returncode == 1, p.stderr
    assert "cannot keep stamps in '%s': the folder is not writable" % (out / ".crisp") in p.stderr, p.stderr
    assert sorted(f.name for f in out.iterdir()) == [".crisp"]


# crisp render and the scene's Crisp panel (scene.crisp, addon/crisp/properties.py): what the command line
# leaves out comes from the .blend's panel when the file set it (addon/crisp/batch.py panel_settings).
SOURCE = pathlib.Path(os.environ.get("CRISP_SOURCE_DIR") or pathlib.Path(__file__).resolve().parents[2])
PANEL_SCENE = """
import sys
sys.path[:0] = [%r, %r]
import bpy, spinning_cube
from crisp import properties
spinning_cube.build()
properties.register()  # the add-on's scene settings, as an artist's Blender has them
s = bpy.context.scene.crisp
%s
bpy.ops.wm.save_as_mainfile(filepath=%r)
"""


def panel_blend(path, settings):
    """spinning_cube saved as `path` by a Blender with the add-on's settings registered, after running
    `settings` (Python, `s` being scene.crisp): "" leaves the panel untouched."""
    code = PANEL_SCENE % (str(SOURCE / "addon"), str(SOURCE / "test_scenes"), settings or "pass", str(path))
    p = subprocess.run(["blender", "-b", "--factory-startup", "--python-exit-code", "1", "--python-expr", code],
                       capture_output=True, text=True, timeout=300,
                       env=dict(os.environ, CRISP_LIBRARY=str(BUILD / "lib" / "libcrisp.so")))
    assert p.returncode == 0 and path.is_file(), p.stdout[-2000:] + p.stderr[-2000:]
    return path


def render_panel(blend, out, *args, ok=True):
    p = subprocess.run([str(CRISP), "render", "--scene", str(blend), "--resolution", "64x36", "--frames", "1-2",
                        "-o", str(out), *map(str, args)], capture_output=True, text=True, timeout=600)
    if ok:
        assert p.returncode == 0, p.stdout[-3000:] + p.stderr[-3000:]
    return p


def run_record(out, name="run.json"):
    return json.loads((out / name).read_text())


def frame_mse(a, b, tmp_path):
    js = tmp_path / "mse.json"
    run("compare", "--reference", a, "--test", b, "--json", js)
    return json.loads(js.read_text())["frames"][0]["mse"]


needs_blender = pytest.mark.skipif(shutil.which("blender") is None, reason="blender not installed")
PANEL_TAA = ('s.method = "taa"; s.taa.sharpen = 0.5; s.jitter_distribution = "uniform"; s.fxaa.subpix = 0.25; '
             's.input_codec = "piz"')


@pytest.fixture(scope="module")
def panel_taa(tmp_path_factory):
    """A .blend whose panel says taa with sharpen 0.5, uniform jitter and PIZ inputs (and fxaa's subpix 0.25)."""
    return panel_blend(tmp_path_factory.mktemp("panel") / "shot.blend", PANEL_TAA)


@needs_blender
def test_render_takes_the_method_jitter_and_parameters_from_the_scenes_panel(panel_taa, tmp_path):
    """Without --method, --jitter, --input-codec or --set, crisp render runs what the .blend's Crisp panel
    says, records it (run.json, each input's sidecar, which a resume compares) and says so in one line; it
    ran fxaa with blackman-harris, uncompressed inputs and the library's defaults."""
    out = tmp_path / "out"
    p = render_panel(panel_taa, out)
    assert "render: method taa, jitter uniform, input codec piz and 1 parameter (sharpen=0.5) from the scene's " \
           "Crisp panel (shot.blend)" in p.stdout, p.stdout[-3000:]
    record = run_record(out)
    assert (record["method"], record["params"], record["jitter_distribution"], record["input_codec"]) == (
        "taa", {"sharpen": "0.5"}, "uniform", "piz")
    assert exr_storage(out / "input" / "frame_0002.exr") == ("float", "piz")
    made = json.loads((out / "input" / "frame_0002.json").read_text())["made_with"]
    assert (made["method"], made["params"], made["jitter_distribution"]) == ("taa", {"sharpen": "0.5"}, "uniform")
    # Not fxaa's frames: the command line's --method fxaa (below) filters the same scene otherwise.
    fxaa = tmp_path / "fxaa"
    p = render_panel(panel_taa, fxaa, "--method", "fxaa", "--quiet")
    assert "Crisp panel" not in p.stdout + p.stderr  # --quiet: the line is not said
    assert frame_mse(fxaa / "filtered" / "frame_0002.exr", out / "filtered" / "frame_0002.exr", tmp_path) > 0
    # --plan reports the panel's method too.
    p = render_panel(panel_taa, tmp_path / "plan", "--plan")
    assert run_record(tmp_path / "plan")["method"] == "taa" and "taa" in p.stdout, p.stdout[-2000:]


@needs_blender
def test_the_command_line_overrides_the_panel_key_by_key(panel_taa, tmp_path):
    """--method another method: it runs with that method's panel parameters (fxaa's subpix here); --set
    replaces one panel parameter and adds others; --jitter and --input-codec replace the panel's."""
    out = tmp_path / "fxaa"
    p = render_panel(panel_taa, out, "--method", "fxaa")
    record = run_record(out)
    assert (record["method"], record["params"]) == ("fxaa", {"subpix": "0.25"}), record["params"]
    assert "render: input codec piz and 1 parameter (subpix=0.25) from the scene's Crisp panel (shot.blend)" \
        in p.stdout, p.stdout[-2000:]
    out = tmp_path / "set"
    p = render_panel(panel_taa, out, "--set", "sharpen=0.25", "--set", "feedbackMin=0.6", "--jitter",
                     "blackman-harris", "--input-codec", "ZIP")
    record = run_record(out)
    assert (record["method"], record["params"], record["jitter_distribution"], record["input_codec"]) == (
        "taa", {"sharpen": "0.25", "feedbackMin": "0.6"}, "blackman-harris", "zip"), record
    assert exr_storage(out / "input" / "frame_0001.exr") == ("float", "zip")
    assert "render: method taa from the scene's Crisp panel (shot.blend)" in p.stdout, p.stdout[-2000:]
    # --method naming the panel's method keeps its parameters under --set.
    p = render_panel(panel_taa, tmp_path / "plan", "--method", "taa", "--set", "feedbackMin=0.6", "--plan")
    assert run_record(tmp_path / "plan")["params"] == {"sharpen": "0.5", "feedbackMin": "0.6"}
    # --no-panel (the Flamenco job's tasks): the command line and the library's defaults only.
    p = render_panel(panel_taa, tmp_path / "taa", "--no-panel", "--method", "taa", "--set", "feedbackMin=0.6",
                     "--plan")
    record = run_record(tmp_path / "taa")
    assert (record["method"], record["params"], record["jitter_distribution"], record["input_codec"]) == (
        "taa", {"feedbackMin": "0.6"}, "blackman-harris", "none"), record
    assert "Crisp panel" not in p.stdout, p.stdout[-2000:]
    render_panel(panel_taa, tmp_path / "none", "--no-panel", "--plan")
    assert (run_record(tmp_path / "none")["method"], run_record(tmp_path / "none")["params"]) == ("fxaa", {})


@needs_blender
def test_an_untouched_panel_method_keeps_fxaa(tmp_path):
    """A panel whose method was never set runs fxaa (as before the panel was read), with the panel's own
    fxaa parameters; the jitter too stays blackman-harris."""
    blend = panel_blend(tmp_path / "fxaa_only.blend", "s.fxaa.subpix = 0.5")
    out = tmp_path / "out"
    p = render_panel(blend, out, "--method", "taa", "--plan")
    assert run_record(out)["jitter_distribution"] == "blackman-harris"
    p = render_panel(blend, out)
    record = run_record(out)
    assert (record["method"], record["params"]) == ("fxaa", {"subpix": "0.5"}), record
    assert "render: 1 parameter (subpix=0.5) from the scene's Crisp panel (fxaa_only.blend)" in p.stdout


@needs_blender
def test_a_panel_value_the_library_refuses_fails_before_rendering(tmp_path):
    """taa's feedbackMin above its feedbackMax: each in its range (the panel takes it), refused by the
    library's commit. The run stops with exit 1 (an error naming a parameter, as when crisp refuses a --set
    before Blender starts) naming the parameter and the panel, before any frame,
    also under --quiet and --plan; a --set that makes them agree lets it run."""
    blend = panel_blend(tmp_path / "bad.blend", 's.method = "taa"; s.taa.feedbackMin = 0.95')
    for extra in ((), ("--quiet",), ("--plan",)):
        out = tmp_path / "out"
        p = render_panel(blend, out, *extra, ok=False)
        assert p.returncode == 1, p.stdout[-2000:] + p.stderr[-2000:]
        assert "taa's parameters from the scene's Crisp panel (bad.blend: feedbackMin=0.95) are refused" \
               in p.stderr and "feedbackMax" in p.stderr, p.stderr[-2000:]
        assert not (out / "input").exists() and not (out / "run.json").exists()
    p = render_panel(blend, tmp_path / "plan", "--plan", "--set", "feedbackMax=0.99")
    assert run_record(tmp_path / "plan")["params"] == {"feedbackMin": "0.95", "feedbackMax": "0.99"}
    # Without --method crisp cannot check --set before Blender starts (the panel names the method): the
    # driver checks it against the panel's method, naming where each value came from.
    p = render_panel(blend, tmp_path / "out", "--plan", "--set", "bogus=1", ok=False)
    assert p.returncode == 1 and "unknown parameter 'bogus'" in p.stderr and "from --set bogus=1" in p.stderr, \
        p.stderr[-2000:]
    assert not (tmp_path / "out" / "run.json").exists()


@needs_blender
def test_a_panel_choice_of_a_newer_addon_is_named_before_rendering(tmp_path):
    """A method or input codec saved by a newer add-on (a number this one's menu does not hold) stops the
    run with exit 2 before anything renders, naming the panel and the option that gives another; with the
    option given, it runs."""
    for setting, option, value, words in (("method", "--method", "fxaa", "has a method this library does not offer"),
                                          ("input_codec", "--input-codec", "zip",
                                           "has an input codec this add-on does not offer")):
        blend = panel_blend(tmp_path / (setting + ".blend"), 's["%s"] = 9' % setting)
        out = tmp_path / setting
        p = render_panel(blend, out, ok=False)
        assert p.returncode == 2, p.stdout[-2000:] + p.stderr[-2000:]
        assert words in p.stderr and "(saved as number 9)" in p.stderr and option in p.stderr, p.stderr[-2000:]
        assert not (out / "run.json").exists() and not (out / "input").exists()
        render_panel(blend, out, option, value, "--plan")
        assert run_record(out)[setting] == value


@needs_blender
def test_a_resume_sees_a_panel_edited_since(tmp_path):
    """A chunk made before the panel's parameter was edited (and the .blend saved) is made again by a
    resume, which names the parameter's change: the sidecars record the panel's values."""
    blend = panel_blend(tmp_path / "shot.blend", 's.method = "taa"; s.taa.sharpen = 0.5')
    out = tmp_path / "out"
    chunk = ("--shot", "1-2", "--preroll", "1", "--resume")
    render_panel(blend, out, *chunk)
    assert run_record(out, "run_0001-0002.json")["params"] == {"sharpen": "0.5"}
    panel_blend(blend, 's.method = "taa"; s.taa.sharpen = 0.25')
    p = render_panel(blend, out, *chunk)
    assert 'params {"sharpen": "0.5"} there, {"sharpen": "0.25"} here' in p.stdout, p.stdout[-3000:]
    assert run_record(out, "run_0001-0002.json")["params"] == {"sharpen": "0.25"}
    assert json.loads((out / "input" / "frame_0001.json").read_text())["made_with"]["params"] == {"sharpen": "0.25"}


LINK_SCENE = """
import bpy
bpy.context.scene.name = "Main"  # the file's own scene, left behind
with bpy.data.libraries.load(%r, link=True) as (src, dst):
    dst.scenes = ["Scene"]
bpy.context.window.scene = dst.scenes[0]
bpy.ops.wm.save_as_mainfile(filepath=%r)
"""


@needs_blender
def test_a_resume_sees_a_linked_library_edited_since(tmp_path):
    """A shot whose scene is linked from another .blend: after that library was edited (its objects
    moved) and saved, a resume makes the frames again, as for an edit of the opened file; they kept
    the old picture, since only the opened file was hashed."""
    library = panel_blend(tmp_path / "set.blend", "")
    shot = tmp_path / "shot.blend"
    p = subprocess.run(["blender", "-b", "--factory-startup", "--python-exit-code", "1", "--python-expr",
                        LINK_SCENE % (str(library), str(shot))], capture_output=True, text=True, timeout=300)
    assert p.returncode == 0 and shot.is_file(), p.stdout[-2000:] + p.stderr[-2000:]
    out, fresh = tmp_path / "out", tmp_path / "fresh"
    render_panel(shot, out, "--method", "fxaa", "--no-panel")
    panel_blend(library, "for o in bpy.data.objects:\n    o.location.x += 0.5 * (o.type != 'CAMERA')")
    p = render_panel(shot, out, "--method", "fxaa", "--no-panel", "--resume")
    assert "frame 1 was made with other settings (scene_key " in p.stdout, p.stdout[-3000:]
    render_panel(shot, fresh, "--method", "fxaa", "--no-panel")
    assert frame_mse(fresh / "filtered" / "frame_0002.exr", out / "filtered" / "frame_0002.exr", tmp_path) == 0


SKY_TEXTURE = """
w = bpy.context.scene.world
w.use_nodes = True
sky = w.node_tree.nodes.new("ShaderNodeTexEnvironment")
sky.image = bpy.data.images.load(%r)
w.node_tree.links.new(sky.outputs["Color"], w.node_tree.nodes["Background"].inputs["Color"])
"""


@needs_blender
def test_a_resume_sees_a_texture_edited_since(tmp_path):
    """A shot whose sky is an image file: a resume with nothing changed keeps its frames, and after the
    image was edited it makes them again, as for an edit of the .blend; they kept the old sky, since
    only the .blend and its libraries were hashed."""
    texture = tmp_path / "tex" / "sky.png"
    texture.parent.mkdir()
    subprocess.run(["oiiotool", "--pattern", "constant:color=0.8,0.1,0.1", "8x8", "3", "-o", str(texture)], check=True)
    shot = panel_blend(tmp_path / "shot.blend", SKY_TEXTURE % str(texture))
    out, fresh = tmp_path / "out", tmp_path / "fresh"
    render_panel(shot, out, "--method", "fxaa", "--no-panel")
    p = render_panel(shot, out, "--method", "fxaa", "--no-panel", "--resume")
    assert "nothing to do" in p.stdout, p.stdout[-3000:]
    subprocess.run(["oiiotool", "--pattern", "constant:color=0.1,0.1,0.8", "8x8", "3", "-o", str(texture)], check=True)
    p = render_panel(shot, out, "--method", "fxaa", "--no-panel", "--resume")
    assert "frame 1 was made with other settings (scene_key " in p.stdout, p.stdout[-3000:]
    render_panel(shot, fresh, "--method", "fxaa", "--no-panel")
    assert frame_mse(fresh / "filtered" / "frame_0002.exr", out / "filtered" / "frame_0002.exr", tmp_path) == 0


@needs_blender
def test_eval_refuses_renders_of_a_linked_library_edited_since(tmp_path):
    """crisp eval reuses the renders it finds in its folder; it checked the opened .blend before Blender
    starts, not the library it links: after the library was edited, a second run measured the old
    renders as the new scene's. It stops (exit 2) naming the edit, and leaves the renders as they were."""
    library = panel_blend(tmp_path / "set.blend", "")
    shot = tmp_path / "shot.blend"
    p = subprocess.run(["blender", "-b", "--factory-startup", "--python-exit-code", "1", "--python-expr",
                        LINK_SCENE % (str(library), str(shot))], capture_output=True, text=True, timeout=300)
    assert p.returncode == 0 and shot.is_file(), p.stdout[-2000:] + p.stderr[-2000:]
    out = tmp_path / "eval"
    eval_panel(shot, out, "--methods", "none", "--no-panel")
    eval_panel(shot, out, "--methods", "none", "--no-panel")  # unchanged: runs again on its renders
    frame = out / "renders" / "eevee_1" / "frame_0001.exr"
    before = frame.read_bytes()
    panel_blend(library, "for o in bpy.data.objects:\n    o.location.x += 0.5 * (o.type != 'CAMERA')")
    p = eval_panel(shot, out, "--methods", "none", "--no-panel", ok=False)
    assert p.returncode == 2, p.stdout[-3000:] + p.stderr[-3000:]
    assert "holds renders made when the scene's linked libraries, images or other files were others" in p.stderr, \
        p.stderr[-3000:]
    assert frame.read_bytes() == before


@needs_blender
def test_a_set_the_panel_completes_is_not_refused_before_blender(tmp_path):
    """--method with a --set that the library's defaults refuse (feedbackMin 0.9 above the default
    feedbackMax 0.85) but the panel's feedbackMax 0.95 completes: the run takes both, so crisp does not
    refuse it before Blender starts; a --set the panel's values refuse is still stopped (exit 1, as the
    refusal before Blender starts exits)."""
    blend = panel_blend(tmp_path / "fmax.blend", 's.method = "taa"; s.taa.feedbackMax = 0.95')
    render_panel(blend, tmp_path / "ok", "--method", "taa", "--set", "feedbackMin=0.9", "--plan")
    assert run_record(tmp_path / "ok")["params"] == {"feedbackMax": "0.95", "feedbackMin": "0.9"}
    p = render_panel(blend, tmp_path / "bad", "--method", "taa", "--set", "feedbackMin=0.97", "--plan", ok=False)
    assert p.returncode == 1 and "feedbackMin" in p.stderr and "Crisp panel" in p.stderr, p.stderr[-2000:]
    # rsaa's camera given on the command line for the panel's rsaa: a usage error (2), as crisp says
    # before Blender starts when --method names rsaa.
    rsaa = panel_blend(tmp_path / "rsaa.blend", 's.method = "rsaa"')
    for extra in ((), ("--method", "rsaa")):
        p = render_panel(rsaa, tmp_path / "cam", "--set", "view01=0.5", "--plan", *extra, ok=False)
        assert p.returncode == 2 and "--set view01: rsaa takes its camera from each frame's sidecar" in p.stderr, \
            (extra, p.stderr[-2000:])
    # --no-panel: the library's defaults complete it, and crisp refuses it before Blender starts.
    p = render_panel(blend, tmp_path / "np", "--no-panel", "--method", "taa", "--set", "feedbackMin=0.9", "--plan",
                     ok=False)
    assert p.returncode == 1 and "must not exceed 'feedbackMax'" in p.stderr, p.stderr[-2000:]


# crisp eval and the scene's Crisp panel: the panel's setting is measured as a row of its own beside the
# library's defaults, with the panel's jitter (addon/crisp/batch_eval.py --read-panel, cli/cmd_eval.cpp).
def eval_panel(blend, out, *args, ok=True):
    p = subprocess.run([str(CRISP), "eval", "--scene", str(blend), "--resolution", "32x18", "--frames", "1-2",
                        "--reference-samples", "4", "--curve", "1", "-o", str(out), *map(str, args)],
                       capture_output=True, text=True, timeout=600)
    if ok:
        assert p.returncode == 0, p.stdout[-3000:] + p.stderr[-3000:]
    return p


def eval_results(out):
    """(the rows' names, the panel's row names, the scene's record) of out/results.json."""
    scene = json.loads((out / "results.json").read_text())["scenes"][0]
    return [m["name"] for m in scene["methods"]], [m["name"] for m in scene["methods"] if m["panel"]], scene


def input_jitter(out, scene, row):
    """The jitter distribution the sidecar of the row's last input frame records."""
    the_input = next(m["input"] for m in scene["methods"] if m["name"] == row)
    return json.loads((out / "renders" / the_input / "frame_0002.json").read_text())["jitter"]["distribution"]


@needs_blender
def test_eval_measures_the_panels_setting_as_a_row_of_its_own(panel_taa, tmp_path):
    """The panel's taa with sharpen 0.5 is measured as the row taa:sharpen=0.5, also when --methods leaves
    taa out, with the panel's uniform jitter; said in one line and recorded. A --methods entry of the
    same setting is its row, not a second one; --jitter replaces the panel's; --no-panel leaves the
    panel out. Before, eval measured the library's defaults with blackman-harris alone. One folder
    throughout: a resume takes each run's jitter and rows."""
    out = tmp_path / "out"
    p = eval_panel(panel_taa, out, "--methods", "fxaa")
    assert "eval: method taa, jitter uniform and 1 parameter (sharpen=0.5) from the scene's Crisp panel " \
           "(shot.blend); measured as 'taa:sharpen=0.5'" in p.stderr, p.stderr[-3000:]
    names, panel_rows, scene = eval_results(out)
    assert names == ["none", "fxaa", "taa:sharpen=0.5", "blender-smaa"] and panel_rows == ["taa:sharpen=0.5"]
    assert (scene["panel"]["method"], scene["panel"]["params"], scene["panel"]["row"]) == (
        "taa", {"sharpen": "0.5"}, "taa:sharpen=0.5"), scene["panel"]
    assert scene["jitter_distribution"] == "uniform" and input_jitter(out, scene, "taa:sharpen=0.5") == "uniform"
    assert (out / "methods" / "taa:sharpen=0.5" / "frame_0002.exr").is_file()

    p = eval_panel(panel_taa, out, "--methods", "taa,taa:sharpen=0.50", "--jitter", "blackman-harris")
    assert "eval: method taa and 1 parameter (sharpen=0.5) from the scene's Crisp panel (shot.blend); measured " \
           "as 'taa:sharpen=0.50'" in p.stderr, p.stderr[-3000:]
    names, panel_rows, scene = eval_results(out)
    assert names == ["none", "taa", "taa:sharpen=0.50", "blender-smaa"] and panel_rows == ["taa:sharpen=0.50"]
    assert scene["jitter_distribution"] == "blackman-harris" and not scene["panel"]["from_panel"]["jitter"]
    assert input_jitter(out, scene, "taa") == "blackman-harris"

    p = eval_panel(panel_taa, out, "--methods", "taa", "--no-panel")
    assert "Crisp panel" not in p.stderr, p.stderr[-3000:]
    names, panel_rows, scene = eval_results(out)
    assert names == ["none", "taa", "blender-smaa"] and not panel_rows and scene["panel"] is None
    assert scene["jitter_distribution"] == "blackman-harris"


@needs_blender
def test_eval_of_an_untouched_panel_adds_nothing(tmp_path):
    """A panel never touched sets nothing: no row, no line, no record; a panel that changed only fxaa's
    parameters (its method left at fxaa, as crisp render then runs) adds fxaa's setting."""
    out = tmp_path / "out"
    p = eval_panel(panel_blend(tmp_path / "plain.blend", ""), out, "--methods", "fxaa")
    assert "Crisp panel" not in p.stderr, p.stderr[-3000:]
    names, panel_rows, scene = eval_results(out)
    assert names == ["none", "fxaa", "blender-smaa"] and not panel_rows and scene["panel"] is None
    out = tmp_path / "fxaa"
    p = eval_panel(panel_blend(tmp_path / "fxaa_only.blend", "s.fxaa.subpix = 0.5"), out, "--methods", "none")
    assert "eval: 1 parameter (subpix=0.5) from the scene's Crisp panel (fxaa_only.blend); measured as " \
           "'fxaa:subpix=0.5'" in p.stderr, p.stderr[-3000:]
    assert eval_results(out)[:2] == (["none", "fxaa:subpix=0.5", "blender-smaa"], ["fxaa:subpix=0.5"])


@needs_blender
def test_eval_stops_before_rendering_at_a_panel_value_the_library_refuses(tmp_path):
    """taa's feedbackMin above its feedbackMax in the panel: eval exits 1 (as crisp render) naming the
    parameter and the panel, before anything renders or the output folder is made."""
    blend = panel_blend(tmp_path / "bad.blend", 's.method = "taa"; s.taa.feedbackMin = 0.95')
    out = tmp_path / "out"
    p = eval_panel(blend, out, "--methods", "fxaa", ok=False)
    assert p.returncode == 1, p.stderr[-3000:]
    assert "taa's parameters from the scene's Crisp panel (bad.blend: feedbackMin=0.95) are refused" in p.stderr \
           and "feedbackMax" in p.stderr and "--no-panel" in p.stderr, p.stderr[-3000:]
    assert not out.exists()


@needs_blender
def test_render_of_a_file_with_several_scenes_says_which_it_renders(tmp_path):
    """crisp render renders the .blend's active scene, as Blender opens it: with other scenes in the file it
    names the one it renders and the others, so an artist who meant another learns it from the first line."""
    blend = panel_blend(tmp_path / "two.blend", 'o = bpy.data.scenes.new("Other Shot"); '
                        'o.collection.objects.link(bpy.context.scene.camera); o.camera = bpy.context.scene.camera; '
                        's.method = "none"')
    p = render_panel(blend, tmp_path / "out", "--plan")
    scene = run_record(tmp_path / "out")["scene"]
    assert scene != "Other Shot"
    assert "crisp: scene '%s', the file's active scene (others: 'Other Shot';" % scene in p.stdout, p.stdout[-2000:]
    one = panel_blend(tmp_path / "one.blend", 's.method = "none"')
    assert "the file's active scene" not in render_panel(one, tmp_path / "one", "--plan").stdout
    # --scene-name renders another (Blender's -S), or refuses a name the file lacks, naming its scenes.
    p = render_panel(blend, tmp_path / "other", "--plan", "--scene-name", "Other Shot")
    assert run_record(tmp_path / "other")["scene"] == "Other Shot"
    assert "the file's active scene" not in p.stdout
    p = render_panel(blend, tmp_path / "nope", "--plan", "--scene-name", "Nope", ok=False)
    assert p.returncode == 2 and "no scene 'Nope' in" in p.stderr and "'Other Shot'" in p.stderr, p.stderr[-2000:]
    assert not (tmp_path / "nope").exists()
    p = subprocess.run([str(CRISP), "eval", "--scene", str(blend), "--scene-name", "Nope", "-o", str(tmp_path / "ev")],
                       capture_output=True, text=True, timeout=120)  # eval checks it before rendering
    assert p.returncode == 2 and "no scene 'Nope' in" in p.stdout + p.stderr, p.stdout[-2000:] + p.stderr[-2000:]
    p = subprocess.run([str(CRISP), "render", "--scene", "still_life", "--scene-name", "Scene", "--plan", "-o",
                        str(tmp_path / "bundled")], capture_output=True, text=True, timeout=60)
    assert p.returncode == 2 and "--scene-name picks a scene of a .blend file" in p.stderr, p.stderr


@needs_blender
def test_eval_warms_each_pass_configuration_up_before_timing_it(tmp_path):
    """The first render with another set of passes (taa-improved's depth, IDs and albedo; rsaa's geometry)
    took ~1.3 s against ~0.05 s after (EEVEE compiling for it), and a 2-frame run reported that as the
    method's render time (taa-improved at 675 ms a frame). Each input set to render is warmed up, untimed,
    first; a run with nothing to render warms nothing up. (160x90: at 64x36 the first frame's extra cost is
    ~0.1 s, too little to tell from the noise.)"""
    out = tmp_path / "out"
    args = ["eval", "--scene", "still_life", "--frames", "1-2", "--methods", "taa-improved,rsaa", "--resolution",
            "160x90", "--reference-samples", "2", "--curve", "1", "--quiet", "-o", out]
    run(*args)
    sets = [m["input"] for m in eval_results(out)[2]["methods"] if m["name"] in ("taa-improved", "rsaa")]
    assert len(set(sets)) == 2 and "eevee_1" not in sets, sets
    for name in sets:
        times = json.loads((out / "renders" / name / "times.json").read_text())
        assert times["0001"] < times["0002"] + 0.4, (name, times)  # was 0.8-1.4 s against 0.05 s
        assert (out / "renders" / "warmup" / name).is_dir(), name
    shutil.rmtree(out / "renders" / "warmup")
    run(*args)
    assert not (out / "renders" / "warmup").exists(), "warmed up with nothing to render"


TWO_SCENES = ('o = bpy.data.scenes.new("Other Shot"); o.collection.objects.link(bpy.context.scene.camera); '
              'o.camera = bpy.context.scene.camera')


@needs_blender
def test_eval_of_a_file_with_several_scenes_says_which_it_measures(tmp_path):
    """crisp eval of a .blend holding several scenes said nothing of which it took (crisp render names it and
    the others, and the README says eval does): it says so in the same line, and the report's heading names
    the scene beside the file's name."""
    blend = panel_blend(tmp_path / "two.blend", TWO_SCENES)
    out = tmp_path / "out"
    p = eval_panel(blend, out, "--methods", "none", "--no-panel")
    scene = eval_results(out)[2]
    assert scene["blender_scene"] != "Other Shot" and scene["name"] == "two"
    said = "crisp: scene '%s', the file's active scene (others: 'Other Shot'; --scene-name NAME renders another)\n"
    assert said % scene["blender_scene"] in p.stderr, p.stderr[-3000:]  # a line of its own
    if shutil.which("chromium"):
        dom = subprocess.run(["chromium", "--headless", "--no-sandbox", "--disable-gpu", "--user-data-dir=" +
                              str(tmp_path / "profile"), "--virtual-time-budget=3000", "--dump-dom",
                              "file://" + str(out / "report.html")], capture_output=True, text=True, timeout=120)
        assert "Scene <b>two</b> (its scene <b>%s</b>)" % scene["blender_scene"] in dom.stdout, dom.stdout[:3000]


@needs_blender
def test_eval_keys_a_folder_to_its_scene_however_it_is_chosen(tmp_path):
    """The folder's key held a --scene-name only when given: naming the active scene after a run without the
    option was refused as other settings (scene_contents). The same scene is accepted however chosen;
    another is refused naming --scene-name; settings written by the builds before are still read."""
    blend = panel_blend(tmp_path / "two.blend", TWO_SCENES)
    out = tmp_path / "out"
    eval_panel(blend, out, "--methods", "none", "--no-panel")
    active = eval_results(out)[2]["blender_scene"]
    eval_panel(blend, out, "--methods", "none", "--no-panel", "--scene-name", active)
    p = eval_panel(blend, out, "--methods", "none", "--no-panel", "--scene-name", "Other Shot", ok=False)
    assert p.returncode == 2, p.stderr[-3000:]
    assert "holds renders of the scene '%s', not of 'Other Shot' (--scene-name); give --scene-name '%s'" % (
        active, active) in p.stderr, p.stderr[-3000:]
    # The key of the builds before, which hashed a --scene-name given after the file's bytes (FNV-1a 64).
    key = 0xcbf29ce484222325
    for byte in blend.read_bytes() + ("\nscene-name\n" + active).encode():
        key = ((key ^ byte) * 0x100000001b3) & 0xffffffffffffffff
    settings = json.loads((out / "eval_settings.json").read_text())
    (out / "eval_settings.json").write_text(json.dumps(dict(settings, scene_contents="fnv1a64:%016x" % key)))
    eval_panel(blend, out, "--methods", "none", "--no-panel", "--scene-name", active)
    assert json.loads((out / "eval_settings.json").read_text()) == settings
    eval_panel(blend, out, "--methods", "none", "--no-panel")


@needs_blender
def test_eval_measures_two_spellings_of_one_setting_once(tmp_path):
    """--methods taa:sharpen=0.5,taa:sharpen=.5 measured two rows of the same figures; the code knew them
    equal (checkedMethodSpec) and used it only for the panel's row. One row, the first spelling, said so."""
    out = tmp_path / "out"
    p = run("eval", "--scene", "still_life", "--frames", "1-1", "--methods", "taa:sharpen=0.5,fxaa,taa:sharpen=.5",
            "--resolution", "48x27", "--reference-samples", "2", "--curve", "1", "--quiet", "-o", out)
    assert eval_results(out)[0] == ["none", "taa:sharpen=0.5", "fxaa", "blender-smaa"]
    assert "crisp eval: --methods 'taa:sharpen=.5' is the setting of 'taa:sharpen=0.5': measured once, as " \
           "'taa:sharpen=0.5'" in p.stderr, p.stderr
    assert not (out / "methods" / "taa:sharpen=.5").exists()
