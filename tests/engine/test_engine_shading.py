"""schnee-view shading against an independent CPU evaluation of DESIGN.md §3.

A unit sphere lit only by one probe with known coefficients (no lights, no emission) is rendered
to EXR on lavapipe. Each pixel's normal is reconstructed analytically (camera ray ∩ sphere) and the
expected value albedo·(shScale·max(E(n),0)/π + ambientTerm) is computed here in numpy from the
formulas of DESIGN.md §3, independently of shaders/sh.glsl and native/src/pb_sh.c.
"""
import sys
from pathlib import Path

import numpy as np
import pytest

sys.path.insert(0, str(Path(__file__).parent / "scripts"))
import scenegen as sg  # noqa: E402
import viewer  # noqa: E402
# DESIGN.md §3 basis (l <= 2) and irradiance in numpy, written from the document (scripts/probe_ref.py).
import probe_ref  # noqa: E402
from probe_ref import irradiance  # noqa: E402

W = H = 64
YFOV = 0.9
CAM_Z = 3.0
ALBEDO = np.array([0.8, 0.6, 0.4])
SH_SCALE, AMBIENT = 0.7, 0.05

# Radiance coefficients (L_i, RGB): strong band 0, all three bands used, some directions clamp to 0.
COEFFS = np.zeros((9, 3))
COEFFS[0] = [2.0, 1.5, 1.0]
COEFFS[1] = [0.5, 0.2, -0.1]
COEFFS[2] = [0.3, -0.2, -1.2]  # blue: E < 0 on the side facing the camera (tests the clamp)
COEFFS[3] = [-0.4, 0.1, 0.2]
COEFFS[4] = [0.1, 0.05, -0.05]
COEFFS[5] = [-0.15, 0.2, 0.1]
COEFFS[6] = [-0.2, 0.1, 0.15]
COEFFS[7] = [0.12, -0.08, 0.3]
COEFFS[8] = [0.1, -0.1, 0.05]


def sphere_normals():
    return probe_ref.sphere_normals(W, H, YFOV, CAM_Z)


@pytest.fixture(scope="module")
def sphere_scene(tmp_path_factory):
    d = tmp_path_factory.mktemp("sphere")
    (d / "sh_coeffs").mkdir()
    sg.write_shprobe_v1(d / "sh_coeffs" / "probes.shprobe", COEFFS[None], np.zeros((1, 1, 1), np.int32),
                        (-2, -2, -2), 4.0)
    b = sg.GltfBuilder()
    m = b.material("sphere", base_color=(*ALBEDO, 1), sh_scale=SH_SCALE, ambient_term=AMBIENT)
    b.node("Sphere", mesh=b.mesh("sphere", sg.uv_sphere(1.0, 192, 96), m))
    b.node("Camera", camera=b.camera("cam", YFOV), translation=(0, 0, CAM_Z))
    b.probe_grids([sg.grid_entry("probes", "sh_coeffs/probes.shprobe", 1, (-2, -2, -2), (1, 1, 1), 4.0)])
    return b.write(d / "sphere.gltf")


def test_numpy_reference_matches_closed_form():
    # E for a constant radiance L: L_00 = L·Y0·4π and E = π·L everywhere (closed form).
    c = np.zeros((9, 3))
    c[0] = 0.282094792 * 4 * np.pi
    n = np.array([[0, 1, 0], [0.6, 0, 0.8], [0, 0, -1]])
    assert np.allclose(irradiance(c, n), np.pi, rtol=1e-8)


def test_sphere_pixels_equal_cpu_evaluation(sphere_scene, tmp_path):
    out = tmp_path / "sphere.exr"
    viewer.check(viewer.run(sphere_scene, "--headless", "--output", out, "--width", W, "--height", H))
    img = viewer.read_image(out)
    assert img.shape == (H, W, 3)
    p, hit, facing = sphere_normals()
    expected = ALBEDO * (SH_SCALE * np.maximum(irradiance(COEFFS, p), 0.0) / np.pi + AMBIENT)
    # Interior pixels: away from the silhouette, where a pixel centre may fall on the other side of
    # the tessellated outline. Tolerance: the 192x96 UV sphere's interpolated normals deviate from
    # the analytic ones by < 1e-3 rad there (chord sag (2π/192)²/8 ≈ 1.3e-4 of the radius, amplified
    # by at most 1/facing). Measured on lavapipe: max abs error 6.8e-5, max relative 1.5e-3, mean
    # relative 7e-5. Bound: 1e-4 absolute + 0.3 % relative, mean relative < 5e-4.
    interior = hit & (facing > 0.3)
    assert interior.sum() > 0.3 * W * H  # the sphere covers ~45 % of the frame
    err = np.abs(img[interior] - expected[interior])
    tol = 1e-4 + 3e-3 * np.abs(expected[interior])
    assert np.all(err <= tol), f"max abs error {err.max():.4g}, worst rel {(err / np.abs(expected[interior])).max():.4g}"
    # A sign, basis or normal mistake gives errors of ~10-50 % (back-face normals gave 55 %).
    assert np.mean(err / np.abs(expected[interior])) < 5e-4
    # Background: nothing drawn, the clear colour (0) stays.
    assert np.all(img[~hit & (np.abs(facing) < 5)] == 0.0)


