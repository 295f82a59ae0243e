"""Dense probe grids per pixel from their texture (--probe-path bricks; docs/grid-field.md): the engine
builds each dense SH grid's cell-centred texture with the core (pb_grid_field: N = v s c, D = v per cell,
RGBA16F in the brick pool), and bricks.glsl's grid_tex_irradiance samples it with one filtered fetch per
channel group where the rule's weights besides validity are separable (movable objects with a full mask,
axis-aligned floors and walls), else with 8 texelFetch taps and the rule's exact weights; step 5 (no
anti-leak weight left) with 8 texelFetch taps and the plain trilinear weights, from the texture too. Real
lavapipe, Khronos validation layer on (viewer.run).

Expected values come from the core's C through the Python module (native.GridField: the rule's status,
weights and coefficients; its binary16 texture and texel coordinates), as test_engine_bricks.py does for
the bricks: flat quads at random heights seen from above put every pixel centre at a known point.
Materials are white with shScale 1 and ambientTerm 0, so an EXR pixel is max(E(n), 0) / pi.
"""
import numpy as np
import pytest

from test_engine_bricks import e_of, pixel_points, quads_scene, render, render_quad
import test_engine_perpixel as pp
from test_engine_perpixel import ref, sg, viewer

from schnee_probes import native

BRICKS = ("--probe-path", "bricks")
HALF_EPS = 2.0 ** -11  # binary16 relative rounding (round to nearest)
W, V, F, N = (native.GRID_FIELD_STATUS.index(s) for s in ("weights", "none", "fallback", "outside"))
FALLBACK = 0.2  # probe 0's uniform radiance: pixel 0.2


def rotation(axis, angle):
    a = np.asarray(axis, float) / np.linalg.norm(axis)
    K = np.array([[0, -a[2], a[1]], [a[2], 0, -a[0]], [-a[1], a[0], 0]])
    return np.eye(3) * np.cos(angle) + np.sin(angle) * K + (1 - np.cos(angle)) * np.outer(a, a)


def f32(a):
    return np.asarray(a, np.float64).astype(np.float32).astype(np.float64)


def random_dense(d, seed, dims=(8, 5, 8), origin=(0.0, 0.0, 0.0), h=0.5, axes=None, empty=0.1, invalid=0.2):
    """A random L2 grid written as a version 2 .shprobe (validity, scales, axes); its float32 values as
    the engine reads them. Returns (entry, cells (Z, Y, X), coeffs, validity, scale, axes)."""
    rng = np.random.default_rng(seed)
    X, Y, Z = dims
    occ = rng.uniform(size=(Z, Y, X)) >= empty
    cells = np.full((Z, Y, X), -1, np.int32)
    cells[occ] = np.arange(occ.sum())
    P = int(occ.sum())
    coeffs = f32(rng.normal(0.0, 0.3, (P, 9, 3)))
    coeffs[:, 0] = f32(rng.uniform(1.0, 4.0, (P, 3)))
    validity = np.where(rng.uniform(size=P) < invalid, 0.0, rng.uniform(0.2, 1.0, P)).astype(np.float32)
    scale = rng.uniform(0.5, 2.0, P).astype(np.float32)
    axes = np.eye(3) if axes is None else np.asarray(axes, float)
    (d / "sh_coeffs").mkdir(exist_ok=True)
    native.write_shprobe(str(d / "sh_coeffs" / "g.shprobe"), coeffs, cells, dims, origin, h, version=2,
                         validity=validity, probe_scale=scale, grid_axes=axes)
    entry = sg.grid_entry("g", "sh_coeffs/g.shprobe", P, origin, dims, h)
    entry["gridAxes"] = f32(axes).tolist()
    return entry, cells, coeffs, validity, scale, f32(axes)


