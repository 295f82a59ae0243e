"""What the bake does to the final probe set before the file is written (issue 31, item 4).

Two steps, each a bake setting (settings.py; measured in bench/results/postprocess.md):

- **Dilation** (Dilate Invalid Probes): a probe the interpolation leaves out (validity <= 0: the
  placement's solid test found it inside geometry, so it was never rendered) gets the mean of its
  valid neighbours, weighted by validity / distance², and a small positive validity
  (:data:`DILATED_VALIDITY`), so the interpolation uses it like the other probes. A probe's
  neighbours are the probes of the cells it is a corner of (the file's own structure: the corner
  octree's leaves, hanging corners expanded, or the tetrahedra around it): the radius is the local
  cell size. A probe with no valid neighbour takes the dilated values of the previous pass (up to
  :data:`DILATE_PASSES` passes, as APV's iterations); one still without any stays invalid.
- **Windowing** (SH Windowing, SH Window Strength): every probe's SH scaled per band by
  ``native.window`` (docs/sh.md "Ringing windows"); strength 0 = the weakest window that makes that
  probe's irradiance non-negative everywhere, chosen per probe.

No Blender here: plain numpy over ``native`` (tests and bench/bench_postprocess.py use it on files).
"""
from __future__ import annotations

from typing import Optional, Tuple

import numpy as np

from . import native

#: The validity written for a dilated probe: above 0, so readers interpolate with it (they drop
#: only validity <= 0, docs/shprobe-format.md), and far below a rendered probe's (>= 1 − the solid
#: test's back-face ratio 0.25 = 0.75), so the overlay and a reader can tell it was dilated.
DILATED_VALIDITY = 0.01
#: Passes of dilation: a probe whose neighbours are all invalid takes the previous pass's values.
DILATE_PASSES = 4
WINDOW_KINDS = {"NONE": "none", "SINC4": "sinc4", "LAPLACIAN": "laplacian"}


def neighbour_pairs(structure, positions: np.ndarray, probes: np.ndarray) -> Tuple[np.ndarray, np.ndarray]:
    """(probe, neighbour) index pairs, unique, for each of ``probes``: the probes of the cells the
    probe is a corner of. Found by querying ``structure`` (a CornerOctree or Tetrahedra) at the 8
    points a small step from the probe towards each octant: each lies in one of those cells and its
    weights name the cell's probes (hanging corners expanded, as the interpolation does)."""
    probes = np.asarray(probes, dtype=np.int64)
    if probes.size == 0:
        return np.zeros(0, np.int64), np.zeros(0, np.int64)
    pos = np.asarray(positions, dtype=np.float64)
    try:
        step = 1e-3 * float(structure.info()["min_cell"])
    except (KeyError, TypeError):
        step = 1e-5 * float(np.ptp(pos, axis=0).max() or 1.0)
    octants = np.array([[(c >> k) & 1 for k in range(3)] for c in range(8)], dtype=np.float64) * 2.0 - 1.0
    pts = (pos[probes][:, None, :] + step * octants[None]).reshape(-1, 3)
    idx, w = structure.query(pts)
    owner = np.repeat(probes, 8 * idx.shape[1])
    q = idx.reshape(-1).astype(np.int64)
    keep = (q >= 0) & (w.reshape(-1) > 0) & (q != owner)
    key = np.unique(owner[keep] * len(pos) + q[keep])
    return key // len(pos), key % len(pos)


def dilate(coeffs: np.ndarray, validity: np.ndarray, positions: np.ndarray, structure,
           passes: int = DILATE_PASSES) -> Tuple[np.ndarray, np.ndarray, dict]:
    """Dilated copies of (coeffs (P, C, 3), validity (P,)) and a summary dict (invalid, dilated,
    left: probes with no valid neighbour after every pass, passes)."""
    c = np.array(coeffs, dtype=np.float64)
    val = np.array(validity, dtype=np.float32)
    pos = np.asarray(positions, dtype=np.float64)
    bad = np.flatnonzero(~(val > 0))
    info = {"invalid": int(bad.size), "dilated": 0, "left": int(bad.size), "passes": 0}
    if bad.size == 0:
        return c, val, info
    p_all, q_all = neighbour_pairs(structure, pos, bad)
    weight_of = val.astype(np.float64)  # a dilated probe lends its values with DILATED_VALIDITY
    todo = np.zeros(len(val), dtype=bool)
    todo[bad] = True
    for it in range(passes):
        ok = todo[p_all] & (weight_of[q_all] > 0)
        p, q = p_all[ok], q_all[ok]
        if p.size == 0:
            break
        d2 = np.sum((pos[p] - pos[q]) ** 2, axis=1)
        w = weight_of[q] / np.maximum(d2, 1e-30)
        wsum = np.bincount(p, weights=w, minlength=len(val))
        acc = np.zeros((len(val),) + c.shape[1:])
        np.add.at(acc, p, w[:, None, None] * c[q])
        got = np.unique(p)
        c[got] = acc[got] / wsum[got][:, None, None]
        todo[got] = False
        weight_of[got] = DILATED_VALIDITY
        val[got] = DILATED_VALIDITY
        info["dilated"] += int(got.size)
        info["passes"] = it + 1
    info["left"] = int(todo.sum())
    return c, val, info


