"""Shadow maps (directional, spot and point lights) and the "mixed" light mode (docs/engine.md
"Shadows" and "Lights: baked, mixed or realtime").

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

Spot and point lights (perspective maps, the second half of this file) use the same plane, box and
probe with the lamp above the box: the expected direct term is probe_ref.point_light_direct (the
"Shading" formula with 1/d² and the spot cone), the shadow is the segment test from the plane point
to the lamp's position against the box, i.e. the box's silhouette projected from the lamp onto the
plane. A closed room of six walls around a point lamp, each wall seen by its own orthographic camera,
puts a shadow on every cube face.

Pixels within EDGE px of the analytic shadow boundary, or of the box's footprint on the screen, are
not compared (the normal offset, the 3x3 PCF and the texel size blur the edge by < 1 px here).
"""
import json
import sys
from collections import namedtuple
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
    """Quaternion (x, y, z, w) turning the node's -Z (a glTF light's or camera's direction) into unit d
    (the shortest arc; half a turn about +Y for d = +Z)."""
    a, d = np.array([0.0, 0.0, -1.0]), unit(d)
    if 1.0 + a @ d < 1e-9:
        return np.array([0.0, 1.0, 0.0, 0.0])
    q = np.append(np.cross(a, d), 1.0 + a @ d)
    return q / np.linalg.norm(q)


def rotate(q, v):
    """v rotated by the unit quaternion q = (x, y, z, w)."""
    u, w = np.asarray(q[:3], float), q[3]
    return v + 2.0 * np.cross(u, np.cross(u, v) + w * np.asarray(v, float))


def plane_points():
    """World point on the plane (y = 0) under each pixel centre of the orthographic camera at CAM
    looking down (camera up = world -Z: image row 0 at z = -YMAG, column 0 at x = -YMAG)."""
    i, j = np.meshgrid(np.arange(W) + 0.5, np.arange(H) + 0.5)
    x = (2 * i / W - 1) * YMAG
    z = (2 * j / H - 1) * YMAG
    return np.stack([x, np.zeros_like(x), z], axis=-1)


def box_hit(p, toward_light, lo=BOX_CENTER - BOX_HALF, hi=BOX_CENTER + BOX_HALF, t_end=np.inf):
    """Whether the ray p + t·toward_light (0 < t <= t_end) hits the box [lo, hi] (slab test), per
    point. A box may be flat (a wall: lo = hi on one axis)."""
    with np.errstate(divide="ignore", invalid="ignore"):
        inv = 1.0 / toward_light
        t0, t1 = (lo - p) * inv, (hi - p) * inv
    # a ray parallel to a slab: inside it (NaN from 0·inf) -> no limit; outside -> +-inf, a miss
    t0, t1 = np.where(np.isnan(t0), -np.inf, t0), np.where(np.isnan(t1), np.inf, t1)
    tmin = np.minimum(t0, t1).max(-1)
    tmax = np.maximum(t0, t1).min(-1)
    return (tmax >= np.maximum(tmin, 0.0)) & (tmin <= t_end)


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


def sun_direct(p, n, d, lux=SUN_LUX, cam=CAM):
    """docs/engine.md "Shading", a directional light of illuminance `lux` pointing along d on a
    metallic 0, roughness 1 surface seen from `cam`: (base/π + 0.04·9/(8π)·(n·h))·E·(n·l)."""
    l = -unit(d)
    v = np.asarray(cam, float) - p
    v /= np.linalg.norm(v, axis=-1, keepdims=True)
    h = l + v
    h /= np.linalg.norm(h, axis=-1, keepdims=True)
    nl = np.maximum(n @ l, 0.0)
    spec = 0.04 * 9.0 / (8.0 * np.pi) * np.maximum((n * h).sum(-1), 0.0)
    return (ALBEDO / np.pi + spec[..., None]) * lux * nl[..., None]


def write_scene(path, suns, box=True, lamps=(), walls=(), builder=None):
    """Plane (+ box), the probe grid, the camera and one directional light per entry of `suns`:
    (direction, mode), mode None = no VULKAN_SCHNEE_light extension; then one light per Lamp of
    `lamps` and one quad per (name, size_u, size_v, normal_axis, translation) of `walls`.
    `builder(b, material)` adds further nodes."""
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
    for lamp in lamps:
        light = b.light(lamp.name, lamp.type, (1, 1, 1), lamp.intensity, schnee_mode=lamp.mode,
                        cone=lamp.cone if lamp.type == "spot" else None)
        b.light_node(f"{lamp.name}Node", light, translation=lamp.pos, rotation=rotation_to(lamp.axis))
    for name, su, sv, axis, translation in walls:
        b.node(name, mesh=b.mesh(name, sg.quad(su, sv, normal_axis=axis), m), translation=translation)
    if builder is not None:
        builder(b, m)
    b.probe_grids([sg.grid_entry("probes", "sh_coeffs/probes.shprobe", 1, (-6, -1, -6), (1, 1, 1), 12.0)])
    return b.write(path)


def render(tmp_path, tag, suns, *args, box=True, lamps=(), walls=()):
    gltf = write_scene(tmp_path / f"{tag}.gltf", suns, box=box, lamps=lamps, walls=walls)
    return render_file(gltf, tmp_path / f"{tag}.exr", *args)[0]


def render_file(gltf, out, *args, size=(W, H)):
    """Renders gltf headless to the EXR `out` (validation on); returns (image RGB, stderr)."""
    proc = viewer.check(viewer.run(gltf, "--headless", "--output", out, "--width", size[0], "--height", size[1],
                                   *args))
    return viewer.read_image(out)[..., :3], proc.stderr


