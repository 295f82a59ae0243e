"""The dense grid's field in the core (native.GridField, native/include/schnee/pb_grid_field.h,
docs/grid-field.md) against independent references:

- a numpy re-derivation of the documented rule written here from docs/grid-field.md "The rule" (vectorised,
  its own code: validity, empty cells, back faces, the home cell's mask, the fallback, rotated axes);
- the engine tests' numpy oracle tests/engine/scripts/probe_ref.py grid_irradiance (written from
  docs/engine.md for the shader, axis-aligned, no masks), so that oracle is now checked against the one
  definition;
- closed forms (a linear field) and binary16's rounding bound for the texture form.
"""
import sys
from pathlib import Path

import numpy as np
import pytest

from schnee_probes import native

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "engine" / "scripts"))
import probe_ref as ref  # noqa: E402

STATUS = {name: i for i, name in enumerate(native.GRID_FIELD_STATUS)}


def rotation(axis, angle):
    a = np.asarray(axis, float) / np.linalg.norm(axis)
    K = np.array([[0, -a[2], a[1]], [a[2], 0, -a[0]], [-a[1], a[0], 0]])
    return np.eye(3) * np.cos(angle) + np.sin(angle) * K + (1 - np.cos(angle)) * np.outer(a, a)


def random_grid(rng, dims=(6, 5, 4), C=9, empty=0.15, invalid=0.2):
    X, Y, Z = dims
    occupied = rng.uniform(size=(Z, Y, X)) >= empty
    cells = np.full((Z, Y, X), -1, np.int32)
    cells[occupied] = np.arange(occupied.sum())
    P = int(occupied.sum())
    coeffs = rng.uniform(-1, 3, (P, C, 3))
    validity = np.where(rng.uniform(size=P) < invalid, 0.0, rng.uniform(0.2, 1.0, P)).astype(np.float32)
    scale = rng.uniform(0.5, 2.0, P).astype(np.float32)
    return cells, coeffs, validity, scale


def smoothstep(e0, e1, x):
    t = np.clip((x - e0) / (e1 - e0), 0, 1)
    return t * t * (3 - 2 * t)


def model(cells, origin, h, R, coeffs, validity, scale, masks, p_s, n, static, bias):
    """docs/grid-field.md "The rule", steps 1-5, in numpy: (status (N,), coeffs (N, C, 3) = sum w s c)."""
    Z, Y, X = cells.shape
    dims = np.array([X, Y, Z])
    origin = np.asarray(origin, float)
    p = p_s + bias * h * n
    u = (p - origin) @ R.T / h
    inside = np.all((u >= -0.01) & (u <= dims + 0.01), axis=1)
    c = u - 0.5
    i0 = np.floor(c).astype(int)
    f = c - i0
    home = np.clip(np.floor((p + 0.01 * h * n - origin) @ R.T / h).astype(int), 0, dims - 1)
    vis = masks[home[:, 2], home[:, 1], home[:, 0]].astype(np.int64)
    sc = coeffs * scale.astype(float)[:, None, None]
    acc = np.zeros((len(p),) + coeffs.shape[1:])
    plain = np.zeros((len(p),) + coeffs.shape[1:])  # step 5: trilinear x validity, no mask, no back face
    wsum = np.zeros(len(p))
    dsum = np.zeros(len(p))
    for k in range(8):
        o = np.array([k & 1, (k >> 1) & 1, (k >> 2) & 1])
        ci = np.clip(i0 + o, 0, dims - 1)
        idx = cells[ci[:, 2], ci[:, 1], ci[:, 0]]
        d = ci - home
        near = np.all(np.abs(d) <= 1, axis=1)
        bit = (d[:, 0] + 1) + 3 * (d[:, 1] + 1) + 9 * (d[:, 2] + 1)
        masked = near & (((vis >> np.where(near, bit, 0)) & 1) == 0)
        w = np.prod(np.where(o == 1, f, 1 - f), axis=1)
        v = np.where(idx >= 0, np.maximum(validity.astype(float)[np.maximum(idx, 0)], 0.0), 0.0)
        plain += (w * v)[:, None, None] * sc[np.maximum(idx, 0)]
        dsum += w * v
        centre = origin + (ci + 0.5) @ R * h
        back = smoothstep(-0.1, 0.1, np.einsum("ij,ij->i", centre - p_s, n) / h) if static else 1.0
        w = w * back * np.where(idx >= 0, validity.astype(float)[np.maximum(idx, 0)], 0.0)
        w = np.where((idx >= 0) & ~masked & (w > 0), w, 0.0)
        acc += w[:, None, None] * sc[np.maximum(idx, 0)]
        wsum += w
    status = np.where(inside, STATUS["weights"], STATUS["outside"])
    out = acc / np.maximum(wsum, 1e-300)[:, None, None]
    low = inside & (wsum <= 1e-6)
    status = np.where(low, np.where(dsum > 1e-6, STATUS["fallback"], STATUS["none"]), status)
    out[low] = np.where((dsum[low] > 1e-6)[:, None, None], plain[low] / np.maximum(dsum[low], 1e-300)[:, None, None],
                        0.0)
    out[~inside] = 0.0
    return status, out


