"""The brick view (schnee-view --probe-path bricks --probe-view, --brick-view cells|texels|validity;
docs/engine.md "Probe view", engine/src/sv_brick_view.h): one box per brick over its region
[r, r + 4 * 2^L) in its level's colour, and each brick's 125 texels as small spheres shaded with the
texel's N / D read from the pool (E(n) / pi, "no probe" magenta where D = 0, tinted where 0 < D < 1) or
coloured by D alone. Real lavapipe, Khronos validation layer on (viewer.run).

Expected values come from the C through the Python module and numpy, independently of the engine:
native.Bricks (the bricks' regions and levels, the float64 texels N and D that the engine's pool holds as
binary16), the camera's projection written out here from the view's definition (--look: a look-at
matrix with up +y, 0.8 rad vertical field of view), rays through the pixel centres against the exact
spheres, and DESIGN.md section 3's irradiance (probe_ref). Images are EXR: linear colours before tone
mapping, so the outline and validity colours are compared exactly and the texel shading to fp32 noise.
"""
import sys
from pathlib import Path

import numpy as np
import pytest

sys.path.insert(0, str(Path(__file__).parent / "scripts"))
import probe_ref as ref  # noqa: E402
import scenegen as sg  # noqa: E402
import viewer  # noqa: E402
from schnee_probes import native  # noqa: E402

BRICKS = ("--probe-path", "bricks")
YFOV = 0.8  # --look's vertical field of view (engine/src/sv_app.c)
# shaders/brick_view_colours.glsl: the colour of levels 0..5 (5 and up share the last).
LEVEL_COLOURS = np.array([[0.1, 0.8, 1.0], [0.3, 1.0, 0.2], [1.0, 0.55, 0.1], [1.0, 0.15, 0.5], [0.6, 0.35, 1.0],
                          [1.0, 1.0, 1.0]])
LEAF_OUTLINE = np.array([0.9, 0.75, 0.2])  # shaders/probe_outline.frag (the probe view's cell outlines)
# shaders/brick_view_colours.glsl
NONE = np.array([0.2, 0.2, 0.2])
NO_PROBE = np.array([1.0, 0.0, 1.0])
PARTIAL_TINT = np.array([1.0, 0.3, 0.3])
INVALID = np.array([1.0, 0.1, 0.0])
VALID = np.array([0.1, 1.0, 0.1])
TEXEL_RADIUS = 0.08  # shaders/sv_gpu_brick_view.h SV_BRICK_TEXEL_RADIUS, in texel spacings
H = 0.25  # min cell


def f32(a):
    return np.asarray(a, np.float64).astype(np.float32).astype(np.float64)


def tree_of_three_levels():
    """A 32 x 8 x 32 lattice of 0.25 m min cells, 4 x 1 x 4 roots of 8 min cells; root 0 split, its child
    at (4, 0, 4) split, and that one's child at (4, 0, 4) split to min cells: bricks of levels 0 (around
    the min-cell leaves), 1 (the other roots of the first 16 x 16 columns) and 2 (the other quadrants;
    their regions are 16 min cells tall, twice the lattice, so their upper texels lie outside every leaf)."""
    t = native.CornerOctree.uniform((0.0, 0.0, 0.0), H, 3, (4, 1, 4))
    for leaf in ([0, 0, 0, 3], [4, 0, 4, 2], [4, 0, 4, 1]):
        leaves = t.info()["leaves"]
        f = np.zeros(t.leaf_count, bool)
        f[np.flatnonzero((leaves == leaf).all(axis=1))] = True
        assert t.split(f) == 1
    t.finalize()
    return t


