"""Rebake Selected Region in a real UI session (Blender under Xvfb with --enable-event-simulate;
tests/blender/test_region_rebake.py): ``blender two_rooms_edited.blend -P region_box_modal.py --
ADDON_PARENT X0 Y0 Z0 X1 Y1 Z1`` beside a previous bake of both volumes (1 m cells, 16 px, 1 sample,
geometry octree, One File per Volume).

With Confirm Above at 10 probes (Left has 15) the button's bake asks first: the operator returns and
Bake Many Probes? opens; a simulated Return confirms it, and the confirmed bake runs modally (the
region passed on by the dialog). Then a box over both volumes is refused. Emits RESULT with what
happened and the files' SHA-256 at each step; quits Blender itself."""
import hashlib
import json
import os
import sys

import bpy

argv = sys.argv[sys.argv.index("--") + 1:]
sys.path.insert(0, argv[0])

import schnee_probes  # noqa: E402
from schnee_probes import operators  # noqa: E402

lo, hi = [float(x) for x in argv[1:4]], [float(x) for x in argv[4:7]]
schnee_probes.register()
scene = bpy.context.scene
props = scene.schnee_probes
props.placement = "OCTREE"
props.min_cell_size = props.max_cell_size = 1.0
props.panorama_resolution = 16
props.samples = 1
props.per_volume_files = True
props.probe_limit = 10
out = os.path.join(os.path.dirname(bpy.data.filepath), "sh_coeffs")
Op = operators.SCHNEE_OT_bake_sh_volumes
results = {"ticks_waited": 0}
phase = ["start"]

mesh = bpy.data.meshes.new("RegionBox")
mesh.from_pydata([(x, y, z) for x in (-1, 1) for y in (-1, 1) for z in (-1, 1)], [],
                 [(0, 1, 3, 2), (4, 6, 7, 5), (0, 4, 5, 1), (2, 3, 7, 6), (0, 2, 6, 4), (1, 5, 7, 3)])
box = bpy.data.objects.new("RegionBox", mesh)
scene.collection.objects.link(box)
box.hide_render = True
box.display_type = 'WIRE'
box.location = [(p + q) / 2 for p, q in zip(lo, hi)]
box.scale = [(q - p) / 2 for p, q in zip(lo, hi)]
bpy.context.view_layer.objects.active = box


def hashes():
    return {n: hashlib.sha256(open(os.path.join(out, n), "rb").read()).hexdigest() for n in sorted(os.listdir(out))}


def override():
    win = bpy.context.window_manager.windows[0]
    area = next((a for a in win.screen.areas if a.type == 'VIEW_3D'), win.screen.areas[0])
    return win, dict(window=win, screen=win.screen, area=area)


def press(op_call):
    """The operator's result, or CANCELLED and the text of the ERROR report bpy.ops raises."""
    try:
        return sorted(op_call()), None
    except RuntimeError as exc:
        return ["CANCELLED"], str(exc)


def tick():
    win, ctx = override()
    if phase[0] == "start":
        results["before"] = hashes()
        with bpy.context.temp_override(**ctx):
            results["large"] = press(bpy.ops.schnee.rebake_selected_region)
        results["large_message"] = props.last_message
        results["large_running"] = Op._running
        results["after_large"] = hashes()
        phase[0] = "confirm"
    elif phase[0] == "confirm":
        win.event_simulate(type='RET', value='PRESS')
        win.event_simulate(type='RET', value='RELEASE')
        phase[0] = "wait"
    elif phase[0] == "wait":
        results["ticks_waited"] += 1
        results["running_seen"] = results.get("running_seen", False) or Op._running
        if (results["running_seen"] and not Op._running) or results["ticks_waited"] > 1200:
            results["confirmed_message"] = props.last_message
            results["files"] = sorted(os.path.basename(f) for f in props.last_files.split(";") if f)
            results["after_confirmed"] = hashes()
            box.location.x += 1.0   # lo.x + 1 .. hi.x + 1: over the wall x = 0 into Right
            with bpy.context.temp_override(**ctx):
                results["both"] = press(bpy.ops.schnee.rebake_selected_region)
            results["both_message"] = props.last_message
            results["after_both"] = hashes()
            print("RESULT " + json.dumps(results), flush=True)
            bpy.ops.wm.quit_blender()
            return None
    return 0.05


bpy.app.timers.register(tick, first_interval=1.0)
