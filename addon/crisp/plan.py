# SPDX-License-Identifier: GPL-2.0-or-later
"""The pass plan: which render passes a method reads, minus what the scene does not need.

Pure Python: nothing here imports ``bpy`` at module level, so plain tests (tests/python/test_plan.py)
reach the logic. ``scene_facts`` takes a Blender scene object as an argument and only calls methods on it.

Logical passes (the library's image roles, see native/core/conventions.h) and the view-layer flag each
one needs in Blender:

    color       Combined              always
    depth       use_pass_z            planar depth (half float on EEVEE 3.4)
    normal      use_pass_normal       world-space normal
    motion      use_pass_vector       only where the renderer writes it (EEVEE Next, Cycles);
                                      on EEVEE 3.4 the library reconstructs it (issue 3 item 4) from
                                      depth, camera matrices and object transforms in the sidecars
    id          use_pass_cryptomatte_object   CryptoObject00 (hash of the object name)
    albedo      use_pass_diffuse_color        DiffCol
    subsamples  extra geometry-only renders (depth + normal) at sub-pixel offsets (RSAA)
"""

import collections
import hashlib
from array import array
from dataclasses import dataclass, field

# What each method reads when the scene needs everything (METHODS.md).
METHOD_PASSES = {
    "none": ("color",),
    "fxaa": ("color",),
    "repair": ("color",),
    "taa": ("color", "motion", "depth"),
    "taa-improved": ("color", "depth", "id", "albedo", "motion"),
    "phlm": ("color", "motion", "depth"),
    "rsaa": ("color", "depth", "normal", "subsamples"),
}
STATIC_METHODS = tuple(METHOD_PASSES)
TEMPORAL_METHODS = ("taa", "taa-improved", "phlm")

# The parameters that stop a temporal filter from averaging still pixels (Plan.still_average False), each
# method's "path with neighbourhood clipping": taa and taa-improved blend them as moving ones; phlm forgets
# them as fast as moving ones (lambdaMoving: its value is read from the library) and keeps the 3x3 box.
# Measured on a keyed scrolling checker, still camera, 240x136, 8 frames, 16-sample reference: taa 16.93 ->
# 19.61 dB, phlm 16.19 -> 19.52 dB (method none 20.86 dB).
NO_STILL_AVERAGE = {"taa": {"staticAccumulation": False}, "taa-improved": {"staticAccumulation": False},
                    "phlm": {"lambda": "lambdaMoving", "footprintBox": False}}

# Not a method: what `crisp eval`'s temporal error (METHODS.md "Metrics") reads where something moves.
# Its warp W and disocclusion test must describe the PIXEL CENTRES of the images it compares (the
# outputs and the reference), so they come from an unjittered 1-sample render: a jittered frame's
# motion, depth and IDs describe the point at p + jitter, up to 1.5 px away, and belong to another
# surface along every edge that moves against what is behind it.
TEMPORAL_ERROR = "temporal-error"
MEASURE_PASSES = {TEMPORAL_ERROR: ("color", "depth", "motion", "id")}

# Why a method reads a pass (used in the reasons).
USE = {
    ("taa", "motion"): "reprojects the history along the motion vectors",
    ("taa", "depth"): "takes the velocity of the closest-depth pixel of the 3x3 neighbourhood",
    ("taa-improved", "motion"): "reprojects the history along the motion vectors",
    ("taa-improved", "depth"): "depth Sobel term and depth pseudo-variances (eqs. 4.4-4.6)",
    ("taa-improved", "id"): "modelAverage: fraction of 3x3 neighbours with another object ID (eq. 4.1)",
    ("taa-improved", "albedo"): "unlit luminance term of the Sobel edge measure",
    ("phlm", "motion"): "reprojects the per-pixel linear models",
    ("phlm", "depth"): "closest-depth velocity and the disocclusion reset of the models",
    ("rsaa", "depth"): "positions for the SADP similarity",
    ("rsaa", "normal"): "normals for the SADP similarity",
    ("rsaa", "subsamples"): "8 geometric sub-samples per pixel (depth + normal at sub-pixel offsets)",
    (TEMPORAL_ERROR, "color"): "always rendered (Combined); the temporal error compares the outputs and the reference",
    (TEMPORAL_ERROR, "motion"): "the temporal error's warp W, at the pixel centres of the compared images",
    (TEMPORAL_ERROR, "depth"): "the temporal error's disocclusion test (and the motion reconstruction)",
    (TEMPORAL_ERROR, "id"): "the temporal error's disocclusion test by object ID",
}

# The order passes are listed in (plans, sidecars, render sets).
PASS_ORDER = ("color", "depth", "normal", "motion", "id", "albedo", "subsamples")

# Blender view-layer flag of each logical pass (None: not a view-layer pass).
PASS_FLAGS = {
    "color": "use_pass_combined",
    "depth": "use_pass_z",
    "normal": "use_pass_normal",
    "motion": "use_pass_vector",
    "id": "use_pass_cryptomatte_object",
    "albedo": "use_pass_diffuse_color",
    "subsamples": None,
}


