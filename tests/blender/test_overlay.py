"""The viewport probe overlay (issue 31 item 1, docs/overlay.md) drawn by Blender 3.4's gpu module.

scripts/overlay_draw.py runs in a real (not ``-b``) Blender under Xvfb (3.4 has no GPU context in
background mode; Mesa's llvmpipe draws), ~10 s. Expected values: the CPU model, native.irradiance
(the C evaluator of DESIGN.md §3) of the coefficients read back from the file, at the centre pixel's
normal (the direction back to the orthographic camera, exact there), / π × probe scale × 2^exposure,
sRGB-encoded. Tolerance: 1 code of the 8-bit offscreen (the shader writes float, the framebuffer
rounds to 1/255; llvmpipe's float32 adds < 1e-5). The view transform is not involved (docs/overlay.md).
The same script runs in Blender 4.3 / 5.2: tests/blender_versions/test_overlay_versions.py.
"""
import json
import os
import shutil
import subprocess

import numpy as np
import pytest

from conftest import ADDON_DIR, REPO

SCRIPT = REPO / "tests" / "blender" / "scripts" / "overlay_draw.py"
TOLERANCE_CODES = 1.0


def srgb_codes(linear):
    c = np.clip(np.asarray(linear, np.float64), 0.0, 1.0)
    return 255.0 * np.where(c <= 0.0031308, 12.92 * c, 1.055 * c ** (1 / 2.4) - 0.055)


def check_pixels(pixels):
    """Every drawn centre pixel against the CPU model (or the colour of its stored value); returns
    the largest difference in codes."""
    worst = 0.0
    bad = []
    for p in pixels:
        diff = np.abs(np.asarray(p["code"], float) - srgb_codes(p["want"])).max()
        worst = max(worst, diff)
        if diff > TOLERANCE_CODES:
            bad.append(p)
    assert not bad, bad[:4]
    return worst


@pytest.fixture(scope="module")
def drawn(tmp_path_factory):
    if shutil.which("xvfb-run") is None:
        pytest.skip("xvfb-run not installed")
    out = tmp_path_factory.mktemp("overlay")
    cmd = ["xvfb-run", "-a", "-s", "-screen 0 800x600x24", "blender", "--factory-startup",
           "--python-exit-code", "1", "-P", str(SCRIPT), "--", str(out)]
    env = {**os.environ, "PYTHONPATH": str(ADDON_DIR), "SCHNEE_REPO": str(REPO)}
    proc = subprocess.run(cmd, capture_output=True, text=True, timeout=600, env=env)
    path = out / "result.json"
    assert path.exists(), proc.stdout[-3000:] + proc.stderr[-3000:]
    result = json.loads(path.read_text())
    result["stderr"] = proc.stderr
    return result


def test_sphere_centre_equals_cpu_irradiance(drawn):
    """3 probes (constant, linear in n, with band 2) x 7 view directions x 2 files (v1 grid
    positions, v2 explicit positions): 42 pixels, each within 1 code of the CPU model."""
    assert "error" not in drawn, drawn.get("error")
    worst = check_pixels(drawn["pixels"])
    modes = [p["mode"] for p in drawn["pixels"]]
    assert modes.count("IRRADIANCE") == 42 and modes.count("VALIDITY") == 6
    print(f"worst difference {worst:.3f} codes ({drawn['renderer']}, Blender {drawn['version']})")


def test_linear_probe_varies_with_normal(drawn):
    """Not a constant colour by accident: the linear probe's pixels differ between opposite views
    as the closed form says (E(n) − E(−n) = 2 · 2π/3 · Σ L1m Y1m(n))."""
    px = [p for p in drawn["pixels"] if p["file"] == 0 and p["probe"] == 1 and p["mode"] == "IRRADIANCE"]
    codes = {tuple(p["view"]): np.asarray(p["code"]) for p in px}
    assert np.abs(codes[(0, -1, 0)] - codes[(0, 1, 0)]).max() > 20


