"""Per-axis refinement of boxes with per-axis levels (issue 29 item 3, docs/aniso-refinement.md "Tests
and the split rule"): the test points of every leaf in 14 columns and the axes each leaf splits along,
computed by the C core (pb_refine_tests_create_axes, pb_refine_decide_axes through
native/python/mod_refine.c), wrapped as :meth:`native.CornerOctree.refine_tests` and
:meth:`~native.CornerOctree.refine_decide` wrap the octree's tests.

Columns of ``leaf_tests`` (L, 14): ``4 a + e`` the midpoint of the edge along axis ``a`` whose other two
axes (in x, y, z order) are at their min or max by bits 0 and 1 of ``e`` (−1 where the leaf's level on
``a`` is 0); 12 the middle of all splittable axes (the centre, or with one level-0 axis the centre of the
face across it at its min) and 13 (that face at its max); −1 for none.
"""
from __future__ import annotations

from typing import Tuple

import numpy as np

from . import native

AXIS_TESTS = 14


def tests_axes(tree: native.CornerOctree, active=None) -> native.RefineTests:
    """Test points of every leaf that may still split (some level > 0), or of the ``active`` ones (L,)
    bool: edge midpoints and the middle point, shared points once, ``probe`` >= 0 where the point
    already is a probe (no bake). ``leaf_tests`` is (L, 14) (columns above)."""
    a = None if active is None else tree._flags(active, "active")
    d = native._lib().refine_tests_axes(tree._handle, a)
    return native.RefineTests(lattice=np.frombuffer(d["lattice"], dtype=np.uint32).reshape(-1, 3),
                              positions=np.frombuffer(d["positions"], dtype=np.float64).reshape(-1, 3),
                              probe=np.frombuffer(d["probe"], dtype=np.int32),
                              leaf_tests=np.frombuffer(d["leaf_tests"], dtype=np.int32).reshape(-1, AXIS_TESTS))


def decide_axes(tree: native.CornerOctree, tests: native.RefineTests, probe_coeffs: np.ndarray,
                test_coeffs: np.ndarray, *, probe_noise=None, test_noise=None, probe_validity=None,
                test_valid=None, tolerance: float = 0.05,
                noise_k: float = 2.0) -> Tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The axes each leaf splits along: (axes (L,) uint8, bit a = axis a; error (L,); threshold (L,)).
    A failing edge midpoint along a sets bit a; a failing middle point sets every splittable axis only
    when no edge test failed; errors and thresholds as :meth:`native.CornerOctree.refine_decide`
    (``probe_coeffs`` (P, C, 3), ``test_coeffs`` (T, C, 3) radiance SH, rows of tests that are probes
    not read; noise: relative RMS irradiance noise per probe / test; a test fails when its error
    exceeds sqrt(tolerance² + (noise_k σ)²))."""
    pc = native._array(probe_coeffs, "probe_coeffs", np.float64, native._FLOAT_KINDS)
    tc = native._array(test_coeffs, "test_coeffs", np.float64, native._FLOAT_KINDS)
    if pc.ndim != 3 or pc.shape[2] != 3:
        raise native._shape_error("probe_coeffs", "(P, sh_count, 3)", pc)
    band = native._band_of(pc.shape[1], "probe_coeffs")
    n_tests = tests.positions.shape[0]
    if tc.shape != (n_tests, pc.shape[1], 3):
        raise native._shape_error("test_coeffs", f"({n_tests}, {pc.shape[1]}, 3)", tc)
    lt = np.ascontiguousarray(tests.leaf_tests, dtype=np.int32)
    if lt.shape != (tree.leaf_count, AXIS_TESTS):
        raise native._shape_error("tests.leaf_tests", f"({tree.leaf_count}, {AXIS_TESTS}) (from tests_axes)", lt)

    def opt(x, name):
        return None if x is None else native._array(x, name, np.float32, native._FLOAT_KINDS)

    tv = None if test_valid is None else np.ascontiguousarray(np.asarray(test_valid).astype(bool), dtype=np.uint8)
    axes, err, thr = native._lib().refine_decide_axes(
        tree._handle, lt, np.ascontiguousarray(tests.positions, dtype=np.float64),
        np.ascontiguousarray(tests.probe, dtype=np.int32), band, pc, tc,
        probe_noise=opt(probe_noise, "probe_noise"), test_noise=opt(test_noise, "test_noise"),
        probe_validity=opt(probe_validity, "probe_validity"), test_valid=tv,
        tolerance=float(tolerance), noise_k=float(noise_k))
    return (np.frombuffer(axes, dtype=np.uint8).copy(), np.frombuffer(err, dtype=np.float64),
            np.frombuffer(thr, dtype=np.float64))
