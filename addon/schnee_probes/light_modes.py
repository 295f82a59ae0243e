"""Per-lamp light mode: baked into the probes, mixed, or realtime in the engine (docs/user-guide.md
"Lights", docs/export.md "Light modes").

- baked: the bake renders the lamp into the probes (direct and bounced light); the engine adds
  no direct term where a baked probe lights a surface, so the lamp is counted once.
- mixed: the lamp lights the scene in the probe renders, so its bounced light is in the probes,
  but its direct light is not (hidden from the probe cameras, not added analytically); the engine
  adds the direct term everywhere, shadowed (shadow maps, docs/engine.md "Shadows"). As
  Unity's Mixed lights: a hard sunbeam's edge is drawn by the shadow map per pixel instead of being
  interpolated between probes.
- realtime: the bake hides the lamp from the probe renders; the engine adds it as direct light.

Where the mode comes from, first match wins (:func:`resolve`):

1. the legacy custom property ``schnee_light_mode`` on the light object, when present: an explicit
   string ("baked", "mixed" or "realtime", exactly; anything else is a :class:`LightModeError`).
   Scripts and files from before the UI keep working; choosing a mode in the UI removes it
   (properties.py), so the last choice wins either way;
2. the registered property ``Object.schnee_light.mode`` (properties.py; the Light properties tab and
   the Schnee Engine sidebar draw it), when it is not "DEFAULT";
3. the default by the lamp's type (:func:`default_mode`): a Sun, a spot and a point lamp of radius
   at most :data:`POINT_MIXED_MAX_RADIUS` are mixed; a larger point lamp and an area lamp are baked.

The defaults follow bench/bench_lamp_modes.py (bench/results/lamp_modes.md, no Cycles: the exact
shadowed direct light of the native step): against a 0.5 m probe lattice (the default Min Cell
Size, the finest the refinement goes) a baked lamp's interpolated direct light is off by a mean
2.8-3.3 % (sun), 2.9-20 % (point) and 68-3077 % (spot: its cone's edge smeared over a cell) of the
light at points between probes, where the engine's shadowed punctual light (the same lamp at
radius 0) is off by 0-0.2 % (sun), 0.2-4.5 % (point, radius <= 0.25 m) and 4-39 % (spot): mixed is
the more accurate for every sun and spot measured and for point lamps up to 0.25 m; from 0.35 m
on the engine's hard-edged punctual light is mostly further from Cycles' wide lamp than the probes
are. An area lamp stays baked: glTF has no area lights, so a mixed area lamp's direct light would
reach nothing.

On the object because render visibility, which the bake switches, is per object, and because a
glTF node (one per object) is what refers to a light: two objects sharing one light datablock
(Alt+D) can have different modes. The bake (bake_core.py), the glTF export (gltf_export.py,
``VULKAN_SCHNEE_light``) and the panels (panel.py) all read it through :func:`light_mode`. This
module imports no ``bpy`` (bench/bench_lamp_modes.py prints the defaults with it).
"""
PROPERTY = "schnee_light_mode"      # the legacy custom property (a string ID property)
SETTINGS = "schnee_light"           # Object.schnee_light: the registered PropertyGroup (properties.py)
BAKED = "baked"
MIXED = "mixed"
REALTIME = "realtime"
MODES = (BAKED, MIXED, REALTIME)
# What a bad value is exported as (gltf_export.py writes a valid file and warns); not the default of
# a lamp without a choice, which depends on its type (default_mode).
DEFAULT = BAKED
# The registered enum's identifiers: "DEFAULT" = by type, the others the modes in upper case.
BY_TYPE = "DEFAULT"
CHOICES = (BY_TYPE,) + tuple(m.upper() for m in MODES)
# Point lamps up to this radius (Blender's shadow_soft_size, metres) default to mixed; larger ones to
# baked (bench/results/lamp_modes.md: mixed better at 0.05-0.25 m, baked at 0.35-0.5 m).
POINT_MIXED_MAX_RADIUS = 0.25


