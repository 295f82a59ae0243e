"""Interpolation on probe positions, error-driven refinement and .shprobe version 3 through the Python
API (issue 12). Expected values are closed forms: a field linear in position is reproduced exactly by
both interpolations; a shadow plane refines exactly the leaves it crosses; the v3 header bytes are
checked against docs/shprobe-format.md's table with struct, independently of the C writer."""
import struct

import numpy as np
import pytest

from schnee_probes import native


def _tree():
    """2 x 1 x 2 roots of 4 min cells (0.5 m) at (1, 2, 3); root 0 split: hanging nodes."""
    t = native.CornerOctree.uniform((1.0, 2.0, 3.0), 0.5, 2, (2, 1, 2))
    flags = np.zeros(t.leaf_count, bool)
    flags[0] = True
    assert t.split(flags) == 1
    t.finalize()
    return t


def _linear(p):
    return 0.5 + 1.5 * p[..., 0] - 0.25 * p[..., 1] + 0.75 * p[..., 2]


def test_tree_counts_and_hanging_rules():
    t = _tree()
    info = t.info()
    # Lattice 8 x 4 x 8; leaves: 3 roots + 8 children = 11. Corner points: the root layer's
    # 3 x 2 x 3 = 18 plus the split root's 3 x 3 x 3 = 27 minus its 8 corners (already counted) = 37.
    assert info["leaves"].shape == (11, 4)
    assert t.probe_count + info["hanging_count"] == 37
    # Every hanging node is a face centre (4 sources of 1/4) or an edge midpoint (2 of 1/2).
    w = info["hanging_weights"]
    used = (w > 0).sum(axis=1)
    assert set(used.tolist()) <= {2, 4}
    np.testing.assert_array_equal(w.sum(axis=1), 1.0)
    np.testing.assert_array_equal(np.sort(w[used == 4], axis=1), 0.25)


@pytest.mark.parametrize("kind", ["octree", "tetra"])
def test_linear_field_exact_and_weights(kind):
    t = _tree()
    pos = t.positions()
    interp = t if kind == "octree" else native.Tetrahedra.create(pos)
    rng = np.random.default_rng(1)
    pts = np.array([1.0, 2.0, 3.0]) + rng.random((2000, 3)) * [4.0, 2.0, 4.0]
    probes, weights = interp.query(pts)
    assert (probes[:, 0] >= 0).all()
    assert (weights >= 0).all()
    np.testing.assert_allclose(weights.sum(axis=1), 1.0, atol=1e-12)
    assert ((weights > 0).sum(axis=1) <= (16 if kind == "octree" else 4)).all()
    got = interp.interpolate(pts, _linear(pos))
    np.testing.assert_allclose(got, _linear(pts), atol=1e-11)
    # Outside: no probe.
    p2, w2 = interp.query(np.array([[0.0, 0.0, 0.0]]))
    assert p2[0, 0] == -1 and w2[0].sum() == 0.0


@pytest.mark.parametrize("kind", ["octree", "tetra"])
def test_moving_object_is_continuous(kind):
    """An object's centre moved in 1e-4 m steps across the coarse/fine border (x = 3 m) and across
    cell borders: its interpolated value (random probe values in [0, 1]) changes by at most the
    interpolant's Lipschitz bound times the step; a jump would be of the order of the spread (~0.3)."""
    t = _tree()
    interp = t if kind == "octree" else native.Tetrahedra.create(t.positions())
    vals = np.random.default_rng(2).random(t.probe_count)
    xs = np.arange(2.2, 3.8, 1e-4)
    pts = np.stack([xs, np.full_like(xs, 2.61), 3.4 + 0.3 * (xs - 2.2)], axis=1)
    v = interp.interpolate(pts, vals)
    steps = np.abs(np.diff(v))
    step = np.linalg.norm(pts[1] - pts[0])
    bound = np.sqrt(3.0) / 0.5 * step * 1.000001 if kind == "octree" else 20.0 * step
    assert steps.max() <= bound


def test_validity_drops_probe_and_renormalises():
    t = _tree()
    p = np.array([[1.3, 2.2, 3.1]])
    probes, weights = t.query(p)
    val = np.ones(t.probe_count, np.float32)
    val[probes[0, 0]] = 0.0
    p2, w2 = t.query(p, validity=val)
    assert probes[0, 0] not in p2[0]
    np.testing.assert_allclose(w2.sum(), 1.0, atol=1e-12)


