"""Run in Blender by test_daylight_box.py: builds scenes/make_daylight_box.py's box per case, renders
the floor from above with Cycles (direct light only) and ray-casts from the spheres' surfaces towards
the sun through Blender's own geometry; writes what it saw as JSON for the test to compare with the
closed form (make_daylight_box.sun_lit).

    blender -b --factory-startup -P tests/bench/daylight_box_check.py -- OUT.json CASE [CASE ...]
"""
import json
import os
import sys

import bpy
import numpy as np
from mathutils import Vector

REPO = os.environ.get("SCHNEE_REPO") or os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))
sys.path.insert(0, os.path.join(REPO, "scenes"))
import make_daylight_box as box  # noqa: E402

W, H = 80, 60                      # 5 cm pixels over the 4 x 3 m floor
SAMPLES = 16


def render_floor(scene, path):
    cam_data = bpy.data.cameras.new("FloorCam")
    cam_data.type = 'ORTHO'
    cam_data.ortho_scale = box.ROOM_MAX[0] - box.ROOM_MIN[0]
    cam = bpy.data.objects.new("FloorCam", cam_data)
    scene.collection.objects.link(cam)
    cam.location = (0.5 * (box.ROOM_MIN[0] + box.ROOM_MAX[0]), 0.5 * (box.ROOM_MIN[1] + box.ROOM_MAX[1]),
                    box.ROOM_MAX[2] - 0.05)
    cam.rotation_euler = (0.0, 0.0, 0.0)            # looking down -Z, image up = +Y
    scene.camera = cam
    r = scene.render
    r.engine = 'CYCLES'
    r.resolution_x, r.resolution_y, r.resolution_percentage = W, H, 100
    r.image_settings.file_format = 'OPEN_EXR'
    r.image_settings.color_depth = '32'
    r.filepath = path
    scene.cycles.samples = SAMPLES
    scene.cycles.max_bounces = 0                   # direct light only: the sun's patch is sharp
    scene.cycles.use_denoising = False
    scene.cycles.use_adaptive_sampling = False
    scene.cycles.pixel_filter_type = 'BOX'
    scene.cycles.filter_width = 1.0
    scene.view_settings.view_transform = 'Standard'
    bpy.ops.render.render(write_still=True)
    img = bpy.data.images.load(path)
    buf = np.empty(W * H * img.channels, dtype=np.float32)
    img.pixels.foreach_get(buf)
    return buf.reshape(H, W, img.channels)[::-1, :, :3]   # row 0 at the top


def main():
    argv = sys.argv[sys.argv.index("--") + 1:]
    out_path, cases = argv[0], argv[1:]
    result = {}
    for case in cases:
        scene = box.build(case)
        hidden = list(bpy.data.collections["Movable"].objects) + list(bpy.data.collections["ProbeVolumes"].objects)
        for ob in hidden:
            ob.hide_render = True
            ob.hide_viewport = True        # out of scene.ray_cast's depsgraph as well
        bpy.context.view_layer.update()
        img = render_floor(scene, os.path.join(os.path.dirname(out_path), f"floor_{case}.exr"))
        # Rays from each sphere's surface points towards the sun, against the room as Blender has it.
        dirs = np.random.default_rng(3).normal(size=(200, 3))
        dirs /= np.linalg.norm(dirs, axis=1, keepdims=True)
        deps = bpy.context.evaluated_depsgraph_get()
        to_sun = Vector(box.TO_SUN)
        casts = {}
        for name, centre, _cam, _cls in box.SPHERES:
            pts = np.array(centre) + box.RADIUS * dirs
            hits = [scene.ray_cast(deps, Vector(p), to_sun)[0] for p in pts]
            casts[name] = {"points": pts.tolist(), "blender_lit": [not h for h in hits]}
        world = scene.world.node_tree
        mapping = [n for n in world.nodes if n.type == 'MAPPING']
        result[case] = {"floor": img.tolist(), "spheres": casts,
                        "lamps": [ob.name for ob in scene.objects if ob.type == 'LIGHT'],
                        "hdri_sun": list(scene.get("daylight_hdri_sun", [])),
                        "mapping_rotation": list(mapping[0].inputs["Rotation"].default_value) if mapping else None,
                        "volumes": [[list(ob.bound_box[0]), list(ob.bound_box[6]), list(ob.location)]
                                    for ob in bpy.data.collections["ProbeVolumes"].objects]}
    with open(out_path, "w", encoding="utf-8") as fh:
        json.dump(result, fh)


main()
