"""Both operators with the Cycles add-on disabled: ``blender -b sky.blend -P hazard_no_cycles.py --
OUT_DIR``. The output goes to OUT_DIR/sh_coeffs/probes.shprobe; prints one RESULT line with what the
operators returned and said, the files under OUT_DIR afterwards and the render settings before and
after (test_bake_hazards.py)."""
import os
import sys

import addon_utils
import bpy

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import addon_common as common  # noqa: E402

import schnee_probes  # noqa: E402

out = common.args()[0]
schnee_probes.register()
scene = bpy.context.scene
props = common.tiny_bake_settings(scene)
props.output_path = os.path.join(out, "sh_coeffs", "probes.shprobe")
addon_utils.disable("cycles", default_set=True)
results = {"cycles_enabled": list(addon_utils.check("cycles")), "scene_has_cycles": hasattr(scene, "cycles")}


def render_state():
    r = scene.render
    return [r.engine, r.resolution_x, r.resolution_y, r.image_settings.file_format, repr(scene.camera),
            sorted(ob.name for ob in scene.objects)]


def run(op):
    """Operator result; in background mode an operator's ERROR report raises RuntimeError."""
    try:
        return sorted(op())
    except RuntimeError:
        return ["CANCELLED"]


results["state_before"] = render_state()
results["volumes_result"] = run(bpy.ops.schnee.bake_sh_volumes)
results["volumes_message"] = props.last_message
scene.cursor.location = (0.5, 0.5, 1.0)
results["cursor_result"] = run(bpy.ops.schnee.bake_sh_cursor)
results["cursor_message"] = props.last_message
results["state_after"] = render_state()
results["files"] = sorted(os.path.relpath(os.path.join(d, f), out) for d, _, fs in os.walk(out) for f in fs)
common.emit(**results)
