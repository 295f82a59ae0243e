"""schnee-view on bad input: a clear message naming the problem, a non-zero exit, never a crash
(a crash would show as a negative return code, i.e. a signal)."""
import struct
import sys
from pathlib import Path

import numpy as np
import pytest

sys.path.insert(0, str(Path(__file__).parent / "scripts"))
import scenegen as sg  # noqa: E402
import viewer  # noqa: E402


def scene_with_probe_bytes(d, data):
    (d / "sh_coeffs").mkdir(exist_ok=True)
    (d / "sh_coeffs" / "p.shprobe").write_bytes(data)
    b = sg.GltfBuilder()
    b.node("Cube", mesh=b.mesh("cube", sg.cube(0.5)))
    b.probe_grids([sg.grid_entry("p", "sh_coeffs/p.shprobe", 2, (0, 0, 0), (2, 1, 1), 1.0)])
    return b.write(d / "scene.gltf")


def good_probe_bytes(tmp_path):
    return sg.write_shprobe_v1(tmp_path / "good.shprobe", np.ones((2, 9, 3)), np.array([[[0, 1]]], np.int32),
                               (0, 0, 0), 1.0)


def expect_error(proc, *fragments):
    assert proc.returncode > 0, f"exit {proc.returncode} (negative = killed by a signal)\n{proc.stderr}"
    assert "error" in proc.stderr
    for f in fragments:
        assert f in proc.stderr, f"expected {f!r} in:\n{proc.stderr}"
    assert "validation error" not in proc.stderr


def corrupt(data, offset, value_bytes):
    b = bytearray(data)
    b[offset:offset + len(value_bytes)] = value_bytes
    return bytes(b)


# DESIGN.md §4 layout: magic @0, version @4, count @8, dims @12, probes from 48 (160 bytes each),
# grid after the probes.
@pytest.mark.parametrize("name, mutate", [
    ("bad magic", lambda d: corrupt(d, 0, b"XXXX")),
    ("unknown version", lambda d: corrupt(d, 4, struct.pack("<I", 99))),
    ("truncated", lambda d: d[:100]),
    ("grid entry >= count", lambda d: corrupt(d, 48 + 2 * 160 + 4, struct.pack("<i", 2))),
    ("grid entry < -1", lambda d: corrupt(d, 48 + 2 * 160, struct.pack("<i", -5))),
    ("NaN coefficient", lambda d: corrupt(d, 48 + 16, struct.pack("<f", float("nan")))),
    ("overflowing dims", lambda d: corrupt(d, 12, struct.pack("<III", 0xFFFFFFFF, 0xFFFFFFFF, 0xFFFFFFFF))),
    ("empty file", lambda d: b""),
])
def test_malformed_shprobe(tmp_path, name, mutate):
    gltf = scene_with_probe_bytes(tmp_path, mutate(good_probe_bytes(tmp_path)))
    proc = viewer.run(gltf, "--headless", "--output", tmp_path / "x.png", "--width", 8, "--height", 8)
    expect_error(proc, "p.shprobe", "shProbeGrids[0]")
    assert not (tmp_path / "x.png").exists()


def v3_octree_bytes(tmp_path):
    """A version 3 corner octree of SH (2 x 1 x 1 roots of 1 m), as the bake writes it."""
    sys.path.insert(0, str(Path(__file__).resolve().parents[2] / "addon"))
    from schnee_probes import native
    tree = native.CornerOctree.uniform((0.0, 0.0, 0.0), 1.0, 0, (2, 1, 1))
    tree.finalize()
    path = tmp_path / "v3.shprobe"
    count = native.write_shprobe_v3(str(path), tree, np.ones((tree.info()["probe_count"], 9, 3), np.float32))
    return path.read_bytes(), count


