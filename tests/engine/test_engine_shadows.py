"""Directional shadow maps and the "mixed" light mode (docs/engine.md "Shadows" and "Lights: baked,
mixed or realtime").

A ground plane (10 m square at y = 0, diffuse: metallic 0, roughness 1) and a 1 m box floating above
it (bottom at y = 1.5) are lit by one known probe (a 1-cell grid holding both objects, so every
surface is probe-lit) and one directional light, seen by an orthographic camera looking straight
down, and rendered to EXR on lavapipe (real Vulkan, validation on). Expected values come from numpy,
independently of the shaders:

- the probe term albedo·(shScale·E(n)/π + ambientTerm) with E from probe_ref.irradiance (DESIGN.md §3);
- the direct term of docs/engine.md "Shading" for a directional light: [(1 − metallic)·base/π +
  F0·(s + 8)/(8π)·(n·h)^s]·E·(n·l), s = 1 at roughness 1, F0 = 0.04, v towards the camera position;
- the shadow: a plane point is in shadow exactly when the ray from it towards the light (−d) hits
  the box (slab test), which is the box's shadow polygon projected along d.

Pixels within EDGE px of the analytic shadow boundary, or of the box's footprint on the screen, are
not compared (the normal offset, the 3x3 PCF and the texel size blur the edge by < 1 px here).
"""
import sys
from pathlib import Path

import numpy as np
import pytest

sys.path.insert(0, str(Path(__file__).parent / "scripts"))
import probe_ref  # noqa: E402
import scenegen as sg  # noqa: E402
import viewer  # noqa: E402

W = H = 160
YMAG = 4.0  # orthographic half extent: the image spans x, z in [-4, 4] (5 cm pixels)
CAM = np.array([0.0, 10.0, 0.0])
ALBEDO = np.array([0.8, 0.7, 0.6])
SH_SCALE, AMBIENT = 0.8, 0.05
SUN_LUX = 3.0
SUN_DIR = np.array([1.0, -1.0, 0.4])  # where the light points (oblique: the shadow lies beside the box)
BOX_CENTER, BOX_HALF = np.array([0.0, 2.0, 0.0]), 0.5
PLANE_SIZE = 10.0
EDGE = 2  # px excluded on either side of every edge

COEFFS = np.zeros((9, 3))  # the probe's radiance SH (band 0..2), E(+Y) > 0
COEFFS[0] = [1.2, 1.0, 0.8]
COEFFS[2] = [0.3, 0.25, 0.2]  # Y_1,0 ~ y: brighter from above
COEFFS[6] = [-0.1, 0.05, 0.1]


def unit(v):
    v = np.asarray(v, float)
    return v / np.linalg.norm(v)


def rotation_to(d):
    """Quaternion (x, y, z, w) turning the node's -Z (a glTF light's direction) into unit d."""
    a, d = np.array([0.0, 0.0, -1.0]), unit(d)
    q = np.append(np.cross(a, d), 1.0 + a @ d)
    return q / np.linalg.norm(q)


def plane_points():
    """World point on the plane (y = 0) under each pixel centre of the orthographic camera at CAM
    looking down (camera up = world -Z: image row 0 at z = -YMAG, column 0 at x = -YMAG)."""
    i, j = np.meshgrid(np.arange(W) + 0.5, np.arange(H) + 0.5)
    x = (2 * i / W - 1) * YMAG
    z = (2 * j / H - 1) * YMAG
    return np.stack([x, np.zeros_like(x), z], axis=-1)


def box_hit(p, toward_light):
    """Whether the ray p + t·toward_light (t > 0) hits the box (slab test), per point."""
    lo, hi = BOX_CENTER - BOX_HALF, BOX_CENTER + BOX_HALF
    with np.errstate(divide="ignore", invalid="ignore"):
        inv = 1.0 / toward_light
        t0, t1 = (lo - p) * inv, (hi - p) * inv
    tmin = np.minimum(t0, t1).max(-1)
    tmax = np.maximum(t0, t1).min(-1)
    return (tmax >= np.maximum(tmin, 0.0))


