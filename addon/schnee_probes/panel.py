"""3D Viewport > Sidebar (N) > Schnee Engine: the bake buttons, the settings and the last result."""
import os

import bpy

from .operators import _draw_settings


class VIEW3D_PT_schnee_probes(bpy.types.Panel):
    bl_label = "SH Probes"
    bl_idname = "VIEW3D_PT_schnee_probes"
    bl_space_type = 'VIEW_3D'
    bl_region_type = 'UI'
    bl_category = "Schnee Engine"

    def draw(self, context):
        layout = self.layout
        props = context.scene.schnee_probes
        col = layout.column(align=True)
        col.scale_y = 1.3
        col.operator("schnee.bake_sh_volumes", icon='LIGHTPROBE_GRID')
        col.operator("schnee.bake_sh_cursor", icon='PIVOT_CURSOR')
        layout.use_property_split = True
        layout.use_property_decorate = False
        _draw_settings(layout, props)


class VIEW3D_PT_schnee_probes_last(bpy.types.Panel):
    bl_label = "Last Bake"
    bl_idname = "VIEW3D_PT_schnee_probes_last"
    bl_space_type = 'VIEW_3D'
    bl_region_type = 'UI'
    bl_category = "Schnee Engine"
    bl_parent_id = "VIEW3D_PT_schnee_probes"

    def draw(self, context):
        props = context.scene.schnee_probes
        col = self.layout.column(align=True)
        if not props.last_message:
            col.label(text="No bake yet")
            return
        col.label(text=f"Probes: {props.last_probe_count}")
        col.label(text=f"Time: {props.last_seconds:.1f} s")
        for path in filter(None, props.last_files.split(";")):
            col.label(text=os.path.basename(path), icon='FILE')
        col.label(text=props.last_message)


classes = (VIEW3D_PT_schnee_probes, VIEW3D_PT_schnee_probes_last)

register, unregister = bpy.utils.register_classes_factory(classes)
