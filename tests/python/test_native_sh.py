"""SH through the Python API against closed forms (DESIGN.md §3): basis formulas, the projection of
constant and linear environments, irradiance of a constant environment, rotation handling, error
codes and argument validation."""
import math

import numpy as np
import pytest

from schnee_probes import native

STUDIO = "/usr/share/blender/datafiles/studiolights/world/interior.exr"


def design_basis(d):
    """The 25 basis functions exactly as written in DESIGN.md §3 (engine space)."""
    x, y, z = d
    return np.array([
        0.282094792,
        0.488602512 * y, 0.488602512 * z, 0.488602512 * x,
        1.092548431 * x * y, 1.092548431 * y * z, 0.315391565 * (3 * z * z - 1),
        1.092548431 * x * z, 0.546274215 * (x * x - y * y),
        0.590043590 * y * (3 * x * x - y * y), 2.890611443 * x * y * z,
        0.457045799 * y * (5 * z * z - 1), 0.373176333 * z * (5 * z * z - 3),
        0.457045799 * x * (5 * z * z - 1), 1.445305721 * z * (x * x - y * y),
        0.590043590 * x * (x * x - 3 * y * y),
        2.503342942 * x * y * (x * x - y * y), 1.770130770 * y * z * (3 * x * x - y * y),
        0.946174696 * x * y * (7 * z * z - 1), 0.669046544 * y * z * (7 * z * z - 3),
        0.105785547 * (35 * z ** 4 - 30 * z * z + 3), 0.669046544 * x * z * (7 * z * z - 3),
        0.473087348 * (x * x - y * y) * (7 * z * z - 1), 1.770130770 * x * z * (x * x - 3 * y * y),
        0.625835735 * (x ** 4 - 6 * x * x * y * y + y ** 4)])


def test_basis_matches_design_formulas():
    rng = np.random.default_rng(7)
    dirs = rng.normal(size=(50, 3))
    dirs /= np.linalg.norm(dirs, axis=1, keepdims=True)
    got = native.sh_basis(dirs, 4)
    assert got.shape == (50, 25) and got.dtype == np.float64
    want = np.array([design_basis(d) for d in dirs])
    # DESIGN's constants have 9-10 significant digits.
    np.testing.assert_allclose(got, want, rtol=0, atol=5e-9)
    np.testing.assert_allclose(native.sh_basis(dirs[0], 1), want[0, :4], atol=5e-9)


def _panorama(w, h, fn):
    """Equirect panorama (h, w, 3) of fn(d) with d the Blender-space pixel-centre direction
    (DESIGN.md §3: φ = π − 2π(i+½)/W, θ = π(r+½)/H, row 0 at the top)."""
    phi = math.pi - 2 * math.pi * (np.arange(w) + 0.5) / w
    theta = math.pi * (np.arange(h) + 0.5) / h
    th, ph = np.meshgrid(theta, phi, indexing="ij")
    d = np.stack([np.sin(th) * np.cos(ph), np.sin(th) * np.sin(ph), np.cos(th)], axis=-1)
    v = fn(d)
    return np.repeat(v[..., None], 3, axis=-1).astype(np.float32)


def test_constant_environment():
    # L(ω) = c: L_0 = c ∫ Y0 dω = 4π·0.282094792·c = 2√π·c, every other coefficient 0 (orthogonality);
    # irradiance E(n) = A0·L_0·Y0 = π·c for every n.
    c = 0.75
    pix = np.full((128, 256, 4), c, np.float32)
    coeffs = native.project_equirect(pix, max_band=4)
    assert coeffs.shape == (25, 3)
    np.testing.assert_allclose(coeffs[0], 2 * math.sqrt(math.pi) * c, rtol=1e-9)
    # The basis is sampled at pixel centres: an O(1/H^2) error, measured 2.2e-4 of L_0 at H = 64.
    assert np.abs(coeffs[1:]).max() < 1e-4 * coeffs[0, 0]
    normals = np.array([[0, 1, 0], [1, 0, 0], [0, 0, -1], [0.6, 0.8, 0]], float)
    np.testing.assert_allclose(native.irradiance(coeffs[:9], normals), math.pi * c, rtol=1e-4)
    assert native.irradiance(coeffs[:9], (0, 1, 0)).shape == (3,)


def test_linear_environment_and_rotation():
    # L(ω) = 1 + z_blender. Default rotation (Blender -> engine): z_blender = y_engine, so
    # L_1 (Y1 = 0.488602512·y) = 0.488602512·4π/3 = 2.0466534 and L_0 = 2√π. With the identity
    # rotation the same panorama lands in L_2 (Y2 = 0.488602512·z) instead.
    pix = _panorama(256, 128, lambda d: 1.0 + d[..., 2])
    lin = 0.488602512 * 4 * math.pi / 3
    c = native.project_equirect(pix, 1)
    np.testing.assert_allclose(c[0], 2 * math.sqrt(math.pi), rtol=1e-4)
    np.testing.assert_allclose(c[1], lin, rtol=1e-3)
    assert np.abs(c[[2, 3]]).max() < 1e-4
    c_id = native.project_equirect(pix, 1, rotation=np.eye(3))
    np.testing.assert_allclose(c_id[2], lin, rtol=1e-3)
    assert np.abs(c_id[[1, 3]]).max() < 1e-4
    np.testing.assert_allclose(native.project_equirect(pix, 1, rotation=native.BLENDER_TO_ENGINE), c,
                               rtol=0, atol=1e-12)


