# SPDX-License-Identifier: Apache-2.0
"""End to end: `crisp eval` on a tiny still_life (96x54, 3 frames, reference 8 samples, curve 1,2,4) in
real Blender, then:
  * results.json has every method, blender-smaa and the EEVEE curve, in the issue's shape;
  * each PSNR in it is recomputed here with numpy from the EXRs it points to (read through libcrisp's
    C API with ctypes), display-encoded as metrics.h says;
  * a second run resumes: nothing is re-rendered and the figures stay the same; a method whose frames
    another build made is computed again;
  * report.html opens in headless Chromium with its self-check "OK" in the title, no console error,
    and a screenshot that is not blank.
Needs Blender, the built CLI and library (CRISP_BUILD_DIR) and Debian's chromium."""

import json
import os
import re
import shutil
import subprocess
import tempfile

import numpy as np
import pytest

from crisp_test_util import CRISP, LIBRARY, SOURCE, Lib, needs_cli_and_blender, psnr, run_eval

CHROMIUM = shutil.which("chromium") or shutil.which("chromium-browser")
ARGS = ["--scene", "still_life", "--resolution", "96x54", "--frames", "1-3", "--reference-samples", "8",
        "--curve", "1,2,4"]

pytestmark = needs_cli_and_blender()


@pytest.fixture(scope="module")
def run():
    out, stdout, stderr = run_eval(ARGS, "crisp_eval_", timeout=600)
    yield out, stdout, stderr
    shutil.rmtree(out, ignore_errors=True)


def test_results_shape_and_every_entry(run):
    out, stdout, _ = run
    assert "report: " + os.path.join(out, "report.html") in stdout
    r = json.load(open(os.path.join(out, "results.json")))
    scene = r["scenes"][0]
    assert scene["name"] == "still_life" and scene["resolution"] == [96, 54] and scene["frames"] == [1, 3]
    names = [m["name"] for m in scene["methods"]]
    assert names[0] == "none" and "blender-smaa" in names
    listed = subprocess.run([CRISP, "help"], stdout=subprocess.PIPE).stdout.decode()
    library = re.search(r"Methods: (.*)", listed).group(1).replace(",", " ").split()
    assert set(library) <= set(names), "every library method is evaluated (or reported failed)"
    for m in scene["methods"]:
        assert {"psnr", "ssim", "temporal_error", "time_s"} <= set(m["mean"])
        assert len(m["frames"]) == 3 and [f["frame"] for f in m["frames"]] == [1, 2, 3]
        if m["error"]:
            continue  # a failed method stays in the results with its reason
        assert 5 < m["mean"]["psnr"] < 100 and 0 < m["mean"]["ssim"] <= 1
        assert m["mean"]["time_s"] > 0 and m["frames"][0]["temporal_error"] is None
        assert m["frames"][1]["temporal_error"] >= 0
        # Where it flickers: the per-pixel temporal error, mean over frames, beside the frame's maps.
        assert os.path.isfile(os.path.join(out, "images", "maps", m["name"] + "_temporal.png")), m["name"]
    assert [c["samples"] for c in scene["eevee_curve"]] == [1, 2, 4]
    curve = scene["eevee_curve"]
    assert all(c["time_s"] > 0 for c in curve)
    assert curve[0]["psnr"] < curve[-1]["psnr"], "more EEVEE samples must get closer to the reference"
    none = scene["methods"][0]
    # The 'none' method copies the 1-sample frame: same figures as the curve's 1-sample point.
    assert abs(none["mean"]["psnr"] - curve[0]["psnr"]) < 1e-9
    assert abs(none["equivalent_eevee_samples"] - 1.0) < 1e-6
    csv = open(os.path.join(out, "results.csv")).read().splitlines()
    assert csv[0].startswith("scene,kind,name,frame,psnr") and len(csv) == 1 + 4 * (len(names) + len(curve))


