"""Scenes of the placement benchmark (bench/bench_placement.py), built inside Blender (``bpy``).

``build(name)`` clears the file, builds the scene and returns a :class:`PlacementScene`: the probe
volume's box and the solid boxes a movable object cannot stand in (Blender space), from which the
benchmark draws its seeded evaluation points.

- ``room``: the bundled default scene (scenes/make_default_scene.py): a closed 10 x 10 x 4 m room,
  a 3 x 2 m window onto ``sunset.exr``, an emissive ceiling panel, three furniture boxes.
- ``courtyard``: the sweep's open courtyard (bench/sweep/scenes.py): 14 x 14 m of ground, two 4 m
  building wings and a pillar under ``forest.exr`` (a small sun: the wings cast a hard shadow);
  volume 10 x 10 x 4 m from 0.5 m above the ground.
- ``hall``: a large hall with open space (the scene type the user guide gives settings for): a
  24 x 16 x 8 m interior, three 3 x 4 m windows high in the +Y wall, six 0.6 m pillars, a Sun lamp
  (strength 4, 0.5 degrees) shining through the windows onto the floor (hard-edged patches of sun),
  ``sunset.exr`` outside; the volume is the whole interior.
"""
import math
import os
import sys
from dataclasses import dataclass
from typing import List, Tuple

import bpy

_HERE = os.path.dirname(os.path.abspath(__file__))
REPO = os.path.dirname(_HERE)
sys.path.insert(0, os.path.join(REPO, "scenes"))
sys.path.insert(0, os.path.join(_HERE, "sweep"))

import scene_lib as lib  # noqa: E402

Box = Tuple[Tuple[float, float, float], Tuple[float, float, float]]

SCENES = ("room", "courtyard", "hall")


@dataclass
class PlacementScene:
    name: str
    volume: Box           # the probe volume (Blender space)
    solids: List[Box]     # boxes inside the volume that movables cannot stand in
    margin: float = 0.1   # evaluation points stay this far from the solids and the volume's faces


def build(name: str) -> PlacementScene:
    if name == "room":
        import make_default_scene
        make_default_scene.build()
        return PlacementScene("room", (make_default_scene.ROOM_MIN, make_default_scene.ROOM_MAX),
                              [(a, b) for _, a, b in make_default_scene.FURNITURE])
    if name == "courtyard":
        import scenes as sweep_scenes
        sweep_scenes.build("courtyard")
        return PlacementScene("courtyard", ((-4.0, -4.0, 0.5), (6.0, 6.0, 4.5)),
                              [((1.0, 1.0, 0.0), (2.0, 2.0, 3.0))])
    if name == "hall":
        return _hall()
    raise ValueError(f"unknown placement scene {name!r}: {', '.join(SCENES)}")


HALL_MIN, HALL_MAX = (-12.0, -8.0, 0.0), (12.0, 8.0, 8.0)
HALL_WINDOWS = ((-9.5, -6.5), (-1.5, 1.5), (6.5, 9.5))   # x ranges of the +Y wall's openings
HALL_WINDOW_Z = (3.0, 7.0)
HALL_PILLARS = [((x - 0.3, y - 0.3, 0.0), (x + 0.3, y + 0.3, 8.0)) for x in (-6.0, 0.0, 6.0) for y in (-3.0, 3.0)]


def _hall() -> PlacementScene:
    scene = lib.clear_scene()
    scene.render.engine = 'CYCLES'
    lib.hdri_world("sunset.exr")
    walls = lib.collection("Hall")
    plaster = lib.diffuse_material("HallPlaster", (0.75, 0.72, 0.68))
    floor_mat = lib.diffuse_material("HallFloor", (0.35, 0.3, 0.25))
    (x0, y0, z0), (x1, y1, z1) = HALL_MIN, HALL_MAX
    t = 0.3
    lib.box("Floor", (x0 - t, y0 - t, z0 - t), (x1 + t, y1 + t, z0), walls, floor_mat)
    lib.box("Roof", (x0 - t, y0 - t, z1), (x1 + t, y1 + t, z1 + t), walls, plaster)
    lib.box("WallWest", (x0 - t, y0, z0), (x0, y1, z1), walls, plaster)
    lib.box("WallEast", (x1, y0, z0), (x1 + t, y1, z1), walls, plaster)
    lib.box("WallSouth", (x0, y0 - t, z0), (x1, y0, z1), walls, plaster)
    wz0, wz1 = HALL_WINDOW_Z
    lib.box("WallNorthBelow", (x0, y1, z0), (x1, y1 + t, wz0), walls, plaster)
    lib.box("WallNorthAbove", (x0, y1, wz1), (x1, y1 + t, z1), walls, plaster)
    edges = [x0] + [v for w in HALL_WINDOWS for v in w] + [x1]
    for i in range(0, len(edges), 2):  # the piers between the openings
        lib.box(f"WallNorthPier{i // 2}", (edges[i], y1, wz0), (edges[i + 1], y1 + t, wz1), walls, plaster)
    for i, (a, b) in enumerate(HALL_PILLARS):
        lib.box(f"Pillar{i}", a, b, walls, plaster)
    # The sun: from +Y (outside the windows), 35 degrees up, slightly from the east; hard shadows.
    sun = bpy.data.lights.new("HallSun", type='SUN')
    sun.energy = 4.0
    sun.angle = math.radians(0.5)
    ob = bpy.data.objects.new("HallSun", sun)
    bpy.context.scene.collection.objects.link(ob)
    elev, azim = math.radians(35.0), math.radians(15.0)
    d = (math.sin(azim) * math.cos(elev), math.cos(azim) * math.cos(elev), math.sin(elev))  # towards the sun
    ob.rotation_mode = 'QUATERNION'
    from mathutils import Vector
    ob.rotation_quaternion = Vector(d).to_track_quat('Z', 'Y')  # a Sun lamp shines along its −Z
    lib.probe_volume("HallVolume", HALL_MIN, HALL_MAX)
    return PlacementScene("hall", (HALL_MIN, HALL_MAX), list(HALL_PILLARS), margin=0.2)


def points(sc: PlacementScene, n: int, seed: int) -> List[Tuple[float, float, float]]:
    """``n`` seeded uniform points (Blender space) in the volume, ``margin`` from its faces and the
    solids. The room keeps the points of the first placement benchmark (seed 2024, the same
    rejection), so its figures stay comparable."""
    import numpy as np
    rng = np.random.default_rng(seed)
    lo = np.add(sc.volume[0], sc.margin if sc.name != "room" else 0.0)
    hi = np.subtract(sc.volume[1], sc.margin if sc.name != "room" else 0.0)
    if sc.name == "room":
        lo, hi = np.array([-4.8, -4.8, 0.2]), np.array([4.8, 4.8, 3.8])
    out = []
    while len(out) < n:
        p = rng.uniform(lo, hi)
        if any(np.all(p > np.subtract(a, sc.margin)) and np.all(p < np.add(b, sc.margin)) for a, b in sc.solids):
            continue
        out.append(p)
    return out
