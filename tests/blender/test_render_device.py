"""Render Device (settings.render_device: 'SCENE', 'CPU', 'GPU') on this machine, which has no GPU,
in Blender 3.4 (the host) and in 4.3 and 5.2 (the Debian chroots of scripts/blender-chroot.sh).

scripts/render_device.py bakes one point (16x8 px, 1 spp, 2 bounces) five times: GPU asked for in a
scene set to GPU Compute, CPU in a CPU and in a GPU scene, and As the scene is set in either. The
expected values are the CPU bake's own: every one of these renders on the CPU here, so the probe
values must be equal bit for bit, and the scene's device must be back as it was set. Runtime: ~3 s
per Blender (2 cores), plus the chroots' creation the first time (scripts/blender-chroot.sh).
"""
import json
import os
import re
import shutil
import subprocess
from pathlib import Path

import pytest

from conftest import ADDON_DIR, BLENDER_CHROOT as CHROOT, REPO, addon_chroot, requires_native, run_blender

HERE = Path(__file__).resolve().parent
SCRIPT = HERE / "scripts" / "render_device.py"
NO_GPU = "no GPU available"
CPU_LABEL = re.compile(r"^CPU \(\d+ threads?\)$")


def _result(stdout):
    lines = [l[l.index("RESULT {") + 7:] for l in stdout.splitlines() if "RESULT {" in l]
    assert lines, stdout[-4000:]
    return json.loads(lines[-1])


def _in_chroot(suite):
    """Run the script in the chroot's Blender on a copy of the add-on (with the native module's
    libraries from the add-on package build/addon_zip, which the chroots lack)."""
    root, libs = addon_chroot(suite)
    inner = Path("/tmp") / f"schnee-render-device-{os.getpid()}-{suite}"
    outer = root / inner.relative_to("/")
    shutil.rmtree(outer, ignore_errors=True)
    try:
        shutil.copytree(ADDON_DIR / "schnee_probes", outer / "schnee_probes",
                        ignore=shutil.ignore_patterns("__pycache__"))
        shutil.copytree(libs, outer / "schnee_probes" / "lib")
        shutil.copy(SCRIPT, outer / SCRIPT.name)
        proc = subprocess.run([str(CHROOT), "run", suite, "--", "blender", "-b", "--factory-startup",
                               "--python-exit-code", "1", "-P", str(inner / SCRIPT.name), "--", str(inner)],
                              capture_output=True, text=True, timeout=300)
    finally:
        shutil.rmtree(outer, ignore_errors=True)
    assert proc.returncode == 0, proc.stdout[-4000:] + proc.stderr[-3000:]
    return proc.stdout


@requires_native
@pytest.mark.parametrize("suite", ["host", pytest.param("trixie", marks=pytest.mark.chroot),
                                   pytest.param("sid", marks=pytest.mark.chroot)])
