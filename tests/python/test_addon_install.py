# SPDX-License-Identifier: Apache-2.0
"""The add-on installed as the README says, in a fresh Blender process whose user scripts folder is
a temporary one: linked into its add-ons folder it finds this checkout's build by itself; copied there
without a library it says where to give one."""

import os
import shutil
import subprocess

import pytest

from crisp_test_util import LIBRARY, SOURCE

pytestmark = [pytest.mark.skipif(shutil.which("blender") is None, reason="blender not installed")]

PROBE = ("import addon_utils; addon_utils.enable('crisp', default_set=False); "
         "from crisp import native; ok, text = native.status(); print('STATUS', ok, text); "
         "from crisp import gpu_filters\n"
         "try:\n    print('SHADER', len(gpu_filters.shader_source('taa.glsl')))\n"
         "except gpu_filters.GpuFilterError as e:\n    print('SHADER', e)")


def status(scripts, library=None, want="STATUS "):
    env = dict(os.environ, BLENDER_USER_SCRIPTS=str(scripts))
    env.pop("CRISP_LIBRARY", None)
    if library:
        env["CRISP_LIBRARY"] = library
    p = subprocess.run(["blender", "-b", "--factory-startup", "--python-expr", PROBE], env=env,
                       stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True, timeout=300)
    lines = [line for line in p.stdout.splitlines() if line.startswith(want)]
    assert lines, p.stdout[-2000:]
    return lines[-1]


def test_linked_addon_finds_the_checkouts_build(tmp_path):
    repo_build = os.path.join(SOURCE, "build", "lib", "libcrisp.so")
    if not os.path.isfile(repo_build):
        pytest.skip("no build in %s/build (the add-on's own fallback)" % SOURCE)
    (tmp_path / "addons").mkdir()
    (tmp_path / "addons" / "crisp").symlink_to(os.path.join(SOURCE, "addon", "crisp"))
    line = status(tmp_path)
    assert line.startswith("STATUS True") and os.path.normpath(repo_build) in line, line
    # The viewport preview's shaders: the link is followed to the checkout's shaders/.
    assert status(tmp_path, want="SHADER ").split()[1].isdigit()


def test_copied_addon_finds_its_shaders_beside_the_library(tmp_path):
    """A copied (or zipped) add-on given the library's path finds the preview's shaders from there:
    the checkout's build/lib -> shaders/ (an installed lib/ -> share/crisp/shaders)."""
    shutil.copytree(os.path.join(SOURCE, "addon", "crisp"), tmp_path / "addons" / "crisp",
                    ignore=shutil.ignore_patterns("__pycache__"))
    line = status(tmp_path, library=LIBRARY, want="SHADER ")
    assert line.split()[1].isdigit(), line
    line = status(tmp_path, want="SHADER ")  # no library: nothing to look beside
    assert "not found" in line, line


def test_copied_addon_without_a_library_says_where_to_give_it(tmp_path):
    assert os.path.isfile(LIBRARY)
    shutil.copytree(os.path.join(SOURCE, "addon", "crisp"), tmp_path / "addons" / "crisp",
                    ignore=shutil.ignore_patterns("__pycache__"))
    line = status(tmp_path)
    assert line.startswith("STATUS False"), line
    assert "preferences" in line and "$CRISP_LIBRARY" in line, line
    # A wrong $CRISP_LIBRARY stops the search there, and the message says to correct it.
    line = status(tmp_path, library=str(tmp_path / "nowhere" / "libcrisp.so"))
    assert line.startswith("STATUS False") and "Correct $CRISP_LIBRARY" in line, line


FIXED_LATER = """
import addon_utils, bpy, os
addon_utils.enable('crisp', default_set=True)
from crisp import native, properties
print('BEFORE', native.status()[0], properties.param_group(bpy.context.scene.crisp, 'taa'))
bpy.context.preferences.addons['crisp'].preferences.library_path = os.environ['FIXED_LIBRARY']
s = bpy.context.scene.crisp
print('AFTER', native.status()[0], {m: properties.param_group(s, m) is not None for m in ('taa', 'taa-improved', 'phlm')})
s.taa.feedbackMin = 0.5
print('CHANGED', properties.changed_params(s, 'taa'))
addon_utils.disable('crisp')
addon_utils.enable('crisp', default_set=True)
print('AGAIN', properties.param_group(bpy.context.scene.crisp, 'taa').feedbackMin)
addon_utils.disable('crisp')
print('OFF', hasattr(bpy.types.Scene, 'crisp'))
"""


def test_library_path_given_after_enabling_brings_the_methods_settings(tmp_path):
    """Enabled without a library, then given its path in the preferences: the library loads, and each
    method's settings appear with it (they are built from the library's tables). They used to appear
    only after the add-on was enabled again, and a run took the defaults meanwhile, without a word."""
    shutil.copytree(os.path.join(SOURCE, "addon", "crisp"), tmp_path / "addons" / "crisp",
                    ignore=shutil.ignore_patterns("__pycache__"))
    env = dict(os.environ, BLENDER_USER_SCRIPTS=str(tmp_path), FIXED_LIBRARY=LIBRARY)
    env.pop("CRISP_LIBRARY", None)
    p = subprocess.run(["blender", "-b", "--factory-startup", "--python-exit-code", "1", "--python-expr", FIXED_LATER],
                       env=env, stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True, timeout=300)
    lines = {line.split(" ", 1)[0]: line for line in p.stdout.splitlines()
             if line.split(" ", 1)[0] in ("BEFORE", "AFTER", "CHANGED", "AGAIN", "OFF")}
    assert p.returncode == 0 and len(lines) == 5, p.stdout[-3000:]
    assert lines["BEFORE"] == "BEFORE False None", lines
    assert lines["AFTER"] == "AFTER True {'taa': True, 'taa-improved': True, 'phlm': True}", lines
    assert lines["CHANGED"] == "CHANGED {'feedbackMin': 0.5}", lines
    assert lines["AGAIN"] == "AGAIN 0.5", lines  # the scene keeps the value through a disable and enable
    assert lines["OFF"] == "OFF False", lines
