"""The bundled default scene: ``blender -b --factory-startup -P scenes/make_default_scene.py -- OUT.blend``

An interior room of 10 x 10 x 4 m (Blender x, y in -5..5, z in 0..4) with a 3 x 2 m window in the
+Y wall opening onto a sky lit by Blender's bundled ``sunset.exr``, an emissive ceiling panel, three
solid furniture boxes, a ProbeVolumes collection holding the room volume, a camera, and two movable
objects (VS Movable Diffuse material when nodes.py provides it). Options after OUT.blend:
``--hdri NAME`` (another bundled HDRI).
"""
import argparse
import os
import sys

import bpy

_HERE = os.path.dirname(os.path.abspath(__file__))
sys.path.insert(0, _HERE)
sys.path.append(os.path.join(os.path.dirname(_HERE), "addon"))  # for schnee_probes.nodes, if present
import scene_lib as lib  # noqa: E402

# Furniture: (name, min corner, max corner), all on the 0.5 m grid so probe counts are predictable.
FURNITURE = (
    ("Table", (-3.0, -3.0, 0.0), (-1.0, -2.0, 1.0)),
    ("Cabinet", (3.5, -4.5, 0.0), (4.5, -3.5, 2.0)),
    ("Sofa", (1.0, 2.0, 0.0), (3.5, 3.0, 1.0)),
)
ROOM_MIN, ROOM_MAX = (-5.0, -5.0, 0.0), (5.0, 5.0, 4.0)
WINDOW = (-1.5, 1.5, 1.0, 3.0)  # x0, x1, z0, z1 in the +Y wall


def build(hdri="sunset.exr"):
    scene = lib.clear_scene()
    lib.hdri_world(hdri)
    walls = lib.collection("Room")
    wall_mat = lib.diffuse_material("Plaster", (0.8, 0.78, 0.75))
    # Large static surfaces sample the probe grid per pixel (docs/engine.md, probe modes): one
    # probe per wall would light a whole wall with the light at its centre.
    wall_mat["schnee_probe_mode"] = "pixel"
    lib.room_walls(ROOM_MIN, ROOM_MAX, coll=walls, material=wall_mat, window=WINDOW)
    furn = lib.collection("Furniture")
    wood = lib.diffuse_material("Wood", (0.45, 0.25, 0.12))
    for name, a, b in FURNITURE:
        lib.box(name, a, b, furn, wood)
    panel_mat = lib.diffuse_material("PanelLight", (1, 1, 1), emission=(1.0, 0.95, 0.85), strength=8.0)
    lib.box("EmissivePanel", (-1.0, -0.5, 3.9), (1.0, 0.5, 4.0), walls, panel_mat)

    lib.probe_volume("RoomVolume", ROOM_MIN, ROOM_MAX)

    movable = lib.collection("Movable")
    mats = []
    for name, color in (("MovableRed", (0.8, 0.1, 0.1, 1.0)), ("MovableBlue", (0.1, 0.2, 0.8, 1.0))):
        mat = None
        try:
            from schnee_probes import nodes  # optional: another module of the add-on
            if hasattr(nodes, "make_movable_diffuse_material"):
                mat = nodes.make_movable_diffuse_material(name, base_color=color, sh_scale=1.0, ambient=0.1)
        except Exception as exc:  # the scene stays usable without the node group
            print(f"make_default_scene: movable material fallback ({exc})")
        mats.append(mat or lib.diffuse_material(name, color[:3]))
    bpy.ops.mesh.primitive_uv_sphere_add(radius=0.4, location=(1.5, -1.0, 0.9))
    sphere = bpy.context.active_object
    bpy.ops.mesh.primitive_monkey_add(size=0.6, location=(-2.0, 1.5, 0.8))
    monkey = bpy.context.active_object
    for ob, mat, name in ((sphere, mats[0], "MovableSphere"), (monkey, mats[1], "MovableMonkey")):
        ob.name = name
        ob.data.materials.append(mat)
        for c in list(ob.users_collection):
            c.objects.unlink(ob)
        movable.objects.link(ob)

    cam_data = bpy.data.cameras.new("Camera")
    cam = bpy.data.objects.new("Camera", cam_data)
    cam.location = (0.0, -4.5, 1.6)
    cam.rotation_euler = (1.5707963, 0.0, 0.0)  # looking along +Y, at the window
    cam_data.lens = 20
    scene.collection.objects.link(cam)
    scene.camera = cam
    scene.render.engine = 'CYCLES'
    scene.cycles.use_denoising = False  # Debian's Blender has no OpenImageDenoise
    scene.cursor.location = (0.0, -2.0, 1.5)
    return scene


def main():
    argv = sys.argv[sys.argv.index("--") + 1:] if "--" in sys.argv else []
    p = argparse.ArgumentParser(prog="make_default_scene.py")
    p.add_argument("output", help="the .blend to write")
    p.add_argument("--hdri", default="sunset.exr", help="bundled HDRI (studiolights/world)")
    args = p.parse_args(argv)
    build(args.hdri)
    print("saved", lib.save(args.output))


if __name__ == "__main__":
    main()
