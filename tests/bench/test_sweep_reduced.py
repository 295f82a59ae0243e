"""Reduced speed-accuracy sweep (bench/sweep/): errors fall as settings rise (the sky-only scene is
exact at any setting since issue 11), and the shipped defaults meet the error docs/user-guide.md
promises.

Same harness as the full sweep (`/usr/bin/python3 bench/sweep/run.py --full`): scenes from
bench/sweep/scenes.py baked in headless Blender through the add-on's `bake_core.ProbeBake`.
References: the sky-only scene's exact HDRI projection, and for the interior the reference bake
stored in bench/results/sweep.json by the full sweep (256x128, 128 spp, 32 bounces, no clamping,
mean of seeds 1 and 2, converged to the tolerance that file reports). Settings compared are far
apart, so the assertions hold with a wide margin over the noise.

Runtime: about 1 minute on 2 cores (two Blender runs: sky ~10 s, interior ~40 s).
"""
import json
import sys

import numpy as np
import pytest

from conftest import REPO

sys.path.insert(0, str(REPO / "bench" / "sweep"))

SWEEP_JSON = REPO / "bench" / "results" / "sweep.json"

# Promised in docs/user-guide.md ("Recommended settings"): irradiance relative RMS at L = 2 of a
# default bake (128×64, 8 spp, 32 bounces). The full sweep measured 1.8e-7 (sky, 8 probes, exact
# since issue 11; 0.57 ± 0.44 % before, when forest.exr's small sun was path traced) and
# 0.81 ± 0.31 % (room, 4 probes with their own seeds, reference good to ~0.1 %; 0.42 ± 0.22 % at the
# 32 spp default before issue 12); the promises leave room for run-to-run noise
# (bench/results/sweep.md). The room promise was 4 % while the default was 16 bounces (2.6 %).
PROMISE_SKY = 0.015       # sky-only forest.exr (small sun), exact reference
PROMISE_INTERIOR = 0.015  # bright closed room with a window


def _ready():
    try:
        import run  # noqa: F401  (bench/sweep/run.py: imports the native module)
        return SWEEP_JSON.exists()
    except Exception:
        return False


pytestmark = pytest.mark.skipif(not _ready(), reason="native module not built or sweep.json missing")


def _bake(tmp_path, scene, jobs):
    import run
    return run.run_scene(scene, (0, 0, 0), jobs, str(tmp_path), log=lambda line: None)


def _errors(doc, jid, refs, band=2):
    import metrics
    c = np.asarray(doc["jobs"][jid]["coeffs"])
    return float(np.mean([metrics.errors(c[i], refs[i], band)[0] for i in range(len(c))]))


def test_sky_is_exact_at_any_resolution_and_samples_and_defaults_meet_promise(tmp_path):
    import run
    low = dict(run.BASE, panorama_resolution=32, samples=8)
    jobs = [run.fixed("low", low, band=2), run.fixed("high", run.BASE, band=2),
            run.fixed("defaults", {}, band=2)]
    doc = _bake(tmp_path, "sky_forest", jobs)
    import report
    effective = doc["jobs"]["defaults"]["settings_effective"]
    # The defaults the report calls "shipped" are the add-on's defaults.
    assert {k: effective[k] for k in report.SHIPPED} == report.SHIPPED
    ref = run.hdri_ref("forest.exr")[:9]  # exact: the HDRI's own projection
    refs = [ref] * len(doc["scene"]["probes"])
    e_low, e_high, e_def = (_errors(doc, j, refs) for j in ("low", "high", "defaults"))
    # Since issue 11 the sky a probe sees directly is added exactly (docs/direct-light.md): a
    # sky-only probe is the HDRI's own projection at any resolution and sample count (measured
    # 1.8e-7 for all three; before, 32x16 at 8 spp was 11x noisier than 128x64 at 64 spp, the full
    # sweep measured 9.5 ± 6.3 % vs 0.31 ± 0.31 %). The noise comparison is moot; the bound is tighter.
    assert max(e_low, e_high, e_def) <= 1e-5, (e_low, e_high, e_def)
    assert e_def <= PROMISE_SKY, e_def


def test_interior_errors_fall_with_bounces_and_defaults_meet_promise(tmp_path):
    import run
    stored = json.loads(SWEEP_JSON.read_text())["scenes"]["interior"]
    refs = np.asarray(stored["reference_coeffs"]["probes"])
    jobs = [run.fixed("b2", dict(run.BASE, max_bounces=2, samples=16), band=2),
            run.fixed("defaults", {}, band=2)]
    doc = _bake(tmp_path, "interior", jobs)
    # The reference was baked at exactly these positions (same scene script).
    np.testing.assert_allclose(doc["scene"]["probes"], stored["spec"]["probes"], atol=1e-9)
    e_b2, e_def = (_errors(doc, j, refs) for j in ("b2", "defaults"))
    # 2 bounces in an albedo-0.8 room miss most inter-reflected light (~0.8^2 of it before the
    # panel's and window's direct light is counted): the full sweep measured 40 % (64 spp).
    assert e_b2 > 0.15, e_b2
    assert e_b2 > 4 * e_def, (e_b2, e_def)
    assert e_def <= PROMISE_INTERIOR, e_def
