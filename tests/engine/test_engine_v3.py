""".shprobe version 3 grids in schnee-view (docs/engine.md "Version 3 grids"): corner octrees with
hanging nodes per pixel (the GLSL mirror of leaf_weights in native/src/pb_interp.c) and per object
(the core's pb_interp_query_cotree at the object's centre, with static-scene visibility), tetrahedra
per object, SH or ambient cubes, float32 or binary16.

Expected values come from the core's CPU model through the Python module (CornerOctree.query /
Tetrahedra.query, themselves tested against closed forms in tests/python/test_native_interp.py) and,
for a field linear in position, from the closed form. Materials are white with shScale 1 and
ambientTerm 0 and the cameras look straight down on +y faces, so an EXR pixel is max(E(+y), 0) / pi.
"""
import re
import shutil
import sys
from pathlib import Path

import numpy as np
import pytest

sys.path.insert(0, str(Path(__file__).parent / "scripts"))
sys.path.insert(0, str(Path(__file__).resolve().parents[2] / "addon"))
import probe_ref as ref  # noqa: E402
import scenegen as sg  # noqa: E402
import viewer  # noqa: E402
from schnee_probes import native  # noqa: E402

Y0 = 0.282094792
UP = np.array([0.0, 1.0, 0.0])
N = 65  # odd: the centre pixel's centre is exactly the camera axis


def octree():
    """Lattice of 0.5 m min cells, 8 x 4 x 8 (4 x 2 x 4 m from the origin): 2 x 1 x 2 roots of 2 m;
    root 0 split into 1 m leaves and its child at (1, 0, 1) m split again into 0.5 m leaves, so hanging
    nodes sit on faces and edges of two levels, and x = 2 m is a fine/coarse border."""
    t = native.CornerOctree.uniform((0.0, 0.0, 0.0), 0.5, 2, (2, 1, 2))
    f = np.zeros(t.leaf_count, bool)
    f[0] = True
    assert t.split(f) == 1
    leaves = t.info()["leaves"]
    f = np.zeros(t.leaf_count, bool)
    f[np.flatnonzero((leaves == [2, 0, 2, 1]).all(axis=1))] = True
    assert t.split(f) == 1
    t.finalize()
    assert t.info()["hanging_count"] > 10
    return t


def random_sh(count, seed):
    rng = np.random.default_rng(seed)
    c = rng.normal(0.0, 0.3, (count, 9, 3))
    c[:, 0] = rng.uniform(1.0, 4.0, (count, 3))  # positive, varied L0
    return c


def linear(p):
    return 1.0 + 0.5 * p[..., 0] + 0.25 * p[..., 1] + 0.75 * p[..., 2]


def linear_sh(pos):
    """L00 linear in position, all other coefficients 0: E(n) = pi * Y0 * f(p), pixel = Y0 * f(p)."""
    c = np.zeros((len(pos), 9, 3))
    c[:, 0, :] = linear(pos)[:, None]
    return c


def write_grid(d, structure, coeffs, name="p", representation="sh", storage="float32", entry_fields=None):
    (d / "sh_coeffs").mkdir(exist_ok=True)
    path = d / "sh_coeffs" / f"{name}.shprobe"
    count = native.write_shprobe_v3(str(path), structure, coeffs, representation=representation, storage=storage)
    f = native.read_shprobe(str(path))
    e = sg.grid_entry(name, f"sh_coeffs/{name}.shprobe", count, f.grid_origin, f.grid_dims, f.grid_spacing)
    e.update(representation=f.representation, storage=f.storage, structure=f.structure)
    e.update(entry_fields or {})
    return e


def pixel_points(cx, cz, mag, y):
    """World points (N, N, 3) of the pixel centres of a look-down ortho camera (xmag = ymag = mag)."""
    t = (2 * (np.arange(N) + 0.5) / N - 1) * mag
    X, Z = np.meshgrid(cx + t, cz + t)  # column -> +x, row -> +z
    return np.stack([X, np.full_like(X, y), Z], axis=-1)


def pixel_of(x, z, cx, cz, mag):
    return int((z - (cz - mag)) / (2 * mag) * N), int((x - (cx - mag)) / (2 * mag) * N)


def render(scene, out, *args):
    """These tests check the storage-buffer path (`octree_irradiance`, `--probe-path buffers`, the reference)
    against the CPU model; the default path (the probe bricks) has its own tests with binary16 bounds
    (test_engine_bricks.py, test_engine_bricks_vis.py). A --probe-path in args wins."""
    path = () if "--probe-path" in args else ("--probe-path", "buffers")
    proc = viewer.check(viewer.run(scene, "--headless", "--output", out, "--width", N, "--height", N, *path, *args))
    return viewer.read_image(out)[..., :3], proc


def sh_e(coeffs, n=UP):
    """E(n) of L2 radiance coefficients (..., 9, 3) for one normal (probe_ref.irradiance, batched)."""
    return np.einsum("i,i,...ic->...c", ref.sh_basis_l2(np.asarray(n, float)), ref.A_L2, np.asarray(coeffs, float))


def cube_e(cubes, n=UP):
    """E_cube(n) of cubes (..., 6, 3) for one normal (probe_ref.cube_irradiance, batched)."""
    n = np.asarray(n, float)
    return sum(n[a] ** 2 * np.asarray(cubes, float)[..., 2 * a + (n[a] < 0), :] for a in range(3))


