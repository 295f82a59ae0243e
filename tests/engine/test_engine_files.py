"""Files a glTF makes schnee-view open (issue 14): buffers, images, the sky and probe grids.

Each special file — a FIFO, /dev/zero, a 2 GiB sparse file, a directory, a symlink loop — gives a
clear message naming the file within seconds (the FIFO used to block forever, the sparse sky was
read whole); references outside the glTF's folder are refused unless --allow-outside-paths; an
error never quotes a foreign file's content; Blender's unencoded '%' loads with a warning;
--probe-storage half falls back to float (with a warning naming the grid) when a coefficient
exceeds the half range, instead of rendering those objects dark.
"""
import json
import os
import sys
import time
from pathlib import Path

import numpy as np
import pytest

sys.path.insert(0, str(Path(__file__).parent / "scripts"))
import scenegen as sg  # noqa: E402
import viewer  # noqa: E402

SPECIALS = ["fifo", "zero", "sparse", "dir", "loop"]
EXPECT = {"fifo": "is a FIFO", "zero": "is a character device", "dir": "is a directory",
          "loop": "too many levels of symbolic links"}
KINDS = ["buffer", "image", "sky", "grid"]


def make_special(d, kind, name):
    """The special file inside d (its uri), or for /dev/zero the absolute device path."""
    p = d / name
    if kind == "fifo":
        os.mkfifo(p)
    elif kind == "dir":
        p.mkdir()
    elif kind == "loop":
        os.symlink(name + ".other", p)
        os.symlink(name, d / (name + ".other"))
    elif kind == "sparse":
        with open(p, "wb") as f:
            f.truncate(2 << 30)  # 2 GiB of holes
    else:
        return "/dev/zero"
    return name


def scene(d, kind, uri):
    """A cube scene whose `kind` reference (buffer, image, sky or probe grid) is `uri`."""
    b = sg.GltfBuilder()
    m = b.material("m", base_color=(1, 1, 1, 1))
    b.node("Cube", mesh=b.mesh("cube", sg.cube(0.5), m))
    b.node("Camera", camera=b.camera("cam", 0.8), translation=(0, 0, 3))
    if kind == "grid":
        b.probe_grids([sg.grid_entry("g", uri, 1, (-1, -1, -1), (1, 1, 1), 2.0)])
    elif kind == "sky":
        b.probe_grids([], sky=sg.sky_entry(uri, np.zeros((9, 3))))
    path = b.write(d / "scene.gltf")
    doc = json.loads(path.read_text())
    if kind == "buffer":
        (d / "mesh.bin").write_bytes(bytes(b.bin))
        doc["buffers"] = [{"byteLength": len(b.bin), "uri": uri}]
    elif kind == "image":
        doc["images"] = [{"uri": uri}]
        doc["textures"] = [{"source": 0}]
        doc["materials"][0]["pbrMetallicRoughness"]["baseColorTexture"] = {"index": 0}
    path.write_text(json.dumps(doc))
    return path


def run(path, *extra, output=None):
    args = [path, "--headless"] + (["--output", output, "--width", 16, "--height", 16] if output else
                                    ["--print-assignments"]) + list(extra)
    t0 = time.monotonic()
    proc = viewer.run(*args, timeout=60)
    return proc, time.monotonic() - t0


@pytest.mark.parametrize("kind", KINDS)
@pytest.mark.parametrize("special", SPECIALS)
def test_special_file_gives_a_clear_message_quickly(tmp_path, kind, special):
    uri = make_special(tmp_path, special, "special.dat")
    path = scene(tmp_path, kind, uri)
    extra = ["--allow-outside-paths"] if special == "zero" else []  # /dev/zero is outside the folder
    proc, seconds = run(path, *extra, output=tmp_path / "out.png" if kind == "image" else None)
    assert seconds < 20, f"{seconds:.1f} s"
    if kind == "buffer" and special == "sparse":
        # A regular file with enough bytes: only byteLength bytes are read, and the scene loads.
        assert proc.returncode == 0, proc.stderr
        return
    shown = uri if special == "zero" else str(tmp_path / uri)
    assert shown in proc.stderr, proc.stderr
    if kind == "image" and special != "loop":
        # An unreadable texture is a warning (the material gets white), as a missing one always was.
        assert proc.returncode == 0, proc.stderr
        assert "warning" in proc.stderr and "using white" in proc.stderr
    else:
        # A symlink loop already fails when the image's path is resolved at load.
        assert proc.returncode == 1, proc.stderr
        assert "error" in proc.stderr
    if special == "sparse":
        # Over the documented limits (1 GiB for images and .shprobe files), refused before reading.
        assert "has 2147483648 bytes, over the limit of 1073741824" in proc.stderr, proc.stderr
    else:
        assert EXPECT[special] in proc.stderr, proc.stderr


