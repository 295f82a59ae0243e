"""Inside a Blender of any version, with the add-on installed into a fresh profile by Blender's own
install command: enable it, build a small scene, run the operators and the glTF export.
``-- WORK_DIR``. Prints one ``RESULT {json}`` line; pytest (test_blender_versions.py) checks it.

Scene: a uniform world of emission colour C (strength 1) and nothing else but a closed probe volume
(and one small mesh with the "VS Movable Diffuse" material, hidden from renders, so the glTF export
has a material; it casts nothing). Every probe then sees radiance C in every direction, so
L0 = C·∫Y00 dω = C·2√π exactly and the higher bands vanish (DESIGN.md §3).
"""
import json
import os
import sys
import traceback

import addon_utils
import bpy

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from recording_layout import RecordingLayout  # noqa: E402  (tests/blender/scripts, copied beside this file)

work = sys.argv[sys.argv.index("--") + 1]
COLOR = (0.25, 0.5, 1.0)
out = {"blender": list(bpy.app.version), "python": sys.version.split()[0]}


def rna_values(struct, prefix, acc, depth=0):
    """Writable non-pointer property values of ``struct`` (recursive into nested settings)."""
    for prop in struct.bl_rna.properties:
        ident = prop.identifier
        # As render_settings._SKIP: the denoisers read with warnings where OIDN is absent; a new
        # file's image linear colour space is unset ('', not a settable value) until a format
        # change gives it one.
        if ident in ("rna_type", "denoiser", "preview_denoiser", "linear_colorspace_settings"):
            continue
        if prop.type == 'POINTER':
            sub = getattr(struct, ident, None)
            if prop.is_readonly and depth < 2 and sub is not None and not isinstance(sub, bpy.types.ID):
                rna_values(sub, prefix + ident + ".", acc, depth + 1)
            elif not prop.is_readonly:
                acc[prefix + ident] = repr(sub)
            continue
        if prop.type == 'COLLECTION' or prop.is_readonly:
            continue
        value = getattr(struct, ident)
        acc[prefix + ident] = repr(tuple(value) if getattr(prop, "is_array", False) else value)
    return acc


def settings_snapshot(scene):
    acc = rna_values(scene.render, "render.", {})
    cycles = getattr(scene, "cycles", None)
    if cycles is not None:
        rna_values(cycles, "cycles.", acc)
    rna_values(scene.view_settings, "view_settings.", acc)
    acc["camera"] = repr(scene.camera)
    acc["objects"] = repr(sorted(o.name for o in scene.objects))
    return acc


