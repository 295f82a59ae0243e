"""The bake's time estimate (addon/schnee_probes/estimate.py) against the sweep rows it is calibrated
on (bench/results/estimate_calibration.json: the 12.3-min run of bench/sweep/run.py --full, whose
figures later runs on a busier machine replaced in sweep.json), and the probe-count bound (plain
Python, < 1 s)."""
import json

import numpy as np
import pytest

from conftest import REPO
from schnee_probes import estimate
from schnee_probes.settings import BakeSettings

CALIBRATION = json.loads((REPO / "bench" / "results" / "estimate_calibration.json").read_text())


def _rows(scene):
    for r in CALIBRATION["scenes"][scene]:
        s = r["settings"]
        w, spp = s.get("panorama_resolution", 128), s.get("samples", 32)
        yield r["label"], w, spp, s.get("max_bounces", 32), r["s_per_probe"]


def test_model_matches_the_closed_room_and_bounds_every_measured_row():
    interior = 0
    for scene in ("interior", "courtyard", "sky_forest", "sky_courtyard"):
        for label, w, spp, bounces, measured in _rows(scene):
            model = estimate.SECONDS_PER_PIXEL_SAMPLE * w * (w // 2) * spp
            if w * (w // 2) * spp >= 32 * 16 * 64:
                # An upper estimate: never below what was measured (tiny renders are dominated
                # by per-render overhead, which the first-probe term covers).
                assert model >= measured, (scene, label, model, measured)
            if scene == "interior" and bounces >= 16:
                # The closed room at 16+ bounces is what the constant is calibrated on: at most
                # 15 % above each measured row (3.46-3.84 µs per pixel-sample measured, 3.9 model).
                assert measured <= model <= 1.15 * measured, (label, model, measured)
                interior += 1
    assert interior >= 10  # the calibration rests on many rows, not one


def test_defaults_estimate_and_sky_term():
    s = BakeSettings()
    assert s.placement == "ADAPTIVE" and s.samples == 8
    # 128 x 64 px x 8 spp x 3.9 µs + 2 renders x 0.03 s = 0.32 s per point (measured in the bundled
    # room: 0.36 s for two 4-spp renders, 0.35 s for one 8-spp render).
    assert estimate.estimate_seconds(1, s) - estimate.FIRST_PROBE_SECONDS == pytest.approx(
        128 * 64 * 8 * 3.9e-6 + 2 * 0.03, rel=1e-12)
    one = BakeSettings(placement="OCTREE", samples=32)
    assert estimate.estimate_seconds(1, one) - estimate.FIRST_PROBE_SECONDS == pytest.approx(
        128 * 64 * 32 * 3.9e-6 + 0.03, rel=1e-12)
    assert estimate.estimate_seconds(0, s) == 0.0
    with_sky = estimate.estimate_seconds(10, s, sky=True) - estimate.estimate_seconds(10, s)
    assert with_sky == pytest.approx(0.15e-6 * 512 * 256 * 8, rel=1e-12)
    assert estimate.estimate_seconds(10, BakeSettings(capture_sky=False), sky=True) == \
        estimate.estimate_seconds(10, BakeSettings(capture_sky=False))


@pytest.mark.parametrize("seconds,text", [(4.4, "4 s"), (89, "89 s"), (600, "10 min"),
                                          (7200, "2.0 h"), (23000, "6.4 h"), (3 * 86400, "3.0 days")])
def test_format_duration(seconds, text):
    assert estimate.format_duration(seconds) == text


def test_grid_cell_bound_counts_min_cells_of_the_bounding_boxes():
    cube = lambda lo, hi: ("v", np.array([[x, y, z] for x in (lo[0], hi[0]) for y in (lo[1], hi[1])
                                          for z in (lo[2], hi[2])], dtype=float), None)
    a, b = cube((0, 0, 0), (4, 2, 4)), cube((10, 0, 0), (11, 1, 1))
    # One grid over the union: ceil(11/0.5) x ceil(2/0.5) x ceil(4/0.5) = 22 x 4 x 8.
    assert estimate.grid_cell_bound([a, b], 0.5, per_volume=False) == 22 * 4 * 8
    # One grid per volume: 8 x 4 x 8 + 2 x 2 x 2.
    assert estimate.grid_cell_bound([a, b], 0.5, per_volume=True) == 8 * 4 * 8 + 8
    # 10 m at 0.5 m stays 20 cells despite rounding (docs/placement.md's tolerance).
    assert estimate.grid_cell_bound([cube((0, 0, 0), (10, 10, 10))], 0.5, False) == 20 ** 3


def test_adaptive_points_and_forecast():
    # Issue 29 item 5: the Adaptive bake's expected points per cell of the grid bound (0.58 at
    # Error Tolerance 0.03, the bench scenes' geometric mean) and its tolerance power law.
    assert estimate.adaptive_points(3200, 0.03) == pytest.approx(0.58 * 3200)
    assert estimate.adaptive_points(3200, 0.06) == pytest.approx(0.58 * 3200 * 2 ** -0.65)
    assert estimate.adaptive_points(0, 0.03) == 0.0
    # Elapsed + the points not rendered yet at the measured time per point times the later points'
    # factor 1 + 0.3 (1 - rendered / expected); never below elapsed.
    assert estimate.forecast_seconds(10.0, 100, 1000, 0.5) == pytest.approx(10.0 + 900 * 0.5 * 1.27)
    assert estimate.forecast_seconds(10.0, 0, 1000, 0.5) == pytest.approx(10.0 + 1000 * 0.5 * 1.3)
    assert estimate.forecast_seconds(10.0, 1200, 1000, 0.5) == pytest.approx(10.0)