def cpu_object_e(interp, coeffs, centre, validity=None, evaluate=sh_e):
    """E(+y) of the CPU model's weights at one point (blend of the probes' coefficients)."""
    probes, weights = interp.query(np.asarray(centre, float)[None], validity)
    assert probes[0, 0] >= 0, "outside the structure"
    blend = np.einsum("k,k...->...", weights[0], coeffs[np.maximum(probes[0], 0)])
    return evaluate(blend)


def interpolate(interp, points, values):
    """The CPU model's weights at points (M, 3) applied to per-probe values (P, ...)."""
    probes, weights = interp.query(points)
    assert (probes[:, 0] >= 0).all()
    return np.einsum("mk,mk...->m...", weights, np.asarray(values, float)[np.maximum(probes, 0)])


def half(a):
    return np.asarray(a, np.float64).astype(np.float16).astype(np.float64)


# Cubes placed per object on pixel centres of the full-lattice camera (centre (2, 2), mag 2).
CUBE = 0.05
rng_cubes = np.random.default_rng(5)
CUBE_XZ = [(2 + (2 * (i + 0.5) / N - 1) * 2, 2 + (2 * (j + 0.5) / N - 1) * 2)
           for i, j in [(6, 9), (20, 40), (31, 12), (45, 52), (58, 30), (12, 58), (38, 27), (52, 6)]]
CUBE_Y = rng_cubes.uniform(0.15, 1.85, len(CUBE_XZ))
CUBE_CENTRES = np.array([(x, y, z) for (x, z), y in zip(CUBE_XZ, CUBE_Y)])


def lattice_scene(d, entry, floor=True, cubes=True, mode_floor="pixel", mode_cubes="object"):
    """A floor on the lattice's bottom face (y = 0, per pixel) and small cubes per object, each
    placed with --move (moved objects leave the static scene, so no cube blocks another's probes)."""
    b = sg.GltfBuilder()
    if floor:
        mf = b.material("FloorMat", sh_scale=1.0, ambient_term=0.0, probe_mode=mode_floor)
        b.node("Floor", mesh=b.mesh("floor", sg.quad(4.0, 4.0, 1), mf), translation=(2.0, 0.0, 2.0))
    moves = []
    if cubes:
        mc = b.material("CubeMat", sh_scale=1.0, ambient_term=0.0, probe_mode=mode_cubes)
        mesh = b.mesh("cube", sg.cube(CUBE), mc)
        for k, c in enumerate(CUBE_CENTRES):
            b.node(f"Cube{k}", mesh=mesh, translation=(9.0 + k, 9.0, 9.0))  # outside, moved in
            moves += ["--move", f"Cube{k}", *c]
    b.node("Camera", camera=b.ortho_camera("top", 2.0), translation=(2.0, 3.0, 2.0), rotation=sg.ROT_LOOK_DOWN)
    b.probe_grids([entry])
    return b.write(d / "lattice.gltf"), moves


def floor_mask():
    """Pixels of the floor not covered by a cube (seen from above)."""
    p = pixel_points(2.0, 2.0, 2.0, 0.0)
    keep = np.ones((N, N), bool)
    for c in CUBE_CENTRES:
        keep &= ~((np.abs(p[..., 0] - c[0]) < CUBE + 0.07) & (np.abs(p[..., 2] - c[2]) < CUBE + 0.07))
    return keep, p


def assert_engine_equals_cpu_model(tmp_path, tree, entry, coeffs, storage, exr_name):
    """The lattice scene lit by the file of ``entry`` (``tree``'s probes holding ``coeffs``): per pixel
    the floor equals the CPU model's interpolation, per object each cube the CPU's query at its
    centre, and --print-assignments lists the CPU's probes and weights for every cube (version 3
    here, version 4 in test_engine_v4.py)."""
    scene, moves = lattice_scene(tmp_path, entry)
    args = ["--probe-storage", "half"] if storage == "float16" else []
    img, proc = render(scene, tmp_path / exr_name, *moves, *args)
    # The entry repeats the file with the Python reader's names ("sh", "float16", "octree", ...): the
    # engine's names are the same, so nothing is reported.
    assert "but the file has" not in proc.stderr, proc.stderr
    # The file holds binary16 colours: the CPU model sees the same rounded values the engine reads.
    c = half(coeffs) if storage == "float16" else coeffs
    keep, p = floor_mask()
    want = np.maximum(sh_e(interpolate(tree, p[keep], c)), 0) / np.pi
    err = np.abs(img[keep] - want).max()
    # Float: float32 on the GPU vs float64 (measured 3.4e-7 per pixel, 1.1e-7 per object). Half: the
    # engine also stores the probes, resolved hanging nodes and slots as binary16 (relative rounding
    # <= 4.9e-4 each; measured 2.7e-4 = 2.2e-4 of the peak, both modes).
    bound = 1e-5 + 1e-5 * want.max() if storage == "float32" else 1e-3 * want.max()
    assert err < bound, (err, bound)
    assert keep.sum() > 0.8 * N * N
    for k, centre in enumerate(CUBE_CENTRES):
        e = np.maximum(cpu_object_e(tree, c, centre), 0) / np.pi
        got = img[pixel_of(centre[0], centre[2], 2.0, 2.0, 2.0)]
        assert np.abs(got - e).max() < (1e-5 + 1e-5 * e.max() if storage == "float32" else 1e-3 * e.max()), (k, got, e)
    # --print-assignments: each cube's slot and the CPU's weights (the probes of the query).
    out = viewer.run(scene, "--headless", "--print-assignments", *moves)
    slots = re.findall(r"^  grid 0 weights (\d+):((?: \d+:[0-9.e-]+)+)", out.stdout, re.M)
    assert len(slots) == 1 + len(CUBE_CENTRES)  # the floor's centre too (a lattice point)
    for k in range(len(CUBE_CENTRES)):
        probes, weights = tree.query(CUBE_CENTRES[k:k + 1])
        got = {int(a) - 1: float(b) for a, b in (t.split(":") for t in slots[1 + k][1].split())}
        want_w = {int(q): w for q, w in zip(probes[0], weights[0]) if q >= 0}
        assert got.keys() == want_w.keys(), k
        assert max(abs(got[q] - want_w[q]) for q in got) < 1e-7


