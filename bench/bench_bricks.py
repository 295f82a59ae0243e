#!/usr/bin/env python3
"""Probe bricks (issue 30 item 1, first step): a numpy prototype of the corner octree's field resampled
into bricks of B x B x B probes in 3D textures with an indirection grid, sampled as the hardware's
trilinear filter samples a 3D texture, measured against the file's own interpolation (the C core,
``native.interpolation_from_file``). No engine code; the design it supports: docs/probe-bricks.md.

    nice -n 19 /usr/bin/python3 bench/bench_bricks.py            # JSON summary on stdout
    nice -n 19 /usr/bin/python3 bench/bench_bricks.py --quick    # fewer points (a smoke run)

Prototype (``Bricks``):

- **Levels.** B = 5 by default (B = 4, 3, 9 and 2 measured for the storage). A brick of level L holds
  B^3 texels at the lattice points ``r + 2^L (i, j, k)``, ``0 <= i, j, k < B``: (B - 1)^3 cells of 2^L
  min cells. Its *region* ``[r, r + (B - 1) 2^L)`` has its min corner ``r`` a multiple of
  ``(B - 1) 2^L``, so a region of level L + 1 is exactly 8 regions of level L (also for B - 1 = 3, which
  is not a power of two). Built top down from level R (the root level): a region that overlaps no leaf
  is empty; one whose overlapped leaves all have level >= L (for a kd tree: every axis level) becomes a
  brick; else it splits into its 8 children. A brick cell (2^L aligned) then lies inside one leaf or
  outside all of them, so trilinear filtering between its corner texels is the leaf's own trilinear
  field: exact.
- **Texels.** Two fields per texel at its lattice point x, both trilinear inside each leaf (hanging
  corners through their rules) and C0 across leaves: the numerator ``N(x) = sum_i W_i(x) m_i s_i c_i``
  and the denominator ``D(x) = sum_i W_i(x) m_i`` (``W_i`` the file's expanded weights without
  validity, ``m_i`` = 1 for validity > 0 else 0, ``s_i`` the probe scale). The file's rule (drop
  validity 0, renormalise) is N / D. Outside every leaf N = D = 0. Texels are computed by the C query.
- **Indirection.** A dense grid with one entry per level-0 region ((B - 1)^3 min cells): the brick and
  its level (-1 = empty), and one occupancy bit per unit cell of the region (a leaf holds it).
- **Sampler.** ``u`` (lattice coordinates, clamped into the lattice) -> unit cell q; if q is empty, the
  CPU's face margin (``locate_point_cell``: within 0.01 above q's lower face the cells below, x, y, xy,
  z, ...) picks an occupied cell and u is clamped into it; none: no probe -> the entry of q's level-0
  region -> region min ``r`` -> brick-local ``x = clamp((u - r) / 2^L, 0, B - 1)`` -> texel coordinate
  ``o + 0.5 + x`` in a pool texture (bricks laid side by side), filtered as Vulkan's LINEAR filter
  does: ``c - 0.5``, floor, fraction; the fraction is quantised to ``subTexelPrecisionBits`` = 8
  (1/256, round to nearest) in the "hw" variants, exact in the "exact" ones (8 texel fetches weighted
  in the shader). Coordinates go through fp32 normalised texture coordinates in the hw variants. Then
  N / D.

Measured (each in the JSON): exactness against the file at random points inside leaves (a linear
field against its closed form too), the seam between the two bricks on either side of every brick
border (evaluated at the same face point with each), validity through N / D, the back-face and
visibility rules (today's shader rule, ``octree_irradiance``, transcribed below) against brick-cell
versions of them on a plane wall, the fp16 irradiance error, and GPU bytes per probe. Synthetic trees
come from ``native.CornerOctree`` (random splits, and random per-axis splits for kd trees), written as
.shprobe files and read back; real bake files are used when present (REAL_FILES).
"""
from __future__ import annotations

import argparse
import glob
import json
import os
import sys
import tempfile
import time

import numpy as np

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
sys.path.insert(0, os.path.join(ROOT, "addon"))
from schnee_probes import native  # noqa: E402

A_BAND = np.array([np.pi] + [2 * np.pi / 3] * 3 + [np.pi / 4] * 5)  # DESIGN.md §3, L <= 2
VIS_RAMP = 0.25       # PB_VIS_RAMP (pb_cotree.h)
SUBTEXEL_BITS = 8     # VkPhysicalDeviceLimits::subTexelPrecisionBits on desktop GPUs and lavapipe
CHANNELS_PER_TEXEL = {0: 4, 1: 16, 2: 28}  # L0: RGB + D; L1: 12 + D -> 4 RGBA; L2: 27 + D -> 7 RGBA
# Real bakes, when present on this machine (none of them is part of the repository).
REAL_FILES = ["/tmp/b10/spheres/sh_coeffs/probes.shprobe", "/tmp/dl/room_after/sh_coeffs/probes.shprobe",
              "/tmp/dl/after_both/sh_coeffs/probes.shprobe"]
REAL_GLOBS = ["/tmp/bench_placement_*/adaptive_*_on.shprobe"]  # version 4 kd corner trees


# ---------------------------------------------------------------------------------------------------
# The file's field
# ---------------------------------------------------------------------------------------------------

class Field:
    """A version 3 / 4 .shprobe (octree or kd corner tree) with the C core's interpolation."""

    def __init__(self, path: str):
        self.path = path
        f = native.read_shprobe(path)
        if f.structure not in ("octree", "kdtree"):
            raise ValueError(f"{path}: structure {f.structure}; the prototype takes corner trees")
        self.file = f
        self.tree = native.interpolation_from_file(path)
        info = self.tree.info()
        self.h = float(f.grid_spacing)
        self.origin = np.array(f.grid_origin, dtype=np.float64)
        self.dims = np.array(f.grid_dims, dtype=np.int64)          # lattice extent in min cells
        self.lo = info["leaves"][:, :3].astype(np.int64)
        self.levels = info["levels"].astype(np.int64)              # (N, 3) per-axis levels
        assert np.array_equal(self.lo, f.leaves[:, :3].astype(np.int64)), "leaf order differs from the file"
        self.corners = f.leaf_corners.astype(np.int64)
        self.P = f.probe_count
        self.band = f.max_band
        self.C = (self.band + 1) ** 2
        self.valid = (f.validity > 0).astype(np.float64)
        scale = f.probe_scale.astype(np.float64)
        self.values = f.coeffs.astype(np.float64) * scale[:, None, None]   # s_i c_i  (P, C, 3)
        self.root_level = int(self.levels.max())
        # Node values as the engine resolves hanging nodes (sv_probe_pack.c resolve_hanging): A / a, a.
        H = 0 if f.hanging_sources is None else len(f.hanging_sources)
        A = np.zeros((self.P + H, self.C, 3))
        a = np.zeros(self.P + H)
        A[:self.P] = self.valid[:, None, None] * self.values
        a[:self.P] = self.valid
        for j in range(H):
            for src, w in zip(f.hanging_sources[j], f.hanging_weights[j]):
                if w > 0:
                    A[self.P + j] += w * A[src]
                    a[self.P + j] += w * a[src]
        self.node_A, self.node_a = A, a

    def world(self, u: np.ndarray) -> np.ndarray:
        return self.origin + u * self.h

    def num_den(self, u: np.ndarray, pair_visibility=None):
        """N and D (module docstring) at lattice points u (n, 3): (n, C, 3), (n,). 0 outside."""
        probes, w = self.tree.query(self.world(u), None, pair_visibility)
        idx = np.maximum(probes, 0)
        wm = w * self.valid[idx]
        N = np.einsum("nk,nkcd->ncd", wm, self.values[idx])
        D = wm.sum(axis=1)
        return N, D

    def interpolate(self, u: np.ndarray, pair_visibility=None):
        """The file's rule (validity 0 dropped, renormalised): (n, C, 3), NaN where no probe."""
        return self.tree.interpolate(self.world(u), self.values, self.file.validity, pair_visibility)

    def leaf_of(self, u: np.ndarray) -> np.ndarray:
        return self.tree.locate(self.world(u))

    def random_inside(self, n: int, rng) -> np.ndarray:
        """n lattice points uniform in random leaves (each leaf equally likely) and their leaves."""
        li = rng.integers(0, len(self.lo), n)
        size = (1 << self.levels[li]).astype(np.float64)
        u = self.lo[li] + rng.random((n, 3)) * size
        return u, li


