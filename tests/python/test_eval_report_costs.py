# SPDX-License-Identifier: Apache-2.0
"""The report's line about EEVEE's own cost ("about X ms for a 1-sample frame and Y ms per further
sample", a line through the curve's times) on a tiny still_life eval, and again once its curve times
do not grow with the sample count (as a short run on a busy machine can measure them: the times edited
in renders/*/times.json, which a resumed eval keeps): the page then gives no cost, rather than a
negative one, and says why. Needs Blender, the built CLI (CRISP_BUILD_DIR) and Debian's chromium."""

import json
import os
import re
import shutil
import subprocess
import tempfile
import urllib.parse

import pytest

from crisp_test_util import CRISP, needs_cli_and_blender, run_eval

CHROMIUM = shutil.which("chromium") or shutil.which("chromium-browser")
ARGS = ["--scene", "still_life", "--resolution", "48x27", "--frames", "1-2", "--reference-samples", "4",
        "--curve", "1,2", "--methods", "none"]

pytestmark = needs_cli_and_blender() + [pytest.mark.skipif(CHROMIUM is None, reason="Debian chromium not installed")]


def subtitle(out):
    """The page's first paragraph as headless Chromium shows it."""
    profile = tempfile.mkdtemp(prefix="crisp_chromium_")
    flags = [CHROMIUM, "--headless", "--no-sandbox", "--disable-gpu", "--disable-quic", "--no-first-run",
             "--disable-background-networking", "--disable-component-update", "--disable-sync",
             "--user-data-dir=" + profile, "--virtual-time-budget=3000", "--dump-dom",
             "file://" + urllib.parse.quote(os.path.join(out, "report.html"))]
    try:
        page = subprocess.run(flags, stdout=subprocess.PIPE, stderr=subprocess.PIPE, timeout=120).stdout.decode()
    finally:
        shutil.rmtree(profile, ignore_errors=True)
    assert "crisp eval report: OK" in page
    return re.search(r'<p class="sub">(.*?)</p>', page, re.S).group(1)


def test_eevee_cost_per_sample_is_never_negative():
    out, _, _ = run_eval(ARGS, "crisp_eval_costs_", timeout=600)
    try:
        text = subtitle(out)
        if "per further sample" in text:  # measured here: a positive cost
            assert re.search(r"about \d[\d.]* ms for a 1-sample frame and \d[\d.]* ms per further sample", text), text
        # EEVEE 2 samples measured faster than 1 (a noisy short run): no cost per sample is given.
        for samples, seconds in ((1, 0.050), (2, 0.040)):
            path = os.path.join(out, "renders", "eevee_%d" % samples, "times.json")
            with open(path, "w") as f:
                json.dump({"0001": seconds, "0002": seconds}, f)
        p = subprocess.run([CRISP, "eval"] + ARGS + ["-o", out], stdout=subprocess.PIPE, stderr=subprocess.PIPE,
                           timeout=600)
        assert p.returncode == 0, p.stderr.decode()[-3000:]
        curve = json.load(open(os.path.join(out, "results.json")))["scenes"][0]["eevee_curve"]
        assert [c["time_s"] for c in curve] == [0.05, 0.04]
        text = subtitle(out)
        assert "per further sample" not in text and "do not grow with the sample count" in text, text
    finally:
        shutil.rmtree(out, ignore_errors=True)


def test_renders_of_the_same_work_are_timed_as_one():
    """taa reads a jittered colour-only render, the same work as EEVEE's 1-sample render (a camera shift
    apart), but timed apart: the machine's noise once put taa's time per frame below the unfiltered
    render's and pushed EEVEE 1 spp off the Pareto front. Both sets' times are now averaged per frame and
    given to every entry that reads either; a set of other passes keeps its own."""
    args = ARGS[:-1] + ["none,taa,taa-improved"]
    out, _, _ = run_eval(args, "crisp_eval_same_work_", timeout=900)
    try:
        renders = os.path.join(out, "renders")
        times = {"eevee_1": (0.050, 0.070), "jittered": (0.030, 0.010), "jittered-depth-id-albedo": (0.200, 0.300)}
        for name, (a, b) in times.items():
            with open(os.path.join(renders, name, "times.json"), "w") as f:
                json.dump({"0001": a, "0002": b}, f)
        p = subprocess.run([CRISP, "eval"] + args + ["-o", out], stdout=subprocess.PIPE, stderr=subprocess.PIPE,
                           timeout=900)
        assert p.returncode == 0, p.stderr.decode()[-3000:]
        scene = json.load(open(os.path.join(out, "results.json")))["scenes"][0]
        entries = {m["name"]: m for m in scene["methods"]}
        entries.update({c["name"]: c for c in scene["eevee_curve"]})
        assert entries["taa"]["input"] == "jittered" and entries["none"]["input"] == "eevee_1"
        for name in ("none", "taa", "blender-smaa"):
            assert [round(f["render_s"], 9) for f in entries[name]["frames"]] == [0.04, 0.04], name
            assert entries[name]["mean"]["render_s"] == pytest.approx(0.04), name
        assert entries["eevee-1"]["time_s"] == pytest.approx(0.04)
        assert entries["eevee-2"]["time_s"] != pytest.approx(0.04)  # other samples: its own times
        # Other passes (depth, IDs, albedo): its own times, not pooled with the colour-only renders.
        assert [round(f["render_s"], 9) for f in entries["taa-improved"]["frames"]] == [0.2, 0.3]
        # taa costs its filter more than the unfiltered render, never less.
        assert entries["taa"]["mean"]["time_s"] > entries["eevee-1"]["time_s"]
        text = subtitle(out)
        assert "the temporal methods a jittered one" in text, text
    finally:
        shutil.rmtree(out, ignore_errors=True)
