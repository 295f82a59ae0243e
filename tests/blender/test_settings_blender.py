"""Every declared bake setting (addon/schnee_probes/settings.py) is a Scene.schnee_probes property
with the declared type, default, limits, choices, label and help, and the panel and the bake dialog
draw exactly the settings declared with a UI place (real Blender 3.4, ~4 s). The other surfaces
(bake.py, validate, the guide) are checked in tests/python/test_settings.py."""
import json
from pathlib import Path

import pytest

from conftest import run_blender
from schnee_probes.settings import SETTINGS

SCRIPT = Path(__file__).resolve().parent / "scripts" / "settings_props.py"
BIG = 2 ** 31 - 1  # Blender's hard limit of an IntProperty without a declared bound


@pytest.fixture(scope="module")
def registered():
    proc = run_blender(SCRIPT, timeout=120)
    lines = [l for l in proc.stdout.splitlines() if l.startswith("RESULT ")]
    assert lines, proc.stdout[-2000:] + proc.stderr[-2000:]
    return json.loads(lines[-1][7:])


def test_no_undeclared_setting_property(registered):
    assert registered["extra"] == []
    assert registered["from_props_equals_defaults"]


@pytest.mark.parametrize("s", SETTINGS, ids=[s.name for s in SETTINGS])
def test_property_matches_declaration(registered, s):
    p = registered["props"].get(s.name)
    assert p is not None, f"Scene.schnee_probes has no property {s.name}"
    assert p["name"] == s.label and p["description"] == s.help
    kind = {"int": "INT", "float": "FLOAT", "bool": "BOOLEAN", "enum": "ENUM", "str": "STRING",
            "path": "STRING"}[s.kind]
    assert p["type"] == kind
    if s.kind == "float":
        assert p["default"] == pytest.approx(s.default, rel=1e-7)
    else:
        assert p["default"] == s.default
    if s.kind in ("int", "float"):
        if s.minimum is not None:
            assert p["hard_min"] == pytest.approx(s.minimum, rel=1e-7)
        else:
            assert p["hard_min"] <= -BIG if s.kind == "int" else p["hard_min"] < -1e30
        if s.maximum is not None:
            assert p["hard_max"] == pytest.approx(s.maximum, rel=1e-7)
        else:
            assert p["hard_max"] >= BIG if s.kind == "int" else p["hard_max"] > 1e30
    if s.kind == "enum":
        assert [tuple(i) for i in p["items"]] == list(s.choices)


# --------------------------------------------------------------------------- panel and dialog
# Every setting with a UI place (settings.Setting.ui) is drawn by the panel and the Bake SH in
# Volumes dialog, and nothing else of Scene.schnee_probes is. Blender's UILayout cannot be created
# headless (no window, and Python cannot construct one), so scripts/settings_draw.py hands the draw
# functions a recording layout that logs every prop()/prop_search() call.
DRAW_SCRIPT = Path(__file__).resolve().parent / "scripts" / "settings_draw.py"
UI_SETTINGS = {s.name for s in SETTINGS if s.ui is not None}
UI_ALL_SETTINGS = {s.name for s in SETTINGS if s.ui == "all"}


@pytest.fixture(scope="module")
def drawn():
    proc = run_blender(DRAW_SCRIPT, timeout=120)
    lines = [l for l in proc.stdout.splitlines() if l.startswith("RESULT ")]
    assert lines, proc.stdout[-2000:] + proc.stderr[-2000:]
    return json.loads(lines[-1][7:])


def test_declaration_has_both_ui_sections():
    # Otherwise the section tests below would compare empty sets.
    assert UI_ALL_SETTINGS and UI_SETTINGS - UI_ALL_SETTINGS
    assert {s.ui for s in SETTINGS} == {"all", "volumes", None}


@pytest.mark.parametrize("surface,expected", [("section_volumes", UI_SETTINGS), ("section_all", UI_ALL_SETTINGS),
                                              ("panel", UI_SETTINGS), ("dialog", UI_SETTINGS)])
def test_drawn_settings_equal_the_declared_ui_places(drawn, surface, expected):
    d = drawn[surface]
    assert set(d["names"]) == expected, (sorted(expected - set(d["names"])), sorted(set(d["names"]) - expected))
    assert len(d["names"]) == len(set(d["names"]))  # each once
    # In declaration order (the guide's table and bake.py --help list them in that order too).
    order = [s.name for s in SETTINGS if s.name in expected]
    assert d["names"] == order


@pytest.mark.parametrize("surface", ["section_volumes", "panel", "dialog"])
def test_drawn_rows_labels_and_search(drawn, surface):
    layouts = {name: (layout, kind, text, search, in_data) for name, layout, kind, text, search, in_data
               in drawn[surface]["layouts"]}
    rows = {}
    for s in SETTINGS:
        if s.ui is None:
            continue
        layout, kind, text, search, in_data = layouts[s.name]
        assert text == s.ui_text, s.name
        if s.ui_row:
            assert kind == "row", s.name
            rows.setdefault(s.ui_row, set()).add(layout)
        else:
            assert kind == "column", s.name
        if s.name == "volume_collection":
            assert search == "collections" and in_data, "the collection is picked from bpy.data.collections"
        else:
            assert search is None, s.name
    assert rows and all(len(ids) == 1 for ids in rows.values()), rows  # a ui_row's settings share one row
