"""Per-axis refinement through the Python API (addon/schnee_probes/refine_axes.py over
pb_refine_tests_create_axes / pb_refine_decide_axes; docs/aniso-refinement.md "Tests and the split
rule"). Expected values are closed forms: the test points of a cube written out by hand, the trilinear's
error at an edge midpoint of a quadratic (the mean of the ends against the middle), a linear field
reproduced exactly, and the noise threshold sqrt(tol² + k²σ²) with σ² from the corner weights."""
import numpy as np
import pytest

from schnee_probes import native, refine_axes

ORIGIN = (1.0, 2.0, 3.0)


def _cube():
    """One cube of 4 min cells of 0.5 m (2 m) at ORIGIN."""
    t = native.CornerOctree.uniform(ORIGIN, 0.5, 2, (1, 1, 1))
    t.finalize()
    return t


def _sh(f, p):
    """Band-1 radiance SH whose every coefficient and channel is f(p) times a fixed pattern, so the
    relative irradiance error of an interpolation is |f_interp - f| / |f| exactly."""
    pattern = 1.0 + 0.05 * np.arange(12.0).reshape(4, 3)
    return f(np.asarray(p, dtype=np.float64))[:, None, None] * pattern


def _decide(tree, f, **kw):
    tests = refine_axes.tests_axes(tree)
    return refine_axes.decide_axes(tree, tests, _sh(f, tree.positions()), _sh(f, tests.positions), **kw)


def test_cube_test_points_by_hand():
    tree = _cube()
    tests = refine_axes.tests_axes(tree)
    assert tests.leaf_tests.shape == (1, 14)
    assert len(tests.positions) == 13 and (tests.probe == -1).all()
    want = {0: (2, 0, 0), 3: (2, 4, 4), 5: (4, 2, 0), 6: (0, 2, 4), 9: (4, 0, 2), 10: (0, 4, 2), 12: (2, 2, 2)}
    for col, lat in want.items():
        ti = tests.leaf_tests[0, col]
        assert tuple(tests.lattice[ti]) == lat
        np.testing.assert_allclose(tests.positions[ti], np.array(ORIGIN) + 0.5 * np.array(lat), atol=1e-15)
    assert tests.leaf_tests[0, 13] == -1
    # Two cubes along x share the 2 y edges and 2 z edges of their common face: 26 - 4 points; only
    # the second active: its 13.
    two = native.CornerOctree.uniform(ORIGIN, 0.5, 2, (2, 1, 1))
    two.finalize()
    assert len(refine_axes.tests_axes(two).positions) == 22
    only = refine_axes.tests_axes(two, active=[False, True])
    assert len(only.positions) == 13 and (only.leaf_tests[0] == -1).all()


def test_closed_form_fields_split_their_axes():
    tree = _cube()
    # f = 1 + ((y - 2) / 2)^2: at the y midpoint 1.25 against the ends' mean 1.5: error 0.25 / 1.25.
    axes, err, thr = _decide(tree, lambda p: 1.0 + ((p[:, 1] - 2.0) / 2.0) ** 2, tolerance=0.05)
    assert axes.dtype == np.uint8 and axes.tolist() == [2]
    assert err[0] == pytest.approx(0.2, abs=1e-12) and thr[0] == pytest.approx(0.05, abs=1e-15)
    axes, _, _ = _decide(tree, lambda p: 1.0 + ((p[:, 1] - 2.0) / 2.0) ** 2, tolerance=0.21)
    assert axes.tolist() == [0]
    # Quadratic in x and z: edges along x and z fail, y edges are exact.
    xz = lambda p: 1.0 + 0.6 * ((p[:, 0] - 1.0) / 2.0) ** 2 + 0.3 * ((p[:, 2] - 3.0) / 2.0) ** 2  # noqa: E731
    assert _decide(tree, xz, tolerance=0.05)[0].tolist() == [5]
    # Linear: trilinear is exact, nothing splits even at a tolerance of 1e-9.
    axes, err, _ = _decide(tree, lambda p: 2.0 + 0.3 * p[:, 0] - 0.7 * p[:, 1] + 0.5 * p[:, 2], tolerance=1e-9)
    assert axes.tolist() == [0] and err[0] < 1e-12


