"""Rebake Selected Volume, the panel's button (tests/blender/test_region_rebake.py):
``blender -b two_rooms_edited.blend -P region_operator.py`` beside a previous bake of both volumes
(1 m cells, 16 px, 1 sample, geometry octree, One File per Volume). Reports the operator's poll with
a wall, with no active object and with the volume Left active, its result and the files it wrote."""
import os
import sys

import bpy

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import addon_common as common  # noqa: E402

import schnee_probes  # noqa: E402

schnee_probes.register()
scene = bpy.context.scene
props = scene.schnee_probes
props.placement = "OCTREE"
props.min_cell_size = props.max_cell_size = 1.0
props.panorama_resolution = 16
props.samples = 1
props.per_volume_files = True
layer = bpy.context.view_layer
op = bpy.ops.schnee.rebake_selected_volume
results = {}
layer.objects.active = None
results["poll_none"] = op.poll()
layer.objects.active = bpy.data.objects["Crate"]
results["poll_crate"] = op.poll()
layer.objects.active = bpy.data.objects["Left"]
results["poll_left"] = op.poll()
try:
    results["result"] = sorted(op())
except RuntimeError as exc:  # in background mode an ERROR report raises
    results["result"] = ["CANCELLED", str(exc)]
results["files"] = sorted(os.path.basename(f) for f in props.last_files.split(";") if f)
results["message"] = props.last_message
results["label"] = op.get_rna_type().name
common.emit(**results)
