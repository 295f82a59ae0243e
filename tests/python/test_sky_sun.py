"""The sky's sun split (native.sky_sun_split, native/src/pb_sky_sun.c) on Blender's eight bundled
HDRIs: which have a sun, and energy conservation against the image's exact projection.

Expected values are independent of the split: the exact projection is native.sky_table over the
whole sphere (each texel with its exact solid angle, the bake's world path, checked against Cycles
in tests/blender/test_direct_sky.py); the sun's projection is that of a Cycles Sun lamp of its
strength and angle (native.direct_project, checked against Cycles in
tests/blender/test_direct_light.py): rest + sun must give the image's projection. The synthetic
closed-form cases (a disc of known size, direction and radiance) are tests/native/test_sky_sun.c.
Runtime: ~7 s (one oiiotool run converts the eight DWAB-compressed HDRIs)."""
import math
import shutil
import subprocess

import numpy as np
import pytest

from conftest import STUDIOLIGHTS, requires_native
from schnee_probes import adaptive, exr, native

pytestmark = requires_native

# Looked at first (docs/direct-light.md "The sky's sun", measured table): a compact, very bright
# sun in six, none in the overcast courtyard and the studio's ~10° softbox. share: the sun's part of
# the image's luminance flux, measured (the bounds leave room on both sides).
WITH_SUN = {"city": (0.20, 0.26), "forest": (0.05, 0.08), "interior": (0.11, 0.15), "night": (0.15, 0.19),
            "sunrise": (0.55, 0.62), "sunset": (0.015, 0.03)}
WITHOUT_SUN = ("courtyard", "studio")


@pytest.fixture(scope="module")
def hdris(tmp_path_factory):
    """The eight HDRIs, each read once for the module. They are DWAB-compressed, which images.py hands
    to oiiotool outside Blender (two oiiotool starts of ~3 s each per image): one oiiotool run
    converts all eight, as images.py does one (float, uncompressed EXR), and exr.py reads them back.
    native.read_image on these files is test_native_sh.py::test_project_file_reads_exr."""
    tool = shutil.which("oiiotool")
    assert tool, "OpenImageIO's oiiotool reads the DWAB HDRIs outside Blender"
    tmp = tmp_path_factory.mktemp("hdri")
    names = sorted(WITH_SUN) + list(WITHOUT_SUN)
    cmd = [tool]
    for name in names:
        cmd += [str(STUDIOLIGHTS / f"{name}.exr"), "-d", "float", "--compression", "none",
                "-o", str(tmp / f"{name}.exr")]
    subprocess.run(cmd, check=True, capture_output=True)
    # As the bake reads a world: RGB, clamped at 0 (the HDRIs hold -1e-5 texels).
    return {name: np.ascontiguousarray(np.clip(exr.read(str(tmp / f"{name}.exr"))[:, :, :3], 0.0, None),
                                       dtype=np.float32) for name in names}


def _projection(world):
    """∫ L Y_i dω over the sphere, L2, engine space: the sky table of one panorama cell."""
    return native.sky_table(world, 1, 1, 2)[0, 0]


@pytest.mark.parametrize("name", sorted(WITH_SUN))
def test_sun_plus_rest_is_the_image(name, hdris):
    world = hdris[name]
    split = native.sky_sun_split(world)
    assert split.verdict == "found" and split.sun is not None
    sun = split.sun
    lo, hi = WITH_SUN[name]
    assert lo <= sun.share <= hi, sun.share
    exact = _projection(world)
    rest = _projection(split.rest)
    lamp = native.direct_project([sun.lamp()], np.zeros((1, 3)), 2)[0]
    # L0 (the energy): the split moves each texel's excess to the sun, summed in double.
    np.testing.assert_allclose(rest[0] + lamp[0], exact[0], rtol=1e-9)
    # Every band: the lamp spreads the sun over a disc of its angle around its centroid, the image
    # over its texels; measured 7e-7 (sunset) to 3e-4 (sunrise) relative irradiance RMS.
    assert adaptive.irradiance_error(rest + lamp, exact) < 1e-3
    # The rest keeps every texel but the sun's, and no sun texel gains light.
    changed = np.any(split.rest != world, axis=2)
    assert changed.sum() <= sun.texels and np.all(split.rest <= world)
    assert sun.angle < math.radians(2.0) and sun.extent <= math.radians(5.0)
    assert abs(np.linalg.norm(sun.direction) - 1.0) < 1e-12


@pytest.mark.parametrize("name", WITHOUT_SUN)
def test_soft_skies_keep_their_light(name, hdris):
    world = hdris[name]
    split = native.sky_sun_split(world)
    assert split.sun is None and split.verdict == "wide"
    assert np.array_equal(split.rest, world)
    assert adaptive.sky_sun(world) is None


def test_sunrise_sun_where_the_image_has_it(hdris):
    """sunrise.exr's sun: about 8° above the horizon (docs/placement.md step 4b, measured from the
    image's brightest texel), holding more than half the sky's light; the brightest texel's own
    direction (independent of the split's centroid) is within one texel (0.35°) of the sun's."""
    world = hdris["sunrise"]
    sun = native.sky_sun_split(world).sun
    h, w = world.shape[:2]
    lum = world @ np.array([0.2126, 0.7152, 0.0722], dtype=np.float32)
    row, col = np.unravel_index(int(np.argmax(lum)), lum.shape)
    theta, phi = math.pi * (row + 0.5) / h, math.pi - 2.0 * math.pi * (col + 0.5) / w
    to_peak = np.array([math.sin(theta) * math.cos(phi), math.cos(theta), -math.sin(theta) * math.sin(phi)])
    assert math.degrees(math.acos(min(1.0, float(np.dot(-np.array(sun.direction), to_peak))))) < 0.35
    assert math.degrees(math.asin(-sun.direction[1])) == pytest.approx(8.1, abs=0.5)
    assert sun.share > 0.5


def test_bad_input_is_refused():
    world = np.ones((8, 16, 3), dtype=np.float32)
    world[2, 3, 1] = np.nan
    with pytest.raises(native.SchneeError, match=r"sky texel \(3, 2\) channel 1 is not finite"):
        native.sky_sun_split(world)
    world[2, 3, 1] = -1.0
    with pytest.raises(native.SchneeError) as info:
        native.sky_sun_split(world)
    assert info.value.code == "negative value" or "negative" in str(info.value)
    with pytest.raises(ValueError):
        native.sky_sun_split(np.ones((8, 16)))
    with pytest.raises(native.SchneeError, match="min_share"):
        native.sky_sun_split(np.ones((8, 16, 3), dtype=np.float32), min_share=2.0)
