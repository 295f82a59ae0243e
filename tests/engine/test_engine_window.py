"""The windowed path under Xvfb: GLFW window, swapchain, same renderer as headless.

The engine copies its last swapchain image to --screenshot; the capture must equal the headless
PNG of the same scene and size (both go through the same tone-mapping pass; the swapchain may be
UNORM with the sRGB curve applied in the shader instead of by the format: ±2 levels of 255)."""
import shutil
import sys
from pathlib import Path

import numpy as np
import pytest

sys.path.insert(0, str(Path(__file__).parent / "scripts"))
import scenegen as sg  # noqa: E402
import viewer  # noqa: E402

W, H = 160, 120

pytestmark = pytest.mark.skipif(shutil.which("xvfb-run") is None, reason="xvfb-run not installed (apt: xvfb)")


@pytest.fixture(scope="module")
def scene(tmp_path_factory):
    d = tmp_path_factory.mktemp("window")
    (d / "sh_coeffs").mkdir()
    c = np.zeros((1, 9, 3))
    c[0, 0] = [3.0, 2.0, 1.0]
    c[0, 2] = [0.5, 0.5, 0.5]
    sg.write_shprobe_v1(d / "sh_coeffs" / "p.shprobe", c, np.zeros((1, 1, 1), np.int32), (-2, -2, -2), 4.0)
    b = sg.GltfBuilder()
    b.node("Sphere", mesh=b.mesh("sphere", sg.uv_sphere(1.0, 64, 32), b.material("m", base_color=(0.9, 0.7, 0.5, 1))))
    b.node("Camera", camera=b.camera("cam", 0.9), translation=(0, 0, 3))
    b.probe_grids([sg.grid_entry("p", "sh_coeffs/p.shprobe", 1, (-2, -2, -2), (1, 1, 1), 4.0)])
    return b.write(d / "scene.gltf")


def test_window_frame_matches_headless(scene, tmp_path):
    shot, ref = tmp_path / "window.png", tmp_path / "headless.png"
    proc = viewer.check(viewer.run(scene, "--frames", 3, "--screenshot", shot, "--width", W, "--height", H,
                                   xvfb=True, timeout=180))
    assert "3 frame(s) presented" in proc.stderr
    viewer.check(viewer.run(scene, "--headless", "--output", ref, "--width", W, "--height", H))
    a, b = viewer.read_image(shot), viewer.read_image(ref)
    assert a.shape == b.shape == (H, W, 3)
    # Not empty: the sphere covers the centre, the corners are background.
    assert a[H // 2, W // 2].min() > 0.2
    assert np.all(a[0, 0] == 0)
    assert (a.max(axis=-1) > 0.1).mean() > 0.3
    assert np.abs(a - b).max() <= 2.0 / 255


def test_window_without_display_fails_cleanly(scene, tmp_path):
    import os
    import subprocess
    env = viewer.env()
    env.pop("DISPLAY", None)
    env.pop("WAYLAND_DISPLAY", None)
    proc = subprocess.run([str(viewer.VIEWER), str(scene), "--frames", "1"], capture_output=True, text=True,
                          timeout=60, env=env)
    assert proc.returncode == 1
    assert "--headless" in proc.stderr
    assert os.path.exists(scene)
