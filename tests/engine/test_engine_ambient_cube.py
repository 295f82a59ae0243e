"""The engine's ambient-cube shading path (docs/ambient-cube.md §5) against an independent numpy
evaluation.

The cube buffer is derived at load from each probe's SH with pb_ambient_cube_from_sh (least
squares). The expected values here come from tests/engine/scripts/probe_ref.py: the closed form of
docs/ambient-cube.md §2 written in numpy (checked against the core's C fit through the Python
module when it is built) and E_cube(n) = Σ n_i² C_{sign(n_i) i} of §1; then DESIGN.md §3's diffuse
albedo·(shScale·max(E, 0)/π + ambientTerm). Per object: a unit sphere lit by one probe, every
interior pixel at its analytic normal. Per pixel: a floor over a 4 × 2 × 4 grid with holes (as
test_engine_perpixel.py) and a sphere inside a 4 × 4 × 4 grid of random probes (every face of
every cube is used, back-face weights). Float and half storage (half: the expected cube is rounded
to binary16 as the engine stores it).
"""
import sys
from pathlib import Path

import numpy as np
import pytest

sys.path.insert(0, str(Path(__file__).parent / "scripts"))
import probe_ref as ref  # noqa: E402
import scenegen as sg  # noqa: E402
import viewer  # noqa: E402
from test_engine_perpixel import (COEFFS as FLOOR_COEFFS, GRID as FLOOR_GRID, N as FLOOR_N,  # noqa: E402
                                  down_camera_points, write_grid)
from test_engine_shading import ALBEDO, AMBIENT, CAM_Z, COEFFS, SH_SCALE, YFOV  # noqa: E402

W = H = 64
FALLBACK = 0.2  # schnee-view's default fallback radiance (docs/engine.md)


def half(a):
    """The engine's binary16 storage (round to nearest even), back in float64."""
    return np.asarray(a, np.float32).astype(np.float16).astype(np.float64)


def cube_of(coeffs, storage):
    # The engine fits from the float32 coefficients of the file.
    c = ref.cube_from_sh(np.asarray(coeffs, np.float32).astype(np.float64))
    return half(c) if storage == "half" else c


def render(scene, out, *args, w=W, h=H):
    viewer.check(viewer.run(scene, "--headless", "--output", out, "--width", w, "--height", h, *args))
    return viewer.read_image(out)


def sphere_scene(d, representation=None, probe_mode=None):
    (d / "sh_coeffs").mkdir(exist_ok=True)
    sg.write_shprobe_v1(d / "sh_coeffs" / "probes.shprobe", COEFFS[None], np.zeros((1, 1, 1), np.int32),
                        (-2, -2, -2), 4.0)
    b = sg.GltfBuilder()
    m = b.material("sphere", base_color=(*ALBEDO, 1), sh_scale=SH_SCALE, ambient_term=AMBIENT,
                   probe_mode=probe_mode)
    if representation is not None:
        b.doc["materials"][m]["extensions"]["VULKAN_SCHNEE_materials"]["probeRepresentation"] = representation
    b.node("Sphere", mesh=b.mesh("sphere", sg.uv_sphere(1.0, 192, 96), m))
    b.node("Camera", camera=b.camera("cam", YFOV), translation=(0, 0, CAM_Z))
    b.probe_grids([sg.grid_entry("probes", "sh_coeffs/probes.shprobe", 1, (-2, -2, -2), (1, 1, 1), 4.0)])
    return b.write(d / "sphere.gltf")


@pytest.fixture(scope="module")
def sphere_render(tmp_path_factory):
    """render(sphere_scene(representation, probe_mode), *args), each distinct render done once for the
    module: the float and half renders of the cube sphere are what test_sphere_per_object_equals_cpu_cube
    checks against the closed form and what test_half_differs_from_float_by_the_rounding_only and
    test_cli_overrides_the_material compare (the same scene file and arguments render the same pixels;
    test_cli_overrides_the_material asserts that too, across files)."""
    done = {}

    def get(representation, *args, probe_mode=None):
        key = (representation, probe_mode, args)
        if key not in done:
            d = tmp_path_factory.mktemp("sphere")
            done[key] = render(sphere_scene(d, representation, probe_mode), d / "out.exr", *args)
        return done[key]
    return get