@dataclass
class SceneFacts:
    """What the plan needs to know about a scene over a frame range."""
    frame_start: int
    frame_end: int
    camera_moves: bool = False
    moving_objects: list = field(default_factory=list)      # names whose world matrix changes
    deforming_objects: list = field(default_factory=list)   # names with animated geometry
    visible_objects: list = field(default_factory=list)     # renderable, visible object names (on any frame)
    renderer_motion_pass: bool = False                      # the renderer writes a Vector pass
    camera_cuts: list = field(default_factory=list)         # frames whose camera is another than the frame before's
    # moving objects whose ID several rendered instances share (render.object_table leaves them out)
    shared_id_movers: list = field(default_factory=list)
    # what changes the image over the range with no geometry moving (a keyed material, a light, what
    # renders), as "material 'Belt'": a still pixel's history would keep the old image
    image_changes: list = field(default_factory=list)
    # the same for a change on a few frames only, a step, as "light 'Switched' (frame 41)": the filters'
    # hold release takes it in, so still pixels keep their average
    image_steps: list = field(default_factory=list)


@dataclass
class Plan:
    method: str
    passes: list                  # logical passes, in PASS_ORDER
    reasons: dict                 # pass -> why it is rendered
    skipped: dict                 # pass -> why it is not rendered
    jitter: bool                  # per-frame sub-pixel jitter (temporal methods)
    motion_source: str = "none"   # "renderer" | "reconstruct" | "none"
    # False: the image changes where nothing moves (SceneFacts.image_changes), so the temporal filter
    # must not average still pixels (pipeline.with_plan_params turns that off)
    still_average: bool = True
    history_note: str = ""        # what changes the image with no motion, and what the filter does of it

    def render_flags(self):
        """View-layer flags to switch on (everything else off)."""
        flags = [PASS_FLAGS[p] for p in self.passes if PASS_FLAGS.get(p)]
        if self.motion_source == "reconstruct":
            flags = [f for f in flags if f != "use_pass_vector"]
        return flags

    def to_json(self):
        return {"method": self.method, "passes": list(self.passes), "reasons": dict(self.reasons),
                "skipped": dict(self.skipped), "jitter": self.jitter, "motion_source": self.motion_source,
                "still_average": self.still_average, "history_note": self.history_note}

    def describe(self):
        lines = ["plan for %s:" % self.method]
        for p in self.passes:
            lines.append("  + %-10s %s" % (p, self.reasons[p]))
        for p, why in self.skipped.items():
            lines.append("  - %-10s %s" % (p, why))
        lines.append("  jitter: %s; motion: %s" % ("per-frame Halton(2,3)" if self.jitter else "none",
                                                     self.motion_source))
        if self.history_note:
            lines.append("  history: " + self.history_note)
        return "\n".join(lines)


def some_names(names, most=4, quote=False):
    """At most `most` names joined by commas (quoted with quote), and how many more there are."""
    shown = ["'%s'" % n if quote else n for n in names[:most]]
    return ", ".join(shown) + (" and %d more" % (len(names) - most) if len(names) > most else "")


RENDERER_SOURCE = "from the renderer's Vector pass"