def texture_model(field, points, bits=0):
    """The GPU's filtered fetch on the CPU: the C's binary16 texels (pb_grid_field_texture_f16) at the C's
    texel coordinates t, trilinear with exact fractions or fractions rounded to 2^-bits, N / D.
    (coeffs (M, C, 3), D (M,))."""
    info = field.info()
    X, Y, Z = info["dims"]
    ch = info["channels"]
    tex16 = field.texture(half=True).astype(np.float64)
    tex = np.concatenate(list(tex16), axis=-1)[..., :ch]  # (Z, Y, X, channels)
    _, _, _, t = field.sample_texture(points)
    dims = np.array([X, Y, Z])
    i0 = np.minimum(np.floor(t).astype(int), dims - 1)
    i1 = np.minimum(i0 + 1, dims - 1)
    fr = t - i0
    if bits:
        fr = np.round(fr * 2.0 ** bits) / 2.0 ** bits
    acc = np.zeros((len(points), ch))
    for k in range(8):
        o = np.array([k & 1, (k >> 1) & 1, (k >> 2) & 1])
        ci = np.where(o == 1, i1, i0)
        w = np.prod(np.where(o == 1, fr, 1 - fr), axis=1)
        acc += w[:, None] * tex[ci[:, 2], ci[:, 1], ci[:, 0]]
    d = acc[:, 3]
    C = info["coeff_count"]
    chans = [[k if c == 0 else 3 * c + 1 + k for k in range(3)] for c in range(C)]
    coeffs = np.stack([acc[:, c] for c in chans], axis=1) / np.where(d > 0, d, 1.0)[:, None, None]
    return coeffs, d


def expected_pixels(field, q, coeffs, scale, p, up, model=None, model8=None):
    """Pixel expected per status: WEIGHTS the texture model (when given) else the C's sum w s c; FALLBACK
    (step 5) the C's sum of the plain trilinear x validity weights (the engine's 8 exact taps of the texture);
    NONE / OUTSIDE probe 0's 0.2."""
    want = np.full((len(p), 3), FALLBACK)
    w = q["status"] == W
    src = q["coeffs"] if model is None else model
    want[w] = e_of(src[w], up[w])
    fb = q["status"] == F
    want[fb] = e_of(q["coeffs"][fb], up[fb])
    return want


@pytest.mark.parametrize("rotated", [False, True])
def test_glsl_filtered_path_equals_the_c_on_random_points(tmp_path, rotated):
    # Movable quads (no static scene: every mask full) at 4 random heights, 97^2 pixel centres each, through
    # a random grid (10 % empty cells, 20 % invalid probes, random scales; rotated axes in one case): every
    # point with weights takes the one-filtered-fetch path. Same binary16 texels on both sides; bound: the
    # exact-fraction model within fp32 noise plus one 2^-8 step of the filter's weights (2 x |model 8-bit -
    # model exact|) + 2e-5 of the peak + 1e-4 near invalid probes (N / D steep).
    R = rotation((0.2, 1.0, 0.1), 0.5) if rotated else np.eye(3)
    origin = (0.4, 0.0, -0.3) if rotated else (0.0, 0.0, 0.0)
    entry, cells, coeffs, validity, scale, axes = random_dense(tmp_path, 3 + rotated, origin=origin, axes=R)
    field = native.GridField.build(cells, origin, 0.5, coeffs, axes=axes, validity=validity, scale=scale)
    rng = np.random.default_rng(11 + rotated)
    heights = rng.uniform(0.1, 2.4, 4)
    scene = quads_scene(tmp_path, heights, entry=entry)
    size = 97
    imgs, pts = [], []
    for k, y in enumerate(heights):
        img, proc = render_quad(tmp_path, scene, k, y, size, (2.0, 2.0), *BRICKS)
        assert "dense grid(s) as cell-centred textures" in proc.stderr, proc.stderr
        imgs.append(img.reshape(-1, 3))
        pts.append(pixel_points(2.0, 2.0, 2.0, y, size).reshape(-1, 3))
    img, p = np.concatenate(imgs), np.concatenate(pts)
    up = np.tile([0.0, 1.0, 0.0], (len(p), 1))
    q = field.query(p)
    exact, _ = texture_model(field, p)
    bits8, _ = texture_model(field, p, bits=8)
    want = expected_pixels(field, q, coeffs, scale, p, up, exact)
    want8 = expected_pixels(field, q, coeffs, scale, p, up, bits8)
    counts = {s: int((q["status"] == i).sum()) for i, s in enumerate(native.GRID_FIELD_STATUS)}
    assert counts["weights"] > 0.5 * len(p), counts
    err = np.abs(img - want).max(axis=1)
    bound = 2 * np.abs(want8 - want).max(axis=1) + 2e-5 * want.max() + 1e-4
    bad = err > bound
    # A point whose D is within fp16 rounding of 1e-6, or on a floor() boundary in fp32, may decide differently.
    assert bad.sum() <= 2, (bad.sum(), err[bad][:5], bound[bad][:5], q["status"][bad][:5])
    # Against the definition itself (float64 coefficients): binary16 texels' bound.
    wpts = q["status"] == W
    defn = e_of(q["coeffs"][wpts], up[wpts])
    rel = np.abs(img[wpts] - defn).max(axis=1) / np.maximum(defn.max(axis=1), 1e-3)
    print(f"rotated={rotated}: {counts}; max |GLSL - C texture model| {err[~bad].max():.3g}; against the "
          f"float64 definition relative p99 {np.percentile(rel, 99):.3g}, max {rel.max():.3g}")
    assert np.percentile(rel, 99) < 4 * HALF_EPS * 8


