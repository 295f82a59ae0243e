"""Image-based lighting from the baked sky (docs/engine.md "Sky and image-based lighting").

Checked against numpy: the background equals a bilinear lookup of the sky image along each pixel's
ray (DESIGN.md §3's panorama mapping); the fallback probe 0 equals the sky's SH; the split-sum BRDF
LUT equals a numerical integration of its defining integral; sky specular is scaled by
clamp(E_probe / E_sky, 0, 1).
"""
import sys
from pathlib import Path

import numpy as np
import pytest

sys.path.insert(0, str(Path(__file__).parent / "scripts"))
import probe_ref as ref  # noqa: E402
import scenegen as sg  # noqa: E402
import viewer  # noqa: E402

SKY_W, SKY_H = 64, 32


def smooth_sky():
    """A smooth HDR sky: brighter and bluer up, a warm lobe toward +x, values 0.2 .. 3."""
    d, _ = ref.equirect_dirs(SKY_W, SKY_H)
    up = d[..., 1]
    sun = np.maximum(d[..., 0], 0) ** 2
    return np.stack([0.6 + 0.3 * up + 2.0 * sun, 0.7 + 0.4 * up + 1.2 * sun, 1.0 + 0.8 * up + 0.4 * sun], -1)


def sky_scene(d, img, objects=(), grids=(), camera=None):
    sg.write_exr(d / "sky.exr", img)
    b = sg.GltfBuilder()
    for build in objects:
        build(b)
    if camera is None:
        b.node("Camera", camera=b.camera("cam", 1.2), translation=(0, 0, 0))
    else:
        camera(b)
    b.probe_grids(list(grids), sky=sg.sky_entry("sky.exr", ref.project_l2(img)))
    return b.write(d / "sky.gltf")


def tiny_far_object(b):
    # Something to draw (an empty scene frames nothing); 1 mm, behind the camera.
    b.node("Speck", mesh=b.mesh("speck", sg.cube(0.0005), b.material("m")), translation=(0, 0, 50))


def quat_x(a):
    return (np.sin(a / 2), 0.0, 0.0, np.cos(a / 2))


@pytest.mark.parametrize("pitch", [0.0, 0.7])
def test_background_is_the_sky_image(tmp_path, pitch):
    W, H, yfov = 48, 32, 1.2
    img = smooth_sky()
    scene = sky_scene(tmp_path, img, [tiny_far_object],
                      camera=lambda b: b.node("Camera", camera=b.camera("cam", yfov), rotation=quat_x(pitch)))
    out = tmp_path / "bg.exr"
    viewer.check(viewer.run(scene, "--headless", "--output", out, "--width", W, "--height", H))
    got = viewer.read_image(out)
    i, j = np.meshgrid(np.arange(W) + 0.5, np.arange(H) + 0.5)
    t = np.tan(yfov / 2)
    ray = np.stack([(2 * i / W - 1) * t * W / H, (1 - 2 * j / H) * t, -np.ones_like(i)], -1)
    c, s = np.cos(pitch), np.sin(pitch)
    ray = np.stack([ray[..., 0], c * ray[..., 1] - s * ray[..., 2], s * ray[..., 1] + c * ray[..., 2]], -1)
    ray /= np.linalg.norm(ray, axis=-1, keepdims=True)
    want = ref.sample_equirect(img, ray)
    # Bilinear weights are quantised by the sampler (lavapipe: 8 sub-texel bits, error <= 1/512 of
    # a neighbouring-texel step, ~1e-3 here); measured max relative error 6e-4.
    rel = np.abs(got - want) / want
    assert rel.max() < 3e-3, f"max relative error {rel.max():.3g}"
    # A wrong mapping (e.g. u mirrored) differs by > 10 % somewhere.
    assert np.abs(ref.sample_equirect(img, ray * [-1, 1, 1]) - want).max() / want.max() > 0.1


def sphere_setup(material):
    def build(b):
        b.node("Sphere", mesh=b.mesh("sphere", sg.uv_sphere(1.0, 96, 48), material(b)))
    return build


