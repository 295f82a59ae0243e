"""Noise-free model of what Cycles' pixel filter does to an equirect render of an HDRI world.

Not a test: the measurement behind docs/sh.md §"Pixel filter". A Cycles camera sample of pixel c
lands at c + u with u drawn from the filter (importance sampling), so with infinitely many samples a
pixel holds ∫ k(u) L(c + u) du / ∫ k. This script evaluates that integral on the HDRI's texels
(Blender's bundled 1024×512 world EXRs, read through Blender into a .npy) for a W×H panorama, projects
it with the native SH code and compares with the projection of the HDRI itself.

    /usr/bin/python3 tests/blender/scripts/cycles_convention_filter_model.py [interior] [256] [SPP...]

With sample counts after the resolution it also renders the HDRI world with real Cycles
(cycles_convention_hdri_render.py) at each count, so noise and bias can be told apart.

Needs Blender and the built native module (cmake --build build -j2).
"""
import math
import os
import subprocess
import sys
import tempfile

import numpy as np

REPO = os.path.abspath(os.path.join(os.path.dirname(__file__), "..", "..", ".."))
sys.path.insert(0, os.path.join(REPO, "addon"))
from schnee_probes import native  # noqa: E402

WORLD = "/usr/share/blender/datafiles/studiolights/world"


def read_exr(name):
    """The HDRI as (H, W, 3) float64, row 0 at the top, read by Blender into a .npy."""
    with tempfile.TemporaryDirectory() as tmp:
        npy = os.path.join(tmp, "x.npy")
        expr = ("import bpy, numpy as np; img = bpy.data.images.load(%r); w, h = img.size; "
                "p = np.empty(w * h * 4, np.float32); img.pixels.foreach_get(p); "
                "np.save(%r, p.reshape(h, w, 4)[::-1, :, :3])" % (os.path.join(WORLD, name + ".exr"), npy))
        subprocess.run(["blender", "-b", "--factory-startup", "--python-exit-code", "1",
                        "--python-expr", expr], check=True, capture_output=True)
        return np.load(npy).astype(np.float64)


def kernel(kind, width):
    """(function of offset in output pixels, support radius) as Cycles builds its filter table."""
    if kind == "box":
        return (lambda x: np.where(np.abs(x) <= width / 2, 1.0, 0.0)), width / 2
    if kind == "blackman_harris":
        w = 2.0 * width  # filter_table(): width *= 2 for Blackman–Harris

        def bh(x):
            t = 2 * np.pi * (x / w + 0.5)
            v = 0.35875 - 0.48829 * np.cos(t) + 0.14128 * np.cos(2 * t) - 0.01168 * np.cos(3 * t)
            return np.where(np.abs(x) <= w / 2, v, 0.0)
        return bh, w / 2
    if kind == "gaussian":
        w = 3.0 * width  # filter_table(): width *= 3 for Gaussian
        return (lambda x: np.where(np.abs(x) <= w / 2, np.exp(-2.0 * (x * 6.0 / w) ** 2), 0.0)), w / 2
    raise ValueError(kind)


def texel_weights(kind, width, ratio):
    """Weights of texel offsets around a pixel centre: ∫ over each texel of k, normalised.
    `ratio` texels per output pixel (even), pixel centre on a texel boundary."""
    k, radius = kernel(kind, width)
    n = int(math.ceil(radius * ratio)) + 1
    offsets = np.arange(-n, n)  # texel j spans [j, j+1) texels from the centre
    sub = 64
    weights = []
    for j in offsets:
        x = (j + (np.arange(sub) + 0.5) / sub) / ratio
        weights.append(k(x).mean())
    weights = np.array(weights)
    return offsets, weights / weights.sum()


def render(env, width_px, kind, fwidth):
    """Noise-free filtered panorama, H = W/2, from the HDRI (continuous = nearest texel)."""
    th, tw = env.shape[:2]
    ratio = tw // width_px
    assert tw % width_px == 0 and ratio % 2 == 0
    offsets, w = texel_weights(kind, fwidth, ratio)
    # φ is periodic; θ reflects across a pole onto the opposite meridian (φ + π), as the camera's
    # directions do past θ = 0 or π.
    pad = len(offsets)
    top = np.roll(env[:pad][::-1], tw // 2, axis=1)
    bottom = np.roll(env[-pad:][::-1], tw // 2, axis=1)
    ext = np.concatenate([top, env, bottom], axis=0)
    centres_x = np.arange(width_px) * ratio + ratio // 2
    centres_y = np.arange(width_px // 2) * ratio + ratio // 2
    rows = sum(wt * ext[pad + centres_y + o] for o, wt in zip(offsets, w))  # (H, tw, 3)
    return sum(wt * np.take(rows, (centres_x + o) % tw, axis=1) for o, wt in zip(offsets, w))


def cycles_render(name, res, spp, kind, fwidth):
    script = os.path.join(os.path.dirname(os.path.abspath(__file__)), "cycles_convention_hdri_render.py")
    with tempfile.TemporaryDirectory() as tmp:
        npy = os.path.join(tmp, "r.npy")
        subprocess.run(["blender", "-b", "--factory-startup", "--python-exit-code", "1", "-P", script, "--",
                        name, str(res), str(spp), kind.upper(), str(fwidth), npy], check=True,
                       capture_output=True)
        return np.load(npy).astype(np.float64)


def main():
    name = sys.argv[1] if len(sys.argv) > 1 else "interior"
    res = int(sys.argv[2]) if len(sys.argv) > 2 else 256
    spps = [int(a) for a in sys.argv[3:]]
    env = read_exr(name)
    band = 2
    exact = native.project_equirect(env.astype(np.float32), max_band=band, negative="allow")
    rng = np.random.default_rng(1)
    normals = rng.normal(size=(20000, 3))
    normals /= np.linalg.norm(normals, axis=1, keepdims=True)
    e_exact = native.irradiance(exact, normals)
    print(f"{name}.exr -> {res}x{res // 2}, L={band}, noise-free filter model")
    print("| filter | L00 rel. error (mean RGB) | irradiance rel. RMS error |")
    print("|---|---|---|")
    def row(label, pano):
        c = native.project_equirect(pano.astype(np.float32), max_band=band, negative="allow")
        e = native.irradiance(c, normals)
        l00 = np.mean(np.abs(c[0] - exact[0]) / np.abs(exact[0]))
        rms = math.sqrt(np.mean(((e - e_exact) / e_exact) ** 2))
        print(f"| {label} | {100 * l00:.3f} % | {100 * rms:.3f} % |", flush=True)

    for kind, fw in (("box", 1.0), ("blackman_harris", 1.5), ("gaussian", 1.5), ("blackman_harris", 0.75)):
        row(f"model: {kind} {fw:g} px", render(env, res, kind, fw))
        for spp in spps:
            if fw in (1.0, 1.5) and kind != "gaussian":
                row(f"Cycles {spp} spp: {kind} {fw:g} px", cycles_render(name, res, spp, kind, fw))


if __name__ == "__main__":
    main()
