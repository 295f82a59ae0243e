"""What the viewport overlay draws, read from the scene's baked ``.shprobe`` files (docs/overlay.md).

No ``gpu`` here: numpy and the add-on's native reader only, so the numbers the overlay draws can be
checked without a GPU. :func:`scene_files` says which files a scene's bakes wrote; :func:`load` reads
one through :func:`native.read_shprobe` into a :class:`ProbeSet` (Blender-space positions, the
L0-L2 coefficients premultiplied for shading, validity, the cells as line segments), cached per path
and re-read when the file's mtime or size changes (a new bake, a reload). A missing or malformed
file is a :class:`ProbeSet` with ``error`` set, never an exception: the panel shows the message.
"""
from __future__ import annotations

import math
import os
import time
from dataclasses import dataclass, field
from typing import Dict, Iterator, List, Optional, Tuple

import numpy as np

from . import bakeinfo, native, scene_export

# DESIGN.md §3: Lambert's A_l for bands 0..2, and the real SH basis constants (no Condon-Shortley).
A_L = (math.pi, 2.0 * math.pi / 3.0, math.pi / 4.0)
BAND_OF = (0, 1, 1, 1, 2, 2, 2, 2, 2)
# Cells drawn at most (12 edges each for a box, 6 for a tetrahedron); past this the panel says so.
MAX_CELLS = 300_000


@dataclass
class ProbeSet:
    """One ``.shprobe`` as the overlay draws it. ``shading`` (P, 9, 3) float32: engine-space radiance
    SH (L0-L2) times A_l / π times the probe's scale, so ``Σ_i shading_i · Y_i(n_engine)`` is the
    radiance a white Lambertian surface with normal n reflects (the engine's
    ``shScale · max(E(n), 0) / π``, DESIGN.md §3, with the ambient term left out)."""
    path: str
    error: Optional[str] = None
    version: int = 0
    structure: str = ""
    representation: str = "sh"
    max_band: int = 0
    positions: np.ndarray = field(default_factory=lambda: np.zeros((0, 3), np.float32))  # Blender space
    shading: np.ndarray = field(default_factory=lambda: np.zeros((0, 9, 3), np.float32))
    validity: np.ndarray = field(default_factory=lambda: np.zeros(0, np.float32))
    has_validity: bool = False
    spacing: float = 0.0
    cell_lines: np.ndarray = field(default_factory=lambda: np.zeros((0, 3), np.float32))  # 2 rows/segment
    cell_levels: np.ndarray = field(default_factory=lambda: np.zeros(0, np.float32))      # per vertex
    cell_count: int = 0
    cells_left_out: int = 0
    stamp: Tuple[int, int] = (0, 0)
    leaves: Optional[np.ndarray] = None       # (L, 4) the file's octree / kd-tree leaves
    leaf_centres: np.ndarray = field(default_factory=lambda: np.zeros((0, 3), np.float32))  # Blender space
    info: Optional[bakeinfo.BakeInfo] = None  # the bake-info sidecar (docs/bakeinfo.md)

    @property
    def probe_count(self) -> int:
        return int(self.positions.shape[0])

    @property
    def has_noise(self) -> bool:
        return self.info is not None and self.info.error is None and self.info.noise is not None

    @property
    def has_refinement(self) -> bool:
        return self.info is not None and self.info.error is None and self.info.leaf_reason is not None

    def info_line(self) -> str:
        """One line for the panel: what the sidecar adds (Noise and Refinement modes), or why not."""
        if self.info is None or self.info.missing:
            return ("Noise, refinement: not stored for this file (baked before bake-info sidecars, "
                    "or not by Adaptive placement with File Version 3)")
        if self.info.error:
            return self.info.error
        return "Noise" + (", refinement" if self.has_refinement else "") + \
            f" stored (Error Tolerance {self.info.tolerance:g})"

    def holds(self) -> str:
        """One line for the panel: what the file holds that the colour modes can show."""
        if self.error:
            return self.error
        parts = [f"v{self.version} {self.structure}", f"{self.probe_count} probes"]
        parts.append("validity" if self.has_validity else "no validity (all 1)")
        parts.append(self.info_line())
        return ", ".join(parts)


