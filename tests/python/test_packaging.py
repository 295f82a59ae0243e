"""pyproject.toml builds a stable-ABI wheel of the add-on package with its native module.

The wheel is built by pip through setup.py's CMake-driven build_ext (Debian's pip and setuptools,
no network), installed into an empty folder, and imported from a fresh interpreter that sees only
that folder and Debian's numpy: the module must load and compute a closed-form projection
(a constant environment c has L00 = c·∫Y00 dω = c·4π·0.282094792 = 2√π·c, DESIGN.md §3).
"""
import math
import os
import subprocess
import sys
import zipfile

from conftest import REPO


def test_wheel_builds_installs_and_projects(tmp_path):
    wheels = tmp_path / "wheels"
    subprocess.run([sys.executable, "-m", "pip", "wheel", str(REPO), "--no-build-isolation",
                    "--no-deps", "--no-index", "-q", "-w", str(wheels)], check=True, timeout=900)
    (wheel,) = wheels.glob("schnee_probes-*.whl")
    assert wheel.name.endswith("-cp311-abi3-linux_x86_64.whl"), wheel.name
    names = zipfile.ZipFile(wheel).namelist()
    assert "schnee_probes/_schnee_native.abi3.so" in names
    assert "schnee_probes/native.py" in names and "schnee_probes/bake_core.py" in names

    target = tmp_path / "site"
    subprocess.run([sys.executable, "-m", "pip", "install", "--no-deps", "--no-index", "-q",
                    "--target", str(target), str(wheel)], check=True, timeout=300)
    code = (
        "import numpy as np, schnee_probes.native as n\n"
        "assert n.__file__.startswith(%r), n.__file__\n"
        "c = np.full((16, 32, 3), 0.5, np.float32)\n"
        "L = n.project_equirect(c, 2)\n"
        "print(L[0, 0], abs(L[1:4, :]).max())\n" % str(target))
    env = {k: v for k, v in os.environ.items() if k != "PYTHONPATH"}
    env["PYTHONPATH"] = str(target)
    out = subprocess.run([sys.executable, "-c", code], check=True, capture_output=True, text=True,
                         env=env, cwd=tmp_path, timeout=120).stdout.split()
    l00, band1 = (float(v) for v in out)
    # Exact: the pixel solid angles sum to 4π exactly (DESIGN.md §3), so L00 = 2√π·0.5 = √π.
    assert abs(l00 - math.sqrt(math.pi)) < 1e-9
    # Band 1 is odd under d → −d, and the equirect grid is symmetric: it cancels to rounding.
    assert band1 < 1e-12
