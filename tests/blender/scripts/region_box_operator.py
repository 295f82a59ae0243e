"""Rebake Selected Region, the panel's button (tests/blender/test_region_rebake.py):
``blender -b two_rooms_edited.blend -P region_box_operator.py -- ADDON_PARENT X0 Y0 Z0 X1 Y1 Z1`` beside
a previous bake of both volumes (1 m cells, 16 px, 1 sample, geometry octree, One File per Volume).
Self-contained (the add-on from ADDON_PARENT, no scene library), so the same file runs in Blender 3.4
and in the 4.3 / 5.2 chroots. With SCHNEE_TEST_RENDER_LOG set, every render is logged as
count_renders.py (beside this file) does.

Adds "RegionBox", a cube mesh hidden from renders whose world box is X0..X1 (a cube of half that
size, scaled and moved, so the box goes through matrix_world), and reports in one RESULT line: the
operator's poll with no active object, a lamp, the volume Left, a Cube and a Plain Axes empty and the
box; three refusals with the files' SHA-256 after each (the box stretched over both volumes, moved
out of them, then in place with One File per Volume off: the bake's own refusal), and the box's own
rebake (its result, report and the files it wrote); then, with the
box moved back, the same rebake from a Cube empty of the same world box."""
import hashlib
import json
import os
import runpy
import sys

import bpy

argv = sys.argv[sys.argv.index("--") + 1:]
sys.path.insert(0, argv[0])
HERE = os.path.dirname(os.path.abspath(__file__))
if os.environ.get("SCHNEE_TEST_RENDER_LOG"):
    runpy.run_path(os.path.join(HERE, "count_renders.py"))

import schnee_probes  # noqa: E402

lo, hi = [float(x) for x in argv[1:4]], [float(x) for x in argv[4:7]]
schnee_probes.register()
scene = bpy.context.scene
props = scene.schnee_probes
props.placement = "OCTREE"
props.min_cell_size = props.max_cell_size = 1.0
props.panorama_resolution = 16
props.samples = 1
props.per_volume_files = True
out = os.path.join(os.path.dirname(bpy.data.filepath), "sh_coeffs")
layer = bpy.context.view_layer
op = bpy.ops.schnee.rebake_selected_region


def hashes():
    return {n: hashlib.sha256(open(os.path.join(out, n), "rb").read()).hexdigest() for n in sorted(os.listdir(out))}


def cube(name):
    mesh = bpy.data.meshes.new(name)
    v = [(x, y, z) for x in (-1, 1) for y in (-1, 1) for z in (-1, 1)]
    faces = [(0, 1, 3, 2), (4, 6, 7, 5), (0, 4, 5, 1), (2, 3, 7, 6), (0, 2, 6, 4), (1, 5, 7, 3)]
    mesh.from_pydata(v, [], faces)
    ob = bpy.data.objects.new(name, mesh)
    scene.collection.objects.link(ob)
    return ob


def place(ob, a, b):
    """Move and scale ``ob`` (a -1..1 cube) so that its world box is a..b."""
    ob.location = [(p + q) / 2 for p, q in zip(a, b)]
    ob.scale = [(q - p) / 2 for p, q in zip(a, b)]


def run():
    """The operator's result, its last report (props.last_message) and the files it wrote."""
    props.last_message, props.last_files = "", ""
    try:
        result = sorted(op())
        error = None
    except RuntimeError as exc:  # in background mode an ERROR report raises
        result, error = ["CANCELLED"], str(exc)
    return {"result": result, "error": error, "message": props.last_message,
            "files": sorted(os.path.basename(f) for f in props.last_files.split(";") if f)}


box = cube("RegionBox")
box.hide_render = True   # a marker, not scene geometry: Cycles and the bake's geometry leave it out
box.display_type = 'WIRE'
lamp = bpy.data.objects.new("Lamp", bpy.data.lights.new("Lamp", 'POINT'))
empty = bpy.data.objects.new("CubeEmpty", None)
empty.empty_display_type = 'CUBE'
axes = bpy.data.objects.new("Axes", None)
for ob in (lamp, empty, axes):
    scene.collection.objects.link(ob)
    ob.hide_render = True
r = {"label": op.get_rna_type().name, "version": list(bpy.app.version), "before": hashes(), "polls": {}}
for name in (None, "Lamp", "Left", "CubeEmpty", "Axes", "RegionBox"):
    layer.objects.active = None if name is None else bpy.data.objects[name]
    r["polls"][str(name)] = op.poll()

# Refusals: nothing may be written.
place(box, (lo[0], lo[1], lo[2]), (1.0, hi[1], hi[2]))        # over the wall x = 0 into Right
layer.objects.active = box
r["both"] = run()
r["after_both"] = hashes()
place(box, (5.0, 5.0, 0.0), (6.0, 6.0, 1.0))                   # beside the room
r["none"] = run()
r["after_none"] = hashes()
place(box, lo, hi)
props.per_volume_files = False                                 # the bake's own refusal, through the button
r["one_file"] = run()
r["after_one_file"] = hashes()
props.per_volume_files = True
r["box"] = run()
r["after_box"] = hashes()
# The same world box from a Cube empty (display size 0.5, scaled and moved): the same file again.
empty.empty_display_size = 0.5
empty.location = [(p + q) / 2 for p, q in zip(lo, hi)]
empty.scale = [(q - p) for p, q in zip(lo, hi)]
layer.objects.active = empty
r["empty"] = run()
r["after_empty"] = hashes()
print("RESULT " + json.dumps(r), flush=True)
