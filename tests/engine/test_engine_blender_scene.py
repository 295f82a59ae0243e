"""schnee-view renders a scene exported by Blender's own glTF exporter (the accessor types,
node transforms, cameras and KHR_lights_punctual Blender writes), with a probe grid added."""
import json
import shutil
import sys
from pathlib import Path

import numpy as np
import pytest

sys.path.insert(0, str(Path(__file__).parent / "scripts"))
import scenegen as sg  # noqa: E402
import viewer  # noqa: E402
from conftest import run_blender  # noqa: E402

pytestmark = pytest.mark.skipif(shutil.which("blender") is None, reason="blender not installed")


@pytest.fixture(scope="module")
def exported(tmp_path_factory):
    d = tmp_path_factory.mktemp("blender")
    out = d / "scene.gltf"
    run_blender(Path(__file__).parent / "scripts" / "blender_export_scene.py", out, timeout=300)
    # One probe grid over the scene: 4x4x4 cells of 1 m from (-2, -2, -2), every cell probe 0,
    # a constant sky-blue environment.
    (d / "sh_coeffs").mkdir()
    c = np.zeros((1, 9, 3))
    c[0, 0] = np.array([0.4, 0.6, 1.0]) * 0.282094792 * 4 * np.pi
    sg.write_shprobe_v1(d / "sh_coeffs" / "room.shprobe", c, np.zeros((4, 4, 4), np.int32), (-2, -2, -2), 1.0)
    doc = json.loads(out.read_text())
    doc["scenes"][doc.get("scene", 0)].setdefault("extensions", {})["VULKAN_SCHNEE_engine_properties"] = {
        "shProbeGrids": [sg.grid_entry("room", "sh_coeffs/room.shprobe", 1, (-2, -2, -2), (4, 4, 4), 1.0)]}
    doc.setdefault("extensionsUsed", []).append("VULKAN_SCHNEE_engine_properties")
    out.write_text(json.dumps(doc))
    return out


def test_blender_export_renders(exported, tmp_path):
    png = tmp_path / "frame.png"
    proc = viewer.check(viewer.run(exported, "--headless", "--output", png, "--width", 96, "--height", 64,
                                   "--print-assignments"))
    got = viewer.assignments(proc.stdout)
    # Blender (x, y, z) -> engine (x, z, -y): the cube at the origin is inside the grid (probe 0 of
    # the only grid = buffer index 1); the sphere at Blender (3, 0, 0.5) = engine (3, 0.5, 0) is past
    # the grid's far edge x = 2, hence the fallback.
    assert got["Cube"] == 1
    assert got["Sphere"] == 0
    img = viewer.read_image(png)
    assert img.shape == (64, 96, 3)
    lit = img.max(axis=-1) > 0.05
    assert 0.05 < lit.mean() < 0.95  # objects and background both visible from Blender's camera
    # The red sphere shows up as red-dominant pixels somewhere.
    assert ((img[..., 0] > 2 * img[..., 1]) & lit).sum() > 5
