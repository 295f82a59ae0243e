"""Per-lamp light mode: baked into the probes, or realtime in the engine (docs/user-guide.md "Lights").

The mode is the custom property ``schnee_light_mode`` on the light **object** (not the light
datablock): ``"baked"`` (the default when the property is absent) or ``"realtime"``.

- baked: the bake renders the lamp into the probes (direct and bounced light); the engine adds
  no direct term where a baked probe lights a surface, so the lamp is counted once.
- realtime: the bake hides the lamp from the probe renders; the engine adds it as direct light.

On the object because render visibility, which the bake switches, is per object, and because a
glTF node (one per object) is what refers to a light: two objects sharing one light datablock
(Alt+D) can have different modes. The bake (bake_core.py), the glTF export (gltf_export.py,
``VULKAN_SCHNEE_light``) and the sidebar panel (panel.py) all read it through :func:`light_mode`.
"""
PROPERTY = "schnee_light_mode"
BAKED = "baked"
REALTIME = "realtime"
MODES = (BAKED, REALTIME)
DEFAULT = BAKED


class LightModeError(ValueError):
    """A light object's ``schnee_light_mode`` is neither "baked" nor "realtime"."""


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
                         f"'{BAKED}' or '{REALTIME}'")
