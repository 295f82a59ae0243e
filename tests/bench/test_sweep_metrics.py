"""The sweep's model of the engine's per-pixel lookup (bench/sweep/metrics.py) against closed forms.

Expected values: trilinear interpolation reproduces a field that is linear in position exactly at
any point with all 8 surrounding cells present (the defining property of trilinear weights);
with a cell missing, the renormalised weights are the remaining corners' weights divided by their
sum (hand-computed below); with no weight at all it falls back to the cell's own probe.
"""
import sys

import numpy as np

from conftest import REPO

sys.path.insert(0, str(REPO / "bench" / "sweep"))
import metrics  # noqa: E402
from schnee_probes import native  # noqa: E402


def _file(tmp_path, grid, coeffs, dims, origin=(0.0, 0.0, 0.0), spacing=1.0):
    path = tmp_path / "g.shprobe"
    native.write_shprobe(str(path), np.asarray(coeffs, dtype=np.float32), np.asarray(grid, np.int32),
                         dims, origin, spacing)
    return native.read_shprobe(str(path))


def test_linear_field_is_reproduced(tmp_path):
    dims = (3, 3, 3)
    centres = [((x + 0.5), (y + 0.5), (z + 0.5)) for z in range(3) for y in range(3) for x in range(3)]
    # L0 coefficient of probe i = a linear function of its cell centre; all 9 coeffs x RGB vary.
    grad = np.array([0.3, -0.2, 0.7])
    coeffs = np.zeros((27, 9, 3))
    for i, c in enumerate(centres):
        coeffs[i] = 1.0 + grad @ np.asarray(c) + 0.01 * np.arange(27).reshape(9, 3)
    f = _file(tmp_path, np.arange(27), coeffs, dims)
    pts = np.array([[0.7, 1.1, 2.3], [1.5, 1.5, 1.5], [2.49, 0.51, 1.0]])
    got = np.asarray(metrics.interpolate_trilinear(f, pts))
    want = 1.0 + (pts @ grad)[:, None, None] + 0.01 * np.arange(27).reshape(1, 9, 3)
    np.testing.assert_allclose(got, want, rtol=0, atol=1e-5)  # float32 storage


def test_missing_cells_are_skipped_and_weights_renormalised(tmp_path):
    # 2 x 2 x 2 cells with cell (1,1,1) empty; the point sits at t = (0.25, 0.5, 0.5) past the centres.
    grid = np.arange(8)
    grid[7] = -1
    coeffs = np.zeros((7, 9, 3))
    coeffs[:, 0, 0] = np.arange(1, 8)  # probe i has L0.r = i + 1
    f = _file(tmp_path, grid, coeffs, (2, 2, 2))
    p = np.array([[0.75, 1.0, 1.0]])  # u = p - 0.5 = (0.25, 0.5, 0.5): t = (0.25, 0.5, 0.5)
    w = {}
    for dz in (0, 1):
        for dy in (0, 1):
            for dx in (0, 1):
                idx = dx + 2 * dy + 4 * dz
                w[idx] = (0.25 if dx else 0.75) * 0.5 * 0.5
    del w[7]
    want = sum(w[i] * (i + 1) for i in w) / sum(w.values())
    got = np.asarray(metrics.interpolate_trilinear(f, p))[0, 0, 0]
    assert abs(got - want) < 1e-6


def test_outside_everything_falls_back_to_none(tmp_path):
    f = _file(tmp_path, [0], np.ones((1, 9, 3)), (1, 1, 1))
    # Inside the single cell: its probe; far outside: no cell, no probe.
    got = metrics.interpolate_trilinear(f, np.array([[0.5, 0.5, 0.5], [10.0, 10.0, 10.0]]))
    np.testing.assert_allclose(got[0], np.ones((9, 3)))
    assert got[1] is None
