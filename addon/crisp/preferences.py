# SPDX-License-Identifier: GPL-2.0-or-later
"""Add-on preferences: where libcrisp is, how many threads it uses."""

import bpy

from . import native, properties


def _library_changed(self, context):
    native.set_preference_path(bpy.path.abspath(self.library_path) if self.library_path else "")
    properties.add_param_groups()  # a library that loads now brings the methods' settings


class CrispPreferences(bpy.types.AddonPreferences):
    bl_idname = __package__

    library_path: bpy.props.StringProperty(
        name="Library", subtype="FILE_PATH", update=_library_changed,
        description="libcrisp.so to load (empty: $CRISP_LIBRARY, then <repo>/build/lib/libcrisp.so)")
    threads: bpy.props.IntProperty(name="Threads", default=0, min=0, max=256,
                                   description="Threads the library uses (0: all cores)")

    def draw(self, context):
        self.layout.prop(self, "library_path")
        self.layout.prop(self, "threads")
        ok, text = native.status()
        self.layout.label(text=text, icon="CHECKMARK" if ok else "ERROR")
        note = native.preference_note()
        if note:
            self.layout.label(text="Library path: " + note, icon="INFO")


def get(context=None):
    """The preferences, or None when the add-on runs unregistered (batch.py)."""
    addons = (context or bpy.context).preferences.addons
    entry = addons.get(__package__)
    return entry.preferences if entry else None


def threads(context=None):
    p = get(context)
    return p.threads if p else 0


def register():
    bpy.utils.register_class(CrispPreferences)
    p = get()
    if p and p.library_path:
        native.set_preference_path(bpy.path.abspath(p.library_path))


def unregister():
    bpy.utils.unregister_class(CrispPreferences)
