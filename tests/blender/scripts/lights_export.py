"""Light modes in the glTF export: ``blender -b --factory-startup -P lights_export.py -- OUT_DIR``.

Builds a cube and lamps of every punctual type: without a mode (the default by type, light_modes.py),
with the legacy custom property ``schnee_light_mode`` and with the registered property
``Object.schnee_light.mode``; two lamp objects sharing one light datablock with different modes,
one with a bad value, and an area lamp (not a glTF punctual light); exports OUT_DIR/on/scene.gltf (checkbox on) and
OUT_DIR/off/scene.gltf (checkbox off), both with Punctual Lights on in the exporter's default
Lighting Mode (Standard), and OUT_DIR/raw, OUT_DIR/compat in the other two. Emits the expected mode
and Blender's strength per lamp object.
"""
import os
import sys

import addon_utils
import bpy

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import addon_common as common  # noqa: E402

# The add-on must be enabled (in preferences) for the exporter to find its user extension.
addon_utils.enable("io_scene_gltf2", default_set=True)
assert addon_utils.enable("schnee_probes", default_set=True) is not None

# name: (light type, datablock name, mode, location). Mode: None = none chosen; lower or mixed case =
# the legacy custom property schnee_light_mode; upper case = Object.schnee_light.mode.
LAMPS = {
    "PlainPoint": ('POINT', "PlainPointData", None, (2, 0, 2)),
    "PlainSun": ('SUN', "PlainSunData", None, (0, 1, 5)),
    "PlainSpot": ('SPOT', "PlainSpotData", None, (1, 2, 3)),
    "BigPoint": ('POINT', "BigPointData", None, (2, 2, 2)),
    "ChosenBakedSun": ('SUN', "ChosenSunData", "BAKED", (-1, 1, 5)),
    "BakedPoint": ('POINT', "BakedPointData", "baked", (-2, 0, 2)),
    "RealtimeSpot": ('SPOT', "SpotData", "realtime", (0, 2, 3)),
    "RealtimeSun": ('SUN', "SunData", "realtime", (0, 0, 5)),
    "MixedSun": ('SUN', "MixedSunData", "mixed", (1, -1, 5)),
    "TwinBaked": ('POINT', "TwinData", "baked", (1, 1, 1)),
    "TwinRealtime": ('POINT', "TwinData", "realtime", (-1, -1, 1)),
    "BadMode": ('POINT', "BadData", "Realtime", (0, -2, 2)),
    "AreaRealtime": ('AREA', "AreaData", "realtime", (0, 0, 4)),
}


def build():
    for ob in list(bpy.data.objects):
        bpy.data.objects.remove(ob)
    scene = bpy.context.scene
    mesh = bpy.data.meshes.new("Cube")
    verts = [(x, y, z) for x in (-0.5, 0.5) for y in (-0.5, 0.5) for z in (-0.5, 0.5)]
    mesh.from_pydata(verts, [], [(0, 1, 3, 2), (4, 6, 7, 5), (0, 4, 5, 1), (2, 3, 7, 6), (0, 2, 6, 4), (1, 5, 7, 3)])
    mesh.update()
    scene.collection.objects.link(bpy.data.objects.new("Cube", mesh))
    for name, (kind, data_name, mode, loc) in LAMPS.items():
        data = bpy.data.lights.get(data_name) or bpy.data.lights.new(data_name, kind)
        ob = bpy.data.objects.new(name, data)
        ob.location = loc
        if name == "BigPoint":
            data.shadow_soft_size = 0.5           # over light_modes.POINT_MIXED_MAX_RADIUS: baked
        if mode is not None and mode.isupper():
            ob.schnee_light.mode = mode
        elif mode is not None:
            ob["schnee_light_mode"] = mode
        scene.collection.objects.link(ob)
    return scene


def export(scene, path, enabled, lighting_mode="SPEC"):
    scene.schnee_gltf_export.enabled = enabled
    os.makedirs(os.path.dirname(path), exist_ok=True)
    bpy.ops.export_scene.gltf(filepath=path, export_format="GLTF_SEPARATE", export_lights=True,
                              convert_lighting_mode=lighting_mode)
    scene.schnee_gltf_export.enabled = True


def main():
    out = common.args()[0]
    scene = build()
    export(scene, os.path.join(out, "on", "scene.gltf"), True)
    export(scene, os.path.join(out, "off", "scene.gltf"), False)
    export(scene, os.path.join(out, "raw", "scene.gltf"), True, "RAW")
    export(scene, os.path.join(out, "compat", "scene.gltf"), True, "COMPAT")
    common.emit(lamps={name: {"data": v[1], "mode": v[2], "type": v[0],
                              "energy": float(bpy.data.objects[name].data.energy)} for name, v in LAMPS.items()})


if __name__ == "__main__":
    main()
