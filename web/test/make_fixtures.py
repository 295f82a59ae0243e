"""Fixtures for the JavaScript `.shprobe` reader's tests (web/test/shprobe.test.js).

Writes `.shprobe` files into OUT_DIR with the project's real writer (schnee_probes.native:
write_shprobe for versions 1 and 2, write_shprobe_v3 for octrees, tetrahedra and kd corner trees,
float32 and binary16, SH and ambient cubes; version 3 dense grids, which no Python entry point writes,
are packed here with `struct` from docs/shprobe-format.md's table), then malformed variants of them
(one field changed at the offset of the format's tables, one per refusal of the C reader) and seeded
random corruptions. For every file it records what the C reader makes of it: native.read_shprobe's
values, or its refusal (result code and message, from the file reader and from the memory reader).
The JavaScript reader must give the same verdict, the same values and the same message.

usage: PYTHONPATH=addon python3 web/test/make_fixtures.py OUT_DIR   -> OUT_DIR/*.shprobe, manifest.json
"""
import json
import os
import struct
import sys

import numpy as np

from schnee_probes import native

MAGIC = 0x52485053
NAN_BITS, NEG_NAN_BITS, INF_BITS, NEG_INF_BITS = 0x7FC00000, 0xFFC00000, 0x7F800000, 0xFF800000


# ---- byte access ------------------------------------------------------------------------------------

def u32(b, off):
    return struct.unpack_from("<I", b, off)[0]


def put_u32(b, off, v):
    b = bytearray(b)
    struct.pack_into("<I", b, off, v & 0xFFFFFFFF)
    return bytes(b)


def put_i32(b, off, v):
    return put_u32(b, off, v & 0xFFFFFFFF)


def put_f32(b, off, v):
    b = bytearray(b)
    struct.pack_into("<f", b, off, v)
    return bytes(b)


def put_u16(b, off, v):
    b = bytearray(b)
    struct.pack_into("<H", b, off, v)
    return bytes(b)


def layout(b):
    """Offsets of a valid file's sections, from its header (docs/shprobe-format.md)."""
    v = u32(b, 4)
    lay = {"version": v, "P": u32(b, 8), "positions": False, "structure": 0, "N": 0, "H": 0, "K": 0, "cb": 16}
    if v == 1:
        lay.update(header=48, coeffs=9, dims=struct.unpack_from("<3I", b, 12))
    else:
        band, flags = u32(b, 12), u32(b, 16)
        lay.update(header=96 if v == 2 else 128, coeffs=(band + 1) ** 2, positions=bool(flags & 1),
                   dims=struct.unpack_from("<3I", b, 20))
        if v >= 3:
            rep, sto, structure, n, h = struct.unpack_from("<5I", b, 92)
            lay.update(structure=structure, N=n, H=h, cb=8 if sto == 1 else 16, coeffs=6 if rep == 1 else lay["coeffs"])
        if v == 4:
            lay["K"] = u32(b, 116)
    P = lay["P"]
    lay["record"] = lay["cb"] * lay["coeffs"] + 16
    lay["records"] = lay["header"]
    lay["pos"] = lay["header"] + P * lay["record"]
    lay["grid"] = lay["pos"] + (16 * P if lay["positions"] else 0)
    s = lay["structure"]
    main = 4 * int(np.prod(lay["dims"])) if s == 0 else (32 if s == 2 else 48) * lay["N"]
    lay["hanging"] = lay["grid"] + main
    lay["split"] = lay["hanging"] + 32 * lay["H"]
    lay["total"] = lay["split"] + 4 * lay["K"]
    assert lay["total"] == len(b), (lay, len(b))
    return lay


# ---- valid files from the real writer ---------------------------------------------------------------

def rotation(seed):
    q, _ = np.linalg.qr(np.random.default_rng(seed).normal(size=(3, 3)))
    return (q * np.sign(np.linalg.det(q))).astype(np.float32)


def dense_grid(rng, dims, P):
    cells = int(np.prod(dims))
    grid = np.full(cells, -1, np.int32)
    grid[rng.choice(cells, size=min(cells, max(P, 0)), replace=False)] = np.arange(min(cells, P))
    if P > 0:
        grid[grid < 0] = np.where(rng.random((grid < 0).sum()) < 0.5, -1, rng.integers(0, P, (grid < 0).sum()))
    return grid