def assert_close(img, expected, mask, what):
    # The plane's normal is exact and its positions are interpolated on a 2-triangle quad: the
    # measured error on lavapipe is float rounding (max 1.9e-7 absolute, lit or shadowed, at every
    # sun direction tested; 3.4e-6 under the lamps, whose 1/d² and cone terms are evaluated in
    # float). Bound: 2e-5 absolute + 1e-4 relative; the smallest effect checked (the sun's direct
    # term, or a fifth of it) is > 0.08 here: a shadow wrongly cast or missed, acne or a direct term
    # wrongly added is off by that much (under a lamp, where the direct term fades, one ninth of it
    # still exceeds the bound wherever it is above 2e-4).
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


@pytest.fixture(scope="module")
def mixed_sun(tmp_path_factory):
    """The plane and box under the mixed sun SUN_DIR, rendered once for the two tests that check it
    (against the analytic shadow, and as what realtime and extension-less suns must equal)."""
    return render(tmp_path_factory.mktemp("mixed"), "mixed", [(SUN_DIR, "mixed")])


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


def assert_shadowed(img, base, lit, shadow, plane, what, edge=EDGE):
    """The analytic shadow `shadow` (a mask) on the `plane` pixels: inside it the image equals `base`,
    outside `lit` (pixels within `edge` px of its boundary excluded); the rendered shadow (pixels
    darker than halfway between the two, where the light adds > 0.05 in green) differs from the
    analytic one only within 1 px of the edge (`edge` px for a coarse map), by at most half that
    band's count."""
    band = edge_band(shadow, edge)
    inside, outside = plane & shadow & ~band, plane & ~shadow & ~band
    assert_close(img, base, inside, f"{what}: shadowed pixels (probe term only)")
    assert_close(img, lit, outside, f"{what}: lit pixels (probe + direct)")
    strong = plane & (lit[..., 1] - base[..., 1] > 0.05)
    rendered_shadow = strong & (img[..., 1] < 0.5 * (base[..., 1] + lit[..., 1]))
    analytic = strong & shadow
    near = edge_band(shadow, 1 if edge <= EDGE else edge)
    tolerance = (strong & near).sum() / 2
    assert abs(int(rendered_shadow.sum()) - int(analytic.sum())) <= tolerance, (
        what, rendered_shadow.sum(), analytic.sum(), tolerance)
    assert not ((rendered_shadow != analytic) & strong & ~near).any(), what
    return inside, outside


def test_mixed_sun_is_shadowed_by_the_box(tmp_path, geometry, mixed_sun):
    p, n, plane = geometry
    img = mixed_sun
    shadow = analytic_shadow(p, SUN_DIR)
    base = probe_term(n)
    # Shadowed pixel count: the rendered pixels darker than halfway between lit and shadowed, against
    # the analytic count; they may differ only within 1 px of the edge.
    inside, outside = assert_shadowed(img, base, base + sun_direct(p, n, SUN_DIR), shadow, plane, "mixed sun")
    assert inside.sum() > 400 and outside.sum() > 10000  # the shadow is well inside the view
    # The same image without the light (--no-direct) is the probe term everywhere on the plane.
    dark = render(tmp_path, "mixed_nodirect", [(SUN_DIR, "mixed")], "--no-direct")
    assert_close(dark, base, plane, "--no-direct")
    assert np.allclose(img[inside], dark[inside], atol=1e-5)


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


def test_baked_sun_adds_nothing_mixed_adds_its_shadowed_direct_term(tmp_path, geometry, mixed_sun):
    p, n, plane = geometry
    base = probe_term(n)
    baked = render(tmp_path, "baked", [(SUN_DIR, "baked")])
    assert_close(baked, base, plane, "baked sun on probe-lit surfaces")
    mixed = mixed_sun
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


def azimuth(d, degrees):
    """d turned about +Y by `degrees`."""
    c, s = np.cos(np.radians(degrees)), np.sin(np.radians(degrees))
    return np.array([c * d[0] + s * d[2], d[1], -s * d[0] + c * d[2]])


def render_suns(tmp_path, tag, suns, *args):
    """Renders write_scene's plane and box under the directional lights `suns`, (direction, lux) each,
    all mixed; returns (image RGB, stderr)."""
    gltf = write_scene(tmp_path / f"{tag}.gltf", [(d, "mixed") for d, _ in suns])
    doc = json.loads(gltf.read_text())
    for light, (_, lux) in zip(doc["extensions"]["KHR_lights_punctual"]["lights"], suns):
        light["intensity"] = lux
    gltf.write_text(json.dumps(doc))
    return render_file(gltf, tmp_path / f"{tag}.exr", *args)


def assert_suns(img, p, n, plane, suns, shadowed, what, edge=EDGE):
    """Every `plane` pixel away from any sun's shadow edge equals the probe term plus each sun's
    direct term, left out where that sun is in `shadowed` and the box shades the pixel from it.
    Returns each sun's analytic shadow (masks)."""
    shadows = [analytic_shadow(p, d) for d, _ in suns]
    band = np.zeros_like(plane)
    expected = probe_term(n)
    for (d, lux), shadow, cast in zip(suns, shadows, shadowed):
        band |= edge_band(shadow, edge)
        expected = expected + sun_direct(p, n, d, lux) * (~(shadow & cast))[..., None]
    assert_close(img, expected, plane & ~band, what)
    return [plane & shadow & ~band for shadow in shadows]