@pytest.fixture(scope="module")
def case(tmp_path_factory):
    """The tree, its file (random L2 SH, 30 % invalid probes, random scales), the scene (nothing else in
    view) and the C's bricks built from the file's float32 values, as the engine builds them."""
    d = tmp_path_factory.mktemp("brick_view")
    tree = tree_of_three_levels()
    rng = np.random.default_rng(11)
    P = tree.probe_count
    coeffs = rng.normal(0.0, 0.25, (P, 9, 3))
    coeffs[:, 0] = rng.uniform(1.5, 4.0, (P, 3))
    validity = (rng.uniform(size=P) > 0.3).astype(np.float32)
    scale = rng.uniform(0.5, 2.0, P)
    (d / "sh_coeffs").mkdir()
    path = d / "sh_coeffs" / "p.shprobe"
    count = native.write_shprobe_v3(str(path), tree, coeffs, validity=validity, probe_scale=scale)
    f = native.read_shprobe(str(path))
    entry = sg.grid_entry("p", "sh_coeffs/p.shprobe", count, f.grid_origin, f.grid_dims, f.grid_spacing)
    entry.update(representation=f.representation, storage=f.storage, structure=f.structure)
    b = sg.GltfBuilder()
    b.node("Far", mesh=b.mesh("far", sg.cube(0.01), b.material("m")), translation=(50, -50, 50))
    b.probe_grids([entry])
    scene = b.write(d / "view.gltf")
    bricks = native.Bricks.build(tree, f32(coeffs), validity=validity, scale=f32(scale))
    info = bricks.info()
    assert info["level_counts"] == {0: 8, 1: 3, 2: 3}, info["level_counts"]
    return dict(d=d, scene=scene, tree=tree, info=info, entry=entry, bricks=bricks)


def render(case, name, w, h, look, *args):
    out = case["d"] / f"{name}.exr"
    proc = viewer.check(viewer.run(case["scene"], "--headless", "--output", out, "--width", w, "--height", h,
                                   "--look", *look, *args))
    return viewer.read_image(out)[..., :3], proc


class Camera:
    """--look F A: world -> pixel (x right, y down, pixel centres at i + 0.5) and pixel-centre rays."""

    def __init__(self, look, w, h):
        self.eye, at = np.array(look[:3], float), np.array(look[3:], float)
        f = (at - self.eye) / np.linalg.norm(at - self.eye)
        s = np.cross(f, [0.0, 1.0, 0.0])
        s /= np.linalg.norm(s)
        self.s, self.u, self.f = s, np.cross(s, f), f
        self.w, self.h, self.F, self.aspect = w, h, 1.0 / np.tan(0.5 * YFOV), w / h

    def project(self, p):
        v = np.asarray(p, float) - self.eye
        depth = v @ self.f
        ndc_x = self.F / self.aspect * (v @ self.s) / depth
        ndc_y = -self.F * (v @ self.u) / depth
        return np.stack([(ndc_x + 1) * 0.5 * self.w, (ndc_y + 1) * 0.5 * self.h], -1), depth

    def ray(self, col, row):
        """Unit directions (M, 3) through pixel centres (col, row)."""
        ndc_x = 2 * (np.asarray(col) + 0.5) / self.w - 1
        ndc_y = 2 * (np.asarray(row) + 0.5) / self.h - 1
        d = (ndc_x * self.aspect / self.F)[:, None] * self.s - (ndc_y / self.F)[:, None] * self.u + self.f
        return d / np.linalg.norm(d, axis=1, keepdims=True)


def brick_boxes(info):
    """World corners (n, 8, 3) of every brick's region (corner bit 0 = +x, 1 = +y, 2 = +z) and levels (n,)."""
    reg = info["regions"].astype(float)
    edge = 4.0 * 2.0 ** reg[:, 3]
    bits = np.array([[(k >> a) & 1 for a in range(3)] for k in range(8)], float)
    corners = np.asarray(info["origin"]) + H * (reg[:, None, :3] + edge[:, None, None] * bits[None])
    return corners, reg[:, 3].astype(int)


EDGES = [(0, 1), (2, 3), (4, 5), (6, 7), (0, 2), (1, 3), (4, 6), (5, 7), (0, 4), (1, 5), (2, 6), (3, 7)]


