"""The bake-info sidecar ``<name>.shprobe.bakeinfo`` (docs/bakeinfo.md, normative): what an Adaptive
bake measured that a ``.shprobe`` does not hold, for the viewport overlay's Noise and Refinement
colour modes (docs/overlay.md): each probe's relative Monte-Carlo noise, and per leaf of the octree
the refinement's last decision (its worst test error, the threshold it was held to, why it is a
leaf), with the decisions of every pass.

A NumPy ``.npz`` archive (uncompressed, no pickled objects: read with ``allow_pickle=False``)
written beside the ``.shprobe`` in the same all-or-none write (bake_outputs.write_all), naming the
SHA-256 of the exact ``.shprobe`` bytes it describes: a reader ignores, with a message, a sidecar
whose hash, probe count or leaves differ from the file's. No ``bpy`` here (the bake's plans and the
overlay call it; tests run it without Blender).
"""
from __future__ import annotations

import hashlib
import math
import os
import zipfile
from dataclasses import dataclass
from typing import Iterator, List, Optional

import numpy as np

from .file_names import NAME_MAX
from .safe_open import open_regular

SUFFIX = ".bakeinfo"
FORMAT = "schnee-bakeinfo"
VERSION = 1
MAGIC = b"PK\x03\x04"            # a zip archive (.npz) begins so; bake_outputs.check_replaceable
MAX_BYTES = 256 << 20            # readers refuse larger sidecars
SHPROBE_MAX_BYTES = 1 << 62      # the .shprobe hashed: its own reader bounded it already
HASH_CHUNK = 8 << 20             # bytes hashed per step of a reader

# Why a leaf of the final octree is a leaf (``leaf_reason``; docs/bakeinfo.md).
UNKNOWN, PASSED, NOISE_LIMITED, MIN_CELL, NEVER_TESTED, NOT_COMPARED = range(6)
REASONS = {UNKNOWN: "unknown", PASSED: "passed", NOISE_LIMITED: "noise-limited", MIN_CELL: "at Min Cell Size",
           NEVER_TESTED: "never tested", NOT_COMPARED: "not compared"}


def path_for(shprobe_path: str) -> str:
    return shprobe_path + SUFFIX


def sha256_steps(path: str, h) -> Iterator[None]:
    """Feed the regular file at ``path`` to the hash ``h``, :data:`HASH_CHUNK` bytes per step (a
    generator: it yields after each); safe_open.RefusedFile for a FIFO, device or directory."""
    f, _ = open_regular(path, "a .shprobe", SHPROBE_MAX_BYTES)
    with f:
        for block in iter(lambda: f.read(HASH_CHUNK), b""):
            h.update(block)
            yield


def sha256_file(path: str) -> str:
    h = hashlib.sha256()
    for _ in sha256_steps(path, h):
        pass
    return h.hexdigest()


# ------------------------------------------------------------------ the bake's side
def record_decision(group, tests_split, direct_split, err, thr, test_valid) -> None:
    """Keep one pass's decision of ``group`` (adaptive.AdaptiveGroup) for the sidecar's history:
    per leaf of the tree before the split, its worst test error and threshold (NaN where no test
    was compared), the axes the tests split and those the lamps' direct-light check split."""
    info = group.tree.info()
    leaves = np.asarray(info["leaves"], dtype=np.uint32)
    n = len(leaves)
    e = np.full(n, np.nan, np.float32)
    t = np.full(n, np.nan, np.float32)
    if err is not None and group.tests is not None:
        cols = np.asarray(group.tests.leaf_tests)
        valid = np.ones(len(group.tests.positions), dtype=bool) if test_valid is None else np.asarray(test_valid, bool)
        compared = ((cols >= 0) & valid[np.maximum(cols, 0)]).any(axis=1)
        e[compared] = np.asarray(err)[compared]
        t[compared] = np.asarray(thr)[compared]
    zero = np.zeros(n, np.uint8)
    group.decisions.append(dict(
        pass_index=len(group.passes), leaves=leaves.copy(), error=e, threshold=t,
        split=zero if tests_split is None else np.asarray(tests_split, np.uint8).copy(),
        direct=zero if direct_split is None else np.asarray(direct_split, np.uint8).copy()))


def file_leaf_words(info: dict) -> np.ndarray:
    """(L, 4) uint32: a tree's leaves (``CornerOctree.info()``) as its file writes them: x, y, z and
    the level (v3), or the packed per-axis levels (v4) when some leaf's levels differ."""
    from .adaptive import leaf_levels
    from .native import pack_levels
    words = np.array(info["leaves"], dtype=np.uint32)
    levels = leaf_levels(info)
    if len(words) and (levels != levels[:, :1]).any():
        words[:, 3] = pack_levels(levels)
    return words


