"""Probe bricks per pixel in schnee-view (--probe-path bricks; docs/probe-bricks.md, docs/engine.md "Probe
bricks"): the engine builds each corner octree's / kd corner tree's bricks with the core (pb_bricks),
uploads the pool as RGBA16F 3D textures (RGBA32F past the half range) and the indirection as RGBA32UI,
and shading.glsl's brick_irradiance (shaders/bricks.glsl) samples them with the hardware's trilinear
filter. Real lavapipe, Khronos validation layer on (viewer.run).

Expected values come from the core's C through the Python module: native.Bricks (the brick texels, the
locate step's brick and brick-local coordinate, the 8-bit quantised sample), the file's interpolation
(CornerOctree.query) and closed forms. The GLSL/C comparison runs through schnee-view --headless renders
(not tests/tools/vk_compute.c, which binds storage buffers only): flat quads at random heights seen from
above put every pixel centre at a known point (tens of thousands of points per case), and the pixel is
compared with a numpy filter over the C's own binary16 texels at the C's brick and brick-local coordinate.
Materials are white with shScale 1 and ambientTerm 0, so an EXR pixel is max(E(n), 0) / pi.
"""
import numpy as np
import pytest

from test_engine_v3 import interpolate, linear, linear_sh, octree, random_sh, ref, sg, viewer
from test_engine_v3 import write_grid as write_grid_v3
from test_engine_v4 import kd_tree
from test_engine_v4 import write_grid as write_grid_v4

from schnee_probes import native

BRICKS = ("--probe-path", "bricks")
HALF_EPS = 2.0 ** -11  # binary16 relative rounding (round to nearest)


def f32(a):
    """The file's float32 values (the engine builds its bricks from them)."""
    return np.asarray(a, np.float64).astype(np.float32).astype(np.float64)


def tree_and_entry(d, kind, coeffs_of, name="p"):
    tree = octree() if kind == "octree" else kd_tree()
    coeffs = coeffs_of(tree)
    entry = (write_grid_v3 if kind == "octree" else write_grid_v4)(d, tree, coeffs, name=name)
    return tree, coeffs, entry


def render(scene, out, size, *args):
    proc = viewer.check(viewer.run(scene, "--headless", "--output", out, "--width", size, "--height", size, *args))
    return viewer.read_image(out)[..., :3], proc


def pixel_points(cx, cz, mag, y, size):
    """World points (size, size, 3) of the pixel centres of a look-down ortho camera (xmag = ymag = mag)."""
    t = (2 * (np.arange(size) + 0.5) / size - 1) * mag
    X, Z = np.meshgrid(cx + t, cz + t)  # column -> +x, row -> +z
    return np.stack([X, np.full_like(X, y), Z], axis=-1)


def e_of(coeffs, normals):
    """max(E(n), 0) / pi of L2 coefficients (M, 9, 3) at unit normals (M, 3): the pixel of a white material."""
    e = np.einsum("mi,i,mic->mc", ref.sh_basis_l2(np.asarray(normals, float)), ref.A_L2, coeffs[:, :9])
    return np.maximum(e, 0) / np.pi


def brick_model(bricks, points, bits=0, f16=True):
    """The engine's sample on the CPU: the C's locate (brick, brick-local x), the C's texels rounded to
    binary16 as the pool the engine uploads (pb_bricks_pool_f16 rounds the same float64 values), trilinear
    at the texel cell with exact fractions or fractions rounded to 2^-bits, N / D. (coeffs (M, C, 3),
    has_value (M,))."""
    info = bricks.info()
    tex = info["texels"].astype(np.float16).astype(np.float64) if f16 else info["texels"]
    _, _, found, brick, x = bricks.sample_raw(points)
    b = np.maximum(brick, 0)
    k0 = np.minimum(np.floor(x), 3).astype(np.int64)
    f = x - k0
    if bits:
        f = np.round(f * 2.0 ** bits) / 2.0 ** bits
    acc = np.zeros((len(points), info["channels"]))
    for c in range(8):
        o = [(c >> a) & 1 for a in range(3)]
        w = np.prod([f[:, a] if o[a] else 1 - f[:, a] for a in range(3)], axis=0)
        acc += w[:, None] * tex[b, k0[:, 2] + o[2], k0[:, 1] + o[1], k0[:, 0] + o[0]]
    d = acc[:, 3]
    has = found & (d > 0)
    chans = [[k if c == 0 else 3 * c + 1 + k for k in range(3)] for c in range(info["coeff_count"])]
    coeffs = np.stack([acc[:, ch] for ch in chans], axis=1) / np.where(has, d, 1.0)[:, None, None]
    return coeffs, has


