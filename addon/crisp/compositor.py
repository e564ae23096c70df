# SPDX-License-Identifier: GPL-2.0-or-later
"""Filtered frames back into Blender: an image sequence inside a compositor node group (an add-on
cannot run its own code as a compositor node, BLENDER.md), and a still-frame preview in the Image
Editor. A group belongs to a folder of filtered frames (tagged with it), so scenes with their own
output folders (output_folder.py) have their own groups, named "Crisp Result: <scene>" (after a renamed
scene on its next load). The group's node is linked into Composite where that takes the render straight
(_wire_output), so the render is the filtered frames."""

import os

import bpy

GROUP_NAME = "Crisp Result"
FOLDER_TAG = "crisp_folder"  # custom property of a result group: the folder whose frames it shows
NAME_TAG = "crisp_name"  # custom property of a result group: the name Crisp gave it (another: the artist's)
NODE_TAG = "crisp_result"  # custom property of the node Crisp put in a scene's compositor
WIRED_TAG = "crisp_wired"  # custom property of that node: the Composite output took its image once
PREVIEW_TAG = "crisp_preview"  # custom property of an image Preview Frame loaded (removed once unused)


def group_name(scene):
    return "%s: %s" % (GROUP_NAME, scene.name)


def _group_output(group, name):
    """Adds an output socket unless the group has it: NodeTree.interface on 4.x, NodeTree.outputs on 3.x."""
    sockets = group.interface.items_tree if hasattr(group, "interface") else group.outputs
    if any(getattr(s, "in_out", "OUTPUT") == "OUTPUT" and s.name == name for s in sockets):
        return
    if hasattr(group, "interface"):
        group.interface.new_socket(name=name, in_out="OUTPUT", socket_type="NodeSocketColor" if name == "Image"
                                   else "NodeSocketFloat")
    else:
        group.outputs.new("NodeSocketColor" if name == "Image" else "NodeSocketFloat", name)


def _path_key(path):
    return os.path.normcase(os.path.abspath(path))


def _image_of(path, source):
    """The image of the file at `path` with that source ("FILE" or "SEQUENCE"), loaded if there is none.
    The compositor's sequence starts at the first frame's file, and Preview Frame shows that file too: two
    images, or the Image Editor is handed the sequence, which it numbers 1 to 100 from the timeline (at
    frame 150 it read frame_0100.exr), and Load into Compositor turns a previewed still into a sequence."""
    key = _path_key(path)
    image = next((i for i in bpy.data.images if i.library is None and i.source == source and i.filepath
                  and _path_key(bpy.path.abspath(i.filepath)) == key), None)  # a linked image cannot be changed
    if image is None:
        image = bpy.data.images.load(path, check_existing=False)
        image.source = source
    return image


def load_sequence(first_path, name):
    """The filtered frames as one image datablock with source SEQUENCE."""
    if not os.path.isfile(first_path):
        raise FileNotFoundError("no filtered frame at %s: render with Crisp first" % first_path)
    image = _image_of(first_path, "SEQUENCE")
    image.name = name
    if bpy.data.filepath and bpy.context.preferences.filepaths.use_relative_paths:
        # As Blender's own Open Image: relative to the .blend, so the node still finds the frames when
        # the project folder (the .blend with its //crisp/ output) is moved or renamed.
        try:
            image.filepath = bpy.path.relpath(first_path)
        except ValueError:  # another drive than the .blend's (Windows): stays absolute
            pass
    return image


def frames_image(group):
    """The image of a result group's "Crisp Frames" node (the filtered frames), or None."""
    node = group.nodes.get("Crisp Frames")
    return node.image if node is not None and node.bl_idname == "CompositorNodeImage" else None


def _folder_of(group):
    """The folder of the frames a result group shows: that of its image node's image, whose path is
    relative to the .blend where load_sequence made it so and which Blender rebases on Save As, so a
    moved or saved-elsewhere project still finds its group; the tag (FOLDER_TAG, absolute, the folder
    the group was made for) where the group has no image."""
    image = frames_image(group)
    if image is None or not image.filepath:
        return group.get(FOLDER_TAG)
    return _path_key(os.path.dirname(bpy.path.abspath(image.filepath, library=image.library)))


