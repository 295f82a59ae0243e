"""Enabling the add-on with a submodule missing or broken is an error naming it (issue 10): it was
silently skipped, giving an add-on without, e.g., its panel. Real Blender 3.4 (~1 s each)."""
import json
from pathlib import Path

import pytest

from conftest import run_blender

SCRIPT = Path(__file__).resolve().parent / "scripts" / "addon_missing_submodule.py"


def _enable(tmp_path, what):
    proc = run_blender(SCRIPT, tmp_path, what, timeout=120, check=False)
    lines = [l for l in proc.stdout.splitlines() if l.startswith("RESULT ")]
    assert lines, proc.stdout[-2000:] + proc.stderr[-2000:]
    return json.loads(lines[-1][7:])


@pytest.mark.parametrize("what", ["panel", "gltf_export", "operators:broken"])
def test_missing_or_broken_submodule_is_an_error_naming_it(tmp_path, what):
    r = _enable(tmp_path, what)
    name = what.split(":")[0]
    assert not r["enabled"]
    assert len(r["errors"]) == 1, r
    assert f"module '{name}' could not be loaded" in r["errors"][0], r["errors"]
    assert "reinstall" in r["errors"][0]


def test_complete_copy_enables(tmp_path):
    # The same copy with nothing removed enables (so the failures above are the removal's).
    r = _enable(tmp_path, "nonexistent_module_name")
    assert r["enabled"] and r["errors"] == [], r
