"""Probe placement through the Python API: closed-form result for a cube, progress callback
(cancel by False, exception propagation, called from the core with the GIL re-acquired), error
codes and argument validation. The placement algorithm itself is tested in tests/native."""
import numpy as np
import pytest

from schnee_probes import native


def cube(half=1.0, drop=0):
    """Closed cube [-half, half]^3 with outward-facing triangles (drop > 0 removes triangles)."""
    v = np.array([[x, y, z] for x in (-half, half) for y in (-half, half) for z in (-half, half)], float)

    def i(x, y, z):
        return (x > 0) * 4 + (y > 0) * 2 + (z > 0)
    quads = [[(-1, -1, -1), (-1, -1, 1), (-1, 1, 1), (-1, 1, -1)],
             [(1, -1, -1), (1, 1, -1), (1, 1, 1), (1, -1, 1)],
             [(-1, -1, -1), (1, -1, -1), (1, -1, 1), (-1, -1, 1)],
             [(-1, 1, -1), (-1, 1, 1), (1, 1, 1), (1, 1, -1)],
             [(-1, -1, -1), (-1, 1, -1), (1, 1, -1), (1, -1, -1)],
             [(-1, -1, 1), (1, -1, 1), (1, 1, 1), (-1, 1, 1)]]
    tris = []
    for q in quads:
        a, b, c, d = (i(*p) for p in q)
        tris += [(a, b, c), (a, c, d)]
    return v, np.array(tris[:len(tris) - drop], np.uint32)


def test_cube_closed_form():
    # A 2 m cube, no geometry, cells 0.5..1 m: eight 1 m leaves -> probes at (±0.5, ±0.5, ±0.5);
    # the 0.5 m grid is 4 x 4 x 4 from (-1, -1, -1), every cell inside, mapping to its octant's probe.
    v, t = cube()
    p = native.place_probes([("cube", v, t)], [], 0.5, 1.0)
    assert p.positions.shape == (8, 3) and p.positions.dtype == np.float64
    np.testing.assert_allclose(np.sort(np.abs(p.positions).ravel()), 0.5)
    assert p.grid_dims == (4, 4, 4) and p.grid_spacing == 0.5
    np.testing.assert_allclose(p.grid_origin, (-1, -1, -1))
    np.testing.assert_allclose(p.cell_sizes, 1.0)
    assert p.backface_ratio.shape == (8,) and p.grid.dtype == np.int32
    for flat, idx in enumerate(p.grid):
        x, y, z = flat % 4, (flat // 4) % 4, flat // 16
        centre = np.array([-0.75 + 0.5 * x, -0.75 + 0.5 * y, -0.75 + 0.5 * z])
        np.testing.assert_allclose(p.positions[idx], np.sign(centre) * 0.5)


def test_progress_and_cancel():
    v, t = cube()
    calls = []
    native.place_probes([("cube", v, t)], [], 0.5, 1.0, progress=lambda f, s: calls.append((f, s)))
    assert calls and all(0.0 <= f <= 1.0 and isinstance(s, str) and s for f, s in calls)
    assert [f for f, _ in calls] == sorted(f for f, _ in calls)
    seen = []

    def cancel_second(f, s):
        seen.append(f)
        return len(seen) < 2
    with pytest.raises(native.SchneeError) as exc:
        native.place_probes([("cube", v, t)], [], 0.5, 1.0, progress=cancel_second)
    assert exc.value.code == "cancelled" and len(seen) == 2

    def boom(f, s):
        raise KeyError("from the callback")
    with pytest.raises(KeyError, match="from the callback"):
        native.place_probes([("cube", v, t)], [], 0.5, 1.0, progress=boom)


def test_errors_and_validation():
    v, t = cube(drop=1)
    with pytest.raises(native.SchneeError) as exc:
        native.place_probes([("leaky box", v, t)], [], 0.5, 1.0)
    assert exc.value.code == "open mesh" and "leaky box" in str(exc.value)
    v, t = cube()
    with pytest.raises(ValueError, match=r"volumes\[0\] triangles must have shape \(T, 3\)"):
        native.place_probes([("c", v, t.reshape(-1, 2))], [], 0.5, 1.0)
    with pytest.raises(TypeError, match=r"geometry\[0\] vertices must be a numeric array"):
        native.place_probes([("c", v, t)], [("g", v.astype(complex), t)], 0.5, 1.0)
    with pytest.raises(ValueError, match=r"volumes\[0\] triangles values must fit uint32"):
        native.place_probes([("c", v, t.astype(np.int64) - 1)], [], 0.5, 1.0)
    with pytest.raises(TypeError, match="progress must be callable"):
        native.place_probes([("c", v, t)], [], 0.5, 1.0, progress=3)
    with pytest.raises(TypeError, match=r"volumes\[0\] must be a \(name, vertices, triangles\) tuple"):
        native.place_probes([(v, t)], [], 0.5, 1.0)