def main():
    name = next(m.__name__ for m in addon_utils.modules() if m.__name__.split(".")[-1] == "schnee_probes")
    out["module"] = name
    addon_utils.enable("io_scene_gltf2", default_set=True)
    mod = addon_utils.enable(name, default_set=True)
    assert mod is not None, "enabling the add-on failed"
    import importlib
    native = importlib.import_module(name + ".native")
    compat = importlib.import_module(name + ".compat")
    bake_core = importlib.import_module(name + ".bake_core")
    out["module_file"] = mod.__file__
    out["native_problem"] = native.native_problem()
    out["native_file"] = native._native.__file__

    # --- scene
    for ob in list(bpy.data.objects):  # the startup file's cube, camera and lamp
        bpy.data.objects.remove(ob)
    scene = bpy.context.scene
    scene.render.engine = 'CYCLES'
    world = bpy.data.worlds.new("Uniform")
    world.use_nodes = True
    bg = next(n for n in world.node_tree.nodes if n.type == 'BACKGROUND')
    bg.inputs["Color"].default_value = COLOR + (1.0,)
    bg.inputs["Strength"].default_value = 1.0
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
    movable = bpy.context.active_object
    movable.name = "Movable"
    movable.hide_render = True
    bpy.ops.object.select_all(action='DESELECT')
    movable.select_set(True)
    bpy.context.view_layer.objects.active = movable
    out["add_material"] = sorted(bpy.ops.schnee.add_movable_diffuse())
    out["movable_material"] = movable.active_material.name if movable.active_material else None
    cam_data = bpy.data.cameras.new("Cam")
    cam = bpy.data.objects.new("Cam", cam_data)
    scene.collection.objects.link(cam)
    cam.location = (0.0, -8.0, 2.0)
    cam.rotation_euler = (1.4, 0.0, 0.0)
    scene.camera = cam
    blend = os.path.join(work, "scene.blend")
    bpy.ops.wm.save_as_mainfile(filepath=blend)

    p = scene.schnee_probes
    p.min_cell_size = p.max_cell_size = 1.0
    p.panorama_resolution = 16
    p.samples = 1

    # --- Bake SH in Volumes through the operator
    before = settings_snapshot(scene)
    res = bpy.ops.schnee.bake_sh_volumes()
    out["bake_volumes"] = sorted(res)
    out["bake_message"] = p.last_message
    shprobe = os.path.join(work, "sh_coeffs", "probes.shprobe")
    f = native.read_shprobe(shprobe)
    out["probe_count"] = f.probe_count
    out["l0"] = f.coeffs[:, 0, :].tolist()
    odd = [1, 2, 3, 4, 5, 7]  # odd under a reflection of the grid: all but Y00, Y20, Y22
    out["odd_max"] = float(abs(f.coeffs[:, odd, :]).max())
    after = settings_snapshot(scene)
    out["restored_after_bake"] = [(k, before[k], after.get(k)) for k in before if before[k] != after.get(k)]

    # --- Bake SH at Cursor
    scene.cursor.location = (0.3, 0.2, 1.1)
    out["bake_cursor"] = sorted(bpy.ops.schnee.bake_sh_cursor())
    debug = os.path.join(work, "sh_coeffs", "debug_probe.txt")
    out["debug_text"] = open(debug).read() if os.path.exists(debug) else None

    # --- cancel after one probe (what Esc does in the modal operator): settings restored, no file
    scene.render.resolution_x, scene.render.resolution_y = 123, 77
    cycles = compat.cycles_settings(scene)
    if cycles is not None:
        cycles.samples = 37
    before = settings_snapshot(scene)
    mtime = os.path.getmtime(shprobe)
    settings = bake_core.BakeSettings.from_props(p)
    bake = bake_core.ProbeBake(scene, bpy.context.view_layer, settings, mode="VOLUMES")
    bake.prepare()
    bake.step()
    bake.cancel()
    after = settings_snapshot(scene)
    out["cancel_changed"] = [(k, before[k], after.get(k)) for k in before if before[k] != after.get(k)]
    out["cancel_file_unchanged"] = os.path.getmtime(shprobe) == mtime

    # --- glTF export through the hook, checkbox on and off
    out["layout_draw"] = None
    registry = compat.gltf_layout_draw_registry()
    if registry is not None:
        out["layout_draw"] = getattr(registry.get(name), "__name__", None)
    else:
        out["layout_draw"] = getattr(getattr(mod, "register_panel", None), "__name__", None)
    bpy.ops.wm.save_mainfile()
    on = os.path.join(work, "export_on", "scene.gltf")
    off = os.path.join(work, "export_off", "scene.gltf")
    for path, enabled in ((on, True), (off, False)):
        os.makedirs(os.path.dirname(path), exist_ok=True)
        scene.schnee_gltf_export.enabled = enabled
        res = bpy.ops.export_scene.gltf(filepath=path, export_format='GLTF_SEPARATE')
        out["export_" + ("on" if enabled else "off")] = sorted(res)
    scene.schnee_gltf_export.enabled = True

    # --- light modes in the export: each lamp's resolved mode (light_modes.py), in a third file
    # with Punctual Lights on; the lamps go again before the save (the later bakes use the file).
    lamps = []
    for lamp_name, kind, how in (("DefaultSun", 'SUN', None), ("ChosenPoint", 'POINT', 'BAKED'),
                                 ("LegacySpot", 'SPOT', "realtime"), ("BigPoint", 'POINT', None)):
        ob = bpy.data.objects.new(lamp_name, bpy.data.lights.new(lamp_name, kind))
        ob.location = (0.0, 0.0, 3.0)
        if lamp_name == "BigPoint":
            ob.data.shadow_soft_size = 0.5
        if how is not None and how.isupper():
            ob.schnee_light.mode = how
        elif how is not None:
            ob["schnee_light_mode"] = how
        scene.collection.objects.link(ob)
        lamps.append(ob)
    lights = os.path.join(work, "export_lights", "scene.gltf")
    os.makedirs(os.path.dirname(lights), exist_ok=True)
    out["export_lights"] = sorted(bpy.ops.export_scene.gltf(filepath=lights, export_format='GLTF_SEPARATE',
                                                            export_lights=True))
    for ob in lamps:
        data = ob.data
        bpy.data.objects.remove(ob)
        bpy.data.lights.remove(data)

    # --- per-object probe modes (probe_modes.py, issue 31 item 2): four planes sharing one mesh and
    # one material (custom property schnee_probe_mode "object"), Object.schnee_probe.mode set on three;
    # exported in a fourth file, then removed again before the save (the later bakes use the file).
    modes = importlib.import_module(name + ".probe_modes")
    panel = importlib.import_module(name + ".panel")
    mat = bpy.data.materials.new("SharedMode")
    mat["schnee_probe_mode"] = "object"
    mesh = bpy.data.meshes.new("ModePlane")
    mesh.from_pydata([(-0.4, -0.4, 0), (0.4, -0.4, 0), (0.4, 0.4, 0), (-0.4, 0.4, 0)], [], [(0, 1, 2, 3)])
    mesh.materials.append(mat)
    planes = []
    for i, (plane_name, mode) in enumerate((("OffPlane", 'OFF'), ("PixelPlane", 'PIXEL'),
                                            ("MaterialPlane", None), ("CubePlane", 'AMBIENT_CUBE'))):
        ob = bpy.data.objects.new(plane_name, mesh)
        ob.location = (-1.5 + i, 0.0, 0.1)
        if mode is not None:
            ob.schnee_probe.mode = mode
        scene.collection.objects.link(ob)
        planes.append(ob)
    out["probe_mode_items"] = [i.identifier for i in bpy.types.Object.bl_rna.properties["schnee_probe"]
                               .fixed_type.properties["mode"].enum_items]
    out["probe_mode_fields"] = {ob.name: modes.node_fields(ob) for ob in planes}
    # Properties > Object's panel drawn into a recording layout (no window in background mode).
    log = []
    for ob in (planes[2], planes[1]):
        panel.OBJECT_PT_schnee_probes.draw(type("P", (), {"layout": RecordingLayout(log)})(),
                                           type("C", (), {"object": ob})())
    out["object_panel"] = log
    modes_path = os.path.join(work, "export_modes", "scene.gltf")
    os.makedirs(os.path.dirname(modes_path), exist_ok=True)
    out["export_modes"] = sorted(bpy.ops.export_scene.gltf(filepath=modes_path, export_format='GLTF_SEPARATE'))
    for ob in planes:
        bpy.data.objects.remove(ob)
    bpy.data.meshes.remove(mesh)
    bpy.data.materials.remove(mat)
    bpy.ops.wm.save_mainfile()


try:
    main()
except Exception:  # the pytest side shows the traceback with the RESULT so far
    out["error"] = traceback.format_exc()
print("RESULT " + json.dumps(out), flush=True)
