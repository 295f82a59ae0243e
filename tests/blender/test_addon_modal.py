"""Bake SH in Volumes as a modal operator in a real UI session (Blender under Xvfb): it bakes to the
end, and a simulated Esc cancels a second bake, leaving the first file untouched and the render
settings restored; SIGINT cancels a third the same way; a bake above Confirm Above waits for the
confirmation. Runtime: ~30-40 s."""
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
    assert r["finished_message"].startswith("Baked 12 probes"), r  # 3 x 2 x 2 m volume, 1 m cells
    assert r["file"]
    assert r["engine_after"] == "BLENDER_EEVEE"  # the scene's engine, restored
    assert r["cancel_message"].startswith("Bake cancelled")
    assert r["file_unchanged"]
    assert r["engine_after_cancel"] == "BLENDER_EEVEE"
    # Ctrl+C in the terminal (SIGINT) cancels like Esc, and Blender keeps running (issue 14).
    assert r["sigint_handler_during_bake"]
    assert r["sigint_message"].startswith("Bake cancelled"), r["sigint_message"]
    assert r["sigint_file_unchanged"] and r["engine_after_sigint"] == "BLENDER_EEVEE"
    assert r["sigint_handler_after"]  # Python's Ctrl+C handler is back once the bake ends
    # 12 probes above Confirm Above = 10: nothing baked until confirmed; confirmed, it bakes.
    assert r["large_result"] == ["CANCELLED"] and not r["large_running"]
    assert "12 probes" in r["large_message"] and "more than the limit of 10" in r["large_message"]
    assert r["large_file_unchanged"]
    assert r["confirmed_result"] == ["RUNNING_MODAL"]
    assert r["confirmed_message"].startswith("Baked 12 probes"), r["confirmed_message"]


@pytest.mark.skipif(shutil.which("xvfb-run") is None, reason="xvfb-run not installed")
def test_modal_adaptive_bake_finishes_and_esc_and_sigint_cancel(tmp_path):
    # The same session with Placement Adaptive: the modal operator steps through the passes (one
    # point, two half renders, per timer tick), Esc and SIGINT cancel it mid-pass and nothing is
    # written; Confirm Above applies to the first pass's probe count.
    cmd = ["xvfb-run", "-a", "-s", "-screen 0 1280x800x24", "blender", "--factory-startup",
           "--enable-event-simulate", "--python-exit-code", "1", "-P", str(SCRIPT), "--", str(tmp_path)]
    env = {**os.environ, "PYTHONPATH": str(ADDON_DIR), "SCHNEE_REPO": str(REPO),
           "SCHNEE_MODAL_PLACEMENT": "ADAPTIVE"}
    proc = subprocess.run(cmd, capture_output=True, text=True, timeout=600, env=env)
    lines = [l for l in proc.stdout.splitlines() if l.startswith("RESULT ")]
    assert lines, proc.stdout[-3000:] + proc.stderr[-2000:]
    r = json.loads(lines[-1][7:])
    assert r["start"] == ["RUNNING_MODAL"] and r["running_after_start"]
    # Sky only: the light is the same everywhere, so the 2 m cells of the 4 x 2 x 2 m volume stay
    # (3 x 2 x 2 corners, 1 pass).
    assert r["finished_message"].startswith("Baked 12 probes (") and "in 1 pass)" in r["finished_message"], r
    assert r["file"] and r["engine_after"] == "BLENDER_EEVEE"
    assert r["cancel_message"].startswith("Bake cancelled") and r["file_unchanged"]
    assert r["sigint_message"].startswith("Bake cancelled") and r["sigint_file_unchanged"]
    assert r["sigint_handler_after"]
    assert r["large_result"] == ["CANCELLED"] and "12 probes" in r["large_message"]
    assert r["large_file_unchanged"]
    assert r["confirmed_message"].startswith("Baked 12 probes (")
