# SPDX-License-Identifier: GPL-2.0-or-later
"""Scene settings (scene.crisp): method, its parameters, references, output.

Each method's parameters are built at registration from the library's own table
(crispGetFilterInfo): same names, types, defaults and ranges as `crisp help METHOD`. Only values that
differ from the default are sent."""

import zlib

import bpy

from . import native
from . import plan as plan_mod

STATIC_METHODS = list(plan_mod.METHOD_PASSES)
_DESCRIPTIONS = {
    "none": "No filtering (the 1-sample baseline)",
    "fxaa": "FXAA 3.11 quality (spatial)",
    "repair": "REPAIR rotated spatial filtering (spatial)",
    "taa": "Temporal anti-aliasing baseline (temporal, jittered)",
    "taa-improved": "Improved TAA with aliasedValue (temporal, jittered)",
    "phlm": "Pixel history linear models (temporal, jittered)",
    "rsaa": "Resampling AA from geometric sub-samples (spatial)",
}
# The number a .blend stores for each method. Blender keeps an enum as a number, which for an item without
# one (the 4th field) is its position in the list: the list is the library's, so a method inserted or
# moved there changed the method of every saved file after it (taa-improved, put before phlm, turned
# files' phlm into taa-improved and rsaa into phlm). The numbers are the positions the list has had since
# then, so files saved since keep their method; a new method takes a new number, never one in use.
METHOD_NUMBERS = {"none": 0, "fxaa": 1, "repair": 2, "taa": 3, "taa-improved": 4, "phlm": 5, "rsaa": 6}
_enum_cache = []  # Blender needs the item strings kept alive


def name_number(name):
    """The number of an enum item the add-on has no fixed number for: from its name, so the same wherever
    it sits in the library's list, and at least 1000, above every fixed one."""
    return 1000 + zlib.crc32(name.encode("utf-8")) % 1000000


def method_number(name):
    """The number a .blend stores for a method: METHOD_NUMBERS, or for a method of a newer library that
    this add-on does not know one from its name (the same wherever it sits in the library's list)."""
    if name in METHOD_NUMBERS:
        return METHOD_NUMBERS[name]
    return name_number(name)


def method_items(self, context):
    try:
        names = native.filter_types()
    except native.CrispError:
        names = STATIC_METHODS
    items = [(n, n, _DESCRIPTIONS.get(n, n), method_number(n)) for n in names]
    _enum_cache[:] = items
    return _enum_cache


# rsaa's camera, which each frame's sidecar gives (native/io/subsamples.h rsaaCameraParamNames; the
# CLI refuses them in --set, and FrameFilter sets them from the sidecar, replacing a panel value).
RSAA_CAMERA_PARAMS = {"orthographic", "proj00", "proj11", "proj02", "proj12"} | {
    "view%d%d" % (r, c) for r in range(3) for c in range(3)}
# Parameters the pipeline sets itself (per frame, or filterSize from the scene's Film > Filter Size:
# pipeline.with_scene_filter_size) or that only tests use: not shown to artists.
PIPELINE_PARAMS = {"jitterX", "jitterY", "filterSize", "reference"} | RSAA_CAMERA_PARAMS


# The same for the choices of the methods' string parameters ("a|b|c" in the library's tables): their
# numbers were their positions in the library's lists, so a choice inserted or moved there would change
# the choice of every saved file after it. Each choice below keeps the number of its position in these
# lists, the library's own when they were fixed (so files saved before hold the same numbers); a choice of
# a newer library takes a number from its name (choice_numbers). Never change or reorder these lists.
_UNJITTER = ("blackman-harris", "nearest", "none")  # native/temporal/jitter.cpp, shared by the temporal ones
_JITTER_WEIGHTING = ("none", "blackman-harris")
_TAA_CHOICES = {"historyFilter": ("catmull-rom", "bilinear"), "clipSpace": ("rgb", "ycocg"),
                "jitterWeighting": _JITTER_WEIGHTING, "unjitter": _UNJITTER}
CHOICE_NUMBERS = {
    "repair": {"mask": ("gauss5", "box3"), "angleEstimator": ("regression", "thesis")},
    "taa": _TAA_CHOICES,
    "taa-improved": _TAA_CHOICES,
    "phlm": {"modelFetch": ("catmull-rom", "bilinear", "nearest"), "jitterWeighting": _JITTER_WEIGHTING,
             "unjitter": _UNJITTER},
    "rsaa": {"verification": ("halve", "reassign", "none"), "textureAA": ("fxaa", "none")},
}


