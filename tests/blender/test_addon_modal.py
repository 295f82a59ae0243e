"""Bake SH in Volumes as a modal operator in a real UI session (Blender under Xvfb): it bakes to the
end, and a simulated Esc cancels a second bake, leaving the first file untouched and the render
settings restored. Runtime: ~20-30 s."""
import json
import os
import shutil
import subprocess
from pathlib import Path

import pytest

from conftest import ADDON_DIR, REPO

SCRIPT = Path(__file__).resolve().parent / "scripts" / "addon_modal.py"


@pytest.mark.skipif(shutil.which("xvfb-run") is None, reason="xvfb-run not installed")
def test_modal_bake_finishes_and_esc_cancels(tmp_path):
    cmd = ["xvfb-run", "-a", "-s", "-screen 0 1280x800x24", "blender", "--factory-startup",
           "--enable-event-simulate", "--python-exit-code", "1", "-P", str(SCRIPT), "--", str(tmp_path)]
    env = {**os.environ, "PYTHONPATH": str(ADDON_DIR), "SCHNEE_REPO": str(REPO)}
    proc = subprocess.run(cmd, capture_output=True, text=True, timeout=600, env=env)
    lines = [l for l in proc.stdout.splitlines() if l.startswith("RESULT ")]
    assert lines, proc.stdout[-3000:] + proc.stderr[-2000:]
    r = json.loads(lines[-1][7:])
    assert r["start"] == ["RUNNING_MODAL"] and r["running_after_start"]
    assert r["finished_message"].startswith("Baked 32 probes"), r  # 4 x 4 x 2 m volume, 1 m cells
    assert r["file"]
    assert r["engine_after"] == "BLENDER_EEVEE"  # the scene's engine, restored
    assert r["cancel_message"].startswith("Bake cancelled")
    assert r["file_unchanged"]
    assert r["engine_after_cancel"] == "BLENDER_EEVEE"
