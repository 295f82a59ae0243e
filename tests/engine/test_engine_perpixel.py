"""Per-pixel probe lighting (DESIGN.md §7 second mode, docs/engine.md "Per-pixel probes") on the storage-
buffer path (`--probe-path buffers`, the reference; the default bricks: test_engine_grid_field.py).

Large quads seen by orthographic cameras, so every pixel centre's world point is known exactly.
Materials are white with shScale 1 and ambientTerm 0, so the EXR pixel is max(E, 0) / π; the
expected E comes from tests/engine/scripts/probe_ref.py, a numpy implementation of the documented
interpolation (trilinear, empty cells skipped, renormalised, back-face weights) and of DESIGN.md §3.
"""
import sys
from pathlib import Path

import numpy as np
import pytest

sys.path.insert(0, str(Path(__file__).parent / "scripts"))
import probe_ref as ref  # noqa: E402
import scenegen as sg  # noqa: E402
import viewer  # noqa: E402

N = 33  # odd: the centre pixel's centre is exactly the camera axis
FALLBACK = 0.2  # schnee-view's default fallback radiance (docs/engine.md)


def random_probes(count, seed):
    rng = np.random.default_rng(seed)
    c = rng.normal(0.0, 0.3, (count, 9, 3))
    c[:, 0] = rng.uniform(1.0, 4.0, (count, 3))  # positive, varied L0
    return c


def write_grid(d, name, coeffs, grid, origin, spacing):
    (d / "sh_coeffs").mkdir(exist_ok=True)
    sg.write_shprobe_v1(d / "sh_coeffs" / f"{name}.shprobe", coeffs, grid, origin, spacing)
    Z, Y, X = grid.shape
    return sg.grid_entry(name, f"sh_coeffs/{name}.shprobe", len(coeffs), origin, (X, Y, Z), spacing)


def down_camera_points(cx, cz, y, mag):
    """World points of the N x N pixel centres of the look-down ortho camera (ymag = xmag = mag)."""
    t = (2 * (np.arange(N) + 0.5) / N - 1) * mag
    xs = cx + t                      # column i -> +x (camera right)
    zs = cz + t                      # row j (top = 0) -> +z (camera up is -z)
    X, Zz = np.meshgrid(xs, zs)
    return np.stack([X, np.full_like(X, y), Zz], axis=-1)


# Grid: 4 x 2 x 4 cells of 1 m from the origin, holes in the bottom layer.
GRID = np.arange(32, dtype=np.int32).reshape(2, 4, 4).transpose(1, 0, 2).copy()  # (Z, Y, X)
GRID[1, 0, 2] = -1
GRID[3, 0, 0] = -1
GRID[2, 0, 3] = -1
COEFFS = random_probes(32, 11)


def floor_scene(d, plane_y, centre, size, mode=None, extra=()):
    entry = write_grid(d, "probes", COEFFS, GRID, (0, 0, 0), 1.0)
    b = sg.GltfBuilder()
    m = b.material("white", sh_scale=1.0, ambient_term=0.0, probe_mode=mode)
    b.node("Floor", mesh=b.mesh("floor", sg.quad(size, size, 1), m), translation=(centre[0], plane_y, centre[1]))
    b.node("Camera", camera=b.ortho_camera("top", size / 2), translation=(centre[0], plane_y + 3, centre[1]),
           rotation=sg.ROT_LOOK_DOWN)
    b.probe_grids([entry])
    return b.write(d / "floor.gltf")


def render(scene, out, *args):
    """This module tests the storage-buffer path (`--probe-path buffers`, the reference) against the float64
    rule; the default path (the bricks) takes the same scenes in test_engine_grid_field.py with binary16
    bounds. A --probe-path in args wins (the last one given)."""
    path = () if "--probe-path" in args else ("--probe-path", "buffers")
    viewer.check(viewer.run(scene, "--headless", "--output", out, "--width", N, "--height", N, *path, *args))
    return viewer.read_image(out)


@pytest.fixture(scope="module")
def pixel_floor(tmp_path_factory):
    """render(floor_scene(0.1, (2, 2), 5.0, mode="pixel"), *args), each distinct render once for the
    module: its default render is the one test_interpolation_equals_cpu_trilinear checks against the CPU
    model and the one the CLI-override and half-storage tests compare with."""
    d = tmp_path_factory.mktemp("floor")
    scene = floor_scene(d, 0.1, (2.0, 2.0), 5.0, mode="pixel")
    done = {}

    def get(*args):
        if args not in done:
            done[args] = render(scene, d / f"r{len(done)}.exr", *args)
        return done[args]
    return get


