"""Adaptive placement: the pass-by-pass refinement of a corner octree driven by the light's own error.

Plain Python + the native core (no ``bpy``): :class:`bake_core.ProbeBake` renders, this module
decides where. The algorithm is docs/placement.md, "Error-driven refinement"; the bake loop:

1. a layer of Max Cell Size leaves over the volumes' bounding box, leaves outside the volumes
   dropped; its corner probes are baked;
2. every leaf above Min Cell Size gets its test points (its centre; with Refinement Tests "Centre
   and faces" also its face centres); those that are not probes yet are baked (a point is baked
   once: :class:`PointCache` keys it by position);
3. ``refine_decide`` compares each test's value with the leaf's interpolation there, allowing
   ``sqrt(tolerance² + (2σ)²)`` with σ the Monte-Carlo noise of the probes and tests involved; flagged leaves
   split; children entirely outside the volumes are dropped; the new corners (test points: already
   baked, edge midpoints: new) are baked; back to 2 until nothing splits or every leaf is at Min Cell
   Size. Children predicted to pass (Policy.predict: their parent's error next to them, over the rate the
   error was measured falling per halving; no rate where the noise sets the threshold,
   Policy.predict_noise) are never tested (docs/placement.md, step 4a).

Points inside solid geometry (the placement's solid test: more than ``Policy.solid_ratio`` of 64 rays hit
back faces) are never rendered: as probes they get validity 0 (left out of the interpolation), as
tests they are not compared.

Samples where a decision needs them (docs/placement.md, step 3): a point is rendered in rounds with
independent seeds, combined by :class:`PointCache` (sample-weighted mean, σ from the pooled variance
of the rounds). Every new point first gets two rounds of ``Policy.first_round`` × Samples each (its
noise is measured, not assumed); a probe then gets one more round up to the samples its measured σ
needs to fall to ``Policy.probe_noise`` × Error Tolerance, a test one more round only where its leaf's decision is
not clear given its noise. At most ``Policy.max_samples`` × Samples per point.
"""
from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Callable, List, Optional, Tuple

import numpy as np

from . import bakeinfo, native, refine_axes
from .metric import _rel, irradiance_error, irradiance_norm  # noqa: F401 (re-exported)

TEST_MODES = ("CENTRE_FACES", "CENTRE")   # Refinement Tests: a leaf's centre + 6 face centres, or its centre
# The sampling scheme's name in the journal's fingerprint (journal.py): a journal of another scheme
# holds records of other sample counts and is not resumed.
SAMPLING = "rounds-1"


@dataclass(frozen=True)
class Policy:
    """The refinement's tuning knobs, measured in bench/results/placement.md. The defaults are
    the add-on's; the bake passes one to :class:`AdaptiveGroup` and :class:`PointCache`
    (``ProbeBake(policy=...)``), benchmarks compare others (``dataclasses.replace(DEFAULT_POLICY,
    predict=2.0)``; bench/bench_placement.py --predict, --retest)."""
    solid_ratio: float = 0.25   # the placement's default back-face ratio (docs/placement.md)
    render_inset: float = 0.01  # m: nodes on or beyond the volumes' bounding box render this far inside it
    # A node inside solid geometry (on a furniture face or edge, where the solid test is a coin toss,
    # or just inside it) renders at the nearest free point within this reach (at most a quarter of
    # Min Cell Size) instead of being left out (docs/placement.md, step 2).
    relocate: float = 0.05
    noise_k: float = 2.0        # refine only where error > sqrt(tolerance² + (noise_k · noise)²) (pb_refine's default)
    # Prediction of children that pass (saves their tests): a leaf's error falls by a measured rate
    # per halving — the ratio of its parent's error next to it to its own worst error, both over
    # their thresholds — and a smooth field's trilinear error falls as h², 4× per halving (exactly 4
    # for a quadratic field), so the rate is capped at ``predict``. A child whose predicted error
    # (its parent's error next to it over that rate) is below 1 is not tested. Rates must have been
    # measured at two consecutive levels (the leaf's and its parent's halving): until then, and
    # where the error did not fall, a child passes untested only where its parent passed next to it
    # (at coarse scales the light is far from the h² regime). 0 = every child tested.
    predict: float = 4.0
    # A rate is measured only where the leaf's threshold is at most predict_noise × Error Tolerance:
    # above it the probes' noise dominates the threshold (2σ > 1.12 × tolerance), the measured
    # errors are mostly noise and their fall says nothing about h² convergence (in the hall at 16
    # spp, σ ≈ 2 %, such rates settled children 3–5 % off). There a child passes untested only where
    # its parent passed next to it, as before a rate is known.
    predict_noise: float = 1.5
    # Progressive samples (docs/placement.md step 3). A new point is rendered as two rounds of
    # first_round × Samples (at least 1 sample each; seeds Seed and Seed + 1): the sample-weighted
    # mean and σ from their difference. A probe whose σ (relative, as a moving object sees it) is
    # above probe_noise × Error Tolerance gets one more round (seed Seed + round) of the samples its
    # σ says it needs, N·(σ / target)², at most max_samples × Samples in all. A test point erring
    # within decide_z · σ of its leaf's threshold (the decision is not clear given its own noise)
    # gets one more round of the samples that make it clear, N·(decide_z · σ / |err − thr|)², and
    # the pass is decided again. Measured in the bundled room at the defaults (bench/results/
    # placement.md "Samples where a decision needs them"): probe_noise 1/3 with max_samples 2 gave
    # 1.65 % at the points for 1.57x the samples of the two half renders before (most points went
    # to 16 samples: two rounds of 2 samples overstate sigma often); 1/2 with max_samples 1 (no
    # point above Samples) 1.77 % for 0.78x (before: 1.87 %). A probe's noise enters the error at a
    # point between probes through the trilinear weights, sqrt(E Σw²) ≈ 0.55 of it, in quadrature.
    first_round: float = 0.25
    probe_noise: float = 0.5
    decide_z: float = 1.0
    max_samples: float = 1.0
    # The direct-light check of a leaf (AdaptiveGroup.direct_check) samples the lamps' exact direct
    # term on this many steps per axis of the leaf (5³ − 8 points; fewer where that is finer than
    # Min Cell).
    direct_divisions: int = 4
    # Per-axis refinement (docs/aniso-refinement.md): a leaf is a box with a level per axis and splits
    # only along the axes its tests disagree on (12 edge midpoints + the middle point; the direct
    # check the same way). Off by default, measured in Cycles at the add-on's defaults
    # (bench/results/placement.md "Per-axis refinement"): fewer probes (room 1368 vs 1646, courtyard
    # 528 vs 916) but more renders (2975 vs 2400, 1750 vs 1481: the slabs' long axes keep being
    # tested) and a larger error at the points (1.97 vs 1.77 %, 1.51 vs 1.04 %). True: bench and
    # tests (bench_placement.py --axes on); Refinement Tests "Centre" always uses the octree.
    axes: bool = False