def write_v12(d, name, rng, P, band, dims, version=0, positions=False, validity=False, axes=None):
    path = os.path.join(d, name)
    coeffs = rng.normal(size=(P, (band + 1) ** 2, 3)) * 2.0
    kw = {}
    if positions:
        kw["positions"] = rng.uniform(-3, 3, (P, 3))
    if validity:
        kw["validity"] = np.concatenate([[0.0, 1.0], rng.random(max(P - 2, 0))])[:P]
    if axes is not None:
        kw["grid_axes"] = axes
    v = native.write_shprobe(path, coeffs, dense_grid(rng, dims, P), dims, (-1.5, 0.25, 2.0), 0.5,
                             default_sh_scale=7.0, default_ambient=3.0, probe_scale=rng.uniform(0.5, 2, P),
                             probe_ambient=rng.uniform(0, 1, P), version=version, **kw)
    return name, v


def pack_v3_grid(rng, P, dims, band=2, cube=False, half=False, positions=True):
    """A version 3 dense grid packed from the format's table (no Python writer makes one)."""
    C = 6 if cube else (band + 1) ** 2
    flags = 1 if positions else 0
    head = struct.pack("<5I3I3f f 9f 2f 5I", MAGIC, 3, P, band, flags, *dims, 0.5, -1.0, 2.25, 0.75,
                       *rotation(5).ravel(), 1.0, 0.1, 1 if cube else 0, 1 if half else 0, 0, 0, 0) + bytes(16)
    assert len(head) == 128
    colours = rng.normal(size=(P, C, 3)) * 3.0
    if half and P > 0:  # binary16 edge values: zero, negative zero, subnormals, the largest finite
        special = np.array([0.0, -0.0, 2.0 ** -24, -(2.0 ** -24), 2.0 ** -14 * 0.999, 65504.0, -65504.0, 1 / 3])
        colours.reshape(-1)[:len(special)] = special
    body = bytearray()
    for i in range(P):
        rgba = np.concatenate([colours[i], np.zeros((C, 1))], axis=1)
        body += rgba.astype("<f2").tobytes() if half else rgba.astype("<f4").tobytes()
        body += struct.pack("<4f", rng.uniform(0.5, 2), rng.uniform(0, 1), rng.random(), 0.0)
    if positions:
        body += np.concatenate([rng.uniform(-2, 2, (P, 3)), np.zeros((P, 1))], axis=1).astype("<f4").tobytes()
    body += dense_grid(rng, dims, P).astype("<i4").tobytes()
    return head + bytes(body)


def octree(split_flags_seed):
    t = native.CornerOctree.uniform((0.5, -1.0, 2.0), 0.25, 2, (2, 1, 2))
    rng = np.random.default_rng(split_flags_seed)
    t.split(np.array([True, False, False, True]))
    t.split(rng.random(t.leaf_count) < 0.2)
    t.finalize()
    return t


def box_tree(seed):
    """2 x 1 x 2 roots of 2^2 min cells, three passes of random per-axis splits (as
    tests/python/test_native_shprobe_v4.py): boxes that are not cubes, so version 4."""
    rng = np.random.default_rng(seed)
    t = native.CornerOctree.uniform((0.5, -1.0, 2.0), 0.25, 2, (2, 1, 2))
    for _ in range(3):
        masks = np.where(rng.random(t.leaf_count) < 0.4, rng.integers(1, 8, t.leaf_count), 0)
        t.split_axes(masks.astype(np.uint8))
    t.finalize()
    return t


def write_v3(d, name, rng, structure, colours, representation="sh", storage="float32"):
    n = colours.shape[0]
    native.write_shprobe_v3(os.path.join(d, name), structure, colours, representation=representation,
                            storage=storage, probe_scale=rng.uniform(0.5, 2, n), probe_ambient=rng.uniform(0, 1, n),
                            validity=rng.random(n), default_sh_scale=2.0, default_ambient=0.5)
    return name


