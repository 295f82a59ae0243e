"""Boxes with per-axis levels in the native corner tree (issue 29 item 3, docs/aniso-refinement.md)
through the Python API. References: a field linear in position is reproduced exactly (closed form);
the field is continuous across leaf borders (a jump would be of the order of the random probe values,
0.1-1); the Python prototype of bench/bench_aniso.py, driven by the same per-leaf split decisions, gives
the same leaves, forced splits, probes, hanging nodes and interpolated values; the split tree's
descent is written again here and must find the leaves the native locate finds, in at most 3R steps."""
import os
import sys

import numpy as np
import pytest

from schnee_probes import native

sys.path.insert(0, os.path.join(os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__)))),
                                "bench"))
import bench_aniso as ba  # noqa: E402

ORIGIN = np.array([0.5, -1.0, 2.0])
H = 0.25
ROOTS = (2, 1, 2)
R = 3
DIMS = np.array(ROOTS) << R  # 16 x 8 x 16 min cells, as test_aniso_prototype.py


def _masks(leaves6, seed, p=0.3):
    """Split masks as a function of the leaf itself (not of its index), so that the native tree and
    the prototype, which order their leaves differently, take the same decisions."""
    out = np.zeros(len(leaves6), np.uint8)
    for i, row in enumerate(np.asarray(leaves6, dtype=np.int64).tolist()):
        r = np.random.default_rng([seed] + row)
        out[i] = sum(1 << a for a in range(3) if r.random() < p)
    return out


def _native_leaves6(t):
    info = t.info()
    return np.concatenate([info["leaves"][:, :3], info["levels"]], axis=1).astype(np.int64)


def _random_pair(seed, passes=4):
    """The native tree and the prototype after the same passes; returns (tree, prototype, forced)."""
    t = native.CornerOctree.uniform(ORIGIN, H, R, ROOTS)
    k = ba.KdTree.roots(DIMS, R)
    forced = 0
    for p in range(passes):
        m = _masks(_native_leaves6(t), seed * 100 + p)
        t.split_axes(m)
        t.finalize()
        forced += t.forced_splits
        km = _masks(k.leaves, seed * 100 + p)
        k.split(((km[:, None] >> np.arange(3)) & 1).astype(bool))
        k.enforce_nesting()
    k.build()
    return t, k, forced


def _sorted_rows(a):
    a = np.asarray(a, dtype=np.int64)
    return a[np.lexsort(a.T[::-1])]


@pytest.mark.parametrize("seed", range(3))
def test_random_boxes_match_the_prototype(seed):
    t, k, forced = _random_pair(seed)
    info = t.info()
    lv = info["levels"]
    assert (lv.min(axis=1) < lv.max(axis=1)).any()  # really anisotropic
    assert info["root_level"] == R
    np.testing.assert_array_equal(info["leaves"][:, 3], lv.max(axis=1))
    np.testing.assert_array_equal(_sorted_rows(_native_leaves6(t)), _sorted_rows(k.leaves))
    assert forced == k.forced
    assert info["probe_count"] == k.probe_count and info["hanging_count"] == k.hanging_count
    np.testing.assert_array_equal(_sorted_rows(info["probe_lattice"]), _sorted_rows(k.probe_lattice))
    # The same field at random points from random probe values keyed by lattice point.
    rng = np.random.default_rng(seed)
    vals = rng.random(len(k.probe_lattice))
    key = {tuple(p): v for p, v in zip(k.probe_lattice.tolist(), vals)}
    nvals = np.array([key[tuple(p)] for p in info["probe_lattice"].tolist()])
    u = rng.random((3000, 3)) * DIMS
    np.testing.assert_allclose(t.interpolate(ORIGIN + H * u, nvals), k.interpolate_lattice(u, k.node_values(vals)),
                               atol=1e-12, rtol=0)


@pytest.mark.parametrize("seed", range(3))
def test_linear_field_exact_and_continuous(seed):
    t, _, _ = _random_pair(seed + 10)
    info = t.info()
    g, c0 = np.array([0.37, -1.3, 0.71]), 0.25
    lin = info["probe_lattice"] @ g + c0
    rng = np.random.default_rng(seed)
    u = rng.random((4000, 3)) * DIMS
    assert np.abs(t.interpolate(ORIGIN + H * u, lin) - (u @ g + c0)).max() < 1e-9
    # Continuity: random points on random leaves' upper faces, 1e-7 min cells to either side. The
    # field's slope is below 2 per min cell (values in [0, 1], leaves >= 1 min cell): < 1e-6 if C0.
    vals = rng.random(info["probe_count"])
    lo, size = info["leaves"][:, :3].astype(np.int64), 1 << info["levels"].astype(np.int64)
    L = rng.integers(0, len(lo), 20000)
    a = rng.integers(0, 3, len(L))
    hi = lo[L, a] + size[L, a]
    keep = hi < DIMS[a]
    L, a, hi = L[keep], a[keep], hi[keep]
    p = lo[L] + rng.random((len(L), 3)) * size[L]
    p[np.arange(len(L)), a] = hi
    below, above = p.copy(), p.copy()
    below[np.arange(len(L)), a] -= 1e-7
    above[np.arange(len(L)), a] += 1e-7
    assert len(L) > 8000
    assert np.abs(t.interpolate(ORIGIN + H * below, vals) - t.interpolate(ORIGIN + H * above, vals)).max() < 1e-6