def test_interpolation_equals_cpu_trilinear(pixel_floor):
    # Floor at y = 0.1 over the whole grid and 0.5 m beyond: holes, clamping at the faces, and the
    # fallback outside the grid. The bottom-layer centres (y = 0.5) are 0.4 spacings above the
    # floor: back-face weight 1, so this is the plain renormalised trilinear formula.
    img = pixel_floor()
    p = down_camera_points(2.0, 2.0, 0.1, 2.5).reshape(-1, 3)
    n = np.tile([0.0, 1.0, 0.0], (len(p), 1))
    e, held = ref.grid_irradiance(p, n, GRID, (0, 0, 0), 1.0, COEFFS)
    e[~held] = np.pi * FALLBACK  # outside the grid: fallback probe, E = π·0.2
    expected = (np.maximum(e, 0) / np.pi).reshape(N, N, 3)
    # Float32 on the GPU vs float64 here: measured max abs error 1.7e-6 (pixel values up to 1.2).
    err = np.abs(img - expected)
    assert err.max() < 1e-4 + 1e-4 * np.abs(expected).max(), f"max abs error {err.max():.3g}"
    assert held.sum() > 0.5 * N * N and (~held).sum() > 50
    # The image really varies across the floor (a per-object render is one colour).
    assert np.ptp(img[held.reshape(N, N)][:, 0]) > 0.3