def scene_files(props) -> List[str]:
    """The ``.shprobe`` files the scene's bakes wrote: those the last bake recorded (``last_files``,
    saved with the .blend, so a reload finds them), then the Output path, each once, existing or not
    (a missing one is reported). Paths are absolute; ``//`` in an unsaved file is skipped."""
    import bpy
    out = []
    names = [p for p in (props.last_files or "").split(";") if p.endswith(".shprobe")]
    names.append(props.output_path)
    for p in names:
        if p.startswith("//") and not bpy.data.filepath:
            continue
        full = os.path.abspath(bpy.path.abspath(p))
        if full not in out:
            out.append(full)
    return out


def lattice_to_blender(u: np.ndarray, origin, spacing: float, axes) -> np.ndarray:
    """Lattice coordinates (N, 3) -> Blender-space points: engine p = origin + spacing · axesᵀ u
    (docs/shprobe-format.md), then engine (x, y, z) -> Blender (x, −z, y)."""
    eng = np.asarray(origin, np.float64) + spacing * (np.asarray(u, np.float64) @ np.asarray(axes, np.float64))
    return scene_export.engine_to_blender(eng)


def shading_coefficients(coeffs: np.ndarray, scale: np.ndarray) -> np.ndarray:
    """(P, ≥9, 3) radiance SH -> (P, 9, 3) float32 L0-L2 times A_l / π times each probe's scale; a
    file with L < 2 is padded with zeros. Bands above 2 are left out: A3 = 0 and A4 = −π/24 is the
    engine's too, but the overlay's spheres use L0-L2 as a v1 file holds (docs/overlay.md)."""
    c = np.zeros((coeffs.shape[0], 9, 3), np.float64)
    k = min(9, coeffs.shape[1])
    c[:, :k] = coeffs[:, :k]
    w = np.array([A_L[BAND_OF[i]] / math.pi for i in range(9)])
    return (c * w[None, :, None] * np.asarray(scale, np.float64)[:, None, None]).astype(np.float32)


_BOX_EDGES = np.array([(0, 1), (2, 3), (4, 5), (6, 7), (0, 2), (1, 3), (4, 6), (5, 7),
                       (0, 4), (1, 5), (2, 6), (3, 7)])
_TET_EDGES = np.array([(0, 1), (0, 2), (0, 3), (1, 2), (1, 3), (2, 3)])
_CORNERS = np.array([(c & 1, c >> 1 & 1, c >> 2 & 1) for c in range(8)], np.float64)


def _box_lines(lo: np.ndarray, size: np.ndarray) -> np.ndarray:
    """Boxes (N, 3) min corner and (N, 3) size in lattice units -> (N·24, 3) segment end points."""
    corners = lo[:, None, :] + _CORNERS[None] * size[:, None, :]      # (N, 8, 3)
    return corners[:, _BOX_EDGES.reshape(-1)].reshape(-1, 3)


CHUNK_CELLS = 16_384   # cells turned into lines per step of a background read (Reader.step)


