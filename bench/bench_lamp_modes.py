#!/usr/bin/env python3
"""Can baked probes resolve a lamp's direct light? Point, spot and Sun lamps against a 0.5 m probe
lattice, without Cycles (issue 27 item 1: the light-mode defaults by lamp type, light_modes.py).

    /usr/bin/python3 bench/bench_lamp_modes.py        # writes bench/results/lamp_modes.md

Scene (engine space, y up): a floor (y = 0), a wall (x = -2, facing +x) and a table top
(x 0..1.2, z -0.6..0.6, y 0.70..0.76) that casts the shadow a desk or a ceiling lamp throws.
Lamps (Cycles units, the native direct-light step's conventions, docs/direct-light.md):
- point: 100 W, radius r;
- spot: 100 W, radius r, pointing down, 45° cone, blend 0.15 (Blender's defaults);
- sun: 3 W/m², 45° up, angle 0.526° (Blender's default) and 5°.
Placed at three spots: "desk" 0.5 m above the table's edge, "ceiling" 2.5 m above the floor (1.75 m
above the table), "wall" 0.25 m in front of the wall at 2 m. Radii 0.05, 0.1 (Blender's startup
lamp), 0.25 (a new lamp's default), 0.35, 0.5 m.

Two ways the lamp's direct light can reach a surface, against the exact value (the lamp's exact
shadowed direct-light SH, native.direct_project, 256 shadow rays):
- baked: the probes at the corners of a uniform 0.5 m lattice (the add-on's default Min Cell Size:
  the finest the Adaptive refinement goes, however hard an edge) over x -1.9..3.1, y 0.1..2.6,
  z -2.5..2.5 hold it, and trilinear interpolation (native.CornerOctree's on equal leaves, the
  engine's per-pixel weights without visibility; here in numpy) gives the value between them;
- mixed: the engine's shadowed punctual light, modelled as the same lamp at radius 0 (hard shadow,
  exact falloff; the shadow map's resolution and bias and the engine's spot-cone curve are not
  modelled).
At 1500 seeded random points of the box where the lamp's light is (none inside the table, none
within r + 0.1 m of the lamp; a spot draws 20x the candidates and keeps the first 1500 in its
light), the error at a point is the refinement's metric (adaptive.direct_check): the irradiance
error of the direct light, RMS over directions and RGB, over the total light there, which holds a
uniform stand-in for the bounced light of AMBIENT x the median lit direct irradiance. Reported:
the mean over the points and the share of them over the default Error Tolerance (0.03); the mode
with the smaller mean is "better". The defaults in light_modes.py follow from the table.
"""
from __future__ import annotations

import argparse
import dataclasses
import math
import os
import sys
import time

import numpy as np

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
sys.path.insert(0, os.path.join(ROOT, "addon"))
from schnee_probes import light_modes, native  # noqa: E402
from schnee_probes.adaptive import irradiance_norm  # noqa: E402

SPACING = 0.5                    # the add-on's default Min Cell Size (settings.py)
TOLERANCE = 0.03                 # the add-on's default Error Tolerance (settings.py)
LO = np.array([-1.9, 0.1, -2.5])
HI = np.array([3.1, 2.6, 2.5])
TABLE = (np.array([0.0, 0.70, -0.6]), np.array([1.2, 0.76, 0.6]))
# The desk lamp is over the table's edge (x = 1.2) so that a spot's 45° cone holds part of the table's
# shadow on the floor, not the table top alone.
PLACES = {"desk": (1.1, 1.26, 0.0), "ceiling": (0.6, 2.5, 0.0), "wall": (-1.75, 2.0, 0.0)}
AMBIENT = 0.1                    # stand-in bounced light: this share of the median lit irradiance
RADII = (0.05, 0.1, 0.25, 0.35, 0.5)
POWER = 100.0
SPOT_SIZE = math.radians(45.0)
SPOT_BLEND = 0.15
SUN_STRENGTH = 3.0
SUN_TRAVEL = (-math.cos(math.radians(45.0)) * 0.6, -math.sin(math.radians(45.0)), -math.cos(math.radians(45.0)) * 0.8)


def box(name, lo, hi):
    """A closed axis-aligned box: (name, vertices, triangles) as native meshes take them."""
    lo, hi = np.asarray(lo, float), np.asarray(hi, float)
    v = np.array([[(hi if (i >> a) & 1 else lo)[a] for a in range(3)] for i in range(8)])
    quads = ((0, 2, 3, 1), (4, 5, 7, 6), (0, 1, 5, 4), (2, 6, 7, 3), (0, 4, 6, 2), (1, 3, 7, 5))
    tris = [(q[0], q[1], q[2]) for q in quads] + [(q[0], q[2], q[3]) for q in quads]
    return name, v, np.array(tris, dtype=np.uint32)