def segment_distance(px, a, b):
    """Distance (M, K) of points px (M, 2) to segments a -> b (K, 2)."""
    ab = b - a
    t = np.clip(np.einsum("mkc,kc->mk", px[:, None] - a[None], ab) / np.maximum((ab * ab).sum(1), 1e-12), 0, 1)
    q = a[None] + t[..., None] * ab[None]
    return np.linalg.norm(px[:, None] - q, axis=-1)


def is_colour(img, c, tol=1e-6):
    return np.all(np.abs(img - c) < tol, axis=-1)


OUTLINE_LOOK = (12.0, 9.0, 14.0, 4.0, 1.0, 4.0)


def test_brick_boxes_are_drawn_at_the_projected_region_corners(case):
    # --brick-view cells: 14 boxes (8 of level 0, 3 of level 1, 3 of level 2) from a perspective camera;
    # every pixel in a level's colour lies on a projected edge of a box of that level, and every edge of
    # every box is drawn along its length in its level's colour.
    W, Hh = 480, 360
    cam = Camera(OUTLINE_LOOK, W, Hh)
    img, proc = render(case, "cells", W, Hh, OUTLINE_LOOK, *BRICKS, "--brick-view", "cells")
    assert "probe bricks: 14 bricks" in proc.stderr, proc.stderr
    corners, levels = brick_boxes(case["info"])
    pix, depth = cam.project(corners.reshape(-1, 3))
    assert (depth > 0).all()
    pix = pix.reshape(-1, 8, 2)
    assert (pix > 2).all() and (pix[..., 0] < W - 2).all() and (pix[..., 1] < Hh - 2).all()  # all in view
    segs = {L: (np.concatenate([pix[levels == L][:, [e[0] for e in EDGES]].reshape(-1, 2)]),
                np.concatenate([pix[levels == L][:, [e[1] for e in EDGES]].reshape(-1, 2)])) for L in (0, 1, 2)}
    rows, cols = np.mgrid[0:Hh, 0:W]
    centres = np.stack([cols + 0.5, rows + 0.5], -1).reshape(-1, 2)
    flat = img.reshape(-1, 3)
    drawn = {}
    for L in (0, 1, 2):
        on = is_colour(flat, LEVEL_COLOURS[L])
        drawn[L] = on.reshape(Hh, W)
        assert on.sum() > 300, (L, on.sum())
        # (a) no pixel of this colour away from this level's projected edges (a rasterised line's pixel
        #     centres lie within 1/sqrt(2) px of it).
        dist = segment_distance(centres[on], *segs[L]).min(axis=1)
        assert dist.max() < 0.75, (L, dist.max())
    # Nothing else in the image but the boxes and the probe spheres: no leaf outline of the bricked grid.
    assert not is_colour(flat, LEAF_OUTLINE).any()
    # (b) every edge drawn: samples every pixel along its middle 80 %, away from the probe spheres (radius
    #     0.1 min cell at the file's probes) and from crossings with edges of other levels, have a pixel of
    #     the box's colour within one pixel.
    probes = case["tree"].info()["positions"]
    sp, sd = cam.project(probes)
    sphere_r = 0.1 * H * cam.F * Hh / 2 / sd
    covered = []
    for i, (box, L) in enumerate(zip(pix, levels)):
        for a, b in EDGES:
            n = int(np.linalg.norm(box[b] - box[a])) + 1
            t = np.linspace(0.1, 0.9, max(n, 8))
            q = box[a] + t[:, None] * (box[b] - box[a])
            near_sphere = (np.linalg.norm(q[:, None] - sp[None], axis=-1) < sphere_r[None] + 2.0).any(axis=1)
            other = np.zeros(len(q), bool)
            for L2 in (0, 1, 2):
                if L2 != L:
                    other |= segment_distance(q, *segs[L2]).min(axis=1) < 2.0
            q = q[~near_sphere & ~other]
            if not len(q):
                continue
            c, r = np.floor(q[:, 0]).astype(int), np.floor(q[:, 1]).astype(int)
            hit = np.zeros(len(q), bool)
            for dr in (-1, 0, 1):
                for dc in (-1, 0, 1):
                    hit |= drawn[L][np.clip(r + dr, 0, Hh - 1), np.clip(c + dc, 0, W - 1)]
            covered.append(hit.mean())
            assert hit.mean() > 0.9, (i, L, a, b, hit.mean())
    assert len(covered) > 100
    print(f"cells: {len(covered)} edges checked, coverage min {min(covered):.3f}; pixels per level "
          f"{[int(drawn[L].sum()) for L in (0, 1, 2)]}")


