# SPDX-License-Identifier: GPL-2.0-or-later
"""still_life: the spatial-aliasing stress test, and the default scene of the main job.

Stresses: thin wires (sub-pixel cylinders at shallow angles: broken, crawling lines at 1 sample),
a high-frequency checker floor receding to the horizon (moire), text (small curved glyph edges), hard
cube silhouettes against a dark world. Nothing moves: the camera is static and nothing is animated,
so temporal methods need no motion vectors and should converge to the reference by accumulation.
Frames 1-16, 480x270.
"""

import bpy

import common


def build():
    scene = common.reset(1, 16)
    common.world((0.03, 0.03, 0.04))
    common.light("SUN", (3, -4, 6), energy=3.0)
    common.floor(12.0, common.checker(scale=24.0))
    common.mesh_object("Box", "cube", common.diffuse("Red", (0.8, 0.1, 0.05)), size=0.8, location=(-1.2, 0.4, 0.4),
                       rotation=(0, 0, common.rad(25)))
    common.mesh_object("Ball", "uv_sphere", common.diffuse("Blue", (0.1, 0.2, 0.8)), radius=0.45,
                       location=(1.1, 0.6, 0.45), segments=24, ring_count=12)
    wire = common.emission("Wire", (1.0, 0.9, 0.6), 2.0)
    for i, (angle, height) in enumerate([(3, 1.3), (12, 1.6), (-7, 1.9), (30, 1.1)]):
        common.mesh_object("Wire%d" % i, "cylinder", wire, radius=0.008, depth=6.0, vertices=6,
                           location=(0, 0.2 * i, height), rotation=(0, common.rad(90), common.rad(angle)))
    text_data = bpy.data.curves.new("Title", "FONT")
    text_data.body = "Crisp AA"
    text_data.size = 0.35
    text = common.link(bpy.data.objects.new("Title", text_data))
    text.location = (-0.9, -0.6, 0.01)
    text.data.materials.append(common.diffuse("White", (0.95, 0.95, 0.95)))
    common.camera((0, -5.5, 2.4), (0, 0.3, 0.6), lens=40)
    return scene


if __name__ == "__main__":
    build()
