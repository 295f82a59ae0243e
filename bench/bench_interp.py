#!/usr/bin/env python3
"""Probes vs error of placements and interpolations on synthetic light fields (CPU only, no Cycles).

    /usr/bin/python3 bench/bench_interp.py            # writes bench/results/interp.md

Fields (radiance SH, band 2, RGB, engine space, a 16 m x 4 m x 16 m box like a hall):
- shadow edge: a constant sky plus a sun (radiance SH of a direction) where lit; lit is a half-space
  behind an oblique plane, so irradiance jumps across it (a hard shadow boundary);
- smooth gradient: the sky plus a point light 0.5 m below the ceiling (1/(d^2 + 0.25) falloff and
  direction), smooth everywhere.
Baked values get Monte-Carlo-like noise of 0.4 % relative RMS (the sweep's per-probe error at the
shipped defaults); errors are measured against the noiseless field at 512 seeded points that are
not probes: relative irradiance RMS over directions (pb_refine_irradiance_error's metric, exact in
SH), mean and 95th percentile over the points.

Placements:
- uniform grid (corner probes every s metres) with trilinear (octree code, one level) / tetrahedra;
- today's geometry octree: leaves touching a wall/floor/ceiling split to Min Cell Size; v1 lookup
  (probe at the leaf centre, constant inside the leaf: what the engine does with a v1 file), and the
  same leaves with corner probes (octree trilinear) / tetrahedra on those probes;
- error-driven refinement (pb_refine) from Max Cell Size leaves at several tolerances, with the
  octree interpolation it refines for, and tetrahedra over the same probes. "bakes" counts every
  point rendered: probes plus the test points that did not become probes.
"""
from __future__ import annotations

import os
import sys
import time

import numpy as np

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
sys.path.insert(0, os.path.join(ROOT, "addon"))
from schnee_probes import native  # noqa: E402

BAND = 2
C = 9
EXTENT = np.array([16.0, 4.0, 16.0])
MIN_CELL = 0.25
ROOT_LEVEL = 4  # Max Cell Size 4 m
NOISE = 0.004
A = np.array([np.pi] + [2 * np.pi / 3] * 3 + [np.pi / 4] * 5)
SKY = np.array([0.6, 0.7, 0.9])


def _basis(d):
    d = d / np.linalg.norm(d, axis=-1, keepdims=True)
    return np.frombuffer(native._lib().sh_basis(np.ascontiguousarray(d.reshape(-1, 3)), BAND),
                         dtype=np.float64).reshape(d.shape[:-1] + (C,))


SUN_DIR = np.array([0.4, 0.8, 0.3])
SUN_Y = _basis(SUN_DIR[None])[0]
PLANE_N = np.array([1.0, 0.0, 0.5]) / np.linalg.norm([1.0, 0.0, 0.5])
PLANE_C = 7.3
LIGHT = np.array([4.1, 3.5, 11.9])


def field_shadow(p):
    c = np.zeros((len(p), C, 3))
    c[:, 0, :] = SKY / 0.282094792 * 0.5
    lit = (p @ PLANE_N < PLANE_C).astype(float)
    c += 4.0 * lit[:, None, None] * SUN_Y[None, :, None] * np.array([1.0, 0.95, 0.8])
    return c


def field_smooth(p):
    c = np.zeros((len(p), C, 3))
    c[:, 0, :] = SKY / 0.282094792 * 0.5
    d = LIGHT - p
    r2 = (d * d).sum(axis=1)
    c += (20.0 / (r2 + 0.25))[:, None, None] * _basis(d)[:, :, None] * np.array([1.0, 0.8, 0.6])
    return c


FIELDS = {"shadow edge": field_shadow, "smooth gradient": field_smooth}


