"""Helpers for the scene-generator scripts (run inside Blender): boxes, rooms, HDRI worlds, volumes.

All positions are Blender world space (Z-up), metres.
"""
import math
import os

import bmesh
import bpy


def clear_scene():
    """Remove every object, collection, material, world and image: an empty scene to build on."""
    for coll in (bpy.data.objects, bpy.data.meshes, bpy.data.cameras, bpy.data.lights,
                 bpy.data.materials, bpy.data.collections, bpy.data.images):
        for item in list(coll):
            coll.remove(item)
    scene = bpy.context.scene
    if scene.world is None:
        scene.world = bpy.data.worlds.new("World")
    return scene


def collection(name, parent=None):
    """The collection ``name``, created and linked under ``parent`` (default: the scene) if missing."""
    coll = bpy.data.collections.get(name)
    if coll is None:
        coll = bpy.data.collections.new(name)
        (parent or bpy.context.scene.collection).children.link(coll)
    return coll


def box(name, bmin, bmax, coll=None, material=None):
    """A closed box (outward normals) spanning ``bmin``..``bmax``; the object sits at its centre."""
    centre = [(a + b) / 2 for a, b in zip(bmin, bmax)]
    size = [b - a for a, b in zip(bmin, bmax)]
    mesh = bpy.data.meshes.new(name)
    bm = bmesh.new()
    bmesh.ops.create_cube(bm, size=1.0)
    for v in bm.verts:
        v.co.x *= size[0]
        v.co.y *= size[1]
        v.co.z *= size[2]
    bm.to_mesh(mesh)
    bm.free()
    ob = bpy.data.objects.new(name, mesh)
    ob.location = centre
    (coll or bpy.context.scene.collection).objects.link(ob)
    if material is not None:
        mesh.materials.append(material)
    return ob


def diffuse_material(name, color, emission=None, strength=0.0):
    """A Principled material of base ``color`` (r, g, b), optionally emitting ``emission`` light."""
    mat = bpy.data.materials.new(name)
    mat.use_nodes = True
    bsdf = mat.node_tree.nodes["Principled BSDF"]
    bsdf.inputs["Base Color"].default_value = (*color, 1.0)
    bsdf.inputs["Roughness"].default_value = 0.8
    if emission is not None:
        # "Emission Color" since Blender 4.0 (Principled BSDF v2), "Emission" before.
        key = "Emission Color" if "Emission Color" in bsdf.inputs else "Emission"
        bsdf.inputs[key].default_value = (*emission, 1.0)
        bsdf.inputs["Emission Strength"].default_value = strength
    return mat


def studiolight_path(name):
    """Path of one of Blender's bundled HDRIs (``studiolights/world/<name>``)."""
    folder = bpy.utils.system_resource('DATAFILES', path=os.path.join("studiolights", "world"))
    path = os.path.join(folder, name)
    if not os.path.exists(path):
        raise FileNotFoundError(f"bundled HDRI not found: {path}")
    return path


def hdri_world(name="interior.exr", strength=1.0):
    """World lit by a bundled HDRI through an Environment Texture with default mapping (the
    mapping DESIGN.md §3 states for the equirect camera)."""
    world = bpy.context.scene.world
    world.use_nodes = True
    nt = world.node_tree
    nt.nodes.clear()
    env = nt.nodes.new("ShaderNodeTexEnvironment")
    env.image = bpy.data.images.load(studiolight_path(name), check_existing=True)
    bg = nt.nodes.new("ShaderNodeBackground")
    bg.inputs["Strength"].default_value = strength
    out = nt.nodes.new("ShaderNodeOutputWorld")
    nt.links.new(env.outputs["Color"], bg.inputs["Color"])
    nt.links.new(bg.outputs["Background"], out.inputs["Surface"])
    return world


