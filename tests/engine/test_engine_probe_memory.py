"""Which probe storage buffers schnee-view uploads (docs/engine.md "Probe buffers", issue 30 "GPU memory per
probe"): with --probe-path bricks and every grid a bricked tree grid or a dense grid's texture (SH, no probe
view) the file's probes, the cell buffer and the cell index (but a dense grid's masks) are not uploaded; the probe buffer holds the fallback probe and the
per-object slots (moved down to entry 1), the cell index one dummy entry; tetrahedra are read through the
objects' slots only, so they join. The cell buffer is uploaded for the probe view only. Real lavapipe, validation on
(viewer.run).

Shading must not change: the same scene with and without the file's probes on the GPU renders bit for bit
alike. The A/B pair is one scene and the same scene with a second grid, of ambient cubes, far from every object
and pixel (a cube grid needs the file's probes, so the engine uploads them; the tree grid is first, so every
pixel and object takes the same grid either way). Per object is also compared with --probe-path buffers, which reads the
same slot. A v1 dense grid joins them (its texture and its step 5, the objects' slots), its cell index the
masks alone. Scenes that keep the file's probes (the probe view, ambient cubes) render as before.

The `probe memory:` / `probe bricks:` lines are checked against an independent sum: the pool's texels x 8 B
(RGBA16F), the indirection's x 16 B (RGBA32UI), 16 B per brick of brick tables, 64 B per visibility record
(from the bricks' own report lines), and the storage buffers at the struct sizes of shaders/sv_gpu.h
(SV_SIZE_CHECK: sv_gpu_probe 416, _half 208, sv_gpu_cube 112, _half 56, sv_gpu_cell 32, sv_gpu_grid 128,
int 4) from the scene's object, probe and cell counts.
"""
import json
import re

import numpy as np
import pytest

from test_engine_bricks import tree_and_entry
from test_engine_perpixel import write_grid as write_grid_v1
from test_engine_v3 import CUBE_CENTRES, lattice_scene, octree, random_sh, sg, viewer
from test_engine_v3 import write_grid as write_grid_v3

N = 65
PROBE, PROBE_HALF, CUBE, CUBE_HALF, CELL, GRID, INT = 416, 208, 112, 56, 32, 128, 4
NOT_UPLOADED = "file probes not uploaded"


def render(scene, out, *args):
    proc = viewer.check(viewer.run(scene, "--headless", "--output", out, "--width", N, "--height", N, *args))
    return viewer.read_image(out)[..., :3], proc.stderr


def memory(err):
    """The `probe memory:` line's figures (bytes) and its per-probe value."""
    m = re.search(r"probe memory: (\d+) B on the GPU for (\d+) file probe\(s\), ([\d.]+) B per probe: pool (\d+) B, "
                  r"indirection (\d+) B, brick tables and records (\d+) B, storage buffers (\d+) B \(probes (\d+), "
                  r"probes half (\d+), cubes (\d+), cubes half (\d+), cells (\d+), grids (\d+), cell index (\d+)\); "
                  r"(file probes (?:not )?uploaded)", err)
    assert m, err
    keys = ["total", "file_probes", "per_probe", "pool", "index", "vis", "buffers", "probes", "probes_half", "cubes",
            "cubes_half", "cells", "grids", "cell_index"]
    out = {k: (float(v) if k == "per_probe" else int(v)) for k, v in zip(keys, m.groups()[:14])}
    out["uploaded"] = m.group(15) == "file probes uploaded"
    return out


def bricks_line(err):
    m = re.search(r"probe bricks: (\d+) bricks \((\d+) texels\) of (\d+) probes; pool (\d+) x (\d+) x (\d+) (\w+) "
                  r"\((\d+) groups\), (\d+) B; indirection (\d+) x (\d+) x (\d+), (\d+) B; GPU memory ([\d.]+) B per "
                  r"probe \(storage buffers, \w+: ([\d.]+) B per probe\); allocated ([\d.]+) B per file probe", err)
    assert m, err
    g = m.groups()
    return {"bricks": int(g[0]), "probes": int(g[2]), "pool": tuple(map(int, g[3:6])), "format": g[6],
            "pool_bytes": int(g[8]), "index": tuple(map(int, g[9:12])), "index_bytes": int(g[12]),
            "buffers_path": float(g[14]), "allocated": float(g[15])}