def v3_scene(d, data, count):
    (d / "sh_coeffs").mkdir(exist_ok=True)
    (d / "sh_coeffs" / "p.shprobe").write_bytes(data)
    b = sg.GltfBuilder()
    b.node("Cube", mesh=b.mesh("cube", sg.cube(0.5)))
    e = sg.grid_entry("p", "sh_coeffs/p.shprobe", count, (0, 0, 0), (2, 1, 1), 1.0)
    e.update(version=3, structure="octree", representation="sh", storage="float32")
    b.probe_grids([e])
    return b.write(d / "scene.gltf")


def test_version_3_loads_and_an_unknown_version_or_structure_is_named(tmp_path):
    # docs/user-guide.md "What can go wrong": the engine reads versions 1 to 4 (a v3 octree
    # loads); a version or a v3 structure it does not know ends the run naming the value, the
    # offset and what it knows (the bake's reader's words), before any frame.
    data, count = v3_octree_bytes(tmp_path)
    assert struct.unpack_from("<II", data, 0)[1] == 3 and struct.unpack_from("<I", data, 100)[0] == 1  # octree
    viewer.check(viewer.run(v3_scene(tmp_path, data, count), "--headless", "--output", tmp_path / "ok.png",
                            "--width", 8, "--height", 8))
    assert (tmp_path / "ok.png").stat().st_size > 0
    shprobe = tmp_path / "sh_coeffs" / "p.shprobe"
    for mutate, message in [
        (lambda d: corrupt(d, 4, struct.pack("<I", 5)),
         "unknown version 5 at offset 4; this reader knows versions 1, 2, 3 and 4"),
        (lambda d: corrupt(d, 100, struct.pack("<I", 4)),
         "unknown structure 4 at offset 100; this reader knows 0 = grid, 1 = octree, 2 = tetrahedra"),
        (lambda d: corrupt(d, 100, struct.pack("<I", 3)),
         "the kd corner tree (structure 3 at offset 100) needs version 4, not 3"),
        (lambda d: corrupt(d, 4, struct.pack("<I", 4)),
         "structure 1 at offset 100 in a version 4 file; version 4 holds 3 = kd corner tree only"),
    ]:
        gltf = v3_scene(tmp_path, mutate(data), count)
        proc = viewer.run(gltf, "--headless", "--output", tmp_path / "x.png", "--width", 8, "--height", 8)
        assert proc.returncode == 1, proc.stderr
        assert f"schnee-view: error: shProbeGrids[0] 'p': cannot read {shprobe}: {message}" in proc.stderr, proc.stderr
        assert not (tmp_path / "x.png").exists()


def test_good_shprobe_control(tmp_path):
    # The unmodified bytes load: the failures above come from the mutations alone.
    gltf = scene_with_probe_bytes(tmp_path, good_probe_bytes(tmp_path))
    viewer.check(viewer.run(gltf, "--headless", "--output", tmp_path / "x.png", "--width", 8, "--height", 8))
    assert (tmp_path / "x.png").stat().st_size > 0


def test_missing_shprobe_file(tmp_path):
    gltf = scene_with_probe_bytes(tmp_path, b"")
    (tmp_path / "sh_coeffs" / "p.shprobe").unlink()
    expect_error(viewer.run(gltf, "--headless", "--print-assignments"), "p.shprobe")


@pytest.mark.parametrize("text, fragment", [
    ('{"asset": {"version": "2.0"}, "scenes": [', "cannot load"),
    ("not json at all", "cannot load"),
    ('{"asset": {"version": "2.0"}, "nodes": [{"mesh": 3}], "scenes": [{"nodes": [0]}]}', "cannot load"),
    ('{"asset": {"version": "2.0"}, "meshes": [{"primitives": [{"attributes": {"POSITION": 9}}]}],'
     ' "nodes": [{"mesh": 0}], "scenes": [{"nodes": [0]}]}', "cannot load"),
    ('{"asset": {"version": "2.0"}, "buffers": [{"byteLength": 64, "uri": "missing.bin"}]}', "cannot load"),
])
def test_malformed_gltf(tmp_path, text, fragment):
    p = tmp_path / "bad.gltf"
    p.write_text(text)
    expect_error(viewer.run(p, "--headless", "--output", tmp_path / "x.png"), fragment, "bad.gltf")


