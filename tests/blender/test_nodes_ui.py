"""The "VS Movable Diffuse" operator (schnee.add_movable_diffuse, nodes.py) in headless Blender.
Expected values: the group's documented defaults (nodes.py, docs/export.md): SH Scale 1.0,
Ambient Term 0.1. Runtime: a few seconds."""
from pathlib import Path

import pytest

from conftest import run_blender

SCRIPTS = Path(__file__).resolve().parent / "scripts"


def _result(proc):
    import json
    lines = [json.loads(l[7:]) for l in proc.stdout.splitlines() if l.startswith("RESULT ")]
    assert lines, proc.stdout[-3000:] + proc.stderr[-2000:]
    return lines[-1]


@pytest.fixture(scope="module")
def r():
    return _result(run_blender(SCRIPTS / "addon_nodes_ui.py"))


def test_operator_wires_group_into_existing_material(r):
    assert r["cube_result"] == ["FINISHED"]
    c = r["cube"]
    assert c["found"] and c["feeds_active_output"]
    assert c["surface_from"] == c["node_name"]  # the Principled BSDF is unlinked, ours replaces it
    assert c["sh_scale"] == pytest.approx(1.0, abs=1e-7)
    assert c["ambient"] == pytest.approx(0.1, abs=1e-7)  # float32 of 0.1
    # The Principled base colour set by the script (0.2, 0.4, 0.6) is carried over exactly.
    assert c["base_color"] == pytest.approx([0.2, 0.4, 0.6, 1.0], abs=1e-7)


def test_operator_creates_material_for_object_without_one(r):
    assert r["bare_result"] == ["FINISHED"]
    b = r["bare"]
    assert b["material"] == "Bare Movable Diffuse" and r["bare_slots"] == 1
    assert b["found"] and b["feeds_active_output"]
    assert b["sh_scale"] == pytest.approx(1.0, abs=1e-7)
    assert b["ambient"] == pytest.approx(0.1, abs=1e-7)


def test_second_run_reuses_the_group(r):
    # One node group per .blend; a second run adds a second node (now the active one) only.
    assert r["group_count"] == 1
    assert r["cube_again"]["group_nodes"] == 2 and r["cube_again"]["feeds_active_output"]


def test_poll_and_menu_registration(r):
    assert r["camera_poll"] is False
    assert r["menu_registered"] is True and r["menu_after_unregister"] is False