def test_numpy_fit_matches_the_core_and_closed_forms():
    # Closed forms of docs/ambient-cube.md §3: a constant radiance c gives C = πc on every face; a
    # hemisphere sky (radiance 1 over y > 0, L2 projection) gives π/2 on ±x, ±z, 9π/8 on +y, −π/8 on −y.
    const = ref.cube_from_sh(ref.uniform_coeffs([1.0, 2.0, 0.5]))
    assert np.allclose(const, np.pi * np.array([1.0, 2.0, 0.5]), rtol=1e-8)
    hemi = np.zeros((9, 3))
    hemi[0] = 0.282094792 * 2 * np.pi  # ∫_{y>0} Y0 dω
    hemi[1] = 0.488602512 * np.pi  # ∫_{y>0} K1 y dω = K1 π
    cube = ref.cube_from_sh(hemi)[:, 0]
    assert np.allclose(cube, [np.pi / 2, np.pi / 2, 9 * np.pi / 8, -np.pi / 8, np.pi / 2, np.pi / 2], rtol=1e-6)
    try:
        import schnee_probes._schnee_native as raw
    except ImportError:
        pytest.skip("the native module is not built")
    core = np.frombuffer(raw.ambient_cube_from_sh(np.ascontiguousarray(COEFFS, np.float64).ravel(), 2, 0),
                         dtype=np.float64).reshape(6, 3)
    assert np.allclose(core, ref.cube_from_sh(COEFFS), rtol=1e-7, atol=1e-7)
    n = np.array([[0.6, -0.8, 0.0], [-0.48, 0.6, -0.64], [0.0, 0.0, 1.0]])
    core_e = np.frombuffer(raw.ambient_cube_irradiance(np.ascontiguousarray(core).ravel(), n.ravel()),
                           dtype=np.float64).reshape(-1, 3)
    assert np.allclose(core_e, ref.cube_irradiance(core, n), rtol=1e-12)


@pytest.mark.parametrize("storage", ["float", "half"])
def test_sphere_per_object_equals_cpu_cube(sphere_render, storage):
    img = sphere_render("ambientCube", "--probe-storage", storage)
    p, hit, facing = ref.sphere_normals(W, H, YFOV, CAM_Z)
    cube = cube_of(COEFFS, storage)
    e = ref.cube_irradiance(cube, p)
    expected = ALBEDO * (SH_SCALE * np.maximum(e, 0.0) / np.pi + AMBIENT)
    interior = hit & (facing > 0.3)
    assert interior.sum() > 0.3 * W * H
    # Tolerance as test_engine_shading.py (the tessellated sphere's normals: < 1e-3 rad from the
    # analytic ones); E_cube is quadratic in n like L2 SH. Measured on lavapipe: max abs 1.1e-4,
    # max relative 2.2e-3, float and half alike (half: the expected cube is the stored binary16 one).
    err = np.abs(img[interior] - expected[interior])
    assert np.all(err <= 1e-4 + 3e-3 * np.abs(expected[interior])), f"max abs error {err.max():.4g}"
    # The clamp is exercised: the blue channel's E_cube is negative on part of the visible half.
    assert (e[interior][:, 2] < 0).sum() > 20
    neg = interior & (e[..., 2] < -0.05)
    assert np.allclose(img[neg][:, 2], ALBEDO[2] * AMBIENT, rtol=1e-5)
    # The cube really differs from the SH image (L2 here).
    sh = ALBEDO * (SH_SCALE * np.maximum(ref.irradiance(COEFFS, p), 0.0) / np.pi + AMBIENT)
    assert np.abs(sh[interior] - expected[interior]).max() > 0.02  # measured 0.0295


def test_half_differs_from_float_by_the_rounding_only(sphere_render):
    f = sphere_render("ambientCube", "--probe-storage", "float")  # float is the default storage
    h = sphere_render("ambientCube", "--probe-storage", "half")
    # binary16 keeps 11 significant bits: ≤ 4.9e-4 relative per colour.
    assert 0 < np.abs(h - f).max() <= 2e-3 * np.abs(f).max()


