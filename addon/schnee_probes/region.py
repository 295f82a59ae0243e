"""Region rebake: bake one probe volume again after an edit and keep every other volume's file
(docs/region-rebake.md).

With One File per Volume every volume is placed on its own and written to its own
``sh_coeffs/<volume>.shprobe``, so baking one volume again never needs to open the others: their
files stay byte for byte. What this module adds is the knowledge of the previous bake, the *bake
record* ``<output>.bake.json`` beside the files (``probes.shprobe.bake.json``), written by every
volume bake with One File per Volume::

    {"format": "schnee-bake-record", "version": 1,
     "settings": {setting: value, ...},          # the values a probe depends on (fingerprint.py)
     "volumes": {"Kitchen": {"file": "Kitchen.shprobe",
                             "scene": {"geometry": "<sha256>", "lights": ..., ...}}}}

A rebake (:class:`VolumeRebake`, ``bake.py --only-volume NAME``, the panel's Rebake Selected Volume)
refuses when there is no previous bake to keep (no record, or another volume's file missing), when
the previous bake had other settings (naming each one that differs) and when the name is no volume
of the collection; it journals beside the volume's own file (``Kitchen.shprobe.journal``, shards
``Kitchen.shprobe.shard-K-of-N.journal``), writes that file and the updated record, and leaves the
sky, the sun and every other file as they were. Plain Python (no Blender: bake_outputs, which
imports bpy, only inside the two functions that make an Output), so tests/python runs it.
"""
from __future__ import annotations

import json
import os
import re
from dataclasses import asdict
from typing import Dict, List, Optional

import numpy as np

from . import bakeinfo, journal, native, scene_export
from .adaptive import leaf_keys, leaf_levels, without_leaves
from .file_names import sibling
from .safe_open import RefusedFile, open_regular
from .settings import BakeError

RECORD_SUFFIX = ".bake.json"
# The record starts with RECORD_MAGIC (json.dumps, indent 2, "format" first): how
# bake_outputs.check_replaceable recognises one of ours.
RECORD_FORMAT = "schnee-bake-record"
RECORD_MAGIC = b'{\n  "format": "schnee-bake-record"'
# Every point of the last bake (journal format, docs/farm.md "Journal file"): what a rebake keeps
# outside its region.
POINTS_SUFFIX = ".points"
# A rebake of a whole volume drops the kept points within this margin of its bounds too (points on
# its faces are rendered 1 cm inside, nodes in solids move up to 5 cm).
VOLUME_MARGIN = 0.1
RECORD_VERSION = 1
# Fingerprint parts that describe the scene (the rest, "settings", is compared value by value).
SCENE_PARTS = ("geometry", "materials", "lights", "world", "render")
# What a change of each part means for the volumes a rebake keeps (a warning, not a refusal: the
# geometry is what one edits before a rebake).
_STALE = {"lights": "the lamps", "world": "the world (sky)", "render": "the render settings",
          "materials": "materials"}
# Settings a rebake may change without refusing: where and how files are written, not the light.
_FREE = frozenset({"output_path", "probe_limit"})


def volume_file_stem(name: str) -> str:
    """The file stem of volume ``name``'s own .shprobe (One File per Volume)."""
    stem = re.sub(r"[^A-Za-z0-9._-]+", "_", name).strip("._")
    return stem or "volume"


def volume_file(main_output: str, name: str) -> str:
    """The .shprobe of volume ``name`` beside the bake's ``main_output`` (absolute paths)."""
    return os.path.join(os.path.dirname(main_output), volume_file_stem(name) + ".shprobe")


def record_path(main_output: str) -> str:
    """The bake record beside ``main_output`` (an absolute .shprobe path)."""
    return sibling(main_output, RECORD_SUFFIX)


def points_path(main_output: str) -> str:
    """The kept points beside ``main_output``."""
    return sibling(main_output, POINTS_SUFFIX)


def points_output(main_output: str, manifest: dict, coeff_count: int, store):
    """The kept points (every point ``store``, a bake_points.PointStore, holds), written whole: a
    bake_outputs.Output."""
    from .bake_outputs import Output

    def write(tmp):
        journal.write_whole(tmp, manifest, coeff_count, *store.points())
    return Output(points_path(main_output), "journal", write)