def geometry():
    # Thin boxes: every surface opaque from both sides, as the bake's shadow rays see them.
    return [box("Floor", (-6, -0.1, -6), (6, 0.0, 6)), box("Wall", (-2.1, 0.0, -6), (-2.0, 4.0, 6)),
            box("Table", *TABLE)]


class Lattice:
    """The probes at the corners of a uniform lattice and trilinear interpolation between them: what
    native.CornerOctree does on a tree of equal leaves (and the engine's per-pixel weights without
    visibility), in numpy so that the figures do not depend on the interpolation code under work."""

    def __init__(self, lo, hi, spacing):
        self.lo, self.spacing = np.asarray(lo, float), float(spacing)
        self.dims = tuple(int(round(v)) + 1 for v in (np.asarray(hi) - lo) / spacing)
        idx = np.stack(np.meshgrid(*[np.arange(d) for d in self.dims], indexing="ij"), -1).reshape(-1, 3)
        self.positions = self.lo + idx * self.spacing

    def interpolate(self, points, values):
        g = (np.asarray(points) - self.lo) / self.spacing
        i0 = np.clip(np.floor(g).astype(int), 0, np.array(self.dims) - 2)
        f = g - i0
        v = np.asarray(values).reshape(self.dims + values.shape[1:])
        out = 0.0
        for corner in range(8):
            o = np.array([(corner >> a) & 1 for a in range(3)])
            w = np.prod(np.where(o, f, 1.0 - f), axis=1)
            c = i0 + o
            out = out + w[:, None, None] * v[c[:, 0], c[:, 1], c[:, 2]]
        return out


def points(rng, n, lamp_pos=None, keep_out=0.0):
    """n seeded points of the probe box, none inside the table or within keep_out of the lamp."""
    out = []
    while sum(len(x) for x in out) < n:
        p = LO + rng.random((4 * n, 3)) * (HI - LO)
        inside = np.all((p > TABLE[0] - 0.01) & (p < TABLE[1] + 0.01), axis=1)
        ok = ~inside
        if lamp_pos is not None:
            ok &= np.linalg.norm(p - np.asarray(lamp_pos), axis=1) > keep_out
        out.append(p[ok])
    return np.concatenate(out)[:n]


def lamps():
    """(kind, place, radius, Lamp, keep-out radius around it)."""
    for kind in ("POINT", "SPOT"):
        for place, pos in PLACES.items():
            for r in RADII:
                lamp = native.Lamp(kind, (POWER,) * 3, pos, (0.0, -1.0, 0.0), radius=r,
                                   spot_size=SPOT_SIZE if kind == "SPOT" else 0.0,
                                   spot_blend=SPOT_BLEND if kind == "SPOT" else 0.0)
                yield kind, place, r, lamp, pos, r + 0.1
    for deg in (math.degrees(0.009180432185530663), 5.0):
        yield "SUN", "45° up", math.radians(deg), native.Lamp("SUN", (SUN_STRENGTH,) * 3, direction=SUN_TRAVEL,
                                                              radius=math.radians(deg)), None, 0.0


def measure(tree, probe_pos, lamp, pts, geo, keep):
    """(baked, mixed) errors of one lamp at (at most ``keep`` of) the points where its light is, each
    (mean, share > tolerance, points)."""
    exact = native.direct_project([lamp], pts, geometry=geo)
    baked = tree.interpolate(pts, native.direct_project([lamp], probe_pos, geometry=geo))
    mixed = native.direct_project([dataclasses.replace(lamp, radius=0.0)], pts, geometry=geo)
    e = irradiance_norm(exact)
    # Only where the lamp's light is, exactly or in either model (a spot's cone; outside it every
    # model gives 0 and would only dilute the means).
    seen = (e > 0) | (irradiance_norm(baked) > 0) | (irradiance_norm(mixed) > 0)
    seen &= np.cumsum(seen) <= keep
    total = exact.copy()
    total[:, 0, :] += AMBIENT * np.median(e[e > 0]) / (math.pi * math.sqrt(3.0))
    out = []
    for model in (baked, mixed):
        # The refinement's metric (adaptive.direct_check): the error of the direct light relative
        # to the total light there.
        err = irradiance_norm(model - exact)[seen] / irradiance_norm(total)[seen]
        out.append((float(np.mean(err)), float(np.mean(err > TOLERANCE)), int(seen.sum())))
    return out


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--points", type=int, default=1500)
    ap.add_argument("--seed", type=int, default=27)
    ap.add_argument("--out", default=os.path.join(ROOT, "bench", "results", "lamp_modes.md"))
    a = ap.parse_args()
    geo = geometry()
    tree = Lattice(LO, HI, SPACING)
    probe_pos = tree.positions
    rows = []
    t0 = time.perf_counter()
    for kind, place, r, lamp, pos, keep_out in lamps():
        # A spot's cone holds a few % of the box: draw more candidates, keep a.points in its light.
        pts = points(np.random.default_rng(a.seed), a.points * (20 if kind == "SPOT" else 1), pos, keep_out)
        baked, mixed = measure(tree, probe_pos, lamp, pts, geo, a.points)
        size = f"{math.degrees(r):.3g}°" if kind == "SUN" else f"{r:g} m"
        rows.append((kind, place, size, r, baked, mixed))
        print(f"{kind:5s} {place:8s} {size:>7s}  baked {baked[0] * 100:6.1f} % ({baked[1] * 100:3.0f} % > tol)  "
              f"mixed {mixed[0] * 100:6.1f} % ({mixed[1] * 100:3.0f} % > tol)  {baked[2]} points", flush=True)
    seconds = time.perf_counter() - t0
    write(a, rows, len(probe_pos), seconds)


