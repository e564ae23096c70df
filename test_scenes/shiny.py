# SPDX-License-Identifier: GPL-2.0-or-later
"""shiny: glossy metal spheres and a torus under a moving point light, static camera and objects.

Stresses: specular highlights that move while no geometry does - the motion vectors are zero
(lights make no motion vectors, so the plan drops the motion pass), yet the shading changes every
frame: temporal methods must not smear or lag the highlights (history clipping), and bright
sub-pixel highlights (fireflies at 1 sample) test HDR robustness. Frames 1-16, 480x270.
"""

import common


def build():
    scene = common.reset(1, 16)
    common.world((0.02, 0.02, 0.03))
    common.floor(10.0, common.checker(scale=10.0, c1=(0.5, 0.5, 0.5), c2=(0.1, 0.1, 0.1)))
    common.mesh_object("Chrome", "uv_sphere", common.glossy("ChromeMat", (0.9, 0.9, 0.9), 0.03), radius=0.6,
                       location=(-0.9, 0, 0.6), segments=48, ring_count=24)
    common.mesh_object("Gold", "uv_sphere", common.glossy("GoldMat", (1.0, 0.75, 0.3), 0.15), radius=0.45,
                       location=(0.6, 0.5, 0.45), segments=48, ring_count=24)
    common.mesh_object("Ring", "torus", common.glossy("CopperMat", (0.95, 0.5, 0.35), 0.08),
                       location=(0.8, -0.7, 0.2), major_radius=0.4, minor_radius=0.08)
    lamp = common.light("POINT", (-3, -2, 3), energy=400.0, name="Lamp")
    common.keyframes(lamp, "location", [(-3, -2, 3), (3, -2, 3)], [1, 16])
    common.camera((0, -5, 2.2), (0, 0, 0.4), lens=45)
    return scene


if __name__ == "__main__":
    build()
