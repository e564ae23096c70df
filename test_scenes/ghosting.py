# SPDX-License-Identifier: GPL-2.0-or-later
"""ghosting: a white sphere crossing a high-contrast striped wall (seed 000's ghosting protocol).

Stresses: history that must be rejected - the wall uncovered behind the sphere differs strongly from
the sphere (ghost trails), thin dark/bright stripes behind a moving edge; one object moves, two are
visible, so motion reconstruction needs IDs to tell the sphere's pixels from the wall's.
Static camera. Frames 1-48 (across by 24, back by 48), 480x270.
"""

import common


def build():
    scene = common.reset(1, 48)
    common.world((0.0, 0.0, 0.0))
    common.light("SUN", (0, -5, 5), energy=3.0)
    common.mesh_object("Wall", "plane", common.checker("Stripes", 12.0, (1, 1, 1), (0, 0, 0)), size=8.0,
                              location=(0, 2, 2), rotation=(common.rad(90), 0, 0))
    ball = common.mesh_object("Sphere", "uv_sphere", common.emission("Glow", (1.0, 1.0, 1.0), 1.5), radius=0.6,
                              location=(-3, 0.5, 2), segments=32, ring_count=16)
    # Across and back: 0.26 units a frame, the wall uncovered behind it on both passes.
    common.keyframes(ball, "location", [(-3, 0.5, 2), (3, 0.5, 2), (-3, 0.5, 2)], [1, 24, 48])
    common.camera((0, -7, 2), (0, 0, 2), lens=45)
    return scene


if __name__ == "__main__":
    build()