def settings_values(settings) -> Dict[str, object]:
    """The settings a record compares: every one but those of :data:`_FREE`, as JSON gives them back
    (tuples as lists), so a record read from its file compares equal."""
    return json.loads(json.dumps({k: v for k, v in asdict(settings).items() if k not in _FREE}))


def read_record(path: str) -> Optional[dict]:
    """The record at ``path``, None when absent; BakeError when it is not a readable record."""
    if not os.path.lexists(path):
        return None
    try:
        f, _ = open_regular(path, "a bake record", 1 << 24)
        with f:
            record = json.loads(f.read().decode("utf-8"))
    except (RefusedFile, OSError, ValueError) as exc:
        raise BakeError(f"Cannot read the previous bake's record {path}: {exc}; bake every volume again") from None
    if not isinstance(record, dict) or record.get("format") != RECORD_FORMAT or \
            record.get("version") != RECORD_VERSION or not isinstance(record.get("volumes"), dict):
        raise BakeError(f"{path} is not a bake record this add-on reads; bake every volume again")
    return record


def kept_outside(values: dict, box) -> dict:
    """The points of ``values`` (journal key -> coefficients) whose position lies outside ``box``
    ((lo, hi), engine space, closed): what a rebake keeps."""
    lo, hi = (np.asarray(b, dtype=np.float64) for b in box)
    out = {}
    for key, v in values.items():
        p = np.array(journal.KEY.unpack(key)[:3])
        if np.any(p < lo) or np.any(p > hi):
            out[key] = v
    return out


def _differences(before: dict, now: dict) -> List[str]:
    out = []
    for k in sorted(set(before) | set(now)):
        if k in _FREE or before.get(k) == now.get(k):
            continue
        out.append(f"{k} {before.get(k, '(absent)')!r} then, {now.get(k, '(absent)')!r} now")
    return out


def record_output(main_output: str, settings, scene: Dict[str, str], names: List[str],
                  previous: Optional[dict] = None):
    """The bake record (bake_outputs.Output) after a bake of the volumes ``names`` with
    ``settings`` in a scene of fingerprint parts ``scene``; ``previous``: the record a rebake keeps
    the other volumes' entries of."""
    from .bake_outputs import text_output
    volumes = dict(previous["volumes"]) if previous else {}
    part = {k: scene[k] for k in SCENE_PARTS if k in scene}
    for name in names:
        volumes[name] = {"file": volume_file_stem(name) + ".shprobe", "scene": part}
    record = {"format": RECORD_FORMAT, "version": RECORD_VERSION,
              "settings": settings_values(settings), "volumes": volumes}
    return text_output(record_path(main_output), "record", json.dumps(record, indent=2, sort_keys=False) + "\n",
                       sync=True)


