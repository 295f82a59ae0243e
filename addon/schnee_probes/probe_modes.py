"""Per-object probe mode: how the engine lights one object from the probes (docs/user-guide.md
"Per-object probe mode", docs/export.md "Node: VULKAN_SCHNEE_node").

An object's choice (``Object.schnee_probe.mode``, properties.py; Properties > Object > Schnee Probes
and the Schnee Engine sidebar draw it, panel.py) replaces what its materials say, for that object
only; "As Its Materials Say" (the default) leaves each material's custom property
``schnee_probe_mode`` / ``schnee_probe_representation`` in charge (docs/export.md "Material"). Two
objects sharing one material (or one mesh) may therefore be lit differently: a large static wall per
pixel, a prop with the same material per object.

The glTF export (gltf_export.py ``gather_node_hook``) writes the choice on the object's node as
``nodes[i].extensions.VULKAN_SCHNEE_node`` = :func:`node_fields`; the engine reads it per node
(engine/ext/sv_ext.c). This module imports no ``bpy``.
"""
SETTINGS = "schnee_probe"       # Object.schnee_probe: the registered PropertyGroup (properties.py)
EXTENSION = "VULKAN_SCHNEE_node"
AS_MATERIALS = "MATERIALS"       # the enum identifier of "As Its Materials Say" (the default)

# Enum identifier -> (label, VULKAN_SCHNEE_node fields, tooltip). Every choice but the default
# writes both fields, so the object's lighting does not depend on its materials' custom
# properties; the values are those of VULKAN_SCHNEE_materials (gltf_export.PROBE_MODES and
# PROBE_REPRESENTATIONS, checked by tests/python/test_probe_modes.py).
CHOICES = (
    (AS_MATERIALS, "As Its Materials Say", None,
     "Each material's own mode (its custom property schnee_probe_mode; the engine's default, per object, "
     "without one)"),
    ("OFF", "Off", {"probeMode": "off", "probeRepresentation": "sh"},
     "No baked probe: the engine's fallback (the sky's light, or a constant without a sky)"),
    ("OBJECT", "Per Object", {"probeMode": "object", "probeRepresentation": "sh"},
     "One probe for the whole object, interpolated at the centre of its bounds (cheap; small or moving "
     "objects)"),
    ("PIXEL", "Per Pixel", {"probeMode": "pixel", "probeRepresentation": "sh"},
     "The probes interpolated at every pixel (large static objects: floors, walls)"),
    ("AMBIENT_CUBE", "Ambient Cube", {"probeMode": "object", "probeRepresentation": "ambientCube"},
     "One probe per object evaluated as Valve's six-colour ambient cube (cheaper than SH, "
     "docs/ambient-cube.md)"),
)
IDENTIFIERS = tuple(c[0] for c in CHOICES)
_FIELDS = {c[0]: c[2] for c in CHOICES}


class ProbeModeError(ValueError):
    """An object's stored choice is not one of :data:`IDENTIFIERS` (a file from a later add-on)."""


def chosen(ob) -> str:
    """The enum identifier chosen for object ``ob``; :data:`AS_MATERIALS` when the add-on's
    property is not registered or the object never had a choice."""
    settings = getattr(ob, SETTINGS, None)
    return str(getattr(settings, "mode", AS_MATERIALS)) if settings is not None else AS_MATERIALS


def fields_for(identifier):
    """The VULKAN_SCHNEE_node fields (a new dict) of enum identifier ``identifier``; None for
    "As Its Materials Say" (no extension: the materials decide)."""
    if identifier not in _FIELDS:
        raise ProbeModeError(f"probe mode {identifier!r} is not one of {', '.join(IDENTIFIERS)}")
    fields = _FIELDS[identifier]
    return None if fields is None else dict(fields)


def node_fields(ob):
    """The ``VULKAN_SCHNEE_node`` object of ``ob``'s glTF node, or None (no extension)."""
    return fields_for(chosen(ob))


def label(identifier) -> str:
    """The label the panel shows for ``identifier``."""
    return next(c[1] for c in CHOICES if c[0] == identifier)


def material_modes(ob, property_name="schnee_probe_mode"):
    """[(material name, value of its custom property ``property_name`` or None)] for the materials of
    object ``ob``'s slots (empty slots skipped; a material listed once): what "As Its Materials Say"
    means for it, for the panel."""
    out, seen = [], set()
    for slot in getattr(ob, "material_slots", ()):
        mat = getattr(slot, "material", None)
        if mat is None or mat.name in seen:
            continue
        seen.add(mat.name)
        value = mat.get(property_name) if hasattr(mat, "get") else None
        out.append((mat.name, value))
    return out
