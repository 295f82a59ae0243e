"""bench/placement_equal_grid.py: the uniform grid of equal error, against closed-form power laws."""
import sys

import pytest

from conftest import REPO

sys.path.insert(0, str(REPO / "bench"))
import placement_equal_grid as peg  # noqa: E402


def _grids(spacings, err, probes):
    return {h: {"error": {"mean": err(h)}, "probes": probes(h)} for h in spacings}


def test_a_power_law_is_recovered_exactly_between_the_enclosing_grids():
    # e = 0.02·h^1.5, n = 4000·h^-3 (closed form): the grid of error e(0.7) is h = 0.7, n(0.7).
    grids = _grids([0.5, 1.0, 2.0], lambda h: 0.02 * h ** 1.5, lambda h: 4000.0 * h ** -3)
    h, n = peg.equal_grid(0.02 * 0.7 ** 1.5, grids, "mean")
    assert h == pytest.approx(0.7, rel=1e-12)
    assert n == pytest.approx(4000.0 * 0.7 ** -3, rel=1e-12)
    # Between 1 and 2 m the same.
    h, n = peg.equal_grid(0.02 * 1.3 ** 1.5, grids, "mean")
    assert (h, n) == (pytest.approx(1.3, rel=1e-12), pytest.approx(4000.0 * 1.3 ** -3, rel=1e-12))


def test_no_figure_outside_the_measured_grids():
    grids = _grids([0.5, 1.0], lambda h: 0.02 * h, lambda h: 100.0 / h ** 3)
    assert peg.equal_grid(0.005, grids, "mean") is None   # finer than the finest grid: no extrapolation
    assert peg.equal_grid(0.05, grids, "mean") is None