@pytest.mark.parametrize("kind", KINDS)
def test_outside_the_folder_is_refused_unless_allowed(tmp_path, kind):
    inside = tmp_path / "scene"
    inside.mkdir()
    # Real files outside the scene folder, so that --allow-outside-paths loads them.
    sg.write_shprobe_v1(tmp_path / "p.shprobe", np.ones((1, 9, 3)), np.zeros((1, 1, 1), np.int32),
                                    (-1, -1, -1), 2.0)
    sg.write_exr(tmp_path / "sky.exr", np.ones((8, 16, 3), np.float32))
    target = {"grid": "p.shprobe", "sky": "sky.exr", "image": "sky.exr", "buffer": "mesh.bin"}[kind]
    for uri in ["../" + target, str(tmp_path / target)]:
        path = scene(inside, kind, uri)
        if kind == "buffer":
            (tmp_path / "mesh.bin").write_bytes((inside / "mesh.bin").read_bytes())
        proc, _ = run(path, output=tmp_path / "out.png" if kind == "image" else None)
        assert uri in proc.stderr, proc.stderr
        assert "outside the glTF's folder" in proc.stderr and "--allow-outside-paths" in proc.stderr
        assert proc.returncode == 1, proc.stderr  # an image outside is refused at load, like a buffer
        proc, _ = run(path, "--allow-outside-paths", output=tmp_path / "out.png" if kind == "image" else None)
        assert proc.returncode == 0, proc.stderr


def test_symlink_leading_out_is_refused(tmp_path):
    inside = tmp_path / "scene"
    inside.mkdir()
    sg.write_shprobe_v1(tmp_path / "p.shprobe", np.ones((1, 9, 3)), np.zeros((1, 1, 1), np.int32), (-1, -1, -1), 2.0)
    os.symlink(tmp_path / "p.shprobe", inside / "link.shprobe")
    path = scene(inside, "grid", "link.shprobe")
    proc, _ = run(path)
    assert proc.returncode == 1
    assert "leads to" in proc.stderr and str(tmp_path / "p.shprobe") in proc.stderr, proc.stderr
    assert viewer.run(path, "--headless", "--print-assignments", "--allow-outside-paths").returncode == 0


@pytest.mark.parametrize("kind", ["grid", "sky"])
def test_error_never_quotes_a_foreign_file(tmp_path, kind):
    # The old reader said "bad magic 0x746F6F72" for /etc/passwd ("root"): four bytes of the file.
    (tmp_path / "secret.txt").write_bytes(b"SECRETS-ARE-HERE\n" * 4)
    proc, _ = run(scene(tmp_path, kind, "secret.txt"))
    assert proc.returncode == 1
    assert "secret.txt" in proc.stderr
    for leak in ("SECRET", "0x52434553", "52434553", "0x45524353"):
        assert leak not in proc.stderr, proc.stderr


def test_unencoded_percent_from_blender_loads_with_a_warning(tmp_path):
    name = "scène #1 100% ü.bin"
    path = scene(tmp_path, "buffer", name)
    (tmp_path / name).write_bytes((tmp_path / "mesh.bin").read_bytes())
    proc, _ = run(path)
    assert proc.returncode == 0, proc.stderr
    assert "has a '%' that is not a %XX escape; taken literally" in proc.stderr
    assert "object 0 'Cube'" in proc.stdout
    # A valid escape still decodes, without a warning.
    (tmp_path / "two words.bin").write_bytes((tmp_path / "mesh.bin").read_bytes())
    path = scene(tmp_path, "buffer", "two%20words.bin")
    proc, _ = run(path)
    assert proc.returncode == 0 and "taken literally" not in proc.stderr, proc.stderr