def test_cli_overrides_the_material(tmp_path, sphere_render):
    for sub in "cse":
        (tmp_path / sub).mkdir()
    cube_scene = sphere_scene(tmp_path / "c", "ambientCube")
    sh_scene = sphere_scene(tmp_path / "s", None)
    explicit_sh = sphere_scene(tmp_path / "e", "sh")
    by_material = sphere_render("ambientCube", "--probe-storage", "float")  # float is the default storage
    forced_cube = render(sh_scene, tmp_path / "f.exr", "--probe-representation", "ambientCube")
    assert np.array_equal(by_material, forced_cube)
    plain = render(sh_scene, tmp_path / "p.exr")
    assert np.array_equal(render(explicit_sh, tmp_path / "x.exr"), plain)
    assert np.array_equal(render(cube_scene, tmp_path / "o.exr", "--probe-representation", "sh"), plain)
    assert np.array_equal(render(cube_scene, tmp_path / "mm.exr", "--probe-representation", "material"),
                          by_material)
    assert np.abs(by_material - plain).max() > 0.02  # measured 0.038


def test_fallback_probe_is_the_cube_of_its_sh(tmp_path):
    # Probe mode off: probe 0, the constant radiance 0.2 -> C = 0.2π on every face, E = 0.2π for
    # every normal (the cube reproduces a constant exactly): the sphere is albedo·(shScale·0.2 + ambient).
    scene = sphere_scene(tmp_path, "ambientCube", probe_mode="off")
    img = render(scene, tmp_path / "off.exr")
    p, hit, facing = ref.sphere_normals(W, H, YFOV, CAM_Z)
    interior = hit & (facing > 0.3)
    assert np.allclose(img[interior], ALBEDO * (SH_SCALE * FALLBACK + AMBIENT), rtol=1e-5)


@pytest.mark.parametrize("storage", ["float", "half"])
def test_floor_per_pixel_equals_cpu_interpolated_cubes(tmp_path, storage):
    # test_engine_perpixel.py's floor (holes, clamping at the faces, fallback outside) shaded with
    # cubes: the same weights applied to the cubes; normal +y, so E = C_{+y} interpolated.
    entry = write_grid(tmp_path, "probes", FLOOR_COEFFS, FLOOR_GRID, (0, 0, 0), 1.0)
    b = sg.GltfBuilder()
    m = b.material("white", sh_scale=1.0, ambient_term=0.0, probe_mode="pixel")
    b.doc["materials"][m]["extensions"]["VULKAN_SCHNEE_materials"]["probeRepresentation"] = "ambientCube"
    b.node("Floor", mesh=b.mesh("floor", sg.quad(5.0, 5.0, 1), m), translation=(2.0, 0.1, 2.0))
    b.node("Camera", camera=b.ortho_camera("top", 2.5), translation=(2.0, 3.1, 2.0), rotation=sg.ROT_LOOK_DOWN)
    b.probe_grids([entry])
    scene = b.write(tmp_path / "floor.gltf")
    img = render(scene, tmp_path / "pp.exr", "--probe-storage", storage, w=FLOOR_N, h=FLOOR_N)
    p = down_camera_points(2.0, 2.0, 0.1, 2.5).reshape(-1, 3)
    n = np.tile([0.0, 1.0, 0.0], (len(p), 1))
    cubes = np.stack([cube_of(c, storage) for c in FLOOR_COEFFS])
    e, held = ref.grid_irradiance(p, n, FLOOR_GRID, (0, 0, 0), 1.0, cubes, evaluate=ref.cube_irradiance)
    e[~held] = np.pi * FALLBACK
    expected = (np.maximum(e, 0) / np.pi).reshape(FLOOR_N, FLOOR_N, 3)
    err = np.abs(img - expected)
    # Measured on lavapipe: max abs error 1.8e-6 (float), 3.2e-5 (half); pixel values up to 1.2.
    assert err.max() < 1e-4 + 1e-4 * np.abs(expected).max(), f"max abs error {err.max():.3g}"
    assert held.sum() > 0.5 * FLOOR_N * FLOOR_N and (~held).sum() > 50
    assert np.ptp(img[held.reshape(FLOOR_N, FLOOR_N)][:, 0]) > 0.3


