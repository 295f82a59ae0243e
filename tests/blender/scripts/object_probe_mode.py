"""The per-object probe mode in Blender (issue 31 item 2; probe_modes.py, docs/export.md "Node"):
``blender -b --factory-startup -P object_probe_mode.py -- WORK_DIR``.

WORK_DIR/scene/sh_coeffs/probes.shprobe must exist (the test writes it). Builds four 2 m planes that
share one mesh and one white material whose custom property schnee_probe_mode is "object", side by
side along X at z = 0.1 (OffPlane Off, PixelPlane Per Pixel, MaterialPlane as its materials say,
CubePlane Ambient Cube, through Object.schnee_probe.mode), a lamp chosen Per Pixel too (no mesh: no
field) and a look-down orthographic camera; saves WORK_DIR/scene/scene.blend, exports
WORK_DIR/on/scene.gltf and WORK_DIR/off/scene.gltf (checkbox off), draws the Object panel into a
recording layout, checks the property across disable / enable and a reopen of the saved file, and
sets two selected planes at once (schnee.set_probe_mode). Emits one RESULT line.
"""
import os
import sys

import addon_utils
import bpy

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import addon_common as common  # noqa: E402
from recording_layout import RecordingLayout  # noqa: E402

PLANES = {"OffPlane": (-4.5, 'OFF'), "PixelPlane": (-1.5, 'PIXEL'), "MaterialPlane": (1.5, None),
          "CubePlane": (4.5, 'AMBIENT_CUBE')}


def registered():
    return {"object_property": hasattr(bpy.types.Object, "schnee_probe"),
            "object_panel": hasattr(bpy.types, "OBJECT_PT_schnee_probes"),
            "sidebar_panel": hasattr(bpy.types, "VIEW3D_PT_schnee_object"),
            "operator": "set_probe_mode" in dir(bpy.ops.schnee)}


def choices():
    return {name: bpy.data.objects[name].schnee_probe.mode if hasattr(bpy.types.Object, "schnee_probe") else None
            for name in PLANES}


def build(work):
    for ob in list(bpy.data.objects):
        bpy.data.objects.remove(ob)
    scene = bpy.context.scene
    mat = bpy.data.materials.new("Shared")
    mat.use_nodes = True
    bsdf = mat.node_tree.nodes["Principled BSDF"]
    bsdf.inputs["Base Color"].default_value = (1.0, 1.0, 1.0, 1.0)
    bsdf.inputs["Metallic"].default_value = 0.0
    mat["schnee_probe_mode"] = "object"
    mesh = bpy.data.meshes.new("Plane")
    mesh.from_pydata([(-1, -1, 0), (1, -1, 0), (1, 1, 0), (-1, 1, 0)], [], [(0, 1, 2, 3)])
    mesh.uv_layers.new(name="UVMap")
    mesh.materials.append(mat)
    mesh.update()
    for name, (x, mode) in PLANES.items():
        ob = bpy.data.objects.new(name, mesh)  # one mesh for all: the mode is the object's, not the mesh's
        ob.location = (x, 0.0, 0.1)
        if mode is not None:
            ob.schnee_probe.mode = mode
        scene.collection.objects.link(ob)
    lamp = bpy.data.objects.new("Lamp", bpy.data.lights.new("Lamp", 'POINT'))
    lamp.location = (0.0, 0.0, 3.0)
    lamp.schnee_probe.mode = 'PIXEL'  # the property exists on every object; a lamp's node has no mesh
    scene.collection.objects.link(lamp)
    cam = bpy.data.objects.new("Top", bpy.data.cameras.new("Top"))
    cam.data.type = 'ORTHO'
    cam.data.ortho_scale = 12.0
    cam.location = (0.0, 0.0, 5.0)  # rotation 0: looks down -Z, up +Y
    scene.collection.objects.link(cam)
    scene.camera = cam
    scene.render.resolution_x, scene.render.resolution_y = 120, 40
    path = os.path.join(work, "scene", "scene.blend")
    bpy.ops.wm.save_as_mainfile(filepath=path)
    return scene, path


def draw_panel(ob):
    """Properties > Object's panel drawn into a recording layout that checks each property exists."""
    from schnee_probes import panel
    log = []
    ctx = type("C", (), {"object": ob})()
    assert panel.OBJECT_PT_schnee_probes.poll(ctx)
    panel.OBJECT_PT_schnee_probes.draw(type("P", (), {"layout": RecordingLayout(log)})(), ctx)
    return log


def main():
    work = common.args()[0]
    out = {}
    addon_utils.enable("io_scene_gltf2", default_set=True)
    assert addon_utils.enable("schnee_probes", default_set=True) is not None
    from schnee_probes import gltf_export, panel, probe_modes
    out["exporter_modes"] = list(gltf_export.PROBE_MODES)
    out["exporter_representations"] = list(gltf_export.PROBE_REPRESENTATIONS)
    out["choice_fields"] = {c[0]: c[2] for c in probe_modes.CHOICES}
    out["enum_items"] = [i.identifier for i in bpy.types.Object.bl_rna.properties["schnee_probe"]
                         .fixed_type.properties["mode"].enum_items]
    out["enabled"] = registered()
    scene, path = build(work)
    out["default"] = bpy.data.objects["MaterialPlane"].schnee_probe.mode
    out["panel_material"] = draw_panel(bpy.data.objects["MaterialPlane"])
    out["panel_pixel"] = draw_panel(bpy.data.objects["PixelPlane"])
    lamp_ctx = type("C", (), {"object": bpy.data.objects["Lamp"]})()
    out["panel_poll_lamp"] = panel.OBJECT_PT_schnee_probes.poll(lamp_ctx)
    for which, enabled in (("on", True), ("off", False)):
        scene.schnee_gltf_export.enabled = enabled
        gltf = os.path.join(work, which, "scene.gltf")
        os.makedirs(os.path.dirname(gltf), exist_ok=True)
        out["export_" + which] = sorted(bpy.ops.export_scene.gltf(
            filepath=gltf, export_format="GLTF_SEPARATE", export_cameras=True, export_lights=True))
    scene.schnee_gltf_export.enabled = True
    bpy.ops.wm.save_mainfile()
    out["set"] = choices()
    addon_utils.disable("schnee_probes", default_set=True)
    out["disabled"] = registered()
    assert addon_utils.enable("schnee_probes", default_set=True) is not None
    out["enabled_again"] = registered()
    out["enabled_again_choices"] = choices()
    bpy.ops.wm.open_mainfile(filepath=path)
    out["reopened_choices"] = choices()
    # Set All Selected Objects: OffPlane active, MaterialPlane and the lamp selected.
    layer = bpy.context.view_layer
    for ob in layer.objects:
        ob.select_set(ob.name in ("OffPlane", "MaterialPlane", "Lamp"))
    layer.objects.active = bpy.data.objects["OffPlane"]
    out["set_selected"] = sorted(bpy.ops.schnee.set_probe_mode(mode='OBJECT'))
    out["after_set_selected"] = dict(choices(), Lamp=bpy.data.objects["Lamp"].schnee_probe.mode)
    common.emit(**out)


main()
