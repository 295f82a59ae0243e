"""Render a Blender world HDRI as a Cycles equirect panorama and save it as .npy (row 0 at the top).

    blender -b --factory-startup -P cycles_convention_hdri_render.py -- HDRI_NAME WIDTH SPP FILTER FWIDTH OUT.npy

Used by cycles_convention_filter_model.py --cycles to compare real renders with the filter model.
"""
import math
import sys

import bpy
import numpy as np

name, width, spp, filt, fwidth, out = sys.argv[sys.argv.index("--") + 1:][:6]
scene = bpy.context.scene
for obj in list(bpy.data.objects):
    bpy.data.objects.remove(obj, do_unlink=True)
world = bpy.data.worlds.new("HDRI")
world.use_nodes = True
nodes = world.node_tree.nodes
tex = nodes.new("ShaderNodeTexEnvironment")
tex.image = bpy.data.images.load("/usr/share/blender/datafiles/studiolights/world/%s.exr" % name)
world.node_tree.links.new(tex.outputs["Color"], nodes["Background"].inputs["Color"])
scene.world = world
cam_data = bpy.data.cameras.new("Pano")
cam_data.type = "PANO"
cam_data.cycles.panorama_type = "EQUIRECTANGULAR"
cam = bpy.data.objects.new("Pano", cam_data)
scene.collection.objects.link(cam)
cam.rotation_euler = (math.radians(90.0), 0.0, math.radians(-90.0))
scene.camera = cam
scene.render.engine = "CYCLES"
scene.cycles.device = "CPU"
scene.cycles.use_denoising = False
scene.cycles.use_adaptive_sampling = False
scene.cycles.samples = int(spp)
scene.cycles.pixel_filter_type = filt
scene.cycles.filter_width = float(fwidth)
scene.render.threads_mode = "FIXED"
scene.render.threads = 2
scene.render.resolution_x = int(width)
scene.render.resolution_y = int(width) // 2
scene.render.resolution_percentage = 100
scene.render.image_settings.file_format = "OPEN_EXR"
scene.render.image_settings.color_depth = "32"
scene.render.filepath = out[:-4] + ".exr"
bpy.ops.render.render(write_still=True)
img = bpy.data.images.load(scene.render.filepath)
w, h = img.size
px = np.empty(w * h * 4, dtype=np.float32)
img.pixels.foreach_get(px)
np.save(out, px.reshape(h, w, 4)[::-1, :, :3].copy())
