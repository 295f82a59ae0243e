"""Blender (headless): export the factory scene (cube, camera, point light) plus a smooth UV sphere
with Blender's own glTF exporter, so the engine reads the accessor layout Blender really writes.
Usage: blender -b --factory-startup -P blender_export_scene.py -- OUT.gltf"""
import sys

import bpy

out = sys.argv[sys.argv.index("--") + 1]
bpy.ops.mesh.primitive_uv_sphere_add(segments=32, ring_count=16, radius=0.75, location=(3.0, 0.0, 0.5))
bpy.ops.object.shade_smooth()
sphere = bpy.context.active_object
mat = bpy.data.materials.new("Red")
mat.use_nodes = True
mat.node_tree.nodes["Principled BSDF"].inputs["Base Color"].default_value = (0.8, 0.1, 0.1, 1.0)
sphere.data.materials.append(mat)
bpy.ops.export_scene.gltf(filepath=out, export_format="GLTF_SEPARATE", export_lights=True, export_cameras=True)
print("SCHNEE-TEST exported", out, flush=True)
