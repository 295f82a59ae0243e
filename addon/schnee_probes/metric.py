"""The refinement's metric: relative irradiance error, RMS over directions and RGB, of radiance SH
(docs/placement.md, "Error-driven refinement"; pb_refine_irradiance_error in native/src/pb_refine.c)."""
from __future__ import annotations

import math

import numpy as np

# Lambert band factors A_l (irradiance = Σ A_l L_lm Y_lm), l = 0..4.
_LAMBERT = (math.pi, 2.0 * math.pi / 3.0, math.pi / 4.0, 0.0, -math.pi / 24.0)


def _band_weights(count: int) -> np.ndarray:
    band = int(round(math.sqrt(count))) - 1
    return np.concatenate([np.full(2 * l + 1, _LAMBERT[l]) for l in range(band + 1)])


def irradiance_norm(c: np.ndarray) -> np.ndarray:
    """‖A·c‖ over the coefficients and RGB of radiance SH ``c`` ((..., C, 3)): the irradiance's RMS
    over directions (times √(4π)), the norm of the refinement's metric."""
    c = np.asarray(c, dtype=np.float64)
    w = _band_weights(c.shape[-2])[:, None]
    return np.sqrt(np.sum((w * c) ** 2, axis=(-2, -1)))


def irradiance_error(a: np.ndarray, ref: np.ndarray) -> np.ndarray:
    """Relative irradiance error, RMS over directions and RGB, of radiance SH ``a`` against ``ref``
    ((..., C, 3) each): ‖A·(a − ref)‖ / ‖A·ref‖ (the metric of pb_refine_irradiance_error); 0 where
    both are 0, 1 where only ref is."""
    a = np.asarray(a, dtype=np.float64)
    ref = np.asarray(ref, dtype=np.float64)
    num, den = irradiance_norm(a - ref), irradiance_norm(ref)
    with np.errstate(divide="ignore", invalid="ignore"):
        out = np.where(den > 0, num / np.where(den > 0, den, 1.0), np.where(num > 0, 1.0, 0.0))
    return out


def _rel(d: np.ndarray, ref: np.ndarray) -> float:
    den, num = float(irradiance_norm(ref)), float(irradiance_norm(d))
    return num / den if den > 0 else 0.0