def quads_scene(d, heights, mag=2.0, centre=(2.0, 2.0), entry=None):
    """One movable 4 x 4 m quad per height (each render shows one: the others are moved away), the camera
    above looking down. Returns the scene and the --move arguments that put quad k in place."""
    b = sg.GltfBuilder()
    m = b.material("White", sh_scale=1.0, ambient_term=0.0, probe_mode="pixel")
    for k, _ in enumerate(heights):
        b.node(f"Quad{k}", mesh=b.mesh(f"quad{k}", sg.quad(2 * mag, 2 * mag, 1), m), translation=(20.0 + k, 20.0, 20.0))
    b.node("Camera", camera=b.ortho_camera("top", mag), translation=(centre[0], 3.0, centre[1]),
           rotation=sg.ROT_LOOK_DOWN)
    b.probe_grids([entry])
    return b.write(d / "quads.gltf")


def render_quad(d, scene, k, y, size, centre=(2.0, 2.0), *args):
    img, proc = render(scene, d / f"q{k}.exr", size, "--move", f"Quad{k}", centre[0], y, centre[1], *args)
    return img, proc


def sphere_scene(d, entry, c, r):
    b = sg.GltfBuilder()
    m = b.material("White", sh_scale=1.0, ambient_term=0.0, probe_mode="pixel")
    b.node("Sphere", mesh=b.mesh("sphere", sg.uv_sphere(r, 128, 64), m), translation=(5.0, 5.0, 5.0))
    b.node("Camera", camera=b.ortho_camera("top", r), translation=(c[0], 3.0, c[2]), rotation=sg.ROT_LOOK_DOWN)
    b.probe_grids([entry])
    return b.write(d / "sphere.gltf")


@pytest.mark.parametrize("kind", ["octree", "kd"])
def test_movable_sphere_per_pixel_equals_the_cpu_model(tmp_path, kind):
    # A movable sphere across leaves of two levels (octree: 0.5 and 1 m leaves and their hanging nodes;
    # kd: boxes of several shapes): every normal of the upper hemisphere. The bricks' field is the
    # movable-object rule, the file's plain interpolation (no back-face weight, no visibility).
    tree, coeffs, entry = tree_and_entry(tmp_path, kind, lambda t: random_sh(t.probe_count, 13))
    c, r = np.array([1.45, 0.8, 1.55]), 0.4
    scene = sphere_scene(tmp_path, entry, c, r)
    size = 65
    img, proc = render(scene, tmp_path / "s.exr", size, "--move", "Sphere", *c, *BRICKS)
    assert "schnee-view: probe bricks:" in proc.stderr and "RGBA16F" in proc.stderr, proc.stderr
    p = pixel_points(c[0], c[2], r, 0.0, size)
    d2 = (p[..., 0] - c[0]) ** 2 + (p[..., 2] - c[2]) ** 2
    on = d2 < (0.9 * r) ** 2  # away from the silhouette (tessellation)
    p[..., 1] = c[1] + np.sqrt(np.maximum(r * r - d2, 0))
    nrm = (p - c) / r
    bricks = native.Bricks.build(tree, f32(coeffs))
    model, has = brick_model(bricks, p[on], bits=8)
    assert has.all()
    want = e_of(model, nrm[on])
    err = np.abs(img[on] - want).max()
    # The tessellated sphere (128 x 64; positions and normals off the analytic ones by < 1.2e-3
    # relative: test_engine_v3's bound for the buffers path, 2.4e-4 measured there) dominates; the fp16
    # texels are in the model. Measured 3.2e-4 (octree) / 2.6e-4 (kd) at peaks 0.75 / 0.87.
    assert err < 1e-4 + 1e-3 * want.max(), (err, want.max())
    # The file's interpolation in float64 (texels exact): the same bound (fp16 texels add <= 5e-4 relative).
    file_e = e_of(interpolate(tree, p[on], coeffs), nrm[on])
    assert np.abs(img[on] - file_e).max() < 1e-4 + 1.5e-3 * file_e.max()


