"""The tree builds from source on newer Debian releases too: Debian 13 (trixie: Embree 4.3,
OpenImageIO 2.5, GCC 14, CMake 3.31) and Debian unstable (sid: Embree 4.4, OpenImageIO 3.1, GCC 16,
CMake 4.3, Python 3.14), while the host (Debian 12: Embree 3.13, OpenImageIO 2.4) is the rest of the
suite. scripts/build-chroot.sh copies the checkout into a dev chroot (scripts/blender-chroot.sh
SUITE-dev: that release's build dependencies and nothing of ours, created when missing, cached in
/var/cache/schnee-chroots and reused), configures with -DSCHNEE_WERROR=ON, builds everything (core,
Python module, engine, tests, add-on zip), runs `ctest -L native` there and imports the Python
module with the release's python3 for a closed-form placement (tests/build_versions/module_check.py).

Runtime on 2 shared cores (measured): first run per release, chroot creation + clean build + tests,
260 s (trixie) and 86-185 s (sid); a rerun with the chroot and its build tree cached 12 s each
(only changed files rebuild; all three tests of this file 24 s). A fresh clone or worktree reruns as
fast: scripts/sync_tree.py copies only files whose bytes differ, so the checkout's new mtimes
rebuild nothing (sid from a fresh worktree: 9.9 s, was 70 s when the whole tree was copied).
"""
import os
import re
import shutil
import subprocess
from pathlib import Path

import pytest

from conftest import BUILD_DIR, REPO

SCRIPT = REPO / "scripts" / "build-chroot.sh"
# Per release: Embree major, lowest OpenImageIO (major, minor) it must have (Debian's packages).
RELEASES = {"trixie": (4, (2, 5)), "sid": (4, (3, 0))}
NATIVE_TESTS = sorted(p.stem for p in (REPO / "tests" / "native").glob("test_*.c"))


@pytest.mark.parametrize("suite", list(RELEASES))
def test_builds_and_passes_native_tests(suite):
    if os.geteuid() != 0:
        pytest.skip("creating/entering the dev chroots needs root")
    if shutil.which("debootstrap") is None and not Path(f"/var/cache/schnee-chroots/{suite}-dev").exists():
        pytest.skip("debootstrap missing (scripts/deps.sh installs it)")
    proc = subprocess.run([str(SCRIPT), suite], capture_output=True, text=True, timeout=3000)
    out = proc.stdout + proc.stderr
    assert proc.returncode == 0, f"exit {proc.returncode}\n{out[-8000:]}"

    embree_major, oiio_min = RELEASES[suite]
    m = re.search(r"Building against Embree (\d+)\.(\d+)\.(\d+) and OpenImageIO (\d+)\.(\d+)\.(\d+)", out)
    assert m, out[-4000:]
    assert int(m.group(1)) == embree_major, m.group(0)
    assert (int(m.group(4)), int(m.group(5))) >= oiio_min, m.group(0)

    # Every C test of tests/native ran and passed, nothing failed.
    passed = set(re.findall(r"Test +#\d+: native\.(\w+) \.+ +Passed", out))
    assert set(NATIVE_TESTS) <= passed, sorted(set(NATIVE_TESTS) - passed)
    assert re.search(r"100% tests passed, 0 tests failed out of \d+", out), out[-4000:]

    # The Python module loaded the release's Embree (through pb_embree_dyn.c) and placed the probes.
    m = re.search(r"MODULE_OK (\S+) (\S+)", out)
    assert m, out[-4000:]
    assert m.group(2).endswith(f"/libembree{embree_major}.so.{embree_major}"), m.group(0)


def test_host_builds_against_embree3():
    """The host build (Debian 12) stays on Embree 3, so both majors are built by the suite."""
    cache = BUILD_DIR / "CMakeCache.txt"
    if not cache.exists():
        pytest.skip("no host build (scripts/build.sh)")
    m = re.search(r"^embree_DIR:PATH=(.*)$", cache.read_text(), re.M)
    assert m and "embree-3" in m.group(1), m.group(0) if m else "embree_DIR not in CMakeCache.txt"
