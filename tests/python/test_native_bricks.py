"""Probe bricks in the core (native.Bricks, native/include/schnee/pb_bricks.h, docs/probe-bricks.md) against
two independent references: the file's own interpolation (the C query, ``native.interpolation_from_file``)
on random octrees and kd trees and on written version 3 and version 4 files, and the numpy prototype
``bench/bench_bricks.py`` (the same bricks, levels, indirection and texels, computed in numpy)."""
import os
import sys

import numpy as np
import pytest

from schnee_probes import native

ROOT = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))
sys.path.insert(0, os.path.join(ROOT, "bench"))
bb = pytest.importorskip("bench_bricks")  # the prototype (needs the native module too)


def _tree(seed, kd=False):
    return bb.synthetic_tree(seed, kd=kd, passes=3, root_dims=(3, 2, 3))


def _points(tree, n, rng, margin=0.0):
    """n points uniform in the lattice's box (grown by ``margin`` min cells on every side)."""
    info = tree.info()
    h, o, dims = info["min_cell"], np.array(info["origin"]), np.array(info["dims"], dtype=np.float64)
    return o + (-margin + rng.random((n, 3)) * (dims + 2 * margin)) * h


def _compare(bricks, ref_tree, values, validity, pts):
    """Max |bricks - file| / max |file| and the count of points where one has a value and the other not."""
    ref = ref_tree.interpolate(pts, values, validity)
    got, has = bricks.sample(pts)
    ref_has = np.isfinite(ref).all(axis=(1, 2))
    both = has & ref_has
    err = np.abs(got[both] - ref[both]).max() / np.abs(ref[both]).max()
    return float(err), int((has != ref_has).sum()), int(both.sum())


@pytest.mark.parametrize("kd", [False, True])
def test_random_trees_equal_the_query(kd):
    rng = np.random.default_rng(3 + kd)
    tree = _tree(40 + kd, kd)
    P = tree.probe_count
    coeffs = bb.random_sh(P, 2, rng)
    validity = np.where(rng.random(P) < 0.2, 0.0, 0.3 + rng.random(P)).astype(np.float32)
    scale = (0.5 + rng.random(P)).astype(np.float32)
    bricks = native.Bricks.build(tree, coeffs, validity, scale)
    assert len(bricks.info()["level_counts"]) > 1  # bricks of several levels
    pts = _points(tree, 20000, rng)
    err, mismatch, n = _compare(bricks, tree, coeffs * scale.astype(np.float64)[:, None, None], validity, pts)
    assert n > 15000 and mismatch == 0
    assert err < 1e-12, err
    # A linear field against its closed form (not the query): trilinear bricks hold it exactly.
    lin = native.Bricks.build(tree, bb.linear_sh(tree.positions()))
    got, has = lin.sample(pts)
    assert has.all()
    expected = bb.linear_sh(pts)
    assert np.abs(got - expected).max() / np.abs(expected).max() < 1e-12


@pytest.mark.parametrize("kd", [False, True])
def test_written_files_v3_v4(tmp_path, kd):
    """A written file read back: the C bricks of its tree and float32 coefficients equal the file's
    interpolation (validity, scale), also within 0.01 of the outer faces of dropped leaves."""
    rng = np.random.default_rng(7 + kd)
    tree = _tree(50 + kd, kd)
    flags = np.zeros(tree.leaf_count, bool)
    flags[::4] = True
    tree.drop(flags)
    tree.finalize()
    P = tree.probe_count
    path = str(tmp_path / "t.shprobe")
    native.write_shprobe_v3(path, tree, bb.random_sh(P, 2, rng).astype(np.float32),
                            probe_scale=(0.5 + rng.random(P)).astype(np.float32),
                            validity=np.where(rng.random(P) < 0.15, 0.0, 1.0).astype(np.float32))
    f = native.read_shprobe(path)
    assert (f.version, f.structure) == ((4, "kdtree") if kd else (3, "octree"))
    t = native.interpolation_from_file(path)
    bricks = native.Bricks.build(t, f.coeffs, f.validity, f.probe_scale)
    values = f.coeffs.astype(np.float64) * f.probe_scale.astype(np.float64)[:, None, None]
    err, mismatch, n = _compare(bricks, t, values, f.validity, _points(t, 20000, rng))
    assert n > 10000 and mismatch == 0 and err < 1e-12, (err, mismatch, n)
    # Just above leaves' max faces (in cells no leaf holds): the face margin as the CPU's.
    field = bb.Field(path)
    lo, hi = field.lo, field.lo + (1 << field.levels)
    li = rng.integers(0, len(lo), 20000)
    a = rng.integers(0, 3, len(li))
    u = lo[li] + rng.random((len(li), 3)) * (hi[li] - lo[li])
    u[np.arange(len(li)), a] = hi[li, a] + rng.choice([0.005, 0.02], len(li))
    inside = np.all(u < field.dims, axis=1)
    err, mismatch, n = _compare(bricks, t, values, f.validity, field.world(u[inside]))
    assert n > 1000 and mismatch == 0 and err < 1e-12, (err, mismatch, n)


