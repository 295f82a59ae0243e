"""Bake settings, stored on the scene as ``Scene.schnee_probes``, and their drawing in the panel and
the bake dialog.

The properties are generated from :data:`settings.SETTINGS` (name, type, default, limits, label,
help), so they equal the fields of :class:`settings.BakeSettings` and the ``bake.py`` options.
Defaults and their time/error trade are documented in docs/user-guide.md (generated from the same
declaration; figures measured with bench/sweep/run.py, report bench/results/sweep.md).
"""
import bpy
from bpy.props import BoolProperty, EnumProperty, FloatProperty, IntProperty, PointerProperty, StringProperty

from . import light_modes, probe_modes
from .settings import SETTINGS, BakeSettings


def make_property(s):
    """The ``bpy.props`` property of one :class:`settings.Setting`."""
    kw = dict(name=s.label, description=s.help, default=s.default)
    if s.kind in ("int", "float"):
        if s.minimum is not None:
            kw["min"] = s.minimum
        if s.maximum is not None:
            kw["max"] = s.maximum
        if s.soft_max is not None:
            kw["soft_max"] = s.soft_max
        if s.unit:
            kw["unit"] = s.unit
        if s.kind == "int":
            for k in ("min", "max", "soft_max"):
                if k in kw:
                    kw[k] = int(kw[k])
            if s.even:
                kw["step"] = 2
            return IntProperty(**kw)
        return FloatProperty(**kw)
    if s.kind == "bool":
        return BoolProperty(**kw)
    if s.kind == "enum":
        return EnumProperty(items=s.choices, **kw)
    if s.kind == "path":
        return StringProperty(subtype=s.unit or 'FILE_PATH', **kw)
    return StringProperty(**kw)


def draw_settings(layout, props, volumes=True):
    """The settings as the panel and the Bake SH in Volumes dialog show them (``settings.Setting.ui``
    says which and in what rows); ``volumes=False`` leaves out the volume-only ones."""
    col = layout.column()
    rows = {}
    for s in SETTINGS:
        if s.ui is None or (s.ui == "volumes" and not volumes):
            continue
        if s.ui_row:
            if s.ui_row not in rows:
                rows[s.ui_row] = col.row(align=True)
            target = rows[s.ui_row]
        else:
            target = col
        kw = {} if s.ui_text is None else {"text": s.ui_text}
        if s.name == "volume_collection":
            target.prop_search(props, s.name, bpy.data, "collections", **kw)
        else:
            target.prop(props, s.name, **kw)


def draw_estimate(layout, scene, props):
    """Before a bake: at most how many probes and how long (volume bounding boxes, no placement;
    the exact count and estimate come once placement has run)."""
    from . import bake_core
    bound, seconds = bake_core.volume_bound(scene, BakeSettings.from_props(props))
    col = layout.column(align=True)
    if bound is None:
        col.label(text="Probes: no usable probe volumes or settings", icon='INFO')
        return
    col.label(text=f"Up to {bound} probes, at most ~{bake_core.format_duration(seconds)}", icon='TIME')
    if props.probe_limit and bound > props.probe_limit:
        col.label(text=f"May exceed Confirm Above ({props.probe_limit}): the bake will ask", icon='ERROR')


# Bake settings from the declaration, then what the last bake produced (shown in the panel; saved
# with the .blend).
_annotations = {s.name: make_property(s) for s in SETTINGS}
_annotations.update(
    last_probe_count=IntProperty(name="Probes", default=0),
    last_seconds=FloatProperty(name="Time (s)", default=0.0),
    last_files=StringProperty(name="Files", default=""),
    last_message=StringProperty(name="Last Bake", default=""),
)

SchneeProbeSettings = type("SchneeProbeSettings", (bpy.types.PropertyGroup,), {
    "__annotations__": _annotations,
    "__doc__": "Settings of Bake SH in Volumes / Bake SH at Cursor, and what the last bake produced.",
    "__module__": __name__,
})



def _light_mode_changed(self, _context):
    # A choice made here is the user's latest: the legacy custom property, which would override it
    # (light_modes.resolve), goes. Runs for a choice from a script too (RNA calls update then).
    ob = self.id_data
    if ob is not None and light_modes.PROPERTY in ob.keys():
        del ob[light_modes.PROPERTY]


LIGHT_MODE_ITEMS = (
    (light_modes.BY_TYPE, "By Type",
     "Mixed for a Sun, a spot and a point lamp of radius up to "
     f"{light_modes.POINT_MIXED_MAX_RADIUS:g} m (their direct light is too sharp for the probes); "
     "baked for a larger point lamp and an area lamp"),
    ("BAKED", "Baked", "Direct and bounced light in the probes; the engine adds no direct light where "
                       "probes light a surface (soft light; a sharp shadow is blurred across probe cells)"),
    ("MIXED", "Mixed", "Bounced light in the probes; the engine adds the direct light per pixel with "
                       "shadow maps (sharp sunbeams and lamp shadows)"),
    ("REALTIME", "Realtime", "Left out of the probe renders; the engine adds it as direct light, "
                             "shadowed (no bounced light)"),
)


class SchneeLightSettings(bpy.types.PropertyGroup):
    """The light mode of a lamp object (light_modes.py): Object.schnee_light. On the object, not the
    light datablock: render visibility and glTF nodes are per object. Not named like the legacy
    custom property ``schnee_light_mode``, whose string old files hold."""
    mode: EnumProperty(
        name="Light Mode",
        description="How the lamp reaches the engine: through the probes (baked), the probes' bounced "
                    "light plus the engine's shadowed direct light (mixed), or the engine alone (realtime)",
        items=LIGHT_MODE_ITEMS, default=light_modes.BY_TYPE, update=_light_mode_changed,
        options=set())  # not animatable: one mode per bake


PROBE_MODE_ITEMS = tuple((ident, text, tip) for ident, text, _fields, tip in probe_modes.CHOICES)


class SchneeObjectProbeSettings(bpy.types.PropertyGroup):
    """How the engine lights an object from the probes (probe_modes.py): Object.schnee_probe. Its
    choice replaces its materials' schnee_probe_mode for this object only; exported on the object's
    glTF node (VULKAN_SCHNEE_node, docs/export.md)."""
    mode: EnumProperty(
        name="Probe Mode",
        description="How the engine lights this object from the baked probes; anything but the default "
                    "replaces its materials' own mode for this object",
        items=PROBE_MODE_ITEMS, default=probe_modes.AS_MATERIALS,
        options=set())  # not animatable: one mode per export


classes = (SchneeProbeSettings, SchneeLightSettings, SchneeObjectProbeSettings)


def register():
    for cls in classes:
        bpy.utils.register_class(cls)
    bpy.types.Scene.schnee_probes = PointerProperty(type=SchneeProbeSettings)
    bpy.types.Object.schnee_light = PointerProperty(type=SchneeLightSettings, name="Schnee Light",
                                                    description="Light mode of a lamp (Schnee probes)")
    bpy.types.Object.schnee_probe = PointerProperty(type=SchneeObjectProbeSettings, name="Schnee Probes",
                                                    description="How the engine lights the object from "
                                                                "the probes (Schnee probes)")


def unregister():
    del bpy.types.Object.schnee_probe
    del bpy.types.Object.schnee_light
    del bpy.types.Scene.schnee_probes
    for cls in reversed(classes):
        bpy.utils.unregister_class(cls)
