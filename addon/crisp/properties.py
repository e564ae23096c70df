# SPDX-License-Identifier: GPL-2.0-or-later
"""Scene settings (scene.crisp): method, its parameters, references, output.

Parameters are sent to the library only when they differ from their default here, so a library whose
filter has other defaults (or a placeholder without parameters) keeps working. LIBRARY_NAMES maps a
property to the library's parameter name (the filter's parameter table, `crisp help METHOD`)."""

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
_enum_cache = []  # Blender needs the item strings kept alive


def method_items(self, context):
    try:
        names = native.filter_types()
    except native.CrispError:
        names = STATIC_METHODS
    items = [(n, n, _DESCRIPTIONS.get(n, n)) for n in names]
    _enum_cache[:] = items
    return _enum_cache


class FxaaParams(bpy.types.PropertyGroup):
    subpix: bpy.props.FloatProperty(name="Sub-pixel", default=0.75, min=0.0, max=1.0)
    edge_threshold: bpy.props.FloatProperty(name="Edge threshold", default=0.166, min=0.0, max=1.0)
    edge_threshold_min: bpy.props.FloatProperty(name="Edge threshold min", default=0.0833, min=0.0, max=1.0)


class RepairParams(bpy.types.PropertyGroup):
    kappa: bpy.props.FloatProperty(name="Kappa", default=-1.0, min=-5.0, max=5.0,
                                   description="Edge threshold T = mean + kappa * sigma of the gradients")
    patch_size: bpy.props.IntProperty(name="Patch size", default=5, min=3, max=9)
    mask: bpy.props.EnumProperty(name="Mask", items=[("gaussian", "Gaussian 5x5", ""), ("average", "Average 3x3", "")])


class TaaParams(bpy.types.PropertyGroup):
    feedback_min: bpy.props.FloatProperty(name="Feedback min", default=0.88, min=0.0, max=1.0)
    feedback_max: bpy.props.FloatProperty(name="Feedback max", default=0.97, min=0.0, max=1.0)
    clip_space: bpy.props.EnumProperty(name="Clip space", items=[("ycocg", "YCoCg", ""), ("rgb", "RGB", "")])
    history_filter: bpy.props.EnumProperty(name="History filter", items=[("catmull-rom", "Catmull-Rom", ""),
                                                                         ("bilinear", "Bilinear", "")])
    sharpen: bpy.props.BoolProperty(name="Sharpen", default=False)


class PhlmParams(bpy.types.PropertyGroup):
    forgetting: bpy.props.FloatProperty(name="Forgetting (lambda)", default=0.998, min=0.9, max=1.0, precision=4)
    alpha_a: bpy.props.FloatProperty(name="a", default=0.125, min=0.0, max=4.0)
    alpha_b: bpy.props.FloatProperty(name="b", default=0.25, min=0.0, max=4.0)


class RsaaParams(bpy.types.PropertyGroup):
    threshold: bpy.props.FloatProperty(name="SADP threshold", default=0.1, min=0.0, max=10.0)
    verification: bpy.props.IntProperty(name="Verification mode", default=0, min=0, max=2)


PARAM_GROUPS = {"fxaa": "fxaa", "repair": "repair", "taa": "taa", "taa-improved": "taa_improved",
                "phlm": "phlm", "rsaa": "rsaa"}
# property -> library parameter name, per method (only where they differ).
LIBRARY_NAMES = {
    "fxaa": {"subpix": "subpix", "edge_threshold": "edgeThreshold", "edge_threshold_min": "edgeThresholdMin"},
    "repair": {"patch_size": "patchSize"},
    "taa": {"feedback_min": "feedbackMin", "feedback_max": "feedbackMax", "clip_space": "clipSpace",
            "history_filter": "historyFilter"},
    "taa-improved": {"feedback_min": "feedbackMin", "feedback_max": "feedbackMax", "clip_space": "clipSpace",
                     "history_filter": "historyFilter"},
    "phlm": {"forgetting": "lambda", "alpha_a": "a", "alpha_b": "b"},
    "rsaa": {},
}


def param_group(settings, method):
    name = PARAM_GROUPS.get(method)
    return getattr(settings, name) if name else None


def changed_params(settings, method):
    """{library name: value} of the parameters that differ from their defaults."""
    group = param_group(settings, method)
    out = {}
    if group is None:
        return out
    for prop in group.bl_rna.properties:
        ident = prop.identifier
        if ident in ("rna_type", "name"):
            continue
        value = getattr(group, ident)
        default = prop.default
        if isinstance(value, float) and abs(value - default) < 1e-7:
            continue
        if value == default:
            continue
        out[LIBRARY_NAMES.get(method, {}).get(ident, ident)] = value
    return out


class CrispSettings(bpy.types.PropertyGroup):
    method: bpy.props.EnumProperty(name="Method", items=method_items,
                                   description="Anti-aliasing filter (from the loaded library's list)")
    fxaa: bpy.props.PointerProperty(type=FxaaParams)
    repair: bpy.props.PointerProperty(type=RepairParams)
    taa: bpy.props.PointerProperty(type=TaaParams)
    taa_improved: bpy.props.PointerProperty(type=TaaParams)
    phlm: bpy.props.PointerProperty(type=PhlmParams)
    rsaa: bpy.props.PointerProperty(type=RsaaParams)
    reference_samples: bpy.props.IntProperty(name="Reference samples", default=256, min=1, max=65536,
                                             description="EEVEE samples of the reference frames (>= 256 for final figures)")
    output_dir: bpy.props.StringProperty(name="Output", subtype="DIR_PATH", default="//crisp/")
    jitter_distribution: bpy.props.EnumProperty(
        name="Jitter", items=[("blackman-harris", "Blackman-Harris", "EEVEE's own sample distribution"),
                              ("uniform", "Uniform", "Halton points inside the pixel")])
    write_png: bpy.props.BoolProperty(name="Also write PNG", default=True)
    load_result: bpy.props.BoolProperty(name="Load into compositor", default=True)
    plan_text: bpy.props.StringProperty(name="Plan", default="")
    last_psnr: bpy.props.FloatProperty(name="PSNR", default=0.0)
    last_ssim: bpy.props.FloatProperty(name="SSIM", default=0.0)
    last_compare: bpy.props.StringProperty(name="Last comparison", default="")


CLASSES = (FxaaParams, RepairParams, TaaParams, PhlmParams, RsaaParams, CrispSettings)


def register():
    for c in CLASSES:
        bpy.utils.register_class(c)
    bpy.types.Scene.crisp = bpy.props.PointerProperty(type=CrispSettings)


def unregister():
    del bpy.types.Scene.crisp
    for c in reversed(CLASSES):
        bpy.utils.unregister_class(c)