class VolumeRebake:
    """Bake the volume ``name`` again, keeping the other volumes' files (module docstring).
    ``record`` is the previous bake's, once :meth:`select` has checked it."""

    def __init__(self, name: str, box=None):
        self.name = name
        self.record: Optional[dict] = None
        # The region, engine space (lo, hi): ``box`` (Blender space, x0 y0 z0 x1 y1 z1) within the
        # volume's bounds, else the bounds with VOLUME_MARGIN; set by select().
        self.box = None if box is None else np.asarray(box, dtype=np.float64).reshape(2, 3)
        self.region = None
        self.first_points = None   # the previous bake's first-round points kept outside the region (seed)

    def kept_tree(self, group) -> Optional["KeptTree"]:
        """The previous bake's tree and records that an Adaptive ``group`` (this volume's) keeps
        outside the region; None for a rebake of the whole volume (no box: nothing is kept)."""
        if self.box is None:
            return None
        return KeptTree(group.path, self.region, group.origin, group.min_cell)

    def output(self, main_output: str) -> str:
        """The file this rebake writes (its journal and shards are named after it)."""
        return volume_file(main_output, self.name)

    def check_settings(self, settings):
        """Before anything else: the rebake needs One File per Volume."""
        if not settings.per_volume_files:
            raise BakeError(f"Rebaking volume '{self.name}' alone needs One File per Volume (--per-volume-files "
                            "on): without it every volume is in one probes.shprobe, which a rebake would replace "
                            "whole; turn it on and bake every volume once")
        if self.box is not None and settings.placement == "ADAPTIVE" and settings.file_version != "V3":
            raise BakeError("A region rebake with Adaptive placement needs File Version 3: it keeps the previous "
                            "octree's leaves and probes outside the region, and a File Version 1 file holds a "
                            f"resampled grid instead; rebake the whole volume (--only-volume {self.name} without "
                            "--region) or bake with File Version 3")

    def select(self, groups: list, settings, main_output: str, collection: str) -> list:
        """The group (name, path, volumes) of this volume among a bake's ``groups``, after checking
        the previous bake: BakeError for an unknown name, no previous bake to keep or other
        settings."""
        names = [g[0] for g in groups]
        if self.name not in names:
            raise BakeError(f"No probe volume named '{self.name}' in collection '{collection}' (its volumes: "
                            f"{', '.join(repr(n) for n in names)})")
        path = record_path(main_output)
        record = read_record(path)
        if record is None:
            raise BakeError(f"No previous bake to keep: {path} is missing (the record a bake with One File per "
                            f"Volume writes); bake every volume once, then rebake '{self.name}'")
        diff = _differences(record.get("settings", {}), settings_values(settings))
        if diff:
            raise BakeError(f"The previous bake ({os.path.basename(path)}) was made with other settings: "
                            + "; ".join(diff) + f". Rebake every volume, or rebake '{self.name}' with the "
                            "previous settings")
        for name, file, _ in groups:
            if name != self.name and not os.path.exists(file):
                raise BakeError(f"No previous bake to keep for volume '{name}': {file} is missing; bake every "
                                f"volume once, then rebake '{self.name}'")
        self.record = record
        group = [g for g in groups if g[0] == self.name]
        self.region = self._region(group[0][2])
        return group

    def _region(self, volumes):
        """The region in engine space: the box within the volume's bounds, or the bounds."""
        verts = np.concatenate([np.asarray(v[1], dtype=np.float64).reshape(-1, 3) for v in volumes])
        lo, hi = verts.min(axis=0), verts.max(axis=0)
        if self.box is None:
            return lo - VOLUME_MARGIN, hi + VOLUME_MARGIN
        corners = scene_export.blender_to_engine(np.sort(self.box, axis=0))
        blo, bhi = corners.min(axis=0), corners.max(axis=0)
        if np.any(np.maximum(blo, lo) > np.minimum(bhi, hi)):
            a, b = (scene_export.engine_to_blender(c) for c in (lo, hi))
            bounds = " .. ".join("(" + ", ".join(f"{x:g}" for x in c) + ")" for c in (np.minimum(a, b), np.maximum(a, b)))
            raise BakeError(f"The region lies outside volume '{self.name}' (its bounds, Blender coordinates: "
                            f"{bounds}); give a box that meets the volume")
        return np.maximum(blo, lo), np.minimum(bhi, hi)

    def open(self, store, main_output: str, manifest: dict, messages: List[str], log) -> None:
        """After the journal is open: what changed in the kept volumes' scenes into ``messages``
        (scene_notes), then the previous bake's points into ``store`` (seed)."""
        messages.extend(self.scene_notes(manifest["parts"]))
        self.seed(store, main_output, manifest, log)

    def seed(self, store, main_output: str, manifest: dict, log) -> None:
        """Give ``store`` the previous bake's points outside the region (they stand for renders);
        BakeError when a box is given and no points were kept, or they are of other settings."""
        path = points_path(main_output)
        if not os.path.lexists(path):
            if self.box is not None:
                raise BakeError(f"No previous bake to keep: {path} is missing (the points a bake with One File "
                                "per Volume keeps); bake every volume once, then rebake a region")
            return
        try:
            kept = journal.read(path)
        except journal.JournalError as exc:
            raise BakeError(f"Cannot read the previous bake's points: {exc}; bake every volume again") from None
        if kept.manifest.get("parts", {}).get("settings") != manifest["parts"]["settings"]:
            raise BakeError(f"{path} was baked with other settings; bake every volume again")
        values = kept_outside(kept.values, self.region)
        taken = store.seed(values, kept.noise)
        # Their first rounds by position, for the kept nodes the previous bake rendered elsewhere
        # (AdaptivePlan.kept_value).
        keys = [journal.KEY.unpack(k) for k in values]
        self.first_points = np.array([k[:3] for k in keys if k[3] == 0], dtype=np.float64).reshape(-1, 3)
        log(f"Schnee: rebake of '{self.name}': {taken} point(s) of the previous bake kept outside the region, "
            f"{len(kept.values) - len(values)} inside it baked again")

    def scene_notes(self, scene: Dict[str, str]) -> List[str]:
        """What changed in the scene since the kept volumes were baked, beyond geometry: each of them
        keeps the earlier light (a message, not a refusal)."""
        notes = []
        for name, entry in sorted((self.record or {}).get("volumes", {}).items()):
            if name == self.name:
                continue
            before = entry.get("scene", {})
            changed = [_STALE[k] for k in _STALE if k in before and before[k] != scene.get(k)]
            if changed:
                notes.append(f"Volume '{name}' keeps its earlier bake, made before " + ", ".join(changed)
                             + " changed: bake every volume to bring it up to date")
        return notes


