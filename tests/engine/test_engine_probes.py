"""Per-object probe assignment (DESIGN.md §7) and probe-file handling of schnee-view.

Two generated grids overlap; objects sit in known cells. Expected buffer indices follow from the
layout DESIGN.md §7 fixes: index 0 = fallback, then grid A's probes (1..5), then grid B's (6..8).
"""
import sys
from pathlib import Path

import numpy as np
import pytest

sys.path.insert(0, str(Path(__file__).parent / "scripts"))
import scenegen as sg  # noqa: E402
import viewer  # noqa: E402

A_COUNT, B_COUNT = 5, 3
A_BASE, B_BASE = 1, 1 + A_COUNT

# name: (world centre, expected buffer index, why)
OBJECTS = {
    "InA0": ((0.5, 0.5, 0.5), A_BASE + 0, "grid A cell (0,0,0) -> probe 0"),
    "InA1": ((1.5, 0.5, 2.5), A_BASE + 1, "grid A cell (1,0,2) -> probe 1"),
    "Overlap": ((2.5, 0.5, 0.5), A_BASE + 2, "both grids hold it: A is first and wins (B would give 6)"),
    "HoleInA": ((3.5, 0.5, 1.5), B_BASE + 2, "A cell (3,0,1) is -1, so B cell (1,0,1) -> probe 2"),
    "OnlyB": ((5.5, 0.5, 0.5), B_BASE + 1, "outside A, B cell (3,0,0) -> probe 1"),
    "Outside": ((10.0, 10.0, 10.0), 0, "outside both grids -> fallback"),
    "HoleBoth": ((0.5, 1.5, 0.5), 0, "A cell (0,1,0) is -1 and B does not reach x = 0.5 -> fallback"),
}
# Child of "Parent" (translation (1,1,1)) at local (0.5,0.5,0.5): world (1.5,1.5,1.5), A cell (1,1,1).
CHILD_EXPECTED = A_BASE + 4
CAMERA_POS = (2.75, 1.0, 9.0)
YFOV, W, H = 0.9, 192, 128


def make_grids(d):
    a = np.full((3, 2, 4), -1, np.int32)  # (Z, Y, X)
    a[0, 0, 0], a[2, 0, 1], a[0, 0, 2], a[0, 0, 3], a[1, 1, 1] = 0, 1, 2, 3, 4
    b = np.full((3, 2, 4), -1, np.int32)
    b[0, 0, 0], b[0, 0, 3], b[1, 0, 1] = 0, 1, 2
    # Distinct constant colours per probe (L_00 only) so a mix-up would also show in shading.
    ca = np.zeros((A_COUNT, 9, 3))
    ca[:, 0, 0] = np.arange(1, A_COUNT + 1)
    cb = np.zeros((B_COUNT, 9, 3))
    cb[:, 0, 1] = np.arange(1, B_COUNT + 1)
    (d / "sh_coeffs").mkdir(exist_ok=True)
    sg.write_shprobe_v1(d / "sh_coeffs" / "a.shprobe", ca, a, (0, 0, 0), 1.0)
    sg.write_shprobe_v1(d / "sh_coeffs" / "b.shprobe", cb, b, (2, 0, 0), 1.0)
    return [sg.grid_entry("a", "sh_coeffs/a.shprobe", A_COUNT, (0, 0, 0), (4, 2, 3), 1.0),
            sg.grid_entry("b", "sh_coeffs/b.shprobe", B_COUNT, (2, 0, 0), (4, 2, 3), 1.0)]


def make_scene(d, entries=None):
    entries = make_grids(d) if entries is None else entries
    b = sg.GltfBuilder()
    mat = b.material("grey", base_color=(0.5, 0.5, 0.5, 1))
    cube = b.mesh("cube", sg.cube(0.25), mat)
    for name, (pos, _, _) in OBJECTS.items():
        b.node(name, mesh=cube, translation=pos)
    parent = b.node("Parent", translation=(1, 1, 1))
    b.node("Child", mesh=cube, translation=(0.5, 0.5, 0.5), parent=parent)
    b.node("Camera", camera=b.camera("cam", YFOV), translation=CAMERA_POS)
    b.probe_grids(entries)
    return b.write(d / "grids.gltf")


@pytest.fixture(scope="module")
def scene(tmp_path_factory):
    return make_scene(tmp_path_factory.mktemp("grids"))


def test_objects_get_expected_probes(scene):
    proc = viewer.check(viewer.run(scene, "--headless", "--print-assignments"))
    got = viewer.assignments(proc.stdout)
    for name, (_, want, why) in OBJECTS.items():
        assert got[name] == want, f"{name}: got {got[name]}, want {want} ({why})"
    assert got["Child"] == CHILD_EXPECTED  # world bounds include the parent's transform


def test_moved_objects_are_requeried(scene):
    # Outside moves into A cell (0,0,0). Parent moves from (1,1,1) to (3,0,0), which puts its
    # Child at (3.5,0.5,0.5) = A cell (3,0,0) -> A probe 3: a moved parent re-queries its subtree.
    proc = viewer.check(viewer.run(scene, "--headless", "--print-assignments",
                                   "--move", "Outside", 0.5, 0.5, 0.5, "--move", "Parent", 3, 0, 0))
    got = viewer.assignments(proc.stdout)
    assert got["Outside"] == A_BASE + 0
    assert got["Child"] == A_BASE + 3
    assert got["InA0"] == A_BASE + 0  # untouched objects keep theirs
    assert "re-assigned" in proc.stderr