def test_refinement_shadow_plane():
    """Passes of test points → decide → split on a jump at x + z = 5.13 (never on the lattice): only
    leaves whose corners lie on both sides split, and the last pass leaves them at Min Cell Size."""
    t = native.CornerOctree.uniform((0.0, 0.0, 0.0), 0.25, 3, (2, 1, 2))
    t.finalize()

    def field(p):
        lit = (p[:, 0] + p[:, 2] < 5.13).astype(float)
        c = np.zeros((len(p), 4, 3))
        c[:, 0, :] = 1.0 + 3.0 * lit[:, None]
        c[:, 1, :] = 2.0 * lit[:, None]
        return c

    for _ in range(5):
        info = t.info()
        leaves = info["leaves"]
        s = (1 << leaves[:, 3]).astype(float) * 0.25
        lo = leaves[:, 0] * 0.25 + leaves[:, 2] * 0.25
        crossed = (lo < 5.13) & (lo + 2 * s > 5.13)
        tests = t.refine_tests()
        split, err, thr = t.refine_decide(tests, field(info["positions"]), field(tests.positions), tolerance=0.01)
        np.testing.assert_array_equal(split, crossed & (leaves[:, 3] > 0))
        assert (err[~crossed] < 1e-12).all()
        if not split.any():
            break
        # Every test point of a split leaf is a probe of the finer tree (no bake wasted) — except a
        # face centre shared with an unsplit same-size neighbour, which hangs there.
        centres = tests.lattice[tests.leaf_tests[split, 0]]
        t.split(split)
        t.finalize()
        lattice = {tuple(x) for x in t.probe_lattice().tolist()}
        assert all(tuple(c) in lattice for c in centres.tolist())
    leaves = t.info()["leaves"]
    s = (1 << leaves[:, 3]).astype(float) * 0.25
    lo = leaves[:, 0] * 0.25 + leaves[:, 2] * 0.25
    crossed = (lo < 5.13) & (lo + 2 * s > 5.13)
    assert (leaves[crossed, 3] == 0).all()


def test_refinement_linear_field_refines_nothing():
    t = native.CornerOctree.uniform((0.0, 0.0, 0.0), 0.25, 3, (2, 1, 2))
    t.finalize()
    tests = t.refine_tests()

    def field(p):
        return np.repeat((2.0 + 0.3 * p[:, 0] - 0.1 * p[:, 1] + 0.2 * p[:, 2])[:, None, None], 3, axis=2)

    split, err, _ = t.refine_decide(tests, field(t.positions()), field(tests.positions), tolerance=1e-9)
    assert not split.any()
    assert err.max() < 1e-12


def test_v3_write_read_octree_and_tetra(tmp_path):
    t = _tree()
    pos = t.positions()
    coeffs = np.stack([_linear(pos)[:, None] * (k + 1) + np.arange(3) for k in range(9)], axis=1)
    path = tmp_path / "oct.shprobe"
    assert native.write_shprobe_v3(str(path), t, coeffs, storage="float16") == t.probe_count
    data = path.read_bytes()
    info = t.info()
    P, N, H = t.probe_count, len(info["leaves"]), info["hanging_count"]
    # docs/shprobe-format.md, version 3: header 128 bytes; records 9 x 8 + 16 (binary16);
    # positions 16 per probe; leaves 48; hanging rules 32.
    assert len(data) == 128 + P * (9 * 8 + 16) + 16 * P + 48 * N + 32 * H
    magic, version, count, band, flags = struct.unpack_from("<5I", data, 0)
    assert (magic, version, count, band, flags) == (0x52485053, 3, P, 2, 1)
    assert struct.unpack_from("<3I", data, 20) == (8, 4, 8)
    assert struct.unpack_from("<3f", data, 32) == (1.0, 2.0, 3.0)
    assert struct.unpack_from("<5I", data, 92) == (0, 1, 1, N, H)
    # Probe 0, coefficient 0 red as binary16 at offset 128.
    assert np.frombuffer(data[128:130], "<f2")[0] == np.float16(coeffs[0, 0, 0])
    f = native.read_shprobe(str(path))
    assert (f.version, f.structure, f.storage, f.representation) == (3, "octree", "float16", "sh")
    assert f.grid is None
    np.testing.assert_allclose(f.coeffs, coeffs, rtol=2 ** -11)
    np.testing.assert_array_equal(f.leaves, info["leaves"])
    np.testing.assert_array_equal(f.leaf_corners, info["leaf_corners"])
    # The file's interpolation is the tree's.
    it = native.interpolation_from_file(str(path))
    pts = np.array([[1.2, 2.3, 3.4], [4.9, 3.9, 6.9], [2.9, 2.1, 4.99]])
    np.testing.assert_allclose(it.interpolate(pts, pos), t.interpolate(pts, pos), atol=1e-6)
    np.testing.assert_allclose(it.interpolate(pts, pos), pts, atol=1e-6)  # positions are linear

    tet = native.Tetrahedra.create(pos)
    cube = np.arange(P * 18, dtype=np.float32).reshape(P, 6, 3) - 5.0
    path2 = tmp_path / "tet.shprobe"
    native.write_shprobe_v3(str(path2), tet, cube, representation="ambientCube")
    g = native.read_shprobe(str(path2))
    assert (g.structure, g.representation, g.coeffs.shape) == ("tetrahedra", "ambientCube", (P, 6, 3))
    np.testing.assert_array_equal(g.coeffs, cube)
    np.testing.assert_array_equal(g.tets, tet.info()["tets"])
    assert g.grid_dims == (0, 0, 0)