def test_five_suns_are_all_shadowed(tmp_path, geometry):
    # Directional lights take layers from the same 16-layer pool as the lamps (docs/engine.md
    # "Shadows"): five suns, 72° apart in azimuth (each a fifth as bright), get five layers, and each
    # box shadow lacks exactly that sun's direct term; no warning.
    p, n, plane = geometry
    # Three cascades each: 15 of the 16 layers (four would need 20, see
    # test_five_suns_with_four_cascades_overflow_the_pool).
    suns = [(azimuth(SUN_DIR, 72 * k), SUN_LUX / 5) for k in range(5)]
    img, stderr = render_suns(tmp_path, "five", suns, "--shadow-cascades", 3)
    assert "unshadowed" not in stderr, stderr
    inside = assert_suns(img, p, n, plane, suns, [True] * 5, "five shadowed suns")
    assert all(m.sum() > 300 for m in inside), [m.sum() for m in inside]  # every shadow is in view


def test_sun_beyond_the_layer_pool_is_unshadowed(tmp_path, geometry):
    # Seventeen suns of one cascade each: the first 16 fill the 16 layers, the 17th does not fit (one
    # warning naming it, the format of a lamp's) and adds its full direct term inside the box's shadow
    # from it.
    p, n, plane = geometry
    suns = [(SUN_DIR, SUN_LUX / 16)] * 16 + [(azimuth(SUN_DIR, 150), SUN_LUX)]
    img, stderr = render_suns(tmp_path, "seventeen", suns, "--shadow-res", 512, "--shadow-cascades", 1)
    assert stderr.count("shadow map layer") == 1, stderr
    assert "light 'Sun16' needs 1 shadow map layer but only 0 of 16 are left; it is unshadowed" in stderr, stderr
    # 512 texels over the scene: a texel is about 2.8 cm, the edge blurs more than at 2048
    inside = assert_suns(img, p, n, plane, suns, [True] * 16 + [False], "16 shadowed suns + one unshadowed",
                         edge=EDGE + 1)
    assert inside[0].sum() > 300 and inside[16].sum() > 300, (inside[0].sum(), inside[16].sum())


@pytest.mark.parametrize("option,value", [("--shadow-res", v) for v in ("-1", "abc", "1.5", "100000", "")]
                         + [("--shadow-cascades", v) for v in ("0", "5", "-1", "abc", "1.5", "")])
def test_bad_shadow_option_is_a_usage_error(tmp_path, option, value):
    gltf = write_scene(tmp_path / "bad.gltf", [(SUN_DIR, "mixed")])
    out = tmp_path / "bad.exr"
    proc = viewer.run(gltf, "--headless", "--output", out, "--width", 16, "--height", 16, option, value)
    assert proc.returncode == 2, proc.stderr
    assert option in proc.stderr, proc.stderr
    assert not out.exists()


def test_five_suns_with_four_cascades_overflow_the_pool(tmp_path, geometry):
    # Four cascades each (the default): the first four suns take all 16 layers, the fifth has none
    # left (one warning naming it) and adds its full direct term inside the box's shadow from it.
    p, n, plane = geometry
    suns = [(azimuth(SUN_DIR, 72 * k), SUN_LUX / 5) for k in range(5)]
    img, stderr = render_suns(tmp_path, "five4", suns)
    assert stderr.count("shadow map layer") == 1, stderr
    assert "light 'Sun4' needs 4 shadow map layers but only 0 of 16 are left; it is unshadowed" in stderr, stderr
    inside = assert_suns(img, p, n, plane, suns, [True] * 4 + [False], "four shadowed suns + one unshadowed")
    assert all(m.sum() > 300 for m in inside), [m.sum() for m in inside]


def test_sun_gets_the_cascades_left_in_the_pool(tmp_path, geometry):
    # Six suns of three cascades: the first five take 15 layers, the sixth gets the one left (a
    # warning naming it: a single map over the whole scene) and is still shadowed. Every shadow is
    # right.
    p, n, plane = geometry
    suns = [(azimuth(SUN_DIR, 60 * k), SUN_LUX / 6) for k in range(6)]
    img, stderr = render_suns(tmp_path, "six", suns, "--shadow-cascades", 3)
    assert stderr.count("shadow map layer") == 1, stderr
    assert ("light 'Sun5' needs 3 shadow map layers (cascades) but only 1 of 16 are left; it gets 1 cascade\n"
            in stderr), stderr
    assert "unshadowed" not in stderr, stderr
    inside = assert_suns(img, p, n, plane, suns, [True] * 6, "six shadowed suns, the last with one cascade")
    assert all(m.sum() > 300 for m in inside), [m.sum() for m in inside]


# ---- cascades over a long view (perspective camera, --look) ---------------------------------------

LONG_W, LONG_H = 360, 240
LONG_EYE, LONG_AT = np.array([0.0, 8.0, 6.0]), np.array([0.0, 0.0, -24.0])
LONG_FOV = 0.8  # --look's vertical field of view
LONG_PLANE_X, LONG_PLANE_Z = (-10.0, 10.0), (-195.0, 5.0)  # a 20 m x 200 m plane at y = 0
LONG_SUN = unit([1.0, -1.0, 0.25])  # shadows fall beside the boxes (+x), a little towards the camera
# (lo, hi) of the boxes floating above the plane, larger with distance (each shadow stays many
# pixels across in its cascade); the first is the near box.
LONG_BOXES = [((-2.0, 0.6, -7.0), (0.0, 1.6, -5.0)),
              ((-3.5, 1.0, -19.0), (-0.5, 3.5, -15.0)),
              ((-5.0, 2.0, -48.0), (-1.0, 6.0, -40.0)),
              ((-7.0, 3.0, -110.0), (-1.0, 12.0, -80.0))]