@pytest.mark.parametrize("storage", ["float", "half"])
def test_sphere_per_pixel_equals_cpu_interpolated_cubes(tmp_path, storage):
    # A sphere of radius R = 0.4 at the centre of a 2 × 2 × 2 grid of 1 m cells (origin −1) with a
    # random probe per cell: every normal direction, so every face of the cubes, and trilinear
    # weights that vary over the sphere. The only segment between cell centres the sphere blocks
    # (visibility masks, not modelled in probe_ref) joins a centre to the opposite one, which is
    # always behind the tangent plane (back-face weight 0), so the masks change nothing here.
    R = 0.4
    rng = np.random.default_rng(5)
    coeffs = rng.normal(0.0, 0.4, (8, 9, 3))
    coeffs[:, 0] = rng.uniform(1.0, 3.0, (8, 3))
    grid = np.arange(8, dtype=np.int32).reshape(2, 2, 2)
    entry = write_grid(tmp_path, "probes", coeffs, grid, (-1, -1, -1), 1.0)
    b = sg.GltfBuilder()
    m = b.material("white", sh_scale=1.0, ambient_term=0.0, probe_mode="pixel")
    b.doc["materials"][m]["extensions"]["VULKAN_SCHNEE_materials"]["probeRepresentation"] = "ambientCube"
    b.node("Sphere", mesh=b.mesh("sphere", sg.uv_sphere(R, 192, 96), m))
    b.node("Camera", camera=b.camera("cam", YFOV), translation=(0, 0, CAM_Z * R))  # the unit view, scaled
    b.probe_grids([entry])
    scene = b.write(tmp_path / "sphere.gltf")
    img = render(scene, tmp_path / "pp.exr", "--probe-storage", storage)
    n, hit, facing = ref.sphere_normals(W, H, YFOV, CAM_Z)
    interior = hit & (facing > 0.3)
    nrm = n[interior]
    cubes = np.stack([cube_of(c, storage) for c in coeffs])
    e, held = ref.grid_irradiance(R * nrm, nrm, grid, (-1, -1, -1), 1.0, cubes, evaluate=ref.cube_irradiance)
    assert held.all()
    expected = np.maximum(e, 0) / np.pi
    err = np.abs(img[interior] - expected)
    # The tessellation moves points and normals by < 1e-3 (relative); the trilinear weights change
    # by < 1e-3 per mm over 1 m cells. Measured on lavapipe: max abs error 3.4e-4 (relative 8.6e-4),
    # float and half alike.
    assert err.max() < 1e-4 + 3e-3 * np.abs(expected).max(), f"max abs {err.max():.3g}"
    # It is not one probe's cube: the interpolation moves the image by more than 0.05 somewhere.
    single = np.maximum(ref.cube_irradiance(cubes[7], nrm), 0) / np.pi
    assert np.abs(single - expected).max() > 0.05
    # The SH image of the same grid is far from it (the cube is a different representation).
    sh, _ = ref.grid_irradiance(R * nrm, nrm, grid, (-1, -1, -1), 1.0, coeffs)
    assert np.abs(np.maximum(sh, 0) / np.pi - expected).max() > 0.02


@pytest.mark.parametrize("value, message", [
    ('"cube"', "probeRepresentation: 'cube' is not sh or ambientCube"),
    ('"SH"', "probeRepresentation: 'SH' is not sh or ambientCube"),
    ("1", "probeRepresentation: expected a string, got a number"),
])
def test_invalid_material_field_is_a_load_error(tmp_path, value, message):
    scene = sphere_scene(tmp_path, "PLACEHOLDER")
    text = Path(scene).read_text().replace('"PLACEHOLDER"', value)
    Path(scene).write_text(text)
    proc = viewer.run(scene, "--headless", "--output", tmp_path / "x.exr", "--width", 8, "--height", 8)
    assert proc.returncode == 1, proc.stderr
    assert f"materials[0].extensions.VULKAN_SCHNEE_materials.{message}" in proc.stderr