@pytest.mark.skipif(not os.path.isfile(LIBRARY), reason="libcrisp not built")
def test_psnr_recomputed_from_the_files(run):
    out, _, _ = run
    lib = Lib()
    scene = json.load(open(os.path.join(out, "results.json")))["scenes"][0]
    refs = [lib.color(os.path.join(out, f)) for f in scene["reference"]["files"]]
    checked = 0
    for entry in scene["methods"] + scene["eevee_curve"]:
        for i, f in enumerate(entry["frames"]):
            if f["psnr"] is None:
                continue
            mine = psnr(refs[i], lib.color(os.path.join(out, f["file"])))
            assert abs(mine - f["psnr"]) < 1e-3, (entry["name"], f["frame"], mine, f["psnr"])
            checked += 1
    assert checked >= 3 * 6


def test_resume_redoes_nothing(run):
    out, _, _ = run
    before = {p: os.path.getmtime(os.path.join(dp, p)) for dp, _, fs in os.walk(os.path.join(out, "renders"))
              for p in fs if p.endswith(".exr")}
    first = json.load(open(os.path.join(out, "results.json")))["scenes"][0]
    p = subprocess.run([CRISP, "eval"] + ARGS + ["-o", out], stdout=subprocess.PIPE, stderr=subprocess.PIPE,
                       timeout=300)
    assert p.returncode == 0, p.stderr.decode()[-2000:]
    assert "done before" in p.stderr.decode()
    after = {p: os.path.getmtime(os.path.join(dp, p)) for dp, _, fs in os.walk(os.path.join(out, "renders"))
             for p in fs if p.endswith(".exr")}
    assert before == after, "no render was redone"
    second = json.load(open(os.path.join(out, "results.json")))["scenes"][0]
    for a, b in zip(first["methods"], second["methods"]):
        assert a["name"] == b["name"] and a["mean"]["psnr"] == b["mean"]["psnr"]


def test_frames_of_another_build_are_computed_again(run):
    """A method folder records the build that made its frames (methods/<name>/build.txt); frames of
    another build are computed again, the others are kept."""
    out, _, _ = run
    taa, none = (os.path.join(out, "methods", m) for m in ("taa", "none"))
    stamp = open(os.path.join(taa, "build.txt")).read()
    assert stamp.startswith("crisp ") and "fnv1a64:" in stamp
    frames = [os.path.join(d, "frame_0003.exr") for d in (taa, none)]
    before = [os.stat(f).st_mtime_ns for f in frames]
    with open(os.path.join(taa, "build.txt"), "w") as f:
        f.write("crisp 0.0.0 executable fnv1a64:0000000000000000\n")
    p = subprocess.run([CRISP, "eval"] + ARGS + ["-o", out], stdout=subprocess.PIPE, stderr=subprocess.PIPE,
                       timeout=300)
    assert p.returncode == 0, p.stderr.decode()[-2000:]
    err = p.stderr.decode()
    assert "methods/taa was made by another crisp build" in err and "methods/none was made" not in err
    after = [os.stat(f).st_mtime_ns for f in frames]
    assert after[0] > before[0] and after[1] == before[1]
    assert open(os.path.join(taa, "build.txt")).read() == stamp