CASCADE_LAMBDA = 0.9  # docs/engine.md "Shadows": the practical split's weight of the logarithmic split
LONG_RES = 1024


def write_long_scene(path, boxes=LONG_BOXES, sun=LONG_SUN):
    """The long plane, `boxes` (lo, hi) and one mixed sun; a one-cell probe grid holding everything."""
    d = Path(path).parent
    (d / "sh_coeffs").mkdir(exist_ok=True)
    origin, spacing = (-110.0, -10.0, -210.0), 220.0
    sg.write_shprobe_v1(d / "sh_coeffs" / "long.shprobe", COEFFS[None], np.zeros((1, 1, 1), np.int32), origin,
                        spacing)
    b = sg.GltfBuilder()
    m = b.material("ground", base_color=(*ALBEDO, 1), sh_scale=SH_SCALE, ambient_term=AMBIENT,
                   metallic=0.0, roughness=1.0)
    size = (LONG_PLANE_Z[1] - LONG_PLANE_Z[0], LONG_PLANE_X[1] - LONG_PLANE_X[0])  # quad: u along z, v along x
    b.node("Ground", mesh=b.mesh("ground", sg.quad(*size, normal_axis=1), m),
           translation=(np.mean(LONG_PLANE_X), 0.0, np.mean(LONG_PLANE_Z)))
    for k, (lo, hi) in enumerate(boxes):
        lo, hi = np.asarray(lo, float), np.asarray(hi, float)
        b.node(f"Box{k}", mesh=b.mesh(f"box{k}", sg.cube(0.5), m), translation=(lo + hi) / 2,
               scale=[float(x) for x in hi - lo])
    light = b.light("Sun", "directional", (1, 1, 1), SUN_LUX, schnee_mode="mixed")
    b.light_node("SunNode", light, translation=(0, 30, 0), rotation=rotation_to(sun))
    b.probe_grids([sg.grid_entry("long", "sh_coeffs/long.shprobe", 1, origin, (1, 1, 1), spacing)])
    return b.write(path)


def long_camera():
    """--look's camera: (forward, right, up) and the ray through each pixel centre (Vulkan: row 0 at
    the top)."""
    f = unit(LONG_AT - LONG_EYE)
    r = unit(np.cross(f, [0.0, 1.0, 0.0]))
    u = np.cross(r, f)
    t, aspect = np.tan(LONG_FOV / 2), LONG_W / LONG_H
    i, j = np.meshgrid(np.arange(LONG_W) + 0.5, np.arange(LONG_H) + 0.5)
    x, y = (2 * i / LONG_W - 1) * t * aspect, (1 - 2 * j / LONG_H) * t
    return f, r, u, f + x[..., None] * r + y[..., None] * u


def long_geometry(boxes=LONG_BOXES):
    """Plane point under each pixel (the plane's centre where the pixel misses it), its normal, and
    the pixels that see the plane (not a box, not beyond its edges), EDGE + 1 px away from any of
    those outlines."""
    _, _, _, ray = long_camera()
    with np.errstate(divide="ignore", invalid="ignore"):
        t = -LONG_EYE[1] / ray[..., 1]
    down = ray[..., 1] < 0
    p = np.where(down[..., None], LONG_EYE + np.where(down, t, 0.0)[..., None] * ray, [0.0, 0.0, -95.0])
    on = (down & (p[..., 0] > LONG_PLANE_X[0]) & (p[..., 0] < LONG_PLANE_X[1]) & (p[..., 2] > LONG_PLANE_Z[0])
          & (p[..., 2] < LONG_PLANE_Z[1]))
    eye = np.broadcast_to(LONG_EYE, ray.shape)
    for lo, hi in boxes:
        on &= ~box_hit(eye, ray, np.asarray(lo, float), np.asarray(hi, float))
    n = np.broadcast_to([0.0, 1.0, 0.0], p.shape).copy()
    return p, n, ~dilate(~on, EDGE + 1)


def long_shadow(p, boxes=LONG_BOXES, sun=LONG_SUN):
    hit = np.zeros(p.shape[:-1], bool)
    for lo, hi in boxes:
        hit |= box_hit(p, -unit(sun), np.asarray(lo, float), np.asarray(hi, float))
    return hit


def render_long(tmp_path, tag, *args, boxes=LONG_BOXES, sun=LONG_SUN, res=LONG_RES):
    gltf = write_long_scene(tmp_path / f"{tag}.gltf", boxes, sun)
    return render_file(gltf, tmp_path / f"{tag}.exr", "--look", *LONG_EYE, *LONG_AT, "--shadow-res", res, *args,
                       size=(LONG_W, LONG_H))[0]