def dilate(mask, r):
    """mask grown by r pixels (square window)."""
    out = np.zeros_like(mask)
    pad = np.pad(mask, r)
    for dy in range(2 * r + 1):
        for dx in range(2 * r + 1):
            out |= pad[dy:dy + mask.shape[0], dx:dx + mask.shape[1]]
    return out


def edge_band(mask, r):
    """Pixels within r px of the boundary of mask (either side)."""
    return dilate(mask, r) & dilate(~mask, r)


def probe_term(n):
    return ALBEDO * (SH_SCALE * np.maximum(probe_ref.irradiance(COEFFS, n), 0.0) / np.pi + AMBIENT)


def sun_direct(p, n, d, lux=SUN_LUX):
    """docs/engine.md "Shading", a directional light of illuminance `lux` pointing along d on a
    metallic 0, roughness 1 surface: (base/π + 0.04·9/(8π)·(n·h))·E·(n·l)."""
    l = -unit(d)
    v = CAM - p
    v /= np.linalg.norm(v, axis=-1, keepdims=True)
    h = l + v
    h /= np.linalg.norm(h, axis=-1, keepdims=True)
    nl = np.maximum(n @ l, 0.0)
    spec = 0.04 * 9.0 / (8.0 * np.pi) * np.maximum((n * h).sum(-1), 0.0)
    return (ALBEDO / np.pi + spec[..., None]) * lux * nl[..., None]


def write_scene(path, suns, box=True):
    """Plane (+ box), the probe grid, the camera and one directional light per entry of `suns`:
    (direction, mode), mode None = no VULKAN_SCHNEE_light extension."""
    d = Path(path).parent
    (d / "sh_coeffs").mkdir(exist_ok=True)
    sg.write_shprobe_v1(d / "sh_coeffs" / "probes.shprobe", COEFFS[None], np.zeros((1, 1, 1), np.int32),
                        (-6, -1, -6), 12.0)
    b = sg.GltfBuilder()
    m = b.material("ground", base_color=(*ALBEDO, 1), sh_scale=SH_SCALE, ambient_term=AMBIENT,
                   metallic=0.0, roughness=1.0)
    b.node("Ground", mesh=b.mesh("ground", sg.quad(PLANE_SIZE, PLANE_SIZE, normal_axis=1), m))
    if box:
        b.node("Box", mesh=b.mesh("box", sg.cube(BOX_HALF), m), translation=BOX_CENTER)
    b.node("Camera", camera=b.ortho_camera("cam", YMAG), translation=CAM, rotation=sg.ROT_LOOK_DOWN)
    for k, (direction, mode) in enumerate(suns):
        light = b.light(f"Sun{k}", "directional", (1, 1, 1), SUN_LUX, schnee_mode=mode)
        b.light_node(f"Sun{k}Node", light, translation=(0, 8, 0), rotation=rotation_to(direction))
    b.probe_grids([sg.grid_entry("probes", "sh_coeffs/probes.shprobe", 1, (-6, -1, -6), (1, 1, 1), 12.0)])
    return b.write(path)


def render(tmp_path, tag, suns, *args, box=True):
    gltf = write_scene(tmp_path / f"{tag}.gltf", suns, box=box)
    out = tmp_path / f"{tag}.exr"
    viewer.check(viewer.run(gltf, "--headless", "--output", out, "--width", W, "--height", H, *args))
    return viewer.read_image(out)[..., :3]


def assert_close(img, expected, mask, what):
    # The plane's normal is exact and its positions are interpolated on a 2-triangle quad: the
    # measured error on lavapipe is float rounding (max 1.9e-7 absolute, lit or shadowed, at every
    # sun direction tested). Bound: 2e-5 absolute + 1e-4 relative; the smallest effect checked (the
    # sun's direct term, or a fifth of it) is > 0.08 here: a shadow wrongly cast or missed, acne or
    # a direct term wrongly added is off by that much.
    err = np.abs(img[mask] - expected[mask])
    tol = 2e-5 + 1e-4 * np.abs(expected[mask])
    bad = (err > tol).any(-1)
    assert not bad.any(), f"{what}: {bad.sum()} of {mask.sum()} pixels off, max abs error {err.max():.4g}"


