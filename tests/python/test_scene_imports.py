# SPDX-License-Identifier: Apache-2.0
"""A bundled test scene that builds on another (light_switch imports still_life): an edit of the scene
it imports is an edit of the scene, as an edit of test_scenes/common.py is, both for `crisp eval`'s
settings check (eval_settings.json scene_contents) and for `crisp render --resume` (the frames'
scene_key). The add-on and scenes of an edited tree come in through CRISP_ADDON_DIR.
Needs Blender and the built CLI (CRISP_BUILD_DIR)."""

import os
import shutil
import subprocess

from crisp_test_util import CRISP, SOURCE, needs_cli_and_blender

pytestmark = needs_cli_and_blender()
SCENE = ["--scene", "light_switch", "--frames", "1-2", "--resolution", "32x18"]


def crisp(args, env=None):
    return subprocess.run([CRISP] + args, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, timeout=300,
                          env=dict(os.environ, **(env or {})))


def edited_tree(tmp_path, script):
    """A copy of this tree's add-on and test scenes with test_scenes/<script> edited; the add-on folder,
    as CRISP_ADDON_DIR."""
    tree = tmp_path / "tree"
    for d in ("addon", "test_scenes"):
        shutil.copytree(os.path.join(SOURCE, d), tree / d)
    with open(tree / "test_scenes" / script, "a") as f:
        f.write("\n# edited\n")
    return {"CRISP_ADDON_DIR": str(tree / "addon")}


def test_eval_refuses_a_folder_made_before_an_edit_of_an_imported_scene(tmp_path):
    out = str(tmp_path / "eval")
    args = ["eval"] + SCENE + ["--reference-samples", "2", "--curve", "1", "--methods", "none", "--quiet", "-o", out]
    p = crisp(args)
    assert p.returncode == 0, p.stderr[-3000:]
    p = crisp(args, edited_tree(tmp_path, "still_life.py"))
    assert p.returncode == 2 and "holds renders made with other settings (scene_contents" in p.stderr, \
        p.stderr[-2000:]
    assert crisp(args).returncode == 0, "the unedited tree still resumes"


def test_render_resume_makes_again_the_frames_of_an_edited_imported_scene(tmp_path):
    out = str(tmp_path / "render")
    args = ["render"] + SCENE + ["--method", "fxaa", "-o", out]
    p = crisp(args + ["--quiet"])
    assert p.returncode == 0, p.stderr[-3000:]
    p = crisp(args + ["--resume"], edited_tree(tmp_path, "still_life.py"))
    assert p.returncode == 0, p.stderr[-3000:]
    assert "nothing to do" not in p.stdout and 'made with other settings (scene_key "sha256:' in p.stdout, \
        p.stdout[-2000:]