def cascade_fit(count, res=LONG_RES, boxes=LONG_BOXES, sun=LONG_SUN):
    """The cascades of this view recomputed from docs/engine.md "Shadows": (split depths, light basis
    (x, y), per cascade (light-space centre (2,), half extent, texel)). The view's depth range over
    the scene bounds split by the practical scheme; the bounding sphere of each slice's 8 corners
    (centre = their mean), its radius rounded up to a power of 2^(1/4) plus room for 9 texels, at
    most the scene's own square (padded 1 % + 1 mm), kept inside it, centre snapped to texels. Count
    1: the single map over the scene."""
    lo = np.array([LONG_PLANE_X[0], 0.0, LONG_PLANE_Z[0]])
    hi = np.array([LONG_PLANE_X[1], 0.0, LONG_PLANE_Z[1]])
    for blo, bhi in boxes:
        lo, hi = np.minimum(lo, blo), np.maximum(hi, bhi)
    corners = np.array([[(lo, hi)[a][0], (lo, hi)[b][1], (lo, hi)[c][2]] for a in (0, 1) for b in (0, 1)
                        for c in (0, 1)])
    f = unit(sun)
    x = unit(np.cross(f, [1.0, 0, 0] if abs(f[1]) > 0.99 else [0, 1.0, 0]))
    y = np.cross(x, f)
    mn = np.array([(corners @ x).min(), (corners @ y).min()])
    mx = np.array([(corners @ x).max(), (corners @ y).max()])
    pad = 0.01 * (mx - mn) + 1e-3
    mn, mx = mn - pad, mx + pad
    scene_half = 0.5 * (mx - mn).max()
    fwd, r, u, _ = long_camera()
    d = (corners - LONG_EYE) @ fwd
    near, far = max(d.min(), 0.05), d.max()
    i = np.arange(count + 1) / count
    split = CASCADE_LAMBDA * near * (far / near) ** i + (1 - CASCADE_LAMBDA) * (near + (far - near) * i)
    if count == 1:
        return split, (x, y), [(0.5 * (mn + mx), scene_half, 2 * scene_half / res)]
    t, aspect = np.tan(LONG_FOV / 2), LONG_W / LONG_H
    cascades = []
    for k in range(count):
        cs = np.array([LONG_EYE + s * fwd + sx * s * t * aspect * r + sy * s * t * u
                       for s in split[k:k + 2] for sx in (-1, 1) for sy in (-1, 1)])
        centre = cs.mean(0)
        rad = np.linalg.norm(cs - centre, axis=1).max()
        h = min(2 ** (np.ceil(4 * np.log2(rad)) / 4) * (1 + 4 * 9 / res), scene_half)
        texel = 2 * h / res
        c = np.array([centre @ x, centre @ y])
        c = np.where(mn + h <= mx - h, np.clip(c, mn + h, mx - h), 0.5 * (mn + mx))
        cascades.append((np.round(c / texel) * texel, h, texel))
    return split, (x, y), cascades


def cascade_texel(p, count=4, res=LONG_RES, **kw):
    """Per point, the texel size of the cascade the shader picks: the first whose box holds the point
    SV_SHADOW_CASCADE_MARGIN = 8 texels inside its edge, else the last; here with 10 texels, so that
    float rounding can only make the test's choice coarser than the shader's."""
    _, (x, y), cascades = cascade_fit(count, res, **kw)
    xy = np.stack([p @ x, p @ y], -1)
    out = np.full(p.shape[:-1], cascades[-1][2])
    for c, h, texel in reversed(cascades[:-1]):
        inside = (np.abs(xy - c) <= h - 10 * texel).all(-1)
        out = np.where(inside, texel, out)
    return out


def world_edge_band(p, shadow_of, width):
    """Plane pixels whose point p lies within `width` (metres, per pixel) of the boundary of the
    analytic shadow `shadow_of(points)`: a point `width` away in one of 16 directions on the plane
    has the other state."""
    here = shadow_of(p)
    band = np.zeros_like(here)
    for a in np.linspace(0, 2 * np.pi, 16, endpoint=False):
        q = p + width[..., None] * np.array([np.cos(a), 0.0, np.sin(a)])
        band |= shadow_of(q) != here
    return band


def long_expected(p, n, sun=LONG_SUN):
    base = probe_term(n)
    return base, base + sun_direct(p, n, sun, cam=LONG_EYE)


def cascade_band_width(p, count=4, res=LONG_RES):
    """Per pixel, 8 texels of the cascade the shader picks there: the shadow edge moves by the normal
    offset along the plane (T (0.5 + 3 sin θ) tan θ = 2.7 T at θ = 45.9° here) and blurs over the
    PCF footprint (2 T / cos θ = 2.9 T either side): 5.6 T at most."""
    return 8.0 * cascade_texel(p, count, res)


def test_cascade_fit_reference():
    # The recomputed fit of this view: four slices of increasing depth from the camera's znear (the
    # tall far box's top corner of the scene bounds lies beside the camera) to the farthest corner,
    # texels growing with depth, the last no coarser than the single map's.
    split, _, cascades = cascade_fit(4)
    texels = [c[2] for c in cascades]
    single = cascade_fit(1)[2][0][2]
    assert split[0] == 0.05 and split[0] < split[1] < split[2] < split[3] < split[4] < 200, split
    assert all(a < b for a, b in zip(texels, texels[1:])), texels
    assert texels[0] < single / 5 and texels[-1] <= single * (1 + 1e-9), (texels, single)


