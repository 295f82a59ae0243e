"""3D Viewport > Sidebar (N) > Schnee Engine: the bake buttons, the settings, the last result, the
active lamp's light mode (baked into the probes, mixed or realtime in the engine, light_modes.py),
which Properties > Light also shows (DATA_PT_schnee_light), and the active object's probe mode
(probe_modes.py), which Properties > Object also shows (OBJECT_PT_schnee_probes)."""
import os

import bpy

from . import bake_core, compat, journal, light_modes, probe_modes, render_settings
from .properties import LIGHT_MODE_ITEMS, PROBE_MODE_ITEMS, draw_estimate, draw_settings


class SidebarPanel:
    """Mixin of the panels on 3D Viewport > Sidebar > Schnee Engine (here and in overlay.py)."""
    bl_space_type = 'VIEW_3D'
    bl_region_type = 'UI'
    bl_category = "Schnee Engine"


class SidebarSubpanel(SidebarPanel):
    """Mixin of the panels under SH Probes (VIEW3D_PT_schnee_probes)."""
    bl_parent_id = "VIEW3D_PT_schnee_probes"


class PropertiesPanel:
    """Mixin of the panels in the Properties editor."""
    bl_space_type = 'PROPERTIES'
    bl_region_type = 'WINDOW'


class ObjectPanel:
    """Mixin of the panels of one object (panel_object: the context's, as Properties has one), shown
    when its type is in ``object_types``."""
    object_types = frozenset()

    @staticmethod
    def panel_object(context):
        return getattr(context, "object", None)

    @classmethod
    def poll(cls, context):
        ob = cls.panel_object(context)
        return ob is not None and ob.type in cls.object_types


class SidebarObjectPanel(ObjectPanel, SidebarSubpanel):
    """Mixin of the sidebar's panels of the active object."""

    @staticmethod
    def panel_object(context):
        return context.active_object


class VIEW3D_PT_schnee_probes(SidebarPanel, bpy.types.Panel):
    bl_label = "SH Probes"
    bl_idname = "VIEW3D_PT_schnee_probes"

    def draw(self, context):
        layout = self.layout
        props = context.scene.schnee_probes
        compat.draw_native_problem(layout)  # the bake core did not load: what is missing, what to do
        col = layout.column(align=True)
        col.scale_y = 1.3
        col.operator("schnee.bake_sh_volumes", icon='LIGHTPROBE_GRID')
        col.operator("schnee.rebake_selected_volume", icon='FILE_REFRESH')
        col.operator("schnee.rebake_selected_region", icon='SELECT_SET')
        col.operator("schnee.bake_sh_cursor", icon='PIVOT_CURSOR')
        row = layout.row()
        row.operator("schnee.add_movable_diffuse", text="Movable Diffuse Material", icon='NODE_MATERIAL')
        layout.use_property_split = True
        layout.use_property_decorate = False
        draw_settings(layout, props)
        draw_estimate(layout, context.scene, props)
        _draw_device(layout, context.scene, props)
        _draw_journal(layout, props)


# The panel lists the Cycles devices at most this often (every redraw would probe them).
PANEL_DEVICE_SECONDS = 5.0


def _draw_device(layout, scene, props):
    """What will render the panoramas with Render Device as set ("GPU: none available, CPU (2
    threads)" when a GPU is asked for and the Preferences give none); nothing without Cycles."""
    try:
        label = render_settings.device_label(scene, props.render_device, max_age=PANEL_DEVICE_SECONDS)
    except bake_core.BakeError:
        return
    layout.label(text=f"Renders on {label}")


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


class VIEW3D_PT_schnee_probes_last(SidebarSubpanel, bpy.types.Panel):
    bl_label = "Last Bake"
    bl_idname = "VIEW3D_PT_schnee_probes_last"

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


def _targets(context, types):
    """The active object and every selected one whose type is in ``types``: one click sets several."""
    obs = list(getattr(context, "selected_objects", None) or [])
    active = getattr(context, "active_object", None)
    if active is not None and active not in obs:
        obs.append(active)
    return [ob for ob in obs if ob.type in types]


