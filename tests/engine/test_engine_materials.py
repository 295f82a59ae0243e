"""Material paths of schnee-view: base-colour texture, emissive strength, the camera-less framing.

Expected values come from the glTF 2.0 spec (baseColorTexture is sRGB-encoded and multiplies
baseColorFactor; emissive = emissiveFactor x KHR_materials_emissive_strength) and from DESIGN.md
§3's diffuse formula albedo * (shScale * E / pi + ambientTerm): with shScale 0 and ambientTerm 1 a
pixel is exactly the albedo. The engine samples every texture with one LINEAR / REPEAT sampler
(docs/engine.md "Materials"); the reference below is bilinear with wrap-around in numpy.
"""
import struct
import sys
import zlib
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).parent / "scripts"))
import scenegen as sg  # noqa: E402
import viewer  # noqa: E402


def write_png(path, rgb8):
    """Minimal 8-bit RGB PNG writer (zlib + the chunk layout of the PNG spec)."""
    h, w, _ = rgb8.shape
    raw = b"".join(b"\x00" + rgb8[y].astype(np.uint8).tobytes() for y in range(h))

    def chunk(tag, data):
        return struct.pack(">I", len(data)) + tag + data + struct.pack(">I", zlib.crc32(tag + data) & 0xFFFFFFFF)

    Path(path).write_bytes(b"\x89PNG\r\n\x1a\n" + chunk(b"IHDR", struct.pack(">IIBBBBB", w, h, 8, 2, 0, 0, 0)) +
                           chunk(b"IDAT", zlib.compress(raw)) + chunk(b"IEND", b""))


def srgb_decode(c):
    c = np.asarray(c, float)
    return np.where(c <= 0.04045, c / 12.92, ((c + 0.055) / 1.055) ** 2.4)


def facing_quad(half):
    """A quad in the z = 0 plane facing +z, uv (0, 0) at the top-left (x = -half, y = +half)."""
    pos = np.array([[-half, -half, 0], [half, -half, 0], [half, half, 0], [-half, half, 0]], np.float32)
    uv = np.array([[0, 1], [1, 1], [1, 0], [0, 0]], np.float32)
    return pos, np.tile([0, 0, 1], (4, 1)).astype(np.float32), uv, np.array([0, 1, 2, 0, 2, 3], np.uint32)


TEXELS = np.array([[[255, 0, 0], [0, 128, 255]], [[64, 200, 32], [250, 250, 250]]], np.uint8)  # (row, col)
FACTOR = np.array([0.9, 0.7, 0.5])
N = 8


def bilinear_repeat(tex, u, v):
    h, w, _ = tex.shape
    x, y = u * w - 0.5, v * h - 0.5
    x0, y0 = np.floor(x).astype(int), np.floor(y).astype(int)
    fx, fy = (x - x0)[..., None], (y - y0)[..., None]
    t = lambda yy, xx: tex[yy % h, xx % w]  # noqa: E731
    return ((1 - fy) * ((1 - fx) * t(y0, x0) + fx * t(y0, x0 + 1)) + fy * ((1 - fx) * t(y0 + 1, x0) + fx * t(y0 + 1, x0 + 1)))


def test_base_color_texture_is_srgb_decoded_times_factor(tmp_path):
    write_png(tmp_path / "tex.png", TEXELS)
    b = sg.GltfBuilder()
    m = b.material("tex", base_color=(*FACTOR, 1), sh_scale=0.0, ambient_term=1.0)
    b.doc["images"] = [{"uri": "tex.png"}]
    b.doc["textures"] = [{"source": 0}]
    b.doc["materials"][m]["pbrMetallicRoughness"]["baseColorTexture"] = {"index": 0}
    b.node("Quad", mesh=b.mesh("quad", facing_quad(1.0), m))
    b.node("Camera", camera=b.ortho_camera("front", 1.0), translation=(0, 0, 3))
    out = tmp_path / "t.exr"
    viewer.check(viewer.run(b.write(tmp_path / "t.gltf"), "--headless", "--output", out, "--width", N, "--height", N,
                            "--no-sky"))
    img = viewer.read_image(out)
    # Pixel (row j, col i) centre: uv = ((i + 0.5) / N, (j + 0.5) / N) on the quad filling the view.
    u = (np.arange(N) + 0.5) / N
    U, V = np.meshgrid(u, u)
    # Vulkan decodes sRGB texels before filtering: bilinear over the decoded values.
    expected = bilinear_repeat(srgb_decode(TEXELS / 255.0), U, V) * FACTOR
    # Tolerance: lavapipe's bilinear weights are fixed point (8-bit steps) on values <= 1, plus
    # float rounding; measured max abs error 5.5e-4 on lavapipe. Bound 2e-3 (a missing sRGB decode
    # is off by up to 0.3, a flipped v or CLAMP edges by > 0.1).
    err = np.abs(img - expected)
    assert err.max() < 2e-3, f"max abs error {err.max():.3g}"


def test_emissive_factor_times_strength(tmp_path):
    b = sg.GltfBuilder()
    m = b.material("glow", base_color=(0, 0, 0, 1), sh_scale=0.0, ambient_term=0.0, emissive=(0.5, 0.25, 1.0))
    b.doc["materials"][m].setdefault("extensions", {})["KHR_materials_emissive_strength"] = {"emissiveStrength": 4.0}
    b._use("KHR_materials_emissive_strength")
    b.node("Quad", mesh=b.mesh("quad", facing_quad(1.0), m))
    b.node("Camera", camera=b.ortho_camera("front", 0.5), translation=(0, 0, 3))
    out = tmp_path / "e.exr"
    viewer.check(viewer.run(b.write(tmp_path / "e.gltf"), "--headless", "--output", out, "--width", N, "--height", N,
                            "--no-sky"))
    img = viewer.read_image(out)
    # glTF: emitted radiance = emissiveFactor x emissiveStrength = (2, 1, 4); black albedo, no
    # lights: nothing else adds. Float32 EXR: 1e-6 relative.
    assert np.allclose(img, [2.0, 1.0, 4.0], rtol=1e-6, atol=0)


def test_cameraless_scene_frames_the_object(tmp_path):
    # No camera: the engine looks at the centre of the scene bounds (docs/engine.md). A sphere is
    # symmetric, so its projection is a disc centred on the projected centre: the covered pixels'
    # centroid must lie within 1 px of the frame centre.
    b = sg.GltfBuilder()
    m = b.material("lit", base_color=(1, 1, 1, 1), sh_scale=0.0, ambient_term=1.0)
    b.node("Sphere", mesh=b.mesh("sphere", sg.uv_sphere(0.5, 64, 32), m), translation=(3.0, 1.0, -2.0))
    W, H = 65, 49
    out = tmp_path / "c.exr"
    viewer.check(viewer.run(b.write(tmp_path / "c.gltf"), "--headless", "--output", out, "--width", W, "--height", H,
                            "--no-sky"))
    img = viewer.read_image(out)
    covered = img[..., 0] > 0.5
    assert covered.sum() > 100
    ys, xs = np.nonzero(covered)
    assert abs(xs.mean() - (W - 1) / 2) <= 1.0 and abs(ys.mean() - (H - 1) / 2) <= 1.0, (xs.mean(), ys.mean())