def valid_files(d):
    rng = np.random.default_rng(32)
    names = []
    for band in (0, 1, 2):  # version 1: bands 0 and 1 are zero-padded to 9 coefficients
        names.append(write_v12(d, f"v1_band{band}.shprobe", rng, 5, band, (3, 2, 2))[0])
    names.append(write_v12(d, "v1_empty.shprobe", rng, 0, 2, (2, 1, 1))[0])
    names.append(write_v12(d, "v1_large.shprobe", rng, 300, 2, (10, 8, 6))[0])
    for band in range(5):
        names.append(write_v12(d, f"v2_band{band}.shprobe", rng, 6, band, (3, 2, 2), positions=band % 2 == 1,
                               validity=True, axes=rotation(band) if band != 2 else None)[0])
    names.append(write_v12(d, "v2_forced.shprobe", rng, 4, 2, (2, 2, 1), version=2)[0])
    for name, kw in [("v3_grid_sh_f32.shprobe", dict(band=3)),
                     ("v3_grid_sh_f16.shprobe", dict(band=2, half=True)),
                     ("v3_grid_cube_f32_nopos.shprobe", dict(cube=True, positions=False)),
                     ("v3_grid_cube_f16.shprobe", dict(cube=True, half=True))]:
        with open(os.path.join(d, name), "wb") as fh:
            fh.write(pack_v3_grid(rng, 7, (3, 2, 2), **kw))
        names.append(name)
    t = octree(1)
    P = t.probe_count
    names.append(write_v3(d, "v3_octree_sh_f32.shprobe", rng, t, rng.normal(size=(P, 9, 3))))
    names.append(write_v3(d, "v3_octree_sh4_f16.shprobe", rng, t, rng.normal(size=(P, 25, 3)), storage="float16"))
    names.append(write_v3(d, "v3_octree_cube_f32.shprobe", rng, t, rng.normal(size=(P, 6, 3)), "ambientCube"))
    names.append(write_v3(d, "v3_octree_cube_f16.shprobe", rng, t, rng.normal(size=(P, 6, 3)), "ambientCube", "float16"))
    pos = rng.uniform(-2, 2, (14, 3))
    tt = native.Tetrahedra.create(pos)
    names.append(write_v3(d, "v3_tetra_sh_f32.shprobe", rng, tt, rng.normal(size=(14, 9, 3))))
    names.append(write_v3(d, "v3_tetra_sh0_f16.shprobe", rng, tt, rng.normal(size=(14, 1, 3)), storage="float16"))
    names.append(write_v3(d, "v3_tetra_cube_f16.shprobe", rng, tt, rng.normal(size=(14, 6, 3)), "ambientCube", "float16"))
    for seed, kw in [(1, dict(band=1)), (2, dict(band=3, storage="float16")), (3, dict(cube=True))]:
        kd = box_tree(seed)
        P = kd.probe_count
        cube = kw.get("cube", False)
        colours = rng.normal(size=(P, 6 if cube else (kw["band"] + 1) ** 2, 3))
        names.append(write_v3(d, f"v4_kd_seed{seed}.shprobe", rng, kd, colours,
                              "ambientCube" if cube else "sh", kw.get("storage", "float32")))
    return names


# ---- malformed variants: one per refusal of the C reader ----------------------------------------------

