"""Scenes for tests/blender/test_bake_hazards.py: ``-- OUT_DIR``.

sky.blend            courtyard.exr sky, one 4 x 4 x 2 m volume (Blender -2..2, -2..2, 0..2), nothing else.
room.blend           sky.blend plus closed 0.2 m walls around the volume (renders cost a little more).
emission_inf.blend   sky.blend plus a 0.5 m box "HotBox" outside the volume whose material "Hot"
                     has an Emission node with Strength = inf (Blender stores 3.4e38).
emission_nan.blend   the same box, "GlowBox", material "NaNGlow": Principled BSDF Emission colour NaN.
emission_huge.blend  a 2 m box "HugeBox" beside the volume, material "Huge": Emission Strength 1e38
                     (finite, so not refused up front; at 4 spp the render's sum of samples
                     overflows float32 to Inf in the panorama).
image_missing.blend  sky.blend plus the box "Brick" whose material "Bricks" has an Image Texture of
                     the image "brick.png" at //textures/brick.png, a file that does not exist.
world_missing.blend  one volume under a world whose Environment Texture image "lost_sky.exr" points at
                     //hdri/lost_sky.exr, which does not exist.
emission_1e30.blend  the same box, "BrightBox", material "Bright": Emission Strength 1e30 (finite in
                     float32 at any sample count here, but far beyond half floats' 65504).
"""
import os
import sys

import bpy

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import addon_common as common  # noqa: E402
from addon_common import scene_lib as lib  # noqa: E402

out = common.args()[0]


def sky():
    lib.clear_scene()
    lib.hdri_world("courtyard.exr")
    lib.probe_volume("SkyVolume", (-2.0, -2.0, 0.0), (2.0, 2.0, 2.0))


def emissive(box_name, mat_name, setup, lo=(3.0, -0.25, 0.75), hi=(3.5, 0.25, 1.25)):
    sky()
    mat = bpy.data.materials.new(mat_name)
    mat.use_nodes = True
    setup(mat.node_tree)
    lib.box(box_name, lo, hi, lib.collection("Props"), mat)


def emission_node(tree, strength):
    nodes = tree.nodes
    em = nodes.new("ShaderNodeEmission")
    em.inputs["Strength"].default_value = strength
    out_node = next(n for n in nodes if n.type == 'OUTPUT_MATERIAL')
    tree.links.new(em.outputs[0], out_node.inputs["Surface"])


def nan_principled(tree):
    bsdf = next(n for n in tree.nodes if n.type == 'BSDF_PRINCIPLED')
    bsdf.inputs["Emission"].default_value = (float("nan"), 1.0, 1.0, 1.0)
    bsdf.inputs["Emission Strength"].default_value = 1.0


sky()
lib.save(os.path.join(out, "sky.blend"))
sky()
lib.room_walls((-2.0, -2.0, 0.0), (2.0, 2.0, 2.0), coll=lib.collection("Room"),
               material=lib.diffuse_material("Plaster", (0.7, 0.7, 0.7)))
lib.save(os.path.join(out, "room.blend"))
emissive("HotBox", "Hot", lambda t: emission_node(t, float("inf")))
lib.save(os.path.join(out, "emission_inf.blend"))
emissive("GlowBox", "NaNGlow", nan_principled)
lib.save(os.path.join(out, "emission_nan.blend"))
emissive("HugeBox", "Huge", lambda t: emission_node(t, 1e38), (2.5, -1.0, 0.0), (4.5, 1.0, 2.0))
lib.save(os.path.join(out, "emission_huge.blend"))
emissive("BrightBox", "Bright", lambda t: emission_node(t, 1e30), (2.5, -1.0, 0.0), (4.5, 1.0, 2.0))
lib.save(os.path.join(out, "emission_1e30.blend"))


def missing_image(name, rel):
    img = bpy.data.images.new(name, 4, 4, float_buffer=True)
    img.source = 'FILE'
    img.filepath = rel
    return img


def image_texture(tree, image):
    tex = tree.nodes.new("ShaderNodeTexImage")
    tex.image = image
    bsdf = next(n for n in tree.nodes if n.type == 'BSDF_PRINCIPLED')
    tree.links.new(tex.outputs["Color"], bsdf.inputs["Base Color"])


emissive("Brick", "Bricks", lambda t: image_texture(t, missing_image("brick.png", "//textures/brick.png")))
lib.save(os.path.join(out, "image_missing.blend"))
lib.clear_scene()
world = bpy.data.worlds.new("Lost")
world.use_nodes = True
env = world.node_tree.nodes.new("ShaderNodeTexEnvironment")
env.image = missing_image("lost_sky.exr", "//hdri/lost_sky.exr")
world.node_tree.links.new(env.outputs["Color"], world.node_tree.nodes["Background"].inputs["Color"])
bpy.context.scene.world = world
lib.probe_volume("SkyVolume", (-2.0, -2.0, 0.0), (2.0, 2.0, 2.0))
lib.save(os.path.join(out, "world_missing.blend"))
common.emit(ok=True)