@pytest.fixture(scope="module")
def geometry():
    p = plane_points()
    n = np.broadcast_to([0.0, 1.0, 0.0], p.shape).copy()
    lo, hi = BOX_CENTER - BOX_HALF, BOX_CENTER + BOX_HALF
    footprint = (p[..., 0] >= lo[0]) & (p[..., 0] <= hi[0]) & (p[..., 2] >= lo[2]) & (p[..., 2] <= hi[2])
    plane = ~dilate(footprint, EDGE + 1)  # pixels that see the plane, away from the box's outline
    return p, n, plane


def analytic_shadow(p, d):
    return box_hit(p, -unit(d))


def test_reference_closed_form():
    # The numpy direct term against a hand-computed case: light straight down on the plane's
    # centre under the camera: n·l = n·h = 1 -> (albedo/π + 0.04·9/(8π))·E.
    p = np.array([[0.0, 0.0, 0.0]])
    got = sun_direct(p, np.array([[0.0, 1.0, 0.0]]), (0, -1, 0))
    assert np.allclose(got, (ALBEDO / np.pi + 0.04 * 9 / (8 * np.pi)) * SUN_LUX, rtol=1e-12)
    # The shadow test: a point straight below the box is shadowed by a vertical sun, one 1 m
    # beside its footprint is not; with SUN_DIR the shadow lies 1.5..2.5 m along +x from the box.
    assert analytic_shadow(np.array([0.0, 0.0, 0.0]), (0, -1, 0))
    assert not analytic_shadow(np.array([1.5, 0.0, 0.0]), (0, -1, 0))
    assert analytic_shadow(np.array([2.0, 0.0, 0.8]), SUN_DIR)


def test_mixed_sun_is_shadowed_by_the_box(tmp_path, geometry):
    p, n, plane = geometry
    img = render(tmp_path, "mixed", [(SUN_DIR, "mixed")])
    shadow = analytic_shadow(p, SUN_DIR)
    band = edge_band(shadow, EDGE)
    inside, outside = plane & shadow & ~band, plane & ~shadow & ~band
    assert inside.sum() > 400 and outside.sum() > 10000  # the shadow is well inside the view
    base = probe_term(n)
    assert_close(img, base, inside, "shadowed pixels (probe term only)")
    assert_close(img, base + sun_direct(p, n, SUN_DIR), outside, "lit pixels (probe + direct)")
    # The same image without the light (--no-direct) is the probe term everywhere on the plane.
    dark = render(tmp_path, "mixed_nodirect", [(SUN_DIR, "mixed")], "--no-direct")
    assert_close(dark, base, plane, "--no-direct")
    assert np.allclose(img[inside], dark[inside], atol=1e-5)

    # Shadowed pixel count: the rendered pixels darker than halfway between lit and shadowed, against
    # the analytic count; they may differ only within 1 px of the edge.
    lit = base + sun_direct(p, n, SUN_DIR)
    rendered_shadow = plane & (img[..., 1] < 0.5 * (base[..., 1] + lit[..., 1]))
    analytic = plane & shadow
    tolerance = (plane & edge_band(shadow, 1)).sum() / 2
    assert abs(int(rendered_shadow.sum()) - int(analytic.sum())) <= tolerance, (
        rendered_shadow.sum(), analytic.sum(), tolerance)
    # ... and every disagreement lies in that band.
    assert not ((rendered_shadow != analytic) & plane & ~edge_band(shadow, 1)).any()


@pytest.mark.parametrize("direction", [(1.0, -1.0, 0.4), (0.3, -0.25, -1.0), (0.05, -0.08, 1.0), (0.0, -1.0, 0.0)],
                         ids=["oblique", "grazing", "very-grazing", "vertical"])