@pytest.mark.parametrize("storage", ["float32", "float16"])
def test_octree_per_pixel_and_per_object_equal_the_cpu_model(tmp_path, storage):
    tree = octree()
    coeffs = random_sh(tree.probe_count, 3)
    entry = write_grid(tmp_path, tree, coeffs, storage=storage)
    assert_engine_equals_cpu_model(tmp_path, tree, entry, coeffs, storage, "v3.exr")


def test_linear_field_is_reproduced(tmp_path):
    # Corner octrees with hanging nodes reproduce a field linear in position exactly (docs/placement.md):
    # the closed form Y0 * f(p), independent of the CPU model, per pixel and per object.
    tree = octree()
    entry = write_grid(tmp_path, tree, linear_sh(tree.positions()))
    scene, moves = lattice_scene(tmp_path, entry)
    img, _ = render(scene, tmp_path / "lin.exr", *moves)
    keep, p = floor_mask()
    want = Y0 * linear(p[keep])
    assert np.abs(img[keep] - want[:, None]).max() < 2e-6 * want.max()
    for centre in CUBE_CENTRES:
        got = img[pixel_of(centre[0], centre[2], 2.0, 2.0, 2.0)]
        assert np.allclose(got, Y0 * linear(centre), rtol=2e-6), (centre, got)


def test_object_moved_across_leaf_border_changes_continuously(tmp_path):
    # A cube moved in 0.05 m steps along x from the 0.5 m leaves (x < 2) into the 2 m root (x > 2),
    # through the hanging nodes on the border: its shading equals the CPU model at every step and
    # changes by at most the trilinear Lipschitz bound sqrt(3) * step / (min cell) * (probe range);
    # a nearest-probe lookup would jump by a sizeable part of the range.
    tree = octree()
    coeffs = random_sh(tree.probe_count, 8)
    entry = write_grid(tmp_path, tree, coeffs)
    b = sg.GltfBuilder()
    m = b.material("CubeMat", sh_scale=1.0, ambient_term=0.0)
    b.node("Cube", mesh=b.mesh("cube", sg.cube(0.02), m), translation=(9.0, 9.0, 9.0))
    b.node("Camera", camera=b.ortho_camera("top", 0.4), translation=(2.0, 3.0, 1.3), rotation=sg.ROT_LOOK_DOWN)
    b.probe_grids([entry])
    scene = b.write(tmp_path / "move.gltf")
    xs = np.round(np.arange(1.75, 2.2501, 0.05), 4)
    got = []
    for x in xs:
        c = (x, 0.61, 1.3)
        img, _ = render(scene, tmp_path / "m.exr", "--move", "Cube", *c)
        v = img[pixel_of(x, 1.3, 2.0, 1.3, 0.4)]
        e = np.maximum(cpu_object_e(tree, coeffs, c), 0) / np.pi
        assert np.abs(v - e).max() < 1e-5 + 1e-5 * e.max(), (x, v, e)
        got.append(v)
    got = np.array(got)
    probe_e = sh_e(coeffs) / np.pi
    spread = probe_e.max(axis=0) - probe_e.min(axis=0)
    bound = np.sqrt(3) * 0.05 / 0.5 * spread
    assert (np.abs(np.diff(got, axis=0)) <= bound).all(), (np.abs(np.diff(got, axis=0)).max(axis=0), bound)
    assert np.abs(got[-1] - got[0]).max() > 0.01  # it does change along the path


def sphere_and_wall_scene(d, entry):
    # A closed sphere in the coarse root (leaf [2, 4]^2 x [0, 2]) and a two-sided wall at x = 3.6
    # between its centre and the four probes at x = 4.
    b = sg.GltfBuilder()
    m = b.material("White", sh_scale=1.0, ambient_term=0.0)
    b.node("Sphere", mesh=b.mesh("sphere", sg.uv_sphere(0.3, 32, 16), m), translation=(3.1, 0.9, 3.1))
    b.node("WallA", mesh=b.mesh("wall_a", sg.quad(2.0, 2.0, 0, -1.0), m), translation=(3.6, 1.0, 3.0))
    b.node("WallB", mesh=b.mesh("wall_b", sg.quad(2.0, 2.0, 0, 1.0), m), translation=(3.6, 1.0, 3.0))
    b.node("Camera", camera=b.ortho_camera("top", 0.4), translation=(3.1, 3.0, 3.1), rotation=sg.ROT_LOOK_DOWN)
    b.probe_grids([entry])
    return b.write(d / "sphere.gltf")


