"""Inside a fresh user profile: install the zip, enable it, bake with its operators.
``-- ZIP WORK_DIR``; prints ZIP-OK when everything worked (exceptions exit non-zero)."""
import os
import sys

import addon_utils
import bpy

zip_path, work = sys.argv[sys.argv.index("--") + 1:][:2]
scripts_dir = os.environ["BLENDER_USER_SCRIPTS"]
bpy.ops.preferences.addon_install(filepath=zip_path, overwrite=True)
bpy.ops.preferences.addon_enable(module="schnee_probes")
import schnee_probes  # noqa: E402

here = os.path.realpath(schnee_probes.__file__)
assert here.startswith(os.path.realpath(scripts_dir)), f"imported from {here}, not the installed copy"
assert addon_utils.check("schnee_probes")[1], "add-on not enabled"
assert hasattr(bpy.types.Scene, "schnee_probes")
assert not any("scipy" in m for m in sys.modules), "the add-on imported scipy"

# A minimal scene: the factory cube as geometry, one volume around it, sky colour from the world.
scene = bpy.context.scene
bpy.ops.mesh.primitive_cube_add(size=6.0, location=(0.0, 0.0, 0.0))
vol = bpy.context.active_object
vol.name = "Volume"
coll = bpy.data.collections.new("ProbeVolumes")
scene.collection.children.link(coll)
for c in list(vol.users_collection):
    c.objects.unlink(vol)
coll.objects.link(vol)
os.makedirs(work, exist_ok=True)
bpy.ops.wm.save_as_mainfile(filepath=os.path.join(work, "zip.blend"))

p = scene.schnee_probes
p.min_cell_size = p.max_cell_size = 3.0
p.panorama_resolution = 16
p.samples = 1
assert bpy.ops.schnee.bake_sh_volumes() == {'FINISHED'}, p.last_message
assert os.path.exists(os.path.join(work, "sh_coeffs", "probes.shprobe"))
scene.cursor.location = (2.5, 2.5, 2.5)
assert bpy.ops.schnee.bake_sh_cursor() == {'FINISHED'}, p.last_message
assert os.path.exists(os.path.join(work, "sh_coeffs", "debug_probe.txt"))
print("ZIP-OK", p.last_probe_count)