def test_temporal_frames_of_a_run_from_another_frame_are_made_again(run):
    """A temporal method's frame depends on where its history started: resumed over frames 2-3, the taa
    frames of the run over 1-3 are made again (and equal those of a fresh run over 2-3); spatial
    methods' frames are kept."""
    out, _, _ = run
    later = list(ARGS)
    later[later.index("1-3")] = "2-3"
    copy = tempfile.mkdtemp(prefix="crisp_eval_later_")
    fresh = tempfile.mkdtemp(prefix="crisp_eval_fresh_")
    try:
        subprocess.run(["cp", "-a", out + "/.", copy], check=True)
        before = {m: os.stat(os.path.join(copy, "methods", m, "frame_0002.exr")).st_mtime_ns for m in ("taa", "fxaa")}
        p = subprocess.run([CRISP, "eval"] + later + ["-o", copy], stdout=subprocess.PIPE, stderr=subprocess.PIPE,
                           timeout=300)
        assert p.returncode == 0, p.stderr.decode()[-2000:]
        assert b"methods/taa: its history started at another frame" in p.stderr, p.stderr.decode()[-2000:]
        after = {m: os.stat(os.path.join(copy, "methods", m, "frame_0002.exr")).st_mtime_ns for m in ("taa", "fxaa")}
        assert after["taa"] != before["taa"] and after["fxaa"] == before["fxaa"]
        p = subprocess.run([CRISP, "eval"] + later + ["-o", fresh], stdout=subprocess.PIPE, stderr=subprocess.PIPE,
                           timeout=600)
        assert p.returncode == 0, p.stderr.decode()[-2000:]
        lib = Lib()
        for f in (2, 3):
            name = "frame_%04d.exr" % f
            a = lib.color(os.path.join(copy, "methods", "taa", name))
            assert np.array_equal(a, lib.color(os.path.join(fresh, "methods", "taa", name))), f
        assert not np.array_equal(lib.color(os.path.join(out, "methods", "taa", "frame_0002.exr")),
                                  lib.color(os.path.join(copy, "methods", "taa", "frame_0002.exr")))
    finally:
        shutil.rmtree(copy, ignore_errors=True)
        shutil.rmtree(fresh, ignore_errors=True)


def test_settings_of_another_run_are_refused(run):
    """A resumed run reuses the renders it finds, so a setting that changes them and is not checked frame
    by frame (the size, what the scene's script holds, EEVEE's pixel filter) must match the first run's,
    or nothing runs. (A changed --jitter renders the jittered set again: test_eval_warp.py.)"""
    out, _, _ = run
    smaller = list(ARGS)
    smaller[smaller.index("96x54")] = "64x36"
    settings = open(os.path.join(out, "eval_settings.json")).read()
    # The same bundled scene name, built by an edited script (CRISP_ADDON_DIR: the add-on and test
    # scenes of another tree).
    tree = tempfile.mkdtemp(prefix="crisp_edited_scene_")
    for d in ("addon", "test_scenes"):
        shutil.copytree(os.path.join(SOURCE, d), os.path.join(tree, d))
    with open(os.path.join(tree, "test_scenes", "still_life.py"), "a") as f:
        f.write("\n# edited\n")
    cases = ((smaller, {}, b'resolution "96x54" there, "64x36" here'),
             (ARGS, {"CRISP_EVAL_FILTER_SIZE": "0.5"}, b'filter_size "" there, "0.5" here'),
             (ARGS, {"CRISP_ADDON_DIR": os.path.join(tree, "addon")}, b"scene_contents \"fnv1a64:"))
    try:
        for args, env, message in cases:
            p = subprocess.run([CRISP, "eval"] + args + ["-o", out], stdout=subprocess.PIPE, stderr=subprocess.PIPE,
                               env=dict(os.environ, **env), timeout=60)
            assert p.returncode == 2 and b"holds renders made with other settings" in p.stderr, p.stderr.decode()[-500:]
            assert b"crisp help" not in p.stderr, "the message says what to do; no pointer to the help"
            assert message in p.stderr, p.stderr.decode()[-500:]
            assert b"rendering in Blender" not in p.stderr, "refused before Blender starts"
    finally:
        shutil.rmtree(tree, ignore_errors=True)
    assert open(os.path.join(out, "eval_settings.json")).read() == settings, "the first run's settings are kept"
    # A settings file of an older build (no scene contents, no filter size) is taken as it is.
    with open(os.path.join(out, "eval_settings.json"), "w") as f:
        json.dump({"resolution": "96x54", "scene": "still_life"}, f)
    p = subprocess.run([CRISP, "eval"] + ARGS + ["-o", out], stdout=subprocess.PIPE, stderr=subprocess.PIPE, timeout=300)
    assert p.returncode == 0, p.stderr.decode()[-2000:]
    assert json.load(open(os.path.join(out, "eval_settings.json"))) == json.loads(settings)