class SetModeOperator:
    """Mixin of the Set ... Mode operators: ``mode`` on the ``settings_group`` of the active and every
    selected object whose type is in ``target_types``; needs one."""
    bl_options = {'REGISTER', 'UNDO'}
    target_types = frozenset()
    settings_group = ""

    @classmethod
    def poll(cls, context):
        return bool(_targets(context, cls.target_types))

    def execute(self, context):
        for ob in _targets(context, self.target_types):
            getattr(ob, self.settings_group).mode = self.mode
        return {'FINISHED'}


LIGHT_OBJECT_TYPES = {'LIGHT'}


class SCHNEE_OT_set_light_mode(SetModeOperator, bpy.types.Operator):
    """Set the light mode of the active and every selected lamp (Object.schnee_light.mode; removes a
    legacy schnee_light_mode custom property, as choosing in the panel does)"""
    bl_idname = "schnee.set_light_mode"
    bl_label = "Set Light Mode"
    target_types = LIGHT_OBJECT_TYPES
    settings_group = "schnee_light"  # its update callback removes the legacy custom property (properties.py)

    # The identifiers and tooltips of the registered property (properties.LIGHT_MODE_ITEMS).
    mode: bpy.props.EnumProperty(name="Mode", items=LIGHT_MODE_ITEMS)


_MODE_TEXT = {
    light_modes.BAKED: "In the probes; no direct light where probes light",
    light_modes.MIXED: "Bounced light in the probes; engine direct light, shadowed",
    light_modes.REALTIME: "Not in the probes; engine direct light",
}


def draw_light_mode(layout, ob, context=None):
    """The light mode of lamp object ``ob``: the choice (Object.schnee_light.mode, with its
    tooltips), what the lamp resolves to and why (light_modes.resolve), and the problems the bake
    would report. Shared by the Light properties tab and the sidebar."""
    col = layout.column(align=True)
    col.prop(ob.schnee_light, "mode", text="")
    try:
        mode, source = light_modes.resolve(ob)
    except light_modes.LightModeError:
        mode, source = None, None
        col.label(text=f"Bad custom property {light_modes.PROPERTY}: {ob.get(light_modes.PROPERTY)!r}",
                  icon='ERROR')
        col.label(text="The bake refuses it; choose a mode above")
    if mode is not None:
        kind = ob.data.type.title()
        if ob.data.type == 'POINT':  # the default depends on the radius too: say which side
            limit = light_modes.POINT_MIXED_MAX_RADIUS
            kind += f", radius {'≤' if ob.data.shadow_soft_size <= limit else '>'} {limit:g} m"
        why = {"default": f"by type ({kind})", "chosen": "chosen",
               "custom property": f"custom property {light_modes.PROPERTY}"}[source]
        col.label(text=f"{mode.title()}: {why}", icon='LIGHT')
        col.label(text=_MODE_TEXT[mode])
        if source == "custom property":
            col.label(text="Choosing a mode above removes the custom property", icon='INFO')
    if mode in (light_modes.MIXED, light_modes.REALTIME) and ob.data.type == 'AREA':
        col.label(text="glTF cannot export area lights", icon='ERROR')
    scene = getattr(context, "scene", None) if context is not None else None
    if mode in (light_modes.MIXED, light_modes.REALTIME) and scene is not None:
        need = light_modes.scene_shadow_layers(scene.objects)
        if need > light_modes.ENGINE_SHADOW_LAYERS:
            # docs/engine.md "Shadows": the lamps past the pool are unshadowed in the engine.
            col.label(text=f"Mixed/realtime lamps need {need} of the engine's "
                           f"{light_modes.ENGINE_SHADOW_LAYERS} shadow layers", icon='ERROR')
            col.label(text="Some will be unshadowed (light through walls): bake some")
    if context is not None and len(_targets(context, LIGHT_OBJECT_TYPES)) > 1:
        col.operator_menu_enum(SCHNEE_OT_set_light_mode.bl_idname, "mode", text="Set All Selected Lamps")


class VIEW3D_PT_schnee_light(SidebarObjectPanel, bpy.types.Panel):
    bl_label = "Light Mode"
    bl_idname = "VIEW3D_PT_schnee_light"
    object_types = LIGHT_OBJECT_TYPES

    def draw(self, context):
        ob = context.active_object
        self.layout.label(text=ob.name, icon='LIGHT')
        draw_light_mode(self.layout, ob, context)


