"""Per-lamp light mode: baked into the probes, mixed, or realtime in the engine (docs/user-guide.md
"Lights", docs/export.md "Light modes").

The mode is the custom property ``schnee_light_mode`` on the light **object** (not the light
datablock): ``"baked"`` (the default when the property is absent), ``"mixed"`` or ``"realtime"``.

- baked: the bake renders the lamp into the probes (direct and bounced light); the engine adds
  no direct term where a baked probe lights a surface, so the lamp is counted once.
- mixed: the lamp lights the scene in the probe renders, so its bounced light is in the probes,
  but its direct light is not (hidden from the probe cameras, not added analytically); the engine
  adds the direct term everywhere, shadowed (shadow maps, docs/engine.md "Shadows"). As
  Unity's Mixed lights: a hard sunbeam's edge is drawn by the shadow map per pixel instead of being
  interpolated between probes.
- realtime: the bake hides the lamp from the probe renders; the engine adds it as direct light.

On the object because render visibility, which the bake switches, is per object, and because a
glTF node (one per object) is what refers to a light: two objects sharing one light datablock
(Alt+D) can have different modes. The bake (bake_core.py), the glTF export (gltf_export.py,
``VULKAN_SCHNEE_light``) and the sidebar panel (panel.py) all read it through :func:`light_mode`.
"""
PROPERTY = "schnee_light_mode"
BAKED = "baked"
MIXED = "mixed"
REALTIME = "realtime"
MODES = (BAKED, MIXED, REALTIME)
DEFAULT = BAKED


class LightModeError(ValueError):
    """A light object's ``schnee_light_mode`` is not "baked", "mixed" or "realtime"."""


def light_mode(ob) -> str:
    """The mode of light object ``ob``: its ``schnee_light_mode``, "baked" when absent.

    Values are compared exactly (lower case, as the engine reads them); anything else raises
    :class:`LightModeError` naming the object, the value and the accepted values."""
    value = ob.get(PROPERTY) if hasattr(ob, "get") else None
    if value is None:
        return DEFAULT
    if isinstance(value, str) and value in MODES:
        return value
    raise LightModeError(f"light '{ob.name}': custom property {PROPERTY} = {value!r} is not "
                         f"'{BAKED}', '{MIXED}' or '{REALTIME}'")
