""".shprobe version 4 (the kd corner tree, docs/shprobe-format.md "Version 4") in schnee-view: boxes
with per-axis levels per pixel (the GLSL descent of the file's split tree and the per-axis weights,
docs/aniso-refinement.md "What the engine's GLSL changes") and per object (the core's
pb_interp_query_cotree on the file's tree), mirroring tests/engine/test_engine_v3.py's octree cases.

The file comes from a box tree of the core (CornerOctree.split_axes, finalized with the nesting rule's
forced splits) through the writer, which picks version 4 for it. Expected values: the CPU model
(CornerOctree.query, tested against closed forms in tests/python/test_native_boxes.py), the closed form
of a field linear in position, and a numpy transcription of the documented per-pixel rule from the
file's own arrays."""
import re
import struct

import numpy as np
import pytest

from test_engine_v3 import (CUBE_CENTRES, N, SHELF, Y0, assert_engine_equals_cpu_model, floor_mask, interpolate,
                            lattice_scene, linear, linear_sh, pixel_of, pixel_points, random_sh, ref, render, sg,
                            shelf_first_hit, viewer)
from schnee_probes import native


def kd_tree():
    """Lattice of 0.5 m min cells, 8 x 4 x 8 (4 x 2 x 4 m from the origin), root level 2: 2 x 1 x 2 roots of
    2 m. The roots split along x, z, x and z, y; then the leaves whose min corner has x < 4 along z and
    those with z >= 4 along x; the nesting rule adds what it needs. Slabs and cubes meet at the roots'
    borders, so hanging nodes sit on faces and edges of boxes of different shapes."""
    t = native.CornerOctree.uniform((0.0, 0.0, 0.0), 0.5, 2, (2, 1, 2))
    lv = t.info()["leaves"]
    t.split_axes(np.array([{(0, 0): 1, (4, 0): 4, (0, 4): 5, (4, 4): 2}[(int(x), int(z))] for x, _, z, _ in lv],
                          np.uint8))
    lv = t.info()["leaves"]
    t.split_axes(np.where(lv[:, 0] < 4, 4, np.where(lv[:, 2] >= 4, 1, 0)).astype(np.uint8))
    t.finalize()
    info = t.info()
    assert (info["levels"].min(axis=1) != info["levels"].max(axis=1)).sum() > 10  # boxes, not cubes
    assert info["hanging_count"] > 5
    return t


def write_grid(d, tree, coeffs, name="p", storage="float32"):
    (d / "sh_coeffs").mkdir(exist_ok=True)
    path = d / "sh_coeffs" / f"{name}.shprobe"
    count = native.write_shprobe_v3(str(path), tree, coeffs, storage=storage)
    assert struct.unpack_from("<I", path.read_bytes(), 4)[0] == 4  # a version 4 file
    f = native.read_shprobe(str(path))
    e = sg.grid_entry(name, f"sh_coeffs/{name}.shprobe", count, f.grid_origin, f.grid_dims, f.grid_spacing)
    # The exporter's entry for a version 4 file (gltf_export._v3_fields, docs/export.md).
    e.update(version=4, structure="kdtree", representation=f.representation, storage=f.storage)
    assert f.structure == "kdtree"
    return e


@pytest.mark.parametrize("storage", ["float32", "float16"])
def test_kd_tree_per_pixel_and_per_object_equal_the_cpu_model(tmp_path, storage):
    # As the octree's test (float32 on the GPU against float64; half storage rounds probes, resolved
    # hanging nodes and slots to binary16), on boxes.
    tree = kd_tree()
    coeffs = random_sh(tree.probe_count, 3)
    entry = write_grid(tmp_path, tree, coeffs, storage=storage)
    assert_engine_equals_cpu_model(tmp_path, tree, entry, coeffs, storage, "v4.exr")


def test_kd_tree_reproduces_a_linear_field(tmp_path):
    # Boxes with hanging nodes reproduce a field linear in position exactly: the closed form Y0 * f(p),
    # per pixel and per object.
    tree = kd_tree()
    entry = write_grid(tmp_path, tree, linear_sh(tree.positions()))
    scene, moves = lattice_scene(tmp_path, entry)
    img, _ = render(scene, tmp_path / "lin.exr", *moves)
    keep, p = floor_mask()
    want = Y0 * linear(p[keep])
    assert np.abs(img[keep] - want[:, None]).max() < 2e-6 * want.max()
    for centre in CUBE_CENTRES:
        got = img[pixel_of(centre[0], centre[2], 2.0, 2.0, 2.0)]
        assert np.allclose(got, Y0 * linear(centre), rtol=2e-6), (centre, got)


