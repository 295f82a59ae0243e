"""The house's size limits (issue 28), measured by scripts/code_sizes.py on the working tree.

- no C file of the product above 900 lines (the generated ones are not in the tree: SPIR-V
  initializers are written to the build folder);
- no add-on class above 400 lines, the bake driver (bake_core.ProbeBake) at most 300;
- Embree is called (``rtc*``) only by the occluder module and the Embree loader (native/src), and
  its headers are private to native/src;
- the engine writes no temporary file (embedded glTF images are decoded from memory).
"""
from __future__ import annotations

import importlib.util
import re
import subprocess
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]
_spec = importlib.util.spec_from_file_location("code_sizes", ROOT / "scripts" / "code_sizes.py")
code_sizes = importlib.util.module_from_spec(_spec)
_spec.loader.exec_module(code_sizes)

# The files that may call Embree: the occluder module and the dlsym loader that resolves Embree's
# functions for the Python module (pb_embree_dyn.*), and Embree's compatibility header.
RTC_ALLOWED = re.compile(r"^native/src/(pb_occluder\.c|pb_embree_dyn\.[ch]|pb_embree_compat\.h)$")


@pytest.fixture(scope="module")
def sizes():
    return code_sizes.report(ROOT, 10_000)


def test_c_files_at_most_900_lines(sizes):
    over = [(f, n) for f, n in sizes["files"] if f.endswith(code_sizes.C_SUFFIXES) and n > code_sizes.C_FILE_LIMIT]
    assert over == []


def test_addon_classes_at_most_400_lines(sizes):
    over = [(f, c, n) for f, c, n in sizes["py_classes"] if n > code_sizes.PY_CLASS_LIMIT]
    assert over == []


def test_bake_driver_at_most_300_lines(sizes):
    driver = [n for f, c, n in sizes["py_classes"] if c == "ProbeBake"]
    assert len(driver) == 1 and driver[0] <= code_sizes.DRIVER_LIMIT


def _grep(pattern, *paths):
    out = subprocess.run(["git", "grep", "-n", "-E", pattern, "--", *paths], cwd=ROOT, capture_output=True,
                         text=True)
    assert out.returncode in (0, 1), out.stderr
    return out.stdout.splitlines()


def test_embree_only_in_the_occluder_module():
    hits = [h for h in _grep(r"\brtc[A-Z][A-Za-z0-9]*\s*\(", "native", "engine")
            if not RTC_ALLOWED.match(h.split(":", 1)[0])]
    assert hits == []
    assert not list((ROOT / "native" / "include").rglob("*embree*"))
    includes = [h for h in _grep(r"#\s*include\s*[<\"](embree|pb_embree)", "native", "engine")
                if not h.startswith("native/src/")]
    assert includes == []


def test_engine_writes_no_temporary_file():
    assert _grep(r"/tmp", "engine/src") == []