def random_points(rng, dims, origin, h, R, count, pad=0.05):
    u = rng.uniform(-pad, 1 + pad, (count, 3)) * np.asarray(dims, float)
    n = rng.normal(size=(count, 3))
    n /= np.linalg.norm(n, axis=1, keepdims=True)
    return np.asarray(origin) + (u @ R) * h, n


@pytest.mark.parametrize("rotated", [False, True])
@pytest.mark.parametrize("static", [False, True])
def test_rule_equals_the_numpy_rederivation(rotated, static):
    # 20 000 random points (5 % of the box beyond each face: ~25 % outside), random normals, 15 % empty cells, 20 %
    # invalid probes, random scales, random neighbour masks (each bit clear with probability 0.3), normal
    # bias 0.3: the C's status and sum w s c equal the numpy rule to rounding.
    rng = np.random.default_rng(17 + rotated + 2 * static)
    cells, coeffs, validity, scale = random_grid(rng)
    masks = np.full(cells.shape, 0x7FFFFFF, np.int64)
    for b in range(27):
        masks &= ~((rng.uniform(size=cells.shape) < 0.3).astype(np.int64) << b)
    masks = masks.astype(np.uint32)
    R = rotation((1, 2, 3), 0.7) if rotated else np.eye(3)
    origin, h = (0.3, -0.7, 1.1), 0.35
    f = native.GridField.build(cells, origin, h, coeffs, axes=R, validity=validity, scale=scale, masks=masks)
    p, n = random_points(rng, (6, 5, 4), origin, h, R, 20000)
    q = f.query(p, n, static_surface=static, normal_bias=0.3)
    status, want = model(cells, origin, h, R, coeffs, validity, scale, masks, p, n, static, 0.3)
    # Points within 1e-9 of a decision boundary (floor of u or of the home point) may round either way.
    mismatch = q["status"] != status
    assert mismatch.sum() <= 2, mismatch.sum()
    same = ~mismatch
    err = np.abs(q["coeffs"][same] - want[same]).max()
    assert err < 1e-12, err
    counts = {k: int((status == v).sum()) for k, v in STATUS.items()}
    assert counts["weights"] > 12000 and counts["outside"] > 1000, counts
    assert counts["fallback"] > 0, counts  # the masks and invalid probes leave some points no weight
    assert counts["none"] > 0, counts  # every corner empty or invalid
    w = q["weight"][(q["status"] == STATUS["weights"]) | (q["status"] == STATUS["fallback"])]
    assert np.abs(w.sum(axis=1) - 1).max() < 1e-12
    print(f"rotated={rotated} static={static}: {counts}, max |C - numpy| {err:.3g}")