def write(a, rows, probe_count, seconds):
    lines = [
        "# Light-mode defaults: can a 0.5 m probe lattice resolve a lamp's direct light?",
        "",
        f"Command: `/usr/bin/python3 bench/bench_lamp_modes.py` ({a.points} points per lamp, seed {a.seed}; "
        f"{probe_count} probes; {seconds:.0f} s on the shared 2-core box). No Cycles: the native",
        "direct-light step's exact shadowed SH (`native.direct_project`, 256 shadow rays) at the probes,",
        "interpolated trilinearly (as `native.CornerOctree` on equal leaves: the engine's per-pixel",
        "weights without visibility), against the exact SH at points between the probes. Scene, lamps",
        "and points: the script's docstring.",
        "",
        "- **baked**: the interpolated probes; **mixed**: the engine's shadowed punctual light, modelled",
        "  as the same lamp at radius 0 (hard shadow, exact falloff; the shadow map's resolution and",
        "  bias and the engine's spot-cone curve are not modelled).",
        f"- Error at a point: the refinement's metric (`adaptive.direct_check`), the irradiance error",
        f"  of the lamp's direct light, RMS over directions and RGB, over the total light there, with a",
        f"  uniform stand-in for the bounced light of {AMBIENT:g} × the median lit direct irradiance.",
        "  Mean over the points where the lamp's light is (exactly or in either model), and the share",
        f"  of them over the default Error Tolerance ({TOLERANCE:g}).",
        "- **default**: what `light_modes.default_for` gives the lamp (the add-on's default when the",
        "  user chose nothing).",
        "",
        "| lamp | where | radius / angle | baked: mean | > 3 % | mixed: mean | > 3 % | points | better | default |",
        "|---|---|---|---|---|---|---|---|---|---|",
    ]
    for kind, place, size, r, baked, mixed in rows:
        better = "mixed" if mixed[0] < baked[0] else "baked"
        lines.append(f"| {kind.title()} | {place} | {size} | {baked[0] * 100:.1f} % | {baked[1] * 100:.0f} % "
                     f"| {mixed[0] * 100:.1f} % | {mixed[1] * 100:.0f} % | {baked[2]} | {better} "
                     f"| {light_modes.default_for(kind, r)} |")
    agree = sum((("mixed" if m[0] < b[0] else "baked") == light_modes.default_for(k, r))
                for k, _, _, r, b, m in rows)
    lines += [
        "",
        f"**Decision** (light_modes.py; the default agrees with the better mode in {agree} of {len(rows)} rows):",
        "Sun and spot lamps default to mixed (every row); point lamps to mixed up to a radius of",
        f"{light_modes.POINT_MIXED_MAX_RADIUS:g} m (`POINT_MIXED_MAX_RADIUS`: Blender's new lamp and its startup lamp, 0.25 and",
        "0.1 m), baked above it, where the engine's hard-edged punctual light is further from Cycles'",
        "wide lamp than the interpolated probes are (at 0.35 m the two are within 1.6 points either way).",
        "Area lamps stay baked: glTF has no area lights, so a mixed area lamp's direct light would reach",
        "nothing. Caveats: a point light takes 6 of the engine's 16 shadow-map layers (a spot over 60°",
        "too, a sun 4 cascades); a mixed lamp left without layers is unshadowed and lights through walls",
        "(docs/engine.md \"Shadows\"), so a scene with many small point lamps should bake some of them.",
        f"Every baked mean ({min(b[0] for *_, b, _m in rows) * 100:.1f} % and up) is above the probes' own noise at the",
        "add-on's defaults (the room's floor, 1.04 %, bench/results/placement.md): a baked lamp's error",
        "here is the interpolation's, which more samples would not lower.",
    ]
    with open(a.out, "w") as f:
        f.write("\n".join(lines) + "\n")
    print(f"wrote {a.out}")


if __name__ == "__main__":
    main()
