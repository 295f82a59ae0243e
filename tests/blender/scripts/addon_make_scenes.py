"""Writes the test scenes of tests/blender/test_addon_*.py: ``-- OUT_DIR``.

room.blend       4 x 4 x 2 m room (Blender x, y in -2..2, z in 0..2), solid walls outside the volume,
                 two 1 x 1 x 1 m furniture boxes on the 0.5 m grid: "BoxInstanced" reaches the scene
                 only as a collection instance, "BoxArray" only through an Array modifier (so the
                 bake must read evaluated geometry). Lit by courtyard.exr through a 1 x 1 m
                 window in the +Y wall.
sky.blend        sky only (courtyard.exr) with one 4 x 4 x 2 m volume, no geometry.
missing_collection.blend, empty_collection.blend, non_mesh.blend, open_volume.blend: bad input.
two_volumes.blend  sky.blend with the volume renamed "West Wing" and a second one, "East", beside it.
render_only.blend  sky.blend plus three 1 m solids inside the volume that only the render sees (see
                 RENDER_ONLY): one hidden in the viewport (monitor icon), one hidden with the eye,
                 and one 0.25 m slab whose render-only Array modifier stacks it to 1 m.
"""
import os
import sys

import bmesh
import bpy

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import addon_common as common  # noqa: E402
from addon_common import scene_lib as lib  # noqa: E402

ROOM_MIN, ROOM_MAX = (-2.0, -2.0, 0.0), (2.0, 2.0, 2.0)
# Where the two furniture boxes end up (Blender world space), for the tests' inside checks.
FURNITURE = {"BoxInstanced": ((-2.0, -2.0, 0.0), (-1.0, -1.0, 1.0)),
             "BoxArray": ((1.0, 0.0, 0.0), (2.0, 1.0, 1.0))}

# render_only.blend: Blender-space boxes of the render-only solids (after modifiers).
RENDER_ONLY = {"ViewportHidden": ((-2.0, -2.0, 0.0), (-1.0, -1.0, 1.0)),
               "EyeHidden": ((-2.0, 1.0, 0.0), (-1.0, 2.0, 1.0)),
               "RenderArray": ((1.0, 0.0, 0.0), (2.0, 1.0, 1.0))}


def room():
    lib.clear_scene()
    lib.hdri_world("courtyard.exr")
    walls = lib.collection("Room")
    plaster = lib.diffuse_material("Plaster", (0.7, 0.7, 0.7))
    lib.room_walls(ROOM_MIN, ROOM_MAX, coll=walls, material=plaster, window=(-0.5, 0.5, 0.5, 1.5))
    # BoxInstanced: a box in a collection excluded from the view layer, instanced by an empty.
    proto = lib.collection("Proto")
    lib.box("BoxInstanced", (10.0, 10.0, 0.0), (11.0, 11.0, 1.0), proto, plaster)
    bpy.context.view_layer.layer_collection.children["Proto"].exclude = True
    proto.instance_offset = (10.0, 10.0, 0.0)
    inst = bpy.data.objects.new("ProtoInstance", None)
    inst.instance_type = 'COLLECTION'
    inst.instance_collection = proto
    inst.location = (-2.0, -2.0, 0.0)
    walls.objects.link(inst)
    # BoxArray: a 1 x 1 x 0.5 m box doubled upwards by an Array modifier.
    ob = lib.box("BoxArray", (1.0, 0.0, 0.0), (2.0, 1.0, 0.5), walls, plaster)
    mod = ob.modifiers.new("Array", 'ARRAY')
    mod.count = 2
    mod.relative_offset_displace = (0.0, 0.0, 1.0)
    lib.probe_volume("RoomVolume", ROOM_MIN, ROOM_MAX)


def sky():
    lib.clear_scene()
    lib.hdri_world("courtyard.exr")
    lib.probe_volume("SkyVolume", (-2.0, -2.0, 0.0), (2.0, 2.0, 2.0))


def render_only():
    sky()
    coll = lib.collection("Props")
    lo, hi = RENDER_ONLY["ViewportHidden"]
    lib.box("ViewportHidden", lo, hi, coll).hide_viewport = True
    lo, hi = RENDER_ONLY["EyeHidden"]
    lib.box("EyeHidden", lo, hi, coll).hide_set(True)
    lo, hi = RENDER_ONLY["RenderArray"]
    slab = lib.box("RenderArray", lo, (hi[0], hi[1], lo[2] + 0.25), coll)
    mod = slab.modifiers.new("Array", 'ARRAY')
    mod.count = 4
    mod.relative_offset_displace = (0.0, 0.0, 1.0)
    mod.show_viewport = False  # render only: the slab's 1 m cell centre (z 0.5) is inside only then


def main():
    out = common.args()[0]
    room()
    lib.save(os.path.join(out, "room.blend"))
    sky()
    lib.save(os.path.join(out, "sky.blend"))

    sky()
    bpy.data.collections.remove(bpy.data.collections["ProbeVolumes"])
    lib.save(os.path.join(out, "missing_collection.blend"))

    sky()
    bpy.data.objects.remove(bpy.data.objects["SkyVolume"])
    lib.save(os.path.join(out, "empty_collection.blend"))

    sky()
    empty = bpy.data.objects.new("NotAMesh", None)
    bpy.data.collections["ProbeVolumes"].objects.link(empty)
    lib.save(os.path.join(out, "non_mesh.blend"))

    sky()
    mesh = bpy.data.objects["SkyVolume"].data
    bm = bmesh.new()
    bm.from_mesh(mesh)
    bm.faces.ensure_lookup_table()
    bm.faces.remove(bm.faces[0])  # one side missing: the volume is open
    bm.to_mesh(mesh)
    bm.free()
    lib.save(os.path.join(out, "open_volume.blend"))

    sky()
    bpy.data.objects["SkyVolume"].name = "West Wing"
    lib.probe_volume("East", (2.0, -2.0, 0.0), (6.0, 2.0, 2.0))
    lib.save(os.path.join(out, "two_volumes.blend"))

    render_only()
    lib.save(os.path.join(out, "render_only.blend"))
    common.emit(furniture=FURNITURE, render_only=RENDER_ONLY)


main()
