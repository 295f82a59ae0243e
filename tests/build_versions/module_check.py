"""Run by scripts/build-chroot.sh inside a dev chroot with that release's python3: the Python module
built there imports (pb_embree_dyn.c opens the release's Embree) and places probes in a 2 m cube
against the closed form (eight 1 m leaves, probes at (±0.5, ±0.5, ±0.5), a 4 x 4 x 4 grid of 0.5 m
cells each mapping to its octant's probe; the inside test behind it is Embree's filtered ray).
Prints "MODULE_OK <python version> <Embree library path>"; exits non-zero on any mismatch.

    python3 module_check.py ADDON_PACKAGE_DIR     (the folder holding _schnee_native.abi3.so)
"""
import os
import sys

import numpy as np

pkg = os.path.abspath(sys.argv[1])
sys.path.insert(0, os.path.dirname(pkg))
from schnee_probes import native  # noqa: E402

assert native.native_problem() is None, native.native_problem()
v = np.array([[x, y, z] for x in (-1.0, 1.0) for y in (-1.0, 1.0) for z in (-1.0, 1.0)])
quads = [(0, 1, 3, 2), (4, 6, 7, 5), (0, 4, 5, 1), (2, 3, 7, 6), (0, 2, 6, 4), (1, 5, 7, 3)]
t = np.array([tri for a, b, c, d in quads for tri in ((a, b, c), (a, c, d))], np.uint32)
p = native.place_probes([("cube", v, t)], [], 0.5, 1.0)
assert p.positions.shape == (8, 3), p.positions.shape
np.testing.assert_allclose(np.abs(p.positions), 0.5, rtol=0, atol=1e-12)
assert len({tuple(np.sign(q)) for q in p.positions}) == 8
assert p.grid_dims == (4, 4, 4) and p.grid_spacing == 0.5, (p.grid_dims, p.grid_spacing)
np.testing.assert_allclose(p.grid_origin, (-1, -1, -1), rtol=0, atol=1e-12)
for flat, idx in enumerate(p.grid):
    x, y, z = flat % 4, (flat // 4) % 4, flat // 16
    centre = np.array([-0.75 + 0.5 * x, -0.75 + 0.5 * y, -0.75 + 0.5 * z])
    np.testing.assert_allclose(p.positions[idx], np.sign(centre) * 0.5, rtol=0, atol=1e-12)
maps = [line.split()[-1] for line in open("/proc/self/maps") if "libembree" in line]
print("MODULE_OK", sys.version.split()[0], maps[0] if maps else "no Embree mapped")
