"""3D Viewport > Sidebar (N) > Schnee Engine: the bake buttons, the settings, the last result and
the active lamp's light mode (baked into the probes or realtime in the engine, light_modes.py)."""
import os

import bpy

from . import bake_core, compat, journal, light_modes
from .properties import draw_estimate, draw_settings


class VIEW3D_PT_schnee_probes(bpy.types.Panel):
    bl_label = "SH Probes"
    bl_idname = "VIEW3D_PT_schnee_probes"
    bl_space_type = 'VIEW_3D'
    bl_region_type = 'UI'
    bl_category = "Schnee Engine"

    def draw(self, context):
        layout = self.layout
        props = context.scene.schnee_probes
        compat.draw_native_problem(layout)  # the bake core did not load: what is missing, what to do
        col = layout.column(align=True)
        col.scale_y = 1.3
        col.operator("schnee.bake_sh_volumes", icon='LIGHTPROBE_GRID')
        col.operator("schnee.bake_sh_cursor", icon='PIVOT_CURSOR')
        row = layout.row()
        row.operator("schnee.add_movable_diffuse", text="Movable Diffuse Material", icon='NODE_MATERIAL')
        layout.use_property_split = True
        layout.use_property_decorate = False
        draw_settings(layout, props)
        draw_estimate(layout, context.scene, props)
        _draw_journal(layout, props)


def _draw_journal(layout, props):
    """A bake that was cancelled, failed or crashed left a journal next to the output: say that
    Bake SH in Volumes resumes it (journal.py; the header and the file size only, cheap to draw)."""
    try:
        path = bake_core.journal_path_for(props.output_path)
    except Exception:  # an unsaved file with a '//' output: no journal can exist
        return
    info = journal.summary(path)
    if info is None:
        return
    box = layout.box()
    box.label(text=f"Resumable bake: {info['records']} probe(s) kept", icon='RECOVER_LAST')
    box.label(text=os.path.basename(path))


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


class SCHNEE_OT_set_light_mode(bpy.types.Operator):
    """Baked: the lamp lights objects only through the probes. Mixed: its bounced light is in the
    probes, the engine adds its direct light with shadows. Realtime: left out of the probe renders;
    the engine adds it as direct light"""
    bl_idname = "schnee.set_light_mode"
    bl_label = "Set Light Mode"
    bl_options = {'REGISTER', 'UNDO'}

    mode: bpy.props.EnumProperty(
        name="Mode",
        items=((light_modes.BAKED, "Baked", "Lit through the probes only (the bake renders it)"),
               (light_modes.MIXED, "Mixed", "Bounced light in the probes; the engine adds its "
                                            "direct light with shadows (sharp sunbeams)"),
               (light_modes.REALTIME, "Realtime", "Left out of the probe renders; the engine adds "
                                                  "it as direct light")))

    @classmethod
    def poll(cls, context):
        return any(ob.type == 'LIGHT' for ob in _target_lights(context))

    def execute(self, context):
        # The custom property is the contract (bake, export, scripts); the panel only writes it.
        for ob in _target_lights(context):
            ob[light_modes.PROPERTY] = self.mode
        return {'FINISHED'}


def _target_lights(context):
    """The active lamp and every selected lamp: one click sets several lamps."""
    obs = list(getattr(context, "selected_objects", None) or [])
    active = getattr(context, "active_object", None)
    if active is not None and active not in obs:
        obs.append(active)
    return [ob for ob in obs if ob.type == 'LIGHT']


class VIEW3D_PT_schnee_light(bpy.types.Panel):
    bl_label = "Light Mode"
    bl_idname = "VIEW3D_PT_schnee_light"
    bl_space_type = 'VIEW_3D'
    bl_region_type = 'UI'
    bl_category = "Schnee Engine"
    bl_parent_id = "VIEW3D_PT_schnee_probes"

    @classmethod
    def poll(cls, context):
        ob = context.active_object
        return ob is not None and ob.type == 'LIGHT'

    def draw(self, context):
        ob = context.active_object
        col = self.layout.column(align=True)
        col.label(text=ob.name, icon='LIGHT')
        try:
            mode = light_modes.light_mode(ob)
        except light_modes.LightModeError:
            mode = None
            col.label(text=f"Unknown {light_modes.PROPERTY}: {ob.get(light_modes.PROPERTY)!r}", icon='ERROR')
        row = col.row(align=True)
        for value, text in ((light_modes.BAKED, "Baked"), (light_modes.MIXED, "Mixed"),
                            (light_modes.REALTIME, "Realtime")):
            row.operator(SCHNEE_OT_set_light_mode.bl_idname, text=text, depress=mode == value).mode = value
        if mode == light_modes.BAKED:
            col.label(text="In the probes; no direct light where probes light")
        elif mode == light_modes.MIXED:
            col.label(text="Bounced light in the probes; engine direct light, shadowed")
        elif mode == light_modes.REALTIME:
            col.label(text="Not in the probes; engine direct light")
        if mode in (light_modes.MIXED, light_modes.REALTIME) and ob.data.type == 'AREA':
            col.label(text="glTF cannot export area lights", icon='ERROR')


classes = (VIEW3D_PT_schnee_probes, VIEW3D_PT_schnee_probes_last, SCHNEE_OT_set_light_mode,
           VIEW3D_PT_schnee_light)

register, unregister = bpy.utils.register_classes_factory(classes)
