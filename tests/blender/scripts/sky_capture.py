"""Sky capture of a volume bake, then glTF export: a bundled HDRI world and a closed box around
the world origin (where the sky camera sits), so a capture that did not hide the geometry would
see only the box's inside.

Args after --: OUT_DIR. Emits a RESULT line (see addon_common.emit).
"""
import json
import os
import sys

import bpy
import numpy as np

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import addon_common as common  # noqa: E402
from addon_common import scene_lib as lib

out_dir = common.args()[0]
import addon_utils  # noqa: E402

# The add-on must be *enabled* (in preferences) for the exporter to find its user extension.
addon_utils.enable("io_scene_gltf2", default_set=True)
assert addon_utils.enable("schnee_probes", default_set=True) is not None
from schnee_probes import bake_core, native  # noqa: E402

lib.clear_scene()
lib.hdri_world("courtyard.exr")
lib.probe_volume("SkyVolume", (1.0, 1.0, 0.0), (3.0, 3.0, 2.0))
bpy.ops.mesh.primitive_cube_add(size=1.0, location=(0.0, 0.0, 0.0))
box = bpy.context.active_object
box.name = "BoxAroundOrigin"
blend = lib.save(os.path.join(out_dir, "sky.blend"))

settings = bake_core.BakeSettings(placement="OCTREE", min_cell_size=2.0, max_cell_size=2.0, panorama_resolution=16, samples=4,
                                  sky_resolution=128)
bake = bake_core.ProbeBake(bpy.context.scene, bpy.context.view_layer, settings)
result = bake.run()
sky = os.path.join(out_dir, "sh_coeffs", "sky.exr")
sh_sky = native.project_file(sky, 2, negative="clamp")
sh_hdri = native.project_file(lib.studiolight_path("courtyard.exr"), 2, negative="clamp")
l0 = np.abs(sh_hdri[0]).max()

gltf = os.path.join(out_dir, "export", "scene.gltf")
os.makedirs(os.path.dirname(gltf))
bpy.ops.export_scene.gltf(filepath=gltf, export_format="GLTF_SEPARATE")
with open(gltf) as fh:
    doc = json.load(fh)
entry = doc["scenes"][0]["extensions"]["VULKAN_SCHNEE_engine_properties"]
common.emit(files=sorted(os.path.basename(f) for f in result.files),
            sky_coeff_max_rel=float(np.abs(sh_sky - sh_hdri).max() / l0),
            sky_irradiance_rel_rms=common.irradiance_rel_rms(native, sh_sky, sh_hdri),
            box_hide_render=box.hide_render, sky_seconds=result.timings.get("sky"),
            entry_sky=entry.get("sky"), grids=len(entry["shProbeGrids"]),
            sh_sky=sh_sky.tolist(), required=doc.get("extensionsRequired", []), gltf=gltf)