def test_fallback_probe_is_the_sky_sh(tmp_path):
    # No grid: the sphere gets probe 0, which is the sky's SH from the glTF entry (not the
    # constant 0.2). Specular off, so the pixel is DESIGN.md §3's diffuse formula.
    W = H = 48
    albedo, sh_scale, ambient = np.array([0.8, 0.7, 0.5]), 0.9, 0.02
    img = smooth_sky()
    scene = sky_scene(tmp_path, img, [sphere_setup(
        lambda b: b.material("m", base_color=(*albedo, 1), sh_scale=sh_scale, ambient_term=ambient))],
        camera=lambda b: b.node("Camera", camera=b.camera("cam", 0.9), translation=(0, 0, 3)))
    out = tmp_path / "fb.exr"
    viewer.check(viewer.run(scene, "--headless", "--output", out, "--width", W, "--height", H, "--no-specular"))
    got = viewer.read_image(out)
    p, hit, facing = ref.sphere_normals(W, H, 0.9, 3.0)
    inner = hit & (facing > 0.3)
    want = albedo * (sh_scale * np.maximum(ref.irradiance(ref.project_l2(img), p[inner]), 0) / np.pi + ambient)
    # Same bound as test_engine_shading (tessellated normals, 96 x 48 sphere): 0.5 %.
    assert np.abs(got[inner] - want).max() < 5e-3 * want.max()
    # With --no-sky the constant fallback (radiance 0.2) is back: albedo·(0.9·0.2 + 0.02).
    viewer.check(viewer.run(scene, "--headless", "--output", out, "--width", W, "--height", H, "--no-sky"))
    assert np.allclose(viewer.read_image(out)[inner], albedo * (sh_scale * 0.2 + ambient), rtol=1e-5)


def brdf_reference(nv, rough, nt=2000, nphi=400):
    """(A, B) of the split-sum LUT by quadrature over half vectors h:
    A = ∫ D(h) G(l, v) (1 - Fc) (v·h) / (n·v) dω_h, B the same with Fc, Fc = (1 - v·h)^5,
    GGX D with alpha = rough², Smith-Schlick G with k = alpha / 2 (Karis 2013)."""
    a = rough * rough
    k = a / 2
    th = (np.arange(nt) + 0.5) * (np.pi / 2) / nt
    ph = (np.arange(nphi) + 0.5) * 2 * np.pi / nphi
    T, P = np.meshgrid(th, ph, indexing="ij")
    h = np.stack([np.sin(T) * np.cos(P), np.sin(T) * np.sin(P), np.cos(T)], -1)
    v = np.array([np.sqrt(1 - nv * nv), 0, nv])
    vh = h @ v
    l = 2 * vh[..., None] * h - v
    nl, nh = l[..., 2], h[..., 2]
    D = a * a / (np.pi * (nh * nh * (a * a - 1) + 1) ** 2)
    g1 = lambda x: x / (x * (1 - k) + k)  # noqa: E731
    ok = (nl > 0) & (vh > 0)
    G = np.where(ok, g1(np.maximum(nl, 1e-9)) * g1(nv), 0.0)
    fc = (1 - np.clip(vh, 0, 1)) ** 5
    dw = np.sin(T) * (np.pi / 2 / nt) * (2 * np.pi / nphi)
    base = D * G * np.maximum(vh, 0) / nv * dw
    return float(np.sum(base * (1 - fc))), float(np.sum(base * fc))