def test_half_storage_overflow_falls_back_to_float(tmp_path):
    # A probe with a coefficient of 1e6 (> 65504, the largest half): half storage would hold Inf.
    coeffs = np.zeros((1, 9, 3))
    coeffs[0, 0] = [1e6, 2e5, 5e4]
    (tmp_path / "sh").mkdir()
    sg.write_shprobe_v1(tmp_path / "sh" / "big.shprobe", coeffs, np.zeros((1, 1, 1), np.int32), (-1, -1, -1), 2.0)
    b = sg.GltfBuilder()
    b.node("Cube", mesh=b.mesh("cube", sg.cube(0.5), b.material("m", base_color=(0.5, 0.5, 0.5, 1))))
    b.node("Camera", camera=b.camera("cam", 0.8), translation=(0, 0, 3))
    b.probe_grids([sg.grid_entry("big grid", "sh/big.shprobe", 1, (-1, -1, -1), (1, 1, 1), 2.0)])
    path = b.write(tmp_path / "scene.gltf")
    f = tmp_path / "f.exr"
    h = tmp_path / "h.exr"
    viewer.check(viewer.run(path, "--headless", "--output", f, "--width", 32, "--height", 32))
    proc = viewer.check(viewer.run(path, "--headless", "--output", h, "--width", 32, "--height", 32,
                                   "--probe-storage", "half"))
    assert "shProbeGrids[0] 'big grid' probe 0: coefficient 0 = 1e+06 exceeds the half-float range" in proc.stderr
    assert "using float storage" in proc.stderr
    fi, hi = viewer.read_image(f), viewer.read_image(h)
    assert np.all(np.isfinite(hi))
    # The cube's front face: albedo 0.5 · (E/π + 0.1) with E = π·L00·Y00 ≈ 2.8e5 — bright, not dark.
    assert hi[16, 16, 0] > 1e4
    assert np.array_equal(fi, hi)  # float storage in both runs


def test_exr_header_over_the_pixel_limit_is_not_decoded(tmp_path):
    # A 60-byte file whose EXR header claims 100000 x 50000 pixels: refused from the header, before
    # OpenImageIO would allocate 60 GB for it.
    import struct
    head = (b"\x76\x2f\x31\x01" + struct.pack("<I", 2) + b"dataWindow\0box2i\0" + struct.pack("<i", 16)
            + struct.pack("<4i", 0, 0, 99999, 49999) + b"\0")
    (tmp_path / "sky.exr").write_bytes(head)
    proc, seconds = run(scene(tmp_path, "sky", "sky.exr"))
    assert proc.returncode == 1 and seconds < 20
    assert "sky: '%s' is 100000 x 50000 pixels, over the limit of %d pixels" % (tmp_path / "sky.exr", 8192 * 4096) \
        in proc.stderr, proc.stderr


def test_sky_near_float_max_is_clamped_not_infinite(tmp_path):
    # Found by tests/fuzz/run_sky_fuzz.sh: a sky texel of 1.7e38 made the GGX prefilter's sums Inf.
    img = np.full((8, 16, 3), 0.5, np.float32)
    img[2:4, 3:6] = 1.7e38
    sg.write_exr(tmp_path / "sky.exr", img)
    path = scene(tmp_path, "sky", "sky.exr")
    proc = viewer.check(viewer.run(path, "--write-sky-mips", tmp_path / "mip", validation=False))
    assert "18 value(s) above 1e+20 clamped to it" in proc.stderr, proc.stderr
    levels = sorted(tmp_path.glob("mip*.exr"))
    assert len(levels) >= 2
    for level in levels:
        px = viewer.read_image(level)
        assert np.all(np.isfinite(px)) and px.max() <= 1e20 * (1 + 1e-6)