def window_factors(kind: str, strength: float, max_band: int) -> np.ndarray:
    """Per-coefficient factors (sh_count,) of a fixed window (strength > 0), from native.window
    itself (its result on all-ones coefficients)."""
    n = native.sh_count(max_band)
    out, _ = native.window(np.ones((n, 3)), WINDOW_KINDS[kind], float(strength))
    return out[:, 0]


#: Directions of the pre-check of the automatic window, and its margin (fraction of the probe's mean
#: irradiance): between 1024 Fibonacci directions (~0.11 rad apart) an L ≤ 4 irradiance dips below
#: its sampled minimum by far less than 5 % of its mean.
_CHECK_DIRECTIONS, _CHECK_MARGIN = 1024, 0.05


def _maybe_negative(c: np.ndarray, band: int) -> np.ndarray:
    """Indices of the probes whose irradiance may go negative somewhere (the only ones the
    automatic window changes; native.window's exact minimum search costs ~1.5 ms a probe)."""
    i = np.arange(_CHECK_DIRECTIONS) + 0.5
    z = 1.0 - 2.0 * i / _CHECK_DIRECTIONS
    r, phi = np.sqrt(1.0 - z * z), np.pi * (1.0 + 5 ** 0.5) * i
    basis = native.sh_basis(np.stack([r * np.cos(phi), r * np.sin(phi), z], 1), band)  # (N, C)
    lam = np.array([(np.pi, 2 * np.pi / 3, np.pi / 4, 0.0, -np.pi / 24)[l] for l in range(band + 1)
                    for _ in range(2 * l + 1)])
    out = []
    for s in range(0, len(c), 4096):
        e = np.einsum("nc,pck->pnk", basis * lam, c[s:s + 4096])
        low = e.min(axis=1) < _CHECK_MARGIN * np.abs(e.mean(axis=1))
        out.append(s + np.flatnonzero(low.any(axis=1)))
    return np.concatenate(out) if out else np.zeros(0, np.int64)


def window(coeffs: np.ndarray, kind: str, strength: float) -> np.ndarray:
    """Windowed copy of SH ``coeffs`` (P, C, 3); kind a settings identifier (NONE, SINC4,
    LAPLACIAN); strength 0 = per probe, the weakest window with non-negative irradiance (a probe
    whose DC term is negative, which no window fixes, is left as it is)."""
    c = np.array(coeffs, dtype=np.float64)
    if kind == "NONE" or c.shape[1] == 1:
        return c
    band = int(round(np.sqrt(c.shape[1]))) - 1
    if strength > 0:
        return c * window_factors(kind, strength, band)[None, :, None]
    for i in _maybe_negative(c, band):
        try:
            c[i], _ = native.window(c[i], WINDOW_KINDS[kind], 0.0)
        except native.SchneeError:
            pass  # negative DC: no window makes it non-negative; the engine clamps max(E, 0)
    return c


def apply(coeffs: np.ndarray, validity: Optional[np.ndarray], structure, settings,
          log=None) -> Tuple[np.ndarray, Optional[np.ndarray]]:
    """The settings' post-process of a bake's final probes (SH coefficients, before any ambient
    cube fit): dilation (needs ``structure``, a CornerOctree or Tetrahedra, and ``validity``),
    then windowing. Returns (coeffs, validity)."""
    c = np.asarray(coeffs, dtype=np.float64)
    if settings.dilate_invalid and validity is not None and structure is not None:
        c, validity, info = dilate(c, validity, structure.positions(), structure)
        if log is not None and info["invalid"]:
            log(f"Schnee: dilated {info['dilated']} of {info['invalid']} probes inside geometry"
                + (f"; {info['left']} have no valid probe near them and stay invalid" if info["left"] else ""))
    if settings.sh_window != "NONE":
        c = window(c, settings.sh_window, settings.sh_window_strength)
    return c, validity