def test_engine_oracle_equals_the_definition():
    # probe_ref.grid_irradiance (the engine tests' oracle of the shader: axis-aligned, no masks, no scale)
    # at 3000 random points and normals, back faces on and off, 15 % empty cells, 20 % invalid probes:
    # its E(n) equals E(n) of the C's interpolated coefficients, and its "held" the C's status.
    rng = np.random.default_rng(5)
    cells, coeffs, validity, _ = random_grid(rng, (5, 4, 3))
    origin, h = (-1.0, 0.5, 0.25), 1.0
    f = native.GridField.build(cells, origin, h, coeffs, validity=validity)
    p, n = random_points(rng, (5, 4, 3), origin, h, np.eye(3), 3000)
    for static in (False, True):
        q = f.query(p, n, static_surface=static)
        e_ref, held = ref.grid_irradiance(p, n, cells, origin, h, coeffs, validity=validity, backface=static)
        has = (q["status"] == STATUS["weights"]) | (q["status"] == STATUS["fallback"])
        assert (held == has).all()
        e_c = np.stack([ref.irradiance(q["coeffs"][i], n[i]) for i in np.flatnonzero(has)])
        err = np.abs(e_c - e_ref[has]).max()
        assert err < 1e-9 * np.abs(e_ref).max(), err
        print(f"oracle (back faces {static}): {has.sum()} points, max |E_C - E_oracle| {err:.3g}")


def test_linear_field_closed_form_and_clamped_faces():
    # Colour 0 linear in the cell centre's world position, every cell valid: the field at p is the linear
    # function at p's grid coordinates clamped to [1/2, dims - 1/2] (constant beyond the outer centres),
    # exact to rounding, rotated axes; the texture form too.
    rng = np.random.default_rng(2)
    R = rotation((0.3, -1, 0.5), 1.1)
    dims, origin, h = np.array([5, 4, 3]), np.array([0.5, -0.25, 1.0]), 0.4
    Z, Y, X = dims[::-1]
    cells = np.arange(X * Y * Z, dtype=np.int32).reshape(Z, Y, X)
    zz, yy, xx = np.meshgrid(np.arange(Z), np.arange(Y), np.arange(X), indexing="ij")
    centres = origin + (np.stack([xx, yy, zz], -1).reshape(-1, 3) + 0.5) @ R * h
    g = np.array([0.3, -0.6, 0.9])
    coeffs = np.zeros((X * Y * Z, 4, 3))
    coeffs[:, 0, :] = (1.0 + centres @ g)[:, None]
    f = native.GridField.build(cells, origin, h, coeffs, axes=R)
    u = -0.0099 + rng.uniform(0, 1, (4000, 3)) * (dims + 0.0198)
    p = origin + (u @ R) * h
    uc = np.clip(u, 0.5, dims - 0.5)
    want = 1.0 + (origin + (uc @ R) * h) @ g
    q = f.query(p)
    assert (q["status"] == STATUS["weights"]).all()
    assert np.abs(q["coeffs"][:, 0, 0] - want).max() < 1e-12
    c, d, has, t = f.sample_texture(p)
    assert has.all() and np.abs(c[:, 0, 0] - want).max() < 1e-12
    assert np.allclose(t, np.clip(u - 0.5, 0, dims - 1), atol=1e-12)
    # 8-bit fractions: the sample moves by at most half a step per axis, |grad| in grid units.
    c8, *_ = f.sample_texture(p, 8)
    grad_u = np.abs(R @ g) * h
    assert np.abs(c8[:, 0, 0] - want).max() <= grad_u.sum() * 2.0 ** -9 + 1e-12


