# SPDX-License-Identifier: GPL-2.0-or-later
"""The Crisp panel in Render properties."""

import bpy

from . import native, output_folder
from . import plan as plan_mod
from . import properties as props


class CRISP_PT_render(bpy.types.Panel):
    bl_label = "Crisp"
    bl_space_type = "PROPERTIES"
    bl_region_type = "WINDOW"
    bl_context = "render"

    def draw(self, context):
        layout = self.layout
        s = context.scene.crisp
        ok, text = native.status()
        row = layout.row()
        row.alert = not ok
        row.label(text=text if ok else "Library: " + text, icon="CHECKMARK" if ok else "ERROR")
        if ok and props.param_groups_missing() and not bpy.app.timers.is_registered(props.add_param_groups):
            # The library loaded since the add-on was registered: its methods' settings, after this draw
            # (a draw may not register classes).
            bpy.app.timers.register(props.add_param_groups, first_interval=0.0)
        layout.prop(s, "method")
        group = props.param_group(s, s.method)
        if group is not None:
            box = layout.box()
            for p in group.bl_rna.properties:
                if p.identifier not in ("rna_type", "name"):
                    box.prop(group, p.identifier)
            if s.method in plan_mod.TEMPORAL_METHODS:  # pipeline.with_scene_filter_size
                box.label(text="filterSize: Film > Filter Size, %g px" % context.scene.render.filter_size)
        layout.prop(s, "jitter_distribution")
        layout.prop(s, "input_codec")
        layout.prop(s, "reference_samples")
        layout.prop(s, "output_dir")
        if not s.output_dir:
            layout.label(text=("Output: " + output_folder.default_out_dir(context.scene)) if bpy.data.filepath
                         else "Output: save the .blend first, or set a folder", icon="FILE_FOLDER")
        row = layout.row()
        row.prop(s, "write_png")
        row.prop(s, "load_result")
        box = layout.box()
        row = box.row()
        row.label(text="Pass plan")
        row.operator("crisp.plan", text="", icon="FILE_REFRESH")
        for line in (s.plan_text or "press refresh to plan").splitlines():
            box.label(text=line.strip())
        col = layout.column(align=True)
        sub = col.row()
        sub.enabled = ok
        sub.operator("crisp.render", icon="RENDER_ANIMATION")
        col.operator("crisp.render_reference", icon="RENDER_STILL")
        sub = col.row()
        sub.enabled = ok
        sub.operator("crisp.compare", icon="MOD_WAVE")
        row = layout.row(align=True)
        row.operator("crisp.load_result", icon="NODETREE")
        row.operator("crisp.preview", icon="IMAGE_DATA")
        if s.last_compare:
            layout.label(text=s.last_compare)


def register():
    bpy.utils.register_class(CRISP_PT_render)


def unregister():
    bpy.utils.unregister_class(CRISP_PT_render)
