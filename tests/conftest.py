"""Shared pytest helpers: repository paths, running scripts in real headless Blender, and the test
tiers (markers assigned here by folder and by what a test launches; registered in pyproject.toml)."""
import contextlib
import fcntl
import functools
import inspect
import os
import re
import subprocess
import sys
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parent.parent
ADDON_DIR = REPO / "addon"
BUILD_DIR = REPO / "build"
STUDIOLIGHTS = Path("/usr/share/blender/datafiles/studiolights/world")

# The add-on package (and the built native module inside it) importable from plain Python tests.
if str(ADDON_DIR) not in sys.path:
    sys.path.insert(0, str(ADDON_DIR))


def run_blender(script, *args, blend=None, timeout=900, check=True, env=None):
    """Run `blender -b [blend] --factory-startup -P script -- args...` and return CompletedProcess.

    The add-on folder is put on PYTHONPATH so scripts can `import schnee_probes`. Output is captured
    (text); on check=True a non-zero exit raises with Blender's output in the message.
    """
    cmd = ["blender", "-b"]
    if blend is not None:
        cmd.append(str(blend))
    cmd += ["--factory-startup", "--python-exit-code", "1", "-P", str(script), "--"]
    cmd += [str(a) for a in args]
    full_env = dict(os.environ)
    full_env["PYTHONPATH"] = str(ADDON_DIR) + os.pathsep + full_env.get("PYTHONPATH", "")
    full_env.setdefault("SCHNEE_REPO", str(REPO))
    if env:
        full_env.update(env)
    proc = subprocess.run(cmd, capture_output=True, text=True, timeout=timeout, env=full_env)
    if check and proc.returncode != 0:
        raise AssertionError(
            f"blender exited {proc.returncode}: {' '.join(cmd)}\n--- stdout\n{proc.stdout[-6000:]}"
            f"\n--- stderr\n{proc.stderr[-4000:]}")
    return proc


BLENDER_CHROOT = REPO / "scripts" / "blender-chroot.sh"


def addon_chroot(suite):
    """(root, libs) to run this tree's add-on in the Blender chroot ``suite`` (scripts/blender-chroot.sh,
    made when missing): the chroot's root folder and the add-on package build's lib/ (build/addon_zip:
    qhull and Embree, which the chroots lack). Skips without root, without debootstrap for a missing
    chroot, or without the package build."""
    import shutil
    if os.geteuid() != 0:
        pytest.skip("entering the Blender chroots needs root")
    if shutil.which("debootstrap") is None and not Path(f"/var/cache/schnee-chroots/{suite}").exists():
        pytest.skip("debootstrap missing (scripts/deps.sh installs it)")
    libs = BUILD_DIR / "addon_zip" / "schnee_probes" / "lib"
    if not libs.is_dir():
        pytest.skip("no add-on package build (cmake --build build): its lib/ holds qhull and Embree")
    proc = subprocess.run([str(BLENDER_CHROOT), "ensure", suite], capture_output=True, text=True, timeout=1800)
    assert proc.returncode == 0, proc.stderr[-4000:]
    return Path(proc.stdout.strip().splitlines()[-1]), libs


@contextlib.contextmanager
def file_lock(path):
    """An exclusive flock on `path` (created if missing) for the with-block: what the tests share
    between pytest-xdist workers (./test.sh runs two) is made or changed by one worker at a time."""
    Path(path).parent.mkdir(parents=True, exist_ok=True)
    with open(path, "a") as fh:
        fcntl.flock(fh, fcntl.LOCK_EX)
        try:
            yield
        finally:
            fcntl.flock(fh, fcntl.LOCK_UN)