def straddle_masks(cells, origin, h, y):
    """The neighbour masks a horizontal plane at world height y (covering the grid) gives an axis-aligned
    grid: the segment between two cell centres is blocked when they lie on opposite sides of it."""
    Z, Y, X = cells.shape
    cy = origin[1] + (np.arange(Y) + 0.5) * h
    masks = np.zeros((Z, Y, X), np.uint32)
    for j in range(Y):
        m = 0
        for dz in (-1, 0, 1):
            for dy in (-1, 0, 1):
                for dx in (-1, 0, 1):
                    jj = j + dy
                    blocked = 0 <= jj < Y and (cy[j] - y) * (cy[jj] - y) < 0
                    if not blocked:
                        m |= 1 << ((dx + 1) + 3 * (dy + 1) + 9 * (dz + 1))
        masks[:, j, :] = m
    return masks


def static_floor_scene(d, entry, y, k):
    """One static 10 x 10 m floor at height y (larger than the grid: it splits every vertical segment it
    crosses), the look-down camera of quads_scene."""
    b = sg.GltfBuilder()
    m = b.material("White", sh_scale=1.0, ambient_term=0.0, probe_mode="pixel")
    b.node("Floor", mesh=b.mesh("floor", sg.quad(10.0, 10.0, 1), m), translation=(2.0, y, 2.0))
    b.node("Camera", camera=b.ortho_camera("top", 2.0), translation=(2.0, y + 3.0, 2.0), rotation=sg.ROT_LOOK_DOWN)
    b.probe_grids([entry])
    return b.write(d / f"floor{k}.gltf")


