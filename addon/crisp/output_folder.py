# SPDX-License-Identifier: GPL-2.0-or-later
"""Where a scene's Crisp frames go when the panel's Output is empty: //crisp/<scene name>/, a folder
of its own. The first operator that needs it writes it into the scene's Output (pins it), as a
render output path is kept with its scene: renaming the scene keeps its folder and its results, and
a new scene given the old name gets another folder. A folder is another scene's when that scene's
Output names it (compared without case, as macOS and Windows do) or its run files name that scene."""

import itertools
import json
import os
import zlib

import bpy

WINDOWS_RESERVED = {"CON", "PRN", "AUX", "NUL"} | {"%s%d" % (p, i) for p in ("COM", "LPT") for i in range(1, 10)}


def folder_name(name):
    """A scene name as a folder name: kept where every file system takes it; else the characters some
    refuse become '_' and a hash of the name is added, so two names never share a folder."""
    safe = "".join("_" if c in '<>:"/\\|?*' or ord(c) < 32 else c for c in name).rstrip(" .")
    if safe != name or safe in ("", ".", "..") or safe.split(".")[0].upper() in WINDOWS_RESERVED:
        safe = "%s-%08x" % (safe.replace(".", "_") or "scene", zlib.crc32(name.encode("utf-8")))
    return safe


def folder_scene(folder):
    """The scene whose runs went to folder (an absolute path), from its run.json or a chunk's
    run_AAAA-BBBB.json; None if there are none."""
    try:
        names = sorted(n for n in os.listdir(folder) if n.startswith("run") and n.endswith(".json"))
    except OSError:
        return None
    for name in names:
        try:
            with open(os.path.join(folder, name)) as f:
                scene = json.load(f).get("scene")
        except (OSError, ValueError, AttributeError):
            continue
        if isinstance(scene, str):
            return scene
    return None


def _key(path):
    return os.path.normpath(os.path.abspath(bpy.path.abspath(path))).casefold()


def sharing(scene):
    """The other scenes whose Output is this scene's folder (a copied scene keeps its Output, as it
    keeps its render output path): their renders overwrite each other's frames."""
    if not scene.crisp.output_dir:
        return []
    key = _key(scene.crisp.output_dir)
    return [other.name for other in bpy.data.scenes
            if other != scene and other.crisp.output_dir and _key(other.crisp.output_dir) == key]


def _taken(path, scene):
    """Whether the folder is another scene's: its Output names it, or its runs went there."""
    key = _key(path)
    if any(other != scene and other.crisp.output_dir and _key(other.crisp.output_dir) == key
           for other in bpy.data.scenes):
        return True
    return folder_scene(bpy.path.abspath(path)) not in (None, scene.name)


def default_out_dir(scene):
    """The folder the scene's Output gets when it is empty. A file saved by an earlier add-on, whose
    runs of this scene went to //crisp/, keeps //crisp/."""
    if bpy.data.filepath and folder_scene(bpy.path.abspath("//crisp/")) == scene.name and \
            not _taken("//crisp/", scene):
        return "//crisp/"
    base = folder_name(scene.name)
    for k in itertools.count(1):
        path = "//crisp/%s/" % (base if k == 1 else "%s-%d" % (base, k))
        if not _taken(path, scene):
            return path


def out_dir(scene):
    """The scene's output folder as an absolute path; an empty Output is pinned to the default."""
    if not scene.crisp.output_dir:
        scene.crisp.output_dir = default_out_dir(scene)
    return os.path.abspath(bpy.path.abspath(scene.crisp.output_dir))
