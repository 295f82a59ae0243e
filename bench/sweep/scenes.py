"""Reference scenes of the speed-accuracy sweep, built inside Blender (``bpy``).

Each scene is small on purpose (few probes, few triangles) so that a full sweep with references
runs in well under an hour on a 2-core machine. ``build(name, offset)`` clears the file, builds the
scene with every object shifted by ``offset`` (Blender metres; used for the 10 km test) and returns
a :class:`SceneSpec` holding the fixed probe positions and the sample points (Blender space, already
offset) that the sweep evaluates.

Scenes:

- ``sky_courtyard`` / ``sky_forest``: nothing but a bundled HDRI world (courtyard.exr is smooth,
  peak 55; forest.exr holds a small sun, peak 1010). Exact reference: the HDRI's own projection.
- ``interior``: a closed 4 x 4 x 2.5 m room (albedo 0.8 walls), an emissive ceiling panel, a table,
  a 1.6 x 1.1 m window in the +Y wall onto courtyard.exr. Reference: a bake far above the sweep.
- ``courtyard``: an open courtyard, 14 x 14 m of ground with two 4 m building wings (west, south)
  and a pillar, under forest.exr (the sun casts the wings' shadow into the yard). Same reference.
- ``sun``: courtyard.exr plus a small emissive sphere of radiance 1e5 (radius 5 cm at 1.75 m from
  the probe, 2.6e-3 sr, about one pixel of a 128x64 panorama: "a sun of 1e5 in one panorama").
  Reference: analytic (HDRI + sphere).
- ``sun_yard`` (issue 11): the courtyard's geometry lit by a Sun lamp (SUN_LAMP_STRENGTH W/m²,
  SUN_LAMP_ANGLE, 30° up from the south-west: the wings throw a hard shadow across the yard's
  south-west half, the pillar one to its north-east) under sunrise.exr (a sky with a low sun,
  half of its energy in 4 texels). Three probes in the lamp's sun, three in shadow.
- ``sun_window`` (issue 11): the interior's room without its ceiling panel, lit by a Sun lamp
  (35° up) through the window (a sun patch on the floor) and forest.exr through the same window.
  Two probes in the sunbeam, four out of it. Both: reference = the interior's converged bakes.
  Which probes are in the lamp's sun is checked by ``lamp_lit`` (a ray against the scene's boxes).
"""
import math
import os
import sys
from dataclasses import dataclass, field
from typing import List, Tuple

import bpy

_HERE = os.path.dirname(os.path.abspath(__file__))
sys.path.insert(0, os.path.join(os.path.dirname(os.path.dirname(_HERE)), "scenes"))
import scene_lib as lib  # noqa: E402

Vec = Tuple[float, float, float]

# The sun sphere of the "sun" scene (Blender space, relative to the scene offset).
SUN_RADIANCE = 1.0e5
SUN_RADIUS = 0.05
SUN_CENTRE = (1.2, 1.0, 1.8)     # 1.75 m from SUN_PROBE
SUN_PROBE = (0.0, 0.0, 1.0)
SUN_PROBE2 = (0.4, -0.3, 1.2)    # a second probe (1.64 m from the sphere): two noise samples per row


# The Sun lamps of sun_yard / sun_window: strength (W/m², Blender's Sun "Strength"), angular
# diameter, and the unit direction TOWARDS the sun (Blender space; the lamp shines along minus it).
SUN_LAMP_STRENGTH = 4.0
SUN_LAMP_ANGLE = math.radians(0.5)
SUN_YARD_TO_SUN = (-0.6123724356957947, -0.6123724356957945, 0.5)          # 30° up, from the SW
SUN_WINDOW_TO_SUN = (0.28016649959323564, 0.7697511313200572, 0.5735764363510462)  # 35° up, 20° off +Y


@dataclass
class SceneSpec:
    name: str
    hdri: str
    probes: List[Vec]                 # fixed probe positions of the render-settings sweep
    samples: List[Vec]                # sample points between probes (where movables sit)
    placement: List[Tuple[float, float]] = field(default_factory=list)  # (min, max) cell sizes studied
    offset: Vec = (0.0, 0.0, 0.0)


N_SAMPLES = 32  # sample points per volume of the placement study


def seeded_samples(fixed, lo, hi, avoid, n=N_SAMPLES, seed=7, margin=0.15):
    """``fixed`` points plus seeded uniform points in the box ``lo``..``hi`` (Blender space, before
    the offset) up to ``n``, none within ``margin`` of a box in ``avoid`` (solid geometry: a movable
    cannot stand inside a table). Deterministic: the same points in every run and in the tests."""
    import random
    rng = random.Random(seed)
    out = list(fixed)
    while len(out) < n:
        p = tuple(round(rng.uniform(lo[i], hi[i]), 3) for i in range(3))
        if any(all(a[i] - margin <= p[i] <= b[i] + margin for i in range(3)) for a, b in avoid):
            continue
        out.append(p)
    return out