def test_method_variants_share_the_renders(run):
    """`--methods taa:KEY=VALUE:...` measures parameter settings side by side on the same renders; a bad
    spec or parameter is refused before Blender starts."""
    out, _, _ = run
    variant = "taa:feedbackMin=0.3:feedbackMax=0.4"
    before = {p: os.path.getmtime(os.path.join(dp, p)) for dp, _, fs in os.walk(os.path.join(out, "renders"))
              for p in fs if p.endswith(".exr")}
    p = subprocess.run([CRISP, "eval"] + ARGS + ["--methods", "taa," + variant, "-o", out], stdout=subprocess.PIPE,
                       stderr=subprocess.PIPE, timeout=300)
    assert p.returncode == 0, p.stderr.decode()[-2000:]
    after = {p: os.path.getmtime(os.path.join(dp, p)) for dp, _, fs in os.walk(os.path.join(out, "renders"))
             for p in fs if p.endswith(".exr")}
    assert before == after, "a variant reuses its method's renders"
    scene = json.load(open(os.path.join(out, "results.json")))["scenes"][0]
    entries = {m["name"]: m for m in scene["methods"]}
    assert {"none", "taa", variant} <= set(entries) and not entries[variant]["error"]
    assert entries[variant]["input"] == entries["taa"]["input"]
    lib = Lib()
    a = lib.color(os.path.join(out, "methods", "taa", "frame_0003.exr"))
    b = lib.color(os.path.join(out, "methods", variant, "frame_0003.exr"))
    assert np.abs(a - b).max() > 1e-4, "the variant's parameters reached the filter"
    for spec, message in (("taa:bogus=1", b"bogus"), ("taa:feedbackMin", b"expected KEY=VALUE"),
                          ("taa:feedbackMin=2", b"feedbackMin"), ("nosuch:x=1", b"unknown method 'nosuch'")):
        p = subprocess.run([CRISP, "eval"] + ARGS + ["--methods", spec, "-o", out], stdout=subprocess.PIPE,
                           stderr=subprocess.PIPE, timeout=60)
        assert p.returncode == 2 and message in p.stderr, (spec, p.stderr.decode()[-500:])
        assert b"rendering in Blender" not in p.stderr, "refused before Blender starts"


@pytest.mark.skipif(CHROMIUM is None, reason="Debian chromium not installed")
def test_report_opens_in_chromium(run):
    out, _, _ = run
    profile = tempfile.mkdtemp(prefix="crisp_chromium_")
    flags = [CHROMIUM, "--headless", "--no-sandbox", "--disable-gpu", "--disable-quic", "--no-first-run",
             "--disable-background-networking", "--disable-component-update", "--disable-sync",
             "--user-data-dir=" + profile, "--enable-logging=stderr", "--v=0", "--virtual-time-budget=3000"]
    url = "file://" + os.path.join(out, "report.html")
    try:
        dom = subprocess.run(flags + ["--dump-dom", url], stdout=subprocess.PIPE, stderr=subprocess.PIPE, timeout=120)
        html = dom.stdout.decode()
        title = re.search(r"<title>([^<]*)</title>", html).group(1)
        assert title.startswith("crisp eval report: OK"), title
        console = [l for l in dom.stderr.decode().splitlines() if "CONSOLE" in l]
        assert not [l for l in console if "error" in l.lower() or "Uncaught" in l], console
        assert html.count("<svg") >= 4 and "blender-smaa" in html and "EEVEE 4 spp" in html
        shot = os.path.join(profile, "shot.png")
        subprocess.run(flags + ["--screenshot=" + shot, "--window-size=1200,1600", url], stdout=subprocess.PIPE,
                       stderr=subprocess.PIPE, timeout=120)
        from skimage.io import imread
        img = imread(shot)
        assert img.shape[0] == 1600 and img.shape[1] == 1200
        assert img[..., :3].std() > 20, "screenshot is blank"
        # Charts drawn: the EEVEE curve's orange is on the page.
        orange = (np.abs(img[..., 0].astype(int) - 255) < 30) & (np.abs(img[..., 1].astype(int) - 127) < 30) & (img[..., 2] < 60)
        assert orange.sum() > 50
    finally:
        shutil.rmtree(profile, ignore_errors=True)
