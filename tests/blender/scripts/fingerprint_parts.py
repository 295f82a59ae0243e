"""Which fingerprint parts (addon/schnee_probes/fingerprint.py) change when one thing in the open
scene changes: prints ``RESULT {"changed": {edit: [parts]}}``; each edit is undone before the next."""
import os
import sys

import bpy

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import addon_common as common  # noqa: E402
import schnee_probes  # noqa: E402
from schnee_probes import fingerprint  # noqa: E402
from schnee_probes.settings import BakeSettings  # noqa: E402

schnee_probes.register()
scene, layer = bpy.context.scene, bpy.context.view_layer
base_settings = BakeSettings.from_props(scene.schnee_probes)


def parts(settings=None):
    return fingerprint.parts(scene, layer, settings or base_settings)


base = parts()
again = parts()
changed = {"nothing": sorted(k for k in base if base[k] != again[k])}


def check(name, do, undo, settings=None):
    do()
    bpy.context.view_layer.update()
    p = parts(settings)
    changed[name] = sorted(k for k in base if base[k] != p[k])
    undo()
    bpy.context.view_layer.update()


mat = bpy.data.materials["Plaster"]
node = next(n for n in mat.node_tree.nodes if n.type == 'BSDF_PRINCIPLED' or n.type == 'BSDF_DIFFUSE')
colour = tuple(node.inputs[0].default_value)
loc = tuple(node.location)
wall = bpy.data.objects["Floor"]
world_node = next(n for n in scene.world.node_tree.nodes if n.type == 'BACKGROUND')
strength = world_node.inputs["Strength"].default_value
check("node moved in the editor", lambda: setattr(node, "location", (loc[0] + 300, loc[1])),
      lambda: setattr(node, "location", loc))
check("material colour", lambda: node.inputs[0].default_value.__setitem__(0, 0.1),
      lambda: node.inputs[0].default_value.__setitem__(0, colour[0]))
check("wall moved", lambda: setattr(wall, "location", (wall.location.x, wall.location.y, wall.location.z - 0.1)),
      lambda: setattr(wall, "location", (wall.location.x, wall.location.y, wall.location.z + 0.1)))
check("world strength", lambda: setattr(world_node.inputs["Strength"], "default_value", strength * 2),
      lambda: setattr(world_node.inputs["Strength"], "default_value", strength))
check("bounces", lambda: setattr(scene.cycles, "max_bounces", scene.cycles.max_bounces + 1),
      lambda: setattr(scene.cycles, "max_bounces", scene.cycles.max_bounces - 1))
light = bpy.data.objects.new("Lamp", bpy.data.lights.new("Lamp", 'POINT'))
check("lamp added", lambda: scene.collection.objects.link(light), lambda: scene.collection.objects.unlink(light))
# A lamp's light mode (mixed by type for this 0.25 m point lamp, realtime by the legacy property):
# its direct light leaves or enters the probes, so a journal of the other mode must not resume.
scene.collection.objects.link(light)
base = parts(base_settings)
check("lamp mode", lambda: light.__setitem__("schnee_light_mode", "realtime"), lambda: light.pop("schnee_light_mode"))
scene.collection.objects.unlink(light)
bpy.context.view_layer.update()
base = parts(base_settings)
import dataclasses  # noqa: E402
check("samples setting", lambda: None, lambda: None, dataclasses.replace(base_settings, samples=base_settings.samples + 1))
check("output path only", lambda: None, lambda: None, dataclasses.replace(base_settings, output_path="//elsewhere.shprobe"))
check("probe representation only", lambda: None, lambda: None,
      dataclasses.replace(base_settings, probe_representation="CUBE_HALF"))
# issue 31: the post-process settings are applied when the file is written, not to the journal's
# records: a resumed bake with other values reuses the renders (as for the probe representation)
check("dilate setting", lambda: None, lambda: None,
      dataclasses.replace(base_settings, dilate_invalid=not base_settings.dilate_invalid))
check("window setting", lambda: None, lambda: None,
      dataclasses.replace(base_settings, sh_window="SINC4" if base_settings.sh_window != "SINC4" else "NONE"))
check("window strength", lambda: None, lambda: None,
      dataclasses.replace(base_settings, sh_window_strength=base_settings.sh_window_strength + 0.5))
common.emit(changed=changed)