def test_noise_within_k_sigma_does_not_split():
    # The y quadratic's error 0.2 at tolerance 0.1 with noise 0.1 on every probe and test: the centre
    # (8 corners of weight 1/8) has sigma^2 = n^2 (1 + 1/8), threshold sqrt(0.01 + 4 * 0.01125) = 0.2345,
    # an edge midpoint (2 corners of 1/2) sqrt(0.01 + 4 * 0.015) = 0.2646: nothing splits, the worst
    # margin is the centre's. Without the noise estimate it splits along y.
    tree = _cube()
    tests = refine_axes.tests_axes(tree)
    f = lambda p: 1.0 + ((p[:, 1] - 2.0) / 2.0) ** 2  # noqa: E731
    pc, tc = _sh(f, tree.positions()), _sh(f, tests.positions)
    noise = dict(probe_noise=np.full(8, 0.1), test_noise=np.full(13, 0.1))
    axes, err, thr = refine_axes.decide_axes(tree, tests, pc, tc, tolerance=0.1, noise_k=2.0, **noise)
    assert axes.tolist() == [0]
    assert err[0] == pytest.approx(0.2, abs=1e-12)
    assert thr[0] == pytest.approx(np.sqrt(0.01 + 4.0 * 0.01 * 9.0 / 8.0), abs=1e-7)  # noise passed as float32
    assert refine_axes.decide_axes(tree, tests, pc, tc, tolerance=0.1)[0].tolist() == [2]
    # Invalid tests are not compared: with every y edge and the centre invalid nothing fails.
    valid = np.ones(13, bool)
    valid[tests.leaf_tests[0, [4, 5, 6, 7, 12]]] = False
    axes, err, _ = refine_axes.decide_axes(tree, tests, pc, tc, tolerance=0.1, test_valid=valid)
    assert axes.tolist() == [0] and err[0] == 0.0


def test_octree_tests_refused():
    tree = _cube()
    tests = tree.refine_tests()  # the octree's 7 columns
    with pytest.raises(ValueError, match="leaf_tests"):
        refine_axes.decide_axes(tree, tests, np.zeros((8, 4, 3)), np.zeros((7, 4, 3)))


def test_box_trees():
    # A 4 x 1 x 4 slab of 0.5 m min cells (levels 2, 0, 2) at ORIGIN: x and z edge midpoints and the
    # centres of its faces across y, 10 points by hand; f quadratic along x splits x only (0.2 as on
    # the cube), f varying along its level-0 axis y nothing (every test point lies at y's ends).
    slab = native.CornerOctree.from_boxes(ORIGIN, 0.5, 2, (4, 1, 4), [[0, 0, 0, 2 | 0 << 8 | 2 << 16]])
    slab.finalize()
    tests = refine_axes.tests_axes(slab)
    want = {(2, 0, 0), (2, 1, 0), (2, 0, 4), (2, 1, 4), (0, 0, 2), (4, 0, 2), (0, 1, 2), (4, 1, 2), (2, 0, 2),
            (2, 1, 2)}
    assert {tuple(int(v) for v in p) for p in tests.lattice} == want and len(tests.lattice) == 10
    assert (tests.leaf_tests[0, 4:8] == -1).all()
    axes, err, _ = _decide(slab, lambda p: 1.0 + ((p[:, 0] - 1.0) / 2.0) ** 2, tolerance=0.05)
    assert axes.tolist() == [1] and err[0] == pytest.approx(0.2, abs=1e-12)
    axes, err, _ = _decide(slab, lambda p: 1.0 + 4.0 * (p[:, 1] - 2.0) ** 2, tolerance=1e-9)
    assert axes.tolist() == [0] and err[0] < 1e-12
    # The refinement step: the cube split along y gives two boxes (2, 1, 2); the y quadratic splits the
    # lower one again (0.0625 / 1.0625 at its middle) but not the upper (0.0625 / 1.5625 = 0.04).
    tree = _cube()
    assert tree.split_axes([2]) == 1
    tree.finalize()
    axes, err, _ = _decide(tree, lambda p: 1.0 + ((p[:, 1] - 2.0) / 2.0) ** 2, tolerance=0.05)
    lower = tree.info()["leaves"][:, 1] == 0
    assert axes.tolist() == np.where(lower, 2, 0).tolist()
    np.testing.assert_allclose(err, np.where(lower, 0.0625 / 1.0625, 0.04), atol=1e-12)