class KeptTree:
    """What an Adaptive region rebake keeps of the previous bake outside its region
    (docs/region-rebake.md "What a region keeps"): the previous file's octree, whose leaves that do
    not meet the region the refinement takes as they were (no test; split where the previous tree is
    split, :meth:`hold`), and the previous file's probe records, which the new file takes over bit for
    bit at every node outside the region that both trees have (:meth:`records`). ``path``: the
    volume's previous ``.shprobe``; ``region`` (lo, hi) engine space; ``origin``, ``min_cell``: the
    rebake's lattice, which must be the previous one's."""

    def __init__(self, path: str, region, origin, min_cell: float):
        try:
            self.file = native.read_shprobe(path)
            info = native.interpolation_from_file(path).info() if self.file.structure in ("octree", "kdtree") \
                else None
        except native.SchneeError as exc:
            raise BakeError(f"Cannot read the previous bake of this volume, {path}: {exc}; rebake the whole volume "
                            "(without --region)") from None
        if info is None:
            raise BakeError(f"{path} holds a {self.file.structure}, not the octree of an Adaptive bake with File "
                            "Version 3, so a region cannot keep its leaves; rebake the whole volume (without --region)")
        self.origin, self.min_cell = np.asarray(origin, dtype=np.float64), float(min_cell)
        if np.max(np.abs(np.asarray(info["origin"]) - self.origin)) > 1e-6 or abs(info["min_cell"] - self.min_cell) > 1e-9:
            raise BakeError(f"The previous bake of this volume ({os.path.basename(path)}) lies on another lattice (the "
                            "volume was moved or resized since): a region cannot keep it; rebake the whole volume "
                            "(without --region)")
        self.lo, self.hi = (np.asarray(r, dtype=np.float64) for r in region)
        self.leaf_lo, self.leaf_size = _leaf_boxes(info)
        self.leaf_row = {k: i for i, k in enumerate(leaf_keys(info))}
        self.node_row = {tuple(int(v) for v in p): i for i, p in enumerate(info["probe_lattice"])}
        # The previous sidecar, when it is valid for the file and its leaf rows are in the tree's order.
        side = bakeinfo.read(bakeinfo.path_for(path), path, self.file.probe_count, self.file.leaves)
        usable = not side.missing and side.error is None and np.array_equal(side.leaves, bakeinfo.file_leaf_words(info))
        self.sidecar = side if usable else None

    def meets(self, info: dict) -> np.ndarray:
        """(L,) bool: the leaves of a tree (``CornerOctree.info()``) that meet the closed region."""
        lattice_lo, size = _leaf_boxes(info)
        lo = self.origin + lattice_lo * self.min_cell
        hi = lo + size * self.min_cell
        return np.all((lo <= self.hi) & (hi >= self.lo), axis=1)

    def hold(self, group, tests, direct):
        """For ``group``'s current leaves: (``tests`` without the kept leaves' tests, ``direct`` (L,)
        axis masks with the kept leaves' zeroed, the kept leaves' split masks (L,) uint8). A kept leaf
        is one that does not meet the region; it splits along the axes along which every previous leaf
        inside it is smaller (the previous tree's first split of it, and the later ones every part of
        it took: the same leaves in the end), and stays whole where the previous tree has it as a leaf
        or holds it inside a larger leaf."""
        info = group.tree.info()
        lo, size = _leaf_boxes(info)
        kept = ~self.meets(info)
        masks = np.zeros(len(lo), dtype=np.uint8)
        keys = leaf_keys(info)
        for i in np.flatnonzero(kept):
            if keys[i] in self.leaf_row:
                continue
            inside = np.all((self.leaf_lo >= lo[i]) & (self.leaf_lo + self.leaf_size <= lo[i] + size[i]), axis=1)
            if inside.any():
                finer = np.all(self.leaf_size[inside] < size[i], axis=0)
                masks[i] = int(finer[0]) | int(finer[1]) << 1 | int(finer[2]) << 2
        rec = group.passes[-1]
        rec.kept, rec.kept_split = int(kept.sum()), int((masks != 0).sum())
        direct = np.where(kept, 0, np.asarray(direct)).astype(np.uint8)
        return without_leaves(tests, kept & (tests.leaf_tests >= 0).any(axis=1)), direct, masks

    def previous_rows(self, lattice: np.ndarray) -> np.ndarray:
        """(P,) int64: per probe of a tree (its lattice nodes), the previous file's probe at the same
        node when the node lies outside the region, else −1."""
        lattice = np.asarray(lattice, dtype=np.int64).reshape(-1, 3)
        pos = self.origin + lattice * self.min_cell
        outside = np.any((pos < self.lo) | (pos > self.hi), axis=1)
        out = np.full(len(lattice), -1, dtype=np.int64)
        for i in np.flatnonzero(outside):
            out[i] = self.node_row.get(tuple(int(v) for v in lattice[i]), -1)
        return out

    @staticmethod
    def stand_in(node, points: np.ndarray, radius: float):
        """The one point of ``points`` ((K, 3) engine space: the previous bake's first-round points kept
        outside the region) within ``radius`` of a kept ``node``'s lattice position, or None when there
        is none or more than one (AdaptivePlan.kept_value: the node is then rendered, and its record is
        still the previous file's). Nodes lie a Min Cell Size apart and each renders within ``radius`` of
        its own, so one point is the node's own render unless the Min Cell Size is below 2 ``radius``."""
        if points is None or len(points) == 0:
            return None
        near = np.flatnonzero(np.sum((points - np.asarray(node, dtype=np.float64)) ** 2, axis=1) <= radius * radius)
        return points[near[0]] if len(near) == 1 else None

    def records(self, rows: np.ndarray):
        """(new rows, the previous file's coefficients there (as stored: SH or ambient-cube faces),
        its validity there) for the probes whose :meth:`previous_rows` ``rows`` are kept."""
        new = np.flatnonzero(rows >= 0)
        validity = self.file.validity if self.file.validity is not None else np.ones(self.file.probe_count, np.float32)
        return new, self.file.coeffs[rows[new]], validity[rows[new]]

    def patch_sidecar(self, arrays: dict, group, rows: np.ndarray) -> None:
        """The new sidecar's ``arrays`` (bakeinfo.adaptive_arrays) with the previous sidecar's noise at
        the kept probes (``rows``: :meth:`previous_rows` of the final tree) and its leaf rows at the
        kept leaves that are previous leaves."""
        if self.sidecar is None:
            return
        keep = rows >= 0
        arrays["noise"][keep] = self.sidecar.noise[rows[keep]]
        info = group.tree.info()
        kept = ~self.meets(info)
        for i, key in enumerate(leaf_keys(info)):
            j = self.leaf_row.get(key)
            if kept[i] and j is not None:
                for name in ("error", "threshold", "parent_ratio", "reason"):
                    arrays["leaf_" + name][i] = getattr(self.sidecar, "leaf_" + name)[j]


def _leaf_boxes(info: dict):
    """(lattice min corners (L, 3), sizes per axis in min cells (L, 3)) of a tree's leaves."""
    return info["leaves"][:, :3].astype(np.int64), np.left_shift(1, leaf_levels(info).astype(np.int64))
