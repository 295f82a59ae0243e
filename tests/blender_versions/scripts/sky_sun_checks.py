"""Inside a Blender of any version with the add-on installed (as version_checks.py): the sky's sun as a
mixed light (issue 27 item 2, docs/direct-light.md "The sky's sun", docs/export.md "Light: the sky's
sun"). ``-- WORK_DIR``. Prints one ``RESULT {json}`` line; test_blender_versions.py checks it
against the split the host computes from the same HDRI file.

Scene (as tests/blender/scripts/sky_sun_bake.py's "sky" case): this Blender's bundled sunrise.exr as
the world (Environment Texture, strength 1) and nothing else a probe can see: a 2 m probe volume at
2 m cells (8 probes) and one small plane hidden from renders (so the glTF has a mesh node). Bake
SH in Volumes through the operator at Sky Sun's default (mixed), 16 px panoramas, 1 spp, a 128 px
sky.exr; then two glTF exports through the add-on's hook: the exporter's default lighting mode
(Standard) with Punctual Lights off, and Raw with Punctual Lights on and two Sun lamps of its own
added after the bake (the hook's light next to the exporter's; one with an Emission node of
Strength 1.5).
"""
import importlib
import json
import os
import sys
import traceback

import addon_utils
import bpy

work = sys.argv[sys.argv.index("--") + 1]
HDRI = "sunrise.exr"
out = {"blender": list(bpy.app.version)}


def main():
    name = next((m.__name__ for m in addon_utils.modules() if m.__name__.split(".")[-1] == "schnee_probes"), None)
    if name is not None:
        assert addon_utils.enable(name, default_set=True) is not None, "enabling the add-on failed"
    else:  # the host's source tree on PYTHONPATH (a run by hand in Blender 3.4)
        name = "schnee_probes"
        importlib.import_module(name).register()
    addon_utils.enable("io_scene_gltf2", default_set=True)
    native = importlib.import_module(name + ".native")

    for ob in list(bpy.data.objects):  # the startup file's cube, camera and lamp
        bpy.data.objects.remove(ob)
    scene = bpy.context.scene
    scene.render.engine = 'CYCLES'
    folder = bpy.utils.system_resource('DATAFILES', path=os.path.join("studiolights", "world"))
    hdri = os.path.join(folder, HDRI)
    out["hdri"] = hdri  # the host reads the same file (through the chroot's root) for the expected sun
    world = bpy.data.worlds.new("Sunrise")
    world.use_nodes = True
    nt = world.node_tree
    nt.nodes.clear()
    env = nt.nodes.new("ShaderNodeTexEnvironment")
    env.image = bpy.data.images.load(hdri, check_existing=True)
    bg = nt.nodes.new("ShaderNodeBackground")
    bg.inputs["Strength"].default_value = 1.0
    wout = nt.nodes.new("ShaderNodeOutputWorld")
    nt.links.new(env.outputs["Color"], bg.inputs["Color"])
    nt.links.new(bg.outputs["Background"], wout.inputs["Surface"])
    scene.world = world

    bpy.ops.mesh.primitive_cube_add(size=2.0, location=(0.0, 0.0, 1.0))
    vol = bpy.context.active_object
    vol.name = "Volume"
    coll = bpy.data.collections.new("ProbeVolumes")
    scene.collection.children.link(coll)
    for c in list(vol.users_collection):
        c.objects.unlink(vol)
    coll.objects.link(vol)
    bpy.ops.mesh.primitive_plane_add(size=0.5, location=(5.0, 0.0, 0.0))
    bpy.context.active_object.name = "Marker"
    bpy.context.active_object.hide_render = True   # exported, never seen by a probe
    bpy.ops.wm.save_as_mainfile(filepath=os.path.join(work, "scene.blend"))

    p = scene.schnee_probes
    out["default_sky_sun"] = p.sky_sun   # the bake below runs at the default
    p.min_cell_size = p.max_cell_size = 2.0
    p.panorama_resolution = 16
    p.samples = 1
    p.capture_sky = True
    p.sky_resolution = 128
    out["bake"] = sorted(bpy.ops.schnee.bake_sh_volumes())
    out["bake_message"] = p.last_message
    sh = os.path.join(work, "sh_coeffs")
    out["files"] = sorted(os.listdir(sh)) if os.path.isdir(sh) else []
    sun_path = os.path.join(sh, "sun.json")
    if os.path.exists(sun_path):
        with open(sun_path, encoding="utf-8") as fh:
            out["sun"] = json.load(fh)
    f = native.read_shprobe(os.path.join(sh, "probes.shprobe"))
    out["probe_count"] = f.probe_count
    out["coeffs"] = f.coeffs.tolist()
    bpy.ops.wm.save_mainfile()

    # Export 1: the exporter's defaults (Standard lighting mode, Punctual Lights off).
    spec = os.path.join(work, "export_spec", "scene.gltf")
    os.makedirs(os.path.dirname(spec), exist_ok=True)
    out["export_spec"] = sorted(bpy.ops.export_scene.gltf(filepath=spec, export_format='GLTF_SEPARATE',
                                                          export_lights=False))
    # Export 2: Raw lighting mode, Punctual Lights on, with a Sun lamp of the scene's own.
    data = bpy.data.lights.new("LampSun", 'SUN')
    data.energy = 2.0
    lamp = bpy.data.objects.new("LampSun", data)
    lamp.location = (0.0, 0.0, 4.0)
    scene.collection.objects.link(lamp)
    # One more with the Emission node's Strength at 1.5 (Cycles renders 2 x 1.5 W/m²).
    data = bpy.data.lights.new("NodeSun", 'SUN')
    data.energy = 2.0
    data.use_nodes = True   # 4.3: creates the node tree; 5.x: every lamp has one
    next(n for n in data.node_tree.nodes if n.type == 'EMISSION').inputs["Strength"].default_value = 1.5
    lamp = bpy.data.objects.new("NodeSun", data)
    scene.collection.objects.link(lamp)
    raw = os.path.join(work, "export_raw", "scene.gltf")
    os.makedirs(os.path.dirname(raw), exist_ok=True)
    out["export_raw"] = sorted(bpy.ops.export_scene.gltf(filepath=raw, export_format='GLTF_SEPARATE',
                                                         export_lights=True,
                                                         export_import_convert_lighting_mode='RAW'))


try:
    main()
except Exception:  # the pytest side shows the traceback with the RESULT so far
    out["error"] = traceback.format_exc()
print("RESULT " + json.dumps(out), flush=True)