def planes_comparison(tmp_path, kind, seed, count, size):
    """Renders `count` quads at random heights through the lattice (random SH, 20 % invalid probes, random
    scales) and returns (image pixels, exact-weight model, 8-bit-weight model, file interpolation, has)."""
    rng = np.random.default_rng(seed)
    tree = octree() if kind == "octree" else kd_tree()
    coeffs = random_sh(tree.probe_count, seed)
    validity = (rng.uniform(size=tree.probe_count) > 0.2).astype(np.float32)
    scale = rng.uniform(0.5, 2.0, tree.probe_count)
    (tmp_path / "sh_coeffs").mkdir(exist_ok=True)
    path = tmp_path / "sh_coeffs" / "p.shprobe"
    count_written = native.write_shprobe_v3(str(path), tree, coeffs, validity=validity, probe_scale=scale)
    f = native.read_shprobe(str(path))
    entry = sg.grid_entry("p", "sh_coeffs/p.shprobe", count_written, f.grid_origin, f.grid_dims, f.grid_spacing)
    entry.update(representation=f.representation, storage=f.storage, structure=f.structure)
    if f.structure == "kdtree":
        entry.update(version=4)
    heights = rng.uniform(0.05, 1.95, count)
    scene = quads_scene(tmp_path, heights, entry=entry)
    bricks = native.Bricks.build(tree, f32(coeffs), validity=validity, scale=f32(scale))
    imgs, pts = [], []
    for k, y in enumerate(heights):
        img, _ = render_quad(tmp_path, scene, k, y, size, (2.0, 2.0), *BRICKS)
        imgs.append(img.reshape(-1, 3))
        pts.append(pixel_points(2.0, 2.0, 2.0, y, size).reshape(-1, 3))
    img, p = np.concatenate(imgs), np.concatenate(pts)
    up = np.tile([0.0, 1.0, 0.0], (len(p), 1))
    exact, has = brick_model(bricks, p)
    bits8, has8 = brick_model(bricks, p, bits=8)
    c64, has_file = bricks.sample(p)
    return img, up, exact, bits8, has, has8, has_file, tree, coeffs, validity, scale, p


@pytest.mark.parametrize("kind", ["octree", "kd"])
def test_glsl_sampler_equals_the_c_on_random_points(tmp_path, kind):
    # brick_irradiance (GLSL, hardware trilinear on lavapipe) against the C's bricks at 4 x 97^2 = 37636
    # pixel centres on quads at random heights, 20 % invalid probes, random probe scales. Where the C has
    # no value (every probe with weight invalid: D = 0) the engine falls back to probe 0, which this
    # scene's fallback makes the uniform 0.2 radiance, E = 0.2 pi, pixel 0.2.
    size = 97
    img, up, exact, bits8, has, has8, has_file, *_ = planes_comparison(tmp_path, kind, 7, 4, size)
    want = e_of(np.nan_to_num(exact), up)
    want8 = e_of(np.nan_to_num(bits8), up)
    both = has & has8
    assert both.sum() > 0.6 * len(img)
    # Same texels (binary16 RNE of the same float64 on both sides); what differs is the filter's weights
    # (lavapipe: fp32 coordinates, its sub-texel precision) and fp32 sums. Bound: the exact-weight model
    # within fp32 noise plus one 2^-8 step of the weights at this point (|model(8 bit) - model(exact)| is
    # at most a half step, so 2x it + 2e-5 of the peak covers a full step either way) and 1e-4 absolute
    # near invalid probes, where N / D is steep.
    err = np.abs(img[both] - want[both]).max(axis=1)
    bound = 2 * np.abs(want8[both] - want[both]).max(axis=1) + 2e-5 * want.max() + 1e-4
    assert (err <= bound).all(), (err.max(), (err > bound).sum())
    rel = err / np.maximum(want[both].max(axis=1), 1e-3)
    print(f"{kind}: {both.sum()} points, max |GLSL - C| {err.max():.3g} (relative p99 {np.percentile(rel, 99):.3g}, "
          f"max {rel.max():.3g}); |C 8-bit - C exact| max {np.abs(want8 - want)[both].max():.3g}")
    # No value in the C: the fallback probe 0 (radiance 0.2 in every channel) as with the buffers path.
    none = ~has & ~has8
    if none.any():
        assert np.abs(img[none] - 0.2).max() < 1e-6
    # The C's value / no-value decision is the file's (exact texels): at most a few points flip where D
    # is within fp16 / weight rounding of 0.
    assert (has != has_file).sum() <= 2