def test_clamped_region_is_exactly_ambient(sphere_scene, tmp_path):
    # Where E(n) < 0 in a channel, the formula gives exactly albedo·ambientTerm in that channel.
    out = tmp_path / "sphere.exr"
    viewer.check(viewer.run(sphere_scene, "--headless", "--output", out, "--width", W, "--height", H))
    img = viewer.read_image(out)
    p, hit, facing = sphere_normals()
    e = irradiance(COEFFS, p)
    neg = hit & (facing > 0.3) & (e[..., 2] < -0.05)
    assert neg.sum() > 50  # by construction of COEFFS[2]
    assert np.allclose(img[neg][:, 2], ALBEDO[2] * AMBIENT, rtol=1e-5)


def test_png_is_tonemapped_srgb_of_the_exr(sphere_scene, tmp_path):
    # Khronos PBR Neutral is the identity below 0.76 after its toe offset; the values here are
    # below 0.76, so PNG = sRGB(x - offset(x)) quantised to 8 bits (±1 level for rounding).
    exr, png = tmp_path / "s.exr", tmp_path / "s.png"
    viewer.check(viewer.run(sphere_scene, "--headless", "--output", exr, "--width", W, "--height", H))
    viewer.check(viewer.run(sphere_scene, "--headless", "--output", png, "--width", W, "--height", H))
    lin, enc = viewer.read_image(exr), viewer.read_image(png)
    x = lin.min(axis=-1, keepdims=True)
    mapped = lin - np.where(x < 0.08, x - 6.25 * x * x, 0.04)
    assert mapped.max() < 0.76
    srgb = np.where(mapped <= 0.0031308, 12.92 * mapped, 1.055 * np.power(np.maximum(mapped, 0), 1 / 2.4) - 0.055)
    assert np.abs(enc - np.clip(srgb, 0, 1)).max() <= 1.5 / 255


def test_band4_probe_matches_core_cpu_evaluator(tmp_path):
    # A version-2 file with L = 4 (25 coefficients), written by the bake core's own writer; the
    # reference is the core's pb_sh_irradiance (through the Python module), which the GLSL in
    # shaders/sh.glsl mirrors. Bands 3 (A3 = 0) and 4 (A4 = -π/24) both enter E.
    native = pytest.importorskip("schnee_probes.native", reason="needs the built _schnee_native module")
    try:
        native.sh_count(4)
    except Exception as exc:  # module present but not built
        pytest.skip(f"_schnee_native unavailable: {exc}")
    rng = np.random.default_rng(7)
    c = rng.normal(0.0, 0.25, (25, 3))
    c[0] = [3.0, 2.5, 2.0]
    c[16:25] *= 3.0  # make band 4 matter (A4 is small)
    (tmp_path / "sh_coeffs").mkdir()
    native.write_shprobe(str(tmp_path / "sh_coeffs" / "l4.shprobe"), c[None].astype(np.float32),
                         np.zeros((1, 1, 1), np.int32), (1, 1, 1), (-2, -2, -2), 4.0)
    b = sg.GltfBuilder()
    m = b.material("white", base_color=(1, 1, 1, 1), sh_scale=1.0, ambient_term=0.0)
    b.node("Sphere", mesh=b.mesh("sphere", sg.uv_sphere(1.0, 192, 96), m))
    b.node("Camera", camera=b.camera("cam", YFOV), translation=(0, 0, CAM_Z))
    b.probe_grids([sg.grid_entry("l4", "sh_coeffs/l4.shprobe", 1, (-2, -2, -2), (1, 1, 1), 4.0, max_band=4)])
    out = tmp_path / "l4.exr"
    viewer.check(viewer.run(b.write(tmp_path / "l4.gltf"), "--headless", "--output", out, "--width", W, "--height", H))
    img = viewer.read_image(out)
    p, hit, facing = sphere_normals()
    interior = hit & (facing > 0.3)
    e = native.irradiance(c.astype(np.float32).astype(np.float64), p[interior] / np.linalg.norm(p[interior], axis=-1, keepdims=True))
    expected = np.maximum(e, 0.0) / np.pi
    band2_only = np.maximum(irradiance(c[:9], p[interior]), 0.0) / np.pi
    assert np.abs(expected - band2_only).max() > 0.02  # band 4 changes the image measurably
    err = np.abs(img[interior] - expected)
    assert np.all(err <= 1e-4 + 3e-3 * np.abs(expected)), f"max abs error {err.max():.4g}"