def test_cascades_sharpen_the_near_shadow_and_keep_every_shadow_right(tmp_path):
    # A 200 m plane and four boxes at 6 to 100 m from the camera, one oblique sun. With the default 4
    # cascades every box's analytic shadow is right (probe term inside, probe + direct outside,
    # pixels within 8 of their cascade's texels of the boundary excluded); the near box's edge band
    # (pixels neither fully lit nor fully shadowed) is narrower than the single map's by the ratio of
    # their texels (the band's width is a fixed number of texels: offset + PCF), within a factor 2.5
    # for the pixel grid (the cascades' band is 1-2 px wide; measured 1.6: 123 against 670 pixels at
    # a texel ratio of 0.115).
    p, n, plane = long_geometry()
    base, lit = long_expected(p, n)
    shadows = [long_shadow(p, [box]) for box in LONG_BOXES]
    shadow = np.any(shadows, axis=0)
    img = render_long(tmp_path, "long4")
    band = world_edge_band(p, long_shadow, cascade_band_width(p))
    inside, outside = plane & shadow & ~band, plane & ~shadow & ~band
    assert_close(img, base, inside, "4 cascades: shadowed pixels (probe term only)")
    assert_close(img, lit, outside, "4 cascades: lit pixels (probe + direct)")
    for k, s in enumerate(shadows):  # every box's shadow is in view and checked
        assert (inside & s).sum() > 40, (k, (inside & s).sum())
    assert outside.sum() > 20000, outside.sum()

    one = render_long(tmp_path, "long1", "--shadow-cascades", 1)
    near = plane & dilate(shadows[0], 30) & ~dilate(np.any(shadows[1:], axis=0), 30)
    band4 = partial_pixels(img, base, lit, near).sum()
    band1 = partial_pixels(one, base, lit, near).sum()
    coarsest = cascade_texel(p[near]).max()  # the near box's shadow lies in cascades this fine or finer
    single = cascade_fit(1)[2][0][2]
    assert band1 > 400, band1  # a single map over 200 m: a wide, blurry edge
    assert coarsest / single < 0.12, (coarsest, single)
    assert band4 <= 2.5 * coarsest / single * band1, (band4, band1, coarsest, single)


def partial_pixels(img, base, lit, region):
    """Pixels of `region` that are neither fully lit nor fully shadowed: lit fraction in (0.02, 0.98)."""
    frac = (img[..., 1] - base[..., 1]) / (lit[..., 1] - base[..., 1])
    return region & (frac > 0.02) & (frac < 0.98)


def test_cascades_change_the_long_scene_and_one_cascade_is_the_whole_scene_map(tmp_path):
    # At a coarse --shadow-res 256 the long scene's shadow edges depend on every texel of the map: the
    # default 4 cascades give a different image from one map over the scene bounds. Both keep every
    # box's analytic shadow (test_cascades_sharpen_the_near_shadow_and_keep_every_shadow_right);
    # exactly one map, the pre-cascade behaviour, is checked against the analytic polygon with that
    # map's texel band by the sun tests above (--shadow-cascades 1).
    gltf = write_long_scene(tmp_path / "ref.gltf")
    args = ["--look", *LONG_EYE, *LONG_AT, "--shadow-res", 256]
    one = render_file(gltf, tmp_path / "one.exr", *args, "--shadow-cascades", 1, size=(96, 64))[0]
    four = render_file(gltf, tmp_path / "four.exr", *args, size=(96, 64))[0]
    assert (np.abs(four - one).max(-1) > 0.01).sum() > 20


@pytest.mark.parametrize("sun", [LONG_SUN, unit([0.3, -0.12, -1.0]), unit([-0.2, -1.0, 0.05])],
                         ids=["oblique", "grazing", "steep"])
def test_cascade_boundaries_leave_a_lit_plane_lit(tmp_path, sun):
    # No box: every plane pixel, across all four cascades and their boundaries, equals the unshadowed
    # formula (no seam, no acne where the shader switches cascades), also at 83° from the normal.
    p, n, plane = long_geometry(boxes=[])
    _, lit = long_expected(p, n, sun)
    img = render_long(tmp_path, "lit", boxes=[], sun=sun)
    assert_close(img, lit, plane, f"lit long plane, sun {sun}")
    used = np.unique(cascade_texel(p[plane], boxes=[], sun=sun))
    assert len(used) >= 3, used  # the plane in view spans three cascades or more


# ---- spot and point lights: perspective shadow maps ---------------------------------------------

Lamp = namedtuple("Lamp", "name type pos axis intensity mode cone", defaults=((0, -1, 0), 60.0, "mixed", None))
LAMP_POS = np.array([-1.2, 4.5, 0.4])  # above the box: its shadow lies on the plane beside it, in view
SPOT_AXIS = unit([0.35, -1.0, -0.12])  # the box's whole shadow lies within 25° of it
SPOT_CONE = (np.radians(30.0), np.radians(45.0))  # the cone's edge crosses the view
POINT = Lamp("Lamp", "point", LAMP_POS)
SPOT = Lamp("Spot", "spot", LAMP_POS, SPOT_AXIS, cone=SPOT_CONE)


def lamp_direct(p, n, lamp, cam=CAM):
    """docs/engine.md "Shading" for a point or spot lamp (probe_ref.point_light_direct)."""
    spot = (unit(lamp.axis), *lamp.cone) if lamp.type == "spot" else None
    return probe_ref.point_light_direct(p, n, cam, ALBEDO, lamp.pos, np.full(3, lamp.intensity), spot=spot)


def lamp_shadow(p, pos, boxes=((BOX_CENTER - BOX_HALF, BOX_CENTER + BOX_HALF),)):
    """Whether the segment from p to the lamp at pos crosses one of the boxes (lo, hi)."""
    hit = np.zeros(p.shape[:-1], bool)
    for lo, hi in boxes:
        hit |= box_hit(p, np.asarray(pos, float) - p, np.asarray(lo, float), np.asarray(hi, float), t_end=1.0)
    return hit