class DATA_PT_schnee_light(ObjectPanel, PropertiesPanel, bpy.types.Panel):
    """Properties > Light (Object Data of a lamp): the Schnee light mode."""
    bl_label = "Schnee Light Mode"
    bl_idname = "DATA_PT_schnee_light"
    bl_context = "data"
    object_types = LIGHT_OBJECT_TYPES

    def draw(self, context):
        draw_light_mode(self.layout, context.object, context)


# Object types the glTF exporter turns into meshes: the ones a probe mode can apply to.
MESH_OBJECT_TYPES = {'MESH', 'CURVE', 'SURFACE', 'META', 'FONT'}
_MATERIAL_MODE_TEXT = {"off": "Off", "object": "Per Object", "pixel": "Per Pixel"}


class SCHNEE_OT_set_probe_mode(SetModeOperator, bpy.types.Operator):
    """Set the probe mode of the active and every selected mesh-like object (Object.schnee_probe.mode)"""
    bl_idname = "schnee.set_probe_mode"
    bl_label = "Set Probe Mode"
    target_types = MESH_OBJECT_TYPES
    settings_group = "schnee_probe"

    # The identifiers and tooltips of the registered property (properties.PROBE_MODE_ITEMS).
    mode: bpy.props.EnumProperty(name="Probe Mode", items=PROBE_MODE_ITEMS)


def draw_object_probe_mode(layout, ob, context=None):
    """The probe mode of object ``ob`` (Object.schnee_probe.mode, with its tooltips) and what it
    means here: with "As Its Materials Say" each material's own mode (its custom property
    schnee_probe_mode), else that the choice replaces them; with several objects selected, a menu
    that sets them all. Shared by Properties > Object and the sidebar."""
    col = layout.column(align=True)
    col.prop(ob.schnee_probe, "mode", text="")
    if context is not None and len(_targets(context, MESH_OBJECT_TYPES)) > 1:
        col.operator_menu_enum(SCHNEE_OT_set_probe_mode.bl_idname, "mode", text="Set All Selected Objects")
    if probe_modes.chosen(ob) != probe_modes.AS_MATERIALS:
        col.label(text="Replaces its materials' modes for this object", icon='INFO')
        return
    mats = probe_modes.material_modes(ob)
    if not mats:
        col.label(text="No material: per object (the engine's default)", icon='INFO')
    for name, value in mats:
        if value is None:
            text = f"{name}: Per Object (default)"
        elif isinstance(value, str) and value in _MATERIAL_MODE_TEXT:
            text = f"{name}: {_MATERIAL_MODE_TEXT[value]}"
        else:  # the export warns and leaves it out (docs/export.md)
            text = f"{name}: bad schnee_probe_mode {value!r}, ignored"
        col.label(text=text, icon='MATERIAL')


class OBJECT_PT_schnee_probes(ObjectPanel, PropertiesPanel, bpy.types.Panel):
    """Properties > Object: the Schnee probe mode of a mesh-like object."""
    bl_label = "Schnee Probes"
    bl_idname = "OBJECT_PT_schnee_probes"
    bl_context = "object"
    object_types = MESH_OBJECT_TYPES

    def draw(self, context):
        draw_object_probe_mode(self.layout, context.object, context)


class VIEW3D_PT_schnee_object(SidebarObjectPanel, bpy.types.Panel):
    bl_label = "Object Probe Mode"
    bl_idname = "VIEW3D_PT_schnee_object"
    object_types = MESH_OBJECT_TYPES

    def draw(self, context):
        ob = context.active_object
        self.layout.label(text=ob.name, icon='OBJECT_DATA')
        draw_object_probe_mode(self.layout, ob, context)


classes = (VIEW3D_PT_schnee_probes, VIEW3D_PT_schnee_probes_last, SCHNEE_OT_set_light_mode,
           VIEW3D_PT_schnee_light, DATA_PT_schnee_light, SCHNEE_OT_set_probe_mode, OBJECT_PT_schnee_probes,
           VIEW3D_PT_schnee_object)

register, unregister = bpy.utils.register_classes_factory(classes)