def test_texture_equals_weights_and_binary16_bound():
    # The texture form (N = v s c, D = v; trilinear, N / D) equals the movable rule without masks wherever
    # the rule has weights (same points with a value: D > 1e-6 exactly when W > 1e-6); binary16 texels are
    # each within 2^-11 relative; N / D from them within the bound derived from those roundings.
    rng = np.random.default_rng(9)
    cells, coeffs, validity, scale = random_grid(rng, (7, 6, 5))
    origin, h = (0.0, 0.0, 0.0), 0.5
    f = native.GridField.build(cells, origin, h, coeffs, validity=validity, scale=scale)
    p, _ = random_points(rng, (7, 6, 5), origin, h, np.eye(3), 20000, pad=0.0)
    q = f.query(p)
    c, d, has, t = f.sample_texture(p)
    rule = q["status"] == STATUS["weights"]
    assert (rule == has).all()
    assert np.abs(c[has] - q["coeffs"][has]).max() < 1e-12
    tex = f.info()["texels"]
    half = f.texture(half=True).astype(np.float64)
    full = f.texture(half=False).astype(np.float64)
    ch = tex.shape[-1]
    flat = np.concatenate([half[g] for g in range(half.shape[0])], axis=-1)[..., :ch]
    flat32 = np.concatenate([full[g] for g in range(full.shape[0])], axis=-1)[..., :ch]
    nz = np.abs(tex) > 1e-4
    assert (np.abs(flat - tex)[nz] / np.abs(tex)[nz]).max() <= 2.0 ** -11
    assert np.abs(flat32 - tex).max() <= 2.0 ** -24 * np.abs(tex).max()
    # D channel (3) is the validity of the cell's probe, 0 for empty cells and invalid probes.
    want_d = np.where(cells >= 0, validity.astype(float)[np.maximum(cells, 0)], 0.0)
    assert np.array_equal(tex[..., 3], want_d)
    # N / D from binary16 texels: |N~ - N| <= 2^-11 sum w |N_k|, |D~ - D| <= 2^-11 D, so
    # |N~/D~ - N/D| <= 2^-11 (sum w |N_k| + |N|) / (D (1 - 2^-11)).
    Zs, Ys, Xs = cells.shape
    i0 = np.minimum(np.floor(t).astype(int), np.array([Xs, Ys, Zs]) - 1)
    i1 = np.minimum(i0 + 1, np.array([Xs, Ys, Zs]) - 1)
    fr = t - i0
    acc_h = np.zeros((len(p), ch))
    acc_abs = np.zeros((len(p), ch))
    for k in range(8):
        o = np.array([k & 1, (k >> 1) & 1, (k >> 2) & 1])
        ci = np.where(o == 1, i1, i0)
        w = np.prod(np.where(o == 1, fr, 1 - fr), axis=1)
        acc_h += w[:, None] * flat[ci[:, 2], ci[:, 1], ci[:, 0]]
        acc_abs += w[:, None] * np.abs(tex[ci[:, 2], ci[:, 1], ci[:, 0]])
    sel = has & (d > 0.05)
    nd = acc_h[sel][:, [0, 1, 2] + list(range(4, ch))] / acc_h[sel][:, 3:4]
    exact = np.concatenate([c[sel][:, 0], c[sel][:, 1:].reshape(sel.sum(), -1)], axis=1)
    num = acc_abs[sel][:, [0, 1, 2] + list(range(4, ch))]
    bound = 2.0 ** -11 * (num + np.abs(exact) * d[sel][:, None]) / (d[sel][:, None] * (1 - 2.0 ** -11)) + 1e-12
    err = np.abs(nd - exact)
    assert (err <= bound).all(), (err - bound).max()
    print(f"binary16: max |N/D error| {err.max():.3g} (relative to the largest coefficient "
          f"{err.max() / np.abs(exact).max():.3g}); bound max {bound.max():.3g}")


def test_refusals_are_clear():
    cells = np.zeros((2, 2, 2), np.int32)
    coeffs = np.ones((1, 9, 3))
    with pytest.raises(native.SchneeError, match="outside \\[-1"):
        native.GridField.build(cells + 1, (0, 0, 0), 1.0, coeffs)
    bad = coeffs.copy()
    bad[0, 3, 1] = np.nan
    with pytest.raises(native.SchneeError, match="coefficient 3 of probe 0"):
        native.GridField.build(cells, (0, 0, 0), 1.0, bad)
    with pytest.raises(native.SchneeError, match="positive"):
        native.GridField.build(cells, (0, 0, 0), 0.0, coeffs)
    with pytest.raises(native.SchneeError, match="orthonormal"):
        native.GridField.build(cells, (0, 0, 0), 1.0, coeffs, axes=np.diag([1.0, 1.0, 2.0]))
    with pytest.raises(native.SchneeError, match="GiB"):
        native.GridField.build(cells, (0, 0, 0), 1.0, coeffs, max_bytes=64)
    with pytest.raises(ValueError, match="masks"):
        native.GridField.build(cells, (0, 0, 0), 1.0, coeffs, masks=np.zeros((2, 2, 3), np.uint32))
    big = native.GridField.build(cells, (0, 0, 0), 1.0, coeffs * 1e5)
    with pytest.raises(native.SchneeError, match="upload float32"):
        big.texture(half=True)
    assert big.texture(half=False).max() == pytest.approx(1e5)


