#!/usr/bin/env python3
"""Anisotropic refinement (issue 29 item 3): the product's isotropic octree against a prototype of
boxes with per-axis levels, on synthetic light fields (CPU only, no Cycles).

    /usr/bin/python3 bench/bench_aniso.py          # writes bench/results/aniso.md and aniso.json
    /usr/bin/python3 bench/bench_aniso.py --quick  # two tolerances, no files (a smoke run)

Volume, lattice, noise, metric and sample points are bench_interp.py's: a 16 m x 4 m x 16 m box,
Min Cell Size 0.25 m, Max Cell Size 4 m (4 x 1 x 4 root cells), radiance SH L2 RGB, bake noise
0.4 % relative RMS (seeded, one value per lattice point), errors = relative irradiance RMS over
directions against the noiseless field at 512 seeded points (mean, p90, max).

Placements, all from the same Max Cell Size roots and the same split rule: a leaf splits where a
test's error against the leaf's own interpolation exceeds sqrt(tol^2 + (2 sigma)^2):

- ``octree``: the product (native CornerOctree, refine_tests / refine_decide exactly as
  bench_interp.py drives them: 7 tests per leaf, centre + face centres, noise k = 2);
- ``kd iso``: the prototype below with its tests (edge midpoints + centre) but every failing leaf
  split on all its axes (cubes stay cubes): separates the effect of the test set from anisotropy;
- ``kd aniso``: the prototype: a failing edge midpoint splits the leaf along its axis; a failing
  middle point (centre) along all its axes, only where no edge test of the leaf failed;
- ``kd aniso, edges only``: the same without the middle point (fewer renders, blind inside a leaf).

Fields (closed form, FIELDS below): a sunlit floor (contact shadow and bounce, along y only), a wall's
near field (along x only), a sun beam edge on a plane oblique to all axes, bench_interp.py's shadow
edge (plane normal in xz) and smooth gradient (point light), the floor crossed by a beam's vertical
edge, a compact spot at a root cell's centre, and a room-like mix (floor, wall, a sun beam through a
skylight with its floor patch, the point light). Ratios in the results: the octree's probes / renders
interpolated in log-log at the prototype's error (equal_error).

Prototype (``KdTree``): leaves are boxes on the lattice with per-axis levels (lx, ly, lz): size
2^l_a min cells on axis a, min corner a multiple of it (a "2:1-split kd-tree": a split halves one
axis). Probes at box corners, trilinear inside. A corner lying inside a face or an edge of another
leaf (a hanging node) takes that leaf's multilinear value there (the largest such face, else edge);
sources are strictly coarser lattice points, so resolving from coarse to fine is acyclic. Faces of
two neighbours must nest (one contains the other); a "cross" (A finer on one tangential axis, B on
the other) is removed by forced splits before each pass, which keeps the field C0 (checked at
10 000 border points per final tree). Test points of a leaf: for every axis a with l_a > 0, the 4
midpoints of its edges along a; plus the point at the middle of all splittable axes (the centre,
or the face centres when one axis is at level 0). A failing test splits the leaf along the axes on
which it lies at the middle (the middle point only where no edge test failed), so it becomes a probe
of the children. "renders" = distinct lattice
points baked (probes + tests that never became probes).
"""
from __future__ import annotations

import json
import os
import resource
import subprocess
import sys
import time

import numpy as np

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
sys.path.insert(0, os.path.join(ROOT, "bench"))
sys.path.insert(0, os.path.join(ROOT, "addon"))
import bench_interp as bi  # noqa: E402  (fields, metric, baker, sample points, native octree)

C = bi.C
EXTENT = bi.EXTENT
MIN_CELL = bi.MIN_CELL
ROOT_LEVEL = bi.ROOT_LEVEL
NOISE = bi.NOISE
DIMS = (EXTENT / MIN_CELL).astype(np.int64)  # lattice cells per axis (64, 16, 64)


# ---------------------------------------------------------------------------------------------
# Prototype: boxes with per-axis levels on the lattice
# ---------------------------------------------------------------------------------------------

def _tz(v, cap=30):
    """Trailing zeros of non-negative ints (0 -> cap)."""
    v = np.asarray(v, dtype=np.int64)
    out = np.full(v.shape, cap, dtype=np.int64)
    nz = v != 0
    low = v[nz] & -v[nz]
    out[nz] = np.minimum(np.round(np.log2(low)).astype(np.int64), cap)
    return out