def test_glsl_exact_taps_equal_the_c_on_static_floors(tmp_path):
    # Static floors at 3 random heights (away from the centres' heights) through a random grid, normal bias
    # 0.2: back-face weights drop the corners below the floor and the home cell's mask those across it
    # (the engine traces them; the C gets the same masks from the straddle rule): where the kept weights are
    # separable (a whole face dropped or kept) one filtered fetch at f', else the 8 exact taps, and points
    # with every weight 0 step 5's plain trilinear x validity weights (8 exact taps). Bound: binary16 texels, |N~/D~ - N/D| <= 2^-11
    # (sum w |E_k| + |E|) per channel, doubled, + 2e-5 of the peak + 1e-5 (fp32 weights and sums) + one
    # 2^-8 filter step for the filtered points.
    entry, cells, coeffs, validity, scale, _ = random_dense(tmp_path, 8)
    rng = np.random.default_rng(4)
    centres_y = (np.arange(5) + 0.5) * 0.5
    heights = []
    while len(heights) < 3:
        y = rng.uniform(0.05, 2.45)
        if np.abs(centres_y - y).min() > 0.03:
            heights.append(y)
    size = 80  # even: no pixel centre on the cell faces x = 2, z = 2 (a floor() tie between fp32 and float64)
    worst, taps, eight, counts_all = 0.0, 0, 0, {}
    for k, y in enumerate(heights):
        scene = static_floor_scene(tmp_path, entry, y, k)
        img, proc = render(scene, tmp_path / f"f{k}.exr", size, "--normal-bias", 0.2, *BRICKS)
        img = img.reshape(-1, 3)
        p = pixel_points(2.0, 2.0, 2.0, y, size).reshape(-1, 3)
        up = np.tile([0.0, 1.0, 0.0], (len(p), 1))
        masks = straddle_masks(cells, (0, 0, 0), 0.5, y)
        field = native.GridField.build(cells, (0, 0, 0), 0.5, coeffs, validity=validity, scale=scale, masks=masks)
        q = field.query(p, up, static_surface=True, normal_bias=0.2)
        want = expected_pixels(field, q, coeffs, scale, p, up)
        # Per-corner |E_k| for the binary16 bound (weights from the C, s c of each corner's probe).
        sc = coeffs * scale.astype(float)[:, None, None]
        absum = np.zeros((len(p), 3))
        for c in range(8):
            pr = np.maximum(q["probe"][:, c], 0)
            absum += q["weight"][:, c, None] * np.abs(e_of(sc[pr], up) * np.pi)
        absum /= np.pi
        p_bias = p + 0.2 * 0.5 * up
        m_exact, _ = texture_model(field, p_bias)
        m8, _ = texture_model(field, p_bias, bits=8)
        step = np.abs(e_of(m8, up) - e_of(m_exact, up)).max(axis=1)
        bound = 2 * HALF_EPS * (absum.max(axis=1) + np.abs(want).max(axis=1)) + 2 * step + 2e-5 * want.max() + 1e-5
        err = np.abs(img - want).max(axis=1)
        bad = err > bound
        assert bad.sum() <= 2, (y, bad.sum(), err[bad][:5], bound[bad][:5], q["status"][bad][:5])
        worst = max(worst, err[~bad].max())
        # How many points had a corner dropped (weights not all from the plain rule), and of those how many
        # take the 8 taps (the kept weights not separable: a mask dropping part of a face; the floor's own
        # back faces drop whole faces and keep the one tap): pb_grid_field_sample_surface_texture.
        plain = native.GridField.build(cells, (0, 0, 0), 0.5, coeffs, validity=validity, scale=scale)
        qp = plain.query(p, up, static_surface=False, normal_bias=0.2)
        dropped = (np.abs(qp["weight"] - q["weight"]).max(axis=1) > 1e-9) & (q["status"] == W)
        taps += int(dropped.sum())
        *_, ntaps = field.sample_surface_texture(p, up, static_surface=True, normal_bias=0.2)
        eight += int((dropped & (ntaps == 8)).sum())
        for i, s in enumerate(native.GRID_FIELD_STATUS):
            counts_all[s] = counts_all.get(s, 0) + int((q["status"] == i).sum())
    assert taps > 1000 and counts_all["fallback"] > 0, (taps, counts_all)
    print(f"static floors: {counts_all}, {taps} points with dropped corners ({eight} of them on 8 taps, the rest "
          f"one tap); max |GLSL - C| {worst:.3g}")


def test_linear_field_closed_form(tmp_path):
    # Every cell valid, L00 linear in the cell centre: f(p) at p's grid coordinates clamped to the outer
    # centres, rotated axes. Bound: binary16 (2^-11 relative of N, D = 1 exactly) + one 2^-8 step x |grad|.
    R = rotation((1.0, 2.0, 3.0), 0.4)
    origin, h, dims = np.array([0.3, -0.2, 0.1]), 0.5, np.array([8, 5, 8])
    X, Y, Z = dims
    cells = np.arange(X * Y * Z, dtype=np.int32).reshape(Z, Y, X)
    zz, yy, xx = np.meshgrid(np.arange(Z), np.arange(Y), np.arange(X), indexing="ij")
    centres = origin + (np.stack([xx, yy, zz], -1).reshape(-1, 3) + 0.5) @ R * h
    g = np.array([0.5, 0.25, 0.75])
    coeffs = np.zeros((X * Y * Z, 9, 3))
    coeffs[:, 0, :] = (2.0 + centres @ g)[:, None]
    coeffs = f32(coeffs)
    (tmp_path / "sh_coeffs").mkdir()
    native.write_shprobe(str(tmp_path / "sh_coeffs" / "g.shprobe"), coeffs, cells, dims, origin, h, version=2,
                         grid_axes=R)
    entry = sg.grid_entry("g", "sh_coeffs/g.shprobe", len(coeffs), origin, dims, h)
    entry["gridAxes"] = f32(R).tolist()
    heights = np.random.default_rng(3).uniform(0.3, 2.0, 2)
    scene = quads_scene(tmp_path, heights, entry=entry)
    field = native.GridField.build(cells, origin, h, coeffs, axes=f32(R))
    worst = 0.0
    for k, y in enumerate(heights):
        img, _ = render_quad(tmp_path, scene, k, y, 65, (2.0, 2.0), *BRICKS)
        p = pixel_points(2.0, 2.0, 2.0, y, 65).reshape(-1, 3)
        q = field.query(p)
        inside = q["status"] == W
        u = (p[inside] - origin) @ R.T / h
        uc = np.clip(u, 0.5, dims - 0.5)
        f = 2.0 + (origin + (uc @ R) * h) @ g
        want = 0.282094792 * f
        assert np.abs(q["coeffs"][inside, 0, 0] - f).max() < 1e-5  # the C: exact (float32 file values)
        grad = np.abs(R @ g).sum() * h  # per grid unit
        bound = 0.282094792 * (2 * HALF_EPS * f + grad * 2.0 ** -8) + 1e-6
        err = np.abs(img.reshape(-1, 3)[inside] - want[:, None]).max(axis=1)
        assert (err <= bound).all(), (err.max(), bound.min())
        worst = max(worst, (err / want).max())
    print(f"linear field: max relative error {worst:.3g}")