def leaf_table(group) -> dict:
    """Per leaf of ``group``'s final tree (the file's leaf order): error, threshold (NaN where it
    has no test of its own), its parent's ratio next to it, and why it is a leaf (the REASONS)."""
    from .adaptive import leaf_keys, leaf_levels
    info = group.tree.info()
    leaves = np.asarray(info["leaves"], dtype=np.uint32)
    keys = leaf_keys(info)
    levels = leaf_levels(info)
    n = len(leaves)
    file_leaves = file_leaf_words(info)
    err = np.full(n, np.nan, np.float32)
    thr = np.full(n, np.nan, np.float32)
    parent = np.array([group.parent_ratio.get(k, math.nan) for k in keys], np.float32)
    reason = np.zeros(n, np.uint8)
    last = {}
    if group.decisions:
        d = group.decisions[-1]
        last = {tuple(int(v) for v in row): i for i, row in enumerate(d["leaves"])}
    for i, k in enumerate(keys):
        if int(levels[i].max()) == 0:
            reason[i] = MIN_CELL
            continue
        if k in group.settled:
            reason[i] = NEVER_TESTED
            continue
        j = last.get(tuple(int(v) for v in leaves[i]))
        if j is None:
            reason[i] = UNKNOWN
            continue
        e, t = group.decisions[-1]["error"][j], group.decisions[-1]["threshold"][j]
        if not np.isfinite(e):
            reason[i] = NOT_COMPARED
            continue
        err[i], thr[i] = e, t
        reason[i] = PASSED if e <= group.tolerance else NOISE_LIMITED
    return dict(leaves=file_leaves, leaf_error=err, leaf_threshold=thr, leaf_parent_ratio=parent, leaf_reason=reason)


def history_table(group) -> dict:
    """Every pass's decisions (``record_decision``) as flat arrays (docs/bakeinfo.md)."""
    ds = group.decisions
    if not ds:
        return dict(history_pass=np.zeros(0, np.uint16), history_leaves=np.zeros((0, 4), np.uint32),
                    history_error=np.zeros(0, np.float32), history_threshold=np.zeros(0, np.float32),
                    history_split=np.zeros(0, np.uint8), history_direct=np.zeros(0, np.uint8))
    return dict(history_pass=np.concatenate([np.full(len(d["leaves"]), d["pass_index"], np.uint16) for d in ds]),
                history_leaves=np.concatenate([d["leaves"] for d in ds]),
                history_error=np.concatenate([d["error"] for d in ds]),
                history_threshold=np.concatenate([d["threshold"] for d in ds]),
                history_split=np.concatenate([d["split"] for d in ds]),
                history_direct=np.concatenate([d["direct"] for d in ds]))


def adaptive_arrays(group, cache, settings) -> dict:
    """The sidecar's arrays for one Adaptive group (all but the hash): the probes' noise in the
    file's probe order (the tree's), the final leaves and the history."""
    noise = np.asarray(cache.values(np.asarray(group.probe_index, dtype=np.int64))[1], np.float32)
    out = dict(placement=np.array("ADAPTIVE"), tolerance=np.float64(group.tolerance),
               noise_k=np.float64(group.policy.noise_k), min_cell_size=np.float64(group.min_cell),
               samples=np.int64(settings.samples), noise=noise)
    out.update(leaf_table(group))
    out.update(history_table(group))
    return out


def write(path: str, shprobe_path: str, arrays: dict) -> None:
    """Write the sidecar of ``shprobe_path`` (its bytes as they are now) to ``path`` (a temporary
    name: bake_outputs.write_all renames it into place)."""
    head = dict(format=np.array(FORMAT), version=np.int32(VERSION),
                shprobe_sha256=np.array(sha256_file(shprobe_path)),
                probe_count=np.int64(len(arrays["noise"])))
    with open(path, "wb") as fh:
        np.savez(fh, **head, **arrays)


def with_sidecar(output, arrays: dict, output_class, log=print):
    """[the .shprobe's Output, its sidecar's Output]: the sidecar hashes the .shprobe's temporary
    file, which write_all has written just before (outputs are written in list order). A .shprobe
    whose sidecar's name would exceed the file system's 255 bytes gets none (logged)."""
    if len(os.path.basename(path_for(output.path)).encode()) > NAME_MAX:
        log(f"Schnee: no bake-info sidecar for {os.path.basename(output.path)}: its name would be longer "
            f"than {NAME_MAX} bytes (the overlay's Noise and Refinement modes need it)")
        return [output]
    written = {}

    def write_shprobe(tmp):
        output.write(tmp)
        written["tmp"] = tmp

    def write_info(tmp):
        write(tmp, written["tmp"], arrays)
    return [output_class(output.path, output.kind, write_shprobe),
            output_class(path_for(output.path), "bakeinfo", write_info)]


