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
               "interior": _interior, "courtyard": _courtyard, "sun": _sun}.get(name)
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


def _interior(offset):
    _world("courtyard.exr")
    walls = lib.collection("Room")
    plaster = lib.diffuse_material("Plaster", (0.8, 0.8, 0.8))
    lo, hi = _shift([(-2.0, -2.0, 0.0), (2.0, 2.0, 2.5)], offset)
    wx, wz = offset[0], offset[2]
    lib.room_walls(lo, hi, coll=walls, material=plaster,
                   window=(wx - 0.8, wx + 0.8, wz + 0.9, wz + 2.0))
    panel = lib.diffuse_material("Panel", (1, 1, 1), emission=(1.0, 0.95, 0.85), strength=8.0)
    _box("Panel", (-0.5, -1.2, 2.45), (0.5, -0.7, 2.5), offset, walls, panel)
    wood = lib.diffuse_material("Wood", (0.45, 0.25, 0.12))
    _box("Table", (-1.6, -1.6, 0.0), (-0.6, -0.9, 0.75), offset, walls, wood)
    lib.probe_volume("RoomVolume", lo, hi)
    # Probes: cell centres of the 1 m grid (the default placement's kind of position): window side,
    # under the panel, next to the table, the middle. Sample points: where movables would stand,
    # between those centres.
    probes = [(0.5, 1.5, 1.25), (-0.5, -0.5, 1.75), (-1.5, -0.5, 0.75), (0.5, -0.5, 0.75)]
    samples = seeded_samples([(0.2, 1.2, 1.4), (-0.3, 0.6, 0.9), (1.3, -1.1, 0.5), (-1.2, 0.3, 1.6)],
                             (-1.85, -1.85, 0.15), (1.85, 1.85, 2.35),
                             [((-1.6, -1.6, 0.0), (-0.6, -0.9, 0.75)), ((-0.5, -1.2, 2.45), (0.5, -0.7, 2.5))])
    return SceneSpec("", "courtyard.exr", probes, samples, placement=[(1.0, 4.0), (2.0, 8.0)])


def _courtyard(offset):
    _world("forest.exr")
    coll = lib.collection("Yard")
    stone = lib.diffuse_material("Stone", (0.5, 0.48, 0.45))
    grass = lib.diffuse_material("Ground", (0.25, 0.3, 0.18))
    _box("Ground", (-7.0, -7.0, -0.2), (7.0, 7.0, 0.0), offset, coll, grass)
    _box("WingWest", (-7.0, -7.0, 0.0), (-5.0, 7.0, 4.0), offset, coll, stone)
    _box("WingSouth", (-5.0, -7.0, 0.0), (7.0, -5.0, 4.0), offset, coll, stone)
    _box("Pillar", (1.0, 1.0, 0.0), (2.0, 2.0, 3.0), offset, coll, stone)
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
