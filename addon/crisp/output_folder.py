# SPDX-License-Identifier: GPL-2.0-or-later
"""Where a scene's Crisp frames go when the panel's Output is empty: //crisp/<scene name>/ beside the
saved .blend, a folder of its own. The first render writes it into the scene's Output (pins it), as a
render output path is kept with its scene, so a renamed scene keeps its folder. A default never
takes a folder that holds another scene's runs, or that another scene's Output names (compared
without case, as macOS and Windows do): it moves on to //crisp/<name>-2/, -3, ... A copied scene keeps the
pinned Output; its first render gives it a folder of its own. An Output the user set is used as it
is, shared or not (the operators then warn)."""

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


def _outputs_naming(path, scene):
    """The other scenes whose Output is the folder path (compared without case)."""
    key = _key(path)
    return [other.name for other in bpy.data.scenes
            if other != scene and other.crisp.output_dir and _key(other.crisp.output_dir) == key]


def sharing(scene):
    """The other scenes whose Output is this scene's folder (a copied scene keeps its Output, as it
    keeps its render output path): their renders overwrite each other's frames."""
    return _outputs_naming(scene.crisp.output_dir, scene) if scene.crisp.output_dir else []


def _taken(path, scene):
    """Whether a default may not take the folder: another scene's Output names it, or it holds runs of
    another scene. Runs of a scene of this name are taken as its own (its Output emptied by an undo,
    or a farm's `crisp render` into //crisp/<scene>/)."""
    return bool(_outputs_naming(path, scene)) or folder_scene(bpy.path.abspath(path)) not in (None, scene.name)


def default_out_dir(scene):
    """The folder the scene's Output gets when it is empty. A file saved by an earlier add-on, whose
    runs of this scene went to //crisp/, keeps //crisp/."""
    legacy = "//crisp/"
    if bpy.data.filepath and folder_scene(bpy.path.abspath(legacy)) == scene.name and \
            not _outputs_naming(legacy, scene):
        return legacy
    base = folder_name(scene.name)
    for k in itertools.count(1):
        path = "//crisp/%s/" % (base if k == 1 else "%s-%d" % (base, k))
        if not _taken(path, scene):
            return path


def _owns(scene, path):
    """Of scenes sharing a pinned folder (a copy and its original), the one whose runs went there, or
    before any run the one it was named after: the other moves on its next render."""
    owner = folder_scene(bpy.path.abspath(path))
    if owner is not None:
        return owner == scene.name
    return os.path.basename(os.path.normpath(bpy.path.abspath(path))) == folder_name(scene.name)


class UnsavedFile(RuntimeError):
    """An unsaved .blend and an empty Output: // has no folder to mean."""


def out_dir(scene, writing):
    """The scene's output folder as an absolute path. writing (the renders): an empty Output is pinned
    to the default, and so is a pinned one another scene shares (a copy's). Otherwise (compare,
    load, preview) nothing is written into the scene."""
    s = scene.crisp
    if not s.output_dir and not bpy.data.filepath:
        raise UnsavedFile("save the .blend file first (Crisp's frames go to //crisp/<scene>/ beside it), "
                          "or set the Output folder in the Crisp panel")
    if s.output_dir and not s.output_dir.startswith("//") and not os.path.isabs(os.path.expanduser(s.output_dir)):
        # Blender would resolve it against the process's working folder.
        raise UnsavedFile("the Output folder '%s' is relative: give an absolute folder, or one relative to the "
                          ".blend file (starting with //)" % s.output_dir)
    if s.output_dir.startswith("//") and not bpy.data.filepath:
        # Blender would resolve // against the process's working folder: somewhere the user never chose.
        raise UnsavedFile("the Output folder '%s' is relative to the .blend file, which is not saved yet: "
                          "save it first, or give an absolute folder" % s.output_dir)
    if writing and (not s.output_dir or (s.output_dir == s.output_pinned and sharing(scene) and
                                         not _owns(scene, s.output_dir))):
        s.output_dir = s.output_pinned = default_out_dir(scene)
    return os.path.abspath(os.path.expanduser(bpy.path.abspath(s.output_dir or default_out_dir(scene))))