def vis_line(err):
    m = re.search(r"probe brick visibility: (\d+) record\(s\) .*?, (\d+) B of brick tables", err)
    assert m, err
    return int(m.group(1)) * 64 + int(m.group(2))


def objects(err):
    return int(re.search(r"loaded .*?: (\d+) object\(s\)", err).group(1))


def with_far_cube_grid(d, scene):
    """The scene plus a grid of ambient cubes 100 m away (appended: the tree grid stays the first grid). Cube
    grids have no bricks and shade per pixel from the buffers, so the engine uploads the file's probes; the pool
    is the same (a dense SH grid would join it and move every texture coordinate by a rounding)."""
    t = octree()
    cubes = np.abs(random_sh(t.probe_count, 9)[:, :6])
    far = write_grid_v3(d, t, cubes, name="far", representation="ambientCube")
    far["gridOrigin"] = [100.0, 100.0, 100.0]
    doc = json.loads(scene.read_text())
    doc["scenes"][0]["extensions"]["VULKAN_SCHNEE_engine_properties"]["shProbeGrids"].append(far)
    out = scene.parent / "with_far.gltf"
    out.write_text(json.dumps(doc))
    return out


@pytest.mark.parametrize("storage", ["float", "half"])
def test_octree_without_the_file_probes_shades_bit_for_bit_alike(tmp_path, storage):
    tree = octree()
    entry = write_grid_v3(tmp_path, tree, random_sh(tree.probe_count, 3))
    scene, moves = lattice_scene(tmp_path, entry)  # floor per pixel, 8 cubes per object (moved in)
    args = [*moves, "--probe-storage", storage]
    img, err = render(scene, tmp_path / "a.exr", *args)
    m = memory(err)
    assert not m["uploaded"] and NOT_UPLOADED in err, err
    img_b, err_b = render(with_far_cube_grid(tmp_path, scene), tmp_path / "b.exr", *args)
    assert memory(err_b)["uploaded"], err_b
    assert np.array_equal(img, img_b)
    assert img.max() > 0.1  # lit: the floor and the cubes read the bricks and the slots
    # Per object everywhere: the slot at entry 1 + i; --probe-path buffers reads the same slot at total + i.
    obj, err_o = render(scene, tmp_path / "o.exr", *args, "--probe-mode", "object")
    obj_buf, err_ob = render(scene, tmp_path / "ob.exr", *args, "--probe-mode", "object", "--probe-path", "buffers")
    assert not memory(err_o)["uploaded"] and memory(err_ob)["uploaded"]
    assert np.array_equal(obj, obj_buf)
    assert len(CUBE_CENTRES) + 1 == objects(err)


def test_kd_tree_without_the_file_probes_shades_bit_for_bit_alike(tmp_path):
    _, _, entry = tree_and_entry(tmp_path, "kd", lambda t: random_sh(t.probe_count, 4))
    scene, moves = lattice_scene(tmp_path, entry)
    img, err = render(scene, tmp_path / "a.exr", *moves)
    img_b, err_b = render(with_far_cube_grid(tmp_path, scene), tmp_path / "b.exr", *moves)
    assert not memory(err)["uploaded"] and memory(err_b)["uploaded"]
    assert np.array_equal(img, img_b)