def test_lamp_reference_closed_form():
    # Straight below a point lamp 2 m up: n·l = n·h = 1, E = I/4 -> (albedo/π + 0.04·9/(8π))·I/4;
    # a spot pointing down adds the cone factor 1 on its axis and 0 beyond the outer angle.
    p, n = np.array([[0.0, 0.0, 0.0]]), np.array([[0.0, 1.0, 0.0]])
    lamp = Lamp("L", "point", (0.0, 2.0, 0.0), intensity=8.0)
    want = (ALBEDO / np.pi + 0.04 * 9 / (8 * np.pi)) * 2.0
    assert np.allclose(lamp_direct(p, n, lamp, cam=(0, 2, 0)), want, rtol=1e-12)
    spot = lamp._replace(type="spot", cone=(0.2, 0.4))
    assert np.allclose(lamp_direct(p, n, spot, cam=(0, 2, 0)), want, rtol=1e-12)
    assert np.allclose(lamp_direct(np.array([[1.0, 0.0, 0.0]]), n, spot), 0.0)  # atan(1/2) > 0.4
    # The segment test: below the box seen from a lamp above it is shadowed, beside it is not, and a
    # box beyond the lamp casts nothing.
    assert lamp_shadow(np.array([0.0, 0.0, 0.0]), (0, 4, 0))
    assert not lamp_shadow(np.array([3.0, 0.0, 0.0]), (0, 4, 0))
    assert not lamp_shadow(np.array([0.0, 0.0, 0.0]), (0, 1.2, 0))


@pytest.mark.parametrize("lamp", [SPOT, POINT], ids=["spot", "point"])
def test_lamp_is_shadowed_by_the_box(tmp_path, geometry, lamp):
    # The box's silhouette projected from the lamp onto the plane gets the probe term only; the
    # plane elsewhere the probe term plus the lamp's direct term (for the spot: zero beyond its cone).
    p, n, plane = geometry
    img = render(tmp_path, lamp.name, [], lamps=[lamp])
    shadow = lamp_shadow(p, lamp.pos)
    base = probe_term(n)
    lit = base + lamp_direct(p, n, lamp)
    inside, outside = assert_shadowed(img, base, lit, shadow, plane, lamp.name)
    assert inside.sum() > 1500 and outside.sum() > 10000  # a large shadow, well inside the view
    if lamp.type == "spot":  # the cone's edge is in view: some plane pixels get no direct term
        assert (plane & (lit[..., 1] - base[..., 1] < 1e-6)).sum() > 1000


@pytest.mark.parametrize("lamp", [
    Lamp("Low", "point", (0.3, 1.0, -0.2), intensity=4.0),
    Lamp("Oblique", "spot", (-3.5, 1.2, 0.5), (1.0, -0.35, 0.1), 30.0, cone=(0.5, 0.95)),
    Lamp("Wide", "spot", (-2.0, 1.0, 0.2), (0.5, -1.0, 0.1), 10.0, cone=(0.9, 1.3)),
], ids=["point-low", "spot-grazing", "spot-wide-as-cube"])
def test_no_acne_under_a_lamp(tmp_path, geometry, lamp):
    # Without the box every plane pixel is lit. The low point lamp (1 m up) sees the plane through
    # five cube faces at up to 80° from the normal, the grazing spot at up to 81°; the 74° spot is
    # wider than 60° and shadowed as a cube (docs/engine.md "Shadows").
    p, n, _ = geometry
    img = render(tmp_path, "acne_" + lamp.name, [], box=False, lamps=[lamp])
    lit = probe_term(n) + lamp_direct(p, n, lamp)
    assert_close(img, lit, np.ones((H, W), bool), f"lit plane under {lamp.name}")
    l = np.asarray(lamp.pos) - p
    l /= np.linalg.norm(l, axis=-1, keepdims=True)
    reached = lamp_direct(p, n, lamp)[..., 1] > 1e-3
    steepest = np.degrees(np.arccos(l[reached][:, 1].min()))
    assert steepest > 77, steepest  # grazing angles are checked


def test_mixed_point_lamp_does_not_light_through_a_wall(tmp_path, geometry):
    # A 3 m wall at x = 0.5 across the whole plane, the lamp 2 m on the other side at 1.5 m: every
    # plane pixel beyond the wall is in its shadow (the probe term only); without shadow maps
    # (--shadow-res 0) the lamp leaks through the wall.
    p, n, plane = geometry
    lamp = Lamp("Lamp", "point", (-1.5, 1.5, 0.3), intensity=20.0)
    wall = [("Wall", 3.0, PLANE_SIZE, 0, (0.5, 1.5, 0.0))]  # normal +X, 3 m along y, 10 m along z
    img = render(tmp_path, "wall", [], box=False, lamps=[lamp], walls=wall)
    shadow = lamp_shadow(p, lamp.pos, [((0.5, 0.0, -5.0), (0.5, 3.0, 5.0))])
    beyond = p[..., 0] > 0.5
    assert np.array_equal(shadow, beyond)  # the analytic shadow is the far side
    base = probe_term(n)
    lit = base + lamp_direct(p, n, lamp)
    inside, outside = assert_shadowed(img, base, lit, shadow, np.ones((H, W), bool), "lamp behind a wall")
    assert inside.sum() > 8000 and outside.sum() > 8000
    leak = render(tmp_path, "wall_off", [], "--shadow-res", 0, box=False, lamps=[lamp], walls=wall)
    assert_close(leak, lit, inside | outside, "--shadow-res 0: the lamp lights both sides")
    added = leak[inside][:, 1] - base[inside][:, 1]
    assert added.min() > 0.01 and added.mean() > 0.05, (added.min(), added.mean())


ROOM_C, ROOM_HALF = np.array([0.0, 3.0, 0.0]), 3.0  # a closed 6 m cube inside the probe grid
ROOM_LAMP = Lamp("RoomLamp", "point", ROOM_C + (0.2, -0.1, 0.15), intensity=20.0)
ROOM_MAG = 1.4  # each wall camera sees 2.8 m x 2.8 m of its wall
ROOM_W = 96