def test_probe_view_without_bricks_is_unchanged(case):
    # The storage-buffer path: the probe view's leaf outlines, none of the brick colours; --brick-view
    # there warns and changes nothing. With bricks, --probe-view alone is the cells brick view.
    W, Hh = 160, 120
    buffers = ("--probe-path", "buffers")  # the bricks are the default (issue 30 item 4)
    plain, _ = render(case, "plain", W, Hh, OUTLINE_LOOK, "--probe-view", *buffers)
    warned, proc = render(case, "warned", W, Hh, OUTLINE_LOOK, "--brick-view", "texels", *buffers)
    assert "--brick-view needs --probe-path bricks" in proc.stderr
    assert np.array_equal(plain, warned)
    assert is_colour(plain, LEAF_OUTLINE).sum() > 100
    for c in LEVEL_COLOURS[:3]:
        assert not is_colour(plain, c).any()
    cells, _ = render(case, "cells_small", W, Hh, OUTLINE_LOOK, *BRICKS, "--brick-view", "cells")
    default, _ = render(case, "default_small", W, Hh, OUTLINE_LOOK, *BRICKS, "--probe-view")
    assert np.array_equal(cells, default)
    assert not is_colour(cells, LEAF_OUTLINE).any() and is_colour(cells, LEVEL_COLOURS[0]).sum() > 50
    bad = viewer.run(case["scene"], "--headless", "--output", case["d"] / "x.exr", "--brick-view", "probes")
    assert bad.returncode == 2 and "bad value 'probes' for --brick-view" in bad.stderr