def test_report_is_the_allocation_and_below_the_old_sum(tmp_path):
    tree = octree()
    entry = write_grid_v3(tmp_path, tree, random_sh(tree.probe_count, 3))
    scene, moves = lattice_scene(tmp_path, entry)
    _, err = render(scene, tmp_path / "a.exr", *moves)
    _, err_buf = render(scene, tmp_path / "b.exr", *moves, "--probe-path", "buffers")
    m, b, buf = memory(err), bricks_line(err), memory(err_buf)
    assert b["format"] == "RGBA16F" and m["file_probes"] == tree.probe_count == b["probes"]
    pool = int(np.prod(b["pool"])) * 8
    index = int(np.prod(b["index"])) * 16
    vis = vis_line(err)  # brick tables (16 B per brick) + records (64 B each)
    assert (pool, index, vis) == (b["pool_bytes"], b["index_bytes"], m["vis"]) == (m["pool"], m["index"], m["vis"])
    # The storage buffers left: the fallback and one slot per object, one-entry dummies for the rest.
    slots = (1 + objects(err)) * PROBE
    storage = slots + PROBE_HALF + CUBE + CUBE_HALF + CELL + GRID + INT
    assert (m["probes"], m["buffers"]) == (slots, storage)
    total = pool + index + vis + storage
    assert m["total"] == total
    assert abs(m["per_probe"] - total / tree.probe_count) <= 0.05
    assert abs(b["allocated"] - total / tree.probe_count) <= 0.05
    # Before (both paths uploaded the buffers path's storage buffers): the bricks plus those.
    old = pool + index + vis + buf["buffers"]
    assert buf["uploaded"] and buf["probes"] == (1 + tree.probe_count + tree.info()["hanging_count"]
                                                 + objects(err)) * PROBE
    assert total < old and m["buffers"] * 5 < buf["buffers"], (total, old)


def test_v1_dense_grid_needs_no_file_probes(tmp_path):
    """A dense grid under the bricks: per pixel its texture (step 5 too, docs/grid-field.md), per object its
    slot (a single probe of weight 1 too), so the file's probes stay off the GPU; the cell index holds the
    neighbour masks alone. Bit for bit as the same scene with the file's probes uploaded (a far cube grid)."""
    grid = np.arange(32, dtype=np.int32).reshape(2, 4, 4).transpose(1, 0, 2).copy()  # (Z, Y, X) = 4 x 2 x 4
    grid[1, 0, 2] = -1
    count = 32
    entry = write_grid_v1(tmp_path, "probes", random_sh(count, 11), grid, (0, 0, 0), 1.0)
    b_ = sg.GltfBuilder()
    mp = b_.material("floor", sh_scale=1.0, ambient_term=0.0, probe_mode="pixel")
    mo = b_.material("box", sh_scale=1.0, ambient_term=0.0, probe_mode="object")
    b_.node("Floor", mesh=b_.mesh("floor", sg.quad(4.0, 4.0, 1), mp), translation=(2.0, 0.3, 2.0))
    b_.node("Box", mesh=b_.mesh("box", sg.cube(0.1), mo), translation=(1.3, 0.8, 2.6))
    # At the centre of cell (1, 0, 2): one probe has all the weight (it used to name the file probe).
    b_.node("Centred", mesh=b_.mesh("centred", sg.cube(0.1), mo), translation=(1.5, 0.5, 2.5))
    b_.node("Camera", camera=b_.ortho_camera("top", 2.0), translation=(2.0, 3.0, 2.0), rotation=sg.ROT_LOOK_DOWN)
    b_.probe_grids([entry])
    scene = b_.write(tmp_path / "v1.gltf")
    proc = viewer.check(viewer.run(scene, "--headless", "--output", tmp_path / "a.exr", "--width", N, "--height",
                                   N, "--print-assignments"))
    img, err = viewer.read_image(tmp_path / "a.exr")[..., :3], proc.stderr
    m, b = memory(err), bricks_line(err)
    assert not m["uploaded"] and NOT_UPLOADED in err and "probe bricks: 1 dense grid(s)" in err, err
    # --print-assignments (before the renderer) still names the file probe: entry 1 + grid[2, 0, 1].
    assert viewer.assignments(proc.stdout)["Centred"] == 1 + int(grid[2, 0, 1])
    # The fallback and one slot per object, the masks (1 int per cell), one-entry dummies for the rest.
    storage = (1 + objects(err)) * PROBE + PROBE_HALF + CUBE + CUBE_HALF + CELL + GRID + grid.size * INT
    assert (m["probes"], m["cell_index"], m["buffers"]) == ((1 + objects(err)) * PROBE, grid.size * INT, storage)
    # Dense only: no indirection and no brick tables (the 16-B stand-ins stay bound).
    total = b["pool_bytes"] + 16 + 16 + storage
    assert (m["index"], m["vis"], m["total"]) == (16, 16, total)
    assert abs(b["allocated"] - total / count) <= 0.0501 and abs(m["per_probe"] - total / count) <= 0.0501
    assert b["pool_bytes"] == int(np.prod(b["pool"])) * 8
    # What the grid takes on the buffers path: its entries at the L4 stride and 8 B per cell (index and mask).
    assert abs(b["buffers_path"] - (count * PROBE + grid.size * 8) / count) <= 0.05
    # The same scene with the file's probes uploaded: the same image, per pixel and per object.
    img_b, err_b = render(with_far_cube_grid(tmp_path, scene), tmp_path / "b.exr")
    mb = memory(err_b)
    assert mb["uploaded"] and mb["cell_index"] > 2 * grid.size * INT, err_b
    assert np.array_equal(img, img_b) and img.max() > 0.1
    # Per object everywhere: the slots (no file probes) against --probe-path buffers (the Centred box its file
    # probe there, scale 1: the same value).
    obj, err_o = render(scene, tmp_path / "o.exr", "--probe-mode", "object")
    obj_buf, err_ob = render(scene, tmp_path / "ob.exr", "--probe-mode", "object", "--probe-path", "buffers")
    assert not memory(err_o)["uploaded"] and memory(err_ob)["uploaded"]
    assert np.array_equal(obj, obj_buf) and obj.max() > 0.1