DEFAULT_POLICY = Policy()
# A sun in the sky image (its light is in the panoramas, not a lamp's exact term) is checked like a
# lamp (AdaptiveGroup.direct_check, docs/placement.md step 4b) through a stand-in Sun lamp: sky_sun,
# the C split of native.sky_sun_split (its criteria: docs/direct-light.md "The sky's sun").
# Relocation directions: the 6 axes first, then the 12 edge and 8 corner diagonals (unit vectors).
_RELOCATE_DIRS = np.array(sorted(((i, j, k) for i in (-1, 0, 1) for j in (-1, 0, 1) for k in (-1, 0, 1)
                                  if (i, j, k) != (0, 0, 0)), key=lambda d: sum(map(abs, d))), dtype=np.float64)
_RELOCATE_DIRS /= np.linalg.norm(_RELOCATE_DIRS, axis=1)[:, None]


def combine_halves(a: np.ndarray, b: np.ndarray, s1: int, s2: int):
    """(value, relative noise) of a point rendered twice with independent seeds: the sample-weighted
    mean, and σ of that mean estimated from the difference (for equal halves σ_mean = ‖d‖/2; in
    general Var(mean) = Var(d) · s1·s2/(s1+s2)²)."""
    a = np.asarray(a, dtype=np.float64)
    b = np.asarray(b, dtype=np.float64)
    mean = (s1 * a + s2 * b) / (s1 + s2)
    scale = math.sqrt(s1 * s2) / (s1 + s2)
    noise = _rel(a - b, mean) * scale
    return mean, noise


def round_samples(samples: int, policy: "Policy") -> Tuple[int, int]:
    """(samples of each of a point's two first rounds, the most samples of a point in all) for the
    bake's Samples: at 8, (2, 16)."""
    first = max(1, int(round(samples * policy.first_round)))
    return first, max(2 * first, int(round(samples * policy.max_samples)))


def add_round(mean: np.ndarray, n: float, m2: float, value: np.ndarray, k: float):
    """Welford's update of a point's rounds by one more round ``value`` of ``k`` samples: (mean, n,
    m2) with m2 = Σ n_j ‖A·(c_j − mean)‖² over the rounds j (A: the Lambert band factors), so
    σ² of the mean = m2 / ((rounds − 1) · n) (:func:`round_noise`)."""
    mean = np.asarray(mean, dtype=np.float64)
    delta = np.asarray(value, dtype=np.float64) - mean
    total = n + k
    m2 = m2 + float(irradiance_norm(delta)) ** 2 * n * k / total
    return mean + delta * (k / total), total, m2


def round_noise(mean: np.ndarray, n: float, m2: float, rounds: int) -> float:
    """Relative σ of the mean of ``rounds`` rounds (pooled per-sample variance m2 / (rounds − 1))."""
    den = float(irradiance_norm(np.asarray(mean, dtype=np.float64)))
    if rounds < 2 or n <= 0 or den <= 0:
        return 0.0
    return math.sqrt(max(m2, 0.0) / ((rounds - 1) * n)) / den


def unclear_tests(leaf_tests, above_min, ok, err_t, noise, thr, direct, z: float) -> np.ndarray:
    """(T,) float: for the test points (``ok``: compared, not probes) erring within z·σ of their
    leaf's threshold ``thr``, in leaves above Min Cell Size (``above_min``) that no test of theirs
    splits clearly (by more than z·σ above it) and that the lamps' direct light does not split,
    their distance |error − threshold| from it; inf for the others (clear)."""
    gap = np.full(len(err_t), np.inf)
    for i in np.flatnonzero(~np.asarray(direct, dtype=bool) & np.asarray(above_min, dtype=bool)):
        cols = leaf_tests[i]
        cols = cols[cols >= 0]
        cols = cols[ok[cols]]
        if len(cols) == 0 or np.any(err_t[cols] - z * noise[cols] > thr[i]):
            continue        # nothing to compare, or clearly split
        d = np.abs(err_t[cols] - thr[i])
        near = d < z * noise[cols]
        gap[cols[near]] = np.minimum(gap[cols[near]], d[near])
    return gap


def leaf_levels(info: dict) -> np.ndarray:
    """(L, 3) per-axis levels of a tree's leaves (``CornerOctree.info()``)."""
    levels = info.get("levels")
    if levels is None:
        return np.repeat(np.asarray(info["leaves"])[:, 3:4], 3, axis=1)
    return np.asarray(levels).reshape(-1, 3)


def leaf_keys(info: dict) -> List[tuple]:
    """A leaf's key: (x, y, z, lx, ly, lz)."""
    leaves, levels = np.asarray(info["leaves"]), leaf_levels(info)
    return [tuple(int(v) for v in leaves[i, :3]) + tuple(int(v) for v in levels[i]) for i in range(len(leaves))]


def child_keys(key: tuple, mask: int) -> List[tuple]:
    """The children of leaf ``key`` split along the axes of ``mask`` (axes at level 0 stay)."""
    axes = [a for a in range(3) if mask >> a & 1 and key[3 + a] > 0]
    out = []
    for bits in range(1 << len(axes)):
        k = list(key)
        for j, a in enumerate(axes):
            k[3 + a] = key[3 + a] - 1
            k[a] = key[a] + ((bits >> j) & 1) * (1 << k[3 + a])
        out.append(tuple(k))
    return out


