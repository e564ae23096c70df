# SPDX-License-Identifier: GPL-2.0-or-later
"""foliage: alpha-cut leaves on a swaying branch over a ground plane.

Stresses: edges made by an alpha test inside a texture, not by geometry: a leaf is one quad whose
shape only the material cuts. EEVEE 3.4's Depth pass follows the cut (alpha clip discards there), so
rsaa's geometry renders see the leaf shapes; a renderer whose geometry passes ignore the material
would show whole quads there and geometry-driven methods would miss these edges. Small holes between
leaves; a gentle rigid sway of the branch. Two visible objects (branch and ground), one moving.
Frames 1-16, 480x270.
"""

import math
import random

import bpy

import common


def leaf_material():
    """Leaf shape cut by alpha: a radial gradient thresholded (alpha clip), green diffuse."""
    mat = bpy.data.materials.new("Leaf")
    mat.use_nodes = True
    if "CLIP" in [i.identifier for i in mat.bl_rna.properties["blend_method"].enum_items]:
        mat.blend_method = "CLIP"   # EEVEE 3.x alpha test
        mat.alpha_threshold = 0.5
    else:
        mat.blend_method = "HASHED"
    nodes, links = mat.node_tree.nodes, mat.node_tree.links
    bsdf = nodes["Principled BSDF"]
    bsdf.inputs["Base Color"].default_value = (0.1, 0.5, 0.08, 1.0)
    coords = nodes.new("ShaderNodeTexCoord")
    grad = nodes.new("ShaderNodeTexGradient")
    grad.gradient_type = "QUADRATIC_SPHERE"
    mapping = nodes.new("ShaderNodeMapping")
    mapping.inputs["Scale"].default_value = (2.2, 1.2, 1.0)
    mapping.inputs["Location"].default_value = (-1.1, -0.6, 0.0)
    ramp = nodes.new("ShaderNodeValToRGB")
    ramp.color_ramp.interpolation = "CONSTANT"
    ramp.color_ramp.elements[1].position = 0.05
    links.new(coords.outputs["UV"], mapping.inputs["Vector"])
    links.new(mapping.outputs["Vector"], grad.inputs["Vector"])
    links.new(grad.outputs["Fac"], ramp.inputs["Fac"])
    links.new(ramp.outputs["Color"], bsdf.inputs["Alpha"])
    return mat


def build():
    scene = common.reset(1, 16)
    common.world((0.6, 0.7, 0.9), 0.7)
    common.light("SUN", (2, -3, 6), energy=4.0)
    common.floor(10.0, common.diffuse("Soil", (0.25, 0.18, 0.1)))
    rng = random.Random(3)
    verts, faces, uvs = [], [], []
    for i in range(40):
        cx, cy, cz = rng.uniform(-1.2, 1.2), rng.uniform(-0.3, 0.3), rng.uniform(0.8, 2.2)
        a = rng.uniform(0, 2 * math.pi)
        dx, dz = 0.18 * math.cos(a), 0.18 * math.sin(a)
        ex, ez = -0.1 * math.sin(a), 0.1 * math.cos(a)
        base = len(verts)
        verts += [(cx - dx - ex, cy, cz - dz - ez), (cx + dx - ex, cy, cz + dz - ez),
                  (cx + dx + ex, cy, cz + dz + ez), (cx - dx + ex, cy, cz - dz + ez)]
        faces.append((base, base + 1, base + 2, base + 3))
        uvs += [(0, 0), (1, 0), (1, 1), (0, 1)]
    mesh = bpy.data.meshes.new("Branch")
    mesh.from_pydata(verts, [], faces)
    uv = mesh.uv_layers.new(name="UVMap")
    for loop in mesh.loops:
        uv.data[loop.index].uv = uvs[loop.vertex_index]
    mesh.materials.append(leaf_material())
    branch = common.link(bpy.data.objects.new("Branch", mesh))
    common.keyframes(branch, "rotation_euler", [(0, common.rad(-4), 0), (0, common.rad(4), 0)], [1, 16])
    common.camera((0, -5, 1.6), (0, 0, 1.4), lens=50)
    return scene


if __name__ == "__main__":
    build()
