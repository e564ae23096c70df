# SPDX-License-Identifier: GPL-2.0-or-later
"""Shared helpers of the procedural test scenes: reset, world, lights, camera, EEVEE settings,
materials (checker, emission, glossy), linear keyframes. Every scene script calls `reset()` first, so
it builds the same scene from Blender's factory startup or from any open file."""

import math

import bpy
from mathutils import Vector

DEFAULT_RESOLUTION = (480, 270)


def reset(frame_start=1, frame_end=16, resolution=DEFAULT_RESOLUTION):
    """Empties the current scene and the data it used; sets frame range, size and EEVEE."""
    scene = bpy.context.scene
    for ob in list(bpy.data.objects):
        bpy.data.objects.remove(ob, do_unlink=True)
    for coll in (bpy.data.meshes, bpy.data.curves, bpy.data.cameras, bpy.data.lights, bpy.data.materials,
                 bpy.data.worlds, bpy.data.node_groups, bpy.data.images, bpy.data.actions):
        for block in list(coll):
            if block.users == 0 or coll in (bpy.data.worlds, bpy.data.actions):
                coll.remove(block)
    scene.frame_start, scene.frame_end = frame_start, frame_end
    scene.frame_set(frame_start)
    scene.render.resolution_x, scene.render.resolution_y = resolution
    scene.render.resolution_percentage = 100
    eevee_settings(scene)
    return scene


def eevee_settings(scene, samples=64):
    items = [i.identifier for i in scene.render.bl_rna.properties["engine"].enum_items]
    scene.render.engine = "BLENDER_EEVEE_NEXT" if "BLENDER_EEVEE_NEXT" in items else "BLENDER_EEVEE"
    scene.eevee.taa_render_samples = samples
    scene.eevee.gi_cubemap_resolution = "64"  # the per-frame probe costs ~1.4 s at 512 (BLENDER.md)
    scene.render.film_transparent = False
    scene.view_settings.view_transform = "Standard"


def world(color=(0.05, 0.05, 0.06), strength=1.0):
    w = bpy.data.worlds.new("World")
    w.use_nodes = True
    bg = w.node_tree.nodes["Background"]
    bg.inputs["Color"].default_value = (*color, 1.0)
    bg.inputs["Strength"].default_value = strength
    bpy.context.scene.world = w
    return w


def link(ob):
    bpy.context.scene.collection.objects.link(ob)
    return ob


def light(kind="SUN", location=(4, -4, 6), energy=3.0, target=(0, 0, 0), name="Light"):
    data = bpy.data.lights.new(name, kind)
    data.energy = energy
    ob = link(bpy.data.objects.new(name, data))
    ob.location = location
    look_at(ob, target)
    return ob


def look_at(ob, target):
    direction = Vector(target) - Vector(ob.location)
    ob.rotation_euler = direction.to_track_quat("-Z", "Y").to_euler()


def camera(location=(0, -6, 3), target=(0, 0, 0.5), lens=50.0, ortho_scale=None, name="Camera"):
    data = bpy.data.cameras.new(name)
    data.lens = lens
    if ortho_scale:
        data.type = "ORTHO"
        data.ortho_scale = ortho_scale
    ob = link(bpy.data.objects.new(name, data))
    ob.location = location
    look_at(ob, target)
    bpy.context.scene.camera = ob
    return ob


def mesh_object(name, primitive, material=None, **kw):
    """Adds a primitive with bpy.ops (fine headless) and names it."""
    getattr(bpy.ops.mesh, "primitive_%s_add" % primitive)(**kw)
    ob = bpy.context.active_object
    ob.name = ob.data.name = name
    if material:
        ob.data.materials.append(material)
    return ob


def _principled(name, color, roughness=0.5, metallic=0.0):
    mat = bpy.data.materials.new(name)
    mat.use_nodes = True
    bsdf = mat.node_tree.nodes["Principled BSDF"]
    bsdf.inputs["Base Color"].default_value = (*color, 1.0)
    bsdf.inputs["Roughness"].default_value = roughness
    bsdf.inputs["Metallic"].default_value = metallic
    return mat, bsdf


def diffuse(name, color):
    return _principled(name, color, roughness=0.8)[0]


def glossy(name, color, roughness=0.05, metallic=1.0):
    return _principled(name, color, roughness, metallic)[0]


def checker(name="Checker", scale=8.0, c1=(0.9, 0.9, 0.9), c2=(0.02, 0.02, 0.02)):
    """High-contrast checker on the object's generated coordinates."""
    mat, bsdf = _principled(name, (1, 1, 1), roughness=0.9)
    nodes, links = mat.node_tree.nodes, mat.node_tree.links
    tex = nodes.new("ShaderNodeTexChecker")
    tex.inputs["Scale"].default_value = scale
    tex.inputs["Color1"].default_value = (*c1, 1.0)
    tex.inputs["Color2"].default_value = (*c2, 1.0)
    links.new(tex.outputs["Color"], bsdf.inputs["Base Color"])
    return mat


def emission(name, color, strength=1.0):
    mat = bpy.data.materials.new(name)
    mat.use_nodes = True
    nodes = mat.node_tree.nodes
    nodes.remove(nodes["Principled BSDF"])
    em = nodes.new("ShaderNodeEmission")
    em.inputs["Color"].default_value = (*color, 1.0)
    em.inputs["Strength"].default_value = strength
    mat.node_tree.links.new(em.outputs["Emission"], nodes["Material Output"].inputs["Surface"])
    return mat


def keyframes(ob, path, values, frames, index=-1):
    """Linear keys of ob.<path> (a sequence property) at the given frames."""
    for value, f in zip(values, frames):
        setattr(ob, path, value)
        ob.keyframe_insert(path, frame=f, index=index)
    if ob.animation_data and ob.animation_data.action:
        for fc in ob.animation_data.action.fcurves:
            for kp in fc.keyframe_points:
                kp.interpolation = "LINEAR"


def floor(size=20.0, material=None):
    return mesh_object("Floor", "plane", material or checker(scale=size), size=size)


def rad(deg):
    return math.radians(deg)