def _names_another_scene(group, scene):
    """Whether a group Crisp named "Crisp Result: <name>" (NAME_TAG; or Blender's "<name>.001" of it) names
    a scene other than this one that is gone or does not show the group in its compositor: the scene was
    renamed since (its pinned folder kept its frames, output_folder.py), and a new scene may have the old
    name. A name the artist gave the group, or one of another scene showing it (a shared folder), stays."""
    prefix = GROUP_NAME + ": "
    given = group.get(NAME_TAG, group.name)  # (groups of earlier add-ons have no tag: their name)
    if group.name == group_name(scene) or group.name != given or not group.name.startswith(prefix):
        return False
    named = group.name[len(prefix):]
    other = bpy.data.scenes.get(named) or bpy.data.scenes.get(named.rsplit(".", 1)[0])
    if other is None:
        return True
    if other == scene:
        return False
    return other.node_tree is None or not any(n.bl_idname == "CompositorNodeGroup" and n.node_tree == group
                                              for n in other.node_tree.nodes)


def result_group(scene, folder, image, frame_start, frame_end):
    """Creates or updates the group of a folder of filtered frames: Image node (the sequence) -> Group
    Output (Image, Alpha). Every node showing the group, the user's too, follows the update. What the
    artist did inside the group stays: nodes where they were put, and an output fed through their own
    nodes (a grade between the frames and the output, where the run's note says to composite) is not
    wired straight to the frames again."""
    key = _path_key(folder)
    # Crisp's own groups only (tagged): a user's group holding a copy of the image node is theirs.
    group = next((g for g in bpy.data.node_groups if g.bl_idname == "CompositorNodeTree" and g.library is None
                  and FOLDER_TAG in g and _folder_of(g) == key), None)
    if group is None:
        group = bpy.data.node_groups.new(group_name(scene), "CompositorNodeTree")
        group[NAME_TAG] = group.name
    elif _names_another_scene(group, scene):
        group.name = group_name(scene)
        group[NAME_TAG] = group.name
    group[FOLDER_TAG] = key
    _group_output(group, "Image")
    _group_output(group, "Alpha")
    nodes = group.nodes
    img = nodes.get("Crisp Frames")
    if img is None:
        img = nodes.new("CompositorNodeImage")
        img.name = img.label = "Crisp Frames"
        img.location = (-300, 0)
    replaced, img.image = img.image, image
    if replaced is not None and replaced != image and replaced.library is None and replaced.users == 0:
        # The sequence of a range that started at another frame, shown nowhere else now: not left behind
        # in the file's images, one more on each render of another range.
        bpy.data.images.remove(replaced)
    img.frame_duration = frame_end - frame_start + 1
    img.frame_start = frame_start
    img.frame_offset = frame_start - 1  # file frame_NNNN.exr shows at scene frame NNNN
    img.use_auto_refresh = True
    out = nodes.get("Group Output")
    if out is None:
        out = nodes.new("NodeGroupOutput")
        out.location = (0, 0)
    for socket in ("Image", "Alpha"):
        fed = out.inputs[socket].links
        # Unfed, or fed by an image node (this one, or one Crisp made that was renamed): the frames.
        if not fed or fed[0].from_node.bl_idname == "CompositorNodeImage":
            group.links.new(img.outputs[socket], out.inputs[socket])
    return group