def _sphere_gltf(d, scale):
    (d / "sh_coeffs").mkdir(exist_ok=True)
    sg.write_shprobe_v1(d / "sh_coeffs" / "probes.shprobe", COEFFS[None], np.zeros((1, 1, 1), np.int32),
                        (-2, -2, -2), 4.0)
    b = sg.GltfBuilder()
    m = b.material("sphere", base_color=(*ALBEDO, 1), sh_scale=SH_SCALE, ambient_term=AMBIENT)
    b.node("Sphere", mesh=b.mesh("sphere", sg.uv_sphere(1.0, 192, 96), m), scale=[float(s) for s in scale])
    b.node("Camera", camera=b.camera("cam", YFOV), translation=(0, 0, CAM_Z))
    b.probe_grids([sg.grid_entry("probes", "sh_coeffs/probes.shprobe", 1, (-2, -2, -2), (1, 1, 1), 4.0)])
    return b.write(d / f"sphere_{'m' if scale[0] < 0 else 'p'}.gltf")


def test_mirrored_node_matches_plain(tmp_path):
    # glTF 2.0 §3.7.4: a node whose world matrix has a negative determinant has clockwise front
    # faces. The UV sphere is symmetric under x -> -x, so scale [-1, 1, 1] draws the same surface with
    # reversed winding (and normals mirrored back outward by the normal matrix); before the per-draw
    # mirror flag the shader flipped every visible normal (max abs diff 0.87 between the two EXRs).
    imgs = []
    for scale in ((1, 1, 1), (-1, 1, 1)):
        out = tmp_path / f"s{scale[0]}.exr"
        viewer.check(viewer.run(_sphere_gltf(tmp_path, scale), "--headless", "--output", out,
                                "--width", W, "--height", H))
        imgs.append(viewer.read_image(out))
    plain, mirrored = imgs
    p, hit, facing = sphere_normals()
    interior = hit & (facing > 0.3)
    # Same pixels up to float noise: the mirrored mesh's vertices land on the same positions (the
    # sphere's x -> -x symmetry is exact up to the float32 sin/cos of its generator): 1e-5 absolute.
    assert np.abs(plain[interior] - mirrored[interior]).max() <= 1e-5
    # And both equal the numpy reference (tolerance of test_sphere_pixels_equal_cpu_evaluation).
    expected = ALBEDO * (SH_SCALE * np.maximum(irradiance(COEFFS, p), 0.0) / np.pi + AMBIENT)
    err = np.abs(mirrored[interior] - expected[interior])
    assert np.all(err <= 1e-4 + 3e-3 * np.abs(expected[interior])), f"max abs error {err.max():.4g}"


@pytest.mark.parametrize("storage", ["float", "half"])
def test_probe_scale_used_probe_ambient_and_header_defaults_ignored(tmp_path, storage):
    # docs/shprobe-format.md "What readers use": the per-probe scale multiplies the material's
    # shScale; the per-probe ambient and the header's default SH scale / default ambient are
    # ignored (the material's ambientTerm is the ambient). A file with scale 2, ambient 5 and header
    # defaults 7 / 3 must shade as albedo·(shScale·2·max(E,0)/π + ambientTerm), the closed form.
    (tmp_path / "sh_coeffs").mkdir()
    sg.write_shprobe_v1(tmp_path / "sh_coeffs" / "probes.shprobe", COEFFS[None], np.zeros((1, 1, 1), np.int32),
                        (-2, -2, -2), 4.0, scale=[2.0], ambient=[5.0], default_scale=7.0, default_ambient=3.0)
    b = sg.GltfBuilder()
    m = b.material("sphere", base_color=(*ALBEDO, 1), sh_scale=SH_SCALE, ambient_term=AMBIENT)
    b.node("Sphere", mesh=b.mesh("sphere", sg.uv_sphere(1.0, 192, 96), m))
    b.node("Camera", camera=b.camera("cam", YFOV), translation=(0, 0, CAM_Z))
    b.probe_grids([sg.grid_entry("probes", "sh_coeffs/probes.shprobe", 1, (-2, -2, -2), (1, 1, 1), 4.0)])
    scene = b.write(tmp_path / "sphere.gltf")
    out = tmp_path / "sphere.exr"
    viewer.check(viewer.run(scene, "--headless", "--output", out, "--width", W, "--height", H,
                            "--probe-storage", storage))
    img = viewer.read_image(out)
    p, hit, facing = sphere_normals()
    expected = ALBEDO * (SH_SCALE * 2.0 * np.maximum(irradiance(COEFFS, p), 0.0) / np.pi + AMBIENT)
    interior = hit & (facing > 0.3)
    err = np.abs(img[interior] - expected[interior])
    # As test_sphere_pixels_equal_cpu_evaluation; half storage adds its rounding (11 bits: 4.9e-4).
    rel = 3e-3 if storage == "float" else 4e-3
    tol = 1e-4 + rel * np.abs(expected[interior])
    assert np.all(err <= tol), f"max abs error {err.max():.4g}"
    # Using the per-probe ambient (5) or a header default would shift every pixel by >= albedo·3.
