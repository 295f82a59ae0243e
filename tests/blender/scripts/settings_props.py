"""The Scene.schnee_probes property of every declared setting (settings.SETTINGS), as Blender
registered it: type, default, hard limits, enum items, label and help. ``blender -b -P`` this."""
import os
import sys

import bpy

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import addon_common as common  # noqa: E402

import schnee_probes  # noqa: E402
from schnee_probes import settings  # noqa: E402

schnee_probes.register()
props = bpy.context.scene.schnee_probes
rna = props.bl_rna.properties
out = {"props": {}, "extra": sorted(p.identifier for p in rna if p.identifier not in settings.SETTINGS_BY_NAME
                                    and p.identifier not in ("rna_type", "name")
                                    and not p.identifier.startswith("last_"))}
for s in settings.SETTINGS:
    p = rna.get(s.name)
    if p is None:
        continue
    d = {"type": p.type, "name": p.name, "description": p.description}
    if p.type in ('INT', 'FLOAT'):
        d.update(default=p.default, hard_min=p.hard_min, hard_max=p.hard_max)
    elif p.type == 'ENUM':
        d.update(default=p.default, items=[[i.identifier, i.name, i.description] for i in p.enum_items])
    else:
        d["default"] = p.default
    out["props"][s.name] = d
from_props = settings.BakeSettings.from_props(props)
# Float properties are float32: 0.1 comes back as 0.10000000149.
out["from_props_equals_defaults"] = all(
    abs(getattr(from_props, s.name) - s.default) <= 1e-7 * abs(s.default) if s.kind == "float"
    else getattr(from_props, s.name) == s.default for s in settings.SETTINGS)
common.emit(**out)
