# SPDX-License-Identifier: GPL-2.0-or-later
"""spinning_cube: one object, rigid rotation, static camera.

Stresses: silhouette edges sweeping at every angle; motion vectors of a rotating rigid body
(reconstruction from its world matrix: the only visible object, so no ID pass is needed - the
object/background split follows from depth); history rejection where the background is uncovered.
Frames 1-48 (a quarter turn about Z plus a tilt every 23 frames), 480x270.
"""

import common


def build():
    scene = common.reset(1, 48)
    common.world((0.2, 0.22, 0.25))
    common.light("SUN", (3, -4, 6), energy=4.0)
    cube = common.mesh_object("Cube", "cube", common.checker("CubeChecker", 3.0), size=1.6)
    common.keyframes(cube, "rotation_euler", [(0, 0, 0), (common.rad(30), 0, common.rad(90)),
                                              (common.rad(60), 0, common.rad(180))], [1, 24, 48])
    common.camera((0, -6, 2.5), (0, 0, 0), lens=50)
    return scene


if __name__ == "__main__":
    build()