def test_errors_have_codes():
    pix = np.ones((32, 64, 3), np.float32)
    pix[5, 7, 1] = -0.5
    with pytest.raises(native.SchneeError) as exc:
        native.project_equirect(pix, 2)
    assert exc.value.code == "negative value" and str(exc.value)
    clamp = native.project_equirect(pix, 2, negative="clamp")
    allow = native.project_equirect(pix, 2, negative="allow")
    assert allow[0, 1] < clamp[0, 1] < native.project_equirect(np.ones_like(pix), 2)[0, 1] + 1e-12
    pix[5, 7, 1] = np.nan
    with pytest.raises(native.SchneeError) as exc:
        native.project_equirect(pix, 2, negative="allow")
    assert exc.value.code == "non-finite value"
    with pytest.raises(native.SchneeError) as exc:
        native.project_equirect(np.ones((1, 2, 3), np.float32), 4)
    assert exc.value.code == "input too small"
    w, h = native.min_panorama_size(4)
    assert native.project_equirect(np.ones((h, w, 3), np.float32), 4).shape == (25, 3)
    with pytest.raises(native.SchneeError) as exc:
        native.project_file("/nonexistent/x.exr", 2)
    assert exc.value.code == "I/O error" and "/nonexistent/x.exr" in str(exc.value)
    assert isinstance(exc.value, RuntimeError)


def test_project_file_reads_exr():
    # Blender's interior.exr holds a few tiny negative pixels (-1.6e-4): refused by default.
    with pytest.raises(native.SchneeError) as exc:
        native.project_file(STUDIO, 2)
    assert exc.value.code == "negative value" and "interior.exr" in str(exc.value)
    c = native.project_file(STUDIO, 2, negative="clamp")
    assert c.shape == (9, 3) and np.all(np.isfinite(c)) and np.all(c[0] > 0)


def test_window_wrapper():
    c = native.project_equirect(_panorama(64, 32, lambda d: 1.0 + d[..., 2]), 2)
    same, min_e = native.window(c, "none")
    np.testing.assert_array_equal(same, c)
    assert min_e.shape == (3,)
    # E(n) = π·(1 + z/3·... ) ≥ 0 here; the minimum irradiance of 1 + z over the sphere is at z = −1:
    # E = A0·L0·Y0 + A1·L1·Y1(−1) = π − (2π/3)·(4π/3)·0.488602512² = π − 2π/3 = π/3.
    np.testing.assert_allclose(min_e, math.pi / 3, rtol=2e-3)
    with pytest.raises(ValueError, match="kind must be one of 'none', 'sinc4', 'laplacian'"):
        native.window(c, "hann")


def test_argument_validation():
    with pytest.raises(ValueError, match=r"pixels must have shape \(H, W, C\) with C >= 3, got \(8, 16\)"):
        native.project_equirect(np.ones((8, 16), np.float32))
    with pytest.raises(TypeError, match="pixels must be a numeric array convertible to float32, got dtype complex128"):
        native.project_equirect(np.ones((8, 16, 3), complex))
    with pytest.raises(ValueError, match=r"dirs must have shape \(N, 3\) or \(3,\), got \(4, 2\)"):
        native.sh_basis(np.ones((4, 2)), 2)
    with pytest.raises(ValueError, match="max_band 5 is out of range 0..4"):
        native.sh_basis(np.ones((4, 3)), 5)
    with pytest.raises(ValueError, match="coeffs has 8 coefficients"):
        native.irradiance(np.ones((8, 3)), (0, 1, 0))
    with pytest.raises(ValueError, match="negative must be one of"):
        native.project_equirect(np.ones((8, 16, 3), np.float32), 1, negative="ignore")
    with pytest.raises(ValueError, match=r"rotation must have shape \(3, 3\)"):
        native.project_equirect(np.ones((8, 16, 3), np.float32), 1, rotation=np.eye(4))
    raw = native._lib()
    with pytest.raises(TypeError, match="pixels must hold float32 items, got buffer format 'd'"):
        raw.project_equirect(np.ones((8, 16, 3)), 16, 8, 3, 1)
    with pytest.raises(ValueError, match="pixels has 384 items, expected 512"):
        raw.project_equirect(np.ones((8, 16, 3), np.float32), 16, 8, 4, 1)
    with pytest.raises(TypeError, match="must be a C-contiguous float64 buffer"):
        raw.sh_basis(np.ones((4, 6))[:, ::2], 2)
    # Non-contiguous and float64 inputs are fine through native.py (it converts).
    pix = np.ones((8, 32, 3))[:, ::2]
    np.testing.assert_allclose(native.project_equirect(pix, 1)[0], 2 * math.sqrt(math.pi), rtol=1e-9)
