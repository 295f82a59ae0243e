"""The add-on zip from the standard build installs into a fresh Blender user profile, enables, and
its operators bake. Runtime: ~10 s."""
import glob
import subprocess
from pathlib import Path

import pytest

from conftest import BUILD_DIR, REPO, run_blender

SCRIPTS = Path(__file__).resolve().parent / "scripts"


def _zip():
    zips = sorted(z for z in glob.glob(str(REPO / "dist" / "schnee_probes-*.zip")) if "-extension" not in z)
    if not zips and (BUILD_DIR / "build.ninja").exists():
        subprocess.run(["cmake", "--build", str(BUILD_DIR), "--target", "schnee_addon_zip"], check=True)
        zips = sorted(z for z in glob.glob(str(REPO / "dist" / "schnee_probes-*.zip")) if "-extension" not in z)
    return zips[-1] if zips else None


def test_zip_contents():
    import zipfile
    z = _zip()
    if z is None:
        pytest.skip("no add-on zip: run cmake --build build")
    names = zipfile.ZipFile(z).namelist()
    assert "schnee_probes/__init__.py" in names
    assert "schnee_probes/_schnee_native.abi3.so" in names
    assert all(n.startswith("schnee_probes/") for n in names)
    assert not [n for n in names if "__pycache__" in n or n.endswith(".pyc")]


def test_zip_installs_in_fresh_profile_and_bakes(tmp_path):
    z = _zip()
    if z is None:
        pytest.skip("no add-on zip: run cmake --build build")
    env = {
        "BLENDER_USER_CONFIG": str(tmp_path / "config"),
        "BLENDER_USER_SCRIPTS": str(tmp_path / "scripts"),
        "PYTHONPATH": "",  # only the installed copy may be importable
    }
    proc = run_blender(SCRIPTS / "addon_zip_install.py", z, tmp_path / "work", env=env, check=False,
                       timeout=300)
    assert proc.returncode == 0, proc.stdout[-4000:] + proc.stderr[-2000:]
    assert "ZIP-OK" in proc.stdout, proc.stdout[-4000:]