def test_missing_gltf(tmp_path):
    expect_error(viewer.run(tmp_path / "nope.gltf", "--headless", "--output", tmp_path / "x.png"), "nope.gltf")


@pytest.mark.parametrize("args, fragment", [
    (["--width", "0"], "bad value '0' for --width"),
    (["--width", "abc"], "bad value 'abc' for --width"),
    (["--exposure", "nan"], "bad value 'nan' for --exposure"),
    (["--tonemap", "reinhard"], "bad value 'reinhard' for --tonemap"),
    (["--frobnicate"], "unknown option '--frobnicate'"),
    (["--move", "Cube", "1", "2"], "--move needs 4 value(s)"),
])
def test_bad_command_line(tmp_path, args, fragment):
    gltf = scene_with_probe_bytes(tmp_path, good_probe_bytes(tmp_path))
    proc = viewer.run(gltf, "--headless", "--output", tmp_path / "x.png", *args, validation=False)
    assert proc.returncode == 2
    assert fragment in proc.stderr


def test_unknown_camera_and_node(tmp_path):
    gltf = scene_with_probe_bytes(tmp_path, good_probe_bytes(tmp_path))
    expect_error(viewer.run(gltf, "--headless", "--output", tmp_path / "x.png", "--camera", "Nope"),
                 "no camera named 'Nope'")
    expect_error(viewer.run(gltf, "--headless", "--print-assignments", "--move", "Ghost", "0", "0", "0"),
                 "no node named 'Ghost'")


def test_empty_scene_renders_black(tmp_path):
    p = tmp_path / "empty.gltf"
    p.write_text('{"asset": {"version": "2.0"}, "scenes": [{"nodes": []}], "scene": 0}')
    out = tmp_path / "empty.exr"
    viewer.check(viewer.run(p, "--headless", "--output", out, "--width", 8, "--height", 8))
    assert np.all(viewer.read_image(out) == 0)


def test_version3_octree_loads_and_rotated_octree_is_refused(tmp_path):
    # A valid version 3 file (corner octree, 8 probes) is read by the engine (docs/engine.md "Version 3
    # grids"); the entry written for a dense grid disagrees with it and is reported, the file is used.
    # The same file with rotated axes (orthonormal, so the reader accepts it) is refused with the core's
    # message, never misread.
    sys.path.insert(0, str(Path(__file__).resolve().parents[2] / "addon"))
    from schnee_probes import native
    tree = native.CornerOctree.uniform((0, 0, 0), 1.0, 0, (1, 1, 1))
    tree.finalize()
    src = tmp_path / "v3.shprobe"
    assert native.write_shprobe_v3(str(src), tree, np.ones((tree.probe_count, 9, 3))) == 8
    assert native.read_shprobe(str(src)).version == 3
    gltf = scene_with_probe_bytes(tmp_path, src.read_bytes())
    proc = viewer.check(viewer.run(gltf, "--headless", "--output", tmp_path / "x.png", "--width", 8, "--height", 8))
    assert "shProbeGrids[0] 'p': structure 'grid' but the file has 'octree' (using the file)" in proc.stderr
    assert "probeCount 2 but the file has 8" in proc.stderr
    assert (tmp_path / "x.png").exists()
    # Axes at offset 48 (docs/shprobe-format.md "Version 3"): x and z swapped, still orthonormal.
    rotated = corrupt(src.read_bytes(), 48, struct.pack("<9f", 0, 0, 1, 0, 1, 0, 1, 0, 0))
    gltf = scene_with_probe_bytes(tmp_path, rotated)
    proc = viewer.run(gltf, "--headless", "--output", tmp_path / "y.png", "--width", 8, "--height", 8)
    expect_error(proc, "shProbeGrids[0]", "p.shprobe", "rotated axes")
    assert not (tmp_path / "y.png").exists()
