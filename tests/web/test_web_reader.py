"""The JavaScript `.shprobe` reader (web/src/shprobe.js, issue 32) through Node's test runner.

web/test/ makes its fixtures with the project's real writer and records the C reader's verdict on each
(web/test/make_fixtures.py: every version 1-4, structure, representation and storage, one malformed
variant per refusal of the C reader, seeded random corruptions); the JS reader must read the same
values exactly and refuse with the same result code and message. This runs `npm ci` in web/ when its
node_modules is missing (scripts/deps.sh installs it under ./test.sh), then `node --test`.
Skipped only when Node itself is absent (a failure under ./test.sh, SCHNEE_STRICT_SKIPS). Runtime ~3 s."""
import os
import shutil
import subprocess
import sys

import pytest

from conftest import REPO

WEB = REPO / "web"


def test_node_reader_tests_pass():
    node = shutil.which("node") or shutil.which("nodejs")
    if node is None:
        pytest.skip("node is not installed (scripts/deps.sh installs nodejs)")
    if not (WEB / "node_modules").is_dir():
        npm = shutil.which("npm")
        assert npm is not None, "web/node_modules is missing and npm is not installed (scripts/deps.sh installs npm)"
        r = subprocess.run([npm, "ci", "--no-audit", "--no-fund", "--loglevel=error"], cwd=WEB,
                           capture_output=True, text=True, timeout=600)
        assert r.returncode == 0, f"npm ci in web/ failed (exit {r.returncode}):\n{r.stdout[-4000:]}\n{r.stderr[-4000:]}"
    tests = sorted(str(p.relative_to(WEB)) for p in (WEB / "test").glob("*.test.js"))
    assert tests, "no web/test/*.test.js"
    env = dict(os.environ, SCHNEE_PYTHON=sys.executable)  # make_fixtures.py needs numpy and the native module
    env.pop("SHPROBE_FIXTURES", None)
    r = subprocess.run([node, "--test", *tests], cwd=WEB, capture_output=True, text=True, env=env, timeout=600)
    out = r.stdout + r.stderr
    assert r.returncode == 0, f"node --test {' '.join(tests)} failed (exit {r.returncode}):\n{out[-15000:]}"
    assert "# fail 0" in out and "# pass 0" not in out, out[-3000:]
