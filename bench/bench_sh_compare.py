"""SH projection throughput: the native core against a numpy/scipy implementation of the same
projection, in one run, on the same panoramas.

    /usr/bin/python3 bench/bench_sh_compare.py [--band 2] [--max-width 8192] [--numpy-limit 60]

(a) numpy/scipy, the way the seed pipeline did it (seeds 000/003: "SH baking requires scipy";
    "integrates the environment over the sphere using real SH basis functions with solid-angle
    weighting"): the direction of every pixel centre, ``scipy.special.sph_harm`` evaluated at every
    pixel for every (l, m), times the pixel's solid angle and radiance, summed. Vectorised over
    pixels (numpy arrays, row chunks of at most 2 M pixels), not a Python loop per pixel: the
    fastest honest form of that pipeline. scipy's complex, Condon-Shortley-phased Y_l^m is turned
    into the project's real basis without that phase (DESIGN.md §3, docs/sh.md):
    m = 0: Y_l^0; m > 0: sqrt(2) (-1)^m Re Y_l^m; m < 0: sqrt(2) (-1)^m Im Y_l^|m|, with polar angle
    from engine +Z and azimuth atan2(y, x) in engine space. Checked against native.sh_basis at
    1000 random directions (tolerance 1e-12 absolute) before anything is timed.
(b) native.project_equirect on one thread (best of several runs).
(c) native.project_equirect on both cores: two Python threads, each projecting its own image
    repeatedly (the module releases the GIL); aggregate pixels/s = pixels x projections / wall.

Before timing each size, the numpy/scipy coefficients must equal the native ones to 1e-9 relative
to the largest coefficient (both accumulate in double from the same float32 pixels with the same
exact per-pixel solid angles (2 pi / W)(cos(theta - dtheta/2) - cos(theta + dtheta/2)), so they
differ only by summation order). Sizes whose numpy run would exceed --numpy-limit seconds
(extrapolated x4 from the previous size) are timed natively only.
Prints a Markdown table (bench/results/sh.md holds the committed run).
"""
import argparse
import os
import sys
import threading
import time

import numpy as np
from scipy.special import sph_harm

REPO = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
sys.path.insert(0, os.path.join(REPO, "addon"))
from schnee_probes import native  # noqa: E402


def real_sh_scipy(band, polar, azimuth):
    """Project's real SH (no Condon-Shortley phase), index l*l + l + m, from scipy's complex Y."""
    out = np.empty((native.sh_count(band),) + polar.shape)
    for l in range(band + 1):
        for m in range(0, l + 1):
            y = sph_harm(m, l, azimuth, polar)  # scipy: sph_harm(order m, degree l, azimuth, polar)
            if m == 0:
                out[l * l + l] = y.real
            else:
                s = np.sqrt(2.0) * (-1.0) ** m
                out[l * l + l + m] = s * y.real
                out[l * l + l - m] = s * y.imag
    return out


def check_basis(band):
    d = np.random.default_rng(7).normal(size=(1000, 3))
    d /= np.linalg.norm(d, axis=1, keepdims=True)
    ours = real_sh_scipy(band, np.arccos(np.clip(d[:, 2], -1, 1)), np.arctan2(d[:, 1], d[:, 0])).T
    err = np.max(np.abs(ours - native.sh_basis(d, band)))
    if not err < 1e-12:
        sys.exit(f"scipy real basis differs from native.sh_basis by {err:.3g} (> 1e-12)")
    return err