def _descend(nodes, grid, root_level, q):
    """docs/aniso-refinement.md "Point location", step by step: (leaf or -1, steps)."""
    c = q >> root_level
    node = int(c[0] + grid[0] * (c[1] + grid[1] * c[2]))
    lo, lv, steps = c << root_level, np.full(3, root_level), 0
    while nodes[node] & 3:
        a = int(nodes[node] & 3) - 1
        lv[a] -= 1
        up = int(q[a] >= lo[a] + (1 << lv[a]))
        lo[a] += up << lv[a]
        node = int(nodes[node] >> 2) + up
        steps += 1
    leaf = int(nodes[node] >> 2)
    return (-1 if leaf == (1 << 30) - 1 else leaf), steps


def test_split_tree_descent_and_canonical():
    t, _, _ = _random_pair(7)
    nodes = t.split_tree()
    info = t.info()
    grid = DIMS >> R
    assert len(nodes) == grid.prod() + 2 * (len(info["leaves"]) - grid.prod())
    rng = np.random.default_rng(3)
    u = rng.random((2000, 3)) * DIMS
    found = t.locate(ORIGIN + H * u)
    depth = 0
    for q, f in zip(np.floor(u).astype(np.int64), found):
        leaf, steps = _descend(nodes, grid, R, q)
        assert leaf == f
        depth = max(depth, steps)
    assert R < depth <= 3 * R
    # The same leaves in another order give the same tree and the same probes.
    boxes = np.concatenate([info["leaves"][:, :3], native.pack_levels(info["levels"])[:, None]], axis=1)
    u2 = native.CornerOctree.from_boxes(ORIGIN, H, R, DIMS, boxes[rng.permutation(len(boxes))])
    np.testing.assert_array_equal(u2.split_tree(), nodes)
    u2.finalize()
    assert u2.forced_splits == 0
    np.testing.assert_array_equal(u2.info()["probe_lattice"], info["probe_lattice"])
    # Split orders: x then y or y then x, the same leaves, the same tree.
    trees = []
    for first, second in ((1, 6), (2, 5)):
        s = native.CornerOctree.uniform(ORIGIN, H, 2, (1, 1, 1))
        s.split_axes(np.array([first]))
        s.split_axes(np.full(s.leaf_count, second))
        trees.append(s.split_tree())
    np.testing.assert_array_equal(trees[0], trees[1])
    assert len(trees[0]) == 15 and trees[0][0] & 3 == 1  # the root splits along x first


def test_cube_trees_are_the_octree():
    rng = np.random.default_rng(5)
    a = native.CornerOctree.uniform(ORIGIN, H, 3, (2, 2, 1))
    b = native.CornerOctree.uniform(ORIGIN, H, 3, (2, 2, 1))
    for _ in range(3):
        f = rng.random(a.leaf_count) < 0.35
        assert a.split(f) == b.split_axes(np.where(f, 7, 0))
    a.finalize()
    b.finalize()
    ia, ib = a.info(), b.info()
    for key in ("leaves", "levels", "probe_lattice", "leaf_corners", "hanging_sources", "hanging_weights"):
        np.testing.assert_array_equal(ia[key], ib[key])
    assert ia["hanging_count"] > 0 and b.forced_splits == 0
    np.testing.assert_array_equal(ia["levels"], np.repeat(ia["leaves"][:, 3:], 3, axis=1))
    # The same cubes through from_boxes and from_leaves: the same tree.
    boxes = ia["leaves"].copy()
    boxes[:, 3] = native.pack_levels(ia["levels"])
    dims = np.array([2, 2, 1]) << 3
    c = native.CornerOctree.from_boxes(ORIGIN, H, 3, dims, boxes)
    d = native.CornerOctree.from_leaves(ORIGIN, H, dims, ia["leaves"])
    c.finalize()
    d.finalize()
    for key in ("leaves", "probe_lattice", "leaf_corners", "hanging_sources", "hanging_weights"):
        np.testing.assert_array_equal(c.info()[key], ia[key])
        np.testing.assert_array_equal(d.info()[key], ia[key])


def test_forced_split_of_a_cross():
    """A (levels 2, 2, 3) beside B (levels 2, 3, 1) across x = 4: A finer on y by 1, coarser on z by
    2, so B (coarser on y, the smaller difference) splits along y: 1 forced split, 3 leaves."""
    boxes = np.array([[0, 0, 0, 2 | 2 << 8 | 3 << 16], [4, 0, 0, 2 | 3 << 8 | 1 << 16]], np.uint32)
    t = native.CornerOctree.from_boxes(ORIGIN, H, 3, (8, 8, 8), boxes)
    t.finalize()
    assert t.forced_splits == 1
    np.testing.assert_array_equal(_sorted_rows(_native_leaves6(t)),
                                  [[0, 0, 0, 2, 2, 3], [4, 0, 0, 2, 2, 1], [4, 4, 0, 2, 2, 1]])


def test_errors():
    with pytest.raises(native.SchneeError, match="not aligned to its size 2 on axis Y") as e:
        native.CornerOctree.from_boxes(ORIGIN, H, 3, (8, 8, 8), [[0, 1, 0, 1 << 8]])
    assert e.value.code == "invalid argument"
    with pytest.raises(native.SchneeError, match="overlaps leaf"):
        native.CornerOctree.from_boxes(ORIGIN, H, 3, (8, 8, 8), [[0, 0, 0, 2], [2, 0, 0, 1 | 1 << 8]])
    with pytest.raises(native.SchneeError, match="above the root level 2"):
        native.CornerOctree.from_boxes(ORIGIN, H, 2, (8, 8, 8), [[0, 0, 0, 3]])
    t = native.CornerOctree.uniform(ORIGIN, H, 1, (1, 1, 1))
    with pytest.raises(ValueError, match="masks must have shape"):
        t.split_axes(np.zeros(3, np.uint8))
    with pytest.raises(ValueError, match="integers 0..7"):
        t.split_axes(np.array([8]))