def kd_pixel_ref(path, p, n, per_axis=True):
    """numpy of the documented per-pixel rule for a static surface (docs/aniso-refinement.md, "Visibility
    field"), from the file's own arrays: hanging nodes resolved as (A, a) in file order, the leaf holding p
    by brute force over the boxes, trilinear corner weights at t = (u - min) / s per axis x validity mass x
    back-face weight smoothstep(-0.1, 0.1, dot((c - p) / s, n)) with s the box's per-axis size in metres
    (per_axis False: one size, the largest, as an octree leaf's), renormalised; when that leaves nothing,
    the plain weights. No visibility field (no static triangles). E(n) of L2 SH per point."""
    f = native.read_shprobe(str(path))
    P, H = f.probe_count, len(f.hanging_sources)
    A = np.zeros((P + H, 9, 3))
    a = np.zeros(P + H)
    A[:P] = f.probe_scale[:, None, None] * f.coeffs
    a[:P] = 1.0
    for j in range(H):
        for src, w in zip(f.hanging_sources[j], f.hanging_weights[j]):
            if w > 0:
                A[P + j] += w * A[src]
                a[P + j] += w * a[src]
    origin, h = np.array(f.grid_origin, float), float(f.grid_spacing)
    lo = f.leaves[:, :3].astype(np.int64)
    size = 2.0 ** np.stack([f.leaves[:, 3] >> (8 * k) & 255 for k in range(3)], axis=1)
    out = np.zeros((len(p), 3))
    for i, (pi, ni) in enumerate(zip(p, n)):
        u = (pi - origin) / h
        q = np.minimum(np.floor(u), np.array(f.grid_dims) - 1)
        li = np.flatnonzero(((lo <= q) & (q < lo + size)).all(axis=1))
        assert len(li) == 1
        s = size[li[0]] if per_axis else np.full(3, size[li[0]].max())
        t = np.clip((u - lo[li[0]]) / size[li[0]], 0, 1)
        for backface in (True, False):
            e, wsum = np.zeros(3), 0.0
            for c in range(8):
                o = np.array([c & 1, (c >> 1) & 1, (c >> 2) & 1])
                w = np.prod(np.where(o, t, 1 - t))
                node = f.leaf_corners[li[0], c]
                w *= a[node]
                if backface:
                    corner = lo[li[0]] + o * size[li[0]]
                    w *= ref.smoothstep(-0.1, 0.1, np.dot((corner - u) / s, ni))
                if w <= 0:
                    continue
                e += w * ref.irradiance(A[node] / a[node], ni)
                wsum += w
            if wsum > 0:
                out[i] = e / wsum
                break
    return out


def test_kd_tree_per_pixel_on_a_movable_sphere_is_the_cpu_model(tmp_path):
    # A movable object gets the CPU model's plain interpolation at each surface point (no back-face
    # weights), here on a sphere across slabs of the x- and z-split roots and their hanging nodes.
    tree = kd_tree()
    coeffs = random_sh(tree.probe_count, 13)
    entry = write_grid(tmp_path, tree, coeffs)
    c, r = np.array([1.95, 0.8, 2.05]), 0.4
    b = sg.GltfBuilder()
    m = b.material("White", sh_scale=1.0, ambient_term=0.0, probe_mode="pixel")
    b.node("Sphere", mesh=b.mesh("sphere", sg.uv_sphere(r, 128, 64), m), translation=(5.0, 5.0, 5.0))
    b.node("Camera", camera=b.ortho_camera("top", r), translation=(c[0], 3.0, c[2]), rotation=sg.ROT_LOOK_DOWN)
    b.probe_grids([entry])
    scene = b.write(tmp_path / "sphere.gltf")
    img, proc = render(scene, tmp_path / "s.exr", "--move", "Sphere", *c)
    p = pixel_points(c[0], c[2], r, 0.0)
    d2 = (p[..., 0] - c[0]) ** 2 + (p[..., 2] - c[2]) ** 2
    on = d2 < (0.9 * r) ** 2
    p[..., 1] = c[1] + np.sqrt(np.maximum(r * r - d2, 0))
    nrm = (p - c) / r
    want = np.maximum([ref.irradiance(x, nn) for x, nn in zip(interpolate(tree, p[on], coeffs), nrm[on])], 0) / np.pi
    err = np.abs(img[on] - want).max()
    assert err < 1e-4 + 1e-3 * want.max(), (err, want.max())
    # The static surfaces' rule (back-face weights per corner) differs here: the case matters.
    backface = np.maximum(kd_pixel_ref(tmp_path / "sh_coeffs" / "p.shprobe", p[on], nrm[on]), 0) / np.pi
    assert np.abs(backface - want).max() > 0.05