def leaf_min_level_grid(field: Field, dilate: bool = True) -> np.ndarray:
    """Per unit lattice cell: the smallest axis level of the leaf covering it, -1 = no leaf. ``dilate``:
    an empty cell next to leaves (26 neighbours) takes the smallest level among them, so a brick over
    empty cells at a leaf's face samples that face at the leaf's resolution (the extension below)."""
    lev = np.full(tuple(field.dims), -1, dtype=np.int64)
    for lo, lv in zip(field.lo, field.levels):
        hi = lo + (1 << lv)
        lev[lo[0]:hi[0], lo[1]:hi[1], lo[2]:hi[2]] = lv.min()
    if dilate:
        big = np.where(lev >= 0, lev, 1 << 20)
        pad = np.pad(big, 1, constant_values=1 << 20)
        nb = np.full_like(big, 1 << 20)
        X, Y, Z = big.shape
        for o in np.ndindex(3, 3, 3):
            nb = np.minimum(nb, pad[o[0]:o[0] + X, o[1]:o[1] + Y, o[2]:o[2] + Z])
        lev = np.where((lev < 0) & (nb < 1 << 20), nb, lev)
    return lev


def leaf_contains(field: Field, li: np.ndarray, u: np.ndarray) -> np.ndarray:
    """Whether u lies in leaf li itself (not only through the face margin of locate_point_cell)."""
    ok = li >= 0
    l = np.maximum(li, 0)
    lo = field.lo[l]
    return ok & np.all((u >= lo) & (u <= lo + (1 << field.levels[l])), axis=1)


# ---------------------------------------------------------------------------------------------------
# Bricks
# ---------------------------------------------------------------------------------------------------