class KdTree:
    """Leaves (N, 6) int64: x, y, z (lattice min corner), lx, ly, lz. ``dims``: lattice cells."""

    def __init__(self, leaves, dims=DIMS):
        self.leaves = np.asarray(leaves, dtype=np.int64).reshape(-1, 6)
        self.dims = np.asarray(dims, dtype=np.int64)
        self.forced = 0  # leaves split by the nesting rule, summed over passes
        self._built = False

    @classmethod
    def roots(cls, dims=DIMS, root_level=ROOT_LEVEL):
        n = dims // (1 << root_level)
        g = np.stack(np.meshgrid(*[np.arange(k) for k in n], indexing="ij"), -1).reshape(-1, 3)
        lv = np.concatenate([g * (1 << root_level), np.full((len(g), 3), root_level)], axis=1)
        return cls(lv, dims)

    # -- geometry -------------------------------------------------------------------------------
    @property
    def lo(self):
        return self.leaves[:, :3]

    @property
    def size(self):
        return np.left_shift(1, self.leaves[:, 3:])

    def _paint(self):
        cm = np.full(tuple(self.dims), -1, dtype=np.int64)
        for i, (x, y, z, lx, ly, lz) in enumerate(self.leaves.tolist()):
            sl = cm[x:x + (1 << lx), y:y + (1 << ly), z:z + (1 << lz)]
            if (sl >= 0).any():
                raise ValueError("overlapping leaves")
            sl[...] = i
        if (cm < 0).any():
            raise ValueError("leaves do not cover the lattice")
        self.cellmap = cm

    def split(self, axes):
        """Split leaf i along every axis a with axes[i, a] (levels > 0 only). Returns leaves split."""
        axes = np.asarray(axes, dtype=bool).copy()
        axes &= self.leaves[:, 3:] > 0
        n = int(axes.any(axis=1).sum())
        lv = self.leaves
        for a in range(3):
            m = axes[:, a]
            if not m.any():
                continue
            kids = lv[m].copy()
            kids[:, 3 + a] -= 1
            hi = kids.copy()
            hi[:, a] += np.left_shift(1, kids[:, 3 + a])
            keep = lv[~m]
            lv = np.concatenate([keep, kids, hi])
            axes = np.concatenate([axes[~m], axes[m], axes[m]])
        self.leaves = lv
        self._built = False
        return n

    def enforce_nesting(self):
        """Forced splits until every pair of face neighbours has nested faces (no cross)."""
        total = 0
        while True:
            self._paint()
            flags = np.zeros((len(self.leaves), 3), dtype=bool)
            lo, lvl = self.lo, self.leaves[:, 3:]
            sz = self.size
            for a in range(3):
                b, c = [k for k in range(3) if k != a]
                hi_a = lo[:, a] + sz[:, a]
                for i in np.nonzero(hi_a < self.dims[a])[0]:
                    sl = [slice(lo[i, k], lo[i, k] + sz[i, k]) for k in range(3)]
                    sl[a] = hi_a[i]
                    for j in np.unique(self.cellmap[tuple(sl)]):
                        db, dc = lvl[j, b] - lvl[i, b], lvl[i, c] - lvl[j, c]
                        if db > 0 and dc > 0:  # i finer on b, coarser on c
                            if dc <= db:
                                flags[i, c] = True
                            else:
                                flags[j, b] = True
                        elif db < 0 and dc < 0:  # i coarser on b, finer on c
                            if -db <= -dc:
                                flags[i, b] = True
                            else:
                                flags[j, c] = True
            if not flags.any():
                break
            total += self.split(flags)
        self.forced += total
        return total

    # -- nodes, probes and hanging rules --------------------------------------------------------
    def build(self):
        """Paint the cell map, number the corner nodes, classify probes / hanging nodes and expand
        every node into probe weights (CSR: node_ptr, node_probe, node_w)."""
        self._paint()
        lo, sz, lvl = self.lo, self.size, self.leaves[:, 3:]
        off = np.array([[(c >> k) & 1 for k in range(3)] for c in range(8)], dtype=np.int64)
        corners = lo[:, None, :] + off[None] * sz[:, None, :]  # (N, 8, 3)
        d1 = self.dims + 1
        keys = corners[..., 0] + d1[0] * (corners[..., 1] + d1[1] * corners[..., 2])
        ukeys, inv = np.unique(keys.reshape(-1), return_inverse=True)
        self.leaf_nodes = inv.reshape(-1, 8)
        nodes = np.stack([ukeys % d1[0], (ukeys // d1[0]) % d1[1], ukeys // (d1[0] * d1[1])], -1)
        self.node_lattice = nodes
        U = len(nodes)
        # adjacent leaves of every node: the up to 8 cells having it as a corner
        best = np.full(U, -1, dtype=np.int64)
        best_score = np.full(U, -1, dtype=np.int64)
        for d in off:
            cell = nodes - d
            ok = ((cell >= 0) & (cell < self.dims)).all(axis=1)
            leaf = np.full(U, -1, dtype=np.int64)
            leaf[ok] = self.cellmap[cell[ok, 0], cell[ok, 1], cell[ok, 2]]
            li = leaf[ok]
            rel = nodes[ok] - lo[li]
            interior = (rel > 0) & (rel < sz[li])
            ni = interior.sum(axis=1)
            score = np.where(ni > 0, 100 * ni + (lvl[li] * interior).sum(axis=1), -1)
            idx = np.nonzero(ok)[0]
            better = score > best_score[idx]
            best[idx[better]] = li[better]
            best_score[idx[better]] = score[better]
        hanging = best_score > 0
        self.host = np.where(hanging, best, -1)
        probe_nodes = np.nonzero(~hanging)[0]
        self.probe_count = len(probe_nodes)
        self.probe_node = probe_nodes
        self.probe_lattice = nodes[probe_nodes]
        pid = np.full(U, -1, dtype=np.int64)
        pid[probe_nodes] = np.arange(len(probe_nodes))
        # expand hanging nodes, coarse to fine (sources are strictly coarser lattice points)
        pot = _tz(nodes, ROOT_LEVEL + 1).sum(axis=1)
        rows = [None] * U
        for u in probe_nodes.tolist():
            rows[u] = {int(pid[u]): 1.0}
        self.max_sources = 1
        hn = np.nonzero(hanging)[0]
        for u in hn[np.argsort(-pot[hn], kind="stable")].tolist():
            L = int(self.host[u])
            w = self._trilinear(L, nodes[u].astype(float))
            acc = {}
            for c in range(8):
                if w[c] == 0.0:
                    continue
                src = rows[int(self.leaf_nodes[L, c])]
                if src is None:
                    raise AssertionError("hanging source not resolved (cycle)")
                for p, v in src.items():
                    acc[p] = acc.get(p, 0.0) + w[c] * v
            rows[u] = acc
            self.max_sources = max(self.max_sources, len(acc))
        ptr = np.zeros(U + 1, dtype=np.int64)
        ptr[1:] = np.cumsum([len(r) for r in rows])
        self.node_ptr = ptr
        self.node_probe = np.fromiter((p for r in rows for p in r), dtype=np.int64, count=ptr[-1])
        self.node_w = np.fromiter((v for r in rows for v in r.values()), dtype=np.float64, count=ptr[-1])
        self.hanging_count = int(hanging.sum())
        self._built = True

    def _trilinear(self, L, p):
        t = (p - self.lo[L]) / self.size[L]
        f = np.stack([1 - t, t])  # (2, 3)
        return np.array([f[c & 1, 0] * f[(c >> 1) & 1, 1] * f[(c >> 2) & 1, 2] for c in range(8)])

    def positions(self):
        return self.probe_lattice * MIN_CELL

    def node_values(self, probe_values):
        v = np.asarray(probe_values, dtype=np.float64)
        U = len(self.node_ptr) - 1
        out = np.zeros((U,) + v.shape[1:])
        rows = np.repeat(np.arange(U), np.diff(self.node_ptr))
        np.add.at(out, rows, self.node_w.reshape((-1,) + (1,) * (v.ndim - 1)) * v[self.node_probe])
        return out

    # -- lookup ---------------------------------------------------------------------------------
    def locate(self, u):
        """Leaf of lattice points u (N, 3) (max faces belong to the last cells)."""
        q = np.clip(np.floor(u).astype(np.int64), 0, self.dims - 1)
        return self.cellmap[q[:, 0], q[:, 1], q[:, 2]]

    def leaf_weights(self, leaf, u):
        """Trilinear weights (N, 8) of points u in the given leaves (not clamped)."""
        t = (u - self.lo[leaf]) / self.size[leaf]
        w = np.ones((len(u), 8))
        for c in range(8):
            for k in range(3):
                w[:, c] *= t[:, k] if (c >> k) & 1 else 1 - t[:, k]
        return w

    def interpolate_lattice(self, u, node_vals, leaf=None):
        if leaf is None:
            leaf = self.locate(u)
        w = self.leaf_weights(leaf, u)
        return np.einsum("nc,nc...->n...", w, node_vals[self.leaf_nodes[leaf]])

    def interpolate(self, points, probe_values):
        return self.interpolate_lattice(np.asarray(points) / MIN_CELL, self.node_values(probe_values))

    def probe_weight_sq(self, leaf, u):
        """sum_i W_i^2 of the expanded probe weights of points u in their leaves."""
        w = self.leaf_weights(leaf, u)
        nodes = self.leaf_nodes[leaf]  # (T, 8)
        t_idx = np.repeat(np.arange(len(u)), 8)
        n = nodes.reshape(-1)
        wc = w.reshape(-1)
        cnt = np.diff(self.node_ptr)[n]
        start = self.node_ptr[n]
        rep = np.repeat(np.arange(len(n)), cnt)
        pos = np.arange(cnt.sum()) - np.repeat(np.cumsum(cnt) - cnt, cnt) + start[rep]
        probe = self.node_probe[pos]
        val = wc[rep] * self.node_w[pos]
        key = t_idx[rep] * (self.probe_count + 1) + probe
        uk, inv = np.unique(key, return_inverse=True)
        s = np.bincount(inv, weights=val)
        return np.bincount(uk // (self.probe_count + 1), weights=s * s, minlength=len(u))

    # -- refinement tests -----------------------------------------------------------------------
    def tests(self):
        """(T, 3) lattice test points (shared ones once), (T,) mid-axis masks (bit a = on the
        middle of axis a), leaf of each (leaf, test) pair and the pair's test index."""
        lo, sz, lvl = self.lo, self.size, self.leaves[:, 3:]
        can = lvl > 0
        pts, masks, leaves = [], [], []
        for m in range(1, 8):
            ax = [k for k in range(3) if (m >> k) & 1]
            others = [k for k in range(3) if not (m >> k) & 1]
            if len(ax) == 1:
                sel = can[:, ax[0]]
            else:
                # the point in the middle of all splittable axes: the centre, or the face centres
                # of a box with one axis at level 0 (edge midpoints already cover single axes)
                sel = (can[:, ax].all(axis=1)) & (~can[:, others]).all(axis=1) if others else can.all(axis=1)
            idx = np.nonzero(sel)[0]
            if not len(idx):
                continue
            for ext in range(1 << len(others)):
                p = lo[idx].copy()
                for k in ax:
                    p[:, k] += sz[idx, k] // 2
                for j, k in enumerate(others):
                    if (ext >> j) & 1:
                        p[:, k] += sz[idx, k]
                pts.append(p)
                masks.append(np.full(len(idx), m))
                leaves.append(idx)
        if not pts:
            return np.zeros((0, 3), np.int64), np.zeros(0, np.int64), np.zeros(0, np.int64), np.zeros(0, np.int64)
        P, M, Lf = np.concatenate(pts), np.concatenate(masks), np.concatenate(leaves)
        d1 = self.dims + 1
        key = P[:, 0] + d1[0] * (P[:, 1] + d1[1] * P[:, 2])
        uk, first, inv = np.unique(key, return_index=True, return_inverse=True)
        return P[first], M, Lf, inv


def kd_refine(field, tol, aniso=True, centre=True, lazy=False, seed=5, noise=NOISE, k=2.0, max_passes=40):
    """Error-driven refinement of the prototype. Returns (tree, probe values, renders, passes).
    ``lazy``: each pass in two stages: the edge midpoints first, then the middle points of the leaves
    whose edge tests all passed (the only ones the rule reads): the same decisions, fewer renders."""
    t = KdTree.roots()
    baker = bi.Baker(field, seed)
    passes = 0
    while True:
        t.enforce_nesting()
        t.build()
        vals = baker.bake(t.positions().astype(float))
        tp, masks, lf, ti = t.tests()
        single = np.isin(masks, (1, 2, 4))
        if not centre:  # edge midpoints only
            used = np.unique(ti[single])
            remap = np.full(len(tp), -1)
            remap[used] = np.arange(len(used))
            tp, masks, lf, ti = tp[used], masks[single], lf[single], remap[ti[single]]
            single = single[single]
        if not len(lf):
            return t, vals, baker.count, passes
        nv = t.node_values(vals)
        u = tp[ti].astype(float)
        fail = np.zeros(len(lf), dtype=bool)
        edge_fail = np.zeros(len(t.leaves), dtype=bool)
        # stage 1 (lazy) or all tests at once
        stages = [single, ~single] if lazy else [np.ones(len(lf), dtype=bool)]
        for st, sel in enumerate(stages):
            if lazy and st == 1:
                sel = sel & ~edge_fail[lf]
            if not sel.any():
                continue
            tv = baker.bake(tp[np.unique(ti[sel])].astype(float) * MIN_CELL)
            ref = np.zeros((len(tp),) + tv.shape[1:])
            ref[np.unique(ti[sel])] = tv
            interp = t.interpolate_lattice(u[sel], nv, leaf=lf[sel])
            err = bi.irr_error(interp, ref[ti[sel]])
            sigma = noise * np.sqrt(1.0 + t.probe_weight_sq(lf[sel], u[sel]))
            fail[sel] = err > np.sqrt(tol * tol + (k * sigma) ** 2)
            edge_fail[lf[fail & single]] = True
        if not fail.any() or passes >= max_passes:
            return t, vals, baker.count, passes
        axes = np.zeros((len(t.leaves), 3), dtype=bool)
        # an edge midpoint decides its own axis; a test in the middle of several axes (the centre)
        # splits along them only where no edge test failed: the edges explain it otherwise (the
        # centre's error is the sum of the axes' curvatures), and the children are tested again
        use = fail & (single | ~edge_fail[lf])
        for a in range(3):
            hit = use & (((masks >> a) & 1) == 1)
            axes[lf[hit], a] = True
        if not aniso:
            axes[axes.any(axis=1)] = True
        t.split(axes)
        passes += 1


# ---------------------------------------------------------------------------------------------
# C0 and linear checks (also used by tests/python/test_aniso_prototype.py)
# ---------------------------------------------------------------------------------------------

def border_jump(tree, n=10000, seed=11):
    """Largest difference between the two leaves' fields at n random points of leaf borders, with
    random probe values in [0, 1]."""
    if not tree._built:
        tree.build()
    rng = np.random.default_rng(seed)
    nv = tree.node_values(rng.random(tree.probe_count))
    lo, sz = tree.lo, tree.size
    worst, done = 0.0, 0
    while done < n:
        m = 4 * (n - done)
        L = rng.integers(0, len(tree.leaves), m)
        a = rng.integers(0, 3, m)
        hi = lo[L, a] + sz[L, a]
        ok = hi < tree.dims[a]
        L, a, hi = L[ok], a[ok], hi[ok]
        u = lo[L] + rng.random((len(L), 3)) * sz[L]
        u[np.arange(len(L)), a] = hi
        cell = np.floor(u).astype(np.int64)
        cell[np.arange(len(L)), a] = hi
        B = tree.cellmap[cell[:, 0], cell[:, 1], cell[:, 2]]
        va = tree.interpolate_lattice(u, nv, leaf=L)
        vb = tree.interpolate_lattice(u, nv, leaf=B)
        k = min(len(L), n - done)
        worst = max(worst, float(np.abs(va - vb)[:k].max()))
        done += k
    return worst


def linear_error(tree, n=4000, seed=12):
    """Largest error reproducing a field linear in position at n random points."""
    if not tree._built:
        tree.build()
    rng = np.random.default_rng(seed)
    g, c0 = np.array([0.37, -1.3, 0.71]), 0.25
    vals = tree.probe_lattice @ g + c0
    u = rng.random((n, 3)) * tree.dims
    return float(np.abs(tree.interpolate_lattice(u, tree.node_values(vals)) - (u @ g + c0)).max())


# ---------------------------------------------------------------------------------------------
# Fields
# ---------------------------------------------------------------------------------------------

def _sky_l0(n):
    c = np.zeros((n, C, 3))
    c[:, 0, :] = bi.SKY / 0.282094792 * 0.5
    return c


Y_DOWN = bi._basis(np.array([[0.0, -1.0, 0.0]]))[0]
Y_WEST = bi._basis(np.array([[-1.0, 0.0, 0.0]]))[0]
FLOOR_RGB = np.array([1.0, 0.85, 0.7])


def _near(d, amp=2.5, occ=0.6, fall=0.35):
    """Sky occlusion and bounce of a lit surface at distance d (m): contact falloff."""
    e = np.exp(-d / fall)
    return 1.0 - occ * e, amp * (0.3 + 0.7 * e)


def field_floor(p):
    """A sunlit floor: irradiance varies along y only (contact shadow of the sky, floor bounce)."""
    sky, bounce = _near(p[:, 1])
    c = _sky_l0(len(p)) * sky[:, None, None]
    return c + bounce[:, None, None] * Y_DOWN[None, :, None] * FLOOR_RGB


def field_wall(p):
    """A wall's near field at x = 0: varies along x only."""
    sky, bounce = _near(p[:, 0], amp=1.8, occ=0.5, fall=0.3)
    c = _sky_l0(len(p)) * sky[:, None, None]
    return c + bounce[:, None, None] * Y_WEST[None, :, None] * np.array([0.8, 0.9, 1.0])


OBL_N = np.array([1.0, 1.3, 0.6]) / np.linalg.norm([1.0, 1.3, 0.6])
OBL_C = float(np.array([8.0, 2.0, 8.0]) @ OBL_N)


def field_oblique(p):
    """A sun beam edge on a plane oblique to all three axes (no axis is constant)."""
    lit = (p @ OBL_N < OBL_C).astype(float)
    return _sky_l0(len(p)) + 4.0 * lit[:, None, None] * bi.SUN_Y[None, :, None] * np.array([1.0, 0.95, 0.8])


BEAM_N = np.array([1.0, 0.0, 0.4]) / np.linalg.norm([1.0, 0.0, 0.4])
BEAM_C = 6.1


def field_floor_beam(p):
    """The floor plus a sun beam whose vertical edge crosses it: the sun where lit, the floor's
    bounce three times brighter on the lit side."""
    lit = (p @ BEAM_N < BEAM_C).astype(float)
    sky, bounce = _near(p[:, 1])
    c = _sky_l0(len(p)) * sky[:, None, None]
    c += (bounce * (1.0 + 2.0 * lit))[:, None, None] * Y_DOWN[None, :, None] * FLOOR_RGB
    return c + 4.0 * lit[:, None, None] * bi.SUN_Y[None, :, None] * np.array([1.0, 0.95, 0.8])


SPOT = np.array([6.0, 2.0, 10.0])  # the centre of the root cell (4..8, 0..4, 8..12) m


def field_spot(p):
    """A compact bright spot (Gaussian, 0.4 m) at a root cell's centre, 2.8 m from its edges: a
    feature that only a test inside the cell can see."""
    g = np.exp(-((p - SPOT) ** 2).sum(axis=1) / (2 * 0.4 ** 2))
    return _sky_l0(len(p)) * (1.0 + 3.0 * g)[:, None, None]


SKYLIGHT = (5.0, 9.0, 6.0, 10.0)  # x0, x1, z0, z1 of a skylight in the ceiling (y = 4 m)


def _skylight_lit(p):
    """Inside the sun's beam through the skylight: the point's ray towards the sun (SUN_DIR) meets the
    ceiling inside the opening. The beam's 4 edges are planes containing the sun direction."""
    d = bi.SUN_DIR / np.linalg.norm(bi.SUN_DIR)
    q = p + d[None] * ((EXTENT[1] - p[:, 1]) / d[1])[:, None]
    x0, x1, z0, z1 = SKYLIGHT
    return ((q[:, 0] > x0) & (q[:, 0] < x1) & (q[:, 2] > z0) & (q[:, 2] < z1)).astype(float)


def field_room(p):
    """A room-like mix: the floor's contact shadow and bounce (y), a wall's near field at x = 0 (x), a
    sun beam through a skylight (oblique edges) whose floor patch brightens the floor's bounce, and the
    smooth gradient's point light."""
    sky, bounce = _near(p[:, 1])
    wsky, wb = _near(p[:, 0], amp=1.8, occ=0.5, fall=0.3)
    c = _sky_l0(len(p)) * (sky * wsky)[:, None, None]
    floor_pt = p.copy()
    floor_pt[:, 1] = 0.0
    patch = _skylight_lit(floor_pt)
    c += (bounce * (1.0 + 2.0 * patch))[:, None, None] * Y_DOWN[None, :, None] * FLOOR_RGB
    c += wb[:, None, None] * Y_WEST[None, :, None] * np.array([0.8, 0.9, 1.0])
    c += 4.0 * _skylight_lit(p)[:, None, None] * bi.SUN_Y[None, :, None] * np.array([1.0, 0.95, 0.8])
    d = bi.LIGHT - p
    c += (20.0 / ((d * d).sum(axis=1) + 0.25))[:, None, None] * bi._basis(d)[:, :, None] * np.array([1.0, 0.8, 0.6])
    return c


FIELDS = {
    "sunlit floor (y only)": field_floor,
    "wall near field (x only)": field_wall,
    "oblique beam edge": field_oblique,
    "shadow edge (bench_interp, plane normal in xz)": bi.field_shadow,
    "smooth gradient (bench_interp, point light)": bi.field_smooth,
    "floor + beam edge crossing it": field_floor_beam,
    "spot inside a root cell": field_spot,
    "room-like mix (floor, wall, skylight beam, lamp)": field_room,
}


# ---------------------------------------------------------------------------------------------
# Bench
# ---------------------------------------------------------------------------------------------

def p90(e):
    return float(np.percentile(e, 90))


def row(method, field_name, tol, probes, renders, passes, e, extra=None):
    r = {"field": field_name, "method": method, "tolerance": tol, "probes": int(probes),
         "renders": int(renders), "passes": int(passes), "mean": float(np.mean(e)), "p90": p90(e),
         "max": float(np.max(e))}
    if extra:
        r.update(extra)
    return r


ROOTS = int(np.prod(DIMS // (1 << ROOT_LEVEL)))


def file_kib(probes, leaves, hanging, tree_bytes=0):
    """Size of the .shprobe (L2 float32, positions): v3 octree, or the v4 proposal with its split
    tree (docs/aniso-refinement.md)."""
    return (128 + (16 * C + 16 + 16) * probes + 48 * leaves + 32 * hanging + tree_bytes) / 1024


def run_field(name, field, tols, pts, ref, log):
    rows = []
    for tol in tols:
        t0 = time.process_time()
        tree, vals, bakes, passes = bi.refine(field, tol)
        e = bi.irr_error(tree.interpolate(pts, vals), ref)
        info = tree.info()
        nl, nh = int(len(info["leaves"])), int(info["hanging_count"])
        rows.append(row("octree", name, tol, tree.probe_count, bakes, passes, e,
                        {"leaves": nl, "hanging": nh, "file_kib": file_kib(tree.probe_count, nl, nh),
                         "max_depth": int(ROOT_LEVEL - info["leaves"][:, 3].min()),
                         "cpu_s": time.process_time() - t0}))
        log(rows[-1])
        for method, aniso, centre, lazy in (("kd iso", False, True, False), ("kd aniso", True, True, False),
                                            ("kd aniso, 2 stages", True, True, True),
                                            ("kd aniso, edges only", True, False, False)):
            t0 = time.process_time()
            kt, kv, kb, kp = kd_refine(field, tol, aniso=aniso, centre=centre, lazy=lazy)
            e = bi.irr_error(kt.interpolate(pts, kv), ref)
            nl = int(len(kt.leaves))
            ex = {"leaves": nl, "hanging": kt.hanging_count, "forced_splits": kt.forced,
                  "max_sources": kt.max_sources,
                  "file_kib": file_kib(kt.probe_count, nl, kt.hanging_count, 4 * (2 * nl - ROOTS)),
                  "max_depth": int((ROOT_LEVEL - kt.leaves[:, 3:]).sum(axis=1).max()),
                  "cpu_s": time.process_time() - t0}
            if aniso:
                lv = kt.leaves[:, 3:]
                ex["leaf_shapes"] = {"cubes": int((lv.min(1) == lv.max(1)).sum()),
                                     "aspect_2": int((lv.max(1) - lv.min(1) == 1).sum()),
                                     "aspect_4+": int((lv.max(1) - lv.min(1) >= 2).sum())}
                if tol == tols[-1]:
                    ex["c0_max_jump"] = border_jump(kt)
                    ex["linear_max_error"] = linear_error(kt)
            rows.append(row(method, name, tol, kt.probe_count, kb, kp, e, ex))
            log(rows[-1])
    return rows


def equal_error(base, other, key, what="mean", slack=0.05):
    """base's `key` (probes / renders) interpolated in log-log (piecewise linear, along base's
    curve sorted by error) at each of other's errors: the ratio base / other at equal error. An
    error outside base's range by at most `slack` (relative) takes the nearest end (base's error
    stops falling once the edge cells are at Min Cell Size); further out: None."""
    best = {}
    for r in base:  # per error value, the fewest counts that reached it
        best[r[what]] = min(best.get(r[what], np.inf), r[key])
    e = np.log(np.array(sorted(best)))
    v = np.log(np.array([best[k] for k in sorted(best)]))
    out = []
    for r in other:
        x = np.log(r[what])
        if x < e[0] - np.log1p(slack) or x > e[-1] + np.log1p(slack):
            out.append(None)
            continue
        out.append(float(np.exp(np.interp(x, e, v)) / r[key]))
    return out


def _fmt_ratio(v):
    return "—" if v is None else f"{v:.2f}"


def _range(vals):
    vals = [v for v in vals if v is not None]
    if not vals:
        return "—"
    lo, hi = min(vals), max(vals)
    return f"{lo:.2f}" if abs(hi - lo) < 0.005 else f"{lo:.2f}–{hi:.2f}"


def markdown(out):
    rows = out["rows"]
    L = ["# Anisotropic refinement on synthetic fields (issue 29 item 3, CPU, no Cycles)", "",
         f"Generated by `{out['command']}` (do not edit by hand); method, fields and prototype: the "
         "script's docstring; the design it supports: docs/aniso-refinement.md. 16 m x 4 m x 16 m box, "
         f"Min Cell Size {out['min_cell_m']} m, Max Cell Size {out['max_cell_m']:g} m, L2 RGB radiance SH, "
         f"bake noise {100 * out['noise']:.1f} % relative RMS, noise k = {out['noise_k']:g}, "
         f"{out['points']} seeded points; error = relative irradiance RMS over directions against the "
         "noiseless field (bench_interp.py's metric). **renders** = distinct lattice points baked "
         "(probes + tests that never became probes).", "",
         f"Run: {out['cpu_s']:.1f} CPU-s, {out['wall_s']:.1f} s wall, one thread, peak RSS "
         f"{out['maxrss_mib']:.0f} MiB, on the project's 2-core VM shared with other engineers' jobs; "
         f"`uptime` before: `{out['uptime_before']}`; after: `{out['uptime_after']}`.", "",
         "## Summary: octree / kd aniso at equal error", "",
         "Ratios > 1: the isotropic octree needs that many times the probes (renders) of the "
         "anisotropic prototype (edge + centre tests) for the same mean (p90) error, interpolated in "
         "log-log on the octree's tolerance curve; range over the tolerances where defined (an error "
         "outside the octree's range by > 5 %: —). *edges only* = the prototype without the centre "
         "test (it misses the spot: see its table); *2 stages* = the middle points baked in a second "
         "stage of each pass, only for the leaves whose edge tests all passed (the same rule).", "",
         "| field | probes, equal mean | renders, equal mean | probes, equal p90 | renders, equal p90 "
         "| tol 0.05: octree → kd aniso probes / renders (mean error) | edges only: renders, equal mean |",
         "|---|---|---|---|---|---|---|"]
    for name in out["fields"]:
        a = [r for r in rows if r["field"] == name and r["method"] == "kd aniso"]
        o = [r for r in rows if r["field"] == name and r["method"] == "octree"]
        eo = [r for r in rows if r["field"] == name and r["method"] == "kd aniso, edges only"]
        a5 = [r for r in a if r["tolerance"] == 0.05]
        o5 = [r for r in o if r["tolerance"] == 0.05]
        at5 = "—"
        if a5 and o5:
            at5 = (f"{o5[0]['probes']} / {o5[0]['renders']} ({100 * o5[0]['mean']:.2f} %) → "
                   f"{a5[0]['probes']} / {a5[0]['renders']} ({100 * a5[0]['mean']:.2f} %)")
        L.append(f"| {name} | {_range([r['octree_probes_ratio_equal_mean'] for r in a])} | "
                 f"{_range([r['octree_renders_ratio_equal_mean'] for r in a])} | "
                 f"{_range([r['octree_probes_ratio_equal_p90'] for r in a])} | "
                 f"{_range([r['octree_renders_ratio_equal_p90'] for r in a])} | {at5} | "
                 f"{_range([r['octree_renders_ratio_equal_mean'] for r in eo])} |")
    L += ["", "Checks on every final prototype tree (last tolerance): largest jump between the two "
          "leaves' fields at 10 000 random points of leaf borders (random probe values in [0, 1]) "
          "and largest error reproducing a linear field at 4000 points:", ""]
    jumps = [r["c0_max_jump"] for r in rows if "c0_max_jump" in r]
    lins = [r["linear_max_error"] for r in rows if "linear_max_error" in r]
    L.append(f"- C0: max jump {max(jumps):.1e} over {len(jumps)} trees; linear field: max error "
             f"{max(lins):.1e} (values of order 10-100 lattice units).")
    forced = [r.get("forced_splits", 0) for r in rows if r["method"].startswith("kd aniso")]
    srcs = [r.get("max_sources", 0) for r in rows if r["method"].startswith("kd")]
    depth = [r.get("max_depth", 0) for r in rows if r["method"].startswith("kd aniso")]
    L.append(f"- Forced splits of the nesting rule: at most {max(forced)} per refinement; a hanging node "
             f"depends on at most {max(srcs)} probes; kd descent depth (splits from a root to a leaf) at "
             f"most {max(depth)}.")
    L.append("")
    for name in out["fields"]:
        L += [f"## {name}", "",
              "| method | tol | probes | renders | passes | leaves | hanging | forced | mean | p90 | max "
              "| file KiB | octree/this probes, renders at equal mean |",
              "|---|---|---|---|---|---|---|---|---|---|---|---|---|"]
        for r in rows:
            if r["field"] != name:
                continue
            eq = ("" if r["method"] == "octree" else
                  f"{_fmt_ratio(r.get('octree_probes_ratio_equal_mean'))}, "
                  f"{_fmt_ratio(r.get('octree_renders_ratio_equal_mean'))}")
            L.append(f"| {r['method']} | {r['tolerance']:g} | {r['probes']} | {r['renders']} | {r['passes']} | "
                     f"{r['leaves']} | {r['hanging']} | {r.get('forced_splits', '')} | "
                     f"{100 * r['mean']:.3f} % | {100 * r['p90']:.3f} % | {100 * r['max']:.2f} % | "
                     f"{r['file_kib']:.0f} | {eq} |")
        L.append("")
    L += ["file KiB: the `.shprobe` at L2 float32 with positions: octree = version 3 (48 B per leaf, 32 B "
          "per hanging node), kd = the version 4 proposal (the same plus 4 B per split-tree node).", ""]
    return "\n".join(L)


def main():
    quick = "--quick" in sys.argv
    tols = (0.05, 0.02) if quick else (0.2, 0.1, 0.05, 0.02, 0.01)
    wall0, cpu0 = time.time(), time.process_time()
    load0 = subprocess.run(["uptime"], capture_output=True, text=True).stdout.strip()
    pts = bi.sample_points()
    rows = []

    def log(r):
        print(f"{r['field'][:28]:28s} {r['method']:20s} tol {r['tolerance']:<5g} probes {r['probes']:6d} "
              f"renders {r['renders']:6d} mean {100 * r['mean']:.3f}% p90 {100 * r['p90']:.3f}% "
              f"max {100 * r['max']:.2f}% ({r['cpu_s']:.1f} CPU-s)", flush=True)

    for name, field in FIELDS.items():
        rows += run_field(name, field, tols, pts, field(pts), log)
    load1 = subprocess.run(["uptime"], capture_output=True, text=True).stdout.strip()
    cpu = time.process_time() - cpu0
    wall = time.time() - wall0
    maxrss = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024
    if quick:
        print(f"{cpu:.1f} CPU-s, {wall:.1f} s wall")
        return
    for name in FIELDS:
        oct_ = [r for r in rows if r["field"] == name and r["method"] == "octree"]
        for m in ("kd iso", "kd aniso", "kd aniso, 2 stages", "kd aniso, edges only"):
            rs = [r for r in rows if r["field"] == name and r["method"] == m]
            for key in ("probes", "renders"):
                for what in ("mean", "p90"):
                    q = equal_error(oct_, rs, key, what)
                    for r, v in zip(rs, q):
                        r[f"octree_{key}_ratio_equal_{what}"] = v
            for r, o in zip(rs, oct_):
                r["octree_probes_ratio_same_tol"] = o["probes"] / r["probes"]
                r["octree_renders_ratio_same_tol"] = o["renders"] / r["renders"]
    out = {"command": "/usr/bin/python3 bench/bench_aniso.py", "cpu_s": cpu, "wall_s": wall,
           "fields": list(FIELDS),
           "maxrss_mib": maxrss, "uptime_before": load0, "uptime_after": load1,
           "volume_m": EXTENT.tolist(), "min_cell_m": MIN_CELL, "max_cell_m": MIN_CELL * 2 ** ROOT_LEVEL,
           "noise": NOISE, "noise_k": 2.0, "points": len(pts), "tolerances": list(tols), "rows": rows}
    with open(os.path.join(ROOT, "bench", "results", "aniso.json"), "w") as f:
        json.dump(out, f, indent=1)
    with open(os.path.join(ROOT, "bench", "results", "aniso.md"), "w") as f:
        f.write(markdown(out))
    print(f"{cpu:.1f} CPU-s, {wall:.1f} s wall; {load0} -> {load1}")


if __name__ == "__main__":
    main()
