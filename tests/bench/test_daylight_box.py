"""The daylight box of issue 27's benchmark (scenes/make_daylight_box.py, bench/bench_spheres.py
``--scene daylight``) is what the benchmark assumes: a sunlit patch on the floor exactly where the
sun's direction through the window puts it, in all three cases (a Sun lamp; sunrise.exr turned so
that its sun comes through the window; both), and six spheres in the beam, across its edge and in
shadow as their classes say.

Independent evidence: Cycles renders the floor from above (orthographic, 5 cm pixels, direct light
only) and Blender ray-casts from 200 points on each sphere towards the sun through its own geometry;
both are compared with the closed form ``sun_lit`` (a ray from the point must cross the window's
opening at the wall's inner and outer faces). Hand check of the closed form: the sun is 40 deg up,
15 deg east of +Y, so a ray rises tan 40 / cos 15 = 0.8687 m per metre of y; a floor point is lit
for 1.15 < 0.8687 (1.5 - y) (the sill at the inner face) and 0.8687 (1.7 - y) < 2.35 (the lintel
at the outer face): -1.005 < y < 0.176. sunrise.exr's sun was located by hand in the image
(texels at rows 278-279 from the bottom, columns 613-614 of 1024 x 512: 8.1 deg up, azimuth
-35.9 deg, DESIGN.md §3's mapping).
"""
import json
import math
import sys

import numpy as np
import pytest

from conftest import REPO

sys.path.insert(0, str(REPO / "scenes"))
import make_daylight_box as box  # noqa: E402

W, H = 80, 60      # daylight_box_check.py's floor image: 5 cm pixels, row 0 at y = +1.5


@pytest.fixture(scope="module")
def seen(tmp_path_factory):
    from conftest import run_blender
    out = tmp_path_factory.mktemp("daylight") / "check.json"
    run_blender(REPO / "tests" / "bench" / "daylight_box_check.py", out, *box.CASES, timeout=300)
    return json.loads(out.read_text())


def floor_lit(ox, oy):
    """Closed form at the point (ox, oy) inside each pixel (0..1, from the top-left corner)."""
    x = box.ROOM_MIN[0] + (np.arange(W) + ox) * 0.05
    y = box.ROOM_MAX[1] - (np.arange(H) + oy) * 0.05
    X, Y = np.meshgrid(x, y)
    return box.sun_lit_many(np.stack([X.ravel(), Y.ravel(), np.zeros(X.size)], 1)).reshape(H, W)


def test_closed_form_by_hand():
    # The floor patch's y limits derived in the docstring, at the patch's middle in x.
    for y, lit in ((0.17, True), (0.19, False), (-0.99, True), (-1.02, False)):
        x = -0.5                             # inside the window's x range after the 15 deg shift
        assert box.sun_lit((x, y, 0.0)) is lit, y
    assert abs(sum(c * c for c in box.TO_SUN) - 1.0) < 1e-12
    assert box.layout_problems() == []


@pytest.mark.parametrize("case", box.CASES)
def test_sunlit_floor_patch_where_the_closed_form_puts_it(seen, case):
    lum = np.array(seen[case]["floor"]) @ np.array([0.2126, 0.7152, 0.0722])
    centre = floor_lit(0.5, 0.5)
    corners = [floor_lit(a, b) for a in (0.0, 1.0) for b in (0.0, 1.0)]
    sure_lit = centre & np.all(corners, 0)            # the whole pixel in the sun by the closed form
    sure_dark = ~centre & ~np.any(corners, 0)
    assert sure_lit.sum() > 500                       # a patch of about 1.7 m^2 (683 pixels)
    med = np.median(lum[sure_lit])
    assert med > 0.3
    # Every whole pixel on the right side of the 50 % threshold: a sharp patch, in the right place.
    assert lum[sure_lit].min() > 0.5 * med
    assert lum[sure_dark].max() < 0.5 * med
    if case == "sun":
        assert lum[sure_dark].max() == 0.0            # black world: only the lamp's light enters


@pytest.mark.parametrize("case", box.CASES)
def test_spheres_in_sun_and_shadow_as_classified(seen, case):
    for name, centre, _cam, cls in box.SPHERES:
        cast = seen[case]["spheres"][name]
        blender_lit = np.array(cast["blender_lit"])
        assert np.array_equal(blender_lit, box.sun_lit_many(np.array(cast["points"]))), name
        frac = blender_lit.mean()
        if cls == "lit":
            assert frac == 1.0, name
        elif cls == "shadow":
            assert frac == 0.0, name
        else:
            assert 0.2 < frac < 0.8, name


def test_lights_world_and_volume(seen):
    assert seen["sun"]["lamps"] == ["SunLamp"] and seen["both"]["lamps"] == ["SunLamp"]
    assert seen["hdri"]["lamps"] == []
    assert seen["sun"]["mapping_rotation"] is None
    for case in ("hdri", "both"):
        d = seen[case]["hdri_sun"]
        assert math.degrees(math.asin(d[2])) == pytest.approx(8.1, abs=0.3)
        assert math.degrees(math.atan2(d[1], d[0])) == pytest.approx(-35.9, abs=0.3)
    for case in box.CASES:
        (lo, hi, loc), = seen[case]["volumes"]
        assert np.allclose(np.add(lo, loc), box.ROOM_MIN) and np.allclose(np.add(hi, loc), box.ROOM_MAX)
