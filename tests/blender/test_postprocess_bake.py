"""Dilate Invalid Probes and SH Windowing reach the .shprobe a real bake writes (Blender 3.4 + Cycles,
issue 31 item 4). Scene and bakes: scripts/postprocess_bake.py (27 probes, one inside a solid box,
two bakes with the same seed: settings off, and dilation + Laplacian window λ = 0.01).

Expected values are independent of postprocess.py: the window's factor per band is Sloan's closed
form 1/(1 + λ l²(l+1)²) applied to the off bake's coefficients, and the dilated probe is the mean
of its 26 neighbours (every other probe of the 3 × 3 × 3 lattice) weighted by validity / distance²,
computed here by hand from the off file. Runtime about 20 s on 2 idle cores."""
from pathlib import Path

import numpy as np
import pytest

from conftest import requires_native, run_blender

SCRIPT = Path(__file__).resolve().parent / "scripts" / "postprocess_bake.py"
LAMBDA = 0.01

pytestmark = requires_native


@pytest.fixture(scope="module")
def bakes(tmp_path_factory):
    out = tmp_path_factory.mktemp("postprocess_bake")
    run_blender(SCRIPT, out, timeout=600)
    return dict(np.load(out / "bakes.npz"))


def laplacian_factors():
    return np.array([1.0 / (1.0 + LAMBDA * (l * (l + 1)) ** 2) for l in range(3) for _ in range(2 * l + 1)])


def test_off_bake_has_one_invalid_probe_at_the_centre(bakes):
    bad = np.flatnonzero(bakes["off_validity"] <= 0)
    assert bad.size == 1
    np.testing.assert_allclose(bakes["off_positions"][bad[0]], [2.0, 2.0, -2.0], atol=1e-6)  # engine z = -y
    assert np.all(bakes["off_coeffs"][bad[0]] == 0)  # never rendered


def test_window_reaches_the_file(bakes):
    good = bakes["off_validity"] > 0
    want = bakes["off_coeffs"][good].astype(np.float64) * laplacian_factors()[None, :, None]
    got = bakes["on_coeffs"][good].astype(np.float64)
    # float32 file values; the renders are the same (same seed): 1e-6 of the largest coefficient
    np.testing.assert_allclose(got, want, rtol=0, atol=1e-6 * np.abs(want).max())
    assert np.abs(got - bakes["off_coeffs"][good]).max() > 1e-3 * np.abs(want).max()  # it did change
    np.testing.assert_array_equal(bakes["on_validity"][good], bakes["off_validity"][good])


def test_dilated_probe_is_the_weighted_mean_of_its_neighbours(bakes):
    val, pos = bakes["off_validity"].astype(np.float64), bakes["off_positions"].astype(np.float64)
    b = int(np.flatnonzero(val <= 0)[0])
    others = [i for i in range(len(val)) if i != b]
    num, den = np.zeros((9, 3)), 0.0
    for i in others:
        w = val[i] / float(np.sum((pos[i] - pos[b]) ** 2))
        num += w * bakes["off_coeffs"][i]
        den += w
    want = num / den * laplacian_factors()[:, None]
    np.testing.assert_allclose(bakes["on_coeffs"][b], want, rtol=0, atol=1e-6 * np.abs(want).max())
    assert bakes["on_validity"][b] == pytest.approx(0.01)
