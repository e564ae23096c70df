# SPDX-License-Identifier: GPL-2.0-or-later
"""Crisp: anti-aliasing filters for 1-sample EEVEE renders. This file only registers."""

bl_info = {
    "name": "Crisp",
    "author": "Crisp contributors",
    "version": (0, 2, 0),
    "blender": (3, 4, 0),
    "location": "Properties > Render > Crisp",
    "description": "Render at 1 sample with exactly the passes a filter needs, filter with libcrisp, compare",
    "category": "Render",
}

from . import compositor, operators, preferences, properties, ui, viewport  # noqa: E402

_modules = (preferences, properties, operators, compositor, ui, viewport)


def register():
    for m in _modules:
        m.register()


def unregister():
    for m in reversed(_modules):
        m.unregister()