def make_plan(method, facts):
    """The passes `method` reads on a scene described by `facts`, each with a reason. `method` may also
    be TEMPORAL_ERROR: the passes of eval's temporal error (unjittered)."""
    wanted = METHOD_PASSES.get(method) or MEASURE_PASSES.get(method)
    if wanted is None:
        raise ValueError("unknown method '%s' (known: %s)" % (method, ", ".join(METHOD_PASSES)))
    moving = bool(facts.camera_moves or facts.moving_objects or facts.deforming_objects)
    single = len(facts.visible_objects) <= 1
    passes, reasons, skipped = [], {}, {}
    motion_source = "none"
    # The library averages every pixel whose motion is zero (static accumulation), moving scene or not:
    # where the image changes there without motion, that average would keep the old image (a ghost).
    changes = some_names(facts.image_changes)
    still_average = not (method in TEMPORAL_METHODS and facts.image_changes)
    history_note = "" if still_average else (
        "%s change%s the image over frames %d-%d with no motion, so pixels that do not move are blended "
        "with neighbourhood clipping as moving ones are, not averaged (an average would keep the old image)"
        % (changes, "s" if len(facts.image_changes) == 1 else "", facts.frame_start, facts.frame_end))
    if method in TEMPORAL_METHODS and facts.image_steps:
        history_note += ("; " if history_note else "") + (
            "%s change%s the image in a step with no motion: still pixels keep their average until the hold's "
            "release takes the change in, about two jitter periods later (holdRelease)"
            % (some_names(facts.image_steps), "s" if len(facts.image_steps) == 1 else ""))

    def rigid_movers():
        return (["the camera"] if facts.camera_moves else []) + facts.moving_objects

    def motion_reason(use, source):
        """Why motion is read: what moves, and what deforms, said apart: reconstruction is rigid."""
        parts = []
        if rigid_movers():
            parts.append("%s move" % some_names(rigid_movers()))
        if facts.deforming_objects:
            parts.append("%s deform%s" % (some_names(facts.deforming_objects),
                                          "s" if len(facts.deforming_objects) == 1 else ""))
        text = "%s: %s; %s" % (" and ".join(parts), use, source)
        if facts.deforming_objects and source != RENDERER_SOURCE:
            # native/motion/reconstruct.h moves each pixel with its object's transform alone.
            text += ("; deforming geometry is reprojected rigidly (with its object's transform, not its "
                     "vertices' motion), so %s may leave a trail" % some_names(facts.deforming_objects))
        return text

    for p in wanted:
        use = USE.get((method, p), "")
        if p == "color":
            passes.append(p)
            reasons[p] = use or "the image %s filters (Combined, 1 sample)" % method
        elif method == TEMPORAL_ERROR and not moving:
            skipped[p] = ("nothing moves over frames %d-%d: the warp W is the identity and nothing is "
                          "disoccluded" % (facts.frame_start, facts.frame_end))
        elif p == "motion":
            if not moving:
                skipped[p] = ("nothing moves over frames %d-%d (camera and every visible object keep their "
                              "world matrix): motion is zero" % (facts.frame_start, facts.frame_end))
                if facts.image_changes:
                    skipped[p] += "; the image changes all the same (%s): see history" % changes
                continue
            passes.append(p)
            if facts.renderer_motion_pass:
                motion_source = "renderer"
                reasons[p] = motion_reason(use, RENDERER_SOURCE)
            else:
                motion_source = "reconstruct"
                reasons[p] = motion_reason(use, "this renderer has no Vector pass, so the library reconstructs "
                                                "it from depth, the camera matrices and the object transforms "
                                                "in the sidecars")
        elif method == "rsaa" and p != "color" and not facts.visible_objects:
            # Nothing to render: no geometry, no geometric edges; rsaa keeps every pixel's colour.
            skipped[p] = "no visible object: no geometric edges, so rsaa keeps every colour and renders no geometry"
        elif p == "depth" and method in ("taa", "phlm") and not moving:
            skipped[p] = "%s reads depth only for velocity and disocclusion, and nothing moves" % method
        elif p == "id" and single:
            skipped[p] = ("%d visible object: an object/background mask follows from depth"
                          % len(facts.visible_objects))
        else:
            passes.append(p)
            reasons[p] = use

    # Motion reconstruction (item 4) needs depth, and IDs to match pixels to moving object transforms.
    if motion_source == "reconstruct":
        if "depth" not in passes:
            passes.append("depth")
            reasons["depth"] = "motion reconstruction unprojects each pixel with its depth"
            skipped.pop("depth", None)
        needs_id = bool(facts.moving_objects or facts.deforming_objects) and not single
        if needs_id and "id" not in passes:
            passes.append("id")
            reasons["id"] = "motion reconstruction matches pixels to moving objects by Cryptomatte ID"
            skipped.pop("id", None)
        elif "id" not in passes and "id" not in skipped:
            skipped["id"] = ("motion reconstruction needs no IDs: "
                             + ("only the camera moves" if not (facts.moving_objects or facts.deforming_objects)
                                else "one visible object, told from the background by depth"))
    for p in ("depth", "normal", "id", "albedo", "subsamples"):
        if p not in passes and p not in skipped:
            skipped[p] = "%s does not read it" % method
    if "motion" not in passes and "motion" not in skipped:
        skipped["motion"] = "%s does not read it" % method
    passes.sort(key=PASS_ORDER.index)
    return Plan(method=method, passes=passes, reasons=reasons, skipped=skipped,
                jitter=method in TEMPORAL_METHODS, motion_source=motion_source, still_average=still_average,
                history_note=history_note)


def render_set_name(p):
    """The 1-sample render set of `crisp eval` that plan p's input comes from: "eevee_1" (the curve's
    1-sample frames) for colour alone without jitter, else "jittered" or "unjittered" followed by the
    passes beyond colour, e.g. "jittered-depth-motion". One set per distinct plan, so that each method's
    time per frame is the render of the passes it reads, not of another method's."""
    if p is None or not p.jitter and p.passes == ["color"]:
        return "eevee_1"
    return "-".join(["jittered" if p.jitter else "unjittered"] + [q for q in p.passes if q != "color"])


def render_sets(plans, facts):
    """The 1-sample render sets of `crisp eval` for the methods' plans on a scene described by `facts`:
    {name: Plan}, one for each distinct set of passes and jitter (render_set_name) but colour alone without
    jitter (the curve's eevee_1); "warp": where something moves, the temporal error's geometry
    (TEMPORAL_ERROR), which no method reads."""
    sets = {}
    for p in plans:
        name = render_set_name(p)
        if name == "eevee_1":
            continue
        # "subsamples" (rsaa): render.render_frames adds the geometry renders frame_NNNN_subK.exr and
        # lists them, with their render times, in each frame's sidecar (eval reports those times apart).
        if name in sets:
            sets[name].method += "+" + p.method
            continue
        sets[name] = Plan(method=p.method, passes=list(p.passes), reasons=dict(p.reasons), skipped={},
                          jitter=p.jitter, motion_source=p.motion_source)
    warp = make_plan(TEMPORAL_ERROR, facts)
    if warp.passes != ["color"]:  # something moves
        sets["warp"] = warp
    return sets


# ---- reading the facts off a Blender scene (bpy objects passed in, no bpy import) -----------------

RENDERABLE_TYPES = {"MESH", "CURVE", "SURFACE", "META", "FONT", "GPENCIL", "VOLUME", "POINTCLOUD", "CURVES"}