def choice_numbers(method, param, choices):
    """{choice: number a .blend stores} for the library's choices of a method's string parameter: its
    position in CHOICE_NUMBERS, or for a choice those lists lack (of a newer library) one from its name,
    never one of the recorded positions (below 1000) nor another choice's (the rare clash of two new
    names moves the later one in name order up to the next free number)."""
    recorded = CHOICE_NUMBERS.get(method, {}).get(param, ())
    numbers = {c: recorded.index(c) for c in choices if c in recorded}
    taken = set(numbers.values())
    for c in sorted(c for c in choices if c not in recorded):
        n = name_number(c)
        while n in taken:
            n += 1
        numbers[c] = n
        taken.add(n)
    return numbers


def saved_choice(method, param, number):
    """The choice a .blend's number stands for (CHOICE_NUMBERS), or None: a choice of a newer library."""
    recorded = CHOICE_NUMBERS.get(method, {}).get(param, ())
    return recorded[number] if 0 <= number < len(recorded) else None


def group_name(method):
    """Attribute of scene.crisp holding a method's parameters."""
    return method.replace("-", "_")


def _precision(spec):
    """Decimals the panel shows of a float parameter: 4, or as many as its default and limits need (up
    to Blender's 6), so that phlm's lambda at its largest, 0.99999, does not read 1.0000."""
    for digits in range(4, 7):
        if all(abs(round(float(spec[k]), digits) - float(spec[k])) < 1e-9 for k in ("default", "min", "max")):
            return digits
    return 6


def _property_for(method, spec):
    """A bpy property built from one row of a method's parameter table (crispGetFilterInfo)."""
    desc = (spec.get("meaning") or "") + (" [" + spec["source"] + "]" if spec.get("source") else "")
    name, kind = spec["name"], spec["type"]
    if kind == "bool":
        return bpy.props.BoolProperty(name=name, default=bool(spec["default"]), description=desc)
    if kind == "int":
        return bpy.props.IntProperty(name=name, default=int(spec["default"]), min=int(spec["min"]),
                                     max=int(spec["max"]), description=desc)
    if kind == "float":
        return bpy.props.FloatProperty(name=name, default=float(spec["default"]), min=float(spec["min"]),
                                       max=float(spec["max"]), description=desc, precision=_precision(spec))
    numbers = choice_numbers(method, name, spec["choices"])
    items = [(c, c, "", numbers[c]) for c in spec["choices"]]
    return bpy.props.EnumProperty(name=name, items=items, default=spec["default"], description=desc)


def _library_param_groups():
    """{method: PropertyGroup class} built from the loaded library's own tables, so names, defaults and
    ranges can never drift from the code. Empty when the library cannot load (the panel says why)."""
    try:
        methods = native.filter_types()
        infos = {m: native.filter_info(m) for m in methods}
    except native.CrispError:
        return {}
    groups = {}
    for method, info in infos.items():
        annotations = {p["name"]: _property_for(method, p) for p in info["params"]
                       if p["name"] not in PIPELINE_PARAMS}
        if annotations:
            groups[method] = type("CrispParams_" + group_name(method), (bpy.types.PropertyGroup,),
                                  {"__annotations__": annotations})
    return groups


_param_classes = {}  # method -> registered PropertyGroup class
_groups_built = False  # whether _param_classes came from a loaded library (else it could not load)


def param_group(settings, method):
    """The PropertyGroup holding a method's parameters, or None (no parameters / no library)."""
    return getattr(settings, group_name(method), None) if method in _param_classes else None


def param_value(group, method, ident):
    """The value of a method's parameter as the renders and the viewport preview send it. A choice a
    saved file holds that this library no longer offers reads "" in Blender (its number matches no item;
    the file keeps the number, so an add-on and library that offer it again show it again): it is given
    by its name (saved_choice), which the library refuses by name ("'ycocg' is not one of: rgb") rather
    than a filter taking another choice. One of a newer library, which this add-on cannot name, is sent
    as "newer-crisp-choice-N" (no spaces: `--set` texts split on them), for the same refusal."""
    value = getattr(group, ident)
    if value == "" and group.bl_rna.properties[ident].type == "ENUM" and group.get(ident) is not None:
        number = group.get(ident)
        # A newer library's choice: this add-on cannot name it, so it says what it is rather than "".
        value = saved_choice(method, ident, number) or "newer-crisp-choice-%d" % number
    return value


def changed_params(settings, method):
    """{library name: value} of the parameters that differ from the library's defaults (param_value:
    a saved choice the library no longer offers by its name, refused before a run)."""
    group = param_group(settings, method)
    out = {}
    if group is None:
        return out
    for prop in group.bl_rna.properties:
        ident = prop.identifier
        if ident in ("rna_type", "name"):
            continue
        value = param_value(group, method, ident)
        default = prop.default
        if isinstance(value, float) and abs(value - default) < 1e-7:
            continue
        if value == default:
            continue
        out[ident] = value
    return out


def set_params_text(settings, method):
    """changed_params as `crisp render --set` takes them: "KEY=VALUE KEY=VALUE", empty when every
    parameter is the library's default (the Flamenco job type crisp-render reads it at submission)."""
    return " ".join("%s=%s" % (k, native.param_text(v)) for k, v in changed_params(settings, method).items())