def build_target(target, timeout=900):
    """`cmake --build build --target TARGET` (a no-op when up to date), one at a time across workers
    (two ninja runs in one build tree would race); False when there is no configured build."""
    if not (BUILD_DIR / "build.ninja").exists():
        return False
    with file_lock(BUILD_DIR / "test-build.lock"):
        proc = subprocess.run(["cmake", "--build", str(BUILD_DIR), "--target", target], timeout=timeout,
                              capture_output=True, text=True)
    assert proc.returncode == 0, f"cmake --build build --target {target}: exit {proc.returncode}\n" + \
        (proc.stdout + proc.stderr)[-4000:]
    return True


def once_per_run(stamp, make):
    """Runs make() once per test run, also across pytest-xdist workers: the first worker to get here
    runs it under a lock and writes `stamp` (this run's id) when it succeeded; the others wait on the
    lock and reuse its result. A later run makes it anew (it never trusts an earlier run's output)."""
    run_id = os.environ.get("PYTEST_XDIST_TESTRUNUID") or f"pid-{os.getpid()}"
    stamp = Path(stamp)
    with file_lock(stamp.with_name(stamp.name + ".lock")):
        if stamp.exists() and stamp.read_text() == run_id:
            return
        stamp.unlink(missing_ok=True)
        make()
        stamp.write_text(run_id)


def native_ready():
    """True when the built native module imports and answers (cmake --build build)."""
    try:
        from schnee_probes import native
        native.min_panorama_size(2)
        return True
    except Exception:
        return False


requires_native = pytest.mark.skipif(not native_ready(),
                                     reason="native module not built (cmake --build build)")


@pytest.fixture
def blender():
    return run_blender


# Under ./test.sh every dependency is installed and everything is built, so a test that skips
# ("module not built", "xvfb-run missing", ...) means the setup is broken: count it as a failure
# there instead of letting a green run hide it. Plain pytest runs keep the skips.
STRICT_SKIPS = os.environ.get("SCHNEE_STRICT_SKIPS") == "1"


@pytest.hookimpl(hookwrapper=True)
def pytest_runtest_makereport(item, call):
    outcome = yield
    report = outcome.get_result()
    if STRICT_SKIPS and report.skipped and not hasattr(report, "wasxfail"):
        reason = report.longrepr[2] if isinstance(report.longrepr, tuple) else str(report.longrepr)
        report.outcome = "failed"
        report.longrepr = f"skipped under ./test.sh (SCHNEE_STRICT_SKIPS=1), which installs and builds everything: {reason}"


# --- Test tiers ------------------------------------------------------------------------------------
# Markers are assigned here, not in the test files: by folder, by the `blender` fixture or an imported
# run_blender, and by the lists below for tests that launch Blender or the engine some other way.
# `./test.sh fast` runs -m "not (blender or chroot or engine or slow)"; plain ./test.sh runs all.
MARKER_FOLDERS = {
    "tests/blender/": ("blender",),
    # Blender 4.3 / 5.2 in chroots, then the host's engine on their export.
    "tests/blender_versions/": ("chroot", "blender", "engine"),
    "tests/build_versions/": ("chroot",),
    "tests/engine/": ("engine",),
    "tests/farm/": ("farm",),
    "tests/bench/": ("bench",),
}
# Modules (path) and single tests (node id) that start Blender or the engine through a script or a
# subprocess rather than run_blender, and tests too slow for the fast tier on their own.
MARKER_TESTS = {
    "tests/python/test_packaging.py": ("slow",),  # pip builds the wheel: a CMake build of the module
    # Over ~30 s on 2 cores by themselves (measured in earlier full runs, or their docstrings' runtime),
    # so that -m "blender and not slow" is a quick pass over the add-on in real Blender.
    "tests/blender/test_direct_sky.py": ("slow",),  # ~3 min: Nishita captures, a 4096x2048 reference
    "tests/blender/test_sky_sun_bake.py": ("slow",),  # ~1-2.5 min: a Nishita capture
    "tests/blender/test_resume.py": ("slow",),  # ~2 min: bakes killed and resumed, shards
    "tests/blender/test_refine_bake.py": ("slow",),  # ~45-60 s
    "tests/blender/test_addon_modal.py": ("slow",),  # ~30-40 s
    "tests/blender/test_direct_light.py": ("slow",),  # ~35 s: seven 512x256 renders at 256 spp
    "tests/blender/test_lights.py": ("slow",),  # ~45 s
    "tests/farm/test_slurm.py": ("slow",),  # ~2 min: a Slurm cluster, 3 chained arrays
    "tests/bench/test_sweep_reduced.py": ("blender", "slow"),  # ~1 min; bench/sweep/run.py bakes in Blender
    "tests/test_main_job.py": ("blender", "engine", "slow"),  # scripts/main_job.py: generate, bake, export, render
}