def texel_spheres(info):
    """Every texel sphere: centres (n * 125, 3), radii, brick, texel index (i + 5j + 25k)."""
    reg = info["regions"].astype(float)
    n = len(reg)
    t = np.arange(125)
    ijk = np.stack([t % 5, (t // 5) % 5, t // 25], -1).astype(float)
    s = 2.0 ** reg[:, 3]
    lat = reg[:, None, :3] + s[:, None, None] * ijk[None]
    centres = np.asarray(info["origin"]) + H * lat.reshape(-1, 3)
    radii = np.repeat(TEXEL_RADIUS * s * H, 125)
    return centres, radii, np.repeat(np.arange(n), 125), np.tile(t, n)


def first_hits(cam, centres, radii):
    """Per pixel: the nearest sphere the pixel-centre ray meets (-1: none), how far inside its silhouette
    (closest approach / radius) and the hit point; from (pixel, sphere) pairs within each sphere's
    projected bounding box."""
    W, Hh = cam.w, cam.h
    pc, depth = cam.project(centres)
    rp = radii * cam.F * Hh / 2 / depth + 2
    pairs_p, pairs_s = [], []
    for k in range(len(centres)):
        c0, c1 = int(max(pc[k, 0] - rp[k], 0)), int(min(pc[k, 0] + rp[k], W - 1))
        r0, r1 = int(max(pc[k, 1] - rp[k], 0)), int(min(pc[k, 1] + rp[k], Hh - 1))
        if c1 < c0 or r1 < r0:
            continue
        rr, cc = np.mgrid[r0:r1 + 1, c0:c1 + 1]
        pairs_p.append((rr * W + cc).ravel())
        pairs_s.append(np.full(rr.size, k))
    pp, ss = np.concatenate(pairs_p), np.concatenate(pairs_s)
    d = cam.ray(pp % W, pp // W)
    oc = cam.eye - centres[ss]
    b = np.einsum("mc,mc->m", oc, d)
    disc = b * b - (np.einsum("mc,mc->m", oc, oc) - radii[ss] ** 2)
    hit = disc > 0
    pp, ss, d, b, disc = pp[hit], ss[hit], d[hit], b[hit], disc[hit]
    t = -b - np.sqrt(disc)
    order = np.lexsort((t, pp))
    pp, ss, t, d, disc = pp[order], ss[order], t[order], d[order], disc[order]
    first = np.r_[True, pp[1:] != pp[:-1]]
    # The second nearest sphere along the same ray (same centre and radius: a border texel two bricks
    # share, drawn by both): kept to accept either brick's value.
    idx = np.flatnonzero(first)
    nxt = idx + 1
    has_next = (nxt < len(pp)) & (pp[np.minimum(nxt, len(pp) - 1)] == pp[idx])
    same = has_next & (np.abs(t[np.minimum(nxt, len(pp) - 1)] - t[idx]) < 1e-9)
    pix, sph = pp[idx], ss[idx]
    alt = np.where(same, ss[np.minimum(nxt, len(pp) - 1)], sph)
    inside = np.sqrt(np.maximum(radii[sph] ** 2 - disc[idx], 0)) / radii[sph]  # closest approach / r
    hit_point = cam.eye + t[idx, None] * d[idx]
    return pix, sph, alt, inside, hit_point


def texel_colour(info, brick, texel, normals, f16=True):
    """E(n) / pi of the texel's N / D times the partial tint, NO_PROBE where D <= 0 (the shader's rule) and
    the texel's D; texels rounded to binary16 as pb_bricks_pool_f16 uploads them (f16) or float64."""
    tex = info["texels"].reshape(len(info["regions"]), 125, -1)[brick, texel]
    if f16:
        tex = tex.astype(np.float16).astype(np.float64)
    D = tex[:, 3]
    chans = [[k if c == 0 else 3 * c + 1 + k for k in range(3)] for c in range(9)]
    N = np.stack([tex[:, ch] for ch in chans], axis=1)  # (M, 9, 3)
    sh = N / np.where(D > 0, D, 1.0)[:, None, None]
    e = np.einsum("mi,i,mic->mc", ref.sh_basis_l2(normals), ref.A_L2, sh)
    col = np.maximum(e, 0) / np.pi * (PARTIAL_TINT + (1 - PARTIAL_TINT) * np.clip(D, 0, 1)[:, None])
    return np.where((D > 0)[:, None], col, NO_PROBE), D


TEXEL_LOOK = (3.6, 2.4, 3.9, 1.0, 0.6, 1.2)


@pytest.mark.parametrize("mode", ["texels", "validity"])
def test_texel_spheres_show_the_c_texels(case, mode):
    # --brick-view texels / validity, close to the min-cell leaves (level-0 bricks, with level-1 and 2
    # bricks behind): every pixel well inside a texel sphere (closest approach < 0.8 r) that no outline
    # covers equals the C's texel at that sphere: texels E(n) / pi at the exact sphere normal of the hit
    # (the shader intersects the pixel's ray with the true sphere), NO_PROBE where D = 0, the red tint where
    # 0 < D < 1; validity mix(INVALID, VALID, D) flat.
    W, Hh = 480, 360
    cam = Camera(TEXEL_LOOK, W, Hh)
    info = case["info"]
    img, _ = render(case, mode, W, Hh, TEXEL_LOOK, *BRICKS, "--brick-view", mode)
    centres, radii, brick, texel = texel_spheres(info)
    pix, sph, alt, inside, hit = first_hits(cam, centres, radii)
    flat = img.reshape(-1, 3)
    line = np.zeros(len(flat), bool)
    for c in LEVEL_COLOURS:
        line |= is_colour(flat, c)
    keep = (inside < 0.8) & ~line[pix]
    pix, sph, alt, hit = pix[keep], sph[keep], alt[keep], hit[keep]
    n = (hit - centres[sph]) / radii[sph, None]
    got = flat[pix]
    if mode == "texels":
        want, D = texel_colour(info, brick[sph], texel[sph], n)
        want_alt, _ = texel_colour(info, brick[alt], texel[alt], n)
        err = np.minimum(np.abs(got - want).max(axis=1), np.abs(got - want_alt).max(axis=1))
        lit = D > 0
        # Same binary16 texels on both sides: what remains is the shader's fp32 (the unprojected ray, the
        # normal, the SH sums), measured below 1e-5 of the value.
        bound = 2e-5 + 2e-5 * np.abs(want).max(axis=1)
        assert (err <= bound).all(), (err.max(), (err > bound).sum())
        # Against the C's float64 texels the binary16 rounding shows (N and D each within 2^-11 relative).
        want64, _ = texel_colour(info, brick[sph], texel[sph], n, f16=False)
        err64 = np.abs(got - want64).max(axis=1)
        print(f"texels: {len(pix)} pixels on {len(np.unique(sph))} spheres (no probe {int((~lit).sum())}, "
              f"partial {int(((D > 0) & (D < 1)).sum())}); max |GPU - C binary16| {err.max():.3g}, "
              f"max |GPU - C float64| {err64[lit].max():.3g} (peak {want[lit].max():.3g})")
        assert err64[lit].max() < 8 * 2.0 ** -11 * want[lit].max() + 1e-6
    else:
        tex = info["texels"].reshape(len(info["regions"]), 125, -1)
        D = tex[brick[sph], texel[sph], 3].astype(np.float16).astype(np.float64)
        want = np.where((D > 0)[:, None], INVALID + (VALID - INVALID) * np.clip(D, 0, 1)[:, None], NO_PROBE)
        err = np.abs(got - want).max(axis=1)
        print(f"validity: {len(pix)} pixels on {len(np.unique(sph))} spheres, max error {err.max():.3g}")
        assert err.max() < 1e-6
    # Every kind of texel is in the comparison: no probe (D = 0: invalid corners and texels above the
    # lattice), partly valid (0 < D < 1) and fully valid, each on many spheres.
    kinds = [D <= 0, (D > 0) & (D < 1), D >= 1]
    assert all(len(np.unique(sph[k])) >= 10 for k in kinds), [len(np.unique(sph[k])) for k in kinds]
    assert is_colour(got[D <= 0], NO_PROBE).all()


@pytest.mark.skipif(__import__("shutil").which("xvfb-run") is None, reason="xvfb-run not installed (apt: xvfb)")
def test_window_brick_view_matches_headless(case):
    # The window's swapchain frame of --brick-view texels (the push constants carry the swapchain's size for
    # the texels' pixel rays) equals the headless PNG within the window path's 2 / 255 (UNORM + shader sRGB).
    W, Hh = 160, 120
    shot, png = case["d"] / "window.png", case["d"] / "headless.png"
    args = ("--look", *TEXEL_LOOK, "--width", W, "--height", Hh, *BRICKS, "--brick-view", "texels")
    proc = viewer.check(viewer.run(case["scene"], "--frames", 2, "--screenshot", shot, *args, xvfb=True, timeout=180))
    assert "2 frame(s) presented" in proc.stderr
    viewer.check(viewer.run(case["scene"], "--headless", "--output", png, *args))
    a, b = viewer.read_image(shot), viewer.read_image(png)
    assert a.shape == b.shape == (Hh, W, 3)
    assert (a.max(axis=-1) > 0.1).mean() > 0.05  # spheres and boxes drawn
    assert np.abs(a - b).max() <= 2.0 / 255


@pytest.mark.parametrize("y", [0.3, 1.45])
def test_debug_views_show_the_brick_each_pixel_samples(case, y):
    # --debug brick-level / brick-validity on a movable 8 x 8 m quad at height y over the whole lattice, seen
    # from above (orthographic, pixel centres at known points): each pixel is the level colour of the brick
    # the C's pb_bricks_locate gives for its point, and the validity colour of D from the C's binary16
    # texels filtered at the C's brick-local x with exact weights (lavapipe filters with fp32 weights).
    size, mag, cx, cz = 129, 4.2, 4.0, 4.0
    b = sg.GltfBuilder()
    m = b.material("White", sh_scale=1.0, ambient_term=0.0, probe_mode="pixel")
    b.node("Quad", mesh=b.mesh("quad", sg.quad(2 * mag, 2 * mag, 1), m), translation=(20.0, 20.0, 20.0))
    b.node("Camera", camera=b.ortho_camera("top", mag), translation=(cx, 5.0, cz), rotation=sg.ROT_LOOK_DOWN)
    b.probe_grids([case["entry"]])
    scene = b.write(case["d"] / "quad.gltf")
    t = (2 * (np.arange(size) + 0.5) / size - 1) * mag
    X, Z = np.meshgrid(cx + t, cz + t)  # column -> +x, row -> +z
    p = np.stack([X, np.full_like(X, y), Z], axis=-1).reshape(-1, 3)
    info, bricks = case["info"], case["bricks"]
    _, _, found, brick, x = bricks.sample_raw(p)
    # Pixels whose point lies within 1e-4 min cells of a lattice plane may fall either side in fp32.
    u = (p - np.asarray(info["origin"])) / H
    clear = (np.abs(u - np.round(u)) > 1e-4).all(axis=1)
    imgs = {}
    for mode in ("brick-level", "brick-validity"):
        out = case["d"] / f"debug_{mode}_{y}.exr"
        viewer.check(viewer.run(scene, "--headless", "--output", out, "--width", size, "--height", size, "--move",
                                "Quad", cx, y, cz, *BRICKS, "--debug", mode))
        imgs[mode] = viewer.read_image(out)[..., :3].reshape(-1, 3)
    levels = info["regions"][np.maximum(brick, 0), 3]
    want = np.where(found[:, None], LEVEL_COLOURS[np.minimum(levels, 5)], NONE)
    got = imgs["brick-level"]
    assert found.mean() > 0.5 and (~found).sum() > 100  # the quad reaches past the lattice
    assert (np.abs(got - want).max(axis=1)[clear] < 1e-6).all()
    # D of the plain filtered sample: the C's binary16 texels, trilinear at the C's brick and x.
    tex = info["texels"].astype(np.float16).astype(np.float64)[..., 3]
    bb = np.maximum(brick, 0)
    k0 = np.minimum(np.floor(x), 3).astype(int)
    f = x - k0
    D = np.zeros(len(p))
    for c in range(8):
        o = [(c >> a) & 1 for a in range(3)]
        w = np.prod([f[:, a] if o[a] else 1 - f[:, a] for a in range(3)], axis=0)
        D += w * tex[bb, k0[:, 2] + o[2], k0[:, 1] + o[1], k0[:, 0] + o[0]]
    want = np.where((D > 0)[:, None], INVALID + (VALID - INVALID) * np.clip(D, 0, 1)[:, None], NO_PROBE)
    want = np.where(found[:, None], want, NONE)
    err = np.abs(imgs["brick-validity"] - want).max(axis=1)[clear]
    lv = {int(L): int((levels[found & clear] == L).sum()) for L in np.unique(levels[found & clear])}
    print(f"debug y={y}: {clear.sum()} pixels, levels {lv}, D in [{D[found].min():.3g}, {D[found].max():.3g}], "
          f"no probe {int((found & (D <= 0)).sum())}, validity max error {err.max():.3g}")
    assert len(lv) >= 2
    # fp32 filter weights (lavapipe) against exact ones: 1e-5 of D's range, times |VALID - INVALID| < 1.
    assert err.max() < 2e-5