def test_visibility_is_judged_against_the_static_scene(tmp_path):
    tree = octree()
    coeffs = random_sh(tree.probe_count, 9)
    entry = write_grid(tmp_path, tree, coeffs)
    scene = sphere_and_wall_scene(tmp_path, entry)
    centre = np.array([3.1, 0.9, 3.1])
    top = pixel_of(3.1, 3.1, 3.1, 3.1, 0.4)  # the sphere's top, normal +y
    pos = tree.positions()
    behind_wall = np.isclose(pos[:, 0], 4.0)
    # 1. Static wall: the probes at x = 4 cannot see the centre and are dropped (the CPU model's
    #    validity drop renormalises exactly as its visibility drop); the sphere's own surface, which
    #    every probe -> centre segment crosses, never blocks its own probes.
    img, proc = render(scene, tmp_path / "wall.exr")
    blocked = cpu_object_e(tree, coeffs, centre, validity=(~behind_wall).astype(np.float32))
    assert np.allclose(img[top], np.maximum(blocked, 0) / np.pi, rtol=1e-5), (img[top], blocked / np.pi)
    free = cpu_object_e(tree, coeffs, centre)
    assert np.abs(free - blocked).max() > 0.05  # the wall matters
    assert "triangle(s)" in proc.stderr
    tris_static = int(re.search(r"against (\d+) triangle", proc.stderr).group(1))
    # 2. The wall moved by 1 cm (now a movable object, still between them): it no longer blocks
    #    (per object) and its triangles leave the per-pixel visibility masks.
    img, proc = render(scene, tmp_path / "moved.exr", "--move", "WallA", 3.61, 1.0, 3.0,
                       "--move", "WallB", 3.61, 1.0, 3.0)
    assert np.allclose(img[top], np.maximum(free, 0) / np.pi, rtol=1e-5), (img[top], free / np.pi)
    tris_moved = int(re.search(r"against (\d+) triangle", proc.stderr).group(1))
    assert tris_static - tris_moved == 4  # two quads of two triangles
    # 3. The sphere moved too: it leaves the masks as well, and still sees its probes.
    c2 = centre + [0.0, 0.01, 0.0]  # straight up: the camera still sees the pole (normal +y)
    img, proc = render(scene, tmp_path / "both.exr", "--move", "Sphere", *c2, "--move", "WallA", 3.61, 1.0, 3.0,
                       "--move", "WallB", 3.61, 1.0, 3.0)
    free2 = cpu_object_e(tree, coeffs, c2)
    assert np.allclose(img[top], np.maximum(free2, 0) / np.pi, rtol=1e-5), (img[top], free2 / np.pi)
    assert "against 0 triangle(s)" in proc.stderr


def test_cube_grid_and_the_sh_mismatch_warning(tmp_path):
    # The same octree stored as ambient cubes (fitted in numpy, docs/ambient-cube.md §2): materials
    # that ask for SH (the default) are shaded with the cube, and one warning per material and grid
    # says so. Expected: the CPU model's weights applied to the cubes, E_cube(+y) (§1).
    tree = octree()
    coeffs = random_sh(tree.probe_count, 4)
    cubes = np.stack([ref.cube_from_sh(c) for c in coeffs])
    entry = write_grid(tmp_path, tree, cubes, name="cubes", representation="ambientCube")
    scene, moves = lattice_scene(tmp_path, entry)
    img, proc = render(scene, tmp_path / "cube.exr", *moves)
    for mat in ("FloorMat", "CubeMat"):
        msg = (f"material '{mat}' asks for SH probes but shProbeGrids[0] 'cubes' holds ambient cubes only; "
               "shaded with the cube")
        assert proc.stderr.count(msg) == 1, proc.stderr
    keep, p = floor_mask()
    want = np.maximum(cube_e(interpolate(tree, p[keep], cubes)), 0) / np.pi
    assert np.abs(img[keep] - want).max() < 1e-5 + 1e-5 * want.max()
    for centre in CUBE_CENTRES:
        e = np.maximum(cpu_object_e(tree, cubes, centre, evaluate=cube_e), 0) / np.pi
        got = img[pixel_of(centre[0], centre[2], 2.0, 2.0, 2.0)]
        assert np.abs(got - e).max() < 1e-5 + 1e-5 * e.max(), (got, e)
    # The cube differs from the SH it came from (so SH shading would fail above) ...
    sh = np.maximum(sh_e(interpolate(tree, p[keep], coeffs)), 0) / np.pi
    assert np.abs(sh - want).max() > 0.01
    # ... and equals the engine's own fit of the SH grid (--probe-representation ambientCube).
    entry_sh = write_grid(tmp_path, tree, coeffs, name="cubes")
    scene_sh, _ = lattice_scene(tmp_path, entry_sh)
    img_sh, proc_sh = render(scene_sh, tmp_path / "sh.exr", *moves, "--probe-representation", "ambientCube")
    assert "asks for SH" not in proc_sh.stderr
    assert np.abs(img_sh - img).max() < 1e-5 * img.max()
    # Half storage: the file in binary16 and the GPU buffer in half.
    entry_h = write_grid(tmp_path, tree, cubes, name="cubes", representation="ambientCube", storage="float16")
    scene_h, _ = lattice_scene(tmp_path, entry_h)
    img_h, _ = render(scene_h, tmp_path / "half.exr", *moves, "--probe-storage", "half")
    want_h = np.maximum(cube_e(interpolate(tree, p[keep], half(cubes))), 0) / np.pi
    assert np.abs(img_h[keep] - want_h).max() < 1e-3 * want_h.max()