def test_files_read_and_described(drawn):
    files = drawn["files"]
    assert [f["error"] for f in files] == [None, None]
    assert [f["version"] for f in files] == [1, 2]
    assert [f["probes"] for f in files] == [3, 3]
    assert "no validity" in files[0]["holds"] and "validity" in files[1]["holds"]
    assert drawn["cells_picture_nonblack"] > 1000  # spheres and cell lines reached the picture


def test_missing_and_malformed_files_are_messages(drawn):
    err = drawn["errors"]
    assert err["missing"]["probes"] == 0 and "not found" in err["missing"]["error"]
    assert err["malformed"]["probes"] == 0 and err["malformed"]["error"].startswith("bad.shprobe: ")
    assert "Traceback" not in drawn["stderr"]


def test_cache_rereads_a_new_bake(drawn):
    r = drawn["reload"]
    assert r["cached"] and r["reread"]
    assert r["l00_ratio"] == pytest.approx(2.0, rel=1e-6)


def test_scene_files_are_the_bakes_outputs(drawn):
    files = drawn["scene_files"]
    assert [os.path.basename(f) for f in files] == ["grid.shprobe", "points.shprobe"]


def test_viewport_handler_draws_the_scene_files(drawn):
    """Blender's own 3D Viewport redraw (wm.redraw_timer) runs the POST_VIEW handler: both files of
    the scene get their probe texture, no error is kept for the panel; the panel itself is drawn
    (its files listed) without an exception. The files are read with no Python thread (a native one):
    Blender 3.4 crashes when a Python thread runs while it draws (docs/overlay.md)."""
    assert drawn["viewport"] == {"drawn": ["grid.shprobe", "points.shprobe"], "error": None, "panel_drawn": True,
                                 "pending_after_first_redraw": ["grid.shprobe", "points.shprobe"],
                                 "python_threads_while_reading": 1}
    assert "Traceback" not in drawn["stderr"]


def test_noise_and_refinement_colours_equal_the_stored_values(drawn):
    """tree.shprobe (v3, 1 + 8 leaves, 26 probes) with its sidecar: every probe's sphere in Noise
    (σ from 0 to 1.3 x the tolerance, one not measured: grey), every leaf's sphere in Refinement
    (one per reason), within 1 code of overlay_data.noise_colours / refinement_colours of the stored
    values; the Refinement lines' pixels are each a leaf's colour (within 1 code)."""
    m = drawn["modes"]
    assert m["has_noise"] and m["has_refinement"], m["holds"]
    worst = check_pixels(m["pixels"])
    kinds = [p["mode"] for p in m["pixels"]]
    assert kinds.count("REFINEMENT") == 9 and kinds.count("NOISE") == 26
    assert m["line_pixels"] > 200 and m["line_worst"] <= TOLERANCE_CODES
    print(f"modes: worst difference {worst:.3f} codes, lines {m['line_worst']:.3f} codes")


def test_files_without_or_with_a_bad_sidecar_say_so(drawn):
    m = drawn["modes"]
    w = m["without"]
    assert not w["has_noise"] and w["line"].startswith("Noise, refinement: not stored for this file (baked before")
    assert np.abs(np.asarray(w["code"], float) - srgb_codes(w["want"])).max() <= TOLERANCE_CODES  # grey
    e = m["sidecar_errors"]
    assert all(v["error"] is None and not v["has_noise"] for v in e.values()), e
    assert e["mismatched"]["line"] == ("points.shprobe.bakeinfo: written for another bake of the .shprobe "
                                       "(its SHA-256 differs); ignored")
    assert e["truncated"]["line"].startswith("points.shprobe.bakeinfo: ") and e["truncated"]["line"].endswith("ignored")
    assert e["not_npz"]["line"].startswith("points.shprobe.bakeinfo: ")
    assert "Traceback" not in drawn["stderr"]