def test_v3_dense_v1_resample(tmp_path):
    t = _tree()
    pos = t.positions()
    coeffs = np.repeat(_linear(pos)[:, None, None], 9, axis=1).repeat(3, axis=2)
    path = tmp_path / "oct.shprobe"
    native.write_shprobe_v3(str(path), t, coeffs)
    d = native.resample_shprobe_dense(str(path))
    assert d.grid_dims == (8, 4, 8) and d.probe_count == 256
    # Cell centres: the linear field there (float32 storage).
    i = np.arange(256)
    centres = np.stack([1.0 + 0.5 * (i % 8 + 0.5), 2.0 + 0.5 * ((i // 8) % 4 + 0.5), 3.0 + 0.5 * (i // 32 + 0.5)], 1)
    np.testing.assert_allclose(d.coeffs[d.grid, 0, 0], _linear(centres), atol=2e-6)
    out = tmp_path / "dense.shprobe"
    assert native.write_shprobe(str(out), d.coeffs, d.grid, d.grid_dims, d.grid_origin, d.grid_spacing,
                                version=1) == 1
    assert len(out.read_bytes()) == 48 + 160 * 256 + 4 * 256


def test_errors():
    with pytest.raises(native.SchneeError, match="cannot be tetrahedralised") as e:
        native.Tetrahedra.create(np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0], [1, 1, 0], [2, 2, 0.0]]))
    assert e.value.code == "invalid argument"
    with pytest.raises(native.SchneeError, match="overlaps"):
        native.CornerOctree.from_leaves((0, 0, 0), 1.0, (4, 4, 4), [[0, 0, 0, 1], [1, 1, 1, 0]])
    t = _tree()
    with pytest.raises(ValueError, match="flags must have shape"):
        t.split(np.zeros(3, bool))
    # A validity array of the wrong length is refused before the core reads it.
    with pytest.raises(ValueError, match="validity has 3 items, expected"):
        native.Tetrahedra.create(t.positions()).query([[2.0, 2.5, 3.5]], validity=np.ones(3))
    with pytest.raises(native.SchneeError, match="unknown version 9"):
        native.read_shprobe_bytes(struct.pack("<II", 0x52485053, 9) + bytes(200))


def _box(lo, hi):
    v = np.array([[hi[0] if i & 1 else lo[0], hi[1] if i & 2 else lo[1], hi[2] if i & 4 else lo[2]]
                  for i in range(8)], float)
    faces = [(0, 4, 6, 2), (1, 3, 7, 5), (0, 1, 5, 4), (2, 6, 7, 3), (0, 2, 3, 1), (4, 5, 7, 6)]
    t = np.array([tri for f in faces for tri in ((f[0], f[1], f[2]), (f[0], f[2], f[3]))], np.uint32)
    return v, t


def test_classify_points_and_leaf_boxes():
    """Room volume 10 x 4 x 10 m with a solid 2 m block (outward normals) at its centre: points in the
    air see front faces only (ratio 0), points in the block back faces only (ratio 1); leaf boxes of
    a corner octree over the room's bounding box are inside / crossed / outside by construction."""
    room = ("room",) + _box((0, 0, 0), (10, 4, 10))
    block = ("block",) + _box((4, 0, 4), (6, 2, 6))
    pts = np.array([[1, 1, 1], [5, 1, 5], [11, 1, 1], [5.5, 1.5, 4.5]], float)
    boxes = np.array([[5, 2, 5, 1], [10, 2, 5, 1], [20, 2, 20, 1]], float)
    inside, ratio, cls = native.classify_placement([room], [block], pts, boxes, threads=2)
    np.testing.assert_array_equal(inside, [True, True, False, True])
    np.testing.assert_array_equal(ratio[[0, 1, 3]], [0.0, 1.0, 1.0])
    np.testing.assert_array_equal(cls, [1, 2, 0])
    # Drop the corner octree's leaves outside the volume, give solid probes validity 0.
    t = native.CornerOctree.uniform((-2.0, 0.0, -2.0), 0.5, 2, (7, 2, 7))  # 14 x 4 x 14 m
    lv = t.info()["leaves"]
    half = 0.5 * (1 << lv[:, 3]) * 0.5
    centres = np.array([-2.0, 0.0, -2.0]) + lv[:, :3] * 0.5 + half[:, None]
    _, _, c = native.classify_placement([room], [block], boxes=np.column_stack([centres, half]))
    t.drop(c == 0)
    t.finalize()
    # 10 / 2 m leaves: the room holds 5 x 2 x 5 = 50 leaves; the rest of the 14 m box is outside (the
    # room's faces lie on leaf faces, which do not count as crossing).
    assert t.leaf_count == 50
    _, r2, _ = native.classify_placement([room], [block], t.positions())
    solid = r2 > 0.25
    pos = t.positions()
    strictly_in_block = ((pos > [4, 0, 4]) & (pos < [6, 2, 6])).all(axis=1)
    np.testing.assert_array_equal(solid[strictly_in_block], True)
    assert solid.sum() >= strictly_in_block.sum()
