"""The ambient cube through the Python module (native/python/mod_sh.c: ambient_cube_from_sh,
ambient_cube_irradiance) against an independent numpy least-squares fit, closed forms
(docs/ambient-cube.md §3) and a real HDRI; error codes and argument checks."""
import math

import numpy as np
import pytest

from conftest import requires_native

pytestmark = requires_native

STUDIO = "/usr/share/blender/datafiles/studiolights/world/interior.exr"
LEAST_SQUARES, AXIS_SAMPLES = 0, 1
AXES = np.array([[1, 0, 0], [-1, 0, 0], [0, 1, 0], [0, -1, 0], [0, 0, 1], [0, 0, -1]], dtype=np.float64)


@pytest.fixture(scope="module")
def raw():
    from schnee_probes import _schnee_native, native  # noqa: F401  (native registers SchneeError)
    return _schnee_native


def cube_from_sh(raw, coeffs, band, fit=LEAST_SQUARES):
    c = np.ascontiguousarray(coeffs, dtype=np.float64)
    return np.frombuffer(raw.ambient_cube_from_sh(c, band, fit), dtype=np.float64).reshape(-1, 6, 3)


def cube_irradiance(raw, cube, normals):
    out = raw.ambient_cube_irradiance(np.ascontiguousarray(cube, dtype=np.float64),
                                      np.ascontiguousarray(normals, dtype=np.float64))
    return np.frombuffer(out, dtype=np.float64).reshape(-1, 3)


def quadrature(n=96):
    """Per-octant Gauss-Legendre nodes and weights on the sphere (numpy's, not the C test's)."""
    t, w = np.polynomial.legendre.leggauss(n)
    z = np.concatenate([(t - 1) / 2, (t + 1) / 2])
    wz = np.concatenate([w / 2, w / 2])
    phi = np.concatenate([(t + 1 + 2 * q) * math.pi / 4 for q in range(4)])
    wp = np.concatenate([w * math.pi / 4] * 4)
    zz, pp = np.meshgrid(z, phi, indexing="ij")
    s = np.sqrt(1 - zz * zz)
    dirs = np.stack([s * np.cos(pp), s * np.sin(pp), zz], -1).reshape(-1, 3)
    return dirs, np.outer(wz, wp).reshape(-1)


def cube_basis(dirs):
    """(N, 6) basis b_{+-i}(n) = n_i^2 where +-n_i > 0, faces +X -X +Y -Y +Z -Z."""
    cols = []
    for i in range(3):
        cols += [np.where(dirs[:, i] > 0, dirs[:, i] ** 2, 0.0), np.where(dirs[:, i] < 0, dirs[:, i] ** 2, 0.0)]
    return np.stack(cols, 1)


def test_least_squares_fit_equals_numpy_normal_equations(raw):
    """The module's fit solves the normal equations G C = integral(b_j E), built here by numpy
    quadrature from native.irradiance at L = 4 (quadrature error ~1e-10: tolerance 1e-8)."""
    from schnee_probes import native
    rng = np.random.default_rng(3)
    coeffs = rng.uniform(-1, 1, size=(25, 3))
    coeffs[0] = 4.0
    dirs, w = quadrature()
    b = cube_basis(dirs)
    gram = (b * w[:, None]).T @ b
    want = np.linalg.solve(gram, (b * w[:, None]).T @ native.irradiance(coeffs, dirs))
    got = cube_from_sh(raw, coeffs, 4)[0]
    np.testing.assert_allclose(got, want, atol=1e-8)
    # Bands 3 and 4 drop out exactly (docs/ambient-cube.md §2).
    np.testing.assert_array_equal(got, cube_from_sh(raw, coeffs[:9], 2)[0])


def test_fit_is_optimal_on_a_real_hdri(raw):
    """interior.exr projected at L = 4: the cube's squared irradiance error over the sphere is
    minimal (any perturbation of one face colour raises it) and smaller than that of the axis
    samples; E_cube matches the numpy formula sum n_i^2 C."""
    from schnee_probes import native
    coeffs = native.project_file(STUDIO, 4, negative="allow")
    ls = cube_from_sh(raw, coeffs, 4)[0]
    ax = cube_from_sh(raw, coeffs, 4, AXIS_SAMPLES)[0]
    np.testing.assert_allclose(ax, native.irradiance(coeffs, AXES), rtol=1e-14)
    dirs, w = quadrature(64)
    e = native.irradiance(coeffs, dirs)
    b = cube_basis(dirs)

    def sq(cube):
        return float(np.sum(w[:, None] * (b @ cube - e) ** 2))
    base = sq(ls)
    assert base < sq(ax)
    for f in range(6):
        for delta in (-1e-3, 1e-3):
            bumped = ls.copy()
            bumped[f] += delta * np.abs(ls[f]).max()
            assert sq(bumped) > base
    np.testing.assert_allclose(cube_irradiance(raw, ls, dirs[::97]), b[::97] @ ls, rtol=1e-13, atol=1e-13)


def test_hemisphere_closed_form(raw):
    """Sky of radiance 1 over y > 0 (L_0 = 2 pi Y_0, L_1 = pi K_1): C = pi/2, 9 pi/8, -pi/8
    (least squares) and pi/2, pi, 0 (axis samples), exactly."""
    coeffs = np.zeros((9, 3))
    coeffs[0] = 2 * math.pi * 0.28209479177387814
    coeffs[1] = math.pi * 0.4886025119029199
    half = math.pi / 2
    np.testing.assert_allclose(cube_from_sh(raw, coeffs, 2)[0, :, 0],
                               [half, half, 9 * math.pi / 8, -math.pi / 8, half, half], atol=1e-13)
    np.testing.assert_allclose(cube_from_sh(raw, coeffs, 2, AXIS_SAMPLES)[0, :, 0],
                               [half, half, math.pi, 0, half, half], atol=1e-13)


def test_batch_equals_single_probes(raw):
    rng = np.random.default_rng(11)
    coeffs = rng.normal(size=(5, 9, 3))
    batch = cube_from_sh(raw, coeffs, 2)
    assert batch.shape == (5, 6, 3)
    for p in range(5):
        np.testing.assert_array_equal(batch[p], cube_from_sh(raw, coeffs[p], 2)[0])
    assert cube_from_sh(raw, np.zeros((0, 9, 3)), 2).shape == (0, 6, 3)


def test_errors(raw):
    from schnee_probes import native
    bad = np.ones((9, 3))
    bad[5, 1] = np.nan
    with pytest.raises(native.SchneeError) as exc:
        cube_from_sh(raw, bad, 2)
    assert exc.value.code == "non-finite value" and "coefficient 5 G is nan" in str(exc.value)
    with pytest.raises(native.SchneeError, match="unknown fit 9"):
        cube_from_sh(raw, np.ones((9, 3)), 2, 9)
    with pytest.raises(ValueError, match="max_band 5"):
        cube_from_sh(raw, np.ones((36, 3)), 5)
    with pytest.raises(ValueError, match="not a multiple of 27"):
        cube_from_sh(raw, np.ones((8, 3)), 2)
    with pytest.raises(ValueError, match="cube has 17 items"):
        cube_irradiance(raw, np.ones(17), np.ones((1, 3)))
    with pytest.raises(TypeError):
        raw.ambient_cube_from_sh(np.ones(27, dtype=np.float32), 2, 0)
