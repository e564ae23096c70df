# SPDX-License-Identifier: Apache-2.0
"""`crisp eval` of a saved .blend whose folder and file name hold what is special in HTML, CSV and the
shell (space, &, <, ', a comma, "<!--<script>"), over 3 frames with --warmup 2, then:
  * results.csv parses (RFC 4180) with every row as long as its header, the scene column the name;
  * the command line in results.json splits (shlex) back into the arguments given;
  * the maps and full images are of a frame the error means cover, not of the warm-up;
  * report.html opens in headless Chromium with its self-check "OK" and the scene name shown as text;
  * with ten methods (blender-smaa the tenth), no method's colour is the EEVEE curve's orange.
Needs Blender, the built CLI (CRISP_BUILD_DIR) and Debian's chromium."""

import csv
import html
import json
import os
import re
import shlex
import shutil
import subprocess
import tempfile
import urllib.parse

import pytest

from crisp_test_util import CRISP, SOURCE, needs_cli_and_blender

CHROMIUM = shutil.which("chromium") or shutil.which("chromium-browser")
NAME = "it's <!--<script> & a, b"
# Nine library entries on the plain 1-sample frames, blender-smaa the tenth.
METHODS = ["none", "fxaa", "repair"] + ["fxaa:subpix=%s" % v for v in ("0", "0.25", "0.5")] + \
    ["fxaa:edgeThreshold=%s" % v for v in ("0.05", "0.1", "0.3")]

pytestmark = needs_cli_and_blender()


@pytest.fixture(scope="module")
def run():
    root = tempfile.mkdtemp(prefix="crisp_eval_names_")
    folder = os.path.join(root, "a & <b> dir")
    os.makedirs(folder)
    blend = os.path.join(folder, NAME + ".blend")
    save = ("import runpy, sys, bpy\n"
            "sys.path.insert(0, %r)\n"
            "runpy.run_path(%r, run_name='__main__')\n"
            "bpy.ops.wm.save_as_mainfile(filepath=%r)\n"
            % (os.path.join(SOURCE, "test_scenes"), os.path.join(SOURCE, "test_scenes", "still_life.py"), blend))
    p = subprocess.run(["blender", "-b", "--factory-startup", "--python-exit-code", "1", "--python-expr", save],
                       stdout=subprocess.PIPE, stderr=subprocess.PIPE, timeout=300)
    assert p.returncode == 0 and os.path.isfile(blend), p.stderr.decode()[-3000:]
    out = os.path.join(root, "out & <o>")
    argv = [CRISP, "eval", "--scene", blend, "--resolution", "48x27", "--frames", "1-3", "--warmup", "2",
            "--reference-samples", "2", "--curve", "1,2", "--methods", ",".join(METHODS), "-o", out]
    p = subprocess.run(argv, stdout=subprocess.PIPE, stderr=subprocess.PIPE, timeout=600)
    assert p.returncode == 0, p.stderr.decode()[-3000:]
    with open(os.path.join(out, "results.json")) as f:
        results = json.load(f)
    yield out, argv, results
    shutil.rmtree(root, ignore_errors=True)


def test_csv_rows_parse_and_name_the_scene(run):
    out, _, results = run
    assert results["scenes"][0]["name"] == NAME
    with open(os.path.join(out, "results.csv"), newline="") as f:
        rows = list(csv.reader(f))
    header = rows[0]
    assert len(rows) > 1
    for row in rows[1:]:
        assert len(row) == len(header), row
        assert row[header.index("scene")] == NAME, row


def test_command_line_splits_back_into_its_arguments(run):
    _, argv, results = run
    assert shlex.split(results["command"]) == argv, results["command"]


def test_maps_are_of_a_measured_frame(run):
    _, _, results = run
    scene = results["scenes"][0]
    first, last = scene["means_over_frames"]
    assert (first, last) == (3, 3)
    assert first <= scene["map_frame"] <= last, scene["map_frame"]


@pytest.fixture(scope="module")
def page(run):
    """report.html as headless Chromium has it after its scripts ran (the DOM)."""
    if CHROMIUM is None:
        pytest.skip("Debian chromium not installed")
    out, _, _ = run
    profile = tempfile.mkdtemp(prefix="crisp_chromium_")
    flags = [CHROMIUM, "--headless", "--no-sandbox", "--disable-gpu", "--disable-quic", "--no-first-run",
             "--disable-background-networking", "--disable-component-update", "--disable-sync",
             "--user-data-dir=" + profile, "--enable-logging=stderr", "--v=0", "--virtual-time-budget=3000"]
    url = "file://" + urllib.parse.quote(os.path.join(out, "report.html"))
    try:
        dom = subprocess.run(flags + ["--dump-dom", url], stdout=subprocess.PIPE, stderr=subprocess.PIPE,
                             timeout=120)
        yield dom.stdout.decode()
    finally:
        shutil.rmtree(profile, ignore_errors=True)


def test_report_opens_with_the_name_as_text(page):
    title = re.search(r"<title>([^<]*)</title>", page).group(1)
    assert title == "crisp eval report: OK - " + html.escape(NAME, quote=False), title
    assert "Scene <b>%s</b>" % html.escape(NAME, quote=False) in page
    assert page.count("<svg") >= 4


def test_no_method_takes_the_eevee_curve_colour(page):
    # The legend of the first chart (PSNR against time): a swatch and a name per series.
    chart = page[:page.index("</svg>")]
    legend = re.findall(r'<rect x="[^"]*" y="[^"]*" width="10" height="10" fill="([^"]*)"></rect>'
                        r'<text x="[^"]*" y="[^"]*">([^<]*)</text>', chart)
    names = [name for _, name in legend]
    assert names[:2] == ["EEVEE curve", "Pareto front"] and "blender-smaa" in names, names
    eevee = legend[0][0]
    assert [name for colour, name in legend[2:] if colour == eevee] == [], legend
