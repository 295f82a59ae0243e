"""Embedded glTF images (a bufferView with a mimeType, a data: URI) decode from memory
(pb_image_read_memory, no temporary file) to the same pixels as the same PNG beside the glTF.

Expected values: the file-URI render is the reference (test_engine_materials checks it against the
glTF spec's sRGB decode); the embedded ones must equal it bit for bit, since the same bytes go
through the same decoder.
"""
import base64
import sys
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).parent / "scripts"))
import scenegen as sg  # noqa: E402
import viewer  # noqa: E402
from test_engine_materials import TEXELS, facing_quad, write_png  # noqa: E402

N = 8


def render(tmp_path, name, image):
    """Renders the textured quad of test_engine_materials with glTF image `image`; returns (pixels, stderr)."""
    b = sg.GltfBuilder()
    m = b.material("tex", base_color=(1, 1, 1, 1), sh_scale=0.0, ambient_term=1.0)
    if "bufferView" in image:  # the PNG's bytes appended to the glTF's own buffer
        image = {"bufferView": b._view(image.pop("bufferView"), None), **image}
        del b.doc["bufferViews"][image["bufferView"]]["target"]
    b.doc["images"] = [image]
    b.doc["textures"] = [{"source": 0}]
    b.doc["materials"][m]["pbrMetallicRoughness"]["baseColorTexture"] = {"index": 0}
    b.node("Quad", mesh=b.mesh("quad", facing_quad(1.0), m))
    b.node("Camera", camera=b.ortho_camera("front", 1.0), translation=(0, 0, 3))
    out = tmp_path / f"{name}.exr"
    proc = viewer.check(viewer.run(b.write(tmp_path / f"{name}.gltf"), "--headless", "--output", out, "--width", N,
                                   "--height", N, "--no-sky"))
    return viewer.read_image(out), proc.stderr


def test_embedded_images_match_the_file(tmp_path):
    write_png(tmp_path / "tex.png", TEXELS)
    png = (tmp_path / "tex.png").read_bytes()
    ref, _ = render(tmp_path, "file", {"uri": "tex.png"})
    view, _ = render(tmp_path, "view", {"name": "embedded", "bufferView": png, "mimeType": "image/png"})
    data, _ = render(tmp_path, "data", {"uri": "data:image/png;base64," + base64.b64encode(png).decode()})
    assert np.ptp(ref) > 0.1  # the texture shows (not the white stand-in)
    assert np.array_equal(view, ref)
    assert np.array_equal(data, ref)


def test_broken_embedded_image_is_white_with_a_warning(tmp_path):
    img, err = render(tmp_path, "bad", {"name": "broken", "bufferView": b"\x89PNG\r\n\x1a\n-not-a-png",
                                        "mimeType": "image/png"})
    assert "warning" in err and "broken" in err and "using white" in err, err
    assert np.allclose(img, 1.0, atol=1e-6)  # white texel x factor 1, ambientTerm 1
