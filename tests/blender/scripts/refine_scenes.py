"""Scenes of the adaptive-placement tests (tests/blender/test_refine_bake.py), built in Blender.

``shadow``: a black world, a bright emissive 3 m square 15 m away along +y (on the probes' horizon,
where the panorama's pixels are best) and a black vertical plane at y = 2.5 covering x < 0.25
(Blender space, Z-up): probes behind the plane do not see the emitter, the others do, so the light
jumps across the near-vertical plane x = boundary_x(y) (0.28-0.32 m for y in -1..1) within a
penumbra of ±penumbra_half(y) (0.18-0.42 m). The dark side is exactly black (no other light), the
lit side varies smoothly. Probe volume: the box x in [-4, 4], y in [-1, 1], z in [0, 2].

``open``: the same volume under a uniform world above a 200 m grey ground plane 1 m below it: the
light is the same everywhere (up to the plane's far edge), but bounces off the ground make it noisy.

Usage: blender -b --factory-startup -P refine_scenes.py -- OUT_DIR
"""
import math
import os
import sys

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import addon_common  # noqa: E402
from addon_common import emit  # noqa: E402

import bpy  # noqa: E402
import scene_lib  # noqa: E402

EDGE_X = 0.25          # the occluder's edge (Blender x)
WALL_Y = 2.5           # the occluder: a black vertical plane at y = 2.5 covering x < EDGE_X
EMITTER_Y = 15.0       # the emitter: a bright vertical square at y = 15 facing the volume
EMITTER_HALF = 1.5     # spans x in [-1.5, 1.5], z in [-0.5, 2.5]


def boundary_x(y):
    """Blender (and engine) x of the shadow boundary at Blender y: the ray to the emitter's centre
    grazing the occluder's edge; the penumbra around it is penumbra_half(y) wide on each side."""
    return EDGE_X * (EMITTER_Y - y) / (EMITTER_Y - WALL_Y)


def penumbra_half(y):
    return EMITTER_HALF * (WALL_Y - y) / (EMITTER_Y - WALL_Y)


def uniform_world(strength):
    world = bpy.context.scene.world
    world.use_nodes = True
    bg = world.node_tree.nodes["Background"]
    bg.inputs["Color"].default_value = (1.0, 1.0, 1.0, 1.0)
    bg.inputs["Strength"].default_value = strength


def vertical_plane(name, x0, x1, z0, z1, y, material):
    """A one-sided quad in the plane Blender y = ``y`` whose normal points to −y (at the volume: a
    probe that sees back faces counts as inside solid geometry, docs/placement.md)."""
    import bmesh
    mesh = bpy.data.meshes.new(name)
    bm = bmesh.new()
    vs = [bm.verts.new(v) for v in ((x0, y, z0), (x1, y, z0), (x1, y, z1), (x0, y, z1))]
    bm.faces.new(vs)
    bm.to_mesh(mesh)
    bm.free()
    ob = bpy.data.objects.new(name, mesh)
    bpy.context.scene.collection.objects.link(ob)
    mesh.materials.append(material)
    return ob


def emission_material(name, strength):
    mat = bpy.data.materials.new(name)
    mat.use_nodes = True
    nt = mat.node_tree
    nt.nodes.clear()
    em = nt.nodes.new("ShaderNodeEmission")
    em.inputs["Strength"].default_value = strength
    out = nt.nodes.new("ShaderNodeOutputMaterial")
    nt.links.new(em.outputs["Emission"], out.inputs["Surface"])
    return mat


def build(kind):
    scene_lib.clear_scene()
    scene = bpy.context.scene
    scene.render.engine = 'CYCLES'
    if kind == "shadow":
        uniform_world(0.0)
        vertical_plane("Emitter", -EMITTER_HALF, EMITTER_HALF, 1 - EMITTER_HALF, 1 + EMITTER_HALF, EMITTER_Y,
                       emission_material("Bright", 50.0))
        vertical_plane("Occluder", -30.0, EDGE_X, -30.0, 30.0, WALL_Y,
                       scene_lib.diffuse_material("Black", (0, 0, 0)))
    elif kind == "open":
        uniform_world(0.5)
        ground = vertical_plane("Ground", -100.0, 100.0, -100.0, 100.0, 0.0,
                                scene_lib.diffuse_material("Grey", (0.5, 0.5, 0.5)))
        ground.rotation_euler = (-math.pi / 2, 0.0, 0.0)   # the plane y = 0 turned into z = 0, facing up
        ground.location = (0.0, 0.0, -1.0)
    else:
        raise ValueError(kind)
    scene_lib.probe_volume("Volume", (-4, -1, 0), (4, 1, 2))
    return scene


def main():
    out = addon_common.args()[0]
    paths = {}
    for kind in ("shadow", "open"):
        build(kind)
        paths[kind] = scene_lib.save(os.path.join(out, f"{kind}.blend"))
    emit(**paths)


if __name__ == "__main__":
    main()
