"""The add-on operators refuse outputs that are not theirs, and the estimate is refined by measured
times: ``blender -b sky.blend -P hazard_operator.py -- OUT_DIR``."""
import os
import sys

import bpy

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import addon_common as common  # noqa: E402

import schnee_probes  # noqa: E402
from schnee_probes import bake_core, estimate  # noqa: E402

out = common.args()[0]
schnee_probes.register()
scene = bpy.context.scene
props = common.tiny_bake_settings(scene)
results = {}


def run(op):
    """Operator result; in background mode an operator's ERROR report raises RuntimeError."""
    try:
        return sorted(op())
    except RuntimeError:
        return ["CANCELLED"]


# 1. Bake SH in Volumes onto a text file named like a probe file: refused, file unchanged.
foreign = os.path.join(out, "notes.shprobe")
with open(foreign, "w") as fh:
    fh.write("my notes\n")
props.output_path = foreign
results["volumes_result"] = run(bpy.ops.schnee.bake_sh_volumes)
results["volumes_message"] = props.last_message
results["foreign_unchanged"] = open(foreign).read() == "my notes\n"

# 2. Bake SH at Cursor next to a foreign debug_probe.txt: refused, unchanged.
folder = os.path.join(out, "cursor")
os.makedirs(folder)
props.output_path = os.path.join(folder, "probes.shprobe")
with open(os.path.join(folder, "debug_probe.txt"), "w") as fh:
    fh.write("not ours\n")
results["cursor_result"] = run(bpy.ops.schnee.bake_sh_cursor)
results["cursor_message"] = props.last_message
results["cursor_files"] = sorted(os.listdir(folder))

# 3. The estimate: the cost model before the first probe, then the measured mean per probe
#    (sky only renders ~25x faster than the closed-room model).
s = bake_core.BakeSettings(placement="OCTREE", min_cell_size=1.0, max_cell_size=1.0, panorama_resolution=128, samples=16,
                           output_path=os.path.join(out, "est", "probes.shprobe"), capture_sky=False)
bake = bake_core.ProbeBake(scene, bpy.context.view_layer, s, log=lambda line: None)
bake.prepare()
results["total"] = bake.total
results["estimated"] = bake.estimated_seconds
results["model_before"] = bake.remaining_seconds()
for _ in range(4):
    bake.step()
spent = bake.timings["render"] + bake.timings["write_exr"] + bake.timings["project"]
results["spent_4"] = spent
results["first_probe"] = bake.first_probe_seconds
results["remaining_after_4"] = bake.remaining_seconds()
results["model_after_4"] = estimate.estimate_seconds(bake.total - 4, s)
results["line"] = bake.progress_line()
bake.cancel()
common.emit(**results)