def test_invalid_cli_value(tmp_path):
    scene = sphere_scene(tmp_path, None)
    proc = viewer.run(scene, "--headless", "--probe-representation", "cube", validation=False)
    assert proc.returncode == 2
    assert "cube" in proc.stderr


def test_fallback_probe_with_a_sky_is_the_cube_of_the_sky_sh(tmp_path):
    # No grid: probe 0 is the sky's SH from the glTF entry, and its cube is fitted from it at load.
    # Specular off, so the pixel is DESIGN.md §3's diffuse formula with E_cube of the sky's SH.
    from test_engine_ibl import sky_scene, smooth_sky, sphere_setup
    w = h = 48
    albedo, sh_scale, ambient = np.array([0.8, 0.7, 0.5]), 0.9, 0.02
    img = smooth_sky()

    def material(b):
        m = b.material("m", base_color=(*albedo, 1), sh_scale=sh_scale, ambient_term=ambient)
        b.doc["materials"][m]["extensions"]["VULKAN_SCHNEE_materials"]["probeRepresentation"] = "ambientCube"
        return m

    scene = sky_scene(tmp_path, img, [sphere_setup(material)],
                      camera=lambda b: b.node("Camera", camera=b.camera("cam", 0.9), translation=(0, 0, 3)))
    out = tmp_path / "fb.exr"
    got = render(scene, out, "--no-specular", w=w, h=h)
    p, hit, facing = ref.sphere_normals(w, h, 0.9, 3.0)
    inner = hit & (facing > 0.3)
    sky_sh = ref.project_l2(img)
    want = albedo * (sh_scale * np.maximum(ref.cube_irradiance(ref.cube_from_sh(sky_sh), p[inner]), 0) / np.pi
                     + ambient)
    # Same bound as test_engine_ibl's SH fallback (96 x 48 sphere): 0.5 % of the largest value.
    assert np.abs(got[inner] - want).max() < 5e-3 * want.max()
    sh_want = albedo * (sh_scale * np.maximum(ref.irradiance(sky_sh, p[inner]), 0) / np.pi + ambient)
    assert np.abs(sh_want - want).max() > 2e-2 * want.max()  # it is the cube, not the SH


def test_cube_beyond_half_range_falls_back_to_float(tmp_path):
    # Coefficients that fit binary16 (40000, 30000 < 65504) whose cube does not:
    # C_{+y} = 0.886227·40000 + 1.279158·30000 = 73824. Half storage would store Inf; the engine
    # warns, names the probe and the face, and renders with float storage.
    c = np.zeros((1, 9, 3))
    c[0, 0] = 40000.0
    c[0, 1] = 30000.0
    assert np.abs(c).max() < 65504 and ref.cube_from_sh(c[0]).max() > 65504
    (tmp_path / "sh_coeffs").mkdir()
    sg.write_shprobe_v1(tmp_path / "sh_coeffs" / "big.shprobe", c, np.zeros((1, 1, 1), np.int32), (-2, -2, -2), 4.0)
    b = sg.GltfBuilder()
    m = b.material("white", sh_scale=1e-5, ambient_term=0.0)
    b.doc["materials"][m]["extensions"]["VULKAN_SCHNEE_materials"]["probeRepresentation"] = "ambientCube"
    b.node("Sphere", mesh=b.mesh("sphere", sg.uv_sphere(1.0, 96, 48), m))
    b.node("Camera", camera=b.camera("cam", YFOV), translation=(0, 0, CAM_Z))
    b.probe_grids([sg.grid_entry("big", "sh_coeffs/big.shprobe", 1, (-2, -2, -2), (1, 1, 1), 4.0)])
    scene = b.write(tmp_path / "big.gltf")
    proc = viewer.run(scene, "--headless", "--output", tmp_path / "h.exr", "--width", 32, "--height", 32,
                      "--probe-storage", "half")
    viewer.check(proc)
    assert "shProbeGrids[0] 'big' probe 0: ambient-cube face 2 channel 0 = 73823.8 exceeds the half-float range" in proc.stderr
    assert "using float storage" in proc.stderr
    f = render(scene, tmp_path / "f.exr", w=32, h=32)
    h = viewer.read_image(tmp_path / "h.exr")
    assert np.isfinite(h).all() and np.array_equal(h, f)
