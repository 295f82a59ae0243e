"""Error measures of the sweep (plain numpy + the add-on's native module; no Blender).

Irradiance is compared in 2000 directions spread evenly over the sphere (Fibonacci lattice, engine
space), all three channels:

- relative RMS = sqrt(mean (E - E_ref)^2) / sqrt(mean E_ref^2);
- relative max = max |E - E_ref| / sqrt(mean E_ref^2) (normalised by the RMS, not per direction, so
  dark directions do not blow it up).

Both sides are evaluated at the same band L (the coefficients truncated to (L+1)^2), so a row
measures the bake's estimation error at that band; band truncation itself is reported separately.
"""
import math
import os
import sys

import numpy as np

_REPO = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))
if os.path.join(_REPO, "addon") not in sys.path:
    sys.path.insert(0, os.path.join(_REPO, "addon"))
from schnee_probes import native  # noqa: E402


def fibonacci_sphere(n=2000):
    i = np.arange(n) + 0.5
    z = 1.0 - 2.0 * i / n
    r = np.sqrt(1.0 - z * z)
    phi = i * math.pi * (3.0 - math.sqrt(5.0))
    return np.stack([r * np.cos(phi), r * np.sin(phi), z], axis=1)


DIRS = fibonacci_sphere()


def truncate(coeffs, band):
    return np.asarray(coeffs, dtype=np.float64)[: (band + 1) ** 2]


def irradiance(coeffs, band, dirs=DIRS):
    return native.irradiance(truncate(coeffs, band), dirs)


def errors(coeffs, ref, band=2):
    """(relative RMS, relative max) of the irradiance of ``coeffs`` against ``ref`` at ``band``."""
    e, r = irradiance(coeffs, band), irradiance(ref, band)
    norm = math.sqrt(float(np.mean(r * r)))
    return math.sqrt(float(np.mean((e - r) ** 2))) / norm, float(np.max(np.abs(e - r))) / norm


def errors_vs_values(coeffs, band, e_ref):
    """Like :func:`errors` against irradiance values ``e_ref`` (N, 3) given at :data:`DIRS`."""
    e = irradiance(coeffs, band)
    norm = math.sqrt(float(np.mean(e_ref * e_ref)))
    return math.sqrt(float(np.mean((e - e_ref) ** 2))) / norm, float(np.max(np.abs(e - e_ref))) / norm


def sun_reference(sky_coeffs, radiance, direction_engine, solid_angle, band=4):
    """SH of the sky plus a small sphere of uniform ``radiance`` seen in ``direction_engine`` under
    ``solid_angle``: the small-source form radiance * solid_angle * Y_i(d) (the cap's exact
    projection differs by a factor 1 - O(l(l+1) alpha^2 / 8) ~ 1e-3 here for alpha = 0.025 rad)."""
    y = native.sh_basis(np.asarray(direction_engine, dtype=np.float64), band)
    return truncate(sky_coeffs, band) + radiance * solid_angle * y[:, None] * np.ones((1, 3))


def sun_true_irradiance(sky_coeffs, radiance, direction_engine, solid_angle, dirs=DIRS):
    """Irradiance of the sun scene without band limit for the sun: sky (L=4, smooth: its higher
    bands are negligible) + radiance * solid_angle * max(0, n . d)."""
    cos = np.clip(dirs @ np.asarray(direction_engine, dtype=np.float64), 0.0, None)
    return irradiance(sky_coeffs, 4, dirs) + radiance * solid_angle * cos[:, None]


def pareto(points):
    """Indices of the non-dominated (time, error) points, sorted by time."""
    order = sorted(range(len(points)), key=lambda i: (points[i][0], points[i][1]))
    front, best = [], math.inf
    for i in order:
        if points[i][1] < best:
            front.append(i)
            best = points[i][1]
    return front


def interpolate_trilinear(f, points):
    """Per-pixel mode of the engine at points (docs/engine.md, shaders/shading.glsl): trilinear over
    the 8 grid cells around each point, cells with no probe skipped and the weights renormalised;
    no weight at all falls back to the cell holding the point. No surface normal here (a point in
    space), so the engine's back-face weight does not apply. Returns (N, C, 3) or None per point."""
    dims = np.array(f.grid_dims)
    origin, spacing = np.array(f.grid_origin, dtype=np.float64), float(f.grid_spacing)
    grid = np.asarray(f.grid).reshape(dims[2], dims[1], dims[0])  # [z, y, x]
    coeffs = np.asarray(f.coeffs, dtype=np.float64)
    validity = np.asarray(getattr(f, "validity", None) if getattr(f, "validity", None) is not None
                          else np.ones(len(coeffs)), dtype=np.float64)
    out = []
    for p, own in zip(points, f.lookup(points)):
        u = (np.asarray(p) - origin) / spacing - 0.5
        i0 = np.floor(u).astype(int)
        t = u - i0
        acc, wsum = np.zeros(coeffs.shape[1:]), 0.0
        for dx in (0, 1):
            for dy in (0, 1):
                for dz in (0, 1):
                    c = i0 + (dx, dy, dz)
                    if (c < 0).any() or (c >= dims).any():
                        continue
                    idx = grid[c[2], c[1], c[0]]
                    if idx < 0:
                        continue
                    w = ((t[0] if dx else 1 - t[0]) * (t[1] if dy else 1 - t[1])
                         * (t[2] if dz else 1 - t[2])) * validity[idx]
                    acc += w * coeffs[idx]
                    wsum += w
        if wsum > 0:
            out.append((acc / wsum).tolist())
        else:
            out.append(coeffs[own].tolist() if own >= 0 else None)
    return out