def room_faces():
    """(axis, sign, unit axis, a lateral offset) per cube face +X, -X, +Y, -Y, +Z, -Z."""
    for axis in range(3):
        for sign in (1.0, -1.0):
            e = np.zeros(3)
            e[axis] = sign
            u, v = np.roll(np.abs(e), 1), np.roll(np.abs(e), 2)
            yield axis, sign, e, 0.3 * u - 0.2 * sign * v


def room_occluder(e, lateral):
    """The 0.5 m cube between the lamp and the wall along e: 1.5 m from the lamp, shifted sideways."""
    c = ROOM_LAMP.pos + 1.5 * e + lateral
    return c - 0.25, c + 0.25


def test_point_lamp_shadows_on_every_wall_of_a_room(tmp_path):
    # Six walls around a point lamp, a small cube between the lamp and each wall: each wall (in a
    # different cube face of the lamp's map) shows the cube's silhouette projected from the lamp, and
    # is lit by the "Shading" formula elsewhere. Each wall is seen by an orthographic camera 0.8 m in
    # front of it, looking at it, behind the cubes (so no cube is in view).
    occluders, walls = [], []
    for axis, sign, e, lateral in room_faces():
        occluders.append(room_occluder(e, lateral))
        if (axis, sign) == (1, -1.0):
            continue  # the floor is write_scene's ground plane (y = 0)
        walls.append((f"Wall{axis}{'+' if sign > 0 else '-'}", 2 * ROOM_HALF, 2 * ROOM_HALF, axis,
                      ROOM_C + ROOM_HALF * e))

    def builder(b, m):
        for k, (lo, hi) in enumerate(occluders):
            b.node(f"Occluder{k}", mesh=b.mesh(f"occ{k}", sg.cube(0.25), m), translation=(lo + hi) / 2)
        for axis, sign, e, _ in room_faces():
            b.node(f"Cam{axis}{'+' if sign > 0 else '-'}", camera=b.ortho_camera(f"cam{axis}{sign}", ROOM_MAG),
                   translation=ROOM_C + 2.2 * e, rotation=rotation_to(e))

    gltf = write_scene(tmp_path / "room.gltf", [], box=False, lamps=[ROOM_LAMP], walls=walls, builder=builder)
    i, j = np.meshgrid(np.arange(ROOM_W) + 0.5, np.arange(ROOM_W) + 0.5)
    xc, yc = (2 * i / ROOM_W - 1) * ROOM_MAG, (1 - 2 * j / ROOM_W) * ROOM_MAG
    for axis, sign, e, lateral in room_faces():
        tag = f"{axis}{'+' if sign > 0 else '-'}"
        img, _ = render_file(gltf, tmp_path / f"room{tag}.exr", "--camera", f"Cam{tag}", size=(ROOM_W, ROOM_W))
        q = rotation_to(e)
        cam = ROOM_C + 2.2 * e
        right, up = rotate(q, np.array([1.0, 0, 0])), rotate(q, np.array([0, 1.0, 0]))
        p = cam + xc[..., None] * right + yc[..., None] * up + 0.8 * e  # on the wall
        n = np.broadcast_to(-e, p.shape).copy()
        shadow = lamp_shadow(p, ROOM_LAMP.pos, occluders)
        base = probe_term(n)
        lit = base + lamp_direct(p, n, ROOM_LAMP, cam=cam)
        d = p - ROOM_LAMP.pos
        assert (np.argmax(np.abs(d), -1) == axis).all()  # the whole view lies in this cube face
        inside, outside = assert_shadowed(img, base, lit, shadow, np.ones(p.shape[:-1], bool), f"wall {tag}")
        assert inside.sum() > 300 and outside.sum() > 3000, (tag, inside.sum(), outside.sum())


def test_layer_budget_overflow_warns_and_leaves_that_lamp_unshadowed(tmp_path, geometry):
    # Three point lamps (6 layers each) and a spot at the same place: the first two take 12 of the 16
    # layers, the third does not fit (one warning naming it) and stays unshadowed, the spot after it
    # still gets its layer. In the box's shadow only the third lamp's direct term remains.
    p, n, plane = geometry
    lamps = [POINT._replace(name=f"Lamp{k}", intensity=20.0) for k in range(3)]
    lamps.append(SPOT._replace(name="Spot3", intensity=20.0))
    gltf = write_scene(tmp_path / "budget.gltf", [], lamps=lamps)
    img, stderr = render_file(gltf, tmp_path / "budget.exr", "--shadow-res", 512)
    assert stderr.count("shadow map layer") == 1, stderr
    assert "'Lamp2'" in stderr and "unshadowed" in stderr, stderr
    base = probe_term(n)
    each = [lamp_direct(p, n, lamp) for lamp in lamps]
    shadow = lamp_shadow(p, LAMP_POS)
    band = edge_band(shadow, EDGE + 1)  # 512 texels: a texel is 2 cm at 5 m, the edge blurs more
    assert_close(img, base + each[2], plane & shadow & ~band, "in the shadow: the third lamp only")
    assert_close(img, base + sum(each), plane & ~shadow & ~band, "outside: all four lamps")


def test_shadow_res_0_leaves_lamps_unshadowed(tmp_path, geometry):
    p, n, plane = geometry
    img = render(tmp_path, "lamps_off", [], "--shadow-res", 0, lamps=[POINT, SPOT])
    lit = probe_term(n) + lamp_direct(p, n, POINT) + lamp_direct(p, n, SPOT)
    assert_close(img, lit, plane, "--shadow-res 0 with a point and a spot lamp")
    assert lamp_shadow(p, LAMP_POS)[plane].sum() > 1500  # the shadow region is checked too
