"""bench/results/ambient_cube.md and docs/ambient-cube.md agree with bench/results/ambient_cube.json
(written by `/usr/bin/python3 bench/bench_ambient_cube.py`), and the bench's closed-form figures
equal the exact fractions derived in docs/ambient-cube.md §3 (which build/native/test_ambient_cube
asserts on the C side): the bench and the derivation cannot drift apart."""
import json
import math
import re
import sys

import pytest

from conftest import REPO, requires_native

sys.path.insert(0, str(REPO / "bench"))
RESULTS = REPO / "bench" / "results"
DOC = REPO / "docs" / "ambient-cube.md"


def _result():
    return json.loads((RESULTS / "ambient_cube.json").read_text(encoding="utf-8"))


@requires_native
def test_report_is_the_rendering_of_the_json():
    import bench_ambient_cube as bench
    assert (RESULTS / "ambient_cube.md").read_text(encoding="utf-8") == bench.render_report(_result())


@pytest.mark.parametrize("case,repr_,want", [
    ("directional, along an axis", "cube LS", math.sqrt(10) / 16),
    ("directional, along an axis", "cube axis L2", math.sqrt(370) / 80),
    ("directional, along an axis", "L2 SH", math.sqrt(2) / 16),
    ("directional, along an axis", "L1 SH", math.sqrt(2) / 4),
    ("directional, diagonal (1,1,1)/sqrt3", "cube LS", math.sqrt(5 / 32)),
    ("directional, diagonal (1,1,1)/sqrt3", "cube axis L2", math.sqrt(7 / 40)),
    ("hemisphere sky (radiance 1, y > 0)", "cube LS", 1 / 8),
    ("hemisphere sky (radiance 1, y > 0)", "cube axis L2", math.sqrt(10) / 20),
    ("constant (radiance 1)", "cube LS", 0.0),
])
def test_closed_form_figures_equal_the_derivation(case, repr_, want):
    # 128-node quadrature; the diagonal light's terminator is off the octant boundaries: 1e-5.
    assert _result()["closed_forms"][case][repr_]["rel_rms"] == pytest.approx(want, abs=1e-5)


def test_doc_quotes_the_measured_table():
    """Every row of the doc's measured table (between the markers) is a row of the bench page."""
    doc = DOC.read_text(encoding="utf-8")
    block = re.search(r"<!-- ambient_cube_table:begin -->\n(.*?)<!-- ambient_cube_table:end -->", doc, re.S)
    assert block, "docs/ambient-cube.md: no ambient_cube_table block"
    page = (RESULTS / "ambient_cube.md").read_text(encoding="utf-8")
    rows = [r for r in block.group(1).splitlines() if r.startswith("| ") and not r.startswith("| scene")]
    assert rows
    for r in rows:
        assert r in page, f"docs/ambient-cube.md row not in bench/results/ambient_cube.md: {r}"
