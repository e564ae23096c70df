# SPDX-License-Identifier: GPL-2.0-or-later
"""camera_dolly: the camera slides sideways over a picket fence and a checker floor.

Stresses: camera-only motion (every pixel moves, by depth-dependent parallax); thin vertical fence
pickets with disocclusion behind them every frame; a receding checker floor (moire under motion).
No object moves, so motion reconstruction needs depth and the camera matrices but no IDs.
Frames 1-48 (there by 24, back by 48), 480x270.
"""

import common


def build():
    scene = common.reset(1, 48)
    common.world((0.5, 0.6, 0.75), 0.8)
    common.light("SUN", (-3, -5, 6), energy=3.5)
    common.floor(30.0, common.checker(scale=30.0))
    wood = common.diffuse("Wood", (0.55, 0.35, 0.2))
    picket = common.mesh_object("Fence", "cube", wood, size=1.0, location=(-6, 1.0, 0.6))
    picket.scale = (0.04, 0.04, 1.2)
    arr = picket.modifiers.new("Pickets", "ARRAY")
    arr.count = 60
    arr.relative_offset_displace = (5.0, 0, 0)
    rail = common.mesh_object("Rail", "cube", wood, size=1.0, location=(0, 1.0, 0.9))
    rail.scale = (14.0, 0.03, 0.05)
    cam = common.camera((-2, -4, 1.4), (-2, 1, 0.8), lens=35)
    common.keyframes(cam, "location", [(-2, -4, 1.4), (2, -4, 1.4), (-2, -4, 1.4)], [1, 24, 48])  # and back
    return scene


if __name__ == "__main__":
    build()