def project(p):
    """Pixel (column, row) of world point p for the test camera (no rotation, looks along -Z)."""
    t = np.tan(YFOV / 2)
    d = np.subtract(p, CAMERA_POS)
    x, y = d[0] / -d[2] / (t * W / H), d[1] / -d[2] / t
    return int((x + 1) / 2 * W), int((1 - y) / 2 * H)


def test_gpu_sees_the_same_probe_index(scene, tmp_path):
    # --debug probe-index writes the draw's probe index into R of the linear EXR: checks the
    # index that reaches the shader, not only the CPU-side assignment.
    out = tmp_path / "ids.exr"
    viewer.check(viewer.run(scene, "--headless", "--output", out, "--width", W, "--height", H,
                            "--debug", "probe-index"))
    img = viewer.read_image(out)
    checked = 0
    for name, (pos, want, _) in OBJECTS.items():
        i, j = project(pos)
        if 0 <= i < W and 0 <= j < H:
            assert img[j, i, 0] == want, f"{name} at pixel ({i},{j}): R = {img[j, i, 0]}, want {want}"
            checked += 1
    i, j = project((1.5, 1.5, 1.5))
    assert img[j, i, 0] == CHILD_EXPECTED
    assert checked >= 6


def test_probe_colours_reach_the_shader(scene, tmp_path):
    # Grid probes hold only L_00 = k in one channel: E = π·k·Y0·... = k·0.886227 (π·Y0), so with
    # albedo 0.5, shScale 1, ambientTerm 0.1: R (grid A probe k-1) = 0.5·(k·Y0 + 0.1), G = 0.05.
    out = tmp_path / "shaded.exr"
    viewer.check(viewer.run(scene, "--headless", "--output", out, "--width", W, "--height", H))
    img = viewer.read_image(out)
    y0 = 0.282094792
    i, j = project(OBJECTS["InA1"][0])
    assert np.allclose(img[j, i], [0.5 * (2 * y0 + 0.1), 0.05, 0.05], rtol=1e-5)
    i, j = project(OBJECTS["HoleInA"][0])  # B probe 2: L_00 = 3 in green
    assert np.allclose(img[j, i], [0.05, 0.5 * (3 * y0 + 0.1), 0.05], rtol=1e-5)
    # Fallback probe: uniform radiance 0.2 -> diffuse = albedo·(0.2 + 0.1) (documented constant).
    i, j = project(OBJECTS["HoleBoth"][0])
    assert np.allclose(img[j, i], 0.5 * 0.3, rtol=1e-5)


def test_entry_header_mismatch_is_a_warning(tmp_path):
    entries = make_grids(tmp_path)
    entries[0]["probeCount"] = 7
    entries[1]["gridSpacing"] = 2.0
    proc = viewer.check(viewer.run(make_scene(tmp_path, entries), "--headless", "--print-assignments"))
    assert "probeCount 7 but the file has 5" in proc.stderr
    assert "gridSpacing 2 but the file has 1" in proc.stderr
    assert viewer.assignments(proc.stdout)["Overlap"] == A_BASE + 2  # the file is trusted


def test_scene_without_probe_grids_uses_fallback(tmp_path):
    b = sg.GltfBuilder()
    b.node("Lonely", mesh=b.mesh("cube", sg.cube(0.5)))
    proc = viewer.check(viewer.run(b.write(tmp_path / "plain.gltf"), "--headless", "--print-assignments"))
    assert viewer.assignments(proc.stdout) == {"Lonely": 0}


def test_rotated_v2_grid(tmp_path):
    # Version-2 grid turned 90° about +Y (rows: grid X = -Z, Y = +Y, grid Z = +X), written by the
    # core's writer. A point p maps to cell floor(((p - origin)·axis_i) / spacing).
    native = pytest.importorskip("schnee_probes.native", reason="needs the built _schnee_native module")
    axes = np.array([[0, 0, -1], [0, 1, 0], [1, 0, 0]], np.float32)
    (tmp_path / "sh_coeffs").mkdir()
    native.write_shprobe(str(tmp_path / "sh_coeffs" / "rot.shprobe"), np.ones((2, 9, 3), np.float32),
                         np.array([0, 1], np.int32), (2, 1, 1), (0, 0, 0), 1.0, grid_axes=axes)
    b = sg.GltfBuilder()
    cube = b.mesh("cube", sg.cube(0.1))
    b.node("Near", mesh=cube, translation=(0.5, 0.5, -0.5))  # grid (0, 0, 0) -> probe 0 -> 1
    b.node("Far", mesh=cube, translation=(0.5, 0.5, -1.5))   # grid (1, 0, 0) -> probe 1 -> 2
    b.node("Behind", mesh=cube, translation=(0.5, 0.5, 0.5))  # grid x = -0.5: outside -> 0
    entry = sg.grid_entry("rot", "sh_coeffs/rot.shprobe", 2, (0, 0, 0), (2, 1, 1), 1.0)
    entry["gridAxes"] = axes.tolist()
    b.probe_grids([entry])
    proc = viewer.check(viewer.run(b.write(tmp_path / "rot.gltf"), "--headless", "--print-assignments"))
    assert viewer.assignments(proc.stdout) == {"Near": 1, "Far": 2, "Behind": 0}
    assert "gridAxes" not in proc.stderr  # entry and file agree: no warning