def test_kd_tree_static_surface_uses_per_axis_back_face_weights(tmp_path):
    # A small static quad (0.1 m, normal +y) 4 cm above the floor inside the box (2, 0, 2) m of sizes
    # (1, 1, 2) m: away from the box's body diagonals and faces, so no corner segment crosses it (the
    # visibility field stays clear) and its pixels show the back-face weights alone. Per axis, the lower
    # corners lie -0.04 box heights away (weight 0): the image is the upper face's field. With one size
    # per box (the largest, 2 m) they would be -0.02 (weight 0.28) and the pixels differ.
    tree = kd_tree()
    info = tree.info()
    box = np.flatnonzero((info["leaves"][:, :3] == [4, 0, 4]).all(axis=1))
    assert len(box) == 1 and list(info["levels"][box[0]]) == [1, 1, 2]
    coeffs = random_sh(tree.probe_count, 21)
    entry = write_grid(tmp_path, tree, coeffs)
    cx, y0, cz, mag = 2.3, 0.04, 2.5, 0.045
    b = sg.GltfBuilder()
    m = b.material("White", sh_scale=1.0, ambient_term=0.0, probe_mode="pixel")
    b.node("Chip", mesh=b.mesh("chip", sg.quad(0.1, 0.1, 1), m), translation=(cx, y0, cz))
    b.node("Camera", camera=b.ortho_camera("top", mag), translation=(cx, 1.5, cz), rotation=sg.ROT_LOOK_DOWN)
    b.probe_grids([entry])
    scene = b.write(tmp_path / "chip.gltf")
    img, proc = render(scene, tmp_path / "c.exr")
    p = pixel_points(cx, cz, mag, y0).reshape(-1, 3)
    nrm = np.tile([0.0, 1.0, 0.0], (len(p), 1))
    path = tmp_path / "sh_coeffs" / "p.shprobe"
    want = np.maximum(kd_pixel_ref(path, p, nrm), 0).reshape(N, N, 3) / np.pi
    one_size = np.maximum(kd_pixel_ref(path, p, nrm, per_axis=False), 0).reshape(N, N, 3) / np.pi
    err = np.abs(img - want).max()
    assert err < 1e-5 + 1e-5 * want.max(), (err, want.max())
    assert np.abs(one_size - want).max() > 100 * (1e-5 + 1e-5 * want.max())  # the case tells them apart


OUTLINE = np.array([0.9, 0.75, 0.2])  # shaders/probe_outline.frag


def test_probe_view_outlines_each_box(tmp_path):
    # --probe-view draws the 12 edges of every leaf's box (sv_probe_pack.c leaf_outlines): from above, the
    # union of the boxes' x-z rectangles. Along each lattice line x = const (and z = const) at 0.5 m
    # steps, every 0.5 m piece between two probes is drawn exactly where some box has a side there,
    # computed here from the file's leaves (the pieces' middles, away from the probes' spheres).
    tree = kd_tree()
    entry = write_grid(tmp_path, tree, random_sh(tree.probe_count, 5))
    b = sg.GltfBuilder()
    b.node("Far", mesh=b.mesh("far", sg.cube(0.01), b.material("m")), translation=(50, -50, 50))
    b.node("Camera", camera=b.ortho_camera("top", 2.1), translation=(2.0, 3.0, 2.0), rotation=sg.ROT_LOOK_DOWN)
    b.probe_grids([entry])
    scene = b.write(tmp_path / "view.gltf")
    n = 253
    out = tmp_path / "v.exr"
    # the storage-buffer path's probe view (the leaves' outlines; the default bricks draw the brick view)
    viewer.check(viewer.run(scene, "--headless", "--output", out, "--width", n, "--height", n, "--probe-view",
                            "--probe-path", "buffers"))
    is_line = np.all(np.abs(viewer.read_image(out) - OUTLINE) < 1e-6, axis=-1)
    t = 2.0 + (2 * (np.arange(n) + 0.5) / n - 1) * 2.1  # pixel centres: column -> x, row -> z
    f = native.read_shprobe(str(tmp_path / "sh_coeffs" / "p.shprobe"))
    lo = f.leaves[:, :3] * 0.5
    hi = lo + 0.5 * 2.0 ** np.stack([f.leaves[:, 3] >> (8 * k) & 255 for k in range(3)], axis=1)
    drawn = {True: 0, False: 0}
    for a, b_ in ((0, 2), (2, 0)):  # lines x = c (a = 0) along z, and z = c along x
        for c in np.arange(0.0, 4.01, 0.5):
            for m in np.arange(0.25, 4.0, 0.5):
                want = bool((((lo[:, a] == c) | (hi[:, a] == c)) & (lo[:, b_] < m) & (m < hi[:, b_])).any())
                i = int(np.argmin(np.abs(t - c)))
                seg = (np.abs(t - m) < 0.12)
                got = is_line[seg][:, max(i - 1, 0):i + 2] if a == 0 else is_line[max(i - 1, 0):i + 2][:, seg].T
                assert bool(got.any(axis=1).all()) == want and (want or not got.any()), (a, c, m, want)
                drawn[want] += 1
    assert drawn[True] > 40 and drawn[False] > 10, drawn


