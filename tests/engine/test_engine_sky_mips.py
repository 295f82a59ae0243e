"""The GGX-prefiltered sky mips the engine uploads (docs/engine.md "Sky and image-based lighting").

`schnee-view SCENE --write-sky-mips PREFIX` dumps the chain; level k (of M) must be the sky
convolved for roughness r = k / (M - 1) with N = V = R (Karis 2013's split-sum assumption):

    prefiltered(n) = ∫ L(l) D(h) (n·l) dω_l / ∫ D(h) (n·l) dω_l,   h = normalize(n + l),

GGX D with alpha = r², over the hemisphere n·l > 0. The reference integrates that by quadrature
(polar grid around n, converged: see reference()) over the continuous sky the engine samples, the
bilinear interpolation of the image (probe_ref.sample_equirect). The engine importance-samples the
same integral with 32–256 Hammersley samples from a box-filtered pyramid (filtered importance
sampling), so it agrees only to a few percent; the tolerances below are measured and stated.
"""
import sys
from pathlib import Path

import numpy as np
import pytest

sys.path.insert(0, str(Path(__file__).parent / "scripts"))
import probe_ref as ref  # noqa: E402
import scenegen as sg  # noqa: E402
import viewer  # noqa: E402

SKY_W, SKY_H = 128, 64  # 6 levels (down to 4 x 2): roughness 0, 0.2, 0.4, 0.6, 0.8, 1


def patch_sky():
    """Smooth gradient (0.3 .. 1.5, bluer up) + a bright 12 x 6 texel patch (+8) around
    engine direction (cos 20°, sin 20°, 0)-ish: u in [0.45, 0.5469), v in [0.3125, 0.4063)."""
    d, _ = ref.equirect_dirs(SKY_W, SKY_H)
    up = d[..., 1]
    img = np.stack([0.6 + 0.3 * up + 0.2 * d[..., 0], 0.7 + 0.4 * up, 0.9 + 0.6 * up - 0.2 * d[..., 2]], -1)
    img[20:26, 58:70] += [8.0, 7.0, 5.0]
    return img


def frame(n):
    t = np.array([0.0, 1.0, 0.0]) if abs(n[1]) < 0.9 else np.array([1.0, 0.0, 0.0])
    x = np.cross(t, n)
    x /= np.linalg.norm(x)
    return x, np.cross(n, x)


def reference(img, n, rough, nt=1000, nphi=192):
    """The prefilter integral above by midpoint quadrature in (θ, φ) around n. θ is spaced
    uniformly in s = sqrt(θ / (π/2)) (finer near n, where a low-roughness lobe lives); against
    nt = 4000, nphi = 768 it differs by < 1.1e-4 relative (measured, roughness 0.2 .. 1)."""
    a2 = rough ** 4
    s = (np.arange(nt) + 0.5) / nt
    th = s * s * (np.pi / 2)
    dth = 2 * s / nt * (np.pi / 2)
    ph = (np.arange(nphi) + 0.5) * 2 * np.pi / nphi
    T, P = np.meshgrid(th, ph, indexing="ij")
    x, y = frame(n)
    l = (np.sin(T) * np.cos(P))[..., None] * x + (np.sin(T) * np.sin(P))[..., None] * y + np.cos(T)[..., None] * n
    nh2 = np.cos(T / 2) ** 2  # h bisects n and l
    D = a2 / (np.pi * (nh2 * (a2 - 1) + 1) ** 2)
    w = D * np.cos(T) * np.sin(T) * dth[:, None]
    L = ref.sample_equirect(img, l)
    return (w[..., None] * L).sum((0, 1)) / w.sum()


