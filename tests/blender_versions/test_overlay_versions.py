"""The viewport probe overlay (issue 31 item 1) drawn by Blender 4.3 (Debian 13) and 5.2 (Debian
unstable) in their chroots: tests/blender/scripts/overlay_draw.py, the same checks as the host's
tests/blender/test_overlay.py (3.4), same tolerance (1 code of the 8-bit offscreen).

Neither release has a GPU context in ``-b`` (4.3: "not available in background mode"; 5.2 asks for a
headless EGL context, but its chroot has no libEGL), so Blender runs with a window on an Xvfb server
that this test starts on the host, listening on TCP (the chroot shares the network, not /tmp): Mesa's
llvmpipe inside the chroot draws. The add-on is the extension package's native module and bundled
libraries (dist/*-extension.zip) with this tree's Python files over it (no reinstall per edit), on
PYTHONPATH (which 4.x reads only with --python-use-system-env).
"""
import json
import os
import shutil
import subprocess
import sys
import time
import zipfile
from pathlib import Path

import pytest

from conftest import REPO, build_target

sys.path.insert(0, str(REPO / "tests" / "blender"))
from test_overlay import TOLERANCE_CODES, check_pixels  # noqa: E402  (the host test's comparison)

CHROOT = REPO / "scripts" / "blender-chroot.sh"
SCRIPT = REPO / "tests" / "blender" / "scripts" / "overlay_draw.py"
ADDON = REPO / "addon" / "schnee_probes"
SUITES = {"trixie": (4, 3), "sid": (5, 2)}


@pytest.fixture(scope="module")
def xserver():
    """An Xvfb on the host listening on TCP; stopped (by its own pid) at the end."""
    if shutil.which("Xvfb") is None:
        pytest.skip("Xvfb not installed")
    for n in range(140, 180):
        if not os.path.exists(f"/tmp/.X11-unix/X{n}") and not os.path.exists(f"/tmp/.X{n}-lock"):
            break
    proc = subprocess.Popen(["Xvfb", f":{n}", "-listen", "tcp", "-screen", "0", "800x600x24"],
                            stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    for _ in range(100):
        if os.path.exists(f"/tmp/.X11-unix/X{n}"):
            break
        time.sleep(0.05)
    yield f"127.0.0.1:{n}"
    proc.terminate()
    proc.wait(timeout=10)


def _chroot(suite):
    if os.geteuid() != 0:
        pytest.skip("entering the Blender chroots needs root")
    proc = subprocess.run([str(CHROOT), "ensure", suite], capture_output=True, text=True, timeout=1800)
    assert proc.returncode == 0, proc.stderr[-3000:]
    return Path(proc.stdout.strip().splitlines()[-1])


@pytest.fixture(scope="module", params=list(SUITES))
def drawn(request, xserver):
    suite = request.param
    root = _chroot(suite)
    build_target("schnee_extension")  # this file may run before test_blender_versions.py's build of it
    zips = sorted((REPO / "dist").glob("schnee_probes-*-extension.zip"))
    if not zips:
        pytest.skip("no extension package: cmake --build build --target schnee_extension")
    if not any((root / d / "libGL.so.1").exists() for d in ("usr/lib/x86_64-linux-gnu", "usr/lib")):
        # Blender opens its window's GPU context through libGL (GLX) under X11, through libEGL in -b:
        # scripts/blender-chroot.sh installs Mesa (libgl1 libegl1 libgl1-mesa-dri) into every chroot.
        pytest.fail(f"the {suite} chroot has no libGL.so.1: rerun scripts/blender-chroot.sh ensure {suite}")
    inner = Path("/tmp") / f"schnee-overlay-{os.getpid()}-{suite}"
    outer = root / inner.relative_to("/")
    shutil.rmtree(outer, ignore_errors=True)
    (outer / "out").mkdir(parents=True)
    with zipfile.ZipFile(zips[-1]) as z:
        z.extractall(outer / "schnee_probes")
    for py in ADDON.glob("*.py"):   # this tree's Python over the package's
        shutil.copy(py, outer / "schnee_probes" / py.name)
    shutil.copy(SCRIPT, outer / "overlay_draw.py")
    try:
        proc = subprocess.run([str(CHROOT), "run", suite, "--", "env", f"DISPLAY={xserver}",
                               f"PYTHONPATH={inner}", "blender", "--factory-startup", "--python-use-system-env",
                               "--python-exit-code", "1", "-P",
                               str(inner / "overlay_draw.py"), "--", str(inner / "out")],
                              capture_output=True, text=True, timeout=600)
        path = outer / "out" / "result.json"
        assert path.exists(), proc.stdout[-3000:] + proc.stderr[-3000:]
        result = json.loads(path.read_text())
    finally:
        shutil.rmtree(outer, ignore_errors=True)
    result["suite"] = suite
    return result


def test_sphere_centre_equals_cpu_irradiance(drawn):
    assert "error" not in drawn, drawn.get("error")
    assert tuple(drawn["version"][:2]) == SUITES[drawn["suite"]]
    worst = check_pixels(drawn["pixels"])
    assert len(drawn["pixels"]) == 48
    print(f"Blender {drawn['version']} ({drawn['renderer']}): worst difference {worst:.3f} codes")


def test_files_errors_and_reload(drawn):
    assert "error" not in drawn, drawn.get("error")
    assert [f["error"] for f in drawn["files"]] == [None, None]
    assert drawn["cells_picture_nonblack"] > 1000
    assert "not found" in drawn["errors"]["missing"]["error"]
    assert drawn["errors"]["malformed"]["error"].startswith("bad.shprobe: ")
    assert drawn["reload"]["cached"] and drawn["reload"]["reread"]
    assert drawn["viewport"] == {"drawn": ["grid.shprobe", "points.shprobe"], "error": None, "panel_drawn": True,
                                 "pending_after_first_redraw": ["grid.shprobe", "points.shprobe"],
                                 "python_threads_while_reading": 1}


def test_noise_and_refinement_colours(drawn):
    """The host test's Noise / Refinement checks (tests/blender/test_overlay.py): each probe's and
    leaf's centre pixel within 1 code of the colour of its stored value, the lines' pixels leaf
    colours, a file without / with a bad sidecar a message."""
    assert "error" not in drawn, drawn.get("error")
    m = drawn["modes"]
    assert m["has_noise"] and m["has_refinement"], m["holds"]
    worst = check_pixels(m["pixels"])
    assert [p["mode"] for p in m["pixels"]].count("REFINEMENT") == 9
    assert m["line_pixels"] > 200 and m["line_worst"] <= TOLERANCE_CODES
    assert m["without"]["line"].startswith("Noise, refinement: not stored for this file (baked before")
    e = m["sidecar_errors"]
    assert e["mismatched"]["line"].endswith("(its SHA-256 differs); ignored")
    assert all(v["error"] is None and not v["has_noise"] for v in e.values()), e
    print(f"Blender {drawn['version']}: modes worst difference {worst:.3f} codes, lines {m['line_worst']:.3f}")