# The engine's shadow-map pool (docs/engine.md "Shadows", SV_MAX_SHADOW_LAYERS) and what each mixed or
# realtime light takes of it at the engine's defaults: a mixed light left without layers is
# unshadowed and lights through walls, so the panel warns when the scene's lights need more.
ENGINE_SHADOW_LAYERS = 16
ENGINE_SUN_CASCADES = 4         # --shadow-cascades' default (SV_SHADOW_DEFAULT_CASCADES)
ENGINE_SPOT_CUBE_HALF_ANGLE = 1.0471975511965976  # 60°: a wider spot takes six layers, as a point


def shadow_layers(kind: str, spot_size: float = 0.0) -> int:
    """Shadow-map layers the engine gives a mixed or realtime lamp of Blender type ``kind`` (spot:
    full cone ``spot_size``, radians; glTF's outer cone angle is half of it)."""
    if kind == 'SUN':
        return ENGINE_SUN_CASCADES
    if kind == 'POINT':
        return 6
    if kind == 'SPOT':
        return 6 if spot_size / 2.0 > ENGINE_SPOT_CUBE_HALF_ANGLE else 1
    return 0  # AREA: not a glTF punctual light


def scene_shadow_layers(objects) -> int:
    """Shadow-map layers the mixed and realtime lamps among ``objects`` need in the engine (lamps
    with a bad mode, which the bake refuses, are not counted)."""
    total = 0
    for ob in objects:
        if getattr(ob, "type", None) != 'LIGHT' or getattr(ob, "hide_render", False):
            continue
        try:
            mode = light_mode(ob)
        except LightModeError:
            continue
        if mode != BAKED:
            total += shadow_layers(ob.data.type, float(getattr(ob.data, "spot_size", 0.0) or 0.0))
    return total


class LightModeError(ValueError):
    """A light object's ``schnee_light_mode`` is not "baked", "mixed" or "realtime"."""


def default_for(kind: str, radius: float = 0.0) -> str:
    """The default mode of a lamp of Blender type ``kind`` ('SUN', 'POINT', 'SPOT', 'AREA') and
    radius ``radius`` (m, point and spot lamps' ``shadow_soft_size``)."""
    if kind in ('SUN', 'SPOT'):
        return MIXED
    if kind == 'POINT':
        return MIXED if radius <= POINT_MIXED_MAX_RADIUS else BAKED
    return BAKED  # AREA: glTF cannot carry it, so only baking brings its direct light anywhere


def default_mode(ob) -> str:
    """The mode of light object ``ob`` when nobody chose one: by its lamp's type and radius."""
    data = getattr(ob, "data", None)
    return default_for(getattr(data, "type", ""), float(getattr(data, "shadow_soft_size", 0.0) or 0.0))


def chosen_mode(ob):
    """The mode chosen with the registered property (lower case), or None for "By Type" (also when
    the add-on's properties are not registered)."""
    settings = getattr(ob, SETTINGS, None)
    choice = getattr(settings, "mode", BY_TYPE) if settings is not None else BY_TYPE
    return None if choice == BY_TYPE else str(choice).lower()


def resolve(ob):
    """(mode, source) of light object ``ob``; source is "custom property", "chosen" or "default".

    The legacy custom property is compared exactly (lower case, as the engine reads it); any other
    value raises :class:`LightModeError` naming the object, the value and the accepted values."""
    value = ob.get(PROPERTY) if hasattr(ob, "get") else None
    if value is not None:
        if isinstance(value, str) and value in MODES:
            return value, "custom property"
        raise LightModeError(f"light '{ob.name}': custom property {PROPERTY} = {value!r} is not "
                             f"'{BAKED}', '{MIXED}' or '{REALTIME}'")
    chosen = chosen_mode(ob)
    if chosen is not None:
        return chosen, "chosen"
    return default_mode(ob), "default"


def light_mode(ob) -> str:
    """The mode of light object ``ob``: "baked", "mixed" or "realtime" (see :func:`resolve`)."""
    return resolve(ob)[0]