def _shift(points, offset):
    return [tuple(p[i] + offset[i] for i in range(3)) for p in points]


def _box(name, a, b, offset, coll, mat):
    return lib.box(name, _shift([a], offset)[0], _shift([b], offset)[0], coll, mat)


def _world(hdri):
    lib.hdri_world(hdri)


def build(name: str, offset: Vec = (0.0, 0.0, 0.0)) -> SceneSpec:
    """Build scene ``name`` into the current (cleared) file; returns its :class:`SceneSpec`."""
    scene = lib.clear_scene()
    scene.render.engine = 'CYCLES'
    scene.cycles.use_denoising = False
    builder = {"sky_courtyard": _sky("courtyard.exr"), "sky_forest": _sky("forest.exr"),
               "interior": _interior, "courtyard": _courtyard, "sun": _sun,
               "sun_yard": _sun_yard, "sun_window": _sun_window}.get(name)
    if builder is None:
        raise ValueError(f"unknown sweep scene {name!r}")
    spec = builder(offset)
    spec.name, spec.offset = name, tuple(offset)
    spec.probes = _shift(spec.probes, offset)
    spec.samples = _shift(spec.samples, offset)
    return spec


def _sky(hdri):
    def make(offset):
        _world(hdri)
        # The light is the same everywhere; the volume only gives the bake somewhere to place probes.
        lib.probe_volume("SkyVolume", *_shift([(-2.0, -2.0, 0.0), (2.0, 2.0, 2.0)], offset))
        # The light does not depend on position: the probes differ only by their Cycles seed
        # (worker.py gives each probe its own), so a row is the mean of 8 noise samples.
        probes = [(-1.0, -1.0, 0.5), (1.0, 0.5, 1.5), (0.5, -1.5, 1.0), (-1.5, 1.5, 0.25),
                  (0.0, 0.0, 1.0), (1.5, 1.5, 1.75), (-0.5, 0.5, 0.75), (1.0, -1.0, 1.25)]
        return SceneSpec("", hdri, probes=probes, samples=[])
    return make



ROOM_WINDOW = (-0.8, 0.8, 0.9, 2.0)   # x0, x1, z0, z1 of the opening in the +Y wall (room_walls)
ROOM_TABLE = ((-1.6, -1.6, 0.0), (-0.6, -0.9, 0.75))


def _room_shell(offset):
    """The 4 x 4 x 2.5 m room's walls (albedo 0.8) with ROOM_WINDOW: (collection, lo, hi)."""
    walls = lib.collection("Room")
    plaster = lib.diffuse_material("Plaster", (0.8, 0.8, 0.8))
    lo, hi = _shift([(-2.0, -2.0, 0.0), (2.0, 2.0, 2.5)], offset)
    wx, wz = offset[0], offset[2]
    x0, x1, z0, z1 = ROOM_WINDOW
    lib.room_walls(lo, hi, coll=walls, material=plaster, window=(wx + x0, wx + x1, wz + z0, wz + z1))
    return walls, lo, hi


def _room_table(offset, walls):
    _box("Table", *ROOM_TABLE, offset, walls, lib.diffuse_material("Wood", (0.45, 0.25, 0.12)))


def _interior(offset):
    _world("courtyard.exr")
    walls, lo, hi = _room_shell(offset)
    panel = lib.diffuse_material("Panel", (1, 1, 1), emission=(1.0, 0.95, 0.85), strength=8.0)
    _box("Panel", (-0.5, -1.2, 2.45), (0.5, -0.7, 2.5), offset, walls, panel)
    _room_table(offset, walls)
    lib.probe_volume("RoomVolume", lo, hi)
    # Probes: cell centres of the 1 m grid (the default placement's kind of position): window side,
    # under the panel, next to the table, the middle. Sample points: where movables would stand,
    # between those centres.
    probes = [(0.5, 1.5, 1.25), (-0.5, -0.5, 1.75), (-1.5, -0.5, 0.75), (0.5, -0.5, 0.75)]
    samples = seeded_samples([(0.2, 1.2, 1.4), (-0.3, 0.6, 0.9), (1.3, -1.1, 0.5), (-1.2, 0.3, 1.6)],
                             (-1.85, -1.85, 0.15), (1.85, 1.85, 2.35),
                             [ROOM_TABLE, ((-0.5, -1.2, 2.45), (0.5, -0.7, 2.5))])
    return SceneSpec("", "courtyard.exr", probes, samples, placement=[(1.0, 4.0), (2.0, 8.0)])