def add_to_compositor(scene, group):
    """Puts one group node in the scene's compositor (turning it on: load_result turns it off again where
    the artist had their nodes off); leaves existing links alone (the Composite output's are load_result's,
    _wire_output). The node Crisp put there before (tagged; it may show the group of the scene's earlier
    folder, or of the scene it was copied from), or a node of the one group all scenes shared before, is
    switched to the group; nodes the user added are left alone."""
    scene.use_nodes = True
    tree = scene.node_tree
    groups = [n for n in tree.nodes if n.bl_idname == "CompositorNodeGroup"]
    # Crisp's node showing no group (its group deleted in the Outliner) is Crisp's node still.
    node = next((n for n in groups if n.get(NODE_TAG)), None) or \
        next((n for n in groups if n.node_tree is not None and n.node_tree.name == GROUP_NAME), None)
    if node is None:
        shown = next((n for n in groups if n.node_tree == group), None)
        if shown is not None:
            return shown  # the user's own node shows the group already: left as it is, untagged
        node = tree.nodes.new("CompositorNodeGroup")
        node.location = (-200, -350)
    node.node_tree = group
    node.label = node.label or GROUP_NAME  # one the artist gave it stays
    node[NODE_TAG] = True
    return node


# Nodes that pass the render through unchanged: a tree of these alone (Blender's default Render Layers ->
# Composite, with Crisp's own result node beside it) composites nothing that Crisp's frames would miss.
_PASS_THROUGH = {"CompositorNodeRLayers", "CompositorNodeComposite", "CompositorNodeViewer", "NodeReroute",
                 "NodeFrame", "NodeGroupInput", "NodeGroupOutput"}


def _is_result(node, key):
    """Whether a node shows the scene's filtered frames as they are: Crisp's node (load_result switches it
    to the scene's group), or the user's own node of the group of those frames (key: the _path_key of
    their folder; add_to_compositor leaves such a node untagged), unless the group holds more than
    result_group puts there (a copy the user edited, which keeps the tag). A node of another folder's group
    (another scene's frames, put in as a plate) is an image like any other."""
    if node.bl_idname != "CompositorNodeGroup" or node.mute:
        return False
    tree = node.node_tree
    return bool(node.get(NODE_TAG)) or (tree is not None and FOLDER_TAG in tree and _folder_of(tree) == key and {
        n.bl_idname for n in tree.nodes} <= {"CompositorNodeImage", "NodeGroupOutput"})


def _changes(node, key):
    return not (node.bl_idname in _PASS_THROUGH or node.mute or _is_result(node, key))


def _graph(tree):
    """({node name: nodes feeding it}, {node name: nodes it feeds}) over the links that carry an image
    (not muted, not invalid)."""
    upstream, downstream = {}, {}
    for link in tree.links:
        if link.is_valid and not getattr(link, "is_muted", False):
            upstream.setdefault(link.to_node.name, []).append(link.from_node)
            downstream.setdefault(link.from_node.name, []).append(link.to_node)
    return upstream, downstream


def _reached(start, step):
    """The names of the nodes reached from `start` (nodes) through step(node) (nodes), start's own too."""
    todo, seen = list(start), {n.name for n in start}
    while todo:
        for other in step(todo.pop()):
            if other.name not in seen:
                seen.add(other.name)
                todo.append(other)
    return seen


def _outputs(tree):
    return [n for n in tree.nodes if n.bl_idname == "CompositorNodeComposite"]


def _tree_changes(tree, key):
    """Whether the tree changes the image its Composite output renders from what the scene's filtered frames
    (key: the _path_key of their folder) are: a node that feeds a Composite output (every node where there
    is none) other than the pass-through ones, muted ones, Crisp's result nodes and the nodes those feed
    (the artist's grade of Crisp's frames, composited as the run's note says to)."""
    upstream, downstream = _graph(tree)
    of_crisp = _reached([n for n in tree.nodes if _is_result(n, key)], lambda n: downstream.get(n.name, ()))
    outputs = _outputs(tree)
    feeding = _reached(outputs, lambda n: upstream.get(n.name, ())) if outputs else {n.name for n in tree.nodes}
    return any(_changes(tree.nodes[name], key) for name in feeding - of_crisp)


def changes_the_image(scene, filtered_dir):
    """Whether the scene's compositor would change its rendered frames (_tree_changes); filtered_dir: the
    folder of the scene's filtered frames."""
    tree = scene.node_tree if scene.use_nodes and scene.render.use_compositing else None
    return tree is not None and _tree_changes(tree, _path_key(filtered_dir))