def test_tetrahedra_per_object_and_per_pixel_falls_back_to_it(tmp_path):
    tree = octree()
    tet = native.Tetrahedra.create(tree.positions())
    coeffs = random_sh(tree.probe_count, 6)
    entry = write_grid(tmp_path, tet, coeffs, name="tets")
    assert entry["structure"] == "tetrahedra"
    scene, moves = lattice_scene(tmp_path, entry, floor=False)
    img, _ = render(scene, tmp_path / "tet.exr", *moves)
    for centre in CUBE_CENTRES:
        e = np.maximum(cpu_object_e(tet, coeffs, centre), 0) / np.pi
        got = img[pixel_of(centre[0], centre[2], 2.0, 2.0, 2.0)]
        assert np.abs(got - e).max() < 1e-5 + 1e-5 * e.max(), (centre, got, e)
    # Per pixel: no GPU point location for tetrahedra; each fragment takes its object's probe.
    img_p, _ = render(scene, tmp_path / "tetp.exr", *moves, "--probe-mode", "pixel")
    assert np.array_equal(img_p, img)


def test_entry_fields_are_compared_with_the_file(tmp_path):
    tree = octree()
    coeffs = random_sh(tree.probe_count, 7)
    entry = write_grid(tmp_path, tree, coeffs, entry_fields={"representation": "ambientCube", "storage": "float16",
                                                             "structure": "tetrahedra"})
    scene, moves = lattice_scene(tmp_path, entry, cubes=False)
    _, proc = render(scene, tmp_path / "x.exr")
    for key, entry_v, file_v in [("representation", "ambientCube", "sh"), ("storage", "float16", "float32"),
                                 ("structure", "tetrahedra", "octree")]:
        assert f"shProbeGrids[0] 'p': {key} '{entry_v}' but the file has '{file_v}' (using the file)" in proc.stderr
    entry["representation"] = "cube"
    scene, _ = lattice_scene(tmp_path, entry, cubes=False)
    proc = viewer.run(scene, "--headless", "--output", tmp_path / "y.exr", "--width", 8, "--height", 8)
    assert "representation: 'cube' is not sh or ambientCube" in proc.stderr


@pytest.mark.skipif(shutil.which("xvfb-run") is None, reason="xvfb-run not installed (apt: xvfb)")
def test_window_frame_matches_headless(tmp_path):
    # The window path (swapchain, per-frame sv_probes_assign, slot uploads between frames) on an octree
    # scene: its last frame equals the headless PNG (±2/255, as tests/engine/test_engine_window.py).
    tree = octree()
    entry = write_grid(tmp_path, tree, random_sh(tree.probe_count, 12))
    scene, moves = lattice_scene(tmp_path, entry)
    shot, png = tmp_path / "window.png", tmp_path / "headless.png"
    proc = viewer.check(viewer.run(scene, "--frames", 3, "--screenshot", shot, "--width", 96, "--height", 96, *moves,
                                   xvfb=True, timeout=180))
    assert "3 frame(s) presented" in proc.stderr
    viewer.check(viewer.run(scene, "--headless", "--output", png, "--width", 96, "--height", 96, *moves))
    a, b = viewer.read_image(shot), viewer.read_image(png)
    assert a.shape == b.shape == (96, 96, 3)
    assert a.min() > 0.05  # the floor fills the frame
    assert np.abs(a - b).max() <= 2.0 / 255


def octree_pixel_ref(path, p, n):
    """numpy of the documented per-pixel octree rule (docs/engine.md "Version 3 grids"), from the file's
    own arrays: hanging nodes resolved as (A, a) in file order, the leaf holding p by brute force,
    trilinear corner weights x validity mass x back-face weight smoothstep(-0.1, 0.1, dot(c - p, n) /
    leaf size), renormalised; when that leaves nothing, the plain weights. No visibility masks (the
    scene has no static triangles). E(n) of L2 SH per point."""
    f = native.read_shprobe(str(path))
    P, H = f.probe_count, len(f.hanging_sources)
    m = (f.validity > 0) if f.validity is not None else np.ones(P, bool)
    A = np.zeros((P + H, 9, 3))
    a = np.zeros(P + H)
    A[:P] = m[:, None, None] * f.probe_scale[:, None, None] * f.coeffs
    a[:P] = m
    for j in range(H):
        for src, w in zip(f.hanging_sources[j], f.hanging_weights[j]):
            if w > 0:
                A[P + j] += w * A[src]
                a[P + j] += w * a[src]
    origin, h = np.array(f.grid_origin, float), float(f.grid_spacing)
    lv = f.leaves.astype(np.int64)
    out = np.zeros((len(p), 3))
    for i, (pi, ni) in enumerate(zip(p, n)):
        u = (pi - origin) / h
        q = np.minimum(np.floor(u), np.array(f.grid_dims) - 1)
        size = 2.0 ** lv[:, 3]
        li = np.flatnonzero(((lv[:, :3] <= q) & (q < lv[:, :3] + size[:, None])).all(axis=1))
        assert len(li) == 1
        leaf, s = lv[li[0]], size[li[0]]
        t = np.clip((u - leaf[:3]) / s, 0, 1)
        for backface in (True, False):
            e, wsum = np.zeros(3), 0.0
            for c in range(8):
                o = np.array([c & 1, (c >> 1) & 1, (c >> 2) & 1])
                w = np.prod(np.where(o, t, 1 - t))
                node = f.leaf_corners[li[0], c]
                w *= a[node]
                if backface:
                    corner = origin + (leaf[:3] + o * s) * h
                    w *= ref.smoothstep(-0.1, 0.1, np.dot(corner - pi, ni) / (s * h))
                if w <= 0:
                    continue
                e += w * ref.irradiance(A[node] / a[node], ni)
                wsum += w
            if wsum > 0:
                out[i] = e / wsum
                break
    return out