def test_linear_field_is_reproduced_to_fp16_precision(tmp_path):
    # L00 linear in position on the octree (hanging nodes, a level border): pixel = Y0 f(p) in closed
    # form. N and D are rounded to binary16 (each <= 2^-11 relative; D = 1 here exactly, f up to 6) and the
    # filter's weights move the sample by <= one 2^-8 step of a texel (2^L h / 256 per axis) x |grad f|.
    tree = octree()
    entry = write_grid_v3(tmp_path, tree, linear_sh(tree.positions()))
    rng = np.random.default_rng(3)
    heights = rng.uniform(0.05, 1.95, 3)
    scene = quads_scene(tmp_path, heights, entry=entry)
    worst = 0.0
    for k, y in enumerate(heights):
        img, _ = render_quad(tmp_path, scene, k, y, 81, (2.0, 2.0), *BRICKS)
        p = pixel_points(2.0, 2.0, 2.0, y, 81).reshape(-1, 3)
        want = 0.282094792 * linear(p)
        grad = 0.5 + 0.25 + 0.75  # |df/dx| + |df/dy| + |df/dz|
        step = 2.0 * 0.5 / 256  # level 1 texel (1 m) / 256: the coarse leaves' bricks
        bound = 0.282094792 * (2 * HALF_EPS * linear(p) + grad * step) + 1e-6
        err = np.abs(img.reshape(-1, 3) - want[:, None]).max(axis=1)
        assert (err <= bound).all(), (err.max(), bound.min())
        worst = max(worst, (err / want).max())
    print(f"linear field: max relative error {worst:.3g}")


def test_no_seam_across_a_coarse_fine_border(tmp_path):
    # The octree's x = 2 m face: 0.5 m leaves (level 0 bricks) on one side, 1 m leaves (level 1) on the
    # other. On a quad through it, the jump between the two pixel columns either side of the border equals
    # the model's (the field's own slope over one pixel) to the fp16/8-bit tolerance: no seam.
    tree = octree()
    coeffs = random_sh(tree.probe_count, 21)
    entry = write_grid_v3(tmp_path, tree, coeffs)
    size = 64  # even: the border x = 2 falls between columns 31 and 32 (camera centred at x = 2)
    y = 0.73
    scene = quads_scene(tmp_path, [y], entry=entry)
    img, _ = render_quad(tmp_path, scene, 0, y, size, (2.0, 2.0), *BRICKS)
    p = pixel_points(2.0, 2.0, 2.0, y, size)
    assert p[0, 31, 0] < 2.0 < p[0, 32, 0]
    rows = (p[:, 0, 2] > 1.0) & (p[:, 0, 2] < 2.0)  # z in the fine child's range: leaves of 0.5 m meet 1 m
    bricks = native.Bricks.build(tree, f32(coeffs))
    up = np.tile([0.0, 1.0, 0.0], (size, 1))
    jumps, model_jumps = [], []
    for i in np.flatnonzero(rows):
        m, has = brick_model(bricks, p[i, 30:34])
        assert has.all()
        e = e_of(m, up[:4])
        jumps.append(img[i, 32] - img[i, 31])
        model_jumps.append(e[2] - e[1])
    jumps, model_jumps = np.array(jumps), np.array(model_jumps)
    peak = img[rows].max()
    assert np.abs(jumps - model_jumps).max() < 2e-3 * peak, np.abs(jumps - model_jumps).max()
    # and the jump is no larger than the neighbouring columns' steps inside either leaf (+ tolerance).
    inner = np.maximum(np.abs(img[rows, 31] - img[rows, 30]), np.abs(img[rows, 33] - img[rows, 32])).max(axis=1)
    assert (np.abs(jumps).max(axis=1) <= 2.5 * inner + 2e-3 * peak).all()


