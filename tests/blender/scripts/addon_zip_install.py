"""Inside a fresh user profile: install the zip, enable it, bake with its operators, then write the
scene of the headless bake through the installed bake.py (test_addon_zip.py).
``-- ZIP WORK_DIR [UNIFORM_BLEND R G B]``; prints ZIP-OK when everything worked (exceptions exit
non-zero).

UNIFORM_BLEND: a world of uniform radiance (R, G, B) (Background node, strength 1) and nothing else
but one closed 2 m cube probe volume centred at Blender (0, 0, 1), in the collection "ProbeVolumes".
"""
import os
import sys

import addon_utils
import bpy

args = sys.argv[sys.argv.index("--") + 1:]
zip_path, work = args[:2]
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

if len(args) >= 6:
    # The uniform-world scene: every object of the scene above goes, the volume is a new 2 m cube.
    uniform_blend, color = args[2], tuple(float(c) for c in args[3:6])
    for ob in list(bpy.data.objects):
        bpy.data.objects.remove(ob)
    world = bpy.data.worlds.new("Uniform")
    world.use_nodes = True
    bg = next(n for n in world.node_tree.nodes if n.type == 'BACKGROUND')
    bg.inputs["Color"].default_value = color + (1.0,)
    bg.inputs["Strength"].default_value = 1.0
    scene.world = world
    bpy.ops.mesh.primitive_cube_add(size=2.0, location=(0.0, 0.0, 1.0))
    vol = bpy.context.active_object
    vol.name = "UniformVolume"
    for c in list(vol.users_collection):
        c.objects.unlink(vol)
    coll.objects.link(vol)
    os.makedirs(os.path.dirname(uniform_blend), exist_ok=True)
    bpy.ops.wm.save_as_mainfile(filepath=uniform_blend)
print("ZIP-OK", p.last_probe_count)