def box_pair_table(tree, first_hit):
    """(leaf_count, 8, 8) uint8 of pb_cotree_pair_visibility for boxes from the closed-form segment test:
    [leaf, k, c] = round(255 t), t = first hit on the way from corner c to corner k (255 clear), corners
    at the box's per-axis sizes."""
    info = tree.info()
    origin, h = np.asarray(info["origin"], float), float(info["min_cell"])
    out = np.full((len(info["leaves"]), 8, 8), 255, np.uint8)
    for i, (row, lv) in enumerate(zip(info["leaves"], info["levels"])):
        s = 2.0 ** lv.astype(float)
        corner = [origin + h * (row[:3] + s * np.array([c & 1, c >> 1 & 1, c >> 2 & 1])) for c in range(8)]
        for k in range(8):
            for c in range(8):
                if k != c:
                    t = first_hit(corner[c], corner[k])
                    out[i, k, c] = 255 if t >= 1 else min(max(int(np.floor(255 * t + 0.5)), 1), 255)
    return out


def test_kd_tree_visibility_field_under_a_shelf_is_the_cpu_model(tmp_path):
    # Two 1 m roots, the left halved along x (slabs 0.5 x 1 x 1 m), the right along y (1 x 0.5 x 1 m);
    # probes at y = 1 hold radiance 5, at y = 0.5 radiance 1, at y = 0 radiance 0.05. The static shelf of
    # test_engine_v3 (x, z in [0.55, 0.95], y = 0.75) blocks segments between the left slab's corners; a
    # movable receiver at y = 0.4 across the border x = 1 is shaded per pixel with the boxes' visibility
    # field: every pixel equals the CPU model with the table built here from the closed-form segment test.
    tree = native.CornerOctree.uniform((0.0, 0.0, 0.0), 0.5, 1, (2, 1, 1))
    tree.split_axes(np.array([1, 2], np.uint8))
    tree.finalize()
    assert tree.leaf_count == 4 and tree.forced_splits == 0
    pos = tree.positions()
    level = np.where(pos[:, 1] > 0.75, 5.0, np.where(pos[:, 1] > 0.25, 1.0, 0.05))
    coeffs = np.stack([ref.uniform_coeffs(v) for v in level])
    entry = write_grid(tmp_path, tree, coeffs)
    b = sg.GltfBuilder()
    m = b.material("White", sh_scale=1.0, ambient_term=0.0, probe_mode="pixel")
    lo, hi, y = SHELF
    b.node("Shelf", mesh=b.mesh("shelf", sg.quad(hi - lo, hi - lo, 1), m), translation=(0.5 * (lo + hi), y, 0.5 * (lo + hi)))
    b.node("Receiver", mesh=b.mesh("receiver", sg.quad(0.6, 0.6, 1), m), translation=(9.0, 9.0, 9.0))
    cx, cz, mag = 1.0, 0.25, 0.24  # the receiver's pixels: z < 0.49, clear of the shelf above it
    b.node("Camera", camera=b.ortho_camera("top", mag), translation=(cx, 3.0, cz), rotation=sg.ROT_LOOK_DOWN)
    b.probe_grids([entry])
    scene = b.write(tmp_path / "beam.gltf")
    img, proc = render(scene, tmp_path / "b.exr", "--move", "Receiver", cx, 0.4, cz)
    assert "probe visibility masks: 224 segment(s)" in proc.stderr  # 4 boxes x 56 corner pairs
    p = pixel_points(cx, cz, mag, 0.4)
    table = box_pair_table(tree, shelf_first_hit)
    assert (table < 255).sum() > 0
    probes, weights = tree.query(p.reshape(-1, 3), pair_visibility=table)
    assert (probes[:, 0] >= 0).all()
    want = np.einsum("mk,mk->m", weights, level[np.maximum(probes, 0)]).reshape(N, N)
    pp, pw = tree.query(p.reshape(-1, 3))
    plain = np.einsum("mk,mk->m", pw, level[np.maximum(pp, 0)]).reshape(N, N)
    lum = img[..., 1]
    assert np.abs(lum - want).max() < 1e-5 * want.max(), np.abs(lum - want).max()
    assert np.abs(plain - want).max() > 0.05  # the shelf changes the picture


