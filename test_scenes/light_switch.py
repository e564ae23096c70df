# SPDX-License-Identifier: GPL-2.0-or-later
"""light_switch: still_life with a second light switched on at frame 41; nothing moves.

Stresses: a change without motion in a still shot. Temporal methods hold a still pixel once it has
averaged a whole jitter period (taa.cpp and phlm.cpp "Hold"); a change that leaves the held value
inside the pixel's box (the rim of every edge the new light brightens) is taken in only through the
hold's release (temporal/hold_release.h), two jitter periods after it began. Frames 1-80 (the
release comes at 64 with the add-on's 16-point jitter), 480x270.
"""

import bpy

import common
import still_life

SWITCH_FRAME = 41


def build():
    scene = still_life.build()
    scene.frame_start, scene.frame_end = 1, 80
    lamp = common.light("POINT", (-2.0, -1.5, 2.5), energy=0.0, name="Switched")
    for frame, energy in ((1, 0.0), (SWITCH_FRAME - 1, 0.0), (SWITCH_FRAME, 400.0)):
        lamp.data.energy = energy
        lamp.data.keyframe_insert("energy", frame=frame)
    for curve in lamp.data.animation_data.action.fcurves:
        for key in curve.keyframe_points:
            key.interpolation = "CONSTANT"
    scene.frame_set(scene.frame_start)
    return scene


if __name__ == "__main__":
    build()
