"""Run before bake.py (``blender -b x.blend -P bake_state_probe.py -P bake.py -- ...``): sets odd
render settings, records the scene state, and at exit (bake.py ends with sys.exit, also after a
signal) prints ``RESULT {"diff": [...]}``: the properties that differ from before (expected: none)."""
import atexit
import json

import bpy


def snapshot():
    scene = bpy.context.scene
    r, c = scene.render, scene.cycles
    out = {f"render.{k}": getattr(r, k) for k in (
        "engine", "resolution_x", "resolution_y", "resolution_percentage", "film_transparent",
        "use_persistent_data", "use_compositing", "filepath")}
    out.update({f"image.{k}": getattr(r.image_settings, k) for k in ("file_format", "color_mode", "color_depth")})
    out.update({f"cycles.{k}": getattr(c, k) for k in (
        "samples", "max_bounces", "diffuse_bounces", "pixel_filter_type", "filter_width", "seed",
        "use_adaptive_sampling", "sample_clamp_indirect", "film_exposure")})
    out["view_layer.samples"] = bpy.context.view_layer.samples
    out["scene.camera"] = scene.camera.name if scene.camera else None
    out["objects"] = sorted(o.name for o in bpy.data.objects)
    out["cameras"] = sorted(c.name for c in bpy.data.cameras)
    for ob in bpy.data.objects:
        out[f"{ob.name}.hide_render"] = ob.hide_render
        out[f"{ob.name}.visible_camera"] = ob.visible_camera
    return out


scene = bpy.context.scene
scene.render.engine = 'BLENDER_EEVEE'
scene.render.resolution_x, scene.render.resolution_y, scene.render.resolution_percentage = 1234, 567, 37
scene.render.image_settings.file_format = 'PNG'
scene.cycles.samples, scene.cycles.max_bounces = 7, 3
scene.cycles.pixel_filter_type = 'GAUSSIAN'
BEFORE = snapshot()


def report():
    after = snapshot()
    diff = sorted(k for k in set(BEFORE) | set(after) if BEFORE.get(k) != after.get(k))
    print("RESULT " + json.dumps({"diff": diff, "engine": after["render.engine"]}), flush=True)


atexit.register(report)