class Bricks:
    """The field in bricks of B^3 texels (module docstring)."""

    def __init__(self, field: Field, B: int = 5, pair_visibility=None, dilate: bool = False):
        self.field, self.B, self.cells = field, B, B - 1
        lev = leaf_min_level_grid(field, dilate)
        self.occupied = leaf_min_level_grid(field, False) >= 0   # unit cells a leaf holds
        self.unit_level = lev
        dims = field.dims
        R = field.root_level
        self.ind_dims = -(-dims // self.cells)                      # level-0 regions per axis
        self.indirection = np.full(tuple(self.ind_dims), -1, dtype=np.int64)
        bricks = []                                                 # (level, region min (3,))
        top = (self.cells << R)
        stack = [(R, np.array(r) * top) for r in np.ndindex(*tuple(-(-dims // top)))]
        while stack:
            L, r = stack.pop()
            ext = self.cells << L
            sl = lev[r[0]:r[0] + ext, r[1]:r[1] + ext, r[2]:r[2] + ext]
            occ = sl[sl >= 0]
            if occ.size == 0:
                continue
            if occ.min() >= L:
                b = len(bricks)
                bricks.append((L, r))
                i0 = r // self.cells
                n = 1 << L
                self.indirection[i0[0]:i0[0] + n, i0[1]:i0[1] + n, i0[2]:i0[2] + n] = b
                continue
            half = ext // 2
            for o in np.ndindex(2, 2, 2):
                stack.append((L - 1, r + np.array(o) * half))
        self.level = np.array([b[0] for b in bricks], dtype=np.int64)
        self.rmin = np.array([b[1] for b in bricks], dtype=np.int64).reshape(-1, 3)
        nb = len(bricks)
        # Texel lattice points of every brick, then N and D from the C query.
        g = np.stack(np.meshgrid(*(np.arange(B),) * 3, indexing="ij"), axis=-1).reshape(-1, 3)  # (B^3, 3)
        pts = self.rmin[:, None, :] + (1 << self.level)[:, None, None] * g[None]              # (nb, B^3, 3)
        N, D = field.num_den(pts.reshape(-1, 3).astype(np.float64), pair_visibility)
        C = field.C
        self.N = N.reshape(nb, B, B, B, C, 3)
        self.D = D.reshape(nb, B, B, B)
        # Pool texture: bricks side by side on a 3D grid of bricks (for the fp32 coordinate emulation).
        pb = int(np.ceil(nb ** (1 / 3)))
        self.pool_bricks = pb
        self.pool_dim = pb * B
        bi = np.arange(nb)
        self.origin = B * np.stack([bi % pb, (bi // pb) % pb, bi // (pb * pb)], axis=1)     # texel origin

    # -- storage -------------------------------------------------------------------------------------
    def texel_count(self) -> int:
        return len(self.level) * self.B ** 3

    def storage(self, half: bool = True) -> dict:
        """GPU bytes: the pool (channels at the file's band + D), the indirection (per level-0 region a
        word brick | level << 27 and the occupancy bits of its (B-1)^3 unit cells, rounded up to 8 or 16
        bytes: B = 4 RG32UI, B = 5 RGBA32UI), the brick table (16 B per brick: visibility base and
        blocked-cell bits); per probe of the file. Visibility records (64 B per blocked brick cell) are
        not counted: they need the scene."""
        ch = CHANNELS_PER_TEXEL[self.field.band]
        texel = ch * (2 if half else 4)
        pool = self.texel_count() * texel
        entry = 4 + 4 * -(-self.cells ** 3 // 32)
        entry = 8 if entry <= 8 else -(-entry // 16) * 16
        ind = int(np.prod(self.ind_dims)) * entry
        table = 16 * len(self.level)
        P = self.field.P
        return {"bricks": len(self.level), "texels": self.texel_count(), "texels_per_probe":
                self.texel_count() / P, "bytes_per_texel": texel, "pool_bytes": pool,
                "indirection_entries": int(np.prod(self.ind_dims)), "indirection_entry_bytes": entry,
                "indirection_bytes": ind, "brick_table_bytes": table,
                "bytes_per_probe": (pool + ind + table) / P,
                "levels": {int(k): int(v) for k, v in zip(*np.unique(self.level, return_counts=True))}}

    # -- sampling ------------------------------------------------------------------------------------
    def lookup(self, u: np.ndarray, margin: bool = True):
        """(brick (n,), -1 outside; the point to sample (n, 3)). The unit cell q of u (point_cell's clamp
        into the lattice) must be occupied (the indirection entry's occupancy bits); else, with
        ``margin``, locate_point_cell's face margin: within 0.01 above q's lower face on the axes of
        mask m = 1..7 (x, y, xy, z, ...) the cell q - m is tried, and u is clamped into it (onto its
        face: the CPU's t = clamp(.., 0, 1))."""
        dims = self.field.dims
        u = np.clip(u, 0.0, dims.astype(np.float64))
        q = np.minimum(np.floor(u).astype(np.int64), dims - 1)
        occ = self.occupied[q[:, 0], q[:, 1], q[:, 2]]
        cell = np.where(occ[:, None], q, -1)
        if margin:
            for m in range(1, 8):
                bits = np.array([m & 1, (m >> 1) & 1, (m >> 2) & 1], dtype=np.int64)
                r = q - bits
                ok = ~occ & np.all((bits == 0) | ((q > 0) & (u - q < 0.01)), axis=1)
                rr = np.maximum(r, 0)
                ok &= self.occupied[rr[:, 0], rr[:, 1], rr[:, 2]]
                cell = np.where(ok[:, None], r, cell)
                occ = occ | ok
        found = occ
        c = np.maximum(cell, 0)
        i = c // self.cells
        b = np.where(found, self.indirection[i[:, 0], i[:, 1], i[:, 2]], -1)
        u = np.where(found[:, None], np.clip(u, c, c + 1), u)
        return b, u

    def local(self, u: np.ndarray, b: np.ndarray) -> np.ndarray:
        """Brick-local texel coordinates x in [0, B - 1] of lattice points u in bricks b."""
        s = (1 << self.level[b]).astype(np.float64)[:, None]
        return np.clip((u - self.rmin[b]) / s, 0.0, self.B - 1.0)

    def cell_weights(self, x: np.ndarray, b: np.ndarray, mode: str):
        """Texel indices (n, 8, 3) in the brick and trilinear weights (n, 8) as the filter computes them.
        mode "exact": float64, the shader's own fraction; "hw": fp32 normalised coordinates through the
        pool texture, fraction quantised to 1/2^SUBTEXEL_BITS (round to nearest)."""
        if mode == "exact":
            i0 = np.minimum(np.floor(x), self.B - 2).astype(np.int64)
            f = x - i0
        else:
            dim = np.float32(self.pool_dim)
            tc = ((self.origin[b] + 0.5 + x).astype(np.float32) / dim).astype(np.float32)
            c = (tc * dim - np.float32(0.5)).astype(np.float32)
            ci = np.floor(c)
            f = (c - ci).astype(np.float64)
            q = float(1 << SUBTEXEL_BITS)
            f = np.round(f * q) / q
            ci = ci.astype(np.int64) - self.origin[b]
            carry = f >= 1.0
            ci = ci + carry
            f = np.where(carry, 0.0, f)
            # A texel index past the brick only ever comes with weight 0 (it is the next brick's).
            i0 = ci
        o = np.array(list(np.ndindex(2, 2, 2)))[:, ::-1]  # corner k: bits x, y, z = k & 1, k >> 1 & 1, k >> 2
        w = np.ones((len(x), 8))
        for a in range(3):
            w *= np.where(o[None, :, a] == 1, f[:, None, a], 1.0 - f[:, None, a])
        idx = i0[:, None, :] + o[None]
        return idx, w

    def fetch(self, b, idx, dtype):
        i = np.clip(idx, 0, self.B - 1)  # weight-0 taps past the brick: any texel
        bb = np.broadcast_to(b[:, None], i.shape[:2])
        N = self.N[bb, i[..., 0], i[..., 1], i[..., 2]].astype(dtype).astype(np.float64)
        D = self.D[bb, i[..., 0], i[..., 1], i[..., 2]].astype(dtype).astype(np.float64)
        return N, D

    def sample(self, u: np.ndarray, mode: str = "exact", dtype=np.float64, b=None):
        """(N / D (n, C, 3), D (n,), brick (n,)) at lattice points u; NaN where D = 0 or outside.
        ``b``: force the brick (the seam measurement)."""
        if b is None:
            b, u = self.lookup(u)
        out = np.full((len(u), self.field.C, 3), np.nan)
        Dout = np.zeros(len(u))
        ok = b >= 0
        if ok.any():
            x = self.local(u[ok], b[ok])
            idx, w = self.cell_weights(x, b[ok], mode)
            N, D = self.fetch(b[ok], idx, dtype)
            n = np.einsum("nk,nkcd->ncd", w, N)
            d = np.einsum("nk,nk->n", w, D)
            with np.errstate(invalid="ignore", divide="ignore"):
                out[ok] = np.where(d[:, None, None] > 0, n / d[:, None, None], np.nan)
            Dout[ok] = d
        return out, Dout, b


# ---------------------------------------------------------------------------------------------------
# Metrics
# ---------------------------------------------------------------------------------------------------

def normals(n: int, rng) -> np.ndarray:
    v = rng.normal(size=(n, 3))
    return v / np.linalg.norm(v, axis=1, keepdims=True)


def irradiance(coeffs: np.ndarray, dirs: np.ndarray, band: int) -> np.ndarray:
    """E(n) of SH coeffs (n_pts, C, 3) for every direction: (n_pts, n_dirs, 3) (DESIGN.md §3)."""
    C = (band + 1) ** 2
    AY = native.sh_basis(dirs, band)[:, :C] * A_BAND[:C]
    return np.einsum("dc,pcr->pdr", AY, coeffs)


def irr_rel_error(a: np.ndarray, ref: np.ndarray, dirs: np.ndarray, band: int) -> np.ndarray:
    """Per point: RMS over directions and RGB of E(a) - E(ref), over the RMS of E(ref)."""
    ea, er = irradiance(a, dirs, band), irradiance(ref, dirs, band)
    num = np.sqrt(np.mean((ea - er) ** 2, axis=(1, 2)))
    den = np.sqrt(np.mean(er ** 2, axis=(1, 2)))
    return num / np.maximum(den, 1e-30)


def stats(x: np.ndarray) -> dict:
    x = np.asarray(x, dtype=np.float64)
    x = x[np.isfinite(x)]
    if x.size == 0:
        return {"n": 0}
    return {"n": int(x.size), "max": float(x.max()), "p99": float(np.percentile(x, 99)),
            "mean": float(x.mean())}


# ---------------------------------------------------------------------------------------------------
# Synthetic trees
# ---------------------------------------------------------------------------------------------------

def synthetic_tree(seed: int, kd: bool = False, passes: int = 3, p_split: float = 0.3,
                   root_dims=(4, 2, 4), root_level: int = 3):
    """A finalized CornerOctree: uniform roots of 2^root_level min cells (min cell 0.25 m), random
    splits (kd: random per-axis masks)."""
    rng = np.random.default_rng(seed)
    t = native.CornerOctree.uniform((0.0, 0.0, 0.0), 0.25, root_level, root_dims)
    t.finalize()
    for _ in range(passes):
        n = t.leaf_count
        if kd:
            masks = np.where(rng.random(n) < p_split, rng.integers(1, 8, n), 0)
            t.split_axes(masks)
        else:
            t.split(rng.random(n) < p_split)
        t.finalize()
    return t


def random_sh(n: int, band: int, rng) -> np.ndarray:
    C = (band + 1) ** 2
    c = rng.uniform(-0.3, 0.3, (n, C, 3))
    c[:, 0, :] = rng.uniform(0.5, 2.0, (n, 3))
    return c


LIN_A = np.linspace(0.5, 2.0, 27).reshape(9, 3)
LIN_G = np.stack([np.linspace(-0.05, 0.05, 27), np.linspace(0.03, -0.02, 27),
                  np.linspace(0.01, 0.04, 27)], axis=-1).reshape(9, 3, 3)   # per metre


def linear_sh(pos: np.ndarray) -> np.ndarray:
    """A field linear in position, closed form: c(p) = LIN_A + LIN_G . p  (n, 9, 3)."""
    return LIN_A[None] + np.einsum("cdk,nk->ncd", LIN_G, pos)


def write_tree(tree, path: str, coeffs: np.ndarray, validity=None) -> Field:
    native.write_shprobe_v3(path, tree, coeffs.astype(np.float32), validity=validity)
    return Field(path)


# ---------------------------------------------------------------------------------------------------
# Measurements
# ---------------------------------------------------------------------------------------------------

MODES = [("exact", np.float64), ("exact", np.float32), ("exact", np.float16), ("hw", np.float32),
         ("hw", np.float16)]


def mode_name(mode, dtype):
    return f"{mode}-{np.dtype(dtype).name}"


def exactness(field: Field, bricks: Bricks, n: int, rng, closed_form=None) -> dict:
    """Bricks against the file at n random points inside leaves, every precision mode. Coefficient
    error relative to the field's largest |coefficient|, and relative irradiance error (16 normals)."""
    u, _ = field.random_inside(n, rng)
    ref = field.interpolate(u)
    keep = np.isfinite(ref).all(axis=(1, 2))
    u, ref = u[keep], ref[keep]
    scale = np.abs(ref).max()
    dirs = normals(16, rng)
    out = {"points": int(len(u))}
    if closed_form is not None:
        cf = closed_form(field.world(u))
        out["file_vs_closed_form"] = float(np.abs(ref - cf).max() / scale)
    for mode, dt in MODES:
        s, _, _ = bricks.sample(u, mode, dt)
        bad = ~np.isfinite(s).all(axis=(1, 2))
        e = {"coeff_max_rel": float(np.nanmax(np.abs(s - ref)) / scale), "no_value": int(bad.sum()),
             "irradiance_rel": stats(irr_rel_error(s[~bad], ref[~bad], dirs, field.band))}
        if closed_form is not None:
            e["coeff_max_rel_closed_form"] = float(np.nanmax(np.abs(s - cf)) / scale)
        out[mode_name(mode, dt)] = e
    return out


def hw_linear_bound(bricks: Bricks) -> float:
    """Closed-form bound of the 8-bit weight error on the linear field, relative to max |coeff|: a
    fraction off by at most 1/2^(bits+1) texel per axis moves the sample by 2^L h / 512 m per axis."""
    h = bricks.field.h
    dx = (1 << bricks.level.max()) * h / (1 << (SUBTEXEL_BITS + 1))
    return float(dx * np.abs(LIN_G).sum(axis=-1).max())


def seams(bricks: Bricks, n: int, rng) -> dict:
    """At n random points of brick borders: the face point evaluated with the brick on either side
    (same level / different levels), max |difference| relative to max |coefficient|."""
    f = bricks.field
    u, _ = f.random_inside(4 * n, rng)
    b, _ = bricks.lookup(u)
    keep = b >= 0
    u, b = u[keep], b[keep]
    axis = rng.integers(0, 3, len(u))
    r = np.arange(len(u))
    ext = (bricks.cells << bricks.level[b]).astype(np.float64)
    lo = bricks.rmin[b, axis].astype(np.float64)
    face = np.where(rng.random(len(u)) < 0.5, lo, lo + ext)
    u = u.copy()
    u[r, axis] = face
    eps = 1e-3
    um, up = u.copy(), u.copy()
    um[r, axis] -= eps
    up[r, axis] += eps
    bm, bp = bricks.lookup(um)[0], bricks.lookup(up)[0]
    ok = (bm >= 0) & (bp >= 0) & (bm != bp) & leaf_contains(f, f.leaf_of(um), um) & \
        leaf_contains(f, f.leaf_of(up), up)
    u, bm, bp = u[ok][:n], bm[ok][:n], bp[ok][:n]
    same = bricks.level[bm] == bricks.level[bp]
    ref = f.interpolate(u)
    scale = np.nanmax(np.abs(ref))
    e = np.zeros_like(u)
    e[np.arange(len(u)), axis[ok][:n]] = 1e-7
    file_jump = np.abs(f.interpolate(u - e) - f.interpolate(u + e)).max(axis=(1, 2)) / scale
    out = {"points": int(len(u)), "different_levels": int((~same).sum()),
           "file_jump_at_1e-7_max": float(np.nanmax(file_jump))}
    for mode, dt in MODES:
        sm, _, _ = bricks.sample(u, mode, dt, b=bm)
        sp, _, _ = bricks.sample(u, mode, dt, b=bp)
        j = np.abs(sm - sp).max(axis=(1, 2)) / scale
        out[mode_name(mode, dt)] = {"same_level_max": float(np.nanmax(j[same])) if same.any() else None,
                                    "different_levels_max": float(np.nanmax(j[~same])) if (~same).any() else None}
    return out


def outer_faces(field: Field, bricks: Bricks, n: int, rng) -> dict:
    """Points just outside the leaves, above a leaf's max face in a unit cell no leaf holds. Within
    0.01 min cells (the CPU's face margin, locate_point_cell) the CPU gives the face's value: bricks
    against it. Between 0.01 and 1 min cell the CPU gives no probe; the bricks' N / D extends the face
    (empty texels have N = D = 0): how many such points get a value."""
    lev = leaf_min_level_grid(field, dilate=False)
    li = rng.integers(0, len(field.lo), 8 * n)
    a = rng.integers(0, 3, len(li))
    size = (1 << field.levels[li]).astype(np.float64)
    u = field.lo[li] + rng.random((len(li), 3)) * size
    r = np.arange(len(li))
    out = {}
    for name, d0, d1 in (("margin 0-0.01", 1e-4, 0.0099), ("shell 0.01-1", 0.011, 0.99)):
        v = u.copy()
        v[r, a] = field.lo[li, a] + size[r, a] + d0 + (d1 - d0) * rng.random(len(li))
        q = np.floor(v).astype(np.int64)
        inside = np.all((q >= 0) & (q < field.dims), axis=1)
        qq = np.where(inside[:, None], q, 0)
        empty = inside & (lev[qq[:, 0], qq[:, 1], qq[:, 2]] < 0)
        v = v[empty][:n]
        ref = field.interpolate(v)
        s_, _, _ = bricks.sample(v)
        cpu = np.isfinite(ref).all(axis=(1, 2))
        brk = np.isfinite(s_).all(axis=(1, 2))
        both = cpu & brk
        scale = np.nanmax(np.abs(ref)) if cpu.any() else 1.0
        out[name] = {"points": int(len(v)), "cpu_value": int(cpu.sum()), "bricks_value": int(brk.sum()),
                     "both_max_rel": float(np.abs(s_[both] - ref[both]).max() / scale) if both.any() else None}
    return out


def validity_check(field: Field, bricks: Bricks, n: int, rng) -> dict:
    """N / D against the file's validity rule; what happens where D is ~0."""
    u, _ = field.random_inside(n, rng)
    ref = field.interpolate(u)
    cpu_none = ~np.isfinite(ref).all(axis=(1, 2))
    out = {"points": int(len(u)), "invalid_probes": int((field.valid == 0).sum()), "probes": field.P,
           "cpu_no_probe": int(cpu_none.sum())}
    scale = np.nanmax(np.abs(ref))
    for mode, dt in MODES:
        s, d, _ = bricks.sample(u, mode, dt)
        none = ~np.isfinite(s).all(axis=(1, 2))
        both = ~cpu_none & ~none
        err = np.abs(s[both] - ref[both]).max(axis=(1, 2)) / scale
        small = d[both] < 0.05
        out[mode_name(mode, dt)] = {
            "coeff_max_rel": float(err.max()) if err.size else None,
            "coeff_max_rel_where_D_below_0.05": float(err[small].max()) if small.any() else None,
            "points_D_below_0.05": int(small.sum()),
            "cpu_none_bricks_value": int((cpu_none & ~none).sum()),
            "cpu_value_bricks_none": int((~cpu_none & none).sum())}
    return out


def snorm8_irradiance(field: Field, bricks: Bricks, n: int, rng) -> dict:
    """The lossy option (not proposed as default): L0 and D in fp16, the L1/L2 numerators in snorm8
    with one scale per brick and coefficient-colour (max |value| over the brick's texels): 8 + 24 B per
    texel instead of 56. Relative irradiance RMS error against fp32 texels (exact weights)."""
    if field.band < 1:
        return {}
    u, _ = field.random_inside(n, rng)
    ref, _, _ = bricks.sample(u, "exact", np.float32)
    keepN = bricks.N.copy()
    sc = np.abs(bricks.N[:, :, :, :, 1:, :]).max(axis=(1, 2, 3), keepdims=True)
    sc = np.where(sc > 0, sc, 1.0)
    bricks.N[:, :, :, :, 1:, :] = np.round(bricks.N[:, :, :, :, 1:, :] / sc * 127) / 127 * sc
    bricks.N[:, :, :, :, :1, :] = bricks.N[:, :, :, :, :1, :].astype(np.float16)
    q, _, _ = bricks.sample(u, "exact", np.float64)
    bricks.N = keepN
    ok = np.isfinite(ref).all(axis=(1, 2)) & np.isfinite(q).all(axis=(1, 2))
    return {"bytes_per_texel": 32, "rms_rel": stats(irr_rel_error(q[ok], ref[ok], normals(64, rng), field.band))}


def fp16_irradiance(field: Field, bricks: Bricks, n: int, rng) -> dict:
    """Relative irradiance error of fp16 texels alone (exact weights), against fp32 texels, over 64
    random normals per point; and per normal (max over normals of |dE| / |E| where |E| is above 1 % of
    the point's largest)."""
    u, _ = field.random_inside(n, rng)
    s32, _, _ = bricks.sample(u, "exact", np.float32)
    s16, _, _ = bricks.sample(u, "exact", np.float16)
    ok = np.isfinite(s32).all(axis=(1, 2)) & np.isfinite(s16).all(axis=(1, 2))
    dirs = normals(64, rng)
    e32 = irradiance(s32[ok], dirs, field.band)
    e16 = irradiance(s16[ok], dirs, field.band)
    mag = np.abs(e32)
    rel = np.abs(e16 - e32) / np.maximum(mag, 1e-30)
    sig = mag > 0.01 * mag.max(axis=(1, 2), keepdims=True)
    return {"rms_rel": stats(irr_rel_error(s16[ok], s32[ok], dirs, field.band)),
            "per_normal_rel_max": float(rel[sig].max()), "per_normal_rel_p99": float(np.percentile(rel[sig], 99))}


# ---------------------------------------------------------------------------------------------------
# Back faces and visibility: today's shader rule (octree_irradiance, transcribed) and brick-cell rules
# ---------------------------------------------------------------------------------------------------

def smoothstep(e0, e1, x):
    t = np.clip((x - e0) / (e1 - e0), 0.0, 1.0)
    return t * t * (3 - 2 * t)


CORNER_BITS = np.array([[k & 1, (k >> 1) & 1, (k >> 2) & 1] for k in range(8)], dtype=np.float64)


def pair_vis_value(q: np.ndarray) -> np.ndarray:
    """pb_vis_pair_value(): V(k, c) from the stored byte."""
    q = q.astype(np.float64)
    return np.where(q >= 255, 1.0, 1.0 - 127.5 / np.maximum(q, 1.0))


def plane_pair_bytes(corners: np.ndarray, plane) -> np.ndarray:
    """The visibility table of boxes (n, 8, 3) against a plane (normal, d): [n, k, c] = round(255 t),
    t the fraction of the way from corner c towards corner k where the segment crosses the plane."""
    nrm, d = plane
    s = corners @ nrm - d                      # (n, 8)
    sc, sk = s[:, None, :], s[:, :, None]      # [n, k, c]
    cross = sc * sk < 0
    with np.errstate(invalid="ignore", divide="ignore"):
        t = np.where(cross, sc / (sc - sk), 1.0)
    q = np.clip(np.round(255 * t), 1, 255).astype(np.uint8)
    q[:, np.arange(8), np.arange(8)] = 255
    return q


def weighted_rule(w8, corner_pos, p, n, cell_size, vis_bytes, movable):
    """The anti-leak weights of shading.glsl octree_irradiance over one cell's 8 corners: back face
    (static only) times the visibility ramp; returns (pass-0 weights, plain weights)."""
    wb = w8.copy()
    if not movable:
        d = np.einsum("nka,na->nk", (corner_pos - p[:, None, :]) / cell_size[:, None, :], n)
        wb = wb * smoothstep(-0.1, 0.1, d)
    wbsum = wb.sum(axis=1)
    w = wb.copy()
    if vis_bytes is not None:
        V = pair_vis_value(vis_bytes)                                   # [n, k, c]
        with np.errstate(invalid="ignore", divide="ignore"):
            v = np.einsum("nk,nkc->nc", wb, V) / wbsum[:, None]
        w = w * smoothstep(0.5, 0.5 + VIS_RAMP, np.nan_to_num(v))
    return w, w8


def finish(w, w8, vals, mass):
    """sum w m V / sum w m over the corners, with the shader's fallback to the plain weights."""
    e = np.einsum("nk,nkcd->ncd", w, vals)
    s = np.einsum("nk,nk->n", w, mass)
    e8 = np.einsum("nk,nkcd->ncd", w8, vals)
    s8 = np.einsum("nk,nk->n", w8, mass)
    with np.errstate(invalid="ignore", divide="ignore"):
        out = np.where((s > 0)[:, None, None], e / s[:, None, None], e8 / s8[:, None, None])
    return out


def today_rule(field: Field, u, n, plane=None, movable=False):
    """shading.glsl octree_irradiance on the CPU: leaf of u, trilinear corner weights, back face,
    visibility field (plane occluder), validity mass of the resolved nodes, renormalised."""
    li = field.leaf_of(u)
    keep = li >= 0
    li = np.where(keep, li, 0)
    s = (1 << field.levels[li]).astype(np.float64)
    lo = field.lo[li].astype(np.float64)
    t = np.clip((u - lo) / s, 0, 1)
    w8 = np.ones((len(u), 8))
    for a in range(3):
        w8 *= np.where(CORNER_BITS[None, :, a] == 1, t[:, None, a], 1 - t[:, None, a])
    cpos = lo[:, None, :] + CORNER_BITS[None] * s[:, None, :]
    vb = None if plane is None else plane_pair_bytes(cpos, plane)
    w, w8 = weighted_rule(w8, cpos, u, n, s, vb, movable)
    nodes = field.corners[li]
    out = finish(w, w8, field.node_A[nodes] * 1.0, field.node_a[nodes])
    # node_A holds a V (premultiplied by the mass): sum w A / sum w a is the shader's sum w a V / sum w a
    out[~keep] = np.nan
    return out


SEPARABLE_EPS = 1e-5  # PB_BRICKS_SEPARABLE_EPS (pb_bricks.h)


def separable(w):
    """pb_bricks_separable over rows of 8 nonnegative corner weights: (mask (n,): sum > 0 and w_k (sum w)^2
    = prod_a M_a(bit_a(k)) within SEPARABLE_EPS relative for every k, M_a(b) the weight on bit_a = b;
    f' (n, 3): M_a(1) / sum w)."""
    sw = w.sum(axis=1)
    M1 = w @ CORNER_BITS
    M0 = w @ (1 - CORNER_BITS)
    pos = sw > 0
    f = M1 / np.where(pos, sw, 1)[:, None]
    lhs = w * (sw * sw)[:, None]
    rhs = np.ones_like(w)
    for a in range(3):
        rhs *= np.where(CORNER_BITS[None, :, a] == 1, M1[:, None, a], M0[:, None, a])
    ok = np.abs(lhs - rhs) <= SEPARABLE_EPS * np.maximum(lhs, rhs)
    return pos & ok.all(axis=1), f


def brick_rule(bricks: Bricks, u, n, plane=None, movable=False, taps: str = "8", dtype=np.float64,
               return_separable=False):
    """The proposal's rule: the same weights on the brick cell holding u (its 8 texels, cell size 2^L),
    N / D; taps "8" = 8 weighted fetches (exact), "1" = one filtered fetch at the fraction that carries
    the weights' per-axis means (APV's offset), 8-bit quantised; "sep" = step 5e of pb_bricks_sample_surface:
    "1" where the weights are separable (or all zero), else "8". return_separable: also the mask (n,)."""
    b, u = bricks.lookup(u)
    out = np.full((len(u), bricks.field.C, 3), np.nan)
    sep_out = np.zeros(len(u), bool)
    ok = b >= 0
    u, n, b = u[ok], n[ok], b[ok]
    x = bricks.local(u, b)
    idx, w8 = bricks.cell_weights(x, b, "exact")
    L = (1 << bricks.level[b]).astype(np.float64)
    cpos = bricks.rmin[b][:, None, :] + idx * L[:, None, None]
    s = np.repeat(L[:, None], 3, axis=1)
    vb = None if plane is None else plane_pair_bytes(cpos, plane)
    w, w8 = weighted_rule(w8, cpos, u, n, s, vb, movable)
    N, D = bricks.fetch(b, idx, dtype)
    sep = separable(w)[0]
    sep_out[ok] = sep
    if taps in ("1", "sep"):
        # Fold the weights into one fraction per axis; where they vanish, the plain fraction.
        sw = w.sum(axis=1)
        fw = np.where(sw[:, None] > 0, (w @ CORNER_BITS) / np.where(sw > 0, sw, 1)[:, None],
                      (w8 @ CORNER_BITS))
        fw = np.round(fw * 256) / 256
        w1 = np.ones_like(w)
        for a in range(3):
            w1 *= np.where(CORNER_BITS[None, :, a] == 1, fw[:, None, a], 1 - fw[:, None, a])
        e = np.einsum("nk,nkcd->ncd", w1, N)
        d = np.einsum("nk,nk->n", w1, D)
        with np.errstate(invalid="ignore", divide="ignore"):
            r = e / d[:, None, None]
        bad = ~(d > 0)
        if bad.any():
            r[bad] = finish(w8[bad], w8[bad], N[bad], D[bad])
        if taps == "sep":
            eight = ~sep & (sw > 0)
            r[eight] = finish(w[eight], w8[eight], N[eight], D[eight])
        out[ok] = r
    else:
        out[ok] = finish(w, w8, N, D)
    return (out, sep_out) if return_separable else out


def wall_experiment(seed: int, n: int, B: int, refine_wall: bool = False) -> dict:
    """A plane wall x = 5.4 min cells (through leaves of every size): probes on its lower side hold a
    uniform radiance 5, on its upper side 0.05 (test_engine's wall rooms). Irradiance at points up to 2
    min cells on the dark side (normal +x: the wall's dark face; +y: a floor beside the wall), relative
    to the dark value (1 = no leak), for: the file's plain field, today's shader rule (back face +
    visibility field), bricks with the same rule on the brick cell (8 taps, 1 tap), texels resampled
    plainly or with the visibility field (the C query's pair_visibility)."""
    rng = np.random.default_rng(seed)
    tree = synthetic_tree(seed, passes=2)
    h = 0.25
    wall_x = 5.4
    while refine_wall:  # every leaf the wall crosses split down to Min Cell Size (as near geometry)
        info = tree.info()
        lo, lv = info["leaves"][:, 0].astype(np.int64), info["levels"][:, 0].astype(np.int64)
        flags = (lo < wall_x) & (lo + (1 << lv) > wall_x) & (lv > 0)
        if not flags.any():
            break
        tree.split(flags)
        tree.finalize()
    pos = tree.positions()
    bright = pos[:, 0] / h < wall_x
    c = np.zeros((len(pos), 9, 3))
    l00 = np.sqrt(4 * np.pi)  # uniform radiance L: L_00 = L * Y0 * 4 pi = L sqrt(4 pi)
    c[:, 0, :] = np.where(bright, 5.0, 0.05)[:, None] * l00
    with tempfile.TemporaryDirectory() as tmp:
        field = write_tree(tree, os.path.join(tmp, "wall.shprobe"), c)
        plane = (np.array([1.0, 0.0, 0.0]), wall_x)
        cpos = field.lo[:, None, :] + CORNER_BITS[None] * (1 << field.levels)[:, None, :]
        pv = plane_pair_bytes(cpos.astype(np.float64), plane)
        plain = Bricks(field, B)
        visb = Bricks(field, B, pair_visibility=pv)
        u = np.column_stack([wall_x + 1e-3 + 2 * rng.random(n), rng.random(n) * field.dims[1],
                             rng.random(n) * field.dims[2]])
        e_dark = 0.05 * np.pi
        cut = (field.lo[:, 0] < wall_x) & (field.lo[:, 0] + (1 << field.levels[:, 0]) > wall_x)
        # Visibility records: today one per leaf (64 B each, all leaves); bricks one per brick cell the
        # wall crosses (64 B each, blocked cells only).
        L = 1 << plain.level
        ncell = 0
        for bi in range(len(L)):
            xs = plain.rmin[bi, 0] + L[bi] * np.arange(B - 1)
            ncell += int(((xs < wall_x) & (xs + L[bi] > wall_x)).sum()) * (B - 1) ** 2
        res = {"points": n, "leaf_levels_cut_by_wall": sorted(set(int(v) for v in field.levels[cut].min(axis=1))),
               "leaves": len(field.lo), "leaves_cut": int(cut.sum()), "brick_cells_cut": ncell,
               "wall_area_min_cells": int(field.dims[1] * field.dims[2])}
        for name, nv in (("wall face (n = +x)", np.array([1.0, 0, 0])), ("floor (n = +y)", np.array([0, 1.0, 0]))):
            nn = np.repeat(nv[None], n, axis=0)

            def leak(sh):
                e = irradiance(sh, nv[None], 2)[:, 0, 0]
                return stats(e / e_dark)
            row = {"file plain": leak(field.interpolate(u)),
                   "file + visibility (CPU query)": leak(field.interpolate(u, pv)),
                   "today's shader rule": leak(today_rule(field, u, nn, plane)),
                   "bricks plain": leak(plain.sample(u)[0]),
                   "bricks 8 taps, plain texels": leak(brick_rule(plain, u, nn, plane)),
                   "bricks 8 taps, visibility texels": leak(brick_rule(visb, u, nn, plane)),
                   "bricks 1 tap, visibility texels": leak(brick_rule(visb, u, nn, plane, taps="1"))}
            res[name] = row
        # The bright side: light kept (1 = all of it).
        ub = u.copy()
        ub[:, 0] = wall_x - 1e-3 - 2 * rng.random(n)
        nb = np.repeat(np.array([[-1.0, 0, 0]]), n, axis=0)
        e_b = 5.0 * np.pi

        def kept(sh):
            return stats(irradiance(sh, np.array([[-1.0, 0, 0]]), 2)[:, 0, 0] / e_b)
        res["bright wall face (n = -x), fraction kept"] = {
            "today's shader rule": kept(today_rule(field, ub, nb, plane)),
            "bricks 8 taps, visibility texels": kept(brick_rule(visb, ub, nb, plane)),
            "bricks 1 tap, visibility texels": kept(brick_rule(visb, ub, nb, plane, taps="1"))}
    return res


def backface_experiment(field: Field, bricks: Bricks, n: int, rng) -> dict:
    """No occluder: the back-face weight alone (static surfaces), random points and normals. Relative
    irradiance difference of the brick-cell rule (8 taps / 1 tap) to today's rule, and of today's rule
    to the plain field (the size of the effect itself)."""
    u, _ = field.random_inside(n, rng)
    nn = normals(n, rng)
    today = today_rule(field, u, nn)
    plain = field.interpolate(u)
    out = {}
    for name, val in (("brick cell 8 taps", brick_rule(bricks, u, nn)),
                      ("brick cell 1 tap", brick_rule(bricks, u, nn, taps="1")),
                      ("plain field (no back-face weight)", plain)):
        e_t = np.einsum("nc,ncd->nd", native.sh_basis(nn, field.band)[:, :field.C] * A_BAND[:field.C], today)
        e_v = np.einsum("nc,ncd->nd", native.sh_basis(nn, field.band)[:, :field.C] * A_BAND[:field.C], val)
        rel = np.abs(e_v - e_t).max(axis=1) / np.maximum(np.abs(e_t).max(axis=1), 1e-30)
        out[name] = stats(rel)
    b1, b8 = brick_rule(bricks, u, nn, taps="1"), brick_rule(bricks, u, nn)
    e1 = np.einsum("nc,ncd->nd", native.sh_basis(nn, field.band)[:, :field.C] * A_BAND[:field.C], b1)
    e8 = np.einsum("nc,ncd->nd", native.sh_basis(nn, field.band)[:, :field.C] * A_BAND[:field.C], b8)
    out["1 tap vs 8 taps"] = stats(np.abs(e1 - e8).max(axis=1) / np.maximum(np.abs(e8).max(axis=1), 1e-30))
    # Where the leaf is the brick cell (min-cell leaves at level-0 bricks) the rules coincide.
    li = field.leaf_of(u)
    same = (field.levels[li].max(axis=1) == bricks.level[bricks.lookup(u)[0]])
    b8 = brick_rule(bricks, u[same], nn[same])
    out["points where leaf = brick cell"] = int(same.sum())
    out["brick 8 taps vs today there, coeff max"] = float(np.nanmax(np.abs(b8 - today[same])) /
                                                           np.nanmax(np.abs(today))) if same.any() else None
    return out


# ---------------------------------------------------------------------------------------------------
# Dense grids (v1 / v2): one texture, texel centres = cell centres
# ---------------------------------------------------------------------------------------------------

def dense_grid_check(path: str, n: int, rng) -> dict:
    """grid_irradiance's trilinear part (8 cells around c = u - 1/2, indices clamped, empty cells
    skipped, validity multiplied, renormalised) against a 3D texture of N = v c, D = v (v = validity,
    0 for empty) filtered with clamp-to-edge: the same field, no bricks needed."""
    f = native.read_shprobe(path)
    dims = np.array(f.grid_dims)
    grid = f.grid.reshape(dims[2], dims[1], dims[0]).transpose(2, 1, 0)  # [x, y, z]
    v = np.where(grid >= 0, f.validity[np.maximum(grid, 0)], 0.0).astype(np.float64)
    vals = f.coeffs.astype(np.float64) * f.probe_scale[:, None, None]
    Ntex = v[..., None, None] * vals[np.maximum(grid, 0)]
    u = rng.random((n, 3)) * dims
    c = u - 0.5
    i0 = np.floor(c).astype(np.int64)
    fr = c - i0
    e = np.zeros((n, vals.shape[1], 3))
    s = np.zeros(n)
    for k in range(8):
        o = CORNER_BITS[k].astype(np.int64)
        ci = np.clip(i0 + o, 0, dims - 1)
        w = np.prod(np.where(o == 1, fr, 1 - fr), axis=1)
        e += w[:, None, None] * Ntex[ci[:, 0], ci[:, 1], ci[:, 2]]
        s += w * v[ci[:, 0], ci[:, 1], ci[:, 2]]
    ref = e / s[:, None, None]
    # Hardware: texel coordinate u (texel centres at cell centres), clamp-to-edge, fp16 texels, 8-bit.
    out = {"path": path, "probes": f.probe_count, "dims": [int(d) for d in dims]}
    for bits in (None, SUBTEXEL_BITS):
        for dt in (np.float32, np.float16):
            fr_q = fr if bits is None else np.round(fr * 256) / 256
            e2 = np.zeros_like(e)
            s2 = np.zeros(n)
            for k in range(8):
                o = CORNER_BITS[k].astype(np.int64)
                ci = np.clip(i0 + o, 0, dims - 1)
                w = np.prod(np.where(o == 1, fr_q, 1 - fr_q), axis=1)
                e2 += w[:, None, None] * Ntex[ci[:, 0], ci[:, 1], ci[:, 2]].astype(dt)
                s2 += w * v[ci[:, 0], ci[:, 1], ci[:, 2]].astype(dt)
            r = e2 / s2[:, None, None]
            key = ("exact" if bits is None else "hw") + "-" + np.dtype(dt).name
            out[key] = float(np.nanmax(np.abs(r - ref)) / np.nanmax(np.abs(ref)))
    texels = int(np.prod(dims))
    out["bytes_per_probe_fp16"] = texels * CHANNELS_PER_TEXEL[f.max_band] * 2 / f.probe_count
    return out


# ---------------------------------------------------------------------------------------------------
# Driver
# ---------------------------------------------------------------------------------------------------

def run_field(field: Field, n: int, rng, Bs=(5,), closed_form=None, validity=True) -> dict:
    H = int(len(field.node_a) - field.P)
    out = {"probes": field.P, "leaves": len(field.lo), "band": field.band, "hanging": H,
           "root_level": field.root_level, "lattice": [int(d) for d in field.dims],
           "leaf_levels": {int(k): int(v) for k, v in zip(*np.unique(field.levels.max(axis=1), return_counts=True))},
           # Today's storage buffers (sv_gpu.h): 416 B (float) / 208 B (half) per entry, probes then hanging
           # nodes, plus 64 B of leaf record and 64 B of visibility table per leaf.
           "today_bytes_per_probe": {"float": ((field.P + H) * 416 + len(field.lo) * 128) / field.P,
                                     "half": ((field.P + H) * 208 + len(field.lo) * 128) / field.P}}
    for B in Bs:
        br = Bricks(field, B)
        r = {"storage_fp16": br.storage(True), "storage_fp32_bytes_per_probe": br.storage(False)["bytes_per_probe"],
             "texels_per_probe_dilated": Bricks(field, B, dilate=True).storage()["texels_per_probe"]}
        if B == Bs[0]:
            r["outer_faces"] = outer_faces(field, br, n // 2, rng)
            r["exactness"] = exactness(field, br, n, rng, closed_form)
            if closed_form is not None:
                r["hw_linear_bound"] = hw_linear_bound(br)
            r["seams"] = seams(br, n // 2, rng)
            if validity and (field.valid == 0).any():
                r["validity"] = validity_check(field, br, n, rng)
            r["fp16_irradiance"] = fp16_irradiance(field, br, n // 2, rng)
            r["snorm8_l1l2_option"] = snorm8_irradiance(field, br, n // 2, rng)
        out[f"B={B}"] = r
    return out


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--quick", action="store_true")
    ap.add_argument("--seed", type=int, default=1)
    args = ap.parse_args(argv)
    n = 1000 if args.quick else 16000
    rng = np.random.default_rng(args.seed)
    t0, c0 = time.time(), time.process_time()
    summary = {"subtexel_bits": SUBTEXEL_BITS, "points": n}
    Bs = (5, 4, 3, 9, 2)
    with tempfile.TemporaryDirectory() as tmp:
        syn = {}
        for kd in (False, True):
            for seed in range(1 if args.quick else 2):
                tree = synthetic_tree(100 + seed, kd=kd)
                pos = tree.positions()
                tag = f"{'kd' if kd else 'octree'} seed {100 + seed}"
                fl = write_tree(tree, os.path.join(tmp, "lin.shprobe"), linear_sh(pos))
                syn[f"linear, {tag}"] = run_field(fl, n, rng, Bs=Bs if seed == 0 else (5,), closed_form=linear_sh)
                valid = (rng.random(len(pos)) > 0.15).astype(np.float32)
                fr = write_tree(tree, os.path.join(tmp, "rnd.shprobe"), random_sh(len(pos), 2, rng), valid)
                syn[f"random SH, 15 % invalid, {tag}"] = run_field(fr, n, rng)
        summary["synthetic"] = syn
        tree = synthetic_tree(7)
        fr = write_tree(tree, os.path.join(tmp, "bf.shprobe"), random_sh(tree.probe_count, 2, rng))
        summary["back_faces"] = backface_experiment(fr, Bricks(fr, 5), n, rng)
    summary["wall"] = {f"B={B}": wall_experiment(3, n // 2, B) for B in (5, 4)}
    summary["wall, leaves at the wall refined to min cell"] = {"B=5": wall_experiment(3, n // 2, 5, True)}
    real = {}
    paths = [p for p in REAL_FILES if os.path.exists(p)]
    for g in REAL_GLOBS:
        paths += sorted(glob.glob(g))[:1]
    for p in paths:
        try:
            fld = Field(p)
        except (ValueError, native.SchneeError) as e:
            real[p] = {"skipped": str(e)}
            continue
        real[p] = run_field(fld, n, rng, Bs=Bs)
    summary["real_files"] = real
    dense = "/tmp/bakeA_after3/adaptive_v1/sh_coeffs/probes.shprobe"
    if os.path.exists(dense):
        summary["dense_grid"] = dense_grid_check(dense, n, rng)
    summary["cpu_s"] = round(time.process_time() - c0, 1)
    summary["wall_s"] = round(time.time() - t0, 1)
    print(json.dumps(summary, indent=1))
    return 0


if __name__ == "__main__":
    sys.exit(main())
