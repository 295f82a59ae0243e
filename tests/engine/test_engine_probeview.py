"""Probe view (--probe-view): a small sphere per probe shaded with its SH (E(n)/π) and the outlines
of the occupied grid cells. Checked against numpy's DESIGN.md §3 irradiance at the analytic
sphere normals, seen from above by an orthographic camera."""
import sys
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).parent / "scripts"))
import probe_ref as ref  # noqa: E402
import scenegen as sg  # noqa: E402
import viewer  # noqa: E402

N = 241
MAG = 1.5
CX, CZ = 1.5, 1.0
OUTLINE = np.array([0.9, 0.75, 0.2])  # shaders/probe_outline.frag


def make_scene(d):
    # Cells (x, y, z): (0,0,0), (1,0,0), (2,0,0) -> probe 0; (0,0,1) -> probe 1; (1,0,1), (2,0,1) empty.
    grid = np.full((2, 1, 3), -1, np.int32)
    grid[0, 0, :] = 0
    grid[1, 0, 0] = 1
    rng = np.random.default_rng(5)
    coeffs = rng.normal(0, 0.25, (2, 9, 3))
    coeffs[:, 0] = [[3.0, 2.0, 1.5], [1.0, 2.5, 3.0]]
    (d / "sh_coeffs").mkdir()
    sg.write_shprobe_v1(d / "sh_coeffs" / "p.shprobe", coeffs, grid, (0, 0, 0), 1.0)
    b = sg.GltfBuilder()
    # Something to draw far below the grid (the scene needs an object; it stays out of the view).
    b.node("Far", mesh=b.mesh("far", sg.cube(0.01), b.material("m")), translation=(50, -50, 50))
    b.node("Camera", camera=b.ortho_camera("top", MAG), translation=(CX, 3, CZ), rotation=sg.ROT_LOOK_DOWN)
    b.probe_grids([sg.grid_entry("p", "sh_coeffs/p.shprobe", 2, (0, 0, 0), (3, 1, 2), 1.0)])
    return b.write(d / "view.gltf"), coeffs


def pixel_xz():
    t = (2 * (np.arange(N) + 0.5) / N - 1) * MAG
    return np.meshgrid(CX + t, CZ + t)  # column -> +x, row (top = 0) -> +z


def test_spheres_show_each_probes_irradiance(tmp_path):
    scene, coeffs = make_scene(tmp_path)
    out = tmp_path / "v.exr"
    viewer.check(viewer.run(scene, "--headless", "--output", out, "--width", N, "--height", N, "--probe-view"))
    img = viewer.read_image(out)
    X, Z = pixel_xz()
    r = 0.1  # 0.1 x spacing (docs/engine.md)
    # Probe 0 maps three cells: one sphere at their mean centre (1.5, 0.5, 0.5); probe 1 at (0.5, 0.5, 1.5).
    for probe, (cx, cz) in [(0, (1.5, 0.5)), (1, (0.5, 1.5))]:
        dx, dz = X - cx, Z - cz
        inside = dx * dx + dz * dz < (0.7 * r) ** 2
        assert inside.sum() > 20
        ny = np.sqrt(np.maximum(r * r - dx * dx - dz * dz, 0))
        n = np.stack([dx, ny, dz], -1)[inside] / r
        want = np.maximum(ref.irradiance(coeffs[probe], n), 0) / np.pi
        # The sphere is a 32 x 16 UV sphere: interpolated normals deviate from the analytic ones
        # by < 0.01 rad inside 0.7 r; measured max relative error 0.23 % / 0.51 %.
        assert want.min() > 0.05  # the chosen coefficients keep E positive on the visible caps
        rel = np.abs(img[inside] - want) / want
        assert rel.max() < 0.02, (probe, rel.max())
    # No sphere where no probe is: the middle of the empty cell (1, 0, 1) is background or outline.
    empty = (np.abs(X - 1.5) < 0.1) & (np.abs(Z - 1.5) < 0.1)
    assert np.all(img[empty] == 0.0)


def test_cell_outlines(tmp_path):
    scene, _ = make_scene(tmp_path)
    out = tmp_path / "v.exr"
    viewer.check(viewer.run(scene, "--headless", "--output", out, "--width", N, "--height", N, "--probe-view"))
    img = viewer.read_image(out)
    X, Z = pixel_xz()
    is_line = np.all(np.abs(img - OUTLINE) < 1e-6, axis=-1)
    col = lambda x: np.argmin(np.abs(X[0] - x))  # noqa: E731
    row = lambda z: np.argmin(np.abs(Z[:, 0] - z))  # noqa: E731
    # The edge x = 1 between occupied cells (0,0,0) and (1,0,0), along z in (0, 1): drawn.
    rows = slice(row(0.1), row(0.35))
    assert np.any(is_line[rows, col(1.0) - 1:col(1.0) + 2], axis=1).all()
    # The edge x = 2 along z in (1, 2) belongs only to empty cells (1,0,1), (2,0,1): not drawn.
    rows = slice(row(1.2), row(1.8))
    assert not is_line[rows, col(2.0) - 1:col(2.0) + 2].any()
    # Without --probe-view nothing of it is drawn.
    viewer.check(viewer.run(scene, "--headless", "--output", out, "--width", N, "--height", N))
    assert np.all(viewer.read_image(out) == 0.0)