# Solid boxes of the courtyard (Blender space, before the offset): ground, two wings, a pillar.
YARD_BOXES = [("Ground", (-7.0, -7.0, -0.2), (7.0, 7.0, 0.0)),
              ("WingWest", (-7.0, -7.0, 0.0), (-5.0, 7.0, 4.0)),
              ("WingSouth", (-5.0, -7.0, 0.0), (7.0, -5.0, 4.0)),
              ("Pillar", (1.0, 1.0, 0.0), (2.0, 2.0, 3.0))]


def _yard_geometry(offset):
    coll = lib.collection("Yard")
    stone = lib.diffuse_material("Stone", (0.5, 0.48, 0.45))
    grass = lib.diffuse_material("Ground", (0.25, 0.3, 0.18))
    for name, a, b in YARD_BOXES:
        _box(name, a, b, offset, coll, grass if name == "Ground" else stone)


def _courtyard(offset):
    _world("forest.exr")
    _yard_geometry(offset)
    # The yard volume: 0.5 m above the ground (movables walk there), clear of the wings by 1 m, so
    # the octree refines around the pillar and at the wings' faces only.
    lib.probe_volume("YardVolume", *_shift([(-4.0, -4.0, 0.5), (6.0, 6.0, 4.5)], offset))
    probes = [(-3.0, -3.0, 1.0), (4.0, 4.0, 2.5), (2.5, 0.5, 1.0), (-1.0, 3.0, 3.5)]
    samples = seeded_samples([(-3.4, 2.2, 1.2), (0.3, -3.1, 1.0), (3.6, 1.6, 0.9), (2.9, 4.8, 1.7),
                              (-1.7, -0.6, 2.6), (0.6, 2.4, 1.3)],
                             (-3.9, -3.9, 0.6), (5.9, 5.9, 4.4), [((1.0, 1.0, 0.0), (2.0, 2.0, 3.0))])
    return SceneSpec("", "forest.exr", probes, samples, placement=[(1.0, 2.0), (1.0, 4.0), (2.0, 8.0)])


def _sun(offset):
    _world("courtyard.exr")
    bpy.ops.mesh.primitive_uv_sphere_add(radius=SUN_RADIUS, segments=48, ring_count=24,
                                         location=_shift([SUN_CENTRE], offset)[0])
    sphere = bpy.context.active_object
    sphere.name = "Sun1e5"
    mat = bpy.data.materials.new("SunEmission")
    mat.use_nodes = True
    nt = mat.node_tree
    nt.nodes.clear()
    em = nt.nodes.new("ShaderNodeEmission")
    em.inputs["Strength"].default_value = SUN_RADIANCE
    out = nt.nodes.new("ShaderNodeOutputMaterial")
    nt.links.new(em.outputs["Emission"], out.inputs["Surface"])
    sphere.data.materials.append(mat)
    lib.probe_volume("SunVolume", *_shift([(-0.5, -0.5, 0.5), (0.5, 0.5, 1.5)], offset))
    return SceneSpec("", "courtyard.exr", probes=[SUN_PROBE, SUN_PROBE2], samples=[])


def sun_direction_and_solid_angle():
    """(unit direction from SUN_PROBE to the sphere centre, Blender space; solid angle in sr)."""
    d = [SUN_CENTRE[i] - SUN_PROBE[i] for i in range(3)]
    dist = math.sqrt(sum(x * x for x in d))
    cos_a = math.sqrt(1.0 - (SUN_RADIUS / dist) ** 2)
    return [x / dist for x in d], 2.0 * math.pi * (1.0 - cos_a)


def _sun_lamp(to_sun, offset):
    """A Sun lamp of SUN_LAMP_STRENGTH and SUN_LAMP_ANGLE shining along ``-to_sun``."""
    from mathutils import Vector
    data = bpy.data.lights.new("SunLamp", type='SUN')
    data.energy = SUN_LAMP_STRENGTH
    data.angle = SUN_LAMP_ANGLE
    ob = bpy.data.objects.new("SunLamp", data)
    # Baked, as the sweep measured it (a Sun lamp defaults to mixed, light_modes.py; bench_spheres.py
    # sets its --sun-mode over this).
    ob["schnee_light_mode"] = "baked"
    bpy.context.scene.collection.objects.link(ob)
    ob.location = _shift([(0.0, 0.0, 10.0)], offset)[0]  # a Sun's position does not matter
    ob.rotation_euler = (-Vector(to_sun)).to_track_quat('-Z', 'Y').to_euler()
    return ob