def test_render_device_without_gpu(suite):
    if suite == "host":
        stdout = run_blender(SCRIPT, ADDON_DIR, timeout=300).stdout
    else:
        stdout = _in_chroot(suite)
    r = _result(stdout)
    cases = r["cases"]
    want = {"host": (3, 4), "trixie": (4, 3), "sid": (5, 2)}[suite]
    assert tuple(r["version"][:2]) == want

    # GPU asked for, no GPU: Cycles is given the CPU, the label and one log line say so, and the
    # scene's GPU Compute is back afterwards.
    gpu = cases["gpu_on_gpu_scene"]
    assert (gpu["during"], gpu["after"]) == ("CPU", "GPU")
    assert CPU_LABEL.match(gpu["label"]), gpu["label"]
    said = [l for l in stdout.splitlines() if l.startswith("Schnee: Render Device GPU")]
    assert len(said) == 1 and NO_GPU in said[0] and "the probes render on the CPU" in said[0], said
    assert "Traceback" not in stdout

    # CPU: set for the bake whatever the scene says, and restored.
    assert (cases["cpu"]["during"], cases["cpu"]["after"]) == ("CPU", "CPU")
    assert (cases["cpu_on_gpu_scene"]["during"], cases["cpu_on_gpu_scene"]["after"]) == ("CPU", "GPU")
    assert CPU_LABEL.match(cases["cpu"]["label"])

    # As the scene is set: scene.cycles.device untouched; a GPU scene renders on the CPU (Cycles'
    # own fallback) and the label says so honestly.
    assert (cases["scene_gpu"]["during"], cases["scene_gpu"]["after"]) == ("GPU", "GPU")
    assert cases["scene_gpu"]["label"].startswith("GPU: none available, CPU (")
    assert any(l.startswith("Schnee: the scene's Device GPU Compute") and NO_GPU in l for l in stdout.splitlines())
    assert (cases["scene_cpu"]["during"], cases["scene_cpu"]["after"]) == ("CPU", "CPU")
    assert CPU_LABEL.match(cases["scene_cpu"]["label"])

    # The expected values: the CPU bake's, bit for bit (every case renders on this CPU, same seed).
    reference = cases["cpu"]["coeffs"]
    assert len(reference) == 27 and any(v != 0.0 for v in reference)
    for name, case in cases.items():
        assert case["coeffs"] == reference, name

    # A compute device type without a device (Debian's builds list CUDA and HIP; none is found here).
    assert r["types"], "this Blender lists no GPU compute device type"
    for kind, t in r["types"].items():
        assert t["devices"] == [] and t["device"] == "CPU", kind
        assert t["gpu_label"].startswith("GPU: none available, CPU (")
        assert t["lines"] == [f"Schnee: Render Device GPU: {NO_GPU} (no {kind} device is found and enabled in "
                              f"Preferences > System > Cycles Render Devices); the probes render on the "
                              f"{t['gpu_label'][len('GPU: none available, '):]}"], t["lines"]

    # The panel says what will render, changing nothing.
    assert r["panel"]["GPU"][0].startswith("Renders on GPU: none available, CPU (")
    assert CPU_LABEL.match(r["panel"]["SCENE"][0][len("Renders on "):])
    assert r["panel"]["GPU"][1] == r["panel"]["SCENE"][1] == "CPU"


def test_device_note():
    """What the estimate and progress lines append: the device, and for a GPU that the estimate
    before the first probes is this CPU's cost model (estimate.py)."""
    from schnee_probes.estimate import device_note
    assert device_note("CPU (2 threads)") == "on CPU (2 threads)"
    assert device_note("GPU: none available, CPU (2 threads)") == "on GPU: none available, CPU (2 threads)"
    assert device_note("GPU: NVIDIA H100 (OPTIX)") == ("on GPU: NVIDIA H100 (OPTIX); the estimate before the "
                                                      "first probes is a 2-core CPU's")


BAKE_PY = REPO / "bake.py"


def test_cli_bogus_render_device():
    proc = run_blender(BAKE_PY, "--cursor", 0, 0, 0, "--render-device", "bogus", check=False, timeout=120)
    assert proc.returncode == 2, proc.stdout[-2000:] + proc.stderr[-2000:]
    assert "--render-device: invalid choice: 'bogus' (choose from 'SCENE', 'CPU', 'GPU')" in proc.stderr
    assert "Traceback" not in proc.stdout + proc.stderr


@requires_native
def test_cli_render_device_gpu_cursor_bake(tmp_path):
    """bake.py --render-device GPU reaches the bake: a cursor bake renders on the CPU here, says why
    in one line, and writes its debug probe."""
    out = tmp_path / "sh" / "probes.shprobe"
    proc = run_blender(BAKE_PY, "--cursor", 0, 0, 1, "--render-device", "GPU", "--panorama-resolution", 16,
                       "--samples", 1, "--max-bounces", 2, "--output", out, timeout=120)
    said = [l for l in proc.stdout.splitlines() if l.startswith("Schnee: Render Device GPU")]
    assert len(said) == 1 and NO_GPU in said[0], proc.stdout[-3000:]
    assert "Traceback" not in proc.stdout + proc.stderr
    assert (out.parent / "debug_probe.txt").is_file()