def test_brdf_lut_against_integration(tmp_path):
    out = tmp_path / "lut.exr"
    viewer.check(viewer.run("--write-brdf-lut", out, validation=False))
    lut = viewer.read_image(out)
    size = lut.shape[0]
    assert lut.shape == (size, size, 3) and size == 64
    # Texel (i, j): NoV = (i + 0.5) / size, roughness = (j + 0.5) / size (row j from the top).
    # Smooth end: NoV -> 1, roughness -> 0 gives (1, 0) (Karis 2013's LUT corner).
    assert np.allclose(lut[0, -1, :2], [1.0, 0.0], atol=2e-3)
    worst = 0.0
    for i, j in [(8, 20), (32, 20), (60, 20), (16, 40), (40, 40), (8, 63), (32, 63), (63, 63)]:
        nv, r = (i + 0.5) / size, (j + 0.5) / size
        a, b = brdf_reference(nv, r)
        worst = max(worst, abs(lut[j, i, 0] - a), abs(lut[j, i, 1] - b))
    # 4096 Hammersley samples vs the quadrature (converged to 1e-6): measured max abs difference
    # 1.9e-3 (at NoV = 0.13, the grazing end, where importance sampling D alone converges slowest).
    assert worst < 4e-3, worst


def mirror_scene(d, probe_radiance=None, sky_radiance=2.0):
    img = np.full((SKY_H, SKY_W, 3), sky_radiance)
    grids = []
    if probe_radiance is not None:
        (d / "sh_coeffs").mkdir(exist_ok=True)
        sg.write_shprobe_v1(d / "sh_coeffs" / "g.shprobe", ref.uniform_coeffs(probe_radiance)[None],
                            np.zeros((1, 1, 1), np.int32), (-2, -2, -2), 4.0)
        grids = [sg.grid_entry("g", "sh_coeffs/g.shprobe", 1, (-2, -2, -2), (1, 1, 1), 4.0)]
    # Metal mirror; shScale 0 and ambient 0 remove the diffuse term, leaving the sky specular.
    return sky_scene(d, img, [sphere_setup(lambda b: b.material(
        "mirror", base_color=(0.9, 0.9, 0.9, 1), sh_scale=0.0, ambient_term=0.0, metallic=1.0, roughness=0.0))],
        grids, camera=lambda b: b.node("Camera", camera=b.camera("cam", 0.9), translation=(0, 0, 3)))


def test_sky_specular_scaled_by_probe_irradiance(tmp_path):
    W = H = 32
    p, hit, facing = ref.sphere_normals(W, H, 0.9, 3.0)
    inner = hit & (facing > 0.3)
    renders = {}
    for name, probe in [("open", None), ("dark", 0.5), ("bright", 4.0)]:
        d = tmp_path / name
        d.mkdir()
        out = d / "m.exr"
        viewer.check(viewer.run(mirror_scene(d, probe), "--headless", "--output", out, "--width", W, "--height", H))
        renders[name] = viewer.read_image(out)
    open_ = renders["open"][inner]
    # Outside every grid the probe is the sky itself: ratio 1. A uniform sky of 2 reflects 2 in
    # every prefiltered mip, times F0·A + B ~ Schlick(0.9, n·v) ~ 0.9 where n·v ~ 1.
    c = H // 2
    assert renders["open"][c, c] == pytest.approx([1.8] * 3, rel=0.02)
    # Inside a grid whose probe sees radiance 0.5 (E = 0.5π) under a sky of 2 (E ~ 2π): ratio
    # lum(E_probe(n)) / lum(E_sky(n)) ~ 0.25, with E_sky from the SH in the glTF (the sky's
    # projection carries ~1e-4 discretisation terms in band 2, so compute it per normal).
    n = p[inner]
    lum = np.array([0.2126, 0.7152, 0.0722])
    sky_sh = ref.project_l2(np.full((SKY_H, SKY_W, 3), 2.0))
    ratio = (0.5 * np.pi) / (ref.irradiance(sky_sh, n) @ lum)
    assert np.abs(ratio - 0.25).max() < 1e-3
    assert np.allclose(renders["dark"][inner], ratio[:, None] * open_, rtol=2e-5)
    # A probe brighter than the sky does not amplify the reflection (clamped at 1).
    assert np.allclose(renders["bright"][inner], open_, rtol=1e-5)
    out = tmp_path / "dark" / "n.exr"
    viewer.check(viewer.run(tmp_path / "dark" / "sky.gltf", "--headless", "--output", out, "--width", W,
                            "--height", H, "--no-renorm"))
    assert np.allclose(viewer.read_image(out)[inner], open_, rtol=1e-4)