def _rendering_layer_collections(layer):
    """The layer's collections that render: not excluded from the layer nor hidden from render (nor any
    collection above them). Viewport visibility (the eye, the monitor icon) does not matter to a render."""
    def walk(lc):
        if lc.exclude or getattr(lc.collection, "hide_render", False):
            return
        yield lc
        for child in lc.children:
            yield from walk(child)

    return list(walk(layer.layer_collection))


def _render_collections_objects(layer):
    """The objects in the layer's collections that render, by as_pointer (a name is not unique: a linked
    object may have a local one's)."""
    return {o.as_pointer() for lc in _rendering_layer_collections(layer) for o in lc.collection.objects}


def scenes_with_sets(scene):
    """The scene, then each scene of its chain of background sets (Scene > Background Scene), which
    render behind it and move with its frames."""
    out, seen = [], set()
    while scene is not None and scene.as_pointer() not in seen:
        seen.add(scene.as_pointer())
        out.append(scene)
        scene = scene.background_set
    return out


def render_layers(layer):
    """(scene, view layer) pairs that make the layer's render: the layer itself, then for each
    background set the layer Blender renders it with (the first whose Use for Rendering is on, else the
    first)."""
    scene = layer.id_data
    pairs = [(scene, layer)]
    for s in scenes_with_sets(scene)[1:]:
        pairs.append((s, next((l for l in s.view_layers if l.use), s.view_layers[0])))
    return pairs


def _layer_objects(layer):
    """The objects of the layer's scene and of its background sets, each once, as [(object, the view
    layer that renders it, whether it is in a collection that renders there)]."""
    out, seen = [], set()
    for s, l in render_layers(layer):
        rendered = _render_collections_objects(l)
        for ob in s.objects:
            if ob.as_pointer() not in seen:
                seen.add(ob.as_pointer())
                out.append((ob, l, ob.as_pointer() in rendered))
    return out


def visible_objects(scene, view_layer=None):
    """Objects that reach the render: renderable types, not hidden from render, in a collection that
    renders in the layer or in a background set's. Hidden in the viewport only, an object still renders,
    so it counts."""
    layer = view_layer or scene.view_layers[0]
    return [ob for ob, _, rendered in _layer_objects(layer)
            if rendered and ob.type in RENDERABLE_TYPES and not ob.hide_render]


# Geometry Nodes that make a tree's output change with time without a keyframe: the scene's time, and
# a simulation zone (Blender 3.6+).
TIME_NODES = {"GeometryNodeInputSceneTime", "GeometryNodeSimulationInput", "GeometryNodeSimulationOutput"}


def animation_curves(id_data):
    """The F-curves that animate a datablock (its active action and its unmuted NLA strips') and its
    drivers."""
    ad = getattr(id_data, "animation_data", None)
    if not ad:
        return []
    actions = [ad.action] if ad.action else []
    for track in ad.nla_tracks:
        if not track.mute:
            actions += [strip.action for strip in track.strips if strip.action and not strip.mute]
    return [fc for action in actions for fc in action.fcurves] + list(ad.drivers)


def _animated(id_data):
    """True if a datablock has keyframes (its action or NLA strips) or drivers (a driver can read the
    frame, #frame)."""
    return bool(animation_curves(id_data))


def _animated_paths(id_data):
    """The data paths of a datablock's keyframes (active action and NLA strips) and drivers."""
    return [fc.data_path for fc in animation_curves(id_data)]


def _escaped(name):
    """A name as Blender writes it inside the quotes of a data path (quotes and backslashes escaped)."""
    return name.replace("\\", "\\\\").replace('"', '\\"')


def _path_of_modifier(name, collection="modifiers"):
    """The data path of modifier `name` of an object's `collection` (modifiers, grease_pencil_modifiers)
    as Blender writes it in an F-curve."""
    return '%s["%s"]' % (collection, _escaped(name))


def _node_tree_varies(tree, seen):
    """True if a node tree (or a group inside it) reads the time or is animated."""
    if tree is None or tree.name in seen:
        return False
    seen.add(tree.name)
    if _animated(tree):
        return True
    for node in tree.nodes:
        if node.bl_idname in TIME_NODES or _node_tree_varies(getattr(node, "node_tree", None), seen):
            return True
    return False


# Modifiers that deform or simulate by themselves (time, a cache, a simulation that needs the frames
# before the range): flagged without measuring, since stepping through the range may not reproduce them.
SELF_DEFORMING = {"CLOTH", "SOFT_BODY", "OCEAN", "WAVE", "DYNAMIC_PAINT", "FLUID", "MESH_CACHE",
                  "MESH_SEQUENCE_CACHE", "EXPLODE", "PARTICLE_SYSTEM"}


def _static_hair(m):
    """A particle system of static hair: rendered strands that follow the emitter, nothing more."""
    system = getattr(m, "particle_system", None)
    return (system is not None and system.settings.type == "HAIR" and not system.use_hair_dynamics)


# Grease pencil modifiers that vary with the frame by themselves.
GP_SELF_VARYING = {"GP_NOISE", "GP_BUILD", "GP_TIME"}