def test_octree_per_pixel_on_a_movable_sphere_is_the_cpu_model(tmp_path):
    # A movable object was not in the bake: every corner probe holds the light where it now is, so
    # per pixel it gets the CPU model's plain interpolation at each surface point (no back-face
    # weights: on a small convex object they throw away the probes behind each point; measured in
    # bench/results/spheres.md, 2-39 % off the file's interpolation before). Every normal of the
    # upper hemisphere, inside the 0.5 m leaves and across the hanging nodes of the fine/coarse
    # borders. The sphere is moved into place, so it is no occluder (no visibility masks).
    tree = octree()
    coeffs = random_sh(tree.probe_count, 13)
    entry = write_grid(tmp_path, tree, coeffs)
    c, r = np.array([1.45, 0.8, 1.55]), 0.4
    b = sg.GltfBuilder()
    m = b.material("White", sh_scale=1.0, ambient_term=0.0, probe_mode="pixel")
    b.node("Sphere", mesh=b.mesh("sphere", sg.uv_sphere(r, 128, 64), m), translation=(5.0, 5.0, 5.0))
    b.node("Camera", camera=b.ortho_camera("top", r), translation=(c[0], 3.0, c[2]), rotation=sg.ROT_LOOK_DOWN)
    b.probe_grids([entry])
    scene = b.write(tmp_path / "sphere.gltf")
    img, proc = render(scene, tmp_path / "s.exr", "--move", "Sphere", *c)
    assert "against 0 triangle(s)" in proc.stderr
    p = pixel_points(c[0], c[2], r, 0.0)
    d2 = (p[..., 0] - c[0]) ** 2 + (p[..., 2] - c[2]) ** 2
    on = d2 < (0.9 * r) ** 2  # away from the silhouette (tessellation)
    p[..., 1] = c[1] + np.sqrt(np.maximum(r * r - d2, 0))
    nrm = (p - c) / r
    want = np.maximum([ref.irradiance(x, nn) for x, nn in zip(interpolate(tree, p[on], coeffs), nrm[on])], 0) / np.pi
    err = np.abs(img[on] - want).max()
    # float32 and the tessellated sphere (128 x 64; positions and normals off the analytic ones by
    # < 1.2e-3 relative) against float64 on the analytic sphere (4.0e-4 measured with the rule below).
    assert err < 1e-4 + 1e-3 * want.max(), (err, want.max())
    # The case matters: the static surfaces' rule (back-face weights per corner) differs here.
    backface = np.maximum(octree_pixel_ref(tmp_path / "sh_coeffs" / "p.shprobe", p[on], nrm[on]), 0) / np.pi
    assert np.abs(backface - want).max() > 0.05  # measured 0.25


@pytest.mark.parametrize("probe_path", ["buffers", "bricks"])
def test_octree_floor_next_to_a_wall_does_not_leak(tmp_path, probe_path):
    # Three 1 m leaves along x: probes at x = 0, 1 see radiance 0.05, at x = 2, 3 radiance 5. A static
    # two-sided wall at x = 1.7 and a floor at y = 0.1 for x in [0, 1.68]. The bright corners of the
    # leaf [1, 2] are above the floor (the back-face weight keeps them), but every segment from them
    # to the dark corners meets the wall 0.3 of the way: the visibility field (pb_interp.h) puts the
    # wall at x = 1.7 exactly (V = 1 - 1/(2 * 0.3) on the dark corners, v = 1/2 at t = 0.7), so its
    # ramp is 0 up to there and the floor stays dark.
    # The same wall moved by 1 cm is no longer static: the floor shows the gradient towards x = 2.
    tree = native.CornerOctree.uniform((0.0, 0.0, 0.0), 1.0, 0, (3, 1, 1))
    tree.finalize()
    pos = tree.positions()
    coeffs = np.stack([ref.uniform_coeffs(0.05 if x < 1.5 else 5.0) for x in pos[:, 0]])
    entry = write_grid(tmp_path, tree, coeffs)
    b = sg.GltfBuilder()
    m = b.material("White", sh_scale=1.0, ambient_term=0.0, probe_mode="pixel")
    b.node("Floor", mesh=b.mesh("floor", sg.quad(1.0, 1.68, 1), m), translation=(0.84, 0.1, 0.5))
    b.node("WallA", mesh=b.mesh("wall_a", sg.quad(1.0, 1.0, 0, -1.0), m), translation=(1.7, 0.5, 0.5))
    b.node("WallB", mesh=b.mesh("wall_b", sg.quad(1.0, 1.0, 0, 1.0), m), translation=(1.7, 0.5, 0.5))
    b.node("Camera", camera=b.ortho_camera("top", 0.84), translation=(0.84, 3.1, 0.5), rotation=sg.ROT_LOOK_DOWN)
    b.probe_grids([entry])
    scene = b.write(tmp_path / "wall.gltf")
    p = pixel_points(0.84, 0.5, 0.84, 0.1)
    on_floor = (p[..., 2] > 0.02) & (p[..., 2] < 0.98)
    path = ("--probe-path", probe_path)
    img, proc = render(scene, tmp_path / "w.exr", *path)
    if probe_path == "bricks":  # built with the static scene's tracer: records for the blocked brick cells
        assert re.search(r"probe brick visibility: [1-9][0-9]* record", proc.stderr), proc.stderr
    assert "probe visibility masks: 168 segment(s)" in proc.stderr  # 3 leaves x 56 corner pairs
    assert np.allclose(img[on_floor], 0.05, rtol=1e-5), img[on_floor].max()
    img, _ = render(scene, tmp_path / "m.exr", "--move", "WallA", 1.71, 0.5, 0.5, "--move", "WallB", 1.71, 0.5, 0.5,
                    *path)
    # No occluder: the plain rule, t = x - 1 of the bright corners' weight near x = 1.68.
    assert img[on_floor].max() > 0.05 + 0.6 * 4.95


