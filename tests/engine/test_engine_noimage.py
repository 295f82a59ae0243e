"""schnee-view-noimage (engine/CMakeLists.txt): the viewer built without OpenImageIO, for machines
that lack its library closure (the GPU timing runs of bench/device/), and the GPU timestamps every
headless run prints (docs/engine.md "Command line").

The expected frame is schnee-view's own: the same scene (test_engine_shadows' plane and box under a
mixed sun and a mixed point lamp: shadow cascades, a cube map, the probe) rendered by both on lavapipe
must be the same floats, and the PFM the no-OpenImageIO build writes is decoded by OpenImageIO
(oiiotool), not by this file.
"""
import re
import sys
from pathlib import Path

import numpy as np
import pytest

sys.path.insert(0, str(Path(__file__).parent / "scripts"))
import viewer  # noqa: E402
import test_engine_shadows as ts  # noqa: E402

NOIMAGE = viewer.REPO / "build" / "schnee-view-noimage"
GPU_LINE = re.compile(r"GPU time per frame \(timestamps, median\): shadows ([0-9.]+) ms, scene ([0-9.]+) ms, "
                      r"tone map ([0-9.]+) ms, total ([0-9.]+) ms")
WALL_LINE = re.compile(r"(\d+) frame\(s\) at \d+x\d+: mean ([0-9.]+) ms, median ([0-9.]+) ms")


def run_noimage(*args):
    assert NOIMAGE.exists(), f"{NOIMAGE} is missing: build it with cmake --build build"
    import subprocess
    cmd = [str(NOIMAGE)] + [str(a) for a in args] + ["--validation"]
    return subprocess.run(cmd, capture_output=True, text=True, timeout=120, env=viewer.env())


@pytest.fixture(scope="module")
def scene(tmp_path_factory):
    d = tmp_path_factory.mktemp("noimage")
    return ts.write_scene(d / "scene.gltf", [(ts.SUN_DIR, "mixed")], lamps=[ts.POINT])


def test_noimage_viewer_renders_the_same_floats_as_the_viewer(scene, tmp_path):
    size = ("--width", 96, "--height", 64)
    viewer.check(viewer.run(scene, "--headless", "--output", tmp_path / "ref.exr", *size))
    proc = run_noimage(scene, "--headless", "--output", tmp_path / "noimage.pfm", *size)
    viewer.check(proc)
    ref = viewer.read_image(tmp_path / "ref.exr")[..., :3]
    got = viewer.read_image(tmp_path / "noimage.pfm")[..., :3]
    assert got.shape == ref.shape == (64, 96, 3)
    # Shadowed and lit pixels are both in the frame (the test would pass on a blank image otherwise).
    lum = ref.mean(-1)
    lit = lum[lum > 0]  # the plane (the background beyond it is black)
    assert lit.size > lum.size / 2 and lit.max() > 2.0 * np.percentile(lit, 5) > 0
    # Same SPIR-V, same driver: the same floats (oiiotool prints 9 significant digits).
    np.testing.assert_allclose(got, ref, rtol=2e-8, atol=1e-9)


def test_noimage_viewer_refuses_other_formats_and_writes_nothing(scene, tmp_path):
    proc = run_noimage(scene, "--headless", "--output", tmp_path / "x.png", "--width", 8, "--height", 8)
    assert proc.returncode > 0, proc.stderr
    assert "writes PFM only" in proc.stderr and "x.png" in proc.stderr
    assert not list(tmp_path.iterdir())


def gpu_times(stderr):
    m = GPU_LINE.search(stderr)
    assert m, stderr
    return [float(v) for v in m.groups()]


def test_gpu_timestamps_split_the_frame_into_its_stages(scene, tmp_path):
    """One frame: the GPU's stage times are non-negative, add up to their printed total and fit in
    the frame's submit-to-fence wall time; the shadow stage holds the shadow maps (10 layers of
    1024² here: 4 sun cascades, 6 cube faces), far more than with shadows off."""
    def run(*extra):
        proc = viewer.check(viewer.run(scene, "--headless", "--output", tmp_path / "t.exr", "--width", 64,
                                       "--height", 64, "--frames", 1, *extra))
        wall = float(WALL_LINE.search(proc.stderr).group(3))
        return gpu_times(proc.stderr), wall
    (shadows, scene_ms, tone, total), wall = run("--shadow-res", 1024)
    assert min(shadows, scene_ms, tone) >= 0.0
    assert total == pytest.approx(shadows + scene_ms + tone, abs=2e-3)
    assert total <= wall + 0.01
    (shadows_off, *_), _ = run("--shadow-res", 0)
    assert shadows > 5.0 * shadows_off + 0.05, (shadows, shadows_off)