@pytest.mark.parametrize("kd", [False, True])
def test_same_bricks_as_the_prototype(tmp_path, kd):
    """The numpy prototype and the C build the same bricks (count, level and region of each, the
    indirection's bricks and occupancy) with the same texels, and sample the same values."""
    rng = np.random.default_rng(11 + kd)
    tree = _tree(60 + kd, kd)
    P = tree.probe_count
    path = str(tmp_path / "p.shprobe")
    field = bb.write_tree(tree, path, bb.random_sh(P, 2, rng), (rng.random(P) > 0.15).astype(np.float32))
    proto = bb.Bricks(field, 5)
    t = native.interpolation_from_file(path)
    f = field.file
    bricks = native.Bricks.build(t, f.coeffs, f.validity, f.probe_scale)
    info = bricks.info()
    assert info["brick_count"] == len(proto.level)
    key_c = {tuple(r): i for i, r in enumerate(info["regions"].tolist())}
    order = np.array([key_c[tuple(r) + (L,)] for r, L in zip(proto.rmin.tolist(), proto.level.tolist())])
    # Indirection: the same brick per level-0 region (prototype index -> C index), the same occupancy.
    ind = info["indirection"].transpose(2, 1, 0, 3)  # [x, y, z, word]
    pi = proto.indirection
    c_brick = np.where(ind[..., 0] == 0xFFFFFFFF, -1, (ind[..., 0] & 0x7FFFFFF).astype(np.int64))
    np.testing.assert_array_equal(c_brick, np.where(pi >= 0, order[np.maximum(pi, 0)], -1))
    np.testing.assert_array_equal(ind[..., 0] >> 27, np.where(pi >= 0, proto.level[np.maximum(pi, 0)], 31))
    bits = (ind[..., 1].astype(np.uint64) | ind[..., 2].astype(np.uint64) << np.uint64(32))
    occ = np.zeros(tuple(4 * np.array(bits.shape)), bool)
    for b in range(64):
        occ[b % 4::4, b // 4 % 4::4, b // 16::4] = (bits >> np.uint64(b)) & np.uint64(1)
    np.testing.assert_array_equal(occ[:field.dims[0], :field.dims[1], :field.dims[2]], proto.occupied)
    # Texels: the C's [brick, z, y, x, channel] against the prototype's N [brick, x, y, z, coeff, rgb], D.
    tex = info["texels"][order].transpose(0, 3, 2, 1, 4)
    C = field.C
    N = np.concatenate([tex[..., 0:3, None].swapaxes(-1, -2), tex[..., 4:].reshape(tex.shape[:4] + (C - 1, 3))],
                       axis=-2)
    scale = np.abs(proto.N).max()
    assert np.abs(N - proto.N).max() / scale < 1e-12
    assert np.abs(tex[..., 3] - proto.D).max() < 1e-12
    # The same samples, brick and brick-local coordinate.
    u, _ = field.random_inside(5000, rng)
    got, _, has, brick, x = bricks.sample_raw(field.world(u))
    pv, pd, pb = proto.sample(u)
    ok = pb >= 0
    np.testing.assert_array_equal(brick[ok], order[pb[ok]])
    np.testing.assert_array_equal(has, np.isfinite(pv).all(axis=(1, 2)))
    assert np.abs(got[has] - pv[has]).max() / np.abs(pv[has]).max() < 1e-12
    assert np.abs(x[ok] - proto.local(proto.lookup(u)[1][ok], pb[ok])).max() < 1e-12


def test_pool_sizes_and_hostile_input():
    rng = np.random.default_rng(5)
    tree = _tree(70)
    P = tree.probe_count
    bricks = native.Bricks.build(tree, bb.random_sh(P, 2, rng))
    info = bricks.info()
    assert (info["channels"], info["groups"], info["bytes_per_texel_f16"]) == (28, 7, 56)
    pool = bricks.pool(half=True)
    assert pool.shape == (7,) + tuple(reversed(info["pool_texels"])) + (4,) and pool.dtype == np.float16
    # Brick 0's texels at the pool's origin: channel 3 (D) is group 0's alpha.
    np.testing.assert_allclose(pool[0, :5, :5, :5, 3], info["texels"][0, ..., 3], rtol=2.0 ** -11, atol=2.0 ** -25)
    assert info["texel_count"] > P  # border texels are stored twice, coarse leaves resampled finer
    assert bricks.bytes_per_probe(P) > 56 * info["texel_count"] / P
    with pytest.raises(ValueError, match="coeffs must have shape"):
        native.Bricks.build(tree, np.zeros((P + 1, 9, 3)))
    with pytest.raises(ValueError, match="coefficients"):
        native.Bricks.build(tree, np.zeros((P, 5, 3)))
    bad = bb.random_sh(P, 2, rng)
    bad[3, 1, 2] = np.nan
    with pytest.raises(native.SchneeError, match="probe 3"):
        native.Bricks.build(tree, bad)
    with pytest.raises(native.SchneeError, match="MiB"):
        native.Bricks.build(tree, bb.random_sh(P, 2, rng), max_bytes=50000)
    big = native.Bricks.build(tree, bb.random_sh(P, 2, rng) * 1e5)
    with pytest.raises(native.SchneeError, match="float32"):
        big.pool(half=True)
    assert big.pool(half=False).dtype == np.float32
    t2 = native.CornerOctree.uniform((0, 0, 0), 1.0, 1, (1, 1, 1))
    with pytest.raises(ValueError, match="not finalized"):
        native.Bricks.build(t2, np.zeros((0, 9, 3)))