def test_half_slot_beyond_the_half_range_is_clamped(tmp_path):
    # One 1 m leaf, no hanging nodes: L00 = 40000 with probe scale 2 fits binary16 factor by factor
    # (so --probe-storage half is kept), but the object's blended slot (scale folded in) is 80000:
    # clamped to 65504 with a warning, never Inf.
    tree = native.CornerOctree.uniform((0.0, 0.0, 0.0), 1.0, 0, (1, 1, 1))
    tree.finalize()
    c = np.zeros((tree.probe_count, 9, 3))
    c[:, 0] = 40000.0
    (tmp_path / "sh_coeffs").mkdir()
    native.write_shprobe_v3(str(tmp_path / "sh_coeffs" / "p.shprobe"), tree, c, probe_scale=np.full(8, 2.0))
    e = sg.grid_entry("p", "sh_coeffs/p.shprobe", 8, (0, 0, 0), (1, 1, 1), 1.0)
    e["structure"] = "octree"
    b = sg.GltfBuilder()
    m = b.material("White", sh_scale=1.0, ambient_term=0.0)
    b.node("Cube", mesh=b.mesh("cube", sg.cube(0.1), m), translation=(0.5, 0.5, 0.5))
    b.node("Camera", camera=b.ortho_camera("top", 0.2), translation=(0.5, 3.0, 0.5), rotation=sg.ROT_LOOK_DOWN)
    b.probe_grids([e])
    scene = b.write(tmp_path / "big.gltf")
    img, proc = render(scene, tmp_path / "h.exr", "--probe-storage", "half")
    assert "an object's interpolated probe exceeds the half-float range (65504); clamped" in proc.stderr
    assert "using float storage" not in proc.stderr
    centre = img[N // 2, N // 2]
    assert np.isfinite(img).all()
    assert np.allclose(centre, Y0 * 65504.0, rtol=1e-3), centre
    img, proc = render(scene, tmp_path / "f.exr")  # float storage: the exact value
    assert np.allclose(img[N // 2, N // 2], Y0 * 80000.0, rtol=1e-5)


def test_wall_on_the_trees_max_face_is_lit_by_its_leaves(tmp_path):
    # Leaves only for x in [0, 2] m of a 4 m lattice (the roots beyond dropped, as the bake drops
    # cells outside the volumes): a per-pixel wall at x = 2 m facing -x lies on the face between
    # leaves and no leaf. Every pixel belongs to the leaves inside (docs/engine.md, locate_point_cell
    # in pb_interp.c), whichever side of 2.0 its interpolated position rounds to; before, about half
    # of them fell back to probe 0 (stripes on the bundled room's +X wall). L00 = 1 + 0.5 x (linear:
    # reproduced exactly) gives the closed form Y0 * 2 on the whole wall.
    t = native.CornerOctree.uniform((0.0, 0.0, 0.0), 0.5, 2, (2, 1, 2))
    t.drop(t.info()["leaves"][:, 0] >= 4)
    t.finalize()
    pos = t.positions()
    c = np.zeros((len(pos), 9, 3))
    c[:, 0, :] = (1.0 + 0.5 * pos[:, 0])[:, None]
    entry = write_grid(tmp_path, t, c)
    b = sg.GltfBuilder()
    m = b.material("Wall", sh_scale=1.0, ambient_term=0.0, probe_mode="pixel")
    b.node("Wall", mesh=b.mesh("wall", sg.quad(4.0, 4.0, 0, -1.0), m), translation=(2.0, 1.0, 2.0))
    b.node("Camera", camera=b.ortho_camera("side", 0.9), translation=(0.5, 1.0, 2.0), rotation=sg.ROT_LOOK_POS_X)
    b.probe_grids([entry])
    img, _ = render(b.write(tmp_path / "wall.gltf"), tmp_path / "wall.exr", "--no-sky", "--no-direct")
    want = Y0 * 2.0
    assert np.abs(img - want).max() < 2e-6 * want, (img.min(), img.max(), want)


# ---- the continuous visibility field (issue 27; pb_interp.h, docs/placement.md "Visibility field") ----
SHELF = (0.55, 0.95, 0.75)  # a static horizontal square x, z in [0.55, 0.95] at y = 0.75


def shelf_first_hit(a, b):
    """Closed-form first meeting of segment a -> b with the shelf (fraction of the way; 1 = clear)."""
    lo, hi, y = SHELF
    d = b[1] - a[1]
    if abs(d) < 1e-12:
        return 1.0
    s = (y - a[1]) / d
    if not (1e-4 < s < 1 - 1e-4):
        return 1.0
    x, z = a[0] + s * (b[0] - a[0]), a[2] + s * (b[2] - a[2])
    return s if lo <= x <= hi and lo <= z <= hi else 1.0


def pair_table(tree, first_hit):
    """(leaf_count, 8, 8) uint8 of pb_cotree_pair_visibility from an independent closed-form segment
    test: [leaf, k, c] = round(255 t), t = first hit on the way from corner c to corner k, 255 clear.
    (The core also traces segments on leaf edges and faces moved by 1e-3 min cells to each side; the
    shelf is nowhere near a lattice plane, so those rays give the same t.)"""
    info = tree.info()
    origin, h = np.asarray(info["origin"], float), float(info["min_cell"])
    out = np.full((len(info["leaves"]), 8, 8), 255, np.uint8)
    for i, (x, y, z, lv) in enumerate(info["leaves"]):
        s = 2 ** int(lv)
        corner = [origin + h * (np.array([x, y, z]) + s * np.array([c & 1, c >> 1 & 1, c >> 2 & 1])) for c in range(8)]
        for k in range(8):
            for c in range(8):
                if k != c:
                    t = shelf_first_hit(corner[c], corner[k])
                    out[i, k, c] = 255 if t >= 1 else min(max(int(np.floor(255 * t + 0.5)), 1), 255)
    return out


def test_per_pixel_is_continuous_across_a_leaf_border_under_a_beam(tmp_path):
    # Two 1 m leaves along x sharing the face x = 1; a sunbeam from above: the probes at y = 1 hold
    # radiance 5, those at y = 0 radiance 0.05. A static shelf (x, z in [0.55, 0.95], y = 0.75) blocks the
    # segment from the left leaf's centre to the shared corner (1, 1, 1) but not the right leaf's: the
    # per-leaf masks of before dropped that sunlit probe on one side of x = 1 only, and a movable quad
    # at y = 0.4 crossing the border showed a step between two neighbouring pixels of 0.71 (this test
    # against the engine of 24e5473).
    # The visibility field changes continuously with the point: neighbouring pixels differ by what the
    # field's gradient gives over one pixel, and every pixel equals the CPU model (the core's weights
    # with a table built here from the closed-form segment test).
    tree = native.CornerOctree.uniform((0.0, 0.0, 0.0), 1.0, 0, (2, 1, 1))
    tree.finalize()
    pos = tree.positions()
    coeffs = np.stack([ref.uniform_coeffs(5.0 if y > 0.5 else 0.05) for y in pos[:, 1]])
    entry = write_grid(tmp_path, tree, coeffs)
    b = sg.GltfBuilder()
    m = b.material("White", sh_scale=1.0, ambient_term=0.0, probe_mode="pixel")
    lo, hi, y = SHELF
    b.node("Shelf", mesh=b.mesh("shelf", sg.quad(hi - lo, hi - lo, 1), m), translation=(0.5 * (lo + hi), y, 0.5 * (lo + hi)))
    b.node("Receiver", mesh=b.mesh("receiver", sg.quad(0.6, 0.6, 1), m), translation=(9.0, 9.0, 9.0))
    cx, cz, mag = 1.0, 0.25, 0.24
    b.node("Camera", camera=b.ortho_camera("top", mag), translation=(cx, 3.0, cz), rotation=sg.ROT_LOOK_DOWN)
    b.probe_grids([entry])
    scene = b.write(tmp_path / "beam.gltf")
    img, proc = render(scene, tmp_path / "b.exr", "--move", "Receiver", cx, 0.4, cz)
    assert "probe visibility masks: 112 segment(s)" in proc.stderr  # 2 leaves x 56 corner pairs
    p = pixel_points(cx, cz, mag, 0.4)
    table = pair_table(tree, shelf_first_hit)
    assert (table < 255).sum() > 0  # the shelf blocks some corner pairs
    probes, weights = tree.query(p.reshape(-1, 3), pair_visibility=table)
    assert (probes[:, 0] >= 0).all()
    want = np.einsum("mk,mk->m", weights, np.where(pos[:, 1] > 0.5, 5.0, 0.05)[np.maximum(probes, 0)]).reshape(N, N)
    lum = img[..., 1]
    # float32 on the GPU against float64, and the quantized table read alike by both: 1e-5 relative.
    assert np.abs(lum - want).max() < 1e-5 * want.max(), np.abs(lum - want).max()
    # Across x (columns) through the border x = 1: no step. The plain field is constant in x here,
    # so a neighbour differs only by the visibility ramp's slope over a pixel (0.0075 m): measured
    # well under 0.05; the masks of before stepped by 0.71 between two neighbouring pixels.
    steps = np.abs(np.diff(lum, axis=1))
    assert steps.max() < 0.05, steps.max()