def test_values_beyond_half_use_a_float32_pool(tmp_path):
    # Coefficients past 65504: the pool falls back to RGBA32F with a warning, and the pixels equal the
    # float64 C within fp32 (the exact-weight model without binary16 rounding; a 2^-8 weight step).
    tree, coeffs, entry = tree_and_entry(tmp_path, "octree", lambda t: random_sh(t.probe_count, 5) * 4e4)
    y = 1.1
    scene = quads_scene(tmp_path, [y], entry=entry)
    img, proc = render_quad(tmp_path, scene, 0, y, 49, (2.0, 2.0), *BRICKS)
    assert "the pool is RGBA32F" in proc.stderr and "RGBA32F" in proc.stderr
    p = pixel_points(2.0, 2.0, 2.0, y, 49).reshape(-1, 3)
    bricks = native.Bricks.build(tree, f32(coeffs))
    up = np.tile([0.0, 1.0, 0.0], (len(p), 1))
    want = e_of(brick_model(bricks, p, f16=False)[0], up)
    want8 = e_of(brick_model(bricks, p, bits=8, f16=False)[0], up)
    err = np.abs(img.reshape(-1, 3) - want).max(axis=1)
    assert (err <= 2 * np.abs(want8 - want).max(axis=1) + 1e-5 * want.max()).all(), err.max()


def test_oversized_and_bad_options_are_clear_errors(tmp_path):
    # One leaf of 2^13 min cells per axis: its indirection alone would take 2048^3 x 16 B = 128 GiB; the
    # core refuses past its 1 GiB cap and the engine says so (exit 1), where the buffers path renders.
    t = native.CornerOctree.uniform((0.0, 0.0, 0.0), 4.0 / 8192, 13, (1, 1, 1))
    t.finalize()
    entry = write_grid_v3(tmp_path, t, random_sh(t.probe_count, 1))
    scene = quads_scene(tmp_path, [1.0], entry=entry)
    proc = viewer.run(scene, "--headless", "--output", tmp_path / "o.exr", "--width", 16, "--height", 16,
                      "--move", "Quad0", 2.0, 1.0, 2.0, *BRICKS)
    assert proc.returncode != 0 and proc.returncode != 3, proc.stderr
    assert "--probe-path bricks" in proc.stderr and "use --probe-path buffers" not in proc.stdout
    assert "GiB" in proc.stderr or "bytes" in proc.stderr or "large" in proc.stderr, proc.stderr
    assert "Segmentation" not in proc.stderr
    viewer.check(viewer.run(scene, "--headless", "--output", tmp_path / "b.exr", "--width", 16, "--height", 16,
                            "--move", "Quad0", 2.0, 1.0, 2.0, "--probe-path", "buffers"))
    # The default path (no --probe-path): the same message as a warning, then the buffers' frame.
    d = viewer.check(viewer.run(scene, "--headless", "--output", tmp_path / "d.exr", "--width", 16, "--height", 16,
                                "--move", "Quad0", 2.0, 1.0, 2.0))
    assert "warning: --probe-path bricks: shProbeGrids[0]" in d.stderr, d.stderr
    assert "probe bricks unavailable (above); per-pixel probes from the storage buffers" in d.stderr
    assert np.array_equal(viewer.read_image(tmp_path / "d.exr"), viewer.read_image(tmp_path / "b.exr"))
    bad = viewer.run(scene, "--headless", "--output", tmp_path / "x.exr", "--probe-path", "textures")
    assert bad.returncode == 2 and "bad value 'textures' for --probe-path" in bad.stderr
    usage = viewer.run("--help", validation=False)
    assert "--probe-path buffers|bricks" in usage.stdout + usage.stderr