def direct_points(leaves: np.ndarray, levels: np.ndarray, divisions: int):
    """The direct check's lattice points of each leaf above Min Cell Size: ``divisions`` steps per axis
    (fewer where finer than a min cell), the corners left out. Returns (lattice (M, 3), leaf (M,),
    edge axis (M,): the axis of the leaf edge a point lies inside, −1 for a point off the edges)."""
    lat, leaf_of, edge = [], [], []
    levels = np.asarray(levels, dtype=np.int64).reshape(-1, 3)
    for lv in np.unique(levels, axis=0):
        sel = np.flatnonzero((levels == lv).all(axis=1))
        if not lv.any() or len(sel) == 0:
            continue
        div = [min(1 << int(v), divisions) for v in lv]
        grid = np.stack(np.meshgrid(*[np.arange(d + 1) for d in div], indexing="ij"), axis=-1).reshape(-1, 3)
        at_end = (grid == 0) | (grid == np.array(div))
        keep = ~at_end.all(axis=1)
        grid, at_end = grid[keep], at_end[keep]
        axis = np.where(at_end.sum(axis=1) == 2, np.argmin(at_end, axis=1), -1)
        step = np.array([(1 << int(v)) // d for v, d in zip(lv, div)], dtype=np.int64)
        lat.append((leaves[sel, None, :3].astype(np.int64) + grid[None] * step).reshape(-1, 3))
        leaf_of.append(np.repeat(sel, len(grid)))
        edge.append(np.tile(axis, len(sel)))
    if not lat:
        return np.zeros((0, 3), np.int64), np.zeros(0, np.int64), np.zeros(0, np.int64)
    return np.concatenate(lat), np.concatenate(leaf_of), np.concatenate(edge)


def split_masks(leaf_count: int, levels: np.ndarray, leaf_of: np.ndarray, edge: np.ndarray, fail: np.ndarray,
                axes: bool) -> np.ndarray:
    """(L,) uint8 axis masks from failing points (the per-axis split rule of docs/aniso-refinement.md:
    a failing point inside an edge along a splits along a; a failing point off the edges splits along
    every axis above level 0 only when no edge point of the leaf failed). ``axes`` False: every axis
    where anything failed (the octree)."""
    out = np.zeros(leaf_count, dtype=np.uint8)
    splittable = (np.asarray(levels).reshape(-1, 3) > 0) @ np.array([1, 2, 4])
    fail = np.asarray(fail, dtype=bool)
    if not axes:
        out[np.unique(leaf_of[fail])] = 7
        return (out & splittable).astype(np.uint8)
    on_edge = fail & (edge >= 0)
    np.bitwise_or.at(out, leaf_of[on_edge], (1 << edge[on_edge]).astype(np.uint8))
    middle = np.unique(leaf_of[fail & (edge < 0)])
    middle = middle[out[middle] == 0]
    out[middle] = splittable[middle]
    return (out & splittable).astype(np.uint8)


def outside_boxes(origin, min_cell: float, volumes, geometry, leaves: np.ndarray, levels: np.ndarray,
                  max_cell: Optional[float] = None) -> np.ndarray:
    """(L,) bool: the leaf boxes outside the volumes: class 0 (``classify_placement``) for each of the
    cubes of the box's smallest side that tile it (at most 8 per axis: beyond that, the cubes
    around 8 × 8 × 8 sub-boxes, which may keep a box just outside). ``max_cell``: the bake's Max
    Cell Size (default ``min_cell``); see :meth:`AdaptiveGroup.classify_points`."""
    levels = np.asarray(levels, dtype=np.int64).reshape(-1, 3)
    side = levels.min(axis=1, keepdims=True)
    split = np.minimum(levels - side, 3)          # cubes per axis 2^split (≤ 8)
    centres, halves, owner = [], [], []
    for lv in np.unique(levels, axis=0):
        sel = np.flatnonzero((levels == lv).all(axis=1))
        sp = split[sel[0]]
        cube = 2.0 ** (lv - sp)                   # min cells per axis (equal unless capped)
        grid = np.stack(np.meshgrid(*[np.arange(1 << k) for k in sp], indexing="ij"), axis=-1).reshape(-1, 3)
        c = leaves[sel, None, :3].astype(np.float64) + (grid[None] + 0.5) * cube
        centres.append(origin + c.reshape(-1, 3) * min_cell)
        halves.append(np.full(len(sel) * len(grid), 0.5 * min_cell * cube.max()))
        owner.append(np.repeat(sel, len(grid)))
    boxes = np.concatenate([np.concatenate(centres), np.concatenate(halves)[:, None]], axis=1)
    _, _, cls = native.classify_placement(volumes, geometry, boxes=boxes, min_cell_size=min_cell,
                                          max_cell_size=min_cell if max_cell is None else max_cell)
    inside = np.zeros(len(leaves), dtype=bool)
    inside[np.concatenate(owner)[np.asarray(cls) != 0]] = True
    return ~inside


def lattice_frame(volume_vertices: np.ndarray, min_cell: float, max_cell: float):
    """(origin (3,), root_level, root_dims (3,)) of the corner octree over the volumes' bounding box:
    origin = its min corner, leaves of Max Cell Size rounded down to Min Cell Size · 2^k (as the
    geometry octree rounds it), as many as cover the box."""
    v = np.asarray(volume_vertices, dtype=np.float64).reshape(-1, 3)
    lo, hi = v.min(axis=0), v.max(axis=0)
    level = max(0, int(math.floor(math.log2(max_cell / min_cell) + 1e-9)))
    level = min(level, 20)
    root = min_cell * (1 << level)
    dims = np.maximum(1, np.ceil((hi - lo) / root - 1e-6)).astype(int)
    return lo, level, dims


# Stages of one refinement pass: its new probes' first rounds; the tests' first rounds with the probes'
# more rounds; the more rounds of tests whose decision was not clear.
STAGES_PER_PASS = 3


def stage_bound(min_cell: float, max_cell: float, policy: Policy = DEFAULT_POLICY) -> int:
    """An upper bound of the stages (probe bakes, test bakes, more rounds) of any group's refinement
    with these cell sizes (AdaptiveGroup.stage_count before the group exists): the farm submits one
    job array per stage. The last pass has its probes' first rounds and their more rounds."""
    level = min(20, max(0, int(math.floor(math.log2(max_cell / min_cell) + 1e-9))))
    return STAGES_PER_PASS * passes_bound(level, policy) + 2


def passes_bound(root_level: int, policy: Policy = DEFAULT_POLICY) -> int:
    """Refinement passes that can split: one level per pass on every axis at once (octree), or on one
    axis at least (per axis: up to three times the levels)."""
    return (3 if policy.axes else 1) * root_level


def centre_only(tests: "native.RefineTests") -> "native.RefineTests":
    """The same test points with every leaf's face tests removed (Refinement Tests "Centre"): the
    points only faces referred to are dropped, the rest keep their order (the sorted lattice order
    of ``refine_tests``), so the result is as deterministic as the input."""
    lt = np.array(tests.leaf_tests, dtype=np.int32, copy=True)
    lt[:, 1:] = -1
    return restrict_tests(tests, lt)


def without_leaves(tests: "native.RefineTests", skip: np.ndarray) -> "native.RefineTests":
    """The same test points with the ``skip`` (L,) leaves' tests removed (see :func:`restrict_tests`)."""
    lt = np.array(tests.leaf_tests, dtype=np.int32, copy=True)
    lt[np.asarray(skip, dtype=bool)] = -1
    return restrict_tests(tests, lt)


def restrict_tests(tests: "native.RefineTests", lt: np.ndarray) -> "native.RefineTests":
    """``tests`` with leaf_tests replaced by ``lt`` (some entries set to −1): the points no leaf refers
    to any more are dropped, the rest keep their order."""
    if len(tests.positions) == 0:
        return native.RefineTests(lattice=tests.lattice, positions=tests.positions, probe=tests.probe,
                                  leaf_tests=np.full_like(np.asarray(lt, dtype=np.int32), -1))
    used = np.zeros(len(tests.positions), dtype=bool)
    used[lt[lt >= 0]] = True
    new_index = np.full(len(tests.positions), -1, dtype=np.int32)
    new_index[used] = np.arange(int(used.sum()), dtype=np.int32)
    lt = np.where(lt >= 0, new_index[np.maximum(lt, 0)], -1).astype(np.int32)
    return native.RefineTests(lattice=tests.lattice[used], positions=tests.positions[used],
                              probe=tests.probe[used], leaf_tests=lt)


def sky_sun(world: np.ndarray) -> Optional["native.Lamp"]:
    """A Sun lamp (engine space) carrying the sun of an equirectangular world image (H, W, >=3)
    radiance, rows top-down, the texel directions of pb_direct_sky_table (θ = π(row + ½)/H from
    Blender +Z, φ = π − 2π(col + ½)/W), or None when it has none: the sun of
    native.sky_sun_split (docs/direct-light.md "The sky's sun": a compact region around the
    brightest texel, its light above the surrounding sky's level; colour × strength = that excess
    ∫L dω, direction the way its light travels, angle its angular diameter). With Sky Sun "baked"
    the refinement's direct-light check uses it as a stand-in for the sun the probes keep; with
    "mixed" it is the light the engine adds (bake_core's engine lamps)."""
    w = np.asarray(world)
    if w.ndim != 3 or w.shape[2] < 3 or w.shape[0] < 1 or w.shape[1] < 1:
        raise ValueError(f"world image of shape {w.shape}: expected (H, W, >=3)")
    # Negative texels (the HDRIs hold -1e-5 ones) clamped at 0, as the bake reads a world.
    split = native.sky_sun_split(np.ascontiguousarray(np.clip(w[:, :, :3], 0.0, None), dtype=np.float32))
    return None if split.sun is None else split.sun.lamp()


class PointCache:
    """Every point the bake needs a value at, keyed by lattice position (1 µm): probes and test points
    of every group share renders. ``index(points)`` returns the cache index of each point, appending new
    ones; new points inside solid geometry (``ratio > Policy.solid_ratio``) are marked done with value 0.
    Two nodes that render at one position (nodes beyond the volumes' box clamped into it, or two solid
    nodes relocated to one free point) are one entry: a position is rendered once.

    A point's value is built in rounds (module doc): ``samples`` (total), ``rounds`` (done; 0: none
    yet, the first request renders two), ``m2`` (:func:`add_round`), ``pending`` (samples of the round
    queued, 0: none). ``samples`` is the bake's Samples setting."""

    def __init__(self, band: int, policy: Policy = DEFAULT_POLICY, samples: int = 8):
        self.solid_ratio = policy.solid_ratio
        self.policy = policy
        self.first, self.most = round_samples(samples, policy)
        self.count_coeffs = native.sh_count(band)
        self._keys = {}              # lattice key (+ placement key, see index) -> entry
        self._placed = {}            # lattice key -> where the group that asked first placed the node
        # Two groups place a node on the face they share on either side of it, Policy.render_inset
        # inside each, along up to three axes: within this they share one point.
        self.share = 2.0 * math.sqrt(3.0) * policy.render_inset + 1e-9
        self._render_keys = {}       # render position key -> entry
        self.positions = np.zeros((0, 3))
        self.coeffs = np.zeros((0, self.count_coeffs, 3))
        self.noise = np.zeros(0, dtype=np.float32)
        self.ratio = np.zeros(0, dtype=np.float32)       # solid test's back-face ratio
        self.rendered = np.zeros(0, dtype=bool)
        self.samples = np.zeros(0, dtype=np.float64)
        self.rounds = np.zeros(0, dtype=np.int32)
        self.m2 = np.zeros(0, dtype=np.float64)
        self.pending = np.zeros(0, dtype=np.int32)

    def __len__(self):
        return len(self.positions)

    @property
    def node_count(self) -> int:
        """Lattice nodes asked for so far (several may share one entry)."""
        return len(self._keys)

    @staticmethod
    def key(p) -> tuple:
        return tuple(int(round(c * 1e6)) for c in p)

    def index(self, points: np.ndarray, locate: Callable[[np.ndarray], Tuple[np.ndarray, np.ndarray]],
              place: Optional[Callable[[np.ndarray], np.ndarray]] = None) -> (np.ndarray, List[int]):
        """(cache index per point, indices of new points that need a render). ``locate`` maps node
        positions (N, 3) to where their panoramas are rendered and the solid test's back-face ratio
        there: (positions (N, 3), ratio (N,)); ``place`` (AdaptiveGroup.render_positions) to where
        they render before any relocation, without the solid test (default: where they are).

        Groups share a node's entry only where they place it within :attr:`share` of each other: a
        node on a face two volumes share renders once, 1 cm inside the volume that asked first. A
        volume's lattice runs past its box to a power of two of cells, and a node beyond the box is
        placed on the box's face: the neighbour volume's node there, inside it, is a point of its own
        (before, it took the light rendered on the face, up to the lattice's overhang away)."""
        pts = np.asarray(points, dtype=np.float64).reshape(-1, 3)
        placed = pts if place is None else np.asarray(place(pts), dtype=np.float64).reshape(-1, 3)
        out = np.empty(len(pts), dtype=np.int64)
        slots, new_pts, waiting, new_placed = {}, [], [], []
        for i, p in enumerate(pts):
            k = self.key(p)
            at = self._placed.get(k)
            if at is not None and np.sum((at - placed[i]) ** 2) > self.share ** 2:
                k = k + self.key(placed[i])   # another group's placement of this node: its own point
            j = self._keys.get(k)
            if j is not None:
                out[i] = j
                continue
            if k not in slots:
                slots[k] = len(new_pts)
                new_pts.append(p)
                new_placed.append(placed[i])
            waiting.append((i, slots[k]))
        if not new_pts:
            return out, []
        at, ratio = locate(np.array(new_pts))
        at = np.asarray(at, dtype=np.float64).reshape(-1, 3)
        ratio = np.asarray(ratio, dtype=np.float32).reshape(-1)
        entry, add, todo = [], [], []
        for s, k in enumerate(slots):
            rk = self.key(at[s])
            j = self._render_keys.get(rk)
            if j is None:
                j = self._render_keys[rk] = len(self.positions) + len(add)
                add.append(s)
                if ratio[s] <= self.solid_ratio:
                    todo.append(j)
            self._keys[k] = j
            self._placed.setdefault(k[:3], new_placed[s])
            entry.append(j)
        for i, s in waiting:
            out[i] = entry[s]
        self._append(at[add], ratio[add])
        self.pending[todo] = 2 * self.first
        return out, todo

    def _append(self, positions, ratio) -> int:
        """Append entries (not rendered yet) at render ``positions`` with solid-test ``ratio``;
        returns the first new index."""
        positions = np.asarray(positions, dtype=np.float64).reshape(-1, 3)
        n, first = len(positions), len(self.positions)
        self.positions = np.concatenate([self.positions, positions])
        self.coeffs = np.concatenate([self.coeffs, np.zeros((n, self.count_coeffs, 3))])
        self.noise = np.concatenate([self.noise, np.zeros(n, dtype=np.float32)])
        self.ratio = np.concatenate([self.ratio, np.asarray(ratio, dtype=np.float32)])
        self.rendered = np.concatenate([self.rendered, np.zeros(n, dtype=bool)])
        self.samples = np.concatenate([self.samples, np.zeros(n)])
        self.rounds = np.concatenate([self.rounds, np.zeros(n, dtype=np.int32)])
        self.m2 = np.concatenate([self.m2, np.zeros(n)])
        self.pending = np.concatenate([self.pending, np.zeros(n, dtype=np.int32)])
        return first

    # -- rounds
    def set_first(self, i: int, mean, noise: float):
        """Point ``i``'s two first rounds (``first`` samples each) as their mean and relative σ
        (:func:`combine_halves`, also what the journal keeps): m2 follows from σ, so a resumed
        bake continues from the journal's record exactly as the bake that rendered it."""
        mean = np.asarray(mean, dtype=np.float64)
        n = 2.0 * self.first
        self.coeffs[i], self.samples[i], self.rounds[i] = mean, n, 2
        self.m2[i] = (float(noise) * float(irradiance_norm(mean))) ** 2 * n
        self.noise[i] = noise
        self.rendered[i] = True
        self.pending[i] = 0

    def add(self, i: int, value, samples: int):
        """One more round of point ``i``: ``value`` rendered with ``samples`` samples."""
        mean, n, m2 = add_round(self.coeffs[i], self.samples[i], self.m2[i], value, samples)
        self.coeffs[i], self.samples[i], self.m2[i] = mean, n, m2
        self.rounds[i] += 1
        self.noise[i] = round_noise(mean, n, m2, int(self.rounds[i]))
        self.pending[i] = 0

    def more(self, idx, want) -> List[int]:
        """Queue one more round for points ``idx`` up to ``want`` samples each (array or scalar;
        capped at the most a point gets), where that is more than they have; points already queued,
        solid or not rendered yet are left alone. Returns the points queued (each once)."""
        idx = np.asarray(idx, dtype=np.int64).reshape(-1)
        want = np.broadcast_to(np.asarray(want, dtype=np.float64), idx.shape)
        out = []
        for i, w in zip(idx, want):
            i = int(i)
            if self.pending[i] or not self.rendered[i] or self.ratio[i] > self.solid_ratio:
                continue
            extra = int(min(self.most, math.ceil(w - 1e-9)) - self.samples[i])
            if extra > 0:
                self.pending[i] = extra
                out.append(i)
        return out

    def needed(self, idx, noise, target: float) -> np.ndarray:
        """Samples points ``idx`` need for their relative ``noise`` (as compared) to fall to
        ``target``: n·(σ / target)², rounded up to a multiple of a first round."""
        idx = np.asarray(idx, dtype=np.int64).reshape(-1)
        n = self.samples[idx]
        ratio = (np.asarray(noise, dtype=np.float64) / max(target, 1e-12)) ** 2
        return np.ceil(n * ratio / self.first - 1e-9) * self.first

    def values(self, idx) -> Tuple[np.ndarray, np.ndarray]:
        """(coefficients, relative noise) of points ``idx``."""
        idx = np.asarray(idx, dtype=np.int64).reshape(-1)
        return self.coeffs[idx], self.noise[idx]

    def solid(self, idx) -> np.ndarray:
        return self.ratio[idx] > self.solid_ratio

    def validity(self, idx) -> np.ndarray:
        """1 − back-face ratio, 0 inside solid geometry (the interpolation leaves those out)."""
        r = self.ratio[idx]
        return np.where(r > self.solid_ratio, 0.0, np.clip(1.0 - r, 0.0, 1.0)).astype(np.float32)


@dataclass
class PassRecord:
    """What one refinement pass did (for the log, the result and the benchmark)."""
    pass_index: int
    leaves: int
    probes: int
    smallest_cell: float
    tests: int = 0
    split: int = 0
    predicted: int = 0      # leaves not tested: predicted to pass from their parent's error (Policy.predict)
    rounds: int = 0         # test points given one more round (their decision was not clear)
    probe_rounds: int = 0   # probes given one more round (their noise was above Policy.probe_noise × tol)
    direct_split: int = 0   # leaves split by the lamps' exact direct light alone (no test flagged them)
    kept: int = 0           # region rebake: leaves outside the region, held to the previous tree (region.py)
    kept_split: int = 0     # of those, split as the previous tree was


class AdaptiveGroup:
    """The corner octree of one output file (the union of the volumes, or one volume) and where its
    refinement stands: ``stage`` "probes" (the new probes' first rounds are being baked), "tests"
    (the test points' first rounds and the probes' more rounds), "rounds" (more rounds of tests whose
    decision was not clear) or "last" (the last probes' more rounds), ``finished`` when nothing
    splits any more and every probe has its samples."""

    def __init__(self, name: str, path: str, volumes, geometry, min_cell: float, max_cell: float,
                 tolerance: float, tests: str = "CENTRE_FACES",
                 direct: Optional[Callable[[np.ndarray], Optional[np.ndarray]]] = None,
                 engine_direct: Optional[Callable[[np.ndarray], Optional[np.ndarray]]] = None,
                 policy: Policy = DEFAULT_POLICY):
        if tests not in TEST_MODES:
            raise ValueError(f"refinement tests {tests!r}: expected one of {', '.join(TEST_MODES)}")
        self.name, self.path = name, path
        self.policy = policy
        self.volumes, self.geometry = volumes, geometry
        self.min_cell = float(min_cell)
        self.max_cell = float(max_cell)
        self.tolerance = float(tolerance)
        self.test_mode = tests
        self.axes = bool(policy.axes) and tests == "CENTRE_FACES"
        verts = np.concatenate([np.asarray(v[1], dtype=np.float64).reshape(-1, 3) for v in volumes])
        self.origin, self.root_level, dims = lattice_frame(verts, min_cell, max_cell)
        self.box_min, self.box_max = verts.min(axis=0), verts.max(axis=0)
        self.tree = native.CornerOctree.uniform(tuple(self.origin), self.min_cell, self.root_level, tuple(dims))
        self._drop_outside()
        self.tree.finalize()
        if self.tree.leaf_count == 0:
            raise native.SchneeError(f"no cell of Max Cell Size lies inside '{name}'", "invalid argument")
        self.stage = "probes"
        self.finished = False
        self.passes: List[PassRecord] = []
        self.tests = None
        self.test_index = None      # cache index per test point
        self.probe_index = None     # cache index per tree probe
        self.last_errors = None
        self.predict = float(policy.predict)
        self.settled = set()        # leaf keys (x, y, z, level) predicted to pass: never tested
        self.decisions = []         # every pass's decision, for the bake-info sidecar (bakeinfo.py)
        self.parent_ratio = {}      # leaf key -> its parent's error over threshold next to it
        self.parent_rate = {}       # leaf key -> the rate its parent's error fell by (when measured)
        # The lamps' exact direct light at engine-space points ((N, C, 3) radiance SH, or None when
        # no lamp is added analytically): leaves whose interpolation of it is off split (no render).
        self.direct = direct
        self._direct_of = {}        # cache index -> direct SH at that point's render position
        self._direct_split = None   # per leaf of the current tree: the direct check failed
        # The mixed lamps' exact direct light at engine-space points ((N, C, 3), or None): not in the
        # probes, added by the engine (shadow maps), so a moving object sees probe + it. Every
        # comparison is made on that total (docs/placement.md step 3): the same light change is a
        # smaller error where the sun also shines.
        self.engine_direct = engine_direct
        self._engine_of = {}        # cache index -> the mixed lamps' direct SH there
        self.kept = None            # region rebake: region.KeptTree, the previous tree outside the region
        self._kept_split = 0        # per leaf: the previous tree's split of a kept leaf (KeptTree.hold)

    # -- geometry queries through the placement's rules
    def _drop_outside(self) -> int:
        info = self.tree.info()
        leaves = info["leaves"]
        if len(leaves) == 0:
            return 0
        outside = outside_boxes(self.origin, self.min_cell, self.volumes, self.geometry, leaves, leaf_levels(info),
                                self.max_cell)
        if outside.any():
            self.tree.drop(outside)
        return int(outside.sum())

    def classify_points(self, points: np.ndarray) -> np.ndarray:
        """Back-face ratio of the solid test at each point."""
        # The bake's own Max Cell Size: the classification does not use it, but the native
        # placement checks it against Min Cell Size, and left out it is the native default of
        # 16 m, which refused any Min Cell Size above 16 m "(16 m) is smaller than min_cell_size"
        # (issue 31).
        _, ratio, _ = native.classify_placement(self.volumes, self.geometry, points=points,
                                                min_cell_size=self.min_cell, max_cell_size=self.max_cell)
        return ratio

    def lattice_positions(self, lattice: np.ndarray) -> np.ndarray:
        return self.origin + np.asarray(lattice, dtype=np.float64) * self.min_cell

    def render_positions(self, nodes: np.ndarray) -> np.ndarray:
        """Where a node's panorama is rendered: the node, moved into the volumes' bounding box by
        Policy.render_inset. The lattice starts at the volumes' min corner, so in a room whose volume is its
        interior the outer nodes lie exactly on the floor, walls and ceiling (a camera there sees
        half of the surface edge-on and the solid test is a coin toss) or beyond them (outside the
        building, seeing the exterior): rendered 1 cm inside, they hold the light at the room's
        boundary, which is what the interpolation next to it needs."""
        return np.clip(nodes, self.box_min + self.policy.render_inset, self.box_max - self.policy.render_inset)

    def locate(self, nodes: np.ndarray) -> Tuple[np.ndarray, np.ndarray]:
        """(positions (N, 3), back-face ratio (N,)): where each node's panorama is rendered and the
        solid test there (the PointCache's ``locate``). The node is moved into the volumes' box
        (:meth:`render_positions`); if the solid test puts it inside solid geometry (ratio >
        Policy.solid_ratio), it moves to the nearest free point within ``min(Policy.relocate, Min Cell Size / 4)``,
        tried at a quarter, half and all of that reach along the 26 axis and diagonal directions
        (axes first; at one distance the lowest ratio wins); points deeper inside stay. A lattice
        node on a furniture face or at its edge with the floor is a coin toss for the solid test and,
        left out, makes its open neighbours take the light of probes a cell away (the hanging rules
        of a solid leaf next to them); rendered 1–5 cm outside, it holds the light there, as the
        nodes on the volume's faces do (Policy.render_inset)."""
        at = self.render_positions(np.asarray(nodes, dtype=np.float64).reshape(-1, 3))
        ratio = np.asarray(self.classify_points(at), dtype=np.float32) if len(at) else np.zeros(0, np.float32)
        reach = min(self.policy.relocate, 0.25 * self.min_cell)
        solid = np.flatnonzero(ratio > self.policy.solid_ratio)
        if len(solid) == 0 or reach <= 0:
            return at, ratio
        steps = reach * np.array([0.25, 0.5, 1.0])
        cand = at[solid, None, None, :] + steps[None, :, None, None] * _RELOCATE_DIRS[None, None]
        cand = np.clip(cand, self.box_min + self.policy.render_inset, self.box_max - self.policy.render_inset)
        cr = np.asarray(self.classify_points(cand.reshape(-1, 3)), dtype=np.float32).reshape(cand.shape[:3])
        for i, s in enumerate(solid):
            for k in range(len(steps)):
                free = np.flatnonzero(cr[i, k] <= self.policy.solid_ratio)
                if len(free):
                    j = free[np.argmin(cr[i, k, free])]
                    at[s], ratio[s] = cand[i, k, j], cr[i, k, j]
                    break
        return at, ratio

    def _index(self, cache: PointCache, lattice: np.ndarray):
        """PointCache.index of lattice nodes, placed and located as this group renders them."""
        return cache.index(self.lattice_positions(lattice), self.locate, self.render_positions)

    def stand_in_radius(self) -> float:
        """How far from its lattice node a node's render position can lie, when the node is on or within
        Policy.render_inset of the volumes' box: the inset along each axis, then the relocation's reach
        (:meth:`locate`). A region rebake's KeptTree.stand_in looks this far for the previous bake's point."""
        return math.sqrt(3.0) * self.policy.render_inset + min(self.policy.relocate, 0.25 * self.min_cell)

    def smallest_cell(self) -> float:
        levels = leaf_levels(self.tree.info())
        return self.min_cell * float(2 ** int(levels.min())) if len(levels) else self.min_cell

    # -- the state machine
    def start(self, cache: PointCache) -> List[int]:
        """Request the first layer's probes; returns the cache indices to render."""
        self.probe_index, todo = self._index(cache, self.tree.probe_lattice())
        info = self.tree.info()
        self.passes.append(PassRecord(1, len(info["leaves"]), int(info["probe_count"]), self.smallest_cell()))
        return todo

    def advance(self, cache: PointCache) -> List[int]:
        """Every requested point has its value: take the next step. Returns the cache indices to
        render next (possibly none: call again until ``finished`` or something is returned)."""
        if self.finished:
            return []
        if self.stage == "last":
            self.finished = True
            return []
        if self.stage == "probes":
            more = self._probe_rounds(cache)
            tests = refine_axes.tests_axes(self.tree) if self.axes else self.tree.refine_tests()
            if self.test_mode == "CENTRE":
                tests = centre_only(tests)
            if self.settled:
                skip = np.array([k in self.settled for k in leaf_keys(self.tree.info())], dtype=bool)
                skip &= (tests.leaf_tests >= 0).any(axis=1)
                self.passes[-1].predicted = int(skip.sum())
                tests = without_leaves(tests, skip)
            self._direct_split = self.direct_check(cache)
            if self.kept is not None:  # outside a rebake's region: no test, the previous tree's splits
                tests, self._direct_split, self._kept_split = self.kept.hold(self, tests, self._direct_split)
            need = tests.probe < 0
            if len(tests.positions) == 0 or not (tests.leaf_tests >= 0).any():
                split = self._direct_split | self._kept_split
                if split.any():
                    bakeinfo.record_decision(self, None if self.kept is None else self._kept_split, self._direct_split,
                                             None, None, None)
                    self.passes[-1].direct_split = int((self._direct_split != 0).sum())
                    self.passes[-1].split = int((split != 0).sum())
                    return more + self._split(split, cache)
                if more:
                    self.stage = "last"
                    return more
                self.finished = True
                return []
            self.tests = tests
            self.test_index = np.full(len(tests.positions), -1, dtype=np.int64)
            idx, todo = self._index(cache, tests.lattice[need])
            self.test_index[need] = idx
            self.passes[-1].tests = int(need.sum())
            self.stage = "tests"
            return more + todo
        split, err, thr, pc, tc, tv = self._decide(cache)
        if self.stage == "tests":
            todo = self._test_rounds(cache, thr, pc, tc, tv)
            if todo:
                self.stage = "rounds"
                return todo
        # the tests' decision is clear (or they have every sample): split, request the new probes
        return self._conclude(cache, split, err, thr, pc, tc, tv)

    def _probe_rounds(self, cache: PointCache) -> List[int]:
        """One more round for each probe whose noise, as a moving object sees it, is above
        Policy.probe_noise × Error Tolerance: up to the samples that noise says it needs."""
        target = self.policy.probe_noise * self.tolerance
        pidx = np.asarray(self.probe_index, dtype=np.int64)
        noise = self.seen(cache, pidx)[1].astype(np.float64)
        loud = (noise > target) & ~cache.solid(pidx)
        if self.kept is not None:  # a rebake keeps the previous records outside its region
            loud &= self.kept.previous_rows(self.tree.probe_lattice()) < 0
        if not loud.any():
            return []
        todo = cache.more(pidx[loud], cache.needed(pidx[loud], noise[loud], target))
        self.passes[-1].probe_rounds += len(todo)
        return todo

    def _decide(self, cache: PointCache):
        """refine_decide on the current tests: (split, worst error, its threshold, probe values, test
        values, test valid), every value as a moving object sees it (:meth:`seen`)."""
        tests = self.tests
        pidx = self.probe_index
        need = tests.probe < 0
        test_coeffs = np.zeros((len(tests.positions),) + cache.coeffs.shape[1:])
        test_noise = np.zeros(len(tests.positions), dtype=np.float32)
        test_valid = np.ones(len(tests.positions), dtype=bool)
        ti = self.test_index[need]
        probe_coeffs, probe_noise = self.seen(cache, pidx)
        test_coeffs[need], test_noise[need] = self.seen(cache, ti)
        test_valid[need] = ~cache.solid(ti)
        kw = dict(probe_noise=probe_noise, test_noise=test_noise, probe_validity=cache.validity(pidx),
                  test_valid=test_valid, tolerance=self.tolerance, noise_k=self.policy.noise_k)
        if self.axes:
            split, err, thr = refine_axes.decide_axes(self.tree, tests, probe_coeffs, test_coeffs, **kw)
        else:
            split, err, thr = self.tree.refine_decide(tests, probe_coeffs, test_coeffs, **kw)
            split = np.where(split, 7, 0).astype(np.uint8)
        return split, err, thr, probe_coeffs, test_coeffs, test_valid

    def _test_rounds(self, cache: PointCache, thr, probe_coeffs, test_coeffs, test_valid) -> List[int]:
        """Test points whose leaf's decision is not clear given their own noise, for one more round of
        the samples that make it clear (at most the most): a test erring within Policy.decide_z × its
        σ of its leaf's threshold, in
        a leaf that no test of it splits clearly (above its threshold by more than that) and that the
        lamps' direct light does not split. Two rounds' σ is itself an estimate: a spike at a few
        samples must not split a leaf, nor the noise let an error through."""
        leaves = self.tree.info()["leaves"]
        tests = self.tests
        need = tests.probe < 0
        noise = np.zeros(len(tests.positions))
        noise[need] = self.seen(cache, self.test_index[need])[1]
        interp = self.tree.interpolate(tests.positions, probe_coeffs, cache.validity(self.probe_index))
        err_t = np.nan_to_num(irradiance_error(interp, test_coeffs))
        direct = self._direct_split if self._direct_split is not None else np.zeros(len(leaves), dtype=bool)
        direct = np.asarray(direct) != 0
        gap = unclear_tests(tests.leaf_tests, leaves[:, 3] > 0, need & np.asarray(test_valid, dtype=bool),
                            err_t, noise, thr, direct, self.policy.decide_z)
        pick = np.isfinite(gap)
        if not pick.any():
            return []
        # The samples that shrink z·σ (∝ 1/√N) to the test's distance from the threshold.
        ti = self.test_index[pick]
        ratio = (self.policy.decide_z * noise[pick] / np.maximum(gap[pick], 1e-12)) ** 2
        todo = cache.more(ti, np.ceil(cache.samples[ti] * ratio / cache.first - 1e-9) * cache.first)
        self.passes[-1].rounds += len(todo)
        return todo

    def _conclude(self, cache: PointCache, split, err, thr, probe_coeffs, test_coeffs, test_valid) -> List[int]:
        """The pass's decision made: record it, predict the children that pass, split."""
        self.last_errors = (err, thr)
        split = split | self._kept_split
        bakeinfo.record_decision(self, split, self._direct_split, err, thr, test_valid)
        if self._direct_split is not None:
            self.passes[-1].direct_split = int(((self._direct_split != 0) & (split == 0)).sum())
            split = split | self._direct_split
        n = int((split != 0).sum())
        self.passes[-1].split = n
        if n == 0:
            self.tests = self.test_index = None
            self.finished = True
            return []
        if self.predict > 0:
            settle_children(self, split, thr, probe_coeffs, cache.validity(self.probe_index), test_coeffs,
                            test_valid)
        self.tests = self.test_index = None
        return self._split(split, cache)

    def seen(self, cache: PointCache, idx) -> Tuple[np.ndarray, np.ndarray]:
        """(coefficients, relative noise) of cache points ``idx`` as a moving object sees them: the
        point's value plus the mixed lamps' exact direct light there (engine_direct; nothing without
        one), its noise rescaled to that total (the noise is absolute: σ‖A·c‖ / ‖A·(c + d)‖)."""
        idx = np.asarray(idx, dtype=np.int64).reshape(-1)
        coeffs, noise = cache.values(idx)
        noise = noise.astype(np.float64)
        if self.engine_direct is None or len(idx) == 0:
            return coeffs, noise.astype(np.float32)
        missing = sorted({int(i) for i in idx if int(i) not in self._engine_of})
        if missing:
            vals = self.engine_direct(cache.positions[missing])
            for i, k in enumerate(missing):
                self._engine_of[k] = None if vals is None else vals[i]
        if any(self._engine_of[int(i)] is None for i in idx):
            return coeffs, noise.astype(np.float32)
        total = coeffs + np.array([self._engine_of[int(i)] for i in idx])
        own, den = irradiance_norm(coeffs), irradiance_norm(total)
        with np.errstate(divide="ignore", invalid="ignore"):
            scale = np.where(den > 0, own / np.where(den > 0, den, 1.0), 1.0)
        return total, (noise * scale).astype(np.float32)

    def _split(self, split: np.ndarray, cache: PointCache) -> List[int]:
        """Split the flagged leaves, drop children outside the volumes, request the new probes."""
        self._direct_split, self._kept_split = None, 0
        self.tree.split_axes(np.asarray(split, dtype=np.uint8))   # the octree's masks are 7
        self.tree.finalize()
        self._drop_outside()
        self.tree.finalize()
        self.probe_index, todo = self._index(cache, self.tree.probe_lattice())
        info = self.tree.info()
        self.passes.append(PassRecord(len(self.passes) + 1, len(info["leaves"]), int(info["probe_count"]),
                                      self.smallest_cell()))
        self.stage = "probes"
        return todo

    def direct_check(self, cache: PointCache) -> np.ndarray:
        """(L,) uint8 axis masks (split_masks): leaves above Min Cell Size whose interpolation of the lamps' exact direct light
        is off by more than the tolerance somewhere on a lattice of Policy.direct_divisions steps per axis
        inside the leaf (at most one per Min Cell Size; the leaf's corners excluded), relative to the
        interpolated total light there. The direct term costs no render (shadow rays only), so a
        sunbeam's edge that passes between a leaf's test points, or crosses a leaf predicted to
        pass, still draws refinement. Points inside solid geometry are not compared."""
        info = self.tree.info()
        leaves, levels = info["leaves"], leaf_levels(info)
        out = np.zeros(len(leaves), dtype=np.uint8)
        if self.direct is None:
            return out
        lat, leaf_of, edge = direct_points(leaves, levels, self.policy.direct_divisions)
        if len(lat) == 0:
            return out
        uniq, inverse = np.unique(lat, axis=0, return_inverse=True)
        pos = self.lattice_positions(uniq)
        at = self.render_positions(pos)
        exact = self.direct(at)
        if exact is None:
            return out
        pidx = self.probe_index
        missing = [int(i) for i in pidx if int(i) not in self._direct_of]
        if missing:
            vals = self.direct(cache.positions[missing])
            for i, v in zip(missing, vals):
                self._direct_of[i] = v
        d_probe = np.array([self._direct_of[int(i)] for i in pidx])
        validity = cache.validity(pidx)
        interp = self.tree.interpolate(pos, d_probe, validity)
        total = self.tree.interpolate(pos, self.seen(cache, pidx)[0], validity)
        num, den = irradiance_norm(interp - exact), irradiance_norm(total)
        with np.errstate(divide="ignore", invalid="ignore"):
            err = np.where(den > 0, num / np.where(den > 0, den, 1.0), 0.0)
        err = np.nan_to_num(err)
        err[np.asarray(self.classify_points(at)) > self.policy.solid_ratio] = 0.0
        fail = err[inverse.reshape(-1)] > self.tolerance
        return split_masks(len(leaves), levels, leaf_of, edge, fail, self.axes)

    def stage_count(self) -> int:
        """An upper bound of the stages (probe bakes, test bakes, more rounds) of this group's
        refinement."""
        return STAGES_PER_PASS * passes_bound(self.root_level, self.policy if self.axes else
                                              Policy(axes=False)) + 2

    def stage_index(self) -> int:
        within = {"probes": 0, "tests": 1, "rounds": 2, "last": 1}[self.stage]
        return STAGES_PER_PASS * (len(self.passes) - 1) + within

    def probe_values(self, cache: PointCache):
        """(coeffs (P, C, 3), validity (P,)) of the finished tree's probes."""
        return cache.values(self.probe_index)[0], cache.validity(self.probe_index)


def settle_children(group: "AdaptiveGroup", split, thr, probe_coeffs, validity, test_coeffs, test_valid):
    """Mark the children of ``group``'s split leaves that are predicted to pass (see Policy.predict).
    A child's parent ratio is the parent's worst error over its threshold at its test points on the child's
    closed box (for an octree leaf its centre and the three face centres of the child's octant;
    where none of those was compared, inside solids, the parent's worst over all its tests)."""
    tests = group.tests
    values = test_coeffs.copy()
    is_probe = tests.probe >= 0
    values[is_probe] = probe_coeffs[tests.probe[is_probe]]
    interp = group.tree.interpolate(tests.positions, probe_coeffs, validity)
    err_t = irradiance_error(interp, values)
    valid_t = np.asarray(test_valid, dtype=bool).copy()
    valid_t[is_probe] &= np.asarray(validity)[tests.probe[is_probe]] > 0
    err_t = np.where(valid_t & np.isfinite(err_t), err_t, np.nan)
    keys = leaf_keys(group.tree.info())
    for i in np.flatnonzero(split):
        key = keys[i]
        cols = tests.leaf_tests[i]
        ratios = np.where(cols >= 0, err_t[np.maximum(cols, 0)], np.nan) / max(float(thr[i]), 1e-12)
        whole = np.nanmax(ratios) if np.isfinite(ratios).any() else np.inf
        # The rate this leaf's error fell by since its parent predicts its children only when
        # its parent's rate was measured too (two consecutive halvings seen). The first rate
        # alone, at the coarsest levels, was chance: in the room at 128×64 px a 4 m leaf from
        # floor to ceiling predicted from the 16 m → 8 m rate was never tested, 15–28 % off at
        # nine points. Unknown: 1 (a child passes only where its parent itself passed).
        # (min(own, parent's) was measured too: more accurate, 1.4–1.5× the renders; see
        # bench/results/placement.md.)
        before = group.parent_ratio.get(key)
        measured = None if before is None or not whole > 0 else min(group.predict, max(1.0, before / whole))
        if float(thr[i]) > group.policy.predict_noise * group.tolerance:
            measured = None     # the threshold is the noise's: no rate (Policy.predict_noise)
        rate = 1.0 if measured is None or key not in group.parent_rate else measured
        lat = np.where(cols[:, None] >= 0, tests.lattice[np.maximum(cols, 0)], -1).astype(np.int64)
        for child in child_keys(key, int(split[i])):
            lo = np.array(child[:3], dtype=np.int64)
            hi = lo + (1 << np.array(child[3:], dtype=np.int64))
            # the parent's tests on the child's closed box (the octree: its centre and the three
            # face centres of the child's octant)
            inside = (cols >= 0) & ((lat >= lo) & (lat <= hi)).all(axis=1) & np.isfinite(ratios)
            worst = float(ratios[inside].max()) if inside.any() else whole
            group.parent_ratio[child] = worst
            if measured is not None:
                group.parent_rate[child] = measured
            if worst / rate < 1.0:
                group.settled.add(child)
