"""Every declared bake setting (addon/schnee_probes/settings.py) is a Scene.schnee_probes property
with the declared type, default, limits, choices, label and help (real Blender 3.4, ~2 s). The
other surfaces (bake.py, validate, the guide) are checked in tests/python/test_settings.py."""
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