def _grease_pencil_varies(ob):
    """A grease pencil object drawn differently over time: several drawings (frames) in a layer, a
    modifier that varies by itself (GP_SELF_VARYING) or follows another object (a hook, a lattice, an
    armature), or a modifier or shader effect whose settings are animated. Grease pencil is not
    measured (_geometry_fingerprint), so these are judged by their settings."""
    if any(len(layer.frames) > 1 for layer in getattr(ob.data, "layers", ())):
        return True
    paths = _animated_paths(ob)
    for m in getattr(ob, "grease_pencil_modifiers", ()):
        if not m.show_render:
            continue
        if m.type in GP_SELF_VARYING or _reads_other_data(m):
            return True
        if any(p.startswith(_path_of_modifier(m.name, "grease_pencil_modifiers")) for p in paths):
            return True
    return any(p.startswith('shader_effects[') for p in paths)


def _deforms(ob):
    """True if, by its settings alone, the object's geometry can change over time (not covered by rigid
    reconstruction; scene_facts also measures the evaluated geometry over the frames, which finds an
    armature's pose, a hook's or a lattice's control object and the like): animated mesh data or shape
    keys (keyframes, NLA strips or drivers), a modifier that deforms or simulates by itself
    (SELF_DEFORMING) or whose settings are animated, Geometry Nodes that read the time or are animated,
    grease pencil drawn differently over time. Modifiers off in renders do not count."""
    data = getattr(ob, "data", None)
    if data is not None and _animated(data):
        return True
    keys = getattr(data, "shape_keys", None)
    if keys is not None and _animated(keys):
        return True
    if ob.type == "GPENCIL" and _grease_pencil_varies(ob):
        return True
    animated_paths = _animated_paths(ob)
    for m in getattr(ob, "modifiers", []):
        if not getattr(m, "show_render", True):
            continue
        if m.type in SELF_DEFORMING and not _static_hair(m):
            return True
        path = _path_of_modifier(m.name)
        if any(p.startswith(path) for p in animated_paths):
            return True
        if m.type == "NODES" and _node_tree_varies(getattr(m, "node_group", None), set()):
            return True
    return False


def geometry_record(ob, depsgraph):
    """What a sidecar says of an object's geometry, for `crisp filter` to tell a still pair of frames
    from one where it deforms (io/sidecar.h): {"geometry": digest of the evaluated vertices} for an
    object that may deform and can be measured, {"deforms": True} for one whose settings make it deform
    but which cannot be measured (grease pencil, volumes, hair curves), else nothing."""
    static = _deforms(ob)
    if static or _may_deform(ob):
        fp = _geometry_fingerprint(ob, depsgraph)
        if fp is not None:
            return {"geometry": fp.hex()}
    return {"deforms": True} if static else {}


def _same(a, b, eps=1e-6, rows=range(4)):
    return all(abs(a[i][j] - b[i][j]) <= eps for i in rows for j in range(4))


def render_size(scene):
    """The rendered image's size in pixels (resolution times its percentage)."""
    r = scene.render
    return (int(r.resolution_x * r.resolution_percentage / 100), int(r.resolution_y * r.resolution_percentage / 100))


# Rows of a projection matrix that place a point on the image: x, y and w (row 2 carries depth, and
# clip_start / clip_end with it, which move no pixel).
IMAGE_ROWS = (0, 1, 3)


def camera_projection(cam, depsgraph, scene):
    """The camera's projection at the render size: the lens, sensor, shift, orthographic scale and
    camera type in one matrix, so that a zoom or an animated shift counts as camera motion."""
    w, h = render_size(scene)
    m = cam.calc_matrix_camera(depsgraph, x=w, y=h, scale_x=scene.render.pixel_aspect_x,
                               scale_y=scene.render.pixel_aspect_y)
    return [list(r) for r in m]


# Object types whose evaluated geometry _geometry_fingerprint reads: meshes as evaluated, and the
# types Blender turns into a mesh to render them (to_mesh).
MESH_TYPES = {"CURVE", "SURFACE", "FONT", "META"}


def _reads_other_data(modifier):
    """True for Geometry Nodes, and for a modifier that points at another datablock (a hook's or a
    lattice's object, a displacement's texture): what it makes can change while its settings do not."""
    if modifier.type == "NODES":
        return True
    for prop in modifier.bl_rna.properties:
        if prop.type == "POINTER" and hasattr(getattr(modifier, prop.identifier, None), "users"):  # an ID
            return True
    return False


def _may_deform(ob):
    """True if the object's evaluated geometry can change with nothing of its own animated (what
    _deforms does not see): a modifier that reads other data, or a type evaluated into a mesh (a curve's
    bevel object, a metaball's other elements). A subdivision or a bevel alone is not measured."""
    return ob.type in MESH_TYPES or any(_reads_other_data(m) for m in getattr(ob, "modifiers", ()))


def _geometry_fingerprint(ob, depsgraph):
    """A digest of the object's evaluated vertex positions (object space) and count, or None for a type
    it does not read (volumes, point clouds, hair curves, grease pencil: left to _deforms)."""
    try:
        ob_eval = ob.evaluated_get(depsgraph)
    except (RuntimeError, ReferenceError):
        return None
    if ob_eval.type == "MESH":
        mesh, cleared = ob_eval.data, None
    elif ob_eval.type in MESH_TYPES:
        mesh, cleared = ob_eval.to_mesh(), ob_eval
    else:
        return None
    try:
        if mesh is None:
            return b""
        co = array("f", bytes(12 * len(mesh.vertices)))
        mesh.vertices.foreach_get("co", co)
        return hashlib.blake2b(co.tobytes() + len(co).to_bytes(8, "little"), digest_size=16).digest()
    finally:
        if cleared is not None:
            cleared.to_mesh_clear()