# ---- the per-pixel dense-grid tests of test_engine_perpixel.py under --probe-path bricks ----------------


def bricks_render(scene, out, *args):
    return pp.render(scene, out, *args, *BRICKS)


def test_bricks_floor_equals_the_definition(tmp_path):
    # test_interpolation_equals_cpu_trilinear's floor (holes, clamped faces, the fallback outside) from the
    # texture: the documented rule (probe_ref, checked against pb_grid_field in test_native_grid_field.py)
    # within binary16 (2^-11 relative per texel, doubled for N / D) + fp32.
    scene = pp.floor_scene(tmp_path, 0.1, (2.0, 2.0), 5.0, mode="pixel")
    img = bricks_render(scene, tmp_path / "b.exr")
    buf = pp.render(scene, tmp_path / "f.exr")
    p = pp.down_camera_points(2.0, 2.0, 0.1, 2.5).reshape(-1, 3)
    n = np.tile([0.0, 1.0, 0.0], (len(p), 1))
    e, held = ref.grid_irradiance(p, n, pp.GRID, (0, 0, 0), 1.0, pp.COEFFS)
    e[~held] = np.pi * pp.FALLBACK
    expected = (np.maximum(e, 0) / np.pi).reshape(pp.N, pp.N, 3)
    # |E_k| sum over the 4 corners' probes bounds the texel rounding: max |E| of any probe here x 2 x 2^-11.
    emax = max(np.abs(ref.irradiance(c, [0, 1, 0])).max() for c in pp.COEFFS) / np.pi
    err = np.abs(img - expected)
    assert err.max() < 4 * HALF_EPS * emax + 1e-4, err.max()
    assert np.abs(img - buf).max() < 4 * HALF_EPS * emax + 1e-4
    print(f"floor: max |bricks - rule| {err.max():.3g} (bound {4 * HALF_EPS * emax + 1e-4:.3g}); "
          f"|bricks - buffers| {np.abs(img - buf).max():.3g}")


def test_bricks_centre_agrees_with_per_object(tmp_path):
    # test_centre_agrees_with_per_object under --probe-path bricks: the centre pixel sits on the centre of
    # cell (1, 0, 1) (trilinear weight 1: the filtered fetch returns that texel), so it equals the per-object
    # probe within binary16 (N and D rounded: 2 x 2^-11 relative).
    scene = pp.floor_scene(tmp_path, 0.5, (1.5, 1.5), 3.0)
    obj = pp.render(scene, tmp_path / "o.exr", "--probe-mode", "object")
    pix = bricks_render(scene, tmp_path / "p.exr", "--probe-mode", "pixel")
    c = pp.N // 2
    want = np.maximum(ref.irradiance(pp.COEFFS[pp.GRID[1, 0, 1]], [0, 1, 0]), 0) / np.pi
    assert np.allclose(obj[c, c], want, rtol=1e-5)
    assert np.allclose(pix[c, c], want, rtol=2 * HALF_EPS, atol=1e-6), (pix[c, c], want)
    assert np.abs(pix[0, 0] - obj[0, 0]).max() > 0.05


