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

from crisp_test_util import CRISP, LIBRARY, SOURCE, Lib, display, needs_cli_and_blender, psnr, run_eval

CHROMIUM = shutil.which("chromium") or shutil.which("chromium-browser")
ARGS = ["--scene", "still_life", "--resolution", "96x54", "--frames", "1-3", "--reference-samples", "8",
        "--curve", "1,2,4", "--warmup", "1"]

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


def test_means_leave_out_the_warmup_and_the_csv_agrees(run):
    """--warmup 1: the error means are over frames 2-3, the times medians over all three; results.csv
    holds the same figures as results.json, rsaa's geometry renders included in its time per frame;
    the reference's time is the median over the run's frames."""
    out, _, _ = run
    scene = json.load(open(os.path.join(out, "results.json")))["scenes"][0]
    assert scene["means_over_frames"] == [2, 3]
    header, *rows = [line.split(",") for line in open(os.path.join(out, "results.csv")).read().splitlines()]
    csv = {(r[header.index("name")], r[header.index("frame")]): r for r in rows}
    for m in scene["methods"] + scene["eevee_curve"]:
        if m["error"]:
            continue
        f = m["frames"]
        assert m["mean"]["psnr"] == pytest.approx(np.mean([f[1]["psnr"], f[2]["psnr"]]), rel=1e-12), m["name"]
        assert m["mean"]["psnr"] != pytest.approx(np.mean([x["psnr"] for x in f]), rel=1e-9) or \
            f[0]["psnr"] == pytest.approx(f[1]["psnr"]), m["name"]  # frame 1 left out
        assert m["mean"]["render_s"] == pytest.approx(np.median([x["render_s"] for x in f]), rel=1e-12)
        for key in ("psnr", "time_s", "geometry_render_s"):
            for frame, figures in [("mean", m["mean"])] + [(str(x["frame"]), x) for x in f]:
                cell, value = csv[(m["name"], frame)][header.index(key)], figures.get(key)
                if value is None:
                    assert cell == "", (m["name"], frame, key, cell)
                else:
                    assert float(cell) == pytest.approx(value, rel=1e-5), (m["name"], frame, key, cell, value)
    rsaa = next(m for m in scene["methods"] if m["name"] == "rsaa")
    assert all(x["geometry_render_s"] > 0 and x["time_s"] > x["render_s"] + x["geometry_render_s"] * 0.999
               for x in rsaa["frames"])
    times = json.load(open(os.path.join(out, "renders", "reference_8", "times.json")))
    assert scene["reference"]["time_s"] == pytest.approx(np.median([times["%04d" % f] for f in (1, 2, 3)]))


def test_each_method_reads_a_render_set_of_its_own_passes(run):
    """A method's time per frame is the 1-sample render of the passes it reads: taa (colour alone on
    this still scene) is not charged for the IDs and albedo taa-improved reads."""
    out, _, _ = run
    renders = json.load(open(os.path.join(out, "renders", "scene.json")))
    results = {m["name"]: m for m in json.load(open(os.path.join(out, "results.json")))["scenes"][0]["methods"]}
    assert renders["inputs"]["taa"] == renders["inputs"]["phlm"] == "jittered"
    assert renders["sets"]["jittered"]["passes"] == ["color"]
    improved = renders["inputs"]["taa-improved"]
    assert improved != "jittered" and renders["sets"][improved]["passes"][0] == "color"
    assert len(renders["sets"][improved]["passes"]) > 1
    for name in ("taa", "taa-improved", "phlm", "rsaa", "fxaa"):
        assert results[name]["input"] == renders["inputs"][name], name


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


@pytest.mark.skipif(not os.path.isfile(LIBRARY), reason="libcrisp not built")
def test_crop_scores_recomputed_from_the_files(run):
    """Each crop's score is the 1-sample frames' squared error there, per pixel and per frame (it
    was once summed over frames, so it grew with the run's length)."""
    out, _, _ = run
    lib = Lib()
    scene = json.load(open(os.path.join(out, "results.json")))["scenes"][0]
    none = scene["methods"][0]
    pairs = [(display(lib.color(os.path.join(out, r))), display(lib.color(os.path.join(out, f["file"]))))
             for r, f in zip(scene["reference"]["files"], none["frames"])]
    assert scene["crops"] and len(pairs) == 3
    for c in scene["crops"]:
        window = (slice(c["y"], c["y"] + c["size"]), slice(c["x"], c["x"] + c["size"]))
        mine = np.mean([np.mean((ref[window] - test[window]) ** 2) for ref, test in pairs])
        assert abs(mine - c["score"]) <= 1e-4 * mine, (c, mine)


def test_last_runs_pictures_are_removed_and_nothing_else(run):
    """A rerun removes the pictures the last results.json lists (a shorter run must not leave the
    last run's crops beside its own), and only those: a listed path that leads out of images/ (by
    '..', or through a symbolic link) is left alone, as is a file of the user's in images/."""
    out, _, _ = run
    copy = tempfile.mkdtemp(prefix="crisp_eval_pictures_")
    outside = tempfile.mkdtemp(prefix="crisp_eval_outside_")
    try:
        subprocess.run(["cp", "-a", out + "/.", copy], check=True)
        keep = [os.path.join(outside, "a.png"), os.path.join(copy, "b.png"), os.path.join(copy, "images", "mine.png")]
        for k in keep:
            open(k, "wb").close()
        os.symlink(outside, os.path.join(copy, "images", "link"))
        results = json.load(open(os.path.join(copy, "results.json")))
        crop = results["scenes"][0]["crops"][0]
        stale = os.path.join(copy, "images", "crops", "c0", "none", "frame_0009.png")  # no frame 9 in this run
        open(stale, "wb").close()
        crop["files"]["none"] += ["images/link/a.png", "images/../b.png", os.path.relpath(stale, copy)]
        json.dump(results, open(os.path.join(copy, "results.json"), "w"))
        p = subprocess.run([CRISP, "eval"] + ARGS + ["-o", copy], stdout=subprocess.PIPE, stderr=subprocess.PIPE,
                           timeout=300)
        assert p.returncode == 0, p.stderr.decode()[-2000:]
        assert not os.path.exists(stale), "the last run's crop of a frame this run does not have"
        for k in keep:
            assert os.path.exists(k), k
        assert os.path.isfile(os.path.join(copy, "images", "crops", "c0", "none", "frame_0001.png"))
    finally:
        shutil.rmtree(copy, ignore_errors=True)
        shutil.rmtree(outside, ignore_errors=True)


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