def split_tree_walk(b, lay):
    """(node, box min, levels, word) of every node reached from the roots, depth first as the reader."""
    R, K = u32(b, 112), lay["K"]
    nodes = struct.unpack_from(f"<{K}I", b, lay["split"])
    root = [-(-dim // (1 << R)) for dim in lay["dims"]]
    out = []
    for g in range(root[0] * root[1] * root[2]):
        stack = [(g, [g % root[0] << R, g // root[0] % root[1] << R, g // (root[0] * root[1]) << R], [R, R, R])]
        while stack:
            n, mn, lv = stack.pop()
            w = nodes[n]
            out.append((n, mn, lv, w))
            if w & 3:
                a, c = (w & 3) - 1, w >> 2
                lo, hi = (c, list(mn), list(lv)), (c + 1, list(mn), list(lv))
                lo[2][a] = hi[2][a] = lv[a] - 1
                hi[1][a] += 1 << hi[2][a]
                stack += [hi, lo]
    return out


def overlap(b, lay):
    """Leaf i + 1 made a min cell at (x + 1, y, z) of leaf i (level >= 1): after it in Morton order, inside it."""
    leaves = np.frombuffer(b, "<u4", 12 * lay["N"], lay["grid"]).reshape(-1, 12)
    i = next(i for i in range(lay["N"] - 1) if leaves[i, 3] >= 1)
    x, y, z = (int(v) for v in leaves[i, :3])
    return b[:lay["grid"] + 48 * (i + 1)] + struct.pack("<4I", x + 1, y, z, 0) + b[lay["grid"] + 48 * (i + 1) + 16:]


def refusals(files):
    """(name, bytes, substring the C message must contain; None: only the verdict is compared)."""
    v1, v2, v2p = files["v1_band2.shprobe"], files["v2_band3.shprobe"], files["v2_band1.shprobe"]
    g3h, oc, oc16 = files["v3_grid_sh_f16.shprobe"], files["v3_octree_sh_f32.shprobe"], files["v3_octree_cube_f16.shprobe"]
    te, kd = files["v3_tetra_sh_f32.shprobe"], files["v4_kd_seed1.shprobe"]
    L1, L2, Lo, Lo16, Lt, Lk, Lg = (layout(x) for x in (v1, v2, oc, oc16, te, kd, g3h))
    out = [
        ("empty", b"", "the magic at offset 0 needs 4"),
        ("three_bytes", v1[:3], "the magic at offset 0 needs 4"),
        ("bad_magic", b"SPHQ" + v1[4:], "bad magic"),
        ("magic_only", v1[:6], "the version at offset 4 needs 8"),
        ("version_0", put_u32(v1, 4, 0), "unknown version 0 at offset 4"),
        ("version_5", put_u32(v1, 4, 5), "unknown version 5 at offset 4"),
        ("v1_short_header", v1[:47], "the version 1 header needs 48"),
        ("v2_short_header", v2[:95], "the version 2 header needs 96"),
        ("v3_short_header", oc[:127], "the version 3 header needs 128"),
        ("v4_short_header", kd[:100], "the version 4 header needs 128"),
        ("v2_band_5", put_u32(v2, 12, 5), "max band 5 at offset 12 is out of range 0..4"),
        ("v2_flags_3", put_u32(v2, 16, 3), "unknown flags 0x3 at offset 16"),
        ("v2_flags_high", put_u32(v2, 16, 0x80000000), "unknown flags 0x80000000"),
        ("v2_axes_zero", v2[:48] + bytes(36) + v2[84:], "grid axes at offset 48 are all zero"),
        ("v2_axes_nan", put_u32(v2, 48 + 16, NAN_BITS), "grid axes[4] is nan (offset 64)"),
        ("v2_axes_negnan", put_u32(v2, 48 + 16, NEG_NAN_BITS), "grid axes[4] is -nan (offset 64)"),
        ("v2_axes_long", put_f32(put_f32(put_f32(v2, 48, 2.0), 52, 0.0), 56, 0.0), "axis 0 . axis 0 = 4, expected 1"),
        ("v2_axes_skew", put_f32(put_f32(put_f32(v2, 60, 0.6), 64, 0.8), 68, 0.0), "not orthonormal"),
        ("v1_dim_y_0", put_u32(v1, 16, 0), "grid dim Y at offset 16 is 0"),
        ("v2_dim_z_0", put_u32(v2, 28, 0), "grid dim Z at offset 28 is 0"),
        ("v1_probes_2p25", put_u32(v1, 8, 1 << 25), "probe count 33554432 (offset 8) is above the limit"),
        ("v2_probes_limit1", put_u32(v2, 8, (1 << 24) + 1), "above the limit of 16777216 probes"),
        ("v1_probes_at_limit", put_u32(v1, 8, 1 << 24), "truncated"),
        ("v1_dims_overflow", put_u32(put_u32(put_u32(v1, 12, 1 << 31), 16, 1 << 31), 20, 1 << 31), "overflow 64 bits"),
        ("v1_cells_limit", put_u32(put_u32(put_u32(v1, 12, 1 << 15), 16, 1 << 14), 20, 1), "cells (offset 12) is above the limit"),
        ("v2_cells_limit", put_u32(put_u32(put_u32(v2, 20, 0xFFFFFFFF), 24, 0xFFFFFFFF), 28, 1), "above the limit of 268435456 cells"),
        ("v1_origin_inf", put_u32(v1, 28, INF_BITS), "grid origin[1] is inf (offset 28)"),
        ("v2_origin_negnan", put_u32(v2, 40, NEG_NAN_BITS), "grid origin[2] is -nan (offset 40)"),
        ("v1_spacing_nan", put_u32(v1, 36, NAN_BITS), "grid spacing is nan (offset 36)"),
        ("v1_spacing_0", put_f32(v1, 36, 0.0), "grid spacing is 0 (offset 36); it must be > 0"),
        ("v2_spacing_neg", put_f32(v2, 44, -0.5), "grid spacing is -0.5 (offset 44)"),
        ("v2_spacing_negzero", put_u32(v2, 44, 0x80000000), "grid spacing is -0 (offset 44)"),
        ("v1_default_scale_nan", put_u32(v1, 40, NAN_BITS), "default SH scale is nan (offset 40)"),
        ("v2_default_ambient_neginf", put_u32(v2, 88, NEG_INF_BITS), "default ambient is -inf (offset 88)"),
        ("v1_coeff_nan", put_u32(v1, 48 + 160 + 16 * 8 + 8, NAN_BITS), "probe 1 coefficient 8 blue is nan (offset 344)"),
        ("v2_coeff_inf", put_u32(v2, L2["records"] + L2["record"] * 2 + 16 * 5 + 4, INF_BITS), "probe 2 coefficient 5 green is inf"),
        ("v1_scale_nan", put_u32(v1, 48 + 144, NAN_BITS), "probe 0 scale is nan (offset 192)"),
        ("v1_ambient_inf", put_u32(v1, 48 + 160 * 4 + 148, INF_BITS), "probe 4 ambient is inf"),
        ("v2_validity_nan", put_u32(v2, L2["records"] + L2["record"] - 8, NAN_BITS), "probe 0 validity is nan"),
        ("v2_validity_1p5", put_f32(v2, L2["records"] + L2["record"] * 2 - 8, 1.5), "probe 1 validity is 1.5"),
        ("v2_validity_neg", put_f32(v2, L2["records"] + L2["record"] - 8, -0.25), "probe 0 validity is -0.25"),
        ("v2_validity_tiny", put_f32(v2, L2["records"] + L2["record"] - 8, 1.0000001), "it must be in [0, 1]"),
        ("v2_position_nan", put_u32(v2, L2["pos"] + 16 * 3 + 8, NEG_NAN_BITS), "probe 3 position[2] is -nan"),
        ("v1_grid_entry_P", put_i32(v1, L1["grid"] + 4 * 11, 5), "grid cell (2, 1, 1) holds 5"),
        ("v2_grid_entry_m2", put_i32(v2, L2["grid"] + 4 * 4, -2), "grid cell (1, 1, 0) holds -2"),
        ("v3_half_inf", put_u16(g3h, Lg["records"] + Lg["record"] + 8 * 2 + 2, 0x7C00), "probe 1 coefficient 2 green is inf"),
        ("v3_half_neginf", put_u16(g3h, Lg["records"] + 8 * 3, 0xFC00), "probe 0 coefficient 3 red is -inf"),
        ("v3_half_nan", put_u16(oc16, Lo16["records"] + 4, 0x7E00), "probe 0 face 0 blue is nan"),
        ("v3_half_negnan", put_u16(oc16, Lo16["records"] + Lo16["record"] * 3 + 8 * 5, 0xFE01), "probe 3 face 5 red is -nan"),
        ("v3_representation_2", put_u32(oc, 92, 2), "unknown representation 2 at offset 92"),
        ("v3_storage_2", put_u32(oc, 96, 2), "unknown storage 2 at offset 96"),
        ("v3_structure_4", put_u32(oc, 100, 4), "unknown structure 4 at offset 100"),
        ("v3_structure_3", put_u32(oc, 100, 3), "needs version 4, not 3"),
        ("v4_structure_1", put_u32(kd, 100, 1), "structure 1 at offset 100 in a version 4 file"),
        ("v3_grid_elements", put_u32(g3h, 104, 1), "a grid file has element and hanging counts 0"),
        ("v3_grid_hanging", put_u32(g3h, 108, 2), "not 0, 2"),
        ("v3_octree_no_positions", put_u32(oc, 16, 0), "the octree structure needs probe positions"),
        ("v4_no_positions", put_u32(kd, 16, 0), "the kd corner tree structure needs probe positions"),
        ("v3_octree_no_leaves", put_u32(oc, 104, 0), "the octree structure has no leaves (offset 104)"),
        ("v3_tetra_no_tets", put_u32(te, 104, 0), "the tetrahedra structure has no tetrahedra"),
        ("v3_octree_leaves_limit", put_u32(oc, 104, (1 << 26) + 1), "67108865 leaves (offset 104) are above the limit"),
        ("v3_tetra_limit", put_u32(te, 104, (1 << 27) + 1), "tetrahedra (offset 104) are above the limit of 134217728"),
        ("v3_hanging_limit", put_u32(oc, 108, (1 << 26) + 1), "hanging nodes (offset 108) are above the limit"),
        ("v3_lattice_0", put_u32(oc, 24, 0), "octree lattice extent Y at offset 24 is 0"),
        ("v3_lattice_big", put_u32(oc, 20, (1 << 20) + 1), "octree lattice extent X at offset 20 is 1048577"),
        ("v3_tetra_hanging", put_u32(te, 108, 1), "tetrahedra have no hanging nodes"),
        ("v3_tetra_dim", put_u32(te, 24, 2), "tetrahedra have no lattice: dim Y at offset 24 must be 0, not 2"),
        ("v3_tetra_spacing_0", put_f32(te, 44, 0.0), None),  # tetrahedra: spacing unused, any finite value
        ("v3_tetra_spacing_nan", put_u32(te, 44, NAN_BITS), "grid spacing is nan"),
        ("v3_leaf_level_21", put_u32(oc, Lo["grid"] + 12, 21), "leaf 0 level 21"),
        ("v3_leaf_misaligned", put_u32(oc, Lo["grid"] + 48 * (Lo["N"] - 1), 1), "is not aligned to its size or reaches past"),
        ("v3_leaf_past", put_u32(oc, Lo["grid"] + 48 * (Lo["N"] - 1) + 12, 3), None),
        ("v3_leaf_order", oc[:Lo["grid"]] + oc[Lo["grid"] + 48:Lo["grid"] + 96] + oc[Lo["grid"]:Lo["grid"] + 48]
         + oc[Lo["grid"] + 96:], "overlaps the leaf before it or is out of Morton order"),
        ("v3_leaf_inside_previous", overlap(oc, Lo), "overlaps the leaf before it or is out of Morton order"),
        ("v3_corner_neg", put_i32(oc, Lo["grid"] + 16 + 4 * 3, -1), "leaf 0 corner 3"),
        ("v3_corner_big", put_i32(oc, Lo["grid"] + 48 + 16, Lo["P"] + Lo["H"]), "must be a node index below"),
        ("v3_hanging_source", put_u32(oc, Lo["hanging"], Lo["P"]), "hanging node 0 source 0"),
        ("v3_hanging_weight_nan", put_u32(oc, Lo["hanging"] + 32 + 16, NAN_BITS), "hanging node 1 weight 0 is nan"),
        ("v3_hanging_weight_neg", put_f32(oc, Lo["hanging"] + 16 + 4, -0.5), "it must be in [0, 1]"),
        ("v3_hanging_weight_big", put_f32(oc, Lo["hanging"] + 16, 1.5), "is 1.5"),
        ("v3_hanging_sum", put_f32(oc, Lo["hanging"] + 16, 0.25), "weights sum to 0.75"),
        ("v3_hanging_sum_near", put_f32(oc, Lo["hanging"] + 16, 0.50001), "weights sum to 1.0000"),
        ("v3_hanging_sum_ok", put_f32(oc, Lo["hanging"] + 16, 0.500001), None),  # within 1e-5: accepted
        ("v3_tet_vertex", put_u32(te, Lt["grid"] + 4, Lt["P"]), "tetrahedron 0 vertex 1"),
        ("v3_tet_repeat", put_u32(te, Lt["grid"] + 8, u32(te, Lt["grid"])), "tetrahedron 0 (offset"),
        ("v3_tet_neighbour_big", put_i32(te, Lt["grid"] + 32 + 16 + 8, Lt["N"]), "tetrahedron 1 neighbour 2"),
        ("v3_tet_neighbour_m2", put_i32(te, Lt["grid"] + 16, -2), "is -2; it must be -1 or below"),
        ("v4_reserved_120", put_u32(kd, 120, 1), "reserved word at offset 120 is 0x1; it must be 0"),
        ("v4_reserved_124", put_u32(kd, 124, 0xABC), "reserved word at offset 124 is 0xABC"),
        ("v4_root_level_21", put_u32(kd, 112, 21), "root level 21 at offset 112 is out of range 0..20"),
        ("v4_nodes_limit", put_u32(kd, 116, (1 << 28) + 1), "split-tree nodes (offset 116) are above the limit"),
        ("v4_nodes_below_roots", put_u32(kd, 116, 1), "is below the 4 root cells"),
        ("v4_levels_top_byte", put_u32(kd, Lk["grid"] + 12, u32(kd, Lk["grid"] + 12) | 1 << 24), "has a nonzero top byte"),
        ("v4_level_above_root", put_u32(kd, Lk["grid"] + 12, 3), "leaf 0 level x is 3"),
        ("v4_leaf_misaligned", put_u32(kd, Lk["grid"] + 48 * (Lk["N"] - 1) + 4, 3), None),
        ("v4_leaf_order", kd[:Lk["grid"]] + kd[Lk["grid"] + 48:Lk["grid"] + 96] + kd[Lk["grid"]:Lk["grid"] + 48]
         + kd[Lk["grid"] + 96:], "is not after the leaf before it in Morton order"),
        ("v4_corner_big", put_i32(kd, Lk["grid"] + 16 + 28, Lk["P"] + Lk["H"]), "leaf 0 corner 7"),
        ("v4_hanging_source", put_u32(kd, Lk["hanging"] + 4, Lk["P"] + 5), "hanging node 0 source 1"),
    ]
    # Truncated by one byte and one byte of trailing data, for every valid file.
    for name, b in files.items():
        stem = name[:-len(".shprobe")]
        out.append((f"{stem}_short1", b[:-1], "truncated:"))
        out.append((f"{stem}_trailing1", b + b"\0", "1 bytes of trailing data after the"))
    out.append(("v1_trailing_1000", v1 + bytes(1000), "1000 bytes of trailing data after the grid"))
    out.append(("v2_positions_flag_off", put_u32(v2p, 16, 0), "bytes of trailing data"))
    # Padding that the reader ignores: version 1's 4th float of each colour and the record's last 8 bytes.
    pad = put_u32(put_u32(v1, 48 + 12, 0x12345678), 48 + 152, 0xFFFFFFFF)
    out.append(("v1_padding_ignored", put_u32(pad, 48 + 156, NAN_BITS), None))
    out.append(("v2_reserved_ignored", put_u32(v2, 92, 0xDEADBEEF), None))
    out.append(("v3_reserved_ignored", put_u32(oc, 112, 7), None))
    # The kd corner tree's split tree (version 4), from the tree the file holds.
    walk = split_tree_walk(kd, Lk)
    word = {n: w for n, _, _, w in walk}
    splits = [n for n, _, _, w in walk if w & 3]
    leaves = [n for n, _, _, w in walk if not w & 3 and w >> 2 != (1 << 30) - 1]
    at = lambda n: Lk["split"] + 4 * n  # noqa: E731
    s0, s1 = splits[0], splits[-1]
    out += [
        ("v4_split_children_back", put_u32(kd, at(s0), s0 << 2 | (word[s0] & 3)), "names children"),
        ("v4_split_children_past", put_u32(kd, at(s0), (Lk["K"] - 1) << 2 | (word[s0] & 3)), "below the node count"),
        ("v4_split_unreached", put_u32(kd, at(s1), ((1 << 30) - 1) << 2), "is not the child of any split reached"),
        ("v4_leaf_node_range", put_u32(kd, at(leaves[0]), Lk["N"] << 2), f"names leaf {Lk['N']}; leaves are below"),
        ("v4_leaf_node_box", put_u32(put_u32(kd, at(leaves[0]), word[leaves[1]]), at(leaves[1]), word[leaves[0]]),
         "but the node's box is at"),
        ("v4_leaf_node_empty", put_u32(kd, at(leaves[0]), ((1 << 30) - 1) << 2), f"of the {Lk['N']} leaves"),
    ]
    # A split's lower child that is a split too, made to name its sibling (already a child) as its own.
    c = next(word[n] >> 2 for n in splits if word[word[n] >> 2] & 3)
    out.append(("v4_split_two_parents", put_u32(kd, at(c), (c + 1) << 2 | (word[c] & 3)), "is the child of two splits"))
    zero_axis = [(n, lv.index(0)) for n, _, lv, w in walk if w & 3 and 0 in lv]
    if zero_axis:
        n, a = zero_axis[0]
        out.append(("v4_split_level_0", put_u32(kd, at(n), (word[n] & ~3) | (a + 1)), "a box of level 0 on that axis"))
    return out


def random_variants(files, count_per_file=12, seed=3232):
    """Seeded random corruptions of every valid file: a byte, a header word or a body word set to a
    telling value, a cut, or bytes appended. Whatever the C reader decides, the JS reader must too."""
    rng = np.random.default_rng(seed)
    words = [0, 1, 2, 3, 4, 5, 0xFFFFFFFF, 0x80000000, 1 << 20, 1 << 24, 1 << 28, NAN_BITS, NEG_NAN_BITS,
             INF_BITS, 0x3F800000, 0xBF800000, 0x7F7FFFFF, 0x00000001]
    out = []
    for name, b in files.items():
        for k in range(count_per_file):
            kind = rng.integers(0, 5)
            x = bytearray(b)
            if kind == 0 and len(x):
                x[rng.integers(0, len(x))] = int(rng.integers(0, 256))
            elif kind == 1:
                off = 4 * int(rng.integers(1, min(len(x), 128) // 4))
                struct.pack_into("<I", x, off, int(words[rng.integers(0, len(words))]))
            elif kind == 2:
                off = 4 * int(rng.integers(0, len(x) // 4))
                struct.pack_into("<I", x, off, int(words[rng.integers(0, len(words))]))
            elif kind == 3:
                x = x[:int(rng.integers(0, len(x)))]
            else:
                x += rng.integers(0, 256, int(rng.integers(1, 64))).astype(np.uint8).tobytes()
            out.append((f"rnd_{name[:-len('.shprobe')]}_{k}", bytes(x), None))
    return out


# ---- what the C reader says ---------------------------------------------------------------------------

def flat(a, kind):
    return None if a is None else np.asarray(a).reshape(-1).astype(kind).tolist()


def c_values(f):
    return {
        "version": f.version, "probeCount": f.probe_count, "maxBand": f.max_band,
        "gridDims": list(f.grid_dims), "gridOrigin": list(f.grid_origin), "gridSpacing": f.grid_spacing,
        "gridAxes": [list(r) for r in f.grid_axes], "defaultShScale": f.default_sh_scale,
        "defaultAmbient": f.default_ambient, "representation": f.representation, "storage": f.storage,
        "structure": f.structure, "coeffs": flat(f.coeffs, float), "colourCount": int(f.coeffs.shape[1]),
        "probeScale": flat(f.probe_scale, float), "probeAmbient": flat(f.probe_ambient, float),
        "validity": flat(f.validity, float), "positions": flat(f.positions, float), "grid": flat(f.grid, int),
        "leaves": flat(f.leaves, int), "leafCorners": flat(f.leaf_corners, int),
        "hangingSources": flat(f.hanging_sources, int), "hangingWeights": flat(f.hanging_weights, float),
        "tets": flat(f.tets, int), "tetNeighbours": flat(f.tet_neighbours, int),
        "rootLevel": f.root_level, "splitNodes": flat(f.split_nodes, int),
    }


def c_verdict(path, data):
    try:
        f = native.read_shprobe(path)
    except native.SchneeError as e:
        try:
            native.read_shprobe_bytes(data)
            raise AssertionError(f"{path}: the memory reader accepts what the file reader refuses: {e}")
        except native.SchneeError as m:
            return {"ok": False, "code": e.code, "message": str(e), "memoryMessage": str(m), "memoryCode": m.code}
    return {"ok": True, "values": c_values(f)}


def main(out_dir):
    os.makedirs(out_dir, exist_ok=True)
    names = valid_files(out_dir)
    files = {}
    for n in names:
        with open(os.path.join(out_dir, n), "rb") as fh:
            files[n] = fh.read()
    entries = []
    for n in names:
        path = os.path.join(out_dir, n)
        entries.append({"name": n, "path": path, "group": "valid", "expect": None, "c": c_verdict(path, files[n])})
    for group, variants in (("refusal", refusals(files)), ("random", random_variants(files))):
        for stem, data, expect in variants:
            n = stem + ".shprobe"
            path = os.path.join(out_dir, n)
            with open(path, "wb") as fh:
                fh.write(data)
            entries.append({"name": n, "path": path, "group": group, "expect": expect, "c": c_verdict(path, data)})
    with open(os.path.join(out_dir, "manifest.json"), "w") as fh:
        json.dump({"entries": entries}, fh, allow_nan=False)
    by = {g: sum(e["group"] == g for e in entries) for g in ("valid", "refusal", "random")}
    refused = sum(not e["c"]["ok"] for e in entries)
    print(f"make_fixtures: {len(entries)} files in {out_dir} ({by}); the C reader refuses {refused}")


if __name__ == "__main__":
    if len(sys.argv) != 2:
        sys.exit(__doc__)
    main(sys.argv[1])