def _cell_boxes(f, ps: ProbeSet):
    """The file's cells as (lo, size, levels) lattice boxes, or tetrahedra as (tets, None, None); None
    for a file with no cells. Sets ``cell_count`` and ``cells_left_out``."""
    if f.structure == "grid":
        dims = f.grid_dims
        flat = np.nonzero(np.asarray(f.grid) >= 0)[0]
        ps.cell_count = len(flat)
        flat = flat[:MAX_CELLS]
        X, Y = dims[0], dims[1]
        lo = np.stack([flat % X, (flat // X) % Y, flat // (X * Y)], axis=1).astype(np.float64)
        boxes = (lo, np.ones_like(lo), np.zeros(len(lo)))
    elif f.structure in ("octree", "kdtree"):
        leaves = np.asarray(f.leaves)
        ps.cell_count = len(leaves)
        leaves = leaves[:MAX_CELLS]
        lo, size = _leaf_boxes(f.structure, leaves)
        boxes = (lo, size, np.log2(size).max(axis=1))
    elif f.structure == "tetrahedra":
        tets = np.asarray(f.tets)
        ps.cell_count = len(tets)
        boxes = (tets[:MAX_CELLS], None, None)
    else:
        return None
    ps.cells_left_out = ps.cell_count - min(ps.cell_count, MAX_CELLS)
    return boxes


def _leaf_boxes(structure: str, leaves: np.ndarray):
    """(lo, size) lattice boxes (N, 3) of a v3 octree's (level) or a v4 kd-tree's (packed levels) leaves."""
    lo = leaves[:, :3].astype(np.float64)
    word = leaves[:, 3].astype(np.int64)
    if structure == "octree":
        lv = np.repeat(word[:, None], 3, axis=1)
    else:
        lv = np.stack([word & 0xFF, word >> 8 & 0xFF, word >> 16 & 0xFF], axis=1)
    return lo, np.exp2(lv.astype(np.float64))


def _cells(f, ps: ProbeSet) -> Iterator[None]:
    """The file's interpolation cells as line segments (Blender space) and a level per vertex, made
    :data:`CHUNK_CELLS` cells per step (a generator: it yields between steps)."""
    boxes = _cell_boxes(f, ps)
    if boxes is None:
        return
    first, size, levels = boxes
    lines, lvls = [], []
    for a in range(0, len(first), CHUNK_CELLS):
        b = a + CHUNK_CELLS
        if size is None:   # tetrahedra: their corner probes' positions
            seg = ps.positions[first[a:b][:, _TET_EDGES.reshape(-1)].reshape(-1)].astype(np.float32)
            lvls.append(np.zeros(len(seg), np.float32))
        else:
            seg = _box_lines(first[a:b], size[a:b])
            lvls.append(np.repeat(levels[a:b], 24).astype(np.float32))
            seg = lattice_to_blender(seg, f.grid_origin, f.grid_spacing, f.grid_axes).astype(np.float32)
        lines.append(seg)
        yield
    if lines:
        ps.cell_lines = np.concatenate(lines)
        ps.cell_levels = np.concatenate(lvls)


def _grid_positions(f) -> np.ndarray:
    """Version 1 holds no positions: each probe at the centre of the first grid cell that names it
    (docs/shprobe-format.md), in Blender space."""
    grid = np.asarray(f.grid)
    X, Y, _ = f.grid_dims
    cells = np.nonzero(grid >= 0)[0]
    probe = grid[cells]
    first = np.full(f.probe_count, -1, np.int64)
    # The first cell per probe: walk backwards so the smallest flat index is written last.
    first[probe[::-1]] = cells[::-1]
    if (first < 0).any():
        raise native.SchneeError("some probes are in no grid cell, so they have no position")
    u = np.stack([first % X, (first // X) % Y, first // (X * Y)], axis=1) + 0.5
    return lattice_to_blender(u, f.grid_origin, f.grid_spacing, f.grid_axes)


def _begin(path: str) -> ProbeSet:
    """The file's ProbeSet with its (mtime, size) stamp, or with ``error`` if it cannot be read."""
    ps = ProbeSet(path=path)
    try:
        st = os.stat(path)
    except OSError as exc:
        ps.error = f"{os.path.basename(path)}: not found ({exc.strerror})"
        return ps
    ps.stamp = (st.st_mtime_ns, st.st_size)
    ps.error = native.native_problem()
    return ps


def _build(ps: ProbeSet, f) -> Iterator[None]:
    """Fill ``ps`` from the read file ``f`` (a generator: it yields between steps)."""
    ps.version, ps.structure, ps.representation = f.version, f.structure, f.representation
    ps.max_band, ps.spacing = f.max_band, float(f.grid_spacing)
    if f.representation != "sh":
        ps.error = (f"{os.path.basename(ps.path)}: an ambient-cube file; the overlay draws SH files "
                    "(bake with Probe Representation SH to see it)")
        return
    if f.positions is not None:
        ps.positions = scene_export.engine_to_blender(f.positions).astype(np.float32)
    else:
        ps.positions = _grid_positions(f).astype(np.float32)
    ps.shading = shading_coefficients(f.coeffs, f.probe_scale)
    ps.has_validity = f.version >= 2 and f.validity is not None and len(f.validity) == f.probe_count
    ps.validity = (np.asarray(f.validity, np.float32) if ps.has_validity
                   else np.ones(f.probe_count, np.float32))
    if f.structure in ("octree", "kdtree"):
        ps.leaves = np.asarray(f.leaves, np.uint32)
        lo, size = _leaf_boxes(f.structure, ps.leaves)
        ps.leaf_centres = lattice_to_blender(lo + size / 2, f.grid_origin, f.grid_spacing,
                                             f.grid_axes).astype(np.float32)
    yield
    yield from _cells(f, ps)
    yield from _sidecar(ps)


def _sidecar(ps: ProbeSet) -> Iterator[None]:
    """The bake-info sidecar beside the file (bakeinfo.read_steps: the .shprobe hashed in steps)."""
    out: List[bakeinfo.BakeInfo] = []
    yield from bakeinfo.read_steps(bakeinfo.path_for(ps.path), ps.path, ps.probe_count, ps.leaves, out)
    ps.info = out[0]


_READ_ERRORS = (native.SchneeError, OSError, ValueError)


def _failed(ps: ProbeSet, exc: BaseException) -> ProbeSet:
    return ProbeSet(path=ps.path, stamp=ps.stamp, error=f"{os.path.basename(ps.path)}: {exc}")


def read(path: str) -> ProbeSet:
    """Read ``path`` into a :class:`ProbeSet`; a missing or malformed file gives one with ``error``."""
    ps = _begin(path)
    if ps.error:
        return ps
    try:
        for _ in _build(ps, native.read_shprobe(path)):
            pass
    except _READ_ERRORS as exc:
        return _failed(ps, exc)
    return ps


class Reader:
    """:func:`load` off the UI: the file is parsed on a native thread that runs no Python
    (native.ShprobeRead: Blender 3.4 crashes when a Python thread runs while it draws), then
    :meth:`step`, called from a timer on Blender's main thread, turns it into a :class:`ProbeSet`
    :data:`CHUNK_CELLS` cells at a time until its deadline, and caches it."""

    def __init__(self, path: str):
        self.path = path
        self.ps = _begin(path)
        self._job = self._steps = None
        if not self.ps.error:
            try:
                self._job = native.ShprobeRead(path)
            except _READ_ERRORS as exc:
                self.ps = _failed(self.ps, exc)

    def step(self, deadline: float) -> bool:
        """Work until ``time.perf_counter()`` passes ``deadline`` (at least one step); True when the
        ProbeSet is done and in the cache, False while the file is still being read or built."""
        try:
            if self._steps is None and self._job is not None:
                f = self._job.poll()
                if f is None:
                    return False
                self._job = None
                self._steps = _build(self.ps, f)
            if self._steps is not None:
                for _ in self._steps:
                    if time.perf_counter() >= deadline:
                        return False
        except _READ_ERRORS as exc:
            self.ps = _failed(self.ps, exc)
        self._steps = None
        _cache[self.path] = self.ps
        return True


_cache: Dict[str, ProbeSet] = {}


def cached(path: str) -> Optional[ProbeSet]:
    """The cached :class:`ProbeSet` of ``path`` while the file's (mtime, size) is unchanged, else None."""
    try:
        st = os.stat(path)
        stamp = (st.st_mtime_ns, st.st_size)
    except OSError:
        stamp = None
    hit = _cache.get(path)
    if hit is not None and stamp is not None and hit.stamp == stamp and _info_current(hit):
        return hit
    return None


def _info_current(ps: ProbeSet) -> bool:
    """The sidecar read with ``ps`` is still the one on disk (written, replaced or removed since: no)."""
    if ps.error or ps.info is None:
        return True
    now = bakeinfo.stamp_of(bakeinfo.path_for(ps.path))
    return now is None if ps.info.missing else now == ps.info.stamp


def load(path: str) -> ProbeSet:
    """:func:`read` through a cache keyed by path, re-read when the file's (mtime, size) changed.
    It blocks; the overlay reads with a :class:`Reader` instead (overlay.probe_set)."""
    hit = cached(path)
    if hit is not None:
        return hit
    ps = read(path)
    _cache[path] = ps
    return ps


def clear_cache() -> None:
    _cache.clear()


# Colour modes Noise and Refinement (docs/overlay.md): linear RGB.
GREEN, YELLOW, RED = np.array([0.02, 0.8, 0.05]), np.array([1.0, 0.8, 0.0]), np.array([1.0, 0.02, 0.02])
GREY = np.array([0.5, 0.5, 0.5])
REFINEMENT_COLOURS = {bakeinfo.NOISE_LIMITED: (0.9, 0.1, 1.0), bakeinfo.NEVER_TESTED: (0.1, 0.35, 1.0),
                      bakeinfo.NOT_COMPARED: tuple(GREY), bakeinfo.UNKNOWN: tuple(GREY)}
MIN_CELL_BELOW = (1.0, 0.45, 0.0)   # at Min Cell Size, its parent's error here within the threshold


def noise_colours(noise: np.ndarray, tolerance: float) -> np.ndarray:
    """(P, 3): σ / Error Tolerance 0 green, ½ (the bake's target for a probe's noise) yellow, ≥ 1
    red, linear between; not measured (NaN) grey."""
    r = np.asarray(noise, np.float64) / float(tolerance)
    c = traffic_light(np.nan_to_num(r))
    c[~np.isfinite(r)] = GREY
    return c


def traffic_light(x: np.ndarray) -> np.ndarray:
    """(N, 3) float32: x 0 green, 0.5 yellow, 1 red (clamped), linear between."""
    x = np.clip(np.asarray(x, np.float64), 0.0, 1.0)[:, None]
    return np.where(x < 0.5, GREEN + (YELLOW - GREEN) * (x * 2), YELLOW + (RED - YELLOW) * (x * 2 - 1)).astype(np.float32)


def refinement_colours(reason: np.ndarray, ratio: np.ndarray, parent_ratio: np.ndarray) -> np.ndarray:
    """(L, 3) per leaf: passed green → yellow as its worst test error / threshold goes 0 → 1;
    noise-limited magenta; at Min Cell Size red where its parent's error here was above the
    threshold (the light still changes more than the tolerance: only a smaller Min Cell Size would
    follow it), orange where not; never tested (predicted to pass) blue; not compared grey."""
    reason = np.asarray(reason)
    x = np.clip(np.nan_to_num(np.asarray(ratio, np.float64)), 0.0, 1.0)[:, None]
    c = GREEN + (YELLOW - GREEN) * x
    for code, colour in REFINEMENT_COLOURS.items():
        c[reason == code] = colour
    at_min = reason == bakeinfo.MIN_CELL
    above = np.nan_to_num(np.asarray(parent_ratio, np.float64)) > 1.0
    c[at_min & above] = RED
    c[at_min & ~above] = MIN_CELL_BELOW
    return c.astype(np.float32)