def nishita_world(elevation_deg=25.0, rotation_deg=60.0):
    """World lit by Blender's Nishita Sky Texture (its sun included) at the given sun elevation and
    rotation: a procedural world, which the bake captures with Cycles (docs/direct-light.md)."""
    world = bpy.context.scene.world
    world.use_nodes = True
    nt = world.node_tree
    nt.nodes.clear()
    sky = nt.nodes.new("ShaderNodeTexSky")
    sky.sky_type = 'NISHITA'
    sky.sun_elevation = math.radians(elevation_deg)
    sky.sun_rotation = math.radians(rotation_deg)
    bg = nt.nodes.new("ShaderNodeBackground")
    out = nt.nodes.new("ShaderNodeOutputWorld")
    nt.links.new(sky.outputs["Color"], bg.inputs["Color"])
    nt.links.new(bg.outputs["Background"], out.inputs["Surface"])
    return world


def room_walls(bmin, bmax, thickness=0.2, coll=None, material=None, window=None):
    """Floor, ceiling and four walls as solid boxes outside the interior ``bmin``..``bmax``.
    ``window`` = (x0, x1, z0, z1): an opening in the +Y wall."""
    (x0, y0, z0), (x1, y1, z1) = bmin, bmax
    t = thickness
    parts = [
        ("Floor", (x0 - t, y0 - t, z0 - t), (x1 + t, y1 + t, z0)),
        ("Ceiling", (x0 - t, y0 - t, z1), (x1 + t, y1 + t, z1 + t)),
        ("WallWest", (x0 - t, y0, z0), (x0, y1, z1)),
        ("WallEast", (x1, y0, z0), (x1 + t, y1, z1)),
        ("WallSouth", (x0, y0 - t, z0), (x1, y0, z1)),
    ]
    if window is None:
        parts.append(("WallNorth", (x0, y1, z0), (x1, y1 + t, z1)))
    else:
        wx0, wx1, wz0, wz1 = window
        parts += [
            ("WallNorthLeft", (x0, y1, z0), (wx0, y1 + t, z1)),
            ("WallNorthRight", (wx1, y1, z0), (x1, y1 + t, z1)),
            ("WallNorthBelow", (wx0, y1, z0), (wx1, y1 + t, wz0)),
            ("WallNorthAbove", (wx0, y1, wz1), (wx1, y1 + t, z1)),
        ]
    return [box(n, a, b, coll, material) for n, a, b in parts]


def movable_sphere(name, centre, radius, material, coll):
    """A smooth UV sphere (64 x 32) "Sphere_<name>" of `radius` at `centre` with `material`, linked to
    collection `coll` only (the sphere benchmarks' movable test objects)."""
    bpy.ops.mesh.primitive_uv_sphere_add(segments=64, ring_count=32, radius=radius, location=centre)
    ob = bpy.context.active_object
    ob.name = ob.data.name = "Sphere_" + name
    bpy.ops.object.shade_smooth()
    ob.data.materials.append(material)
    for c in list(ob.users_collection):
        c.objects.unlink(ob)
    coll.objects.link(ob)
    return ob


def probe_volume(name, bmin, bmax, collection_name="ProbeVolumes"):
    """A closed box in the probe-volume collection, shown as wireframe in the viewport."""
    ob = box(name, bmin, bmax, collection(collection_name))
    ob.display_type = 'WIRE'
    return ob


def save(path):
    """Save the scene to ``path`` with its image paths absolute. Blender's default (Preferences >
    File Paths > Relative Paths) stores them relative to the .blend ("//../../../usr/share/..."), and
    a copy of the file in a folder of another depth then finds no sky image: Cycles renders the
    missing image magenta, silently (found by a test whose bakes depended on their folder)."""
    path = os.path.abspath(path)
    os.makedirs(os.path.dirname(path), exist_ok=True)
    bpy.context.preferences.filepaths.use_relative_paths = False
    bpy.ops.wm.save_as_mainfile(filepath=path, check_existing=False, relative_remap=False)
    return path
