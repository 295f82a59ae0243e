"""Probe placement of the opened .blend through the add-on (geometry gathering + native octree),
without rendering: ``blender -b room.blend -P addon_placement.py -- MIN MAX [MIN MAX ...]``.
For each (MIN, MAX) pair of cell sizes, one after the other in this Blender (one launch, not one per
pair): emits the probe positions in Blender space and the grid, and the viewport/modifier state of
every object before and after (placement evaluates the scene as rendered, then must put it back)."""
import os
import sys

import bpy

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import addon_common as common  # noqa: E402

import schnee_probes  # noqa: E402
from schnee_probes import bake_core, scene_export  # noqa: E402

sizes = [float(x) for x in common.args()]
assert sizes and len(sizes) % 2 == 0, "MIN MAX pairs expected"
schnee_probes.register()


def viewport_state():
    vl = bpy.context.view_layer
    out = {}
    for ob in bpy.data.objects:
        out[ob.name] = [ob.hide_viewport, ob.hide_get(view_layer=vl) if ob.name in vl.objects else None,
                        [[m.name, m.show_viewport, m.show_render, getattr(m, "levels", None)]
                         for m in ob.modifiers]]
    for coll in bpy.data.collections:
        out["collection:" + coll.name] = coll.hide_viewport
    return out


def place(lo, hi):
    state_before = viewport_state()
    settings = bake_core.BakeSettings(placement="OCTREE", min_cell_size=lo, max_cell_size=hi, panorama_resolution=32,
                                      samples=1)
    bake = bake_core.ProbeBake(bpy.context.scene, bpy.context.view_layer, settings)
    try:
        bake.prepare()
    finally:
        bake.cancel()
    t = bake.targets[0]
    common.emit(min_cell=lo, max_cell=hi, count=bake.total,
                positions=scene_export.engine_to_blender(bake.positions).tolist(),
                grid_dims=list(t.grid_dims), grid_valid=int((t.grid >= 0).sum()), grid_size=int(t.grid.size),
                state_before=state_before, state_after=viewport_state())


for lo, hi in zip(sizes[0::2], sizes[1::2]):
    place(lo, hi)
