"""The bake-info sidecar of a real Adaptive bake (docs/bakeinfo.md) in headless Blender 3.4 + Cycles:
refine_scenes.py's shadow scene baked as tests/blender/test_refine_bake.py bakes it (~10 s), its
journal kept. Expected values: the journal's records (each probe's noise rebuilt from them as a
resumed bake rebuilds it), the bake's own pass log, the .shprobe's bytes and leaves.
"""
import math
from pathlib import Path

import numpy as np
import pytest

from conftest import requires_native, run_blender
from test_refine_bake import result_of

SCRIPTS = Path(__file__).resolve().parent / "scripts"
pytestmark = requires_native
PASSED, NOISE_LIMITED, MIN_CELL, NEVER_TESTED, NOT_COMPARED = 1, 2, 3, 4, 5


@pytest.fixture(scope="module")
def baked(tmp_path_factory):
    scenes = result_of(run_blender(SCRIPTS / "refine_scenes.py", tmp_path_factory.mktemp("scenes")))
    out = tmp_path_factory.mktemp("bakeinfo")
    return result_of(run_blender(SCRIPTS / "bakeinfo_bake.py", out, blend=scenes["shadow"], timeout=600))


def test_sidecar_is_written_beside_the_file_and_names_its_bytes(baked):
    a = baked["arrays"]
    assert [Path(f).name for f in baked["files"]] == ["probes.shprobe", "probes.shprobe.bakeinfo"]
    assert a["format"] == "schnee-bakeinfo" and a["version"] == 1 and a["placement"] == "ADAPTIVE"
    assert a["shprobe_sha256"] == baked["sha256"]
    assert a["probe_count"] == baked["probe_count"] == len(a["noise"])
    assert a["tolerance"] == pytest.approx(0.05) and a["noise_k"] == 2.0 and a["samples"] == 16
    assert a["leaves"] == baked["file_leaves"]
    assert baked["read_error"] is None and not baked["read_missing"]


def test_noise_equals_the_journals(baked):
    """Each probe's noise equals the one its journal records give (float32 of the float64)."""
    got = np.asarray(baked["arrays"]["noise"], np.float64)
    want = np.asarray(baked["journal_noise"], np.float64)
    assert np.allclose(got, want, rtol=1e-6, atol=1e-9), np.abs(got - want).max()
    assert (want > 0).sum() > len(want) // 4           # measured, not zeros
    assert max(baked["journal_rounds"]) > 2          # some probes got more rounds (combined noise)


def test_history_reproduces_every_pass_decision(baked):
    """A leaf its tests split erred above its threshold, a leaf that erred above it split unless at
    Min Cell Size, and each pass's count of split leaves is the bake's own pass log."""
    a = baked["arrays"]
    err, thr = np.asarray(a["history_error"], float), np.asarray(a["history_threshold"], float)
    split, direct = np.asarray(a["history_split"]), np.asarray(a["history_direct"])
    level = np.asarray(a["history_leaves"])[:, 3]
    compared = np.isfinite(err)
    above = compared & (err > thr)
    assert ((split != 0) <= above).all()
    assert (above <= ((split != 0) | (level == 0))).all()
    assert above.sum() > 0 and (compared & ~above).sum() > 0
    passes = np.asarray(a["history_pass"])
    for p in baked["passes"]:
        sel = passes == p["pass_index"]
        if sel.any():
            assert int(((split[sel] != 0) | (direct[sel] != 0)).sum()) == p["split"], p


def test_final_leaves_say_why_they_are_leaves(baked):
    a = baked["arrays"]
    reason = np.asarray(a["leaf_reason"])
    err, thr = np.asarray(a["leaf_error"], float), np.asarray(a["leaf_threshold"], float)
    level = np.asarray(a["leaves"])[:, 3]
    tol = a["tolerance"]
    assert set(reason.tolist()) <= {PASSED, NOISE_LIMITED, MIN_CELL, NEVER_TESTED, NOT_COMPARED}
    assert ((reason == MIN_CELL) == (level == 0)).all()
    tested = (reason == PASSED) | (reason == NOISE_LIMITED)
    assert np.isfinite(err[tested]).all() and np.isnan(err[~tested]).all()
    assert (err[reason == PASSED] <= tol).all()
    assert ((err[reason == NOISE_LIMITED] > tol) & (err[reason == NOISE_LIMITED] <= thr[reason == NOISE_LIMITED])).all()
    assert (err[tested] <= thr[tested]).all()          # a final leaf's own tests passed
    # the shadow scene splits down to Min Cell Size along the boundary, and some leaves pass
    assert (reason == MIN_CELL).sum() > 0 and tested.sum() > 0
    parent = np.asarray(a["leaf_parent_ratio"], float)
    assert (parent[reason == MIN_CELL] > 1).any() and not math.isnan(parent[reason == MIN_CELL].max())
