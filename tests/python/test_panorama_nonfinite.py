"""A panorama holding Inf/NaN is refused by the native projection the bake uses (project_file,
negative="clamp" as in bake_core.ProbeBake.step) with a message naming the pixel; the bake adds
the probe and its position (bake_core). Cycles itself drops non-finite samples, so this is the
backstop for a render that overflows. The EXR is written by OpenImageIO's oiiotool (deps.sh)."""
import shutil
import subprocess

import pytest

from conftest import requires_native

pytestmark = [requires_native,
              pytest.mark.skipif(shutil.which("oiiotool") is None, reason="oiiotool missing (scripts/deps.sh)")]


def test_inf_panorama_is_refused_naming_the_pixel(tmp_path):
    from schnee_probes import native
    exr = tmp_path / "inf.exr"
    # 1e30 x 1e30 overflows float32 to +Inf in the red channel of every pixel.
    subprocess.run(["oiiotool", "--pattern", "constant:color=1e30,1,1", "16x8", "3", "-d", "float",
                    "--mulc", "1e30,1,1", "-o", str(exr)], check=True)
    with pytest.raises(native.SchneeError) as err:
        native.project_file(str(exr), 2, negative="clamp")
    assert err.value.code == "non-finite value"
    assert "non-finite radiance inf at pixel (x=0, y=0), channel 0 (R)" in str(err.value)
