"""The refinement's metric: relative irradiance error, RMS over directions and RGB, of radiance SH
(docs/placement.md, "Error-driven refinement"). Computed in one place, the C core's
pb_refine_irradiance_error (native/src/pb_refine.c), which also makes the placement decisions
(pb_refine_decide); these functions hand it whole arrays through native.refine_error/refine_norm."""
from __future__ import annotations

import numpy as np

from . import native


def irradiance_norm(c: np.ndarray) -> np.ndarray:
    """‖A·c‖ over the coefficients and RGB of radiance SH ``c`` ((..., C, 3)): the irradiance's RMS
    over directions (times √(4π)), the norm of the refinement's metric."""
    return native.refine_norm(c)


def irradiance_error(a: np.ndarray, ref: np.ndarray) -> np.ndarray:
    """Relative irradiance error, RMS over directions and RGB, of radiance SH ``a`` against ``ref``
    ((..., C, 3) each, broadcast): ‖A·(a − ref)‖ / ‖A·ref‖ (pb_refine_irradiance_error); 0 where
    both are 0, 1 where only ref is. A point whose ``a`` is NaN (an interpolation outside the
    probes) gives NaN, or 0 against a zero reference."""
    a, ref = np.broadcast_arrays(np.asarray(a, dtype=np.float64), np.asarray(ref, dtype=np.float64))
    out = native.refine_error(a, ref)
    nan = np.isnan(a).any(axis=(-2, -1)) | np.isnan(ref).any(axis=(-2, -1))
    if np.any(nan):
        # The C metric calls any difference against a zero reference 1; NaN is no difference.
        out = np.where(nan & ~(irradiance_norm(ref) > 0), 0.0, out)
    return out


def _rel(d: np.ndarray, ref: np.ndarray) -> float:
    """‖A·d‖ / ‖A·ref‖ of one point's difference ``d`` (C, 3); 0 against a zero reference."""
    den, num = float(irradiance_norm(ref)), float(irradiance_norm(d))
    return num / den if den > 0 else 0.0