def project_scipy(img, band, chunk_pixels=1 << 21):
    """Radiance SH (sh_count, 3) of an equirect image (H, W, 3), row 0 at the top, engine space."""
    h, w = img.shape[:2]
    rows = max(1, chunk_pixels // w)
    phi = np.pi - 2 * np.pi * (np.arange(w) + 0.5) / w          # canonical Cycles panorama
    acc = np.zeros((native.sh_count(band), 3))
    for r0 in range(0, h, rows):
        th = np.pi * (np.arange(r0, min(h, r0 + rows)) + 0.5) / h
        T, P = np.meshgrid(th, phi, indexing="ij")
        bx, by, bz = np.sin(T) * np.cos(P), np.sin(T) * np.sin(P), np.cos(T)
        ex, ey, ez = bx, bz, -by                                  # Blender -> engine (DESIGN.md §3)
        polar = np.arccos(np.clip(ez, -1, 1))
        azim = np.arctan2(ey, ex)
        dw = (2 * np.pi / w) * (np.cos(T - np.pi / (2 * h)) - np.cos(T + np.pi / (2 * h)))
        Y = real_sh_scipy(band, polar, azim)
        acc += np.einsum("irw,rw,rwc->ic", Y, dw, img[r0:r0 + len(th)].astype(np.float64))
    return acc


def best(fn, min_time=0.3, max_runs=20):
    ts, t_all = [], time.perf_counter()
    while len(ts) < max_runs and (len(ts) < 3 or time.perf_counter() - t_all < min_time):
        t = time.perf_counter()
        fn()
        ts.append(time.perf_counter() - t)
    return min(ts)


def both_cores(img_a, img_b, band, single_s):
    reps = max(3, int(0.5 / max(single_s, 1e-6)))
    barrier = threading.Barrier(3)

    def work(img):
        barrier.wait()
        for _ in range(reps):
            native.project_equirect(img, band)
    th = [threading.Thread(target=work, args=(im,)) for im in (img_a, img_b)]
    for t in th:
        t.start()
    barrier.wait()
    t0 = time.perf_counter()
    for t in th:
        t.join()
    return 2 * reps * img_a.shape[0] * img_a.shape[1] / (time.perf_counter() - t0)


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--band", type=int, default=2)
    ap.add_argument("--max-width", type=int, default=8192)
    ap.add_argument("--numpy-limit", type=float, default=60.0, help="seconds per numpy projection")
    a = ap.parse_args()
    band = a.band
    print(f"scipy basis vs native.sh_basis, L={band}: max abs difference {check_basis(band):.2e}")
    print(f"load average before: {os.getloadavg()[0]:.2f}")
    print()
    print(f"| panorama | L | numpy/scipy (s) | numpy Mpixel/s | native 1 thread (ms) | native 1 thread Mpixel/s "
          f"| native 2 threads, aggregate Mpixel/s | native speed-up (1 thread) | max coeff. difference (rel.) |")
    print("|---|---|---|---|---|---|---|---|---|")
    rng = np.random.default_rng(1)
    t_numpy = None
    w = 128
    while w <= a.max_width:
        h = w // 2
        img = rng.random((h, w, 3), dtype=np.float32)
        img2 = rng.random((h, w, 3), dtype=np.float32)
        px = w * h
        c_nat = native.project_equirect(img, band)
        t1 = best(lambda: native.project_equirect(img, band))
        agg = both_cores(img, img2, band, t1)
        if t_numpy is None or 4 * t_numpy <= a.numpy_limit:
            t = time.perf_counter()
            c_np = project_scipy(img, band)
            t_numpy = time.perf_counter() - t
            rel = np.max(np.abs(c_np - c_nat)) / np.max(np.abs(c_nat))
            if not rel < 1e-9:
                sys.exit(f"{w}x{h}: numpy/scipy and native coefficients differ by {rel:.3g} relative (> 1e-9)")
            np_cols = f"{t_numpy:.3f} | {px / t_numpy / 1e6:.2f}"
            ratio = f"{t_numpy / t1:.0f}×"
            relc = f"{rel:.1e}"
        else:
            t_numpy = 4 * t_numpy
            np_cols, ratio, relc = f"— (≈{t_numpy:.0f} s extrapolated)", "—", "—"
            np_cols = np_cols + " | —"
        print(f"| {w}x{h} | {band} | {np_cols} | {1e3 * t1:.3f} | {px / t1 / 1e6:.0f} | {agg / 1e6:.0f} "
              f"| {ratio} | {relc} |", flush=True)
        w *= 2
    print(f"\nload average after: {os.getloadavg()[0]:.2f}")


if __name__ == "__main__":
    main()