def rendered_instances(layer):
    """The instanced objects that render (a collection instance, instancing by vertices or faces,
    geometry nodes instances), as [(source object, instancer name, matrix_world as lists)], from
    the layer's depsgraph at the current frame. Cryptomatte names an instance by its source object, so
    instances of one source share one object ID."""
    rendered = {ob.as_pointer() for ob, _, r in _layer_objects(layer) if r}
    out = []
    for inst in layer.depsgraph.object_instances:
        if not inst.is_instance or inst.parent is None:
            continue
        source, parent = inst.object.original, inst.parent.original
        if source.type not in RENDERABLE_TYPES or source.hide_render or parent.hide_render:
            continue
        if parent.as_pointer() not in rendered:
            continue
        out.append((source, parent.name, [list(r) for r in inst.matrix_world]))
    return out


def show_in_viewport(scene, layer):
    """Unhides in the viewport (object eye and monitor icons, collection eye and monitor icons) what
    renders in the layer and its background sets; returns the calls that hide each again."""
    undo = []
    for _, set_layer in render_layers(layer):
        for lc in _rendering_layer_collections(set_layer):
            if lc.hide_viewport:
                lc.hide_viewport = False
                undo.append(lambda lc=lc: setattr(lc, "hide_viewport", True))
            if lc.collection.hide_viewport:
                lc.collection.hide_viewport = False
                undo.append(lambda c=lc.collection: setattr(c, "hide_viewport", True))
    for ob, own_layer, rendered in _layer_objects(layer):  # every type: an empty instancing a collection too
        if ob.hide_render or not rendered:
            continue
        if ob.hide_viewport:
            ob.hide_viewport = False
            undo.append(lambda ob=ob: setattr(ob, "hide_viewport", True))
        if ob.hide_get(view_layer=own_layer):
            ob.hide_set(False, view_layer=own_layer)
            undo.append(lambda ob=ob, l=own_layer: ob.hide_set(True, view_layer=l))
        _show_instanced(ob, undo, set())
    return undo


def show_render_modifiers(scene):
    """Shows in the viewport, for the measure of scene_facts and the sidecars' digests, the modifiers
    as renders show them: switches on those shown in renders only that read other data
    (_reads_other_data: an armature, a hook, a lattice...; a heavy subdivision kept off in the viewport
    stays off), and off those shown in the viewport only (a hook off in renders reshapes nothing that
    renders); returns the calls that switch each back."""
    undo = []
    for ob in {o.as_pointer(): o for s in scenes_with_sets(scene) for o in s.objects}.values():
        if ob.type not in RENDERABLE_TYPES or ob.hide_render:
            continue
        for m in getattr(ob, "modifiers", ()):
            if m.show_render and not m.show_viewport and _reads_other_data(m):
                m.show_viewport = True
                undo.append(lambda m=m: setattr(m, "show_viewport", False))
            elif m.show_viewport and not m.show_render:
                m.show_viewport = False
                undo.append(lambda m=m: setattr(m, "show_viewport", True))
    return undo


def _show_instanced(instancer, undo, seen):
    """The monitor icons inside a collection an object instances (an asset hidden in the viewport for
    speed still renders through its instancer): collections and objects that render, nested instances
    too; `seen` guards against a collection met twice."""
    collection = instancer.instance_collection if instancer.instance_type == "COLLECTION" else None
    if collection is None:
        return

    def walk(c):
        if c.name in seen or c.hide_render:
            return
        seen.add(c.name)
        if c.hide_viewport:
            c.hide_viewport = False
            undo.append(lambda c=c: setattr(c, "hide_viewport", True))
        for ob in c.objects:
            if ob.hide_render:
                continue
            if ob.hide_viewport:
                ob.hide_viewport = False
                undo.append(lambda ob=ob: setattr(ob, "hide_viewport", True))
            if ob.instance_type == "COLLECTION" and ob.instance_collection is not None:
                walk(ob.instance_collection)
        for child in c.children:
            walk(child)

    walk(collection)


# Animated object properties that scene_facts sees otherwise: as motion (the world matrix: transforms,
# constraints, parenting), as deformation (modifiers, a pose, custom properties that drive them) or as
# a change of what renders (hide_render); not named again as a change of the image.
OBJECT_MOTION_PATHS = {"location", "rotation_euler", "rotation_quaternion", "rotation_axis_angle", "scale",
                       "delta_location", "delta_rotation_euler", "delta_rotation_quaternion", "delta_scale",
                       "hide_render", "hide_viewport"}
OBJECT_MOTION_PREFIXES = ("modifiers[", "constraints[", "pose.", "grease_pencil_modifiers[", "shader_effects[", "[")

# Image sources that show another picture on each frame.
MOVING_IMAGE_SOURCES = {"SEQUENCE", "MOVIE"}


def _label(kind, id_data):
    return "%s '%s'" % (kind, id_data.name)