class CrispSettings(bpy.types.PropertyGroup):
    method: bpy.props.EnumProperty(name="Method", items=method_items,
                                   description="Anti-aliasing filter (from the loaded library's list)")
    reference_samples: bpy.props.IntProperty(name="Reference samples", default=256, min=1, max=65536,
                                             description="EEVEE samples of the reference frames (>= 256 for final figures)")
    output_dir: bpy.props.StringProperty(
        name="Output", subtype="DIR_PATH", default="",
        description="Folder of this scene's frames; empty: //crisp/<scene name>/ beside the .blend file (set here "
                    "on the first render, so the scene keeps it when renamed and two scenes never share one)")
    output_pinned: bpy.props.StringProperty(options={"HIDDEN"}, description="The Output Crisp set itself "
                                            "(output_folder.py); empty or other: the user's")
    jitter_distribution: bpy.props.EnumProperty(  # numbers fixed, as METHOD_NUMBERS
        name="Jitter", items=[("blackman-harris", "Blackman-Harris", "EEVEE's own sample distribution", 0),
                              ("uniform", "Uniform", "Halton points inside the pixel", 1)])
    input_codec: bpy.props.EnumProperty(  # identifiers render.INPUT_CODECS; numbers fixed, as METHOD_NUMBERS
        name="Input Codec", description="How the 1-sample renders kept in input/ (and reference/) are stored; "
        "all lossless, so the filtered frames are the same with each",
        items=[("none", "None", "Uncompressed: the fastest to save and read (about 41 MB a 1920x1080 frame with "
                "colour and depth)", 0),
               ("piz", "PIZ", "About 4.5x smaller; about 0.1 s more to save and 0.06 s more to read a 1920x1080 "
                "frame", 1),
               ("zip", "ZIP", "About 4.7x smaller; about 0.17 s more to save and 0.05 s more to read a 1920x1080 "
                "frame", 2)])
    write_png: bpy.props.BoolProperty(name="Also write PNG", default=True)
    load_result: bpy.props.BoolProperty(name="Load into compositor", default=True)
    plan_text: bpy.props.StringProperty(name="Plan", default="")
    last_psnr: bpy.props.FloatProperty(name="PSNR", default=0.0)
    last_ssim: bpy.props.FloatProperty(name="SSIM", default=0.0)
    last_compare: bpy.props.StringProperty(name="Last comparison", default="")

    def set_params_text(self):
        """This panel's parameters of its method, as `crisp render --set` takes them (set_params_text):
        the Flamenco job type's filter_params evaluates scene.crisp.set_params_text()."""
        return set_params_text(self, self.method)


def _library_loaded():
    try:
        native.load()
    except native.CrispError:
        return False
    return True


def register():
    global _groups_built
    _param_classes.clear()
    _param_classes.update(_library_param_groups())
    _groups_built = _library_loaded()
    for cls in _param_classes.values():
        bpy.utils.register_class(cls)
    # One pointer per method with parameters, added before CrispSettings is registered.
    for method, cls in _param_classes.items():
        CrispSettings.__annotations__[group_name(method)] = bpy.props.PointerProperty(type=cls)
    bpy.utils.register_class(CrispSettings)
    bpy.types.Scene.crisp = bpy.props.PointerProperty(type=CrispSettings)


def param_groups_missing():
    """Whether the methods' settings wait for the library: registered without one, which loads now."""
    return CrispSettings.is_registered and not _groups_built and native._lib is not None


def add_param_groups():
    """The methods' settings, when the add-on was registered without a library that loads now (its path
    given in the preferences, or built since): added to the registered scene settings, so the panel shows
    them and a run sends them (without them every run took the defaults until the add-on was enabled
    again). Values a scene kept from an earlier session come back with them. Returns None (a timer)."""
    global _groups_built
    if not CrispSettings.is_registered or _groups_built or not _library_loaded():
        return None
    groups = _library_param_groups()
    _groups_built = True
    for method, cls in groups.items():
        bpy.utils.register_class(cls)
        _param_classes[method] = cls
        pointer = bpy.props.PointerProperty(type=cls)
        CrispSettings.__annotations__[group_name(method)] = pointer  # unregister() takes it out again
        setattr(CrispSettings, group_name(method), pointer)  # on the registered class: the property now
    return None


def unregister():
    global _groups_built
    del bpy.types.Scene.crisp
    bpy.utils.unregister_class(CrispSettings)
    for method, cls in reversed(list(_param_classes.items())):
        CrispSettings.__annotations__.pop(group_name(method), None)
        if group_name(method) in CrispSettings.__dict__:  # added by add_param_groups
            delattr(CrispSettings, group_name(method))
        bpy.utils.unregister_class(cls)
    _param_classes.clear()
    _groups_built = False
