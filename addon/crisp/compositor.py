# SPDX-License-Identifier: GPL-2.0-or-later
"""Filtered frames back into Blender: an image sequence inside a compositor node group
"Crisp Result" (an add-on cannot run its own code as a compositor node, BLENDER.md), and a
still-frame preview in the Image Editor."""

import os

import bpy

GROUP_NAME = "Crisp Result"


def _group_output(group, name):
    """Adds an output socket: NodeTree.interface on 4.x, NodeTree.outputs on 3.x."""
    if hasattr(group, "interface"):
        group.interface.new_socket(name=name, in_out="OUTPUT", socket_type="NodeSocketColor" if name == "Image"
                                   else "NodeSocketFloat")
    else:
        group.outputs.new("NodeSocketColor" if name == "Image" else "NodeSocketFloat", name)


def load_sequence(first_path, frame_start, frame_end):
    """The filtered frames as one image datablock with source SEQUENCE."""
    if not os.path.isfile(first_path):
        raise FileNotFoundError("no filtered frame at %s: render with Crisp first" % first_path)
    image = bpy.data.images.load(first_path, check_existing=True)
    image.source = "SEQUENCE"
    image.name = "Crisp " + os.path.basename(os.path.dirname(first_path))
    return image


def result_group(image, frame_start, frame_end):
    """Creates or updates the node group: Image node (the sequence) -> Group Output (Image, Alpha)."""
    group = bpy.data.node_groups.get(GROUP_NAME)
    if group is None or group.bl_idname != "CompositorNodeTree":
        group = bpy.data.node_groups.new(GROUP_NAME, "CompositorNodeTree")
        _group_output(group, "Image")
        _group_output(group, "Alpha")
    nodes = group.nodes
    img = nodes.get("Crisp Frames") or nodes.new("CompositorNodeImage")
    img.name = img.label = "Crisp Frames"
    img.location = (-300, 0)
    img.image = image
    img.frame_duration = frame_end - frame_start + 1
    img.frame_start = frame_start
    img.frame_offset = frame_start - 1  # file frame_NNNN.exr shows at scene frame NNNN
    img.use_auto_refresh = True
    out = nodes.get("Group Output") or nodes.new("NodeGroupOutput")
    out.location = (0, 0)
    group.links.new(img.outputs["Image"], out.inputs["Image"])
    group.links.new(img.outputs["Alpha"], out.inputs["Alpha"])
    return group


def add_to_compositor(scene, group):
    """Puts one group node in the scene's compositor (turning it on); leaves existing links alone."""
    scene.use_nodes = True
    tree = scene.node_tree
    node = next((n for n in tree.nodes if n.bl_idname == "CompositorNodeGroup" and n.node_tree == group), None)
    if node is None:
        node = tree.nodes.new("CompositorNodeGroup")
        node.node_tree = group
        node.location = (-200, -350)
    node.label = GROUP_NAME
    return node


def load_result(scene, filtered_dir, frame_start, frame_end, ext=".exr"):
    first = os.path.join(filtered_dir, "frame_%04d%s" % (frame_start, ext))
    image = load_sequence(first, frame_start, frame_end)
    group = result_group(image, frame_start, frame_end)
    return add_to_compositor(scene, group)


def preview(path, context=None):
    """Shows one filtered frame in every open Image Editor (none in background mode); returns the image."""
    if not os.path.isfile(path):
        raise FileNotFoundError("no frame at %s" % path)
    image = bpy.data.images.load(path, check_existing=True)
    image.reload()
    wm = (context or bpy.context).window_manager
    for window in wm.windows:
        for area in window.screen.areas:
            if area.type == "IMAGE_EDITOR":
                area.spaces.active.image = image
    return image


def register():
    pass


def unregister():
    pass
