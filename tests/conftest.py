"""Shared pytest helpers: repository paths and running scripts in real headless Blender."""
import os
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