# ------------------------------------------------------------------ the reader's side
@dataclass
class BakeInfo:
    """A sidecar as the overlay uses it; ``error``: why it is ignored (None = usable);
    ``missing``: there is none."""
    path: str
    error: Optional[str] = None
    missing: bool = False
    tolerance: float = 0.0
    noise: Optional[np.ndarray] = None          # (P,) relative σ, NaN = not measured
    leaves: Optional[np.ndarray] = None         # (L, 4)
    leaf_ratio: Optional[np.ndarray] = None     # (L,) error / threshold, NaN = no own test
    leaf_error: Optional[np.ndarray] = None     # (L,) as stored (a region rebake keeps them: region.py)
    leaf_threshold: Optional[np.ndarray] = None
    leaf_parent_ratio: Optional[np.ndarray] = None
    leaf_reason: Optional[np.ndarray] = None
    stamp: tuple = (0, 0)


def stamp_of(path: str):
    try:
        st = os.stat(path)
        return (st.st_mtime_ns, st.st_size)
    except OSError:
        return None


def _field(z, name, dtype, shape=None):
    if name not in z.files:
        raise ValueError(f"no '{name}'")
    a = np.asarray(z[name])
    if shape is not None and a.shape != shape:
        raise ValueError(f"'{name}' has shape {a.shape}, expected {shape}")
    return a.astype(dtype)


def _parse(info: BakeInfo, z, sha: str, probe_count: int, leaves) -> None:
    if str(_field(z, "format", str)) != FORMAT:
        raise ValueError("not a Schnee bake-info file")
    version = int(_field(z, "version", np.int64))
    if version != VERSION:
        raise ValueError(f"version {version}; this add-on reads version {VERSION}")
    if str(_field(z, "shprobe_sha256", str)) != sha:
        raise ValueError("written for another bake of the .shprobe (its SHA-256 differs)")
    count = int(_field(z, "probe_count", np.int64))
    if count != probe_count:
        raise ValueError(f"{count} probes, the .shprobe has {probe_count}")
    info.tolerance = float(_field(z, "tolerance", np.float64))
    if not (info.tolerance > 0 and math.isfinite(info.tolerance)):
        raise ValueError(f"Error Tolerance {info.tolerance}")
    info.noise = _field(z, "noise", np.float32, (probe_count,))
    if leaves is not None and "leaves" in z.files:
        own = _field(z, "leaves", np.uint32)
        if own.shape != np.shape(leaves) or not np.array_equal(own, np.asarray(leaves, np.uint32)):
            raise ValueError("its leaves differ from the .shprobe's")
        n = len(own)
        err = _field(z, "leaf_error", np.float32, (n,))
        thr = _field(z, "leaf_threshold", np.float32, (n,))
        with np.errstate(divide="ignore", invalid="ignore"):
            info.leaf_ratio = np.where(thr > 0, err / np.where(thr > 0, thr, 1), np.nan).astype(np.float32)
        info.leaf_error, info.leaf_threshold = err, thr
        info.leaf_parent_ratio = _field(z, "leaf_parent_ratio", np.float32, (n,))
        info.leaf_reason = _field(z, "leaf_reason", np.uint8, (n,))
        info.leaves = own


def read_steps(path: str, shprobe_path: str, probe_count: int, leaves, out: List[BakeInfo]) -> Iterator[None]:
    """Read the sidecar ``path`` of ``shprobe_path`` (``probe_count`` probes, ``leaves`` (L, 4) or
    None) into ``out[0]``, hashing the .shprobe :data:`HASH_CHUNK` bytes per step (a generator: it
    yields between steps). Missing, malformed or mismatched: a BakeInfo with ``missing`` or
    ``error`` set, never an exception."""
    name = os.path.basename(path)
    info = BakeInfo(path=path)
    out[:] = [info]
    info.stamp = stamp_of(path)
    if info.stamp is None:
        info.missing = True
        return
    try:
        if info.stamp[1] > MAX_BYTES:
            raise ValueError(f"{info.stamp[1]} bytes, more than the {MAX_BYTES >> 20} MiB a sidecar may have")
        # Opened as the native readers open files: a FIFO or device is refused, never waited on.
        fh, _ = open_regular(path, "a bake-info sidecar", MAX_BYTES)
        with fh:
            if fh.read(len(MAGIC)) != MAGIC:
                raise ValueError("not a bake-info file (not a .npz archive)")
            h = hashlib.sha256()
            yield from sha256_steps(shprobe_path, h)
            fh.seek(0)
            with np.load(fh, allow_pickle=False) as z:
                _parse(info, z, h.hexdigest(), probe_count, leaves)
    except (OSError, ValueError, KeyError, TypeError, zipfile.BadZipFile, EOFError) as exc:
        out[0] = BakeInfo(path=path, stamp=info.stamp, error=f"{name}: {exc}; ignored")


def read(path: str, shprobe_path: str, probe_count: int, leaves=None) -> BakeInfo:
    out: List[BakeInfo] = []
    for _ in read_steps(path, shprobe_path, probe_count, leaves, out):
        pass
    return out[0]
