# SPDX-License-Identifier: GPL-2.0-or-later
"""The Flamenco job type's settings that follow the Crisp panel (flamenco/crisp-render.js: method, jitter,
input_codec, filter_params): their `eval` expressions, read out of the job type by Node.js, evaluated here
as Flamenco's add-on evaluates them at submission (eval(expression, {}, locals) with C = bpy.context),
give the panel's method, jitter, input codec and changed parameters with the Crisp add-on enabled, a
filter_params that `crisp render --set` accepts, and the job type's defaults without the add-on."""

import json
import os
import shutil
import subprocess
import sys
import tempfile
import unittest
from pathlib import Path

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import harness  # noqa: E402

import bpy  # noqa: E402
import crisp  # noqa: E402

JOB_TYPE_SCRIPT = os.path.join(harness.SOURCE_DIR, "flamenco", "crisp-render.js")
NODE = shutil.which("node")
CLI = os.path.join(harness.BUILD_DIR, "bin", "crisp")
PANEL_SETTINGS = ("method", "jitter", "input_codec", "filter_params")


def job_type():
    """JOB_TYPE of crisp-render.js, as the Manager reads it (the script run by Node.js)."""
    script = ("const fs = require('fs'), vm = require('vm'); const c = vm.createContext({});"
              "vm.runInContext(fs.readFileSync(process.argv[1], 'utf8') + ';globalThis.__jt = JOB_TYPE;', c);"
              "process.stdout.write(JSON.stringify(c.__jt));")
    run = subprocess.run([NODE, "-e", script, JOB_TYPE_SCRIPT], capture_output=True, text=True, check=True)
    return {s["key"]: s for s in json.loads(run.stdout)["settings"]}


def flamenco_eval(expression):
    """As Flamenco's add-on evaluates a setting (job_types_propgroup.JobTypePropertyGroup.eval_setting):
    empty globals, its names as locals (so a lambda or comprehension in the expression does not see C)."""
    names = {"bpy": bpy, "C": bpy.context, "jobname": "sh010", "Path": Path, "abspath": bpy.path.abspath,
             "last_n_dir_parts": None, "settings": None}
    return eval(expression, {}, names)


@unittest.skipUnless(NODE, "node not installed (it reads the job type's settings)")
class FlamencoSettingsTest(unittest.TestCase):
    @classmethod
    def setUpClass(cls):
        cls.settings = job_type()

    def evaluated(self):
        out = {}
        for key in PANEL_SETTINGS:
            expression = self.settings[key].get("eval")
            self.assertTrue(expression, "setting %s has no eval" % key)
            self.assertTrue(self.settings[key].get("evalInfo", {}).get("showLinkButton"), key)  # linked: evaluated
            out[key] = flamenco_eval(expression)
        return out

    @unittest.skipUnless(harness.library_usable()[0] and os.path.isfile(CLI), "libcrisp or crisp not built")
    def test_the_panel_decides_method_jitter_and_parameters(self):
        crisp.register()
        try:
            s = bpy.context.scene.crisp
            s.method = "phlm"
            s.jitter_distribution = "uniform"
            s.input_codec = "zip"
            setattr(s.phlm, "lambda", 0.99)  # a float (float32 in Blender), an int, a choice, a bool
            s.phlm.holdPeriod = 8
            s.phlm.modelFetch = "bilinear"
            s.phlm.footprintBox = False
            s.repair.kappa = -1.0  # another method's: not sent
            got = self.evaluated()
            self.assertEqual(got["method"], "phlm")
            self.assertEqual(got["jitter"], "uniform")
            self.assertEqual(got["input_codec"], "zip")
            self.assertEqual(sorted(got["filter_params"].split(" ")),
                             ["footprintBox=false", "holdPeriod=8", "lambda=0.99", "modelFetch=bilinear"])

            # crisp render takes it as the job type passes it: one --set per item. A value it refuses
            # (lambda out of its range) fails the same command, before Blender starts.
            def plan(params):
                with tempfile.TemporaryDirectory() as d:
                    cmd = [CLI, "render", "--plan", "--scene", "still_life", "--method", got["method"], "--jitter",
                           got["jitter"], "--input-codec", got["input_codec"], "-o", d]
                    for kv in params.split():
                        cmd += ["--set", kv]
                    return subprocess.run(cmd, capture_output=True, text=True, timeout=300)
            run = plan(got["filter_params"])
            self.assertEqual(run.returncode, 0, run.stdout + run.stderr)
            refused = plan(got["filter_params"].replace("lambda=0.99", "lambda=2"))
            self.assertNotEqual(refused.returncode, 0)
            self.assertIn("lambda", refused.stderr)

            # A choice saved by a newer add-on (a number this one's menu does not hold, which reads ""): the
            # job type refuses the value the expression gives, rather than run with crisp's default.
            for prop, key in (("jitter_distribution", "jitter"), ("input_codec", "input_codec")):
                saved = s[prop]
                s[prop] = 9
                try:
                    self.assertEqual(self.evaluated()[key], "unknown to this add-on")
                    self.assertNotIn(self.evaluated()[key], self.settings[key]["choices"])
                finally:
                    s[prop] = saved

            # Back at the library's defaults, nothing is sent.
            for name in ("lambda", "holdPeriod", "modelFetch", "footprintBox"):
                s.phlm.property_unset(name)
            self.assertEqual(self.evaluated()["filter_params"], "")
            s.method = "repair"
            self.assertEqual(self.evaluated()["filter_params"], "kappa=-1")
        finally:
            crisp.unregister()

    def test_the_scene_setting_names_the_submitting_scene(self):
        """The job renders the scene it was submitted from (crisp render --scene-name), also when the
        window shows another scene than the one the file opened at."""
        other = bpy.data.scenes.new("Shot B")
        try:
            self.assertEqual(flamenco_eval(self.settings["scene"]["eval"]), bpy.context.scene.name)
            with bpy.context.temp_override(scene=other):
                self.assertEqual(flamenco_eval(self.settings["scene"]["eval"]), "Shot B")
        finally:
            bpy.data.scenes.remove(other)

    def test_without_the_addon_the_job_types_defaults(self):
        """The Crisp add-on not enabled in the submitting Blender: no scene.crisp. An expression that
        raised would stop Flamenco's submission with a Python error; each gives the setting's default."""
        self.assertFalse(hasattr(bpy.context.scene, "crisp"))
        got = self.evaluated()
        self.assertEqual(got, {k: self.settings[k]["default"] for k in PANEL_SETTINGS})


if __name__ == "__main__":
    harness.run(FlamencoSettingsTest)
