"""Render tiny Cycles equirect panoramas of a black world with one small emissive square.

Run by tests/blender/test_cycles_convention.py through conftest.run_blender:
    blender -b --factory-startup -P cycles_convention.py -- OUT_DIR CASES_JSON
CASES_JSON is a list of {"name", "dir" (Blender world, unit), "width", "height", "samples",
"filter" (BLACKMAN_HARRIS | BOX | GAUSSIAN), "filter_width", "half_size", "distance", "strength"}.

Camera at the origin rotated (90°, 0, −90°), Cycles panorama EQUIRECTANGULAR (Blender 3.4 keeps it
in camera.data.cycles.panorama_type), 32-bit float EXR. For every case it writes NAME.exr (as Cycles
wrote it) and NAME.npy (H, W, 4) float32 with row 0 at the TOP (Blender's Image.pixels is bottom-up,
so it is flipped here), and finally OUT_DIR/cases_done.json.
"""
import json
import math
import os
import sys

import bpy
import numpy as np
from mathutils import Vector


def args():
    argv = sys.argv
    return argv[argv.index("--") + 1:] if "--" in argv else []


def clear_scene():
    for obj in list(bpy.data.objects):
        bpy.data.objects.remove(obj, do_unlink=True)
    for mesh in list(bpy.data.meshes):
        bpy.data.meshes.remove(mesh)


def black_world(scene):
    world = bpy.data.worlds.new("Black")
    world.use_nodes = True
    bg = world.node_tree.nodes["Background"]
    bg.inputs["Color"].default_value = (0.0, 0.0, 0.0, 1.0)
    bg.inputs["Strength"].default_value = 0.0
    scene.world = world


def emissive_square(name, direction, half_size, distance, strength):
    """A flat square of side 2·half_size centred at distance·direction, facing the origin."""
    d = Vector(direction).normalized()
    centre = d * distance
    # Orthonormal frame (u, v) perpendicular to d.
    helper = Vector((0.0, 0.0, 1.0)) if abs(d.z) < 0.9 else Vector((1.0, 0.0, 0.0))
    u = d.cross(helper).normalized()
    v = d.cross(u).normalized()
    corners = [centre + (su * u + sv * v) * half_size for su, sv in ((-1, -1), (1, -1), (1, 1), (-1, 1))]
    mesh = bpy.data.meshes.new(name)
    mesh.from_pydata([tuple(c) for c in corners], [], [(0, 1, 2, 3)])
    mesh.update()
    obj = bpy.data.objects.new(name, mesh)
    bpy.context.scene.collection.objects.link(obj)
    mat = bpy.data.materials.new(name + "Mat")
    mat.use_nodes = True
    nodes = mat.node_tree.nodes
    nodes.clear()
    emit = nodes.new("ShaderNodeEmission")
    emit.inputs["Color"].default_value = (1.0, 1.0, 1.0, 1.0)
    emit.inputs["Strength"].default_value = strength
    out = nodes.new("ShaderNodeOutputMaterial")
    mat.node_tree.links.new(emit.outputs["Emission"], out.inputs["Surface"])
    obj.data.materials.append(mat)
    return obj


def panorama_camera(scene):
    cam_data = bpy.data.cameras.new("Pano")
    cam_data.type = "PANO"
    cam_data.cycles.panorama_type = "EQUIRECTANGULAR"  # Blender 3.4 location of the setting
    cam = bpy.data.objects.new("Pano", cam_data)
    scene.collection.objects.link(cam)
    cam.location = (0.0, 0.0, 0.0)
    cam.rotation_euler = (math.radians(90.0), 0.0, math.radians(-90.0))
    scene.camera = cam
    return cam


def main():
    out_dir, cases_json = args()[:2]
    with open(cases_json) as f:
        cases = json.load(f)
    scene = bpy.context.scene
    clear_scene()
    black_world(scene)
    panorama_camera(scene)
    scene.render.engine = "CYCLES"
    scene.cycles.device = "CPU"
    scene.cycles.use_denoising = False  # Debian's Blender has no OpenImageDenoise
    scene.cycles.use_adaptive_sampling = False
    scene.render.threads_mode = "FIXED"
    scene.render.threads = 2
    scene.render.resolution_percentage = 100
    scene.render.film_transparent = False
    scene.render.use_compositing = False
    scene.render.use_sequencer = False
    settings = scene.render.image_settings
    settings.file_format = "OPEN_EXR"
    settings.color_depth = "32"
    settings.color_mode = "RGBA"

    done = []
    for case in cases:
        for obj in [o for o in scene.objects if o.type == "MESH"]:
            bpy.data.objects.remove(obj, do_unlink=True)
        emissive_square("Emitter", case["dir"], case["half_size"], case["distance"], case["strength"])
        scene.render.resolution_x = case["width"]
        scene.render.resolution_y = case["height"]
        scene.cycles.samples = case["samples"]
        scene.cycles.pixel_filter_type = case["filter"]
        scene.cycles.filter_width = case["filter_width"]
        exr = os.path.join(out_dir, case["name"] + ".exr")
        scene.render.filepath = exr
        bpy.ops.render.render(write_still=True)
        img = bpy.data.images.load(exr)
        w, h = img.size
        px = np.empty(w * h * 4, dtype=np.float32)
        img.pixels.foreach_get(px)
        bpy.data.images.remove(img)
        np.save(os.path.join(out_dir, case["name"] + ".npy"), px.reshape(h, w, 4)[::-1].copy())
        done.append(dict(case, exr=exr))
        print("cycles_convention: rendered", case["name"], w, h, flush=True)
    with open(os.path.join(out_dir, "cases_done.json"), "w") as f:
        json.dump(done, f, indent=1)


main()