def test_tetrahedra_need_only_the_slots(tmp_path):
    """No bricks for tetrahedra: per object and per pixel each fragment takes its object's slot, on either path;
    bricks (the fallback and the slots only) and buffers (every entry) render bit for bit alike."""
    from schnee_probes import native
    tree = octree()
    tet = native.Tetrahedra.create(tree.positions())
    entry = write_grid_v3(tmp_path, tet, random_sh(tree.probe_count, 6), name="tets")
    scene, moves = lattice_scene(tmp_path, entry, floor=False)
    img, err = render(scene, tmp_path / "a.exr", *moves, "--probe-mode", "pixel")
    img_buf, err_buf = render(scene, tmp_path / "b.exr", *moves, "--probe-mode", "pixel", "--probe-path", "buffers")
    m = memory(err)
    assert not m["uploaded"] and memory(err_buf)["uploaded"] and "probe bricks:" not in err
    assert m["probes"] == (1 + objects(err)) * PROBE
    assert np.array_equal(img, img_buf) and img.max() > 0.1
    # An octree and tetrahedra in one scene: still the slots only.
    both, _ = lattice_scene(tmp_path, entry, floor=False)
    doc = json.loads(both.read_text())
    tree_entry = write_grid_v3(tmp_path, tree, random_sh(tree.probe_count, 3))
    doc["scenes"][0]["extensions"]["VULKAN_SCHNEE_engine_properties"]["shProbeGrids"].insert(0, tree_entry)
    both.write_text(json.dumps(doc))
    _, err_both = render(both, tmp_path / "c.exr", *moves)
    assert not memory(err_both)["uploaded"] and "probe bricks:" in err_both


def test_probe_view_keeps_the_file_probes(tmp_path):
    tree = octree()
    entry = write_grid_v3(tmp_path, tree, random_sh(tree.probe_count, 3))
    scene, moves = lattice_scene(tmp_path, entry)
    _, err = render(scene, tmp_path / "a.png", *moves, "--probe-view")
    m = memory(err)
    # A sphere per buffer entry (probes and resolved hanging nodes), an outline per leaf.
    cells = (tree.probe_count + tree.info()["hanging_count"] + tree.leaf_count) * CELL
    assert m["uploaded"] and m["cells"] == cells and m["probes"] > (1 + objects(err)) * PROBE