def _markers_of(item):
    path = Path(str(item.fspath)).resolve().relative_to(REPO).as_posix()
    names = set()
    for folder, marks in MARKER_FOLDERS.items():
        if path.startswith(folder):
            names.update(marks)
    for key, marks in MARKER_TESTS.items():
        if key in (path, item.nodeid) or item.nodeid.startswith(key + "["):
            names.update(marks)
    if "blender" in getattr(item, "fixturenames", ()) or _launches_blender(getattr(item, "function", None)):
        names.add("blender")
    fixtures = getattr(getattr(item, "_fixtureinfo", None), "name2fixturedefs", {})
    if any(_launches_blender(d.func) for defs in fixtures.values() for d in defs):
        names.add("blender")
    return names


_BLENDER_CALL = re.compile(r'run_blender\(|\[\s*"blender",')


@functools.lru_cache(maxsize=None)
def _launches_blender(func):
    """True when a test or fixture function calls run_blender or runs ["blender", ...] itself."""
    try:
        return bool(_BLENDER_CALL.search(inspect.getsource(func)))
    except (TypeError, OSError):
        return False


# --- Order under pytest-xdist ----------------------------------------------------------------------
# ./test.sh runs pytest on two workers with --dist loadfile: each file goes whole to one worker, in
# collection order, as a worker runs low. So the longest files go first and both workers end together:
# the files below (the longest measured, longest first), then every other file marked slow or chroot,
# then the rest in their usual order. The list is only a hint: a new file needs no entry (one with a
# slow or chroot marker goes early anyway). A serial run keeps the usual order.
LONG_FILES_FIRST = [
    "tests/blender/test_direct_sky.py",
    "tests/blender/test_resume.py",
    "tests/blender_versions/test_blender_versions.py",
    "tests/build_versions/test_build_newer.py",
    "tests/farm/test_slurm.py",
    "tests/blender/test_bake_hazards.py",
    "tests/blender/test_sky_sun_bake.py",
    "tests/blender/test_addon_modal.py",
    "tests/web/test_web_page.py",
    "tests/blender/test_refine_bake.py",
]


def _run_order(items):
    """items sorted by their file's rank (LONG_FILES_FIRST, then slow/chroot files, then the rest),
    files kept whole and in their usual order within a rank (the same order on every worker)."""
    first_index, rank = {}, {}
    for i, item in enumerate(items):
        path = item.nodeid.split("::", 1)[0]
        first_index.setdefault(path, i)
        r = LONG_FILES_FIRST.index(path) if path in LONG_FILES_FIRST else (
            len(LONG_FILES_FIRST) if item.get_closest_marker("slow") or item.get_closest_marker("chroot") else
            len(LONG_FILES_FIRST) + 1)
        rank[path] = min(rank.get(path, r), r)
    return sorted(items, key=lambda it: (rank[it.nodeid.split("::", 1)[0]], first_index[it.nodeid.split("::", 1)[0]]))


def pytest_collection_modifyitems(config, items):
    for item in items:
        for name in sorted(_markers_of(item)):
            item.add_marker(name)
    if os.environ.get("PYTEST_XDIST_WORKER"):
        items[:] = _run_order(items)