def test_pool_beyond_the_device_3d_limit_is_a_clear_error(tmp_path):
    # 44 one-brick L4 grids: each adds a 5-texel layer to every channel group's slab, and L4 has 19 groups
    # (76 channels), so the pool is 5 x 5 x 19 * 220 = 4180 texels deep, past lavapipe's
    # maxImageDimension3D of 4096: a clear error naming the size and the limit (exit 1), no crash; the
    # buffers path renders the same scene.
    (tmp_path / "sh_coeffs").mkdir()
    entries = []
    for g in range(44):
        t = native.CornerOctree.uniform((0.0, 0.0, 0.0), 0.5, 2, (1, 1, 1))
        t.finalize()
        c = np.zeros((t.probe_count, 25, 3))
        c[:, 0] = 1.0 + 0.01 * g
        path = tmp_path / "sh_coeffs" / f"g{g}.shprobe"
        n = native.write_shprobe_v3(str(path), t, c)
        f = native.read_shprobe(str(path))
        e = sg.grid_entry(f"g{g}", f"sh_coeffs/g{g}.shprobe", n, f.grid_origin, f.grid_dims, f.grid_spacing)
        e.update(representation=f.representation, storage=f.storage, structure=f.structure, maxBand=4)
        entries.append(e)
    b = sg.GltfBuilder()
    m = b.material("White", sh_scale=1.0, ambient_term=0.0, probe_mode="pixel")
    b.node("Quad", mesh=b.mesh("quad", sg.quad(2.0, 2.0, 1), m), translation=(1.0, 1.0, 1.0))
    b.node("Camera", camera=b.ortho_camera("top", 1.0), translation=(1.0, 3.0, 1.0), rotation=sg.ROT_LOOK_DOWN)
    b.probe_grids(entries)
    scene = b.write(tmp_path / "many.gltf")
    args = ["--headless", "--output", tmp_path / "o.exr", "--width", 16, "--height", 16]
    proc = viewer.run(scene, *args, *BRICKS)
    assert proc.returncode == 1, (proc.returncode, proc.stderr)
    assert "the brick pool needs a 5 x 5 x 4180 3D texture, beyond the device's limit" in proc.stderr, proc.stderr
    assert "use --probe-path buffers" in proc.stderr
    viewer.check(viewer.run(scene, *args[:2], tmp_path / "b.exr", *args[3:], "--probe-path", "buffers"))
    # The default path: a warning, the storage buffers, the same frame as --probe-path buffers.
    d = viewer.check(viewer.run(scene, *args[:2], tmp_path / "d.exr", *args[3:]))
    assert "warning: --probe-path bricks: the brick pool needs a 5 x 5 x 4180 3D texture" in d.stderr, d.stderr
    assert "probe bricks unavailable (above); per-pixel probes from the storage buffers" in d.stderr
    assert np.array_equal(viewer.read_image(tmp_path / "d.exr"), viewer.read_image(tmp_path / "b.exr"))


def test_unrolled_and_plain_shader_loops_shade_alike(tmp_path):
    # docs/engine.md "Probe bricks": a GPU gets mesh.frag built with SV_UNROLL_GROUPS (the channel-group loops
    # unrolled to a constant bound), a CPU device such as lavapipe the plain loops (--shader-loops auto); the
    # tests above compare the plain build with the C. The unrolled build must shade the same: the generated
    # benchmark room's v1 grid (the dense-grid texture's one-tap and 8-tap sums) and its v3 octree (the bricks'
    # one tap, 8 taps, back faces and visibility records), per pixel. Same arithmetic in the same order: equal
    # to float32 rounding (1e-6 relative to the frame's peak).
    import sys
    sys.path.insert(0, str(viewer.REPO / "tests" / "engine" / "scripts"))
    sys.path.insert(0, str(viewer.REPO / "bench"))
    import bench_engine_v3
    import make_room
    room = make_room.main(tmp_path / "room")
    v3 = bench_engine_v3.octree_scene(room)[0]
    for scene in (room, v3):
        imgs = {}
        for loops in ("plain", "unrolled", "auto") if scene == room else ("plain", "unrolled"):
            out = tmp_path / f"{scene.stem}-{loops}.exr"
            proc = viewer.check(viewer.run(scene, "--headless", "--output", out, "--width", 160, "--height", 90,
                                           "--probe-mode", "pixel", "--no-direct", "--shader-loops", loops))
            want = "plain" if loops == "auto" else loops  # lavapipe is a CPU device
            assert f"; shader loops {want}" in proc.stderr, proc.stderr
            imgs[loops] = viewer.read_image(out)[..., :3]
        peak = imgs["plain"].max()
        assert peak > 0.01
        assert np.abs(imgs["unrolled"] - imgs["plain"]).max() <= 1e-6 * peak
        if "auto" in imgs:
            assert np.array_equal(imgs["auto"], imgs["plain"])
    bad = viewer.run(room, "--headless", "--output", tmp_path / "x.exr", "--shader-loops", "fast")
    assert bad.returncode == 2 and "bad value 'fast' for --shader-loops" in bad.stderr