def rendered_lights(layer):
    """The light objects that light the layer's render (and its background sets'), not hidden from it."""
    return [ob for ob, _, rendered in _layer_objects(layer) if rendered and ob.type == "LIGHT" and not ob.hide_render]


def _node_trees(tree, seen):
    """A node tree and the groups inside it, each once."""
    if tree is None or tree.as_pointer() in seen:
        return
    seen.add(tree.as_pointer())
    yield tree
    for node in tree.nodes:
        yield from _node_trees(getattr(node, "node_tree", None), seen)


def shading_ids(scene, objects, lights):
    """(label, datablock) of what shades the render besides geometry: the scene's own settings (and its
    background sets'), its world, the rendered objects and their materials, the lights and their data,
    the camera's data (depth of field), each with the node trees inside (a keyed Mapping node is
    animation of the material's node tree, not of the material)."""
    out, seen = [], set()

    def add(label, id_data, trees=True):
        if id_data is None or id_data.as_pointer() in seen:
            return
        seen.add(id_data.as_pointer())
        out.append((label, id_data))
        for tree in _node_trees(getattr(id_data, "node_tree", None) if trees else None, seen):
            out.append((label, tree))

    for s in scenes_with_sets(scene):
        # Not its node tree: the compositor works on the render after Crisp's filters (and shows Crisp's
        # own results as an image sequence).
        add(_label("scene", s), s, trees=False)
        if s.world is not None:
            add(_label("world", s.world), s.world)
    if scene.camera is not None:
        add(_label("camera", scene.camera), scene.camera.data)
    for ob in lights:
        add(_label("light", ob), ob)
        add(_label("light", ob), ob.data)
    for ob in objects:
        add(_label("object", ob), ob)
        for slot in getattr(ob, "material_slots", ()):
            if slot.material is not None:
                add(_label("material", slot.material), slot.material)
    return out


def _comparable(value):
    """A property's value as something == compares (arrays as tuples), floats to 6 places."""
    if isinstance(value, str):
        return value
    try:
        return tuple(_comparable(v) for v in value)
    except TypeError:
        return round(value, 6) if isinstance(value, float) else value


def animated_values(id_data):
    """{data path: value} of a datablock's animated properties (keyframes, NLA strips, drivers) as the
    current frame evaluates them; an object's that scene_facts sees as motion are left out, and of a
    camera's data all but its depth of field (its projection is motion; its clipping changes the image
    only where geometry crosses it)."""
    is_object = hasattr(id_data, "matrix_world")
    is_camera = hasattr(id_data, "lens")
    out = {}
    for path in _animated_paths(id_data):
        if path in out or is_object and (path in OBJECT_MOTION_PATHS or path.startswith(OBJECT_MOTION_PREFIXES)):
            continue
        if is_camera and not path.startswith("dof."):
            continue
        try:
            out[path] = _comparable(id_data.path_resolve(path))
        except (ValueError, AttributeError, TypeError):  # a curve whose property no longer exists
            continue
    return out


def moving_images(shading):
    """Labels of the image sequences and movies that the node trees of `shading` (shading_ids) show:
    another picture on each frame."""
    out = set()
    for _, id_data in shading:
        for node in getattr(id_data, "nodes", ()):
            image = getattr(node, "image", None)
            if image is not None and getattr(image, "source", None) in MOVING_IMAGE_SOURCES:
                out.add(_label("image", image))
    return out