def test_material_mode_cli_override_and_off(pixel_floor):
    by_material = pixel_floor()
    forced = pixel_floor("--probe-mode", "pixel")
    assert np.array_equal(by_material, forced)
    obj = pixel_floor("--probe-mode", "object")
    # Per object: one value for the whole floor, the grid's field at its centre (2, 0.1, 2) (movable
    # rule, no back faces; the floor is the only object, so the segment test drops no probe): the numpy
    # rule gives E/pi = (0.756, 0.672, 0.563), where the old rule's cell (2, 0, 2) gave (1.017, 0.592,
    # 0.927), 36 % off in the largest channel.
    assert np.ptp(obj[..., 0]) < 1e-5
    e, held = ref.grid_irradiance([[2.0, 0.1, 2.0]], [[0.0, 1.0, 0.0]], GRID, (0, 0, 0), 1.0, COEFFS,
                                  backface=False)
    want = np.maximum(e[0], 0) / np.pi
    assert held[0] and np.allclose(obj[N // 2, N // 2], want, rtol=1e-5), (obj[N // 2, N // 2], want)
    cell = np.maximum(ref.irradiance(COEFFS[GRID[2, 0, 2]], [0, 1, 0]), 0) / np.pi
    assert np.abs(cell - want).max() > 0.3 * want.max()  # the case tells the two rules apart
    off = pixel_floor("--probe-mode", "off")
    assert np.allclose(off, FALLBACK, atol=1e-6)  # fallback probe: E/π = 0.2 everywhere


def test_half_storage_matches_float(pixel_floor):
    f = pixel_floor()
    h = pixel_floor("--probe-storage", "half")
    # binary16 keeps 11 significant bits: relative rounding <= 2^-11 = 4.9e-4 per coefficient.
    assert np.abs(h - f).max() <= 2e-3 * np.abs(f).max()
    assert np.abs(h - f).max() > 0  # it really is a different storage


def test_centre_agrees_with_per_object(tmp_path):
    # A 3 m floor at the bottom-layer centre height, centred on the centre of cell (1, 0, 1):
    # the grid (1 m) is finer than the object. Per object the floor gets probe GRID[1, 0, 1];
    # per pixel the centre pixel sits exactly on that probe's centre (trilinear weight 1).
    scene = floor_scene(tmp_path, 0.5, (1.5, 1.5), 3.0)
    obj = render(scene, tmp_path / "o.exr", "--probe-mode", "object")
    pix = render(scene, tmp_path / "p.exr", "--probe-mode", "pixel")
    c = N // 2
    want = np.maximum(ref.irradiance(COEFFS[GRID[1, 0, 1]], [0, 1, 0]), 0) / np.pi
    assert np.allclose(obj[c, c], want, rtol=1e-5)
    assert np.allclose(pix[c, c], want, rtol=1e-4), (pix[c, c], want)
    # Away from the centre the two modes differ: per pixel follows the neighbouring probes.
    assert np.abs(pix[0, 0] - obj[0, 0]).max() > 0.05


def two_rooms(d):
    """A row of four 1 m cells along x: a dark room (cells 0, 1: uniform radiance 0.05) and a bright
    one (cells 2, 3: radiance 5). Returns (grid, coeffs, the written grid's glTF entry)."""
    grid = np.array([[[0, 1, 2, 3]]], np.int32)
    coeffs = np.stack([ref.uniform_coeffs(r) for r in (0.05, 0.05, 5.0, 5.0)])
    return grid, coeffs, write_grid(d, "rooms", coeffs, grid, (0, 0, 0), 1.0)


def wall_quad_scene(d, at):
    """The two rooms with a 1 m quad "Wall" facing -x at ``at``, seen from the dark side by an
    orthographic camera at the dark room's centre. Returns (scene, grid, coeffs)."""
    grid, coeffs, entry = two_rooms(d)
    b = sg.GltfBuilder()
    m = b.material("white", sh_scale=1.0, ambient_term=0.0)
    b.node("Wall", mesh=b.mesh("wall", sg.quad(1.0, 1.0, 0, -1.0), m), translation=at)
    b.node("Camera", camera=b.ortho_camera("side", 0.45), translation=(0.5, 0.5, 0.5), rotation=sg.ROT_LOOK_POS_X)
    b.probe_grids([entry])
    return b.write(d / "wall.gltf"), grid, coeffs


def test_wall_does_not_leak(tmp_path):
    # Two rooms (two_rooms) separated by a wall at x = 2. The quad is the wall's dark face at
    # x = 1.99, facing -x, seen from the dark side. Plain trilinear at x = 1.99 would give the bright
    # probe weight 0.49 (pixel ~2.5); the bright centre (x = 2.5) lies 0.51 spacings behind the
    # face, so its back-face weight is 0 and per pixel the face stays exactly as dark as the dark room.
    scene, grid, coeffs = wall_quad_scene(tmp_path, (1.99, 0.5, 0.5))
    obj = render(scene, tmp_path / "o.exr", "--probe-mode", "object")
    pix = render(scene, tmp_path / "p.exr", "--probe-mode", "pixel")
    assert np.allclose(pix, 0.05, rtol=1e-5), f"per pixel leaks: max {pix.max():.4g}"
    # Per object reads the field at the quad's centre (docs/grid-field.md "Per object"): no back faces,
    # and the quad never blocks its own probes (it is the only geometry), so it gets the interpolation
    # (1 - 0.49)·0.05 + 0.49·5 = 2.4755 (the old rule gave the dark cell's 0.05): one value per object
    # cannot be right on both faces of a wall straddling two rooms.
    e, _ = ref.grid_irradiance([[1.99, 0.5, 0.5]], [[-1.0, 0, 0]], grid, (0, 0, 0), 1.0, coeffs, backface=False)
    assert np.allclose(e[0] / np.pi, 0.51 * 0.05 + 0.49 * 5.0, rtol=1e-9)
    assert np.allclose(obj, e[0] / np.pi, rtol=1e-5), (obj.min(), obj.max(), e[0] / np.pi)
    # The case matters: without the back-face weight the numpy formula gives ~2.5 at the centre.
    p = np.array([[1.99, 0.5, 0.5]])
    f = 1.99 - 0.5 - 1  # fractional position between the centres x = 1.5 and 2.5
    assert (1 - f) * 0.05 + f * 5.0 > 2.0
    e, _ = ref.grid_irradiance(p, np.array([[-1.0, 0, 0]]), grid, (0, 0, 0), 1.0, coeffs)
    assert np.allclose(e / np.pi, 0.05, rtol=1e-6)


def test_movable_quad_gets_no_back_face_weight(tmp_path):
    # The wall quad of the test above, but movable (placed with --move): it was not in the bake, so
    # the bright probe behind its face holds the light where the quad now is and keeps its trilinear
    # weight (docs/engine.md, "Movable objects get no back-face weight"). Closed form: uniform
    # radiance per cell, so every pixel is the x-interpolation (1 - f)·0.05 + f·5 with f = 0.49
    # (x = 1.99 between the centres 1.5 and 2.5); the moved quad is the only mesh, so no masks.
    scene, grid, coeffs = wall_quad_scene(tmp_path, (9.0, 9.0, 9.0))
    pix = render(scene, tmp_path / "p.exr", "--probe-mode", "pixel", "--move", "Wall", 1.99, 0.5, 0.5)
    f = 1.99 - 1.5
    want = (1 - f) * 0.05 + f * 5.0
    assert np.allclose(pix, want, rtol=1e-4), (pix.min(), pix.max(), want)
    # The numpy rule without back-face weights agrees; with them it is the static wall's 0.05.
    p, n = np.array([[1.99, 0.5, 0.5]]), np.array([[-1.0, 0, 0]])
    e, _ = ref.grid_irradiance(p, n, grid, (0, 0, 0), 1.0, coeffs, backface=False)
    assert np.allclose(e / np.pi, want, rtol=1e-6)
    e, _ = ref.grid_irradiance(p, n, grid, (0, 0, 0), 1.0, coeffs)
    assert np.allclose(e / np.pi, 0.05, rtol=1e-6)


def floor_by_wall_scene(d, wall):
    # Four 1 m cells along x: radiance 0.05 (cells 0, 1) and 5 (cells 2, 3); a floor at y = 0.1 for
    # x in [0, 1.98], z in [0, 1], seen from above; optionally a two-sided wall (both faces) at x = 2.
    grid, coeffs, entry = two_rooms(d)
    b = sg.GltfBuilder()
    m = b.material("white", sh_scale=1.0, ambient_term=0.0)
    b.node("Floor", mesh=b.mesh("floor", sg.quad(1.0, 1.98, 1), m), translation=(0.99, 0.1, 0.5))
    if wall:
        b.node("WallA", mesh=b.mesh("wall_a", sg.quad(1.0, 1.0, 0, -1.0), m), translation=(2.0, 0.5, 0.5))
        b.node("WallB", mesh=b.mesh("wall_b", sg.quad(1.0, 1.0, 0, 1.0), m), translation=(2.0, 0.5, 0.5))
    b.node("Camera", camera=b.ortho_camera("top", 0.99), translation=(0.99, 3.1, 0.5), rotation=sg.ROT_LOOK_DOWN)
    b.probe_grids([entry])
    return b.write(d / ("floor_wall.gltf" if wall else "floor_open.gltf")), grid, coeffs


def test_floor_next_to_wall_does_not_leak(tmp_path):
    # The bright probes (x = 2.5) are above the floor's tangent plane, so the back-face weight keeps
    # them: before the visibility masks the floor peaked at 2.29 next to the wall (per object 0.05).
    # The segment between the centres of cells 1 and 2 crosses the wall, so cell 1 (the floor's
    # home cell) has that neighbour's bit clear and the bright probes get weight 0.
    scene, _, _ = floor_by_wall_scene(tmp_path, wall=True)
    obj = render(scene, tmp_path / "o.exr", "--probe-mode", "object")
    pix = render(scene, tmp_path / "p.exr", "--probe-mode", "pixel")
    p = down_camera_points(0.99, 0.5, 0.1, 0.99)
    on_floor = (p[..., 2] > 0.02) & (p[..., 2] < 0.98)
    assert on_floor.sum() > 0.4 * N * N
    assert np.allclose(obj[on_floor], 0.05, rtol=1e-5)  # per object: the floor's centre is in cell 0
    assert pix[on_floor].max() <= obj[on_floor].max() * (1 + 1e-5), f"per pixel leaks: max {pix.max():.4g}"
    proc = viewer.run(scene, "--headless", "--output", tmp_path / "x.exr", "--width", 8, "--height", 8)
    # 3 clear-or-blocked pairs (cells 0-1, 1-2, 2-3) against 3 quads x 2 triangles.
    assert "probe visibility masks: 3 segment(s) against 6 triangle(s)" in proc.stderr, proc.stderr


def segment_blocked_by_wall(a, b, x=2.0, lo=0.0, hi=1.0):
    """True when segment a -> b (ends left out by 1e-4 of its length, as sv_probe_visible) crosses the
    two-sided 1 m wall in the plane x = ``x`` spanning y, z in [lo, hi]."""
    a, b = np.asarray(a, float), np.asarray(b, float)
    if a[0] == b[0]:
        return False
    t = (x - a[0]) / (b[0] - a[0])
    q = a + t * (b - a)
    return bool(1e-4 < t < 1 - 1e-4 and lo <= q[1] <= hi and lo <= q[2] <= hi)


def test_per_object_drops_probes_behind_a_static_wall(tmp_path):
    # Per object on a dense grid (docs/grid-field.md "Per object"): the field's weights at the object's
    # centre (movable rule), each probe judged by the segment from its cell's centre to the centre
    # through the static scene, as the trees' per-object query. A 10 cm box at (1.9, 0.5, 0.5) next to
    # the two-sided wall at x = 2 of floor_by_wall_scene's rooms: trilinear gives cell 1 (dark) 0.6 and
    # cell 2 (bright, x = 2.5) 0.4; the segment from (2.5, 0.5, 0.5) crosses the wall, so the box keeps
    # the dark 0.05 (the old rule's cell 1 too). The walls moved by 1 cm (movable objects no longer block):
    # the interpolation 2.03.
    grid, coeffs, entry = two_rooms(tmp_path)
    b = sg.GltfBuilder()
    m = b.material("white", sh_scale=1.0, ambient_term=0.0)
    b.node("Box", mesh=b.mesh("box", sg.cube(0.05), m), translation=(1.9, 0.5, 0.5))
    b.node("WallA", mesh=b.mesh("wall_a", sg.quad(1.0, 1.0, 0, -1.0), m), translation=(2.0, 0.5, 0.5))
    b.node("WallB", mesh=b.mesh("wall_b", sg.quad(1.0, 1.0, 0, 1.0), m), translation=(2.0, 0.5, 0.5))
    b.node("Camera", camera=b.ortho_camera("side", 0.45), translation=(0.5, 0.5, 0.5), rotation=sg.ROT_LOOK_POS_X)
    b.probe_grids([entry])
    scene = b.write(tmp_path / "box_wall.gltf")
    c, n = np.array([1.9, 0.5, 0.5]), np.array([[-1.0, 0, 0]])
    # numpy: the segment test for every probe (cell centres), then the field with the hidden ones at
    # validity 0 (renormalised over the rest), the movable rule.
    Z, Y, X = grid.shape
    hidden = np.zeros(len(coeffs), bool)
    for x in range(X):
        hidden[grid[0, 0, x]] = segment_blocked_by_wall((x + 0.5, 0.5, 0.5), c)
    assert hidden.tolist() == [False, False, True, True]
    blocked, _ = ref.grid_irradiance([c], n, grid, (0, 0, 0), 1.0, coeffs, validity=(~hidden).astype(float),
                                     backface=False)
    free, _ = ref.grid_irradiance([c], n, grid, (0, 0, 0), 1.0, coeffs, backface=False)
    assert np.allclose(blocked[0] / np.pi, 0.05, rtol=1e-9) and np.allclose(free[0] / np.pi, 2.03, rtol=1e-9)
    k = N // 2
    obj = render(scene, tmp_path / "o.exr", "--probe-mode", "object")
    assert np.allclose(obj[k, k], blocked[0] / np.pi, rtol=1e-5), obj[k, k]
    # Moved by 1 cm, still between the box and the bright probes: movable objects never block.
    moved = render(scene, tmp_path / "m.exr", "--probe-mode", "object", "--move", "WallA", 2.01, 0.5, 0.5,
                   "--move", "WallB", 2.01, 0.5, 0.5)
    assert np.allclose(moved[k, k], free[0] / np.pi, rtol=1e-5), moved[k, k]


def test_floor_without_wall_keeps_its_gradient(tmp_path):
    # Same floor, no wall: every segment is clear, so per pixel is the documented trilinear formula
    # (probe_ref.grid_irradiance) and rises towards the bright cells.
    scene, grid, coeffs = floor_by_wall_scene(tmp_path, wall=False)
    pix = render(scene, tmp_path / "p.exr", "--probe-mode", "pixel")
    p = down_camera_points(0.99, 0.5, 0.1, 0.99)
    on_floor = (p[..., 2] > 0.02) & (p[..., 2] < 0.98)
    pts = p[on_floor]
    e, held = ref.grid_irradiance(pts, np.tile([0.0, 1.0, 0.0], (len(pts), 1)), grid, (0, 0, 0), 1.0, coeffs)
    assert held.all()
    expected = np.maximum(e, 0) / np.pi
    # Float32 vs float64, as in test_interpolation_equals_cpu_trilinear.
    assert np.abs(pix[on_floor] - expected).max() < 1e-4 + 1e-4 * expected.max()
    assert pix[on_floor].max() > 2.0  # the gradient: near x = 1.98 the bright probes weigh ~0.48


def test_bad_probe_mode_is_a_clear_error(tmp_path):
    scene = floor_scene(tmp_path, 0.1, (2.0, 2.0), 5.0, mode="everywhere")
    proc = viewer.run(scene, "--headless", "--output", tmp_path / "x.exr")
    assert proc.returncode == 1
    assert "probeMode: 'everywhere' is not off, object or pixel" in proc.stderr
    proc = viewer.run(scene, "--headless", "--output", tmp_path / "x.exr", "--probe-mode", "sometimes")
    assert proc.returncode == 2 and "bad value 'sometimes' for --probe-mode" in proc.stderr