def test_corrupt_split_tree_ends_the_run_naming_the_node(tmp_path):
    # The engine reads version 4 with the core's reader: a split whose children are not after it ends the
    # run before any frame with the reader's words, the node and its offset.
    tree = kd_tree()
    entry = write_grid(tmp_path, tree, random_sh(tree.probe_count, 2))
    path = tmp_path / "sh_coeffs" / "p.shprobe"
    b = bytearray(path.read_bytes())
    K = struct.unpack_from("<I", b, 116)[0]
    at = len(b) - 4 * K
    struct.pack_into("<I", b, at, 0 << 2 | 1)  # root 0 split along x with children 0 and 1
    path.write_bytes(bytes(b))
    scene, moves = lattice_scene(tmp_path, entry)
    proc = viewer.run(scene, "--headless", "--output", tmp_path / "x.png", "--width", 8, "--height", 8, *moves)
    assert proc.returncode == 1, proc.stderr
    assert (f"schnee-view: error: shProbeGrids[0] 'p': cannot read {path}: split-tree node 0 (offset {at}) names "
            "children 0 and 1; they must come after it") in proc.stderr, proc.stderr
    assert not (tmp_path / "x.png").exists()


@pytest.mark.parametrize("probe_path", ["buffers", "bricks"])
def test_kd_tree_floor_next_to_a_wall_does_not_leak(tmp_path, probe_path):
    # test_engine_v3's leak case on slabs: three 1 m roots along x, each halved along y (1 x 0.5 x 1 m
    # boxes); probes at x = 0, 1 see radiance 0.05, at x = 2, 3 radiance 5. A static two-sided wall at
    # x = 1.7 and a floor at y = 0.1 for x in [0, 1.68]: the back-face weights (per axis: the corners
    # at y = 0 lie 0.2 box heights below the floor) keep the slab's upper corners, and every segment
    # from the bright ones to the dark ones meets the wall 0.3 of the way, so the visibility field keeps
    # the floor dark. Moved walls (no occluder): the plain rule's gradient towards x = 2.
    tree = native.CornerOctree.uniform((0.0, 0.0, 0.0), 0.5, 1, (3, 1, 1))
    tree.split_axes(np.full(3, 2, np.uint8))
    tree.finalize()
    pos = tree.positions()
    coeffs = np.stack([ref.uniform_coeffs(0.05 if x < 1.5 else 5.0) for x in pos[:, 0]])
    entry = write_grid(tmp_path, tree, coeffs)
    b = sg.GltfBuilder()
    m = b.material("White", sh_scale=1.0, ambient_term=0.0, probe_mode="pixel")
    b.node("Floor", mesh=b.mesh("floor", sg.quad(1.0, 1.68, 1), m), translation=(0.84, 0.1, 0.5))
    b.node("WallA", mesh=b.mesh("wall_a", sg.quad(1.0, 1.0, 0, -1.0), m), translation=(1.7, 0.5, 0.5))
    b.node("WallB", mesh=b.mesh("wall_b", sg.quad(1.0, 1.0, 0, 1.0), m), translation=(1.7, 0.5, 0.5))
    b.node("Camera", camera=b.ortho_camera("top", 0.84), translation=(0.84, 3.1, 0.5), rotation=sg.ROT_LOOK_DOWN)
    b.probe_grids([entry])
    scene = b.write(tmp_path / "wall.gltf")
    p = pixel_points(0.84, 0.5, 0.84, 0.1)
    on_floor = (p[..., 2] > 0.02) & (p[..., 2] < 0.98)
    path = ("--probe-path", probe_path)
    img, proc = render(scene, tmp_path / "w.exr", *path)
    if probe_path == "bricks":  # built with the static scene's tracer: records for the blocked brick cells
        assert re.search(r"probe brick visibility: [1-9][0-9]* record", proc.stderr), proc.stderr
    assert "probe visibility masks: 336 segment(s)" in proc.stderr  # 6 boxes x 56 corner pairs
    assert np.allclose(img[on_floor], 0.05, rtol=1e-5), img[on_floor].max()
    img, _ = render(scene, tmp_path / "m.exr", "--move", "WallA", 1.71, 0.5, 0.5, "--move", "WallB", 1.71, 0.5, 0.5,
                    *path)
    # No occluder: near x = 1.68 the upper corners' t_x = 0.68 of the bright ones.
    assert img[on_floor].max() > 0.05 + 0.6 * 4.95