def test_bricks_wall_does_not_leak(tmp_path):
    # test_wall_does_not_leak under --probe-path bricks: the bright probe behind the wall's dark face has
    # back-face weight 0, so the 8 exact taps keep the dark value 0.05 (binary16 of it: <= 2^-11 relative).
    # Per object is the field at the quad's centre under either path (movable rule; the quad never blocks
    # its own probes): 0.51 * 0.05 + 0.49 * 5 = 2.4755 (docs/grid-field.md "Per object").
    scene, grid, coeffs = pp.wall_quad_scene(tmp_path, (1.99, 0.5, 0.5))
    obj = bricks_render(scene, tmp_path / "o.exr", "--probe-mode", "object")
    pix = bricks_render(scene, tmp_path / "p.exr", "--probe-mode", "pixel")
    e, _ = ref.grid_irradiance([[1.99, 0.5, 0.5]], [[-1.0, 0, 0]], grid, (0, 0, 0), 1.0, coeffs, backface=False)
    assert np.allclose(obj, e[0] / np.pi, rtol=1e-5), (obj.min(), obj.max())
    assert np.abs(pix - 0.05).max() <= 0.05 * 2 * HALF_EPS, f"per pixel leaks: max {pix.max():.6g}"


def test_bricks_floor_next_to_wall_does_not_leak(tmp_path):
    # test_floor_next_to_wall_does_not_leak under --probe-path bricks: the home cell's mask drops the bright
    # probes across the wall (8 exact taps): the floor stays at the dark value (binary16 of it).
    scene, _, _ = pp.floor_by_wall_scene(tmp_path, wall=True)
    obj = pp.render(scene, tmp_path / "o.exr", "--probe-mode", "object")
    pix = bricks_render(scene, tmp_path / "p.exr", "--probe-mode", "pixel")
    p = pp.down_camera_points(0.99, 0.5, 0.1, 0.99)
    on_floor = (p[..., 2] > 0.02) & (p[..., 2] < 0.98)
    assert pix[on_floor].max() <= obj[on_floor].max() * (1 + 2 * HALF_EPS), pix[on_floor].max()
    # Without the wall the gradient is back (the filtered fetch), equal to the rule within binary16.
    scene, grid, coeffs = pp.floor_by_wall_scene(tmp_path, wall=False)
    pix = bricks_render(scene, tmp_path / "q.exr", "--probe-mode", "pixel")
    pts = p[on_floor]
    e, held = ref.grid_irradiance(pts, np.tile([0.0, 1.0, 0.0], (len(pts), 1)), grid, (0, 0, 0), 1.0, coeffs)
    expected = np.maximum(e, 0) / np.pi
    assert np.abs(pix[on_floor] - expected).max() < 2 * HALF_EPS * 5.0 + 1e-4
    assert pix[on_floor].max() > 2.0


def test_bricks_movable_quad_gets_no_back_face_weight(tmp_path):
    # test_movable_quad_gets_no_back_face_weight under --probe-path bricks: the filtered fetch gives the
    # x-interpolation (1 - f) 0.05 + f 5 (f = 0.49), within binary16 of the texels (and 2^-8 of a weight
    # step: lavapipe filters with fp32 weights, measured below it).
    scene, grid, coeffs = pp.wall_quad_scene(tmp_path, (9.0, 9.0, 9.0))
    pix = bricks_render(scene, tmp_path / "p.exr", "--probe-mode", "pixel", "--move", "Wall", 1.99, 0.5, 0.5)
    f = 1.99 - 1.5
    want = (1 - f) * 0.05 + f * 5.0
    assert np.allclose(pix, want, rtol=2 * HALF_EPS), (pix.min(), pix.max(), want)


def test_ambient_cube_grids_keep_the_buffers(tmp_path):
    # A dense grid holding ambient cubes is not textured: the bricks path renders what the buffers do.
    scene = pp.floor_scene(tmp_path, 0.1, (2.0, 2.0), 5.0, mode="pixel")
    a = pp.render(scene, tmp_path / "a.exr", "--probe-representation", "ambientCube")
    b = bricks_render(scene, tmp_path / "b.exr", "--probe-representation", "ambientCube")
    assert np.array_equal(a, b)
    proc = viewer.run(scene, "--headless", "--output", tmp_path / "x.exr", "--width", 8, "--height", 8, *BRICKS)
    assert "dense grid(s) as cell-centred textures" in proc.stderr