def write_mips(d, img):
    sg.write_exr(d / "sky.exr", img)
    b = sg.GltfBuilder()
    b.node("Camera", camera=b.camera("cam", 1.2))
    # The loader wants something to load (an empty buffer is malformed): a 1 mm speck.
    b.node("Speck", mesh=b.mesh("speck", sg.cube(0.0005), b.material("m")), translation=(0, 0, 50))
    b.probe_grids([], sky=sg.sky_entry("sky.exr", ref.project_l2(img)))
    scene = b.write(d / "sky.gltf")
    viewer.check(viewer.run(scene, "--write-sky-mips", d / "mip", validation=False))
    return [viewer.read_image(p) for p in sorted(d.glob("mip*.exr"), key=lambda p: int(p.stem[3:]))]


# Panorama (u, v) of the texels checked: the patch centre, its edge, a far horizon, near each pole.
PROBES_UV = [(0.5, 0.36), (0.56, 0.36), (0.0, 0.5), (0.25, 0.05), (0.75, 0.92)]


def test_sky_mips_against_integration(tmp_path):
    img = patch_sky()
    mips = write_mips(tmp_path, img)
    # sv_sky.c: levels while (h >> M) >= 2, at most 7: 128 x 64 -> M = 6, down to 4 x 2, each half
    # the previous; level 0 is the image itself (bit-exact through float EXR).
    assert [m.shape[:2] for m in mips] == [(SKY_H >> k, SKY_W >> k) for k in range(6)]
    assert np.abs(mips[0] - img).max() < 1e-6 * img.max()
    M = len(mips)
    worst = {}
    for k in (1, 2, 5):  # roughness 0.2, 0.4 (low) and 1.0 (high)
        r = k / (M - 1)
        h, w = mips[k].shape[:2]
        dirs, _ = ref.equirect_dirs(w, h)
        texels = list(dict.fromkeys((min(int(v * h), h - 1), min(int(u * w), w - 1)) for u, v in PROBES_UV))
        for y, x in texels:
            want = reference(img, dirs[y, x], r)
            err = np.abs(mips[k][y, x] - want).max() / want.max()
            worst[k] = max(worst.get(k, 0.0), err)
            if k == 1 and (y, x) == texels[0]:
                # The check resolves roughness: the neighbouring levels' integrals differ here by more
                # than the bound below.
                for r2 in ((k - 0.5) / (M - 1), (k + 1) / (M - 1)):
                    assert np.abs(reference(img, dirs[y, x], r2) - want).max() / want.max() > 0.1
    # 256 Hammersley samples per texel read from the box pyramid (filtered importance sampling, lod
    # bias +1) blur the lobe a little: measured max relative error (of the texel's largest channel)
    # 1.9 % (level 1), 2.3 % (level 2), 3.6 % (level 5, near the top pole). With FIS off (lod 0) and
    # 65536 samples (a local experiment) the engine agrees to 5e-5 at every level, so the weight,
    # the direction mapping and roughness k / (M - 1) are exact and only the sampling is approximate.
    print("max relative error per level (run with -s):", worst)
    assert max(worst.values()) < 0.05, worst


def test_sky_mips_need_a_sky(tmp_path):
    # --no-sky contradicts the dump (usage error, 2); a scene without a sky is an error (1), no files.
    mips = write_mips(tmp_path, np.full((8, 16, 3), 1.0))
    assert len(mips) == 3  # 16 x 8: levels while (8 >> M) >= 2
    for m in mips[1:]:  # a constant sky stays constant under any normalised filter (to float error)
        assert np.abs(m - 1.0).max() < 1e-5
    p = viewer.run(tmp_path / "sky.gltf", "--no-sky", "--write-sky-mips", tmp_path / "x", validation=False)
    assert p.returncode == 2 and "--write-sky-mips needs a scene with a sky" in p.stderr
    b = sg.GltfBuilder()
    b.node("Speck", mesh=b.mesh("speck", sg.cube(0.0005), b.material("m")))
    b.probe_grids([])
    p = viewer.run(b.write(tmp_path / "nosky.gltf"), "--write-sky-mips", tmp_path / "y", validation=False)
    assert p.returncode == 1 and "has no sky" in p.stderr and not list(tmp_path.glob("y*"))
