"""The probe-brick prototype of bench/bench_bricks.py (issue 30 item 1, docs/probe-bricks.md): the corner
octree's field resampled into bricks of 5^3 texels at the level of the finest leaf each overlaps, an
indirection grid, and a sampler that filters as a 3D texture does. Inside a leaf the field is trilinear,
so the bricks must reproduce it exactly (a linear field against its closed form), agree on every border
between bricks of different levels, and carry the validity rule as numerator / denominator."""
import os
import sys
import tempfile

import numpy as np
import pytest

ROOT = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))
sys.path.insert(0, os.path.join(ROOT, "bench"))
bb = pytest.importorskip("bench_bricks")  # needs the native module (addon/schnee_probes)


@pytest.fixture(scope="module")
def tmp():
    with tempfile.TemporaryDirectory() as d:
        yield d


def _tree(seed, kd=False):
    return bb.synthetic_tree(seed, kd=kd, passes=3, root_dims=(2, 2, 2))


@pytest.mark.parametrize("kd", [False, True])
def test_linear_field_is_reproduced_exactly(tmp, kd):
    tree = _tree(11, kd)
    field = bb.write_tree(tree, os.path.join(tmp, f"lin{kd}.shprobe"), bb.linear_sh(tree.positions()))
    bricks = bb.Bricks(field, 5)
    assert len(set(bricks.level.tolist())) > 1  # bricks of several levels
    rng = np.random.default_rng(1)
    u, _ = field.random_inside(3000, rng)
    expected = bb.linear_sh(field.world(u))  # closed form, not the file's interpolation
    scale = np.abs(expected).max()
    got64, _, _ = bricks.sample(u, "exact", np.float64)
    got16, _, _ = bricks.sample(u, "exact", np.float16)
    hw16, _, _ = bricks.sample(u, "hw", np.float16)
    # The file holds float32 coefficients: 2^-24 relative per probe value.
    assert np.abs(got64 - expected).max() / scale < 2e-7
    # fp16 texels: round to nearest, 2^-11 relative of each texel (values are <= scale).
    assert np.abs(got16 - expected).max() / scale < 2.0 ** -11 + 2e-7
    # 8-bit sub-texel weights: a position error of <= 2^L h / 512 per axis (hw_linear_bound), plus fp16.
    assert np.abs(hw16 - expected).max() / scale < bb.hw_linear_bound(bricks) + 2.0 ** -11 + 2e-7