def irr_error(a, ref):
    """Relative irradiance RMS over directions and RGB, per point (exact in SH)."""
    d = (A[None, :, None] * (a - ref)) ** 2
    r = (A[None, :, None] * ref) ** 2
    return np.sqrt(d.sum(axis=(1, 2)) / r.sum(axis=(1, 2)))


class Baker:
    """Bakes points once (cache by lattice point), with seeded noise; counts bakes."""

    def __init__(self, field, seed):
        self.field, self.cache, self.rng = field, {}, np.random.default_rng(seed)

    def bake(self, positions):
        keys = [tuple(np.round(p / MIN_CELL * 2).astype(np.int64)) for p in positions]
        todo = [i for i, k in enumerate(keys) if k not in self.cache]
        if todo:
            v = self.field(positions[todo])
            v *= 1.0 + NOISE * self.rng.standard_normal(v.shape)
            for i, val in zip(todo, v):
                self.cache[keys[i]] = val
        return np.stack([self.cache[k] for k in keys]) if keys else np.zeros((0, C, 3))

    @property
    def count(self):
        return len(self.cache)


def sample_points(seed=7, n=512):
    rng = np.random.default_rng(seed)
    return rng.random((n, 3)) * (EXTENT - 0.2) + 0.1


def root_tree():
    dims = (EXTENT / (MIN_CELL * 2 ** ROOT_LEVEL)).astype(int)
    t = native.CornerOctree.uniform((0, 0, 0), MIN_CELL, ROOT_LEVEL, tuple(int(d) for d in dims))
    t.finalize()
    return t


def stats(e):
    return float(np.mean(e)), float(np.percentile(e, 95)), float(np.max(e))


def measure(interp, values, pts, ref):
    return stats(irr_error(interp.interpolate(pts, values), ref))


def uniform_rows(field, pts, ref):
    rows = []
    for s in (2.0, 1.0, 0.5, 0.25):
        dims = tuple(int(round(v / s)) for v in EXTENT)
        t = native.CornerOctree.uniform((0, 0, 0), s, 0, dims)
        t.finalize()
        pos = t.positions()
        vals = Baker(field, 1).bake(pos)
        for name, it in (("trilinear", t), ("tetrahedra", native.Tetrahedra.create(pos))):
            rows.append((f"uniform grid {s:g} m", name, len(pos), len(pos)) + measure(it, vals, pts, ref))
    return rows


def geometry_rows(field, pts, ref):
    """Today's rule: leaves touching the box's faces (walls, floor, ceiling) split to Min Cell Size."""
    t = root_tree()
    lat = (EXTENT / MIN_CELL).astype(int)
    while True:
        lv = t.info()["leaves"]
        size = 1 << lv[:, 3]
        touch = ((lv[:, :3] == 0) | (lv[:, :3] + size[:, None] >= lat)).any(axis=1) & (lv[:, 3] > 0)
        if not touch.any():
            break
        t.split(touch)
    t.finalize()
    lv = t.info()["leaves"]
    size = (1 << lv[:, 3]) * MIN_CELL
    centres = lv[:, :3] * MIN_CELL + size[:, None] / 2
    baker = Baker(field, 2)
    cvals = baker.bake(centres)
    # v1 lookup: the probe of the leaf holding the point, constant inside it.
    lo = lv[:, :3] * MIN_CELL
    inside = ((pts[:, None, :] >= lo[None]) & (pts[:, None, :] < lo[None] + size[None, :, None])).all(axis=2)
    got = cvals[inside.argmax(axis=1)]
    rows = [("geometry octree (today)", "v1 centre probe, constant", len(centres), len(centres))
            + stats(irr_error(got, ref))]
    pos = t.positions()
    b2 = Baker(field, 3)
    vals = b2.bake(pos)
    for name, it in (("trilinear", t), ("tetrahedra", native.Tetrahedra.create(pos))):
        rows.append(("geometry octree, corner probes", name, len(pos), len(pos)) + measure(it, vals, pts, ref))
    return rows


