"""Blender (headless): export the opened .blend with the Schnee add-on enabled (probe grids, sky,
VS Movable Diffuse materials), e.g. the bundled scene after a bake, for the engine's doc images:
blender -b room.blend --factory-startup -P export_with_addon.py -- OUT.gltf"""
import os
import sys

import addon_utils
import bpy

sys.path.insert(0, os.path.join(os.path.dirname(os.path.abspath(__file__)), "..", "..", "..", "addon"))
out = sys.argv[sys.argv.index("--") + 1]
addon_utils.enable("io_scene_gltf2", default_set=True)
assert addon_utils.enable("schnee_probes", default_set=True) is not None, "schnee_probes could not be enabled"
bpy.ops.export_scene.gltf(filepath=out, export_format="GLTF_SEPARATE", export_lights=True, export_cameras=True)
print("SCHNEE exported", out, flush=True)