def _taking_result(tree, key):
    """The Composite outputs that take the image of a result node of the frames of `key` (through any
    nodes)."""
    upstream, _ = _graph(tree)
    return [out for out in _outputs(tree)
            if any(_is_result(tree.nodes[name], key) for name in _reached([out], lambda n: upstream.get(n.name, ())))]


def _straight_from_render(socket, output, scene, layer):
    """Whether an input takes the `output` socket of a Render Layers node straight (Blender's default tree)
    that renders the scene's view layer `layer` (None: any of the scene's), the render Crisp's frames
    stand for; one of another scene or view layer is the artist's plate, which the frames do not
    replace."""
    link = socket.links[0] if socket.is_linked else None
    if link is None or not link.is_valid or getattr(link, "is_muted", False):
        return False
    node = link.from_node
    return (node.bl_idname == "CompositorNodeRLayers" and link.from_socket.identifier == output
            and (node.scene is None or node.scene == scene) and (layer is None or node.layer == layer))


def _wire_output(tree, node, scene, layer, key):
    """Links Crisp's node into each Composite output that takes the render as Blender's default tree does
    (its Image unlinked or straight from Render Layers; its Alpha too where linked straight from them), so
    that the render (F12, an animation) is the filtered frames (key: the _path_key of their folder). Where
    the artist's nodes are between (a grade), their tree is not rewired: output_note says how to connect
    it. Once for a node (WIRED_TAG, also when the artist connected it): one who links the render back
    afterwards chose to, and a later load or run leaves it so. A Viewer is left alone: it shows what the
    artist last looked at (Ctrl+Shift+click), not what is rendered. scene, layer: the render the frames are
    of (_straight_from_render)."""
    if not node.get(NODE_TAG) or node.get(WIRED_TAG):
        return
    taking, wired = _taking_result(tree, key), False
    for out in _outputs(tree):
        image, alpha = out.inputs["Image"], out.inputs.get("Alpha")  # (no Alpha input on later Blenders)
        if out in taking or image.is_linked and not _straight_from_render(image, "Image", scene, layer):
            continue
        tree.links.new(node.outputs["Image"], image)
        wired = True
        if alpha is not None and _straight_from_render(alpha, "Alpha", scene, layer):
            tree.links.new(node.outputs["Alpha"], alpha)
    if taking or (wired and _is_result(node, key)):  # an output takes the frames now (a muted node shows none)
        node[WIRED_TAG] = True


def output_note(scene, filtered_dir, after_run=False):
    """What to tell the artist when the scene's render does not take Crisp's frames (those of
    filtered_dir) from the compositor (it is then the unfiltered render), else None. after_run: told after
    a run, whose note said that a compositor that changes the image is not applied to the frames, which
    says what the note of a Composite node not taking them would."""
    tree = scene.node_tree
    if tree is None:
        return None
    outputs, taking = _outputs(tree), _taking_result(tree, _path_key(filtered_dir))
    if not scene.use_nodes:
        return ("the compositor's Use Nodes is off, so the render (F12) is the unfiltered one (Crisp turns it on "
                "only where nothing but its frames would reach Composite): link the 'Crisp Result' node's Image "
                "output into Composite (or into your nodes where the Render Layers Image goes in) and turn Use "
                "Nodes on")
    if not outputs:
        return ("the compositor has no Composite node, so the render (F12) is not the filtered frames: add "
                "one and link the 'Crisp Result' node's Image output into it")
    if not taking:
        if after_run and changes_the_image(scene, filtered_dir):
            return None
        return ("the compositor's Composite node does not take the filtered frames, so the render (F12) is the "
                "unfiltered one: link the 'Crisp Result' node's Image output into Composite's Image, or into "
                "your nodes where the Render Layers Image goes in")
    if len(taking) < len(outputs):
        # Blender renders one Composite node, the active one (the last clicked), which Python cannot read.
        rest = [o for o in outputs if o not in taking]
        them = "them" if len(rest) > 1 else "it"
        return ("the compositor has %d Composite nodes and Blender renders only the active one, which an add-on "
                "cannot see; %s %s not take the filtered frames, so a render through %s is the unfiltered one: "
                "link the 'Crisp Result' node's Image output into %s too (or into your nodes before %s), or "
                "delete the Composite nodes you do not render"
                % (len(outputs), " and ".join("'%s'" % o.name for o in rest), "do" if len(rest) > 1 else "does",
                   them, them, them))
    if not scene.render.use_compositing:
        return ("Post Processing > Compositing is off, so the render (F12) is not the filtered frames of the "
                "'Crisp Result' node: turn it on to render them")
    return None


