"""Render Device (settings.render_device) in real Blender, on a machine without a GPU: prints
``RESULT {...}`` for tests/blender/test_render_device.py.

    blender -b --factory-startup -P render_device.py -- ADDON_DIR

ADDON_DIR holds the ``schnee_probes`` package (the repository's addon/, or its copy inside a
chroot). A one-point bake (bake_core.ProbeBake, mode POINTS: the cursor bake's render session
without its debug file) of a tiny scene: a 16x8 px panorama at 1 spp, 2 bounces, inside a box lit
by a grey world through its open top, with Render Device GPU, CPU and As the scene is set, and the
scene's own device set to GPU or CPU before each; each bake records the device Cycles was given
while it rendered, the log lines and the values. Then the device labels with the Preferences'
compute device type set to each GPU type this Blender lists (none of them finds a device here).
"""
import json
import sys

import bpy

sys.path.insert(0, sys.argv[sys.argv.index("--") + 1])

from schnee_probes import bake_core, compat, panel, render_settings  # noqa: E402
from schnee_probes.settings import BakeSettings  # noqa: E402

if not hasattr(bpy.types.Scene, "schnee_probes"):
    import schnee_probes
    schnee_probes.register()


def make_scene():
    for ob in list(bpy.data.objects):
        bpy.data.objects.remove(ob)
    scene = bpy.context.scene
    world = scene.world or bpy.data.worlds.new("World")
    scene.world = world
    world.use_nodes = True
    world.node_tree.nodes["Background"].inputs["Color"].default_value = (0.6, 0.7, 0.8, 1.0)
    bpy.ops.mesh.primitive_cube_add(size=4.0, location=(0.0, 0.0, 0.0))
    box = bpy.context.active_object
    mesh = box.data
    top = [p.index for p in mesh.polygons if p.normal.z > 0.5]
    import bmesh
    bm = bmesh.new()
    bm.from_mesh(mesh)
    bm.faces.ensure_lookup_table()
    bmesh.ops.delete(bm, geom=[bm.faces[i] for i in top], context='FACES_ONLY')
    bm.to_mesh(mesh)
    bm.free()
    return scene


def bake(scene, render_device, scene_device):
    """One point baked with Render Device ``render_device`` after scene.cycles.device = scene_device."""
    scene.cycles.device = scene_device
    lines = []

    def log(line):
        lines.append(line)
        print(line, flush=True)
    settings = BakeSettings(panorama_resolution=16, samples=1, max_bounces=2, render_device=render_device)
    b = bake_core.ProbeBake(scene, bpy.context.view_layer, settings, mode="POINTS",
                            points=[[0.3, -0.2, 0.4]], log=log)
    during = {}
    try:
        b.prepare()
        during["device"] = scene.cycles.device
        during["label"] = render_settings.device_label(scene)
        while b.step():
            pass
        b.finish()
    except BaseException:
        b.cancel()
        raise
    return {"during": during["device"], "label": during["label"], "after": scene.cycles.device,
            "lines": lines, "coeffs": [float(v) for v in b.coeffs[0].ravel()]}


def labels_per_type():
    """device_label / apply_render_device with the Preferences' compute device type set to each GPU
    type this build lists (Debian's: CUDA and HIP); no device of any is found on this machine."""
    prefs = compat.cycles_preferences()
    old = prefs.compute_device_type
    out = {}
    scene = bpy.context.scene
    try:
        for kind in compat.GPU_DEVICE_TYPES:
            try:  # the enum's items are the types this build has (a callback: not in bl_rna)
                prefs.compute_device_type = kind
            except TypeError:
                continue
            scene.cycles.device = 'GPU'
            lines = []
            out[kind] = {"scene_label": render_settings.device_label(scene),
                         "gpu_label": render_settings.apply_render_device(scene, 'GPU', lines.append),
                         "device": scene.cycles.device, "lines": lines,
                         "devices": compat.cycles_gpu_devices(prefs)[1]}
    finally:
        prefs.compute_device_type = old
    return out


scene = make_scene()
result = {"version": list(bpy.app.version), "threads": scene.render.threads, "cases": {}}
for name, (render_device, scene_device) in {"gpu_on_gpu_scene": ('GPU', 'GPU'), "cpu": ('CPU', 'CPU'),
                                            "cpu_on_gpu_scene": ('CPU', 'GPU'),
                                            "scene_gpu": ('SCENE', 'GPU'), "scene_cpu": ('SCENE', 'CPU')}.items():
    result["cases"][name] = bake(scene, render_device, scene_device)
result["types"] = labels_per_type()


class Labels:
    """Records the labels panel._draw_device draws (no UILayout exists in blender -b)."""

    def __init__(self):
        self.texts = []

    def label(self, text="", **_kw):
        self.texts.append(text)


panel_labels = {}
props = scene.schnee_probes
for render_device in ('GPU', 'SCENE'):
    props.render_device = render_device
    scene.cycles.device = 'CPU'
    layout = Labels()
    panel._draw_device(layout, scene, props)
    panel_labels[render_device] = layout.texts + [scene.cycles.device]
result["panel"] = panel_labels
print("RESULT " + json.dumps(result), flush=True)
