""".shprobe version 4 (docs/shprobe-format.md "Version 4", the kd corner tree) through the Python module.

The header and section bytes are read with ``struct`` at the offsets of the format's table and compared
with the tree's own arrays (CornerOctree.info, split_tree); the file's interpolation
(interpolation_from_file) must weigh the probes as the tree does; a tree of cubes is still written as
version 3 structure 1; a corrupt split tree is refused with the reader's message. Runtime < 1 s."""
import struct

import numpy as np
import pytest

from schnee_probes import native


def box_tree(seed):
    """2 x 1 x 2 roots of 2^2 min cells (0.25 m), three passes of random per-axis splits, finalized."""
    rng = np.random.default_rng(seed)
    t = native.CornerOctree.uniform((0.5, -1.0, 2.0), 0.25, 2, (2, 1, 2))
    for _ in range(3):
        masks = np.where(rng.random(t.leaf_count) < 0.4, rng.integers(1, 8, t.leaf_count), 0)
        t.split_axes(masks.astype(np.uint8))
    t.finalize()
    return t


@pytest.mark.parametrize("seed", [1, 2, 3])
def test_header_and_sections_at_the_documented_offsets(tmp_path, seed):
    t = box_tree(seed)
    info = t.info()
    assert (info["levels"].min(axis=1) != info["levels"].max(axis=1)).any(), "no box in the tree"
    P, N, H = t.probe_count, t.leaf_count, info["hanging_count"]
    nodes = t.split_tree()
    K = len(nodes)
    coeffs = np.random.default_rng(seed).normal(size=(P, 4, 3))
    path = tmp_path / "kd.shprobe"
    assert native.write_shprobe_v3(str(path), t, coeffs) == P
    b = path.read_bytes()
    rp = 16 * 4 + 16  # record: 4 colours (band 1) + (scale, ambient, validity, 0)
    assert len(b) == 128 + rp * P + 16 * P + 48 * N + 32 * H + 4 * K
    magic, version, count, band, flags = struct.unpack_from("<5I", b, 0)
    assert (magic, version, count, band, flags) == (0x52485053, 4, P, 1, 1)
    assert struct.unpack_from("<3I", b, 20) == tuple(int(v) for v in info["dims"])
    assert struct.unpack_from("<7I", b, 92) == (0, 0, 3, N, H, 2, K)  # SH, float32, kd tree, N, H, R, K
    assert struct.unpack_from("<2I", b, 120) == (0, 0)
    leaves = np.frombuffer(b, np.uint32, N * 12, 128 + (rp + 16) * P).reshape(N, 12)
    assert (leaves[:, :3] == info["leaves"][:, :3]).all()
    assert (leaves[:, 3] == native.pack_levels(info["levels"])).all()
    assert (leaves[:, 4:].view(np.int32) == info["leaf_corners"]).all()
    at = 128 + (rp + 16) * P + 48 * N + 32 * H
    assert (np.frombuffer(b, np.uint32, K, at) == nodes).all()
    f = native.read_shprobe(str(path))
    assert (f.version, f.structure, f.root_level) == (4, "kdtree", 2)
    assert (f.split_nodes == nodes).all() and (f.leaves[:, 3] == leaves[:, 3]).all()
    assert np.allclose(f.coeffs, coeffs.astype(np.float32))


def test_file_interpolation_weighs_as_the_tree(tmp_path):
    t = box_tree(7)
    path = tmp_path / "kd.shprobe"
    native.write_shprobe_v3(str(path), t, np.ones((t.probe_count, 1, 3)))
    ft = native.interpolation_from_file(str(path))
    pts = np.random.default_rng(8).uniform((0.5, -1.0, 2.0), (2.5, 0.0, 4.0), (3000, 3))
    pa, wa = t.query(pts)
    pb, wb = ft.query(pts)
    assert (pa[:, 0] >= 0).all()
    assert (pa == pb).all() and np.abs(wa - wb).max() <= 1e-12


def test_a_tree_of_cubes_stays_version_3(tmp_path):
    t = native.CornerOctree.uniform((0.0, 0.0, 0.0), 0.5, 2, (2, 1, 2))
    t.split_axes(np.array([7, 0, 0, 0], np.uint8))  # all three axes: eight cubes
    t.finalize()
    path = tmp_path / "oct.shprobe"
    native.write_shprobe_v3(str(path), t, np.ones((t.probe_count, 1, 3)))
    b = path.read_bytes()
    assert struct.unpack_from("<I", b, 4)[0] == 3 and struct.unpack_from("<I", b, 100)[0] == 1
    assert native.read_shprobe(str(path)).structure == "octree"


def test_corrupt_split_tree_is_refused_with_its_message(tmp_path):
    t = box_tree(4)
    path = tmp_path / "kd.shprobe"
    native.write_shprobe_v3(str(path), t, np.ones((t.probe_count, 1, 3)))
    b = bytearray(path.read_bytes())
    K = struct.unpack_from("<I", b, 116)[0]
    at = len(b) - 4 * K
    split = next(i for i in range(K) if struct.unpack_from("<I", b, at + 4 * i)[0] & 3)
    struct.pack_into("<I", b, at + 4 * split, 0 << 2 | 1)  # a split whose children would be nodes 0 and 1
    with pytest.raises(native.SchneeError, match=rf"split-tree node {split} \(offset {at + 4 * split}\) names "
                                                 r"children 0 and 1; they must come after it"):
        native.read_shprobe_bytes(bytes(b))


def test_dense_resample_of_a_linear_field(tmp_path):
    # Boxes with hanging rules reproduce a field linear in position: the dense version 1 grid of the
    # version 4 file holds it at every cell centre (closed form; float32 storage).
    t = box_tree(5)
    pos = t.positions()
    f = 1.0 + 0.5 * pos[:, 0] - 0.25 * pos[:, 1] + 0.75 * pos[:, 2]
    coeffs = np.zeros((t.probe_count, 9, 3))
    coeffs[:, 0, :] = f[:, None]
    path = tmp_path / "kd.shprobe"
    native.write_shprobe_v3(str(path), t, coeffs)
    d = native.resample_shprobe_dense(str(path))
    assert d.grid_dims == (8, 4, 8) and d.probe_count == 256
    X, Y, Z = d.grid_dims
    idx = np.arange(X * Y * Z)
    centre = np.array(d.grid_origin) + d.grid_spacing * (np.stack([idx % X, idx // X % Y, idx // (X * Y)], 1) + 0.5)
    want = 1.0 + 0.5 * centre[:, 0] - 0.25 * centre[:, 1] + 0.75 * centre[:, 2]
    assert np.abs(d.coeffs[d.grid, 0, 0] - want).max() < 1e-5
