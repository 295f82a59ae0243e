"""The anisotropic refinement prototype of bench/bench_aniso.py (issue 29 item 3, docs/aniso-refinement.md):
boxes with per-axis levels on the lattice, probes at their corners, hanging corners from the larger
neighbour's face/edge. Its field must be C0 across every leaf border and reproduce a linear field exactly;
without the nesting rule (no "cross" of two face neighbours) it is not C0, which is why the rule exists."""
import os
import sys

import numpy as np

sys.path.insert(0, os.path.join(os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__)))),
                                "bench"))
import bench_aniso as ba  # noqa: E402

DIMS = np.array([16, 8, 16])


def _random_tree(seed, passes=4, nest=True):
    t = ba.KdTree.roots(DIMS, 3)
    rng = np.random.default_rng(seed)
    for _ in range(passes):
        t.split(rng.random((len(t.leaves), 3)) < 0.3)
        if nest:
            t.enforce_nesting()
    t.build()
    return t


def test_random_anisotropic_trees_are_c0_and_linear_exact():
    for seed in range(4):
        t = _random_tree(seed)
        lv = t.leaves[:, 3:]
        assert (lv.min(axis=1) < lv.max(axis=1)).any()  # really anisotropic
        assert t.hanging_count > 0
        assert ba.border_jump(t, n=10000, seed=seed) < 1e-9
        assert ba.linear_error(t, n=4000, seed=seed) < 1e-9
        # expanded weights of every node: >= 0, summing to 1
        rows = np.repeat(np.arange(len(t.node_ptr) - 1), np.diff(t.node_ptr))
        assert (t.node_w > 0).all()
        np.testing.assert_allclose(np.bincount(rows, weights=t.node_w), 1.0, atol=1e-12)


def test_cross_neighbours_break_c0_without_the_nesting_rule():
    jumps = [ba.border_jump(_random_tree(seed, nest=False), n=4000, seed=seed) for seed in range(4)]
    assert max(jumps) > 1e-2


def test_hanging_rules_of_a_y_split():
    """Two roots of 8 min cells side by side along x; the first split along y only: its new corners
    at mid-height on the shared face hang on the second root's edges (linear, 1/2 and 1/2)."""
    t = ba.KdTree(np.array([[0, 0, 0, 3, 3, 3], [8, 0, 0, 3, 3, 3]]), dims=(16, 8, 8))
    t.split(np.array([[False, True, False], [False, False, False]]))
    t.build()
    assert len(t.leaves) == 3
    assert t.probe_count == 12 + 2  # the 12 root corners + the 2 mid-height corners on x = 0
    assert t.hanging_count == 2
    for u in np.nonzero(t.host >= 0)[0]:
        x, y, z = t.node_lattice[u]
        assert (x, y) == (8, 4) and z in (0, 8)
        w = t.node_w[t.node_ptr[u]:t.node_ptr[u + 1]]
        np.testing.assert_allclose(np.sort(w), [0.5, 0.5])


def test_floor_refines_along_y_only():
    t, _, renders, _ = ba.kd_refine(ba.field_floor, 0.05)
    lv = t.leaves[:, 3:]
    assert (lv[:, 0] == ba.ROOT_LEVEL).all() and (lv[:, 2] == ba.ROOT_LEVEL).all()
    assert lv[:, 1].min() == 0  # Min Cell Size at the floor
    assert renders < 1000


def test_centre_test_finds_a_spot_the_edges_miss():
    """A compact bright spot at a root cell's centre: the edge midpoints alone never see it."""
    edges, _, _, _ = ba.kd_refine(ba.field_spot, 0.05, centre=False)
    full, _, _, _ = ba.kd_refine(ba.field_spot, 0.05, centre=True)
    assert len(edges.leaves) == len(ba.KdTree.roots().leaves)
    assert len(full.leaves) > 2 * len(edges.leaves)
