# SPDX-License-Identifier: GPL-2.0-or-later
"""hairball: a rotating ball of thin curved fibres (one curve object, many splines).

Stresses: sub-pixel-wide geometry everywhere (fibres thinner than a pixel vanish and reappear at
1 sample), dense overlapping edges of one object (ID is constant across fibres: object IDs cannot
separate them, depth must), rigid rotation. One visible object. Frames 1-16, 480x270.
"""

import math
import random

import bpy

import common


def build():
    scene = common.reset(1, 16)
    common.world((0.08, 0.08, 0.1))
    common.light("SUN", (2, -4, 5), energy=4.0)
    rng = random.Random(7)  # deterministic fibres
    data = bpy.data.curves.new("Hairball", "CURVE")
    data.dimensions = "3D"
    data.bevel_depth = 0.006
    data.bevel_resolution = 0
    for _ in range(160):
        spline = data.splines.new("POLY")
        spline.points.add(5)
        theta, phi = rng.uniform(0, 2 * math.pi), math.acos(rng.uniform(-1, 1))
        for k, p in enumerate(spline.points):
            r = 1.0 + 0.08 * k
            t = theta + 0.25 * k
            x = r * math.sin(phi) * math.cos(t)
            y = r * math.sin(phi) * math.sin(t)
            z = r * math.cos(phi) + 0.05 * k * rng.uniform(-1, 1)
            p.co = (x, y, z, 1.0)
    ob = common.link(bpy.data.objects.new("Hairball", data))
    ob.data.materials.append(common.diffuse("Fibre", (0.9, 0.75, 0.4)))
    common.keyframes(ob, "rotation_euler", [(0, 0, 0), (0, 0, common.rad(60))], [1, 16])
    common.camera((0, -6, 1.5), (0, 0, 0), lens=50)
    return scene


if __name__ == "__main__":
    build()