def load_result(scene, filtered_dir, frame_start, frame_end, ext=".exr", layer=None):
    """The frames frame_start..frame_end of filtered_dir into the scene's compositor, from the first that
    exists (a run of a later part of the range, or one whose first frames were removed); the caller names
    the missing ones (pipeline.sequence_warnings). layer: the name of the view layer they were rendered
    from (None: any of the scene's), whose Render Layers node they replace in Composite."""
    def path(f):
        return os.path.join(filtered_dir, "frame_%04d%s" % (f, ext))
    if frame_start < 0:
        # Blender reads the "-" of frame_-002 as part of the name: its sequence would show frame -1 at
        # frame 1 and nothing at frames -2..0.
        raise ValueError("frames %d-%d: Blender's image sequences cannot show negative frame numbers; load "
                         "frames from 0 on (the filtered files of the others are in %s)"
                         % (frame_start, frame_end, filtered_dir))
    first = next((f for f in range(frame_start, frame_end + 1) if os.path.isfile(path(f))), None)
    if first is None:
        raise FileNotFoundError("no filtered frame of frames %d-%d in %s: render with Crisp first"
                                % (frame_start, frame_end, filtered_dir))
    image = load_sequence(path(first), "Crisp " + scene.name)
    group = result_group(scene, filtered_dir, image, first, frame_end)
    image.name = "Crisp " + scene.name  # the name of the image it replaced, if that held it
    switched_off, key = not scene.use_nodes and scene.node_tree is not None, _path_key(filtered_dir)
    node = add_to_compositor(scene, group)
    tree = scene.node_tree
    _wire_output(tree, node, scene, layer, key)
    if switched_off and (_tree_changes(tree, key) or len(_taking_result(tree, key)) < len(_outputs(tree))):
        # The artist's nodes, switched off: on, they would change the render (output_note says so). Off with
        # Blender's default tree, or with none yet, it is turned on to render the frames.
        scene.use_nodes = False
    return node


def preview(path, context=None):
    """Shows one filtered frame in every open Image Editor (none in background mode); returns the image.
    The image of the frame previewed before, when Preview Frame loaded it and nothing else uses or shows it
    now, goes: stepping through a shot kept one image, with its pixels, per frame (2 MB a frame at 960x540)."""
    if not os.path.isfile(path):
        raise FileNotFoundError("no frame at %s" % path)
    before = set(bpy.data.images)
    image = _image_of(path, "FILE")
    if image not in before:
        image[PREVIEW_TAG] = True
    image.reload()
    wm = (context or bpy.context).window_manager
    for window in wm.windows:
        for area in window.screen.areas:
            if area.type == "IMAGE_EDITOR":
                area.spaces.active.image = image
    _remove_unused_previews(keep=image)
    return image


def _remove_unused_previews(keep):
    """Removes the images Preview Frame loaded (PREVIEW_TAG) that no Image Editor of any screen shows and
    nothing uses (a node, a texture, a fake user); an editor's own user (use_extra_user) is not a use."""
    shown = {space.image for screen in bpy.data.screens for area in screen.areas for space in area.spaces
             if space.type == "IMAGE_EDITOR" and space.image is not None}
    for image in [i for i in bpy.data.images if i.get(PREVIEW_TAG) and i != keep and i not in shown]:
        if image.library is None and not image.use_fake_user and image.users == int(image.use_extra_user):
            bpy.data.images.remove(image)


def register():
    pass


def unregister():
    pass