@pytest.mark.parametrize("rotated", [False, True])
def test_surface_texture_one_tap_where_separable(rotated):
    # pb_grid_field_sample_surface_texture (the engine's texture path, shaders/bricks.glsl
    # grid_tex_irradiance) against the rule itself (pb_grid_field_query's sum w s c): with exact fractions
    # the 8 taps and the one tap on floors and walls equal it to 1e-12 wherever the rule has weights (same
    # points with a value); a tilted plane's one tap (weights separable within 1e-5 relative) within 4e-5. Full grid,
    # valid probes, no masks, static surfaces: floors and walls (normals along the grid's axes) take one tap
    # at every inside point, tilted planes 8 taps at most points (their back-face weights are not a product
    # of per-axis ones) and one tap where every corner keeps weight 1. Then 15 % empty cells, 20 % invalid
    # probes, random masks, normal bias 0.3: still equal to the rule; which taps were taken is counted.
    rng = np.random.default_rng(41 + rotated)
    R = rotation((1, 2, 3), 0.7) if rotated else np.eye(3)
    origin, h, dims = (0.3, -0.7, 1.1), 0.35, (6, 5, 4)
    for hostile in (False, True):
        cells, coeffs, validity, scale = random_grid(rng, dims, empty=0.15 if hostile else 0.0,
                                                     invalid=0.2 if hostile else 0.0)
        masks = np.full(cells.shape, 0x7FFFFFF, np.int64)
        for b in range(27 if hostile else 0):
            masks &= ~((rng.uniform(size=cells.shape) < 0.3).astype(np.int64) << b)
        f = native.GridField.build(cells, origin, h, coeffs, axes=R, validity=validity, scale=scale,
                                   masks=masks.astype(np.uint32))
        p, tilt = random_points(rng, dims, origin, h, R, 6000, pad=0.0)
        axis = (np.eye(3)[rng.integers(0, 3, len(p))] * rng.choice([-1.0, 1.0], (len(p), 1))) @ R
        bias = 0.3 if hostile else 0.0
        for name, n in (("axis-aligned", axis), ("tilted", tilt)):
            q = f.query(p, n, static_surface=True, normal_bias=bias)
            c, d, has, taps = f.sample_surface_texture(p, n, static_surface=True, normal_bias=bias)
            rule = (q["status"] == STATUS["weights"]) | (q["status"] == STATUS["fallback"])
            assert (rule == has).all()
            e = np.abs(c - q["coeffs"]).max(axis=(1, 2)) / np.abs(q["coeffs"][has]).max()
            err = e[has].max()
            assert e[has & (taps == 8)].max(initial=0) < 1e-12, name
            # One tap: exact where the weights are exactly separable (floors, walls, all kept); a tilted
            # plane's cells separable within PB_BRICKS_SEPARABLE_EPS = 1e-5 relative per weight: each
            # normalised weight within 2e-5 relative, so within 4e-5 of the weighted |values| (measured 1e-7).
            assert e[has & (taps == 1)].max(initial=0) < (1e-12 if name == "axis-aligned" else 4e-5), name
            # Step 5 (no anti-leak weight left): 8 exact taps with the plain trilinear weights.
            fall = q["status"] == STATUS["fallback"]
            assert (taps[fall] == 8).all()
            one, eight = int((taps[has] == 1).sum()), int((taps[has & ~fall] == 8).sum())
            print(f"rotated={rotated} hostile={hostile} {name}: one tap {one}, 8 taps {eight}, step 5 {fall.sum()}, "
                  f"max err {err:.3g}")
            assert one + eight + fall.sum() == has.sum()
            if not hostile:
                if name == "axis-aligned":
                    assert eight == 0
                else:
                    assert eight > one > 0
            else:
                assert one > 0 and eight > 0
            # 8-bit fractions change the one tap's value only (the 8 taps are exact); not at every one-tap
            # point: an axis clamped at the faces, or f' 0 or 1 (measured 72-96 % moved).
            # (The quantised tap's D may fall below 1/64 where the exact one's did not: both calls' taps.)
            c8, _, _, taps8 = f.sample_surface_texture(p, n, static_surface=True, normal_bias=bias,
                                                       subtexel_bits=8)
            moved = np.abs(c8 - c).max(axis=(1, 2)) > 0
            assert not moved[has & (taps == 8) & (taps8 == 8)].any()
            assert moved[has & (taps == 1) & (taps8 == 1)].mean() > 0.5
