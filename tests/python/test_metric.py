"""The refinement's metric computed in one place: metric.py hands whole arrays to the core's
pb_refine_irradiance_error (native.refine_error / refine_norm), the function pb_refine_decide uses."""
import math

import numpy as np
import pytest

from schnee_probes import metric, native

LAMBERT = np.array([math.pi] + [2 * math.pi / 3] * 3 + [math.pi / 4] * 5)  # A_l of bands 0..2


def test_norm_and_error_closed_forms():
    # ‖A·c‖ by the band factors, written out; error of 1.1·ref against ref = 0.1 (tolerance: rounding).
    rng = np.random.default_rng(5)
    c = rng.normal(size=(4, 9, 3))
    want = np.sqrt(np.sum((LAMBERT[:, None] * c) ** 2, axis=(1, 2)))
    assert metric.irradiance_norm(c) == pytest.approx(want, rel=1e-14)
    assert isinstance(metric.irradiance_norm(c[0]), np.floating)
    assert metric.irradiance_error(1.1 * c, c) == pytest.approx(np.full(4, 0.1), rel=1e-13)
    # Broadcast: one reference against several points.
    assert metric.irradiance_error(c, c[0]).shape == (4,) and metric.irradiance_error(c, c[0])[0] == 0.0


def test_error_is_the_core_function_bit_for_bit():
    # pb_refine_irradiance_error sums (A·(a − ref))² and (A·ref)² and takes sqrt(num / den): the same
    # bits as the per-point function, checked through a one-point call for each row.
    rng = np.random.default_rng(6)
    a, ref = rng.normal(size=(2, 50, 16, 3))
    many = metric.irradiance_error(a, ref)
    one = np.array([float(native.refine_error(a[i], ref[i])) for i in range(50)])
    assert np.array_equal(many, one)


def test_zero_and_nan_references():
    # 0 where both are 0, 1 where only the reference is; a NaN point (an interpolation outside the
    # probes) gives NaN, or 0 against a zero reference, as the add-on's callers expect.
    z = np.zeros((9, 3))
    a = np.ones((9, 3))
    assert metric.irradiance_error(z, z) == 0.0 and metric.irradiance_error(a, z) == 1.0
    nan = np.full((9, 3), np.nan)
    got = metric.irradiance_error(np.stack([nan, nan, a]), np.stack([a, z, z]))
    assert np.isnan(got[0]) and got[1] == 0.0 and got[2] == 1.0
    assert metric._rel(a, z) == 0.0 and metric._rel(a, 2 * a) == pytest.approx(0.5, rel=1e-15)


def test_argument_errors():
    with pytest.raises(ValueError, match="a has 8 coefficients"):
        native.refine_error(np.zeros((8, 3)), np.zeros((8, 3)))
    with pytest.raises(ValueError, match="ref must have shape"):
        native.refine_error(np.zeros((9, 3)), np.zeros((4, 3)))
    with pytest.raises(ValueError, match="max_band 5 is out of range"):
        native._lib().refine_norm(np.zeros(108), 5)
    with pytest.raises(ValueError, match="c has 27 items, not a multiple of 12"):
        native._lib().refine_norm(np.zeros(27), 1)