def scene_facts(scene, frame_start, frame_end, view_layer=None, renderer_motion_pass=False):
    """Steps through the frame range and compares world matrices with the first frame's (each camera's
    with its own, and its projection: a zoom or an animated shift moves the picture; a switch of cameras
    at a timeline marker is a cut, listed in camera_cuts, where temporal history restarts; FrameFilter
    and `crisp filter` see it in the sidecars), and the evaluated geometry of what may deform with the
    first frame's.

    Restores the current frame and camera. Checks matrices and geometry (not only animation data) so
    constraints, drivers, parenting and control objects count too. Modifiers are measured as renders
    show them (show_render_modifiers)."""
    layer = view_layer or scene.view_layers[0]
    saved = (scene.frame_current, scene.frame_subframe, scene.camera)
    first_cam = {}  # camera object's full name -> its matrix and projection at the first frame it is the scene's camera
    first, moving, names, named, cuts = {}, set(), [], set(), []
    first_geometry, deforming = {}, set()  # object name -> _geometry_fingerprint at the first frame; deforming
    shared = set()  # names that render more than once on a frame (instances, instanced and visible itself, or
    # objects of one name from different files)
    instances = []  # the last frame's (rendered_instances)
    camera_moves = False
    previous_cam = None
    # What changes the image with no geometry moving: label -> the frames where it differs from the frame
    # before; the last frame's values of each animated property by (label, path), rendered objects and
    # lights, and lights' matrices; what shows another picture on every frame (image sequences).
    changed_at, last_values, last_rendered, last_light, every_frame = collections.defaultdict(set), {}, None, {}, set()
    shown = []
    try:
        # What is hidden in the viewport alone still renders, but the viewport's depsgraph does not
        # evaluate it (its matrix_world would not follow the frames): shown while stepping, then hidden
        # again; modifiers as renders show them.
        shown += show_in_viewport(scene, layer)
        shown += show_render_modifiers(scene)
        for f in range(frame_start, frame_end + 1):
            scene.frame_set(f)  # switches scene.camera at timeline markers bound to cameras
            cam = scene.camera
            cam_key = cam.name_full if cam else None  # by full name: a linked camera may have a local one's name
            if f > frame_start and cam_key != previous_cam:
                cuts.append(f)
            previous_cam = cam_key
            obs = visible_objects(scene, layer)
            instances = rendered_instances(layer)
            lights = rendered_lights(layer)
            rendered_now = {o.name_full: o.name for o in obs + lights}
            for _, name in rendered_now.items() ^ (last_rendered or rendered_now).items():
                changed_at["visibility of '%s'" % name].add(f)
            last_rendered = rendered_now
            for o in lights:  # a light that moves moves the shading, not the pixels
                m = [list(r) for r in o.matrix_world]
                if o.name_full in last_light and not _same(m, last_light[o.name_full]):
                    changed_at[_label("light", o)].add(f)
                last_light[o.name_full] = m
            shading = shading_ids(scene, obs, lights)
            every_frame.update(moving_images(shading))
            for label, id_data in shading:
                for path, value in animated_values(id_data).items():
                    if last_values.get((label, path), value) != value:
                        changed_at[label].add(f)
                    last_values[(label, path)] = value
            # Over every frame: an object that appears later (hide_render keyed) renders there too, and
            # rsaa renders geometry only where something is visible.
            # Each object once (by its full name), listed by name: a linked object and a local one of the
            # same name are two.
            for key, name in ([(o.name_full, o.name) for o in obs]
                              + sorted({(source.name_full, source.name) for source, _, _ in instances})):
                if key not in named:  # a set: a list's `in` would cost objects x objects per frame
                    named.add(key)
                    names.append(name)
            if cam is not None:
                cm = ([list(r) for r in cam.matrix_world], camera_projection(cam, layer.depsgraph, scene))
                if cam_key not in first_cam:
                    first_cam[cam_key] = cm
                elif not (_same(cm[0], first_cam[cam_key][0]) and _same(cm[1], first_cam[cam_key][1], rows=IMAGE_ROWS)):
                    camera_moves = True
            # Each object by its full name (a linked object may have a local one's name), each fact by its
            # name, as Cryptomatte's IDs are (hashing.cryptomatte_hex).
            for o in obs:
                m = [list(r) for r in o.matrix_world]
                if o.name_full not in first:
                    first[o.name_full] = m
                elif not _same(m, first[o.name_full]):
                    moving.add(o.name)
            # Geometry that changes with no animation of its own (a hook or lattice whose control object
            # moves, Geometry Nodes reading another object): measured, as the matrices are.
            # Each frame's visible objects: one hidden from the render on later frames deforms on earlier ones.
            # A source is measured once per frame, however many times it is instanced.
            measured = {o.name_full: o for o in obs}
            for source, _, _ in instances:
                measured.setdefault(source.name_full, source)
            for key, o in measured.items():
                if o.name in deforming:
                    continue
                if _deforms(o):
                    deforming.add(o.name)
                    continue
                fp = _geometry_fingerprint(o, layer.depsgraph) if _may_deform(o) else None
                if fp is None:
                    continue
                if key not in first_geometry:
                    first_geometry[key] = fp
                elif fp != first_geometry[key]:
                    deforming.add(o.name)
            # Cryptomatte names an instance by its source: how often each such ID renders on this frame.
            # So are objects of one name (a linked object and a local one of the same name).
            renders = collections.Counter(o.name for o in obs)
            renders.update(source.name for source, _, _ in instances)
            shared.update(name for name, n in renders.items() if n > 1)
            seen = {}  # an instance is told from the others of its source and instancer by its order
            for source, parent, m in instances:
                key = (source.name, parent, seen.setdefault((source.name, parent), 0))
                seen[(source.name, parent)] += 1
                if key not in first:
                    first[key] = m
                elif not _same(m, first[key]):
                    moving.add(source.name)
    finally:
        for restore in reversed(shown):
            restore()
        scene.frame_set(saved[0], subframe=saved[1])
        scene.camera = saved[2]
    if camera_moves:  # its animated lens or shift is motion, already said
        changed_at = {c: at for c, at in changed_at.items() if not c.startswith("camera ")}
    # A change on a few frames (a light switched on, an object popping in) is a step, which the filters'
    # hold release takes in (temporal/hold_release.h) while still pixels keep their average; one that
    # goes on, on most frames (a scrolling texture, a moving light, a sequence), would leave that average
    # behind.
    going_on = every_frame | {c for c, at in changed_at.items() if 2 * len(at) > frame_end - frame_start}
    stepped = {c: at for c, at in changed_at.items() if c not in going_on}
    return SceneFacts(frame_start=frame_start, frame_end=frame_end, camera_moves=camera_moves,
                      moving_objects=sorted(moving), deforming_objects=sorted(deforming),
                      visible_objects=names, renderer_motion_pass=renderer_motion_pass, camera_cuts=cuts,
                      shared_id_movers=sorted(shared & (moving | deforming)), image_changes=sorted(going_on),
                      image_steps=["%s (frame %s)" % (c, ", ".join(map(str, sorted(at)))) for c, at in sorted(stepped.items())])