def lamp_lit(point, to_sun, boxes):
    """Whether the ray from ``point`` towards the sun misses every box (a, b) (pure Python, no
    Blender: the scenes' probe lists were chosen with it; tests/bench checks them)."""
    for a, b in boxes:
        t0, t1 = 1e-6, 1e9
        for i in range(3):
            if abs(to_sun[i]) < 1e-12:
                if not a[i] <= point[i] <= b[i]:
                    break
                continue
            u, v = (a[i] - point[i]) / to_sun[i], (b[i] - point[i]) / to_sun[i]
            t0, t1 = max(t0, min(u, v)), min(t1, max(u, v))
        else:
            if t0 <= t1:
                return False
    return True


# sun_yard: the courtyard's probes plus two; (-3,-3,1), (0,-2,1) lie in the wings' shadow of the
# lamp, (2.5,2.5,1) in the pillar's; (4,4,2.5), (-1,3,3.5), (3,-1,1.5) in its sun.
SUN_YARD_PROBES = [(-3.0, -3.0, 1.0), (4.0, 4.0, 2.5), (2.5, 2.5, 1.0), (-1.0, 3.0, 3.5),
                   (0.0, -2.0, 1.0), (3.0, -1.0, 1.5)]
# sun_window: (0.5,1.5,1.25) and (-0.4,0.6,0.8) in the sunbeam through the window; the interior's
# (-0.5,-0.5,1.75), (-1.5,-0.5,0.75), (0.5,-0.5,0.75) and (1.2,1,0.5) beside the floor's sun patch
# out of it.
SUN_WINDOW_PROBES = [(0.5, 1.5, 1.25), (-0.4, 0.6, 0.8), (-0.5, -0.5, 1.75), (-1.5, -0.5, 0.75),
                     (0.5, -0.5, 0.75), (1.2, 1.0, 0.5)]


def room_boxes():
    """The room's solid boxes as lib.room_walls builds them (interior -2..2 x -2..2 x 0..2.5, walls
    0.2 m, the window ROOM_WINDOW) plus the table: for lamp_lit."""
    x0, y0, z0, x1, y1, z1, t = -2.0, -2.0, 0.0, 2.0, 2.0, 2.5, 0.2
    wx0, wx1, wz0, wz1 = ROOM_WINDOW
    return [((x0 - t, y0 - t, z0 - t), (x1 + t, y1 + t, z0)), ((x0 - t, y0 - t, z1), (x1 + t, y1 + t, z1 + t)),
            ((x0 - t, y0, z0), (x0, y1, z1)), ((x1, y0, z0), (x1 + t, y1, z1)),
            ((x0, y0 - t, z0), (x1, y0, z1)), ((x0, y1, z0), (wx0, y1 + t, z1)),
            ((wx1, y1, z0), (x1, y1 + t, z1)), ((wx0, y1, z0), (wx1, y1 + t, wz0)),
            ((wx0, y1, wz1), (wx1, y1 + t, z1)), ROOM_TABLE]


def _sun_yard(offset):
    _world("sunrise.exr")
    _yard_geometry(offset)
    _sun_lamp(SUN_YARD_TO_SUN, offset)
    lib.probe_volume("YardVolume", *_shift([(-4.0, -4.0, 0.5), (6.0, 6.0, 4.5)], offset))
    samples = seeded_samples([(-3.4, 2.2, 1.2), (0.3, -3.1, 1.0), (3.6, 1.6, 0.9), (2.9, 4.8, 1.7),
                              (-1.7, -0.6, 2.6), (0.6, 2.4, 1.3)],
                             (-3.9, -3.9, 0.6), (5.9, 5.9, 4.4), [((1.0, 1.0, 0.0), (2.0, 2.0, 3.0))], seed=11)
    return SceneSpec("", "sunrise.exr", list(SUN_YARD_PROBES), samples)


def _sun_window(offset):
    _world("forest.exr")
    walls, lo, hi = _room_shell(offset)
    _room_table(offset, walls)
    _sun_lamp(SUN_WINDOW_TO_SUN, offset)
    lib.probe_volume("RoomVolume", lo, hi)
    samples = seeded_samples([(0.2, 1.2, 1.4), (-0.3, 0.6, 0.9), (1.3, -1.1, 0.5), (-1.2, 0.3, 1.6)],
                             (-1.85, -1.85, 0.15), (1.85, 1.85, 2.35), [ROOM_TABLE], seed=11)
    return SceneSpec("", "forest.exr", list(SUN_WINDOW_PROBES), samples)