def test_no_acne_on_a_lit_plane(tmp_path, geometry, direction):
    # Without the box every plane pixel is lit, also at 77° and 85° from the normal (grazing: the
    # normal offset grows with sin(theta) to cover the slope over the PCF footprint).
    p, n, _ = geometry
    img = render(tmp_path, "acne", [(direction, "realtime")], box=False)
    everywhere = np.ones((H, W), bool)
    assert_close(img, probe_term(n) + sun_direct(p, n, direction), everywhere, f"lit plane {direction}")


def test_vertical_sun_shadow_hides_under_the_box(tmp_path, geometry):
    # Straight down, the box's shadow is its own footprint: every plane pixel the camera sees is lit.
    p, n, plane = geometry
    img = render(tmp_path, "vertical", [((0, -1, 0), None)])
    assert_close(img, probe_term(n) + sun_direct(p, n, (0, -1, 0)), plane, "vertical sun")


def test_baked_sun_adds_nothing_mixed_adds_its_shadowed_direct_term(tmp_path, geometry):
    p, n, plane = geometry
    base = probe_term(n)
    baked = render(tmp_path, "baked", [(SUN_DIR, "baked")])
    assert_close(baked, base, plane, "baked sun on probe-lit surfaces")
    mixed = render(tmp_path, "mixed2", [(SUN_DIR, "mixed")])
    shadow = analytic_shadow(p, SUN_DIR)
    outside = plane & ~shadow & ~edge_band(shadow, EDGE)
    assert_close(mixed, base + sun_direct(p, n, SUN_DIR), outside, "mixed sun, lit")
    # realtime and no extension shadow the same way as mixed on these probe-lit surfaces
    assert np.array_equal(render(tmp_path, "realtime", [(SUN_DIR, "realtime")]), mixed)
    assert np.array_equal(render(tmp_path, "noext", [(SUN_DIR, None)]), mixed)


def test_shadow_res_0_gives_the_unshadowed_image(tmp_path, geometry):
    p, n, plane = geometry
    img = render(tmp_path, "off", [(SUN_DIR, "mixed")], "--shadow-res", 0)
    assert_close(img, probe_term(n) + sun_direct(p, n, SUN_DIR), plane, "--shadow-res 0")
    assert analytic_shadow(p, SUN_DIR)[plane].sum() > 400  # the shadow region is checked too


def test_more_than_four_suns_warn_once(tmp_path, geometry):
    # Five shadow-casting suns (each a fifth as bright): the first four are shadowed, the fifth is
    # not, with one warning. In the box's shadow 4/5 of the direct term is missing.
    p, n, plane = geometry
    suns = [(SUN_DIR, "mixed")] * 5
    gltf = write_scene(tmp_path / "five.gltf", suns)
    doc = __import__("json").loads(gltf.read_text())
    for light in doc["extensions"]["KHR_lights_punctual"]["lights"]:
        light["intensity"] = SUN_LUX / 5
    gltf.write_text(__import__("json").dumps(doc))
    out = tmp_path / "five.exr"
    proc = viewer.check(viewer.run(gltf, "--headless", "--output", out, "--width", W, "--height", H))
    assert proc.stderr.count("directional lights cast shadows") == 1, proc.stderr
    assert "'Sun4'" in proc.stderr, proc.stderr
    img = viewer.read_image(out)[..., :3]
    shadow = analytic_shadow(p, SUN_DIR)
    inside = plane & shadow & ~edge_band(shadow, EDGE)
    assert_close(img, probe_term(n) + sun_direct(p, n, SUN_DIR) / 5, inside, "fifth sun unshadowed")


@pytest.mark.parametrize("value", ["-1", "abc", "1.5", "100000", ""])
def test_bad_shadow_res_is_a_usage_error(tmp_path, value):
    gltf = write_scene(tmp_path / "bad.gltf", [(SUN_DIR, "mixed")])
    out = tmp_path / "bad.exr"
    proc = viewer.run(gltf, "--headless", "--output", out, "--width", 16, "--height", 16, "--shadow-res", value)
    assert proc.returncode == 2, proc.stderr
    assert "--shadow-res" in proc.stderr, proc.stderr
    assert not out.exists()