@pytest.mark.parametrize("kd", [False, True])
def test_random_field_equals_the_files_interpolation_inside_leaves(tmp, kd):
    """A linear field is reproduced by any trilinear resampling; random probe values only where every
    brick cell lies inside one leaf (bricks at the finest level they overlap). Reference: the C core."""
    tree = _tree(15, kd)
    rng = np.random.default_rng(5)
    field = bb.write_tree(tree, os.path.join(tmp, f"r{kd}.shprobe"), bb.random_sh(tree.probe_count, 2, rng))
    bricks = bb.Bricks(field, 5)
    u, _ = field.random_inside(4000, rng)
    ref = field.interpolate(u)
    got, _, _ = bricks.sample(u)
    assert np.abs(got - ref).max() / np.abs(ref).max() < 1e-12
    # Where the bricks are at level 0, a level-1 lattice would not hold the file's field (the level
    # rule matters): trilinear between the file's values at the level-1 cell corners differs.
    u2 = u[bricks.level[bricks.lookup(u)[0]] == 0]
    wrong = field.interpolate(u2)
    cells = (u2 // 2) * 2  # the level-1 cells: trilinear between their corners' file values
    t = (u2 - cells) / 2
    w = np.ones((len(u2), 8))
    for a in range(3):
        w *= np.where(bb.CORNER_BITS[None, :, a] == 1, t[:, None, a], 1 - t[:, None, a])
    corners = field.interpolate((cells[:, None, :] + 2 * bb.CORNER_BITS[None]).reshape(-1, 3)).reshape(
        len(u2), 8, 9, 3)
    ok = np.isfinite(corners).all(axis=(1, 2, 3))
    resampled = np.einsum("nk,nkcd->ncd", w[ok], corners[ok])
    assert np.abs(resampled - wrong[ok]).max() > 1e-3


@pytest.mark.parametrize("B", [5, 4])
def test_bricks_agree_across_coarse_fine_borders(tmp, B):
    tree = _tree(12)
    rng = np.random.default_rng(2)
    field = bb.write_tree(tree, os.path.join(tmp, f"rnd{B}.shprobe"), bb.random_sh(tree.probe_count, 2, rng))
    bricks = bb.Bricks(field, B)
    s = bb.seams(bricks, 2000, rng)
    assert s["different_levels"] > 50
    # The same face point through the brick on either side: equal to rounding (random values in [-0.3, 2]).
    assert s["exact-float64"]["different_levels_max"] < 1e-12
    assert s["exact-float64"]["same_level_max"] < 1e-12
    # and the bricks equal the file's own field there (the file is C0: its jump at +-1e-7 is tiny)
    assert s["file_jump_at_1e-7_max"] < 1e-4


def test_validity_numerator_over_denominator_is_the_files_rule(tmp):
    tree = _tree(13)
    rng = np.random.default_rng(3)
    n = tree.probe_count
    valid = (rng.random(n) > 0.3).astype(np.float32)
    field = bb.write_tree(tree, os.path.join(tmp, "val.shprobe"), bb.random_sh(n, 2, rng), valid)
    assert (field.valid == 0).sum() > 0.2 * n
    bricks = bb.Bricks(field, 5)
    u, _ = field.random_inside(4000, rng)
    ref = field.interpolate(u)  # the C core: validity-0 probes dropped, renormalised
    got, d, _ = bricks.sample(u)
    none_ref = ~np.isfinite(ref).all(axis=(1, 2))
    none_got = ~np.isfinite(got).all(axis=(1, 2))
    assert np.array_equal(none_ref, none_got)
    assert np.abs(got[~none_ref] - ref[~none_ref]).max() / np.abs(ref[~none_ref]).max() < 1e-12
    # D is the valid weight: in [0, 1], below 1 exactly where an invalid probe has weight
    assert (d >= -1e-15).all() and (d <= 1 + 1e-12).all() and (d < 1 - 1e-9).sum() > 100


def test_face_margin_as_the_cpu(tmp):
    """locate_point_cell's margin: within 0.01 above a leaf's max face in an empty cell, the CPU gives the
    face's value; beyond it none. The sampler (occupancy bits, the cell below, clamped onto the face)
    gives the same."""
    tree = _tree(14)
    flags = np.zeros(tree.leaf_count, dtype=bool)
    flags[::3] = True
    tree.drop(flags)
    tree.finalize()
    rng = np.random.default_rng(4)
    field = bb.write_tree(tree, os.path.join(tmp, "drop.shprobe"), bb.random_sh(tree.probe_count, 2, rng))
    out = bb.outer_faces(field, bb.Bricks(field, 5), 1000, rng)
    m, s = out["margin 0-0.01"], out["shell 0.01-1"]
    assert m["points"] > 100 and m["cpu_value"] == m["bricks_value"] == m["points"]
    assert m["both_max_rel"] < 1e-12
    assert s["points"] > 100 and s["cpu_value"] == s["bricks_value"]


def test_wall_stops_light_in_min_cell_leaves():
    """A wall through Min Cell Size leaves (probes 5 on one side, 0.05 on the other): with the brick
    cell's visibility table and visibility-resampled texels no point on the dark side gets more than the
    dark side's irradiance (test_engine's wall rooms: 0.05 per pixel); without them it leaks."""
    res = bb.wall_experiment(3, 1000, 5, refine_wall=True)
    for name in ("wall face (n = +x)", "floor (n = +y)"):
        row = res[name]
        assert row["bricks plain"]["max"] > 10  # the plain trilinear field leaks
        for k in ("today's shader rule", "bricks 8 taps, visibility texels", "bricks 1 tap, visibility texels"):
            assert row[k]["max"] < 1.0 + 1e-6, (name, k, row[k])