def refine(field, tol, seed=4, centre_only=False):
    t = root_tree()
    baker = Baker(field, seed)
    passes = 0
    while True:
        pos = t.positions()
        vals = baker.bake(pos)
        tests = t.refine_tests()
        tvals = np.zeros((len(tests.positions), C, 3))
        if centre_only:  # only the leaf centres are tested (and baked)
            tests.leaf_tests = tests.leaf_tests.copy()
            tests.leaf_tests[:, 1:] = -1
        used = np.unique(tests.leaf_tests[tests.leaf_tests >= 0])
        tvals[used] = baker.bake(tests.positions[used])
        split, _, _ = t.refine_decide(tests, vals, tvals, probe_noise=np.full(len(pos), NOISE, np.float32),
                                      test_noise=np.full(len(tests.positions), NOISE, np.float32),
                                      tolerance=tol)
        if not split.any():
            return t, vals, baker.count, passes
        t.split(split)
        t.finalize()
        passes += 1


def refine_rows(field, pts, ref):
    rows = []
    for centre_only in (False, True):
        for tol in (0.2, 0.1, 0.05, 0.02, 0.01):
            t, vals, bakes, passes = refine(field, tol, centre_only=centre_only)
            pos = t.positions()
            what = "centre tests" if centre_only else "centre + face tests"
            for name, it in (("trilinear", t), ("tetrahedra", native.Tetrahedra.create(pos))):
                rows.append((f"error-driven, {what}, tol {tol:g} ({passes} passes)", name, len(pos), bakes)
                            + measure(it, vals, pts, ref))
    return rows


def pareto(rows):
    """Rows not dominated in (bakes, mean error): bakes are what a bake's time is made of."""
    out = set()
    for i, r in enumerate(rows):
        if not any(o[3] <= r[3] and o[4] <= r[4] and (o[3] < r[3] or o[4] < r[4]) for o in rows):
            out.add(i)
    return out


def main():
    t0 = time.time()
    pts = sample_points()
    lines = ["# Interpolation and placement on synthetic fields (CPU, no Cycles)", "",
             "Generated by `/usr/bin/python3 bench/bench_interp.py` (do not edit by hand). "
             "Method, fields and metric: the script's docstring. 16 m x 4 m x 16 m box, Min Cell Size "
             f"{MIN_CELL} m, Max Cell Size {MIN_CELL * 2 ** ROOT_LEVEL:g} m, L = {BAND}, bake noise "
             f"{NOISE * 100:.1f} % relative RMS, {len(pts)} seeded points. Error = relative irradiance RMS over "
             "directions against the noiseless field; **P** = Pareto-optimal in (bakes, mean error); bakes = "
             "points rendered (probes + test points that did not become probes). Reading and the recommended "
             "default: docs/placement.md, \"Measured on synthetic fields\".", ""]
    for fname, field in FIELDS.items():
        ref = field(pts)
        rows = uniform_rows(field, pts, ref) + geometry_rows(field, pts, ref) + refine_rows(field, pts, ref)
        front = pareto(rows)
        lines += [f"## {fname}", "",
                  "| placement | interpolation | probes | bakes | mean error | p95 error | max error | |",
                  "|---|---|---|---|---|---|---|---|"]
        for i, (pl, it, n, bakes, m, p95, mx) in enumerate(rows):
            lines.append(f"| {pl} | {it} | {n} | {bakes} | {100 * m:.2f} % | {100 * p95:.2f} % | "
                         f"{100 * mx:.1f} % | {'**P**' if i in front else ''} |")
        lines.append("")
    lines.append(f"Run time {time.time() - t0:.1f} s.")
    out = os.path.join(ROOT, "bench", "results", "interp.md")
    text = "\n".join(lines) + "\n"
    if "--print" in sys.argv:
        print(text)
    else:
        with open(out, "w") as f:
            f.write(text)
        print(text)


if __name__ == "__main__":
    main()
