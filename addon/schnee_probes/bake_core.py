"""The probe bake as a stepper: prepare -> one probe per step -> finish (or cancel).

The same :class:`ProbeBake` object drives the modal operator (one panorama per timer tick), the
synchronous operator path and headless ``bake.py``::

    bake = ProbeBake(scene, view_layer, settings)      # or mode="CURSOR", cursor=(x, y, z)
    try:
        bake.prepare()                 # validate, place probes, override render settings
        while bake.step():             # render + project one probe
            print(bake.progress_line())
        result = bake.finish()         # write the files atomically, restore the scene
    except BaseException:
        bake.cancel()                  # restore the scene, write nothing
        raise

Nothing is written to the output folder before :meth:`ProbeBake.finish`; a failed or cancelled bake
leaves existing ``.shprobe`` files untouched. Every scene setting the bake changes goes through one
:class:`render_settings.StateGuard` and is restored by ``finish`` and ``cancel``.

Before any work :meth:`ProbeBake.prepare` refuses outputs that are not ours
(:func:`check_replaceable`: the open .blend, a file that is not a .shprobe by content, anything
not a regular file) and NaN/Inf emission (:func:`check_finite_emission`); after placement it logs
the probe count with an estimate (estimate.py) and refuses more than ``settings.probe_limit``
probes unless ``allow_large``. :meth:`ProbeBake.request_cancel` (Esc, or a signal through
:class:`CancelOnSignals`) stops the bake at the next check point: placement's progress, each
probe, before the sky and before writing.
"""
from __future__ import annotations

import json
import math
import os
import re
import shutil
import signal
import stat
import tempfile
import time
from dataclasses import dataclass, field
from typing import List, Optional, Sequence, Tuple

import bpy
import numpy as np

from . import adaptive, compat, direct_light, fingerprint, journal, light_modes, native, render_settings, scene_export
from .safe_open import file_kind
# The settings are declared in settings.py; re-exported here for scripts that use bake_core.*.
from .settings import DEFAULT_OUTPUT, PIXEL_FILTERS, BakeError, BakeSettings  # noqa: F401
from .estimate import (SECONDS_PER_PIXEL_SAMPLE, estimate_seconds, format_duration,  # noqa: F401
                       grid_cell_bound)

# The world (sky) alone, captured by a volume bake next to the probe files; the glTF exporter
# copies it and lists it as VULKAN_SCHNEE_engine_properties.sky (docs/export.md).
SKY_FILE_NAME = "sky.exr"
# The sky's sun split off as a mixed light (Sky Sun "mixed", docs/export.md "The sky's sun"); the
# file starts with SUN_MAGIC (json.dumps of a dict whose first key is "format", indent 2), which
# check_replaceable looks for before replacing or removing it.
SUN_FILE_NAME = "sun.json"
SUN_FORMAT = "schnee-sky-sun"
SUN_MAGIC = b'{\n  "format": "schnee-sky-sun"'
DEBUG_TEXT_NAME = "debug_probe.txt"
# Where Bake SH at Cursor puts its single-probe file when probes.shprobe holds a full bake:
# a subfolder, so the glTF exporter (which scans sh_coeffs/*.shprobe) never exports it.
DEBUG_SUBDIR = "debug"
DEBUG_SHPROBE_NAME = "debug_probe.shprobe"
DEBUG_TEXT_FIRST_LINE = "# Schnee probes: Bake SH at Cursor"
# How an existing file is recognised as one of ours before the bake replaces it (by content).
SHPROBE_MAGIC = b"SPHR"             # 0x52485053 little-endian at offset 0 (DESIGN.md §4)
EXR_MAGIC = b"\x76\x2f\x31\x01"     # OpenEXR
# Temporary folders: schnee_bake_<pid>_<random> in the system temporary folder; a folder whose
# process is gone was left by a killed bake and is removed by the next one.
TMP_PREFIX = "schnee_bake_"
# The journal beside the output (docs/farm.md): <output>.journal, a shard's <output>.shard-K-of-N.journal.
JOURNAL_SUFFIX = ".journal"


def journal_path_for(output_path: str) -> str:
    """The local journal of a bake writing ``output_path`` (may start with ``//``)."""
    return _abspath(output_path) + JOURNAL_SUFFIX


def shard_journal_path(output: str, k: int, n: int) -> str:
    return f"{output}.shard-{k}-of-{n}{JOURNAL_SUFFIX}"



@dataclass
class _Target:
    """One output file: its probes (indices into the unique render positions) and grid."""
    path: str
    name: str
    probe_render_index: np.ndarray
    grid: np.ndarray
    grid_dims: tuple
    grid_origin: tuple
    grid_spacing: float
    validity: Optional[np.ndarray] = None  # (P,) float32 1 - solid-test back-face ratio; None = all 1
    group: Optional["adaptive.AdaptiveGroup"] = None  # Adaptive placement: the refined octree


@dataclass
class BakeResult:
    """What a finished bake produced."""
    files: List[str]
    probe_count: int            # probes rendered (unique positions)
    seconds: float
    timings: dict = field(default_factory=dict)  # stage -> seconds summed over probes
    messages: List[str] = field(default_factory=list)
    renders: int = 0            # points rendered (Adaptive: probes and test points, 2 half renders each)
    passes: list = field(default_factory=list)  # Adaptive: adaptive.PassRecord per pass (first group)


def _safe_file_stem(name: str) -> str:
    stem = re.sub(r"[^A-Za-z0-9._-]+", "_", name).strip("._")
    return stem or "volume"


def _abspath(path: str) -> str:
    """Resolve ``//`` against the saved .blend; refuse it for an unsaved one."""
    if path.startswith("//") and not bpy.data.filepath:
        raise BakeError(
            "The .blend file is not saved, so '//' (the folder of the .blend) has no meaning: "
            f"save the file first or give an explicit output path instead of '{path}'")
    return os.path.abspath(bpy.path.abspath(path))


class ProbeBake:
    """One bake run. ``mode`` is "VOLUMES" (Bake SH in Volumes) or "CURSOR" (Bake SH at Cursor,
    ``cursor`` = Blender-space position). ``log`` receives human-readable lines."""

    def __init__(self, scene, view_layer, settings: BakeSettings, mode: str = "VOLUMES",
                 cursor: Optional[Sequence[float]] = None, log=print, allow_large=False, points=None,
                 shard: Optional[Tuple[int, int]] = None, merge_shards: Optional[int] = None,
                 restart: bool = False):
        if mode not in ("VOLUMES", "CURSOR", "POINTS"):
            raise ValueError(f"unknown bake mode {mode!r}")
        if mode == "CURSOR" and cursor is None:
            raise ValueError("a cursor bake needs a cursor position")
        self.scene = scene
        self.view_layer = view_layer
        self.settings = settings
        self.mode = mode
        self.cursor = None if cursor is None else tuple(float(c) for c in cursor)
        self.points = points  # mode "POINTS" (bake_points): engine-space positions, nothing written
        self.log = log
        self.positions = np.zeros((0, 3))   # unique probe positions, engine space
        self.coeffs = None                  # (P, sh_count, 3) float64
        self.targets: List[_Target] = []
        self.done = 0
        self.timings = {"placement": 0.0, "render": 0.0, "write_exr": 0.0, "project": 0.0}
        self.messages: List[str] = []
        self._state = None
        self._camera = None
        self._tmpdir = None
        self._t0 = None
        self._closed = False
        self._sky_exr = None                # rendered sky (temporary folder) until finish()
        self._realtime_lights = []          # lamps hidden from the probe renders (light_modes.py)
        self._mixed_lights = frozenset()    # names of lamps whose direct light the probes leave out
        self._direct = None                 # direct_light.DirectLightPlan (issue 11 hook)
        self._sky_sun = None                # [the world image's sun as a Sun lamp] or [] (_check_lamps)
        self.allow_large = allow_large      # bake above settings.probe_limit without asking
        self.estimated_seconds = None       # the cost model's estimate, set after placement
        self._cancel_requested = False
        self._first_probe_seconds = None
        # The render queue: indices into positions/coeffs, rendered in order. Adaptive placement
        # appends to it pass by pass (adaptive.py); the other modes fill it once in prepare().
        self._todo: List[int] = []
        self._cache: Optional[adaptive.PointCache] = None
        self._groups: List[adaptive.AdaptiveGroup] = []
        self._pass_start = 0                # self.done when the current adaptive stage began
        # The journal (journal.py, docs/farm.md): every rendered point is appended durably; a bake
        # that finds a matching journal takes its points from it instead of rendering them again.
        # shard = (k, n): render only the k-th of every n points of each stage (the rest come from
        # the other shards' journals) and write no .shprobe; merge_shards = n: take every point from
        # the n shard journals (and the local one) and write the files.
        if shard is not None and not (len(shard) == 2 and 0 <= shard[0] < shard[1]):
            raise ValueError(f"shard must be (k, n) with 0 <= k < n, not {shard!r}")
        if shard is not None and merge_shards is not None:
            raise ValueError("a bake is either one shard or the merge of the shards")
        if merge_shards is not None and merge_shards < 1:
            raise ValueError("merge_shards must be at least 1")
        self.shard = None if shard is None else (int(shard[0]), int(shard[1]))
        self.merge_shards = merge_shards
        self.restart = restart
        self.journal_path = None
        self.resumed = 0                    # points taken from journals instead of rendered
        self.rendered = 0                   # points rendered by this run
        self._journal = None
        self._known = {}                    # journal key -> coefficients, from journals at prepare
        self._known_noise = {}
        self._missing = 0                   # points of the current stage left to other shards
        self.shard_waiting = False          # a shard whose stage needs the other shards' points
        self._kept = 0                      # points in the journal when it was closed

    @property
    def adaptive(self) -> bool:
        return self.mode == "VOLUMES" and self.settings.placement == "ADAPTIVE"

    @property
    def renders_per_point(self) -> int:
        """Renders of one point: two half-sample renders for the Adaptive noise estimate, else one."""
        return 2 if self.adaptive else 1

    def request_cancel(self):
        """Ask the bake to stop (signal handlers, Esc): the next check point raises
        :class:`BakeCancelled`; the caller's cancel()/run() restores the scene and writes nothing."""
        self._cancel_requested = True

    @property
    def cancel_requested(self) -> bool:
        return self._cancel_requested

    def _check_cancel(self):
        if self._cancel_requested:
            raise BakeCancelled("Bake cancelled")

    # ------------------------------------------------------------------ prepare
    @property
    def total(self) -> int:
        """Points to render so far (Adaptive: grows pass by pass until the refinement ends)."""
        return len(self._todo)

    def prepare(self, placement_progress=None):
        """Validate the input, place the probes and set up rendering. Raises :class:`BakeError`."""
        self._t0 = time.perf_counter()
        # Before anything else: without the Cycles add-on nothing can be rendered (and scene.cycles
        # does not exist), so refuse with what to do instead of failing after placement.
        render_settings.require_cycles(self.scene)
        s = self.settings
        s.validate()
        self._realtime_lights, self._mixed_lights = self._check_light_modes()
        check_finite_emission(self.scene)
        min_w, min_h = native.min_panorama_size(s.max_band)
        if s.panorama_resolution < min_w or s.panorama_resolution // 2 < min_h:
            raise BakeError(f"Panorama Resolution {s.panorama_resolution} is too small for Max SH Band "
                            f"{s.max_band}: at least {min_w}x{min_h} is needed")
        if self.mode == "CURSOR":
            self._prepare_cursor()
            self._todo = list(range(len(self.positions)))
        elif self.mode == "POINTS":
            self.positions = np.asarray(self.points, dtype=np.float64).reshape(-1, 3)
            self._todo = list(range(len(self.positions)))
        elif self.adaptive:
            self._prepare_volumes(placement_progress)
        else:
            self._prepare_volumes(placement_progress)
            self._todo = list(range(len(self.positions)))
        if self.total == 0:
            raise BakeError("No probe could be placed: every candidate position is inside solid "
                            "geometry. Check the probe volumes or use a smaller Min Cell Size.")
        self._check_cancel()
        self.estimated_seconds = estimate_seconds(self.total, s, sky=self.mode == "VOLUMES",
                                                  renders=self.renders_per_point)
        if self.adaptive:
            self.log(f"Schnee: pass 1: {self.total} probe(s) of Max Cell Size to bake, estimated "
                     f"{format_duration(self.estimated_seconds)} (at most; then test points and finer "
                     f"cells only where the light needs them, at most "
                     f"{max(g.stage_count() for g in self._groups)} stages)")
        else:
            self.log(f"Schnee: {self.total} probe(s) to bake, estimated {format_duration(self.estimated_seconds)} "
                     f"(at most; {SECONDS_PER_PIXEL_SAMPLE * 1e6:.1f} µs per pixel-sample, refined after the "
                     "first probes)")
        if s.probe_limit and self.total > s.probe_limit and not self.allow_large:
            raise BakeTooLarge(self.total, self.estimated_seconds, s.probe_limit)
        if not self.adaptive:
            self.coeffs = np.zeros((self.total, native.sh_count(s.max_band), 3))
        if self.mode == "VOLUMES":
            self._open_journal()  # before _setup_render: the fingerprint is of the user's settings
        self._setup_render()

    def bake_positions(self, positions):
        """After :meth:`prepare` of a cursor bake: render these engine-space positions instead (the
        benchmarks' references at arbitrary points, with the bake's own render settings and camera)."""
        if self.mode != "CURSOR":
            raise BakeError("bake_positions() is for cursor bakes")
        self.positions = np.asarray(positions, dtype=np.float64).reshape(-1, 3)
        self.coeffs = np.zeros((len(self.positions), native.sh_count(self.settings.max_band), 3))
        self._todo = list(range(len(self.positions)))
        self.done = 0

    def _open_journal(self):
        """Open (or create at the first point) this bake's journal and load the points it and, for
        a merge, the shard journals already hold. A local journal of another bake is moved aside;
        a shard's or a merge's is an error."""
        main = _abspath(self.settings.output_path)
        manifest = journal.make_manifest(fingerprint.parts(self.scene, self.view_layer, self.settings),
                                         scene=self.scene.name, blend=bpy.data.filepath)
        count = native.sh_count(self.settings.max_band)
        if self.shard is not None:
            self.journal_path = shard_journal_path(main, *self.shard)
        else:
            self.journal_path = main + JOURNAL_SUFFIX
        check_replaceable(self.journal_path, "journal")
        if self.restart and os.path.lexists(self.journal_path):
            os.unlink(self.journal_path)
        if self.shard is None and self.merge_shards is None and os.path.lexists(self.journal_path):
            # A local journal of another bake (settings or scene changed since a cancel): kept one
            # generation back as <journal>.previous, and this bake starts from scratch. Shards and
            # merges refuse instead: mixing farm jobs of different scenes is a mistake to report.
            try:
                journal.read(self.journal_path, expect_manifest=manifest)
            except journal.JournalError as exc:
                previous = self.journal_path + ".previous"
                try:
                    os.replace(self.journal_path, previous)
                except OSError as exc2:
                    raise BakeError(f"{exc}; and it cannot be moved aside: {exc2}") from exc2
                self.log(f"Schnee: {exc}: not resumed; it was moved to {previous} and this bake starts from "
                         "scratch")
                self.messages.append(f"An earlier, different bake's journal was moved to {previous}")
        try:
            self._journal = journal.Writer(self.journal_path, manifest, count, shard=self.shard)
            self._known, self._known_noise = dict(self._journal.values), dict(self._journal.noise)
            others = []
            if self.merge_shards is not None:
                others = [shard_journal_path(main, k, self.merge_shards) for k in range(self.merge_shards)]
                missing = [p for p in others if not os.path.exists(p)]
                if missing:
                    raise BakeError(f"Cannot merge: {len(missing)} of {self.merge_shards} shard journal(s) "
                                    f"missing ({', '.join(os.path.basename(p) for p in missing)}); bake them "
                                    "first (--shard K/N)")
            elif self.shard is not None:
                k, n = self.shard
                others = [p for p in (shard_journal_path(main, j, n) for j in range(n) if j != k)
                          if os.path.exists(p)]
            if others:
                values, noise, _ = journal.merge(others, manifest)
                for key, v in values.items():
                    if key not in self._known:
                        self._known[key], self._known_noise[key] = v, noise[key]
        except journal.JournalError as exc:
            raise BakeError(f"{exc} (or bake with --restart to discard it)") from exc
        except OSError as exc:
            raise BakeError(f"Cannot open the bake journal {self.journal_path}: {exc}") from exc
        if self._journal.torn_bytes:
            self.log(f"Schnee: the journal's last {self._journal.torn_bytes} bytes were an incomplete record "
                     "(a crash mid-write); cut off")
        if self._known:
            where = self.journal_path if self.merge_shards is None else "the journals"
            pos = self._cache.positions if self.adaptive else self.positions
            hits = sum(journal.key_of(pos[i]) in self._known for i in self._todo)
            more = f" in the first pass ({len(self._known)} points in the journals)" if self.adaptive else ""
            self.log(f"Schnee: resuming from {where}: {hits} of {self.total} probes already baked, "
                     f"{self.total - hits} to render{more}")

    def _check_light_modes(self):
        """(the lamp objects marked realtime, the names of those marked mixed) by their
        ``schnee_light_mode`` (light_modes.py; a mixed lamp's direct light is left out of the probes,
        direct_light.prepare). Refuses a bad value before anything changes."""
        realtime, mixed = [], []
        for ob in compat.light_objects(self.scene):
            try:
                mode = light_modes.light_mode(ob)
            except light_modes.LightModeError as exc:
                raise BakeError(f"{exc}: set it in the Schnee Engine panel "
                                "(Light Mode) or remove the property") from exc
            if mode == light_modes.REALTIME:
                realtime.append(ob)
                if ob.data.type == 'AREA':
                    self.messages.append(f"Light '{ob.name}' is realtime but an area light, which "
                                         "glTF cannot export: its light reaches neither the probes "
                                         "nor the engine")
            elif mode == light_modes.MIXED:
                mixed.append(ob.name)
                if ob.data.type == 'AREA':
                    self.messages.append(f"Light '{ob.name}' is mixed but an area light, which glTF "
                                         "cannot export: only its bounced light reaches the probes "
                                         "and its direct light nothing")
        return realtime, frozenset(mixed)

    def _volume_objects(self):
        name = self.settings.volume_collection
        coll = bpy.data.collections.get(name)
        if coll is None:
            raise BakeError(f"Probe volume collection '{name}' not found: create a collection of that "
                            "name holding closed mesh objects")
        objects = list(coll.all_objects)
        if not objects:
            raise BakeError(f"Probe volume collection '{name}' is empty: add one or more closed mesh "
                            "objects to it")
        for ob in objects:
            if ob.type != 'MESH':
                raise BakeError(f"Object '{ob.name}' in probe volume collection '{name}' is a "
                                f"{ob.type.lower()}, not a mesh: only closed meshes can be probe volumes")
        return objects

    def _prepare_volumes(self, placement_progress):
        s = self.settings
        main_path = _abspath(s.output_path)
        objects = self._volume_objects()
        depsgraph = bpy.context.evaluated_depsgraph_get()
        volumes = [scene_export.volume_mesh(ob, depsgraph) for ob in objects]
        for name, _, tris in volumes:
            if len(tris) == 0:
                raise BakeError(f"Probe volume '{name}' has no faces: a volume must be a closed mesh")
        if s.per_volume_files:
            folder = os.path.dirname(main_path)
            groups, seen = [], {}
            for vol in volumes:
                stem = _safe_file_stem(vol[0])
                if stem in seen:
                    raise BakeError(f"Volumes '{seen[stem]}' and '{vol[0]}' would both be written to "
                                    f"'{stem}.shprobe': rename one of them")
                seen[stem] = vol[0]
                groups.append((vol[0], os.path.join(folder, stem + ".shprobe"), [vol]))
        else:
            groups = [(os.path.splitext(os.path.basename(main_path))[0], main_path, volumes)]
        # Refuse before any work is done to replace something that is not ours.
        for _, path, _ in groups:
            check_replaceable(path, "shprobe")
        if s.capture_sky:
            check_replaceable(os.path.join(os.path.dirname(main_path), SKY_FILE_NAME), "exr")
        # Written (Sky Sun "mixed" and a sun) or removed (else: a stale sun would be added twice).
        check_replaceable(os.path.join(os.path.dirname(main_path), SUN_FILE_NAME), "sun")
        exclude = frozenset(ob.name for ob in objects)
        # Solid geometry as Cycles renders it, not as the viewport shows it (render_settings.py).
        coll = bpy.data.collections.get(s.volume_collection)
        evaluation = render_settings.RenderEvaluation(self.scene, self.view_layer,
                                                      keep=exclude | {coll.name})
        with evaluation as render_depsgraph:
            geometry = scene_export.gather_geometry(render_depsgraph, exclude)
        if evaluation.skipped:
            self.messages.append("Placement could not match the viewport to the render for "
                                 + ", ".join(evaluation.skipped) + " (read-only data)")
        if evaluation.failed:
            self.log("Schnee: could not restore " + ", ".join(evaluation.failed))
        self.log(f"Schnee: {len(volumes)} volume(s), {len(geometry)} geometry mesh(es), "
                 f"{sum(len(g[2]) for g in geometry)} triangles")

        bound = grid_cell_bound(volumes, s.min_cell_size, s.per_volume_files)
        self.log(f"Schnee: placing probes (at most {bound} = the grid cells of Min Cell Size "
                 f"{s.min_cell_size:g} m; Esc / Ctrl+C cancels)")

        def progress(fraction, stage):
            if placement_progress is not None and placement_progress(fraction, stage) is False:
                return False
            return not self._cancel_requested

        t = time.perf_counter()
        if self.adaptive:
            self._prepare_adaptive(groups, geometry)
            self.timings["placement"] = time.perf_counter() - t
            return
        unique = {}
        positions = []
        for name, path, vols in groups:
            try:
                pl = native.place_probes(vols, geometry, s.min_cell_size, s.max_cell_size,
                                         progress=progress)
            except native.SchneeError as exc:
                if getattr(exc, "code", None) == "cancelled":
                    raise BakeCancelled("Bake cancelled") from exc
                raise BakeError(f"Probe placement failed: {exc}") from exc
            index = np.empty(len(pl.positions), dtype=np.int64)
            for i, p in enumerate(pl.positions):
                key = tuple(np.round(p, 6))
                if key not in unique:
                    unique[key] = len(positions)
                    positions.append(p)
                index[i] = unique[key]
            self.log(f"Schnee: '{name}': {len(pl.positions)} probes ({pl.pruned_count} pruned inside "
                     f"solid geometry), grid {pl.grid_dims[0]}x{pl.grid_dims[1]}x{pl.grid_dims[2]}")
            if len(pl.positions) == 0:
                raise BakeError(f"No probe could be placed in '{name}': every candidate position is "
                                "inside solid geometry")
            validity = np.clip(1.0 - np.asarray(pl.backface_ratio, dtype=np.float32), 0.0, 1.0)
            self.targets.append(_Target(path, name, index, np.asarray(pl.grid, dtype=np.int32),
                                        tuple(pl.grid_dims), tuple(pl.grid_origin), float(pl.grid_spacing),
                                        validity.astype(np.float32)))
        self.timings["placement"] = time.perf_counter() - t
        self.positions = np.array(positions, dtype=np.float64).reshape(-1, 3)

    def _prepare_adaptive(self, groups, geometry):
        """The first layer of every group's corner octree (adaptive.py); its probes start the queue."""
        s = self.settings
        self._cache = adaptive.PointCache(s.max_band)
        self._geometry = geometry
        for name, path, vols in groups:
            self._check_cancel()
            try:
                group = adaptive.AdaptiveGroup(name, path, vols, geometry, s.min_cell_size, s.max_cell_size,
                                               s.error_tolerance, s.refinement_tests, direct=self._direct_at,
                                               engine_direct=self._mixed_at)
                todo = group.start(self._cache)
            except native.SchneeError as exc:
                raise BakeError(f"Probe placement failed: {exc}") from exc
            self._groups.append(group)
            self._todo += todo
            rec = group.passes[0]
            self.log(f"Schnee: '{name}': Adaptive placement, lattice {s.min_cell_size:g} m, first layer "
                     f"{rec.leaves} cell(s) of {rec.smallest_cell:g} m with {rec.probes} probes "
                     f"({rec.probes - len(todo)} inside solid geometry or shared)")
            self.targets.append(_Target(path, name, np.zeros(0, dtype=np.int64), np.zeros(0, dtype=np.int32),
                                        (0, 0, 0), (0.0, 0.0, 0.0), float(s.min_cell_size), None, group))
        self.positions = self._cache.positions

    def _check_lamps(self) -> list:
        """The lamps of the refinement's direct-light check: the lamps added analytically, and with
        Sky Sun "baked" a Sun standing in for a sun in the world image (adaptive.sky_sun; only where
        the shadow geometry was gathered, i.e. with Lamps Seen by Probes, and the world is an image
        read as it is). With "mixed" the world's sun is not in the probes: it is one of the engine's
        lamps (_engine_lamps), like a mixed Sun lamp."""
        if self._sky_sun is None:
            self._sky_sun = []
            d = self._direct
            if d is not None and d.geometry and self.settings.sky_sun == "baked":
                src = direct_light.world_image(self.scene.world)
                sun = None if src is None else adaptive.sky_sun(np.clip(src[0][:, :, :3] * src[1], 0.0, None))
                if sun is not None:
                    self._sky_sun = [sun]
                    deg = math.degrees(sun.radius)
                    self.log(f"Schnee: the world's sun ({deg:.2g}° wide) is checked like a lamp where the "
                             "probes' light is interpolated")
        return (list(self._direct.lamps) if self._direct is not None else []) + self._sky_sun

    def _direct_at(self, positions: np.ndarray) -> Optional[np.ndarray]:
        """The check lamps' exact direct light (radiance SH) at engine-space positions, or None when
        there is none: the refinement's direct-light check (adaptive.AdaptiveGroup)."""
        return self._project_lamps(positions, self._check_lamps())

    def _engine_lamps(self) -> list:
        """The lights whose direct part the engine adds and the probes leave out: the mixed lamps,
        and with Sky Sun "mixed" the world's sun split off (direct_light.DirectLightPlan.sun_lamp;
        only with Lamps Seen by Probes, when the shadow geometry is gathered, as for mixed lamps)."""
        d = self._direct
        if d is None:
            return []
        lamps = list(d.mixed_lamps)
        if self.settings.sky_sun == "mixed" and self.settings.lights_visible:
            sun = d.sun_lamp(self)
            if sun is not None:
                lamps.append(sun)
        return lamps

    def _mixed_at(self, positions: np.ndarray) -> Optional[np.ndarray]:
        """The engine lamps' exact direct light at engine-space positions (the mixed lamps' and the
        sky's mixed sun's, which the probes leave out), or None without such lamps: the refinement
        judges the probes' error against the light a moving object gets, probe + this
        (adaptive.AdaptiveGroup.seen)."""
        return self._project_lamps(positions, self._engine_lamps())

    def _project_lamps(self, positions: np.ndarray, lamps: list) -> Optional[np.ndarray]:
        """``lamps``' exact direct light (radiance SH, shadowed) at engine-space positions, timed as
        "direct"; None without lamps."""
        if not lamps:
            return None
        t = time.perf_counter()
        out = self._direct.project(np.asarray(positions, dtype=np.float64).reshape(-1, 3), self.settings.max_band,
                                   lamps)
        self.timings["direct"] = self.timings.get("direct", 0.0) + time.perf_counter() - t
        return out

    def _advance_adaptive(self):
        """Every queued point is rendered: move each group on (tests -> decision -> split -> new
        probes) until something is queued or every group has finished."""
        while self.done == len(self._todo) and not all(g.finished for g in self._groups):
            self._check_cancel()
            for g in self._groups:
                if g.finished:
                    continue
                before = len(g.passes)
                try:
                    self._todo += g.advance(self._cache)
                except native.SchneeError as exc:
                    raise BakeError(f"Refinement of '{g.name}' failed: {exc}") from exc
                if len(g.passes) > before:
                    prev, rec = g.passes[-2], g.passes[-1]
                    extra = "".join([f", {prev.predicted} predicted to pass" if prev.predicted else "",
                                     f", {prev.retests} re-tested" if prev.retests else "",
                                     f", {prev.direct_split} split by the lamps' direct light"
                                     if prev.direct_split else ""])
                    self.log(f"Schnee: '{g.name}': pass {prev.pass_index}: {prev.split} of {prev.leaves} "
                             f"cell(s) split ({prev.tests} test points{extra}); pass {rec.pass_index}: "
                             f"{rec.leaves} cells down to {rec.smallest_cell:g} m, {rec.probes} probes")
                elif g.finished:
                    rec = g.passes[-1]
                    self.log(f"Schnee: '{g.name}': refinement done after {rec.pass_index} pass(es): "
                             f"{rec.leaves} cells, {rec.probes} probes")
        self.positions = self._cache.positions
        self._pass_start = self.done

    def _prepare_cursor(self):
        s = self.settings
        main_path = _abspath(s.output_path)
        folder = os.path.dirname(main_path)
        path = main_path
        if os.path.exists(main_path) and not _is_single_probe_file(main_path):
            # Never destroy a full bake for a debug probe.
            path = os.path.join(folder, DEBUG_SUBDIR, DEBUG_SHPROBE_NAME)
            self.messages.append(f"'{os.path.basename(main_path)}' holds a full bake; the debug probe "
                                 f"goes to '{path}'")
        self.debug_text_path = os.path.join(folder, DEBUG_TEXT_NAME)
        check_replaceable(path, "shprobe")
        check_replaceable(self.debug_text_path, "text")
        pos = scene_export.blender_to_engine(np.array([self.cursor]))[0]
        h = s.min_cell_size / 2
        self.positions = pos.reshape(1, 3)
        self.targets.append(_Target(path, "debug_probe", np.zeros(1, dtype=np.int64),
                                    np.zeros(1, dtype=np.int32), (1, 1, 1),
                                    tuple(float(c - h) for c in pos), float(s.min_cell_size)))

    def _setup_render(self):
        scene, s = self.scene, self.settings
        # A cursor bake hides the volumes too: a camera inside a closed volume would see its inside.
        coll = bpy.data.collections.get(s.volume_collection)
        volume_objects = list(coll.all_objects) if coll is not None else []
        lights = compat.light_objects(scene)
        # Every change below goes through one StateGuard, undone by _close() (finish and cancel).
        state = self._state = render_settings.StateGuard()
        state.snapshot(scene.render, "render")
        cycles = compat.cycles_settings(scene)  # saved/restored only where Cycles' settings exist
        if cycles is not None:
            state.snapshot(cycles, "cycles")
        state.snapshot(self.view_layer, "view_layer")
        frame = (scene.frame_current, scene.frame_subframe)

        def restore_frame():
            if (scene.frame_current, scene.frame_subframe) != frame:
                scene.frame_set(frame[0], subframe=frame[1])
        state.on_restore(restore_frame, "scene.frame")
        render_settings.apply_bake_settings(scene, self.view_layer, s)
        for ob in volume_objects:
            state.set(ob, "hide_render", True, f"object[{ob.name}].hide_render")
        for ob in lights:
            if compat.has_visible_camera(ob):
                state.set(ob, "visible_camera", s.lights_visible, f"object[{ob.name}].visible_camera")
        # Realtime lamps are the engine's direct light (VULKAN_SCHNEE_light): the probes must not
        # hold them too, so they are left out of every panorama render (restored on success, error
        # and cancel like everything else here).
        for ob in self._realtime_lights:
            state.set(ob, "hide_render", True, f"object[{ob.name}].hide_render")
        # --- issue 11 hook: lamps added analytically are hidden from camera rays (direct_light.py).
        self._direct = direct_light.prepare(self)

        cam_data = bpy.data.cameras.new("SchneeProbeCamera")
        compat.set_equirectangular(cam_data)
        cam_data.clip_start = 0.001
        cam_data.clip_end = 1.0e5
        cam = bpy.data.objects.new("SchneeProbeCamera", cam_data)
        # (90°, 0°, -90°): the orientation of DESIGN.md §3, so project_file's default rotation
        # yields engine-space coefficients.
        cam.rotation_mode = 'XYZ'
        cam.rotation_euler = (math.pi / 2, 0.0, -math.pi / 2)
        state.on_restore(lambda: _remove_camera(cam), "the probe camera")
        scene.collection.objects.link(cam)
        self._camera = cam
        state.set(scene, "camera", cam, "scene.camera")
        removed = clean_stale_temp_dirs()
        if removed:
            self.log(f"Schnee: removed {len(removed)} temporary folder(s) left by killed bakes: "
                     + ", ".join(removed))
        self._tmpdir = tempfile.mkdtemp(prefix=f"{TMP_PREFIX}{os.getpid()}_")
        tmpdir = self._tmpdir
        state.on_restore(lambda: shutil.rmtree(tmpdir, ignore_errors=True), "the temporary folder")

    # ------------------------------------------------------------------ steps
    def step(self) -> bool:
        """Render and project the next point (points the journals hold are taken from them, and a
        shard passes over the other shards' points). Returns True while points remain (Adaptive
        placement: when the last point of a stage is done, the refinement decides the next stage
        here; a shard whose stage needs points of other shards stops there: ``shard_waiting``)."""
        if self.shard_waiting or self.done >= self.total:
            return False
        self._check_cancel()
        while self.done < self.total:
            i = self._todo[self.done]
            pos = self._cache.positions[i] if self.adaptive else self.positions[i]
            retest = self.adaptive and self._cache.factor[i] > 0
            key = (journal.key_of(pos, adaptive.RETEST_FLAG if retest else 0)
                   if self._journal is not None else None)
            rendered = False
            if key is not None and key in self._known:
                self._store(i, self._known[key], self._known_noise[key])
                self.resumed += 1
            elif self.shard is not None and (self.done - self._pass_start) % self.shard[1] != self.shard[0]:
                self._missing += 1  # another shard's point
            elif self.merge_shards is not None:
                where = tuple(float(c) for c in scene_export.engine_to_blender(pos))
                raise BakeError(f"Cannot merge: the point at Blender ({where[0]:.3f}, {where[1]:.3f}, "
                                f"{where[2]:.3f}) is in no shard journal (shards still running or failed); "
                                "re-run the incomplete shards, then merge again")
            else:
                self._render_and_record(i, pos, key)
                rendered = True
            self.done += 1
            if self.adaptive and self.done == self.total:
                if self._missing:
                    self.shard_waiting = True
                    self.log(f"Schnee: shard {self.shard[0]}/{self.shard[1]}: its share of this pass is baked; "
                             "the next pass needs the other shards' points (the farm's next job continues)")
                    return False
                self._advance_adaptive()
            if rendered:
                break
        return self.done < self.total

    def _store(self, i, coeffs, noise):
        if self.adaptive:
            self._cache.coeffs[i], self._cache.noise[i] = coeffs, noise
            self._cache.rendered[i] = True
        else:
            self.coeffs[i] = coeffs

    def _render_and_record(self, i, pos, key):
        s = self.settings
        t0 = time.perf_counter()
        if self.adaptive:
            # Two renders of half the samples with different seeds: their difference measures this
            # point's Monte-Carlo noise, which the refinement must not mistake for light changing.
            # Cycles' persistent data ignores changed integrator settings unless the scene is
            # tagged (measured: identical renders for seeds 0 and 1 without update_tag).
            # A re-test (adaptive.RETEST) renders factor × the samples with seeds of its own, so it
            # is independent of the point's first render, which it is combined with.
            factor = int(self._cache.factor[i])
            seed = s.seed + (2 if factor > 0 else 0)
            s1, s2 = adaptive.split_samples(s.samples * max(factor, 1))
            cycles = self.scene.cycles
            cycles.samples, cycles.seed = s1, seed
            self.scene.update_tag()
            a = self._render_point(pos, i)
            cycles.samples, cycles.seed = s2, seed + 1
            self.scene.update_tag()
            b = self._render_point(pos, i)
            cycles.samples, cycles.seed = s.samples, s.seed
            if self._direct is not None and self._direct.lamps:
                # Issue 11: the lamps' direct light is exact (no noise), so it goes into both halves
                # before the noise estimate, and into every point before the refinement decides
                # (a sun's shadow edge must draw refinement like any other change of the light).
                t_d = time.perf_counter()
                lamp = self._direct.project(np.asarray(pos)[None, :], s.max_band)[0]
                a, b = a + lamp, b + lamp
                self.timings["direct"] = self.timings.get("direct", 0.0) + time.perf_counter() - t_d
            self._cache.coeffs[i], self._cache.noise[i] = adaptive.combine_halves(a, b, s1, s2)
            self._cache.rendered[i] = True
            value, noise = self._cache.coeffs[i], float(self._cache.noise[i])
        else:
            value, noise = self._render_point(pos, i), 0.0
            self.coeffs[i] = value
        if self._journal is not None:
            try:
                self._journal.append(key, value, noise)
            except OSError as exc:
                raise BakeError(f"Cannot write the bake journal {self.journal_path}: {exc}") from exc
        if self.rendered == 0:
            self._first_probe_seconds = time.perf_counter() - t0
        self.rendered += 1

    def _render_point(self, position, i):
        """Render the panorama at an engine-space position and project it: (C, 3) radiance SH."""
        s = self.settings
        self._camera.location = tuple(scene_export.engine_to_blender(position))
        exr = os.path.join(self._tmpdir, "probe.exr")
        t0 = time.perf_counter()
        bpy.ops.render.render(write_still=False, layer=self.view_layer.name, scene=self.scene.name)
        t1 = time.perf_counter()
        image = bpy.data.images.get("Render Result")
        if image is None:
            raise BakeError("Cycles produced no render result")
        image.save_render(exr, scene=self.scene)
        t2 = time.perf_counter()
        try:
            coeffs = native.project_file(exr, s.max_band, negative="clamp")
        except native.SchneeError as exc:
            where = tuple(float(c) for c in scene_export.engine_to_blender(position))
            hint = ""
            if getattr(exc, "code", None) == "non-finite value":
                hint = (": the render holds NaN or Inf, which the probes cannot represent (an "
                        "infinite or NaN value in the world, a texture or a shader); find it by "
                        "rendering from that position")
            raise BakeError(f"Projecting the panorama of probe {i + 1} at Blender "
                            f"({where[0]:.3f}, {where[1]:.3f}, {where[2]:.3f}) failed: {exc}{hint}") from exc
        if self._direct is not None:         # --- issue 11 hook: the world seen directly
            sky = self._direct.sky_coeffs(self, exr)
            if sky is not None:
                coeffs = coeffs + sky
        t3 = time.perf_counter()
        if not np.isfinite(coeffs).all():
            raise BakeError(f"Probe {i + 1}: the projected coefficients are not finite (NaN/Inf in "
                            "the render, e.g. an infinite emission)")
        self.timings["render"] += t1 - t0
        self.timings["write_exr"] += t2 - t1
        self.timings["project"] += t3 - t2
        return coeffs

    def remaining_seconds(self) -> float:
        """Time left: the cost model before the first probe, then the measured mean per probe
        (without the first probe's scene upload once a second one is done)."""
        left = self.total - self.done
        if self.rendered == 0:
            return estimate_seconds(left, self.settings, sky=self.mode == "VOLUMES",
                                    renders=self.renders_per_point)
        spent = self.timings["render"] + self.timings["write_exr"] + self.timings["project"]
        if self.rendered >= 2 and self._first_probe_seconds is not None:
            per = (spent - self._first_probe_seconds) / (self.rendered - 1)
        else:
            per = spent / self.rendered
        return per * left

    def progress_line(self) -> str:
        elapsed = time.perf_counter() - (self._t0 or time.perf_counter())
        eta = self.remaining_seconds()
        if self.adaptive:
            g = max(self._groups, key=lambda g: g.stage_index())
            rec = g.passes[-1]
            what = "test points" if g.stage == "tests" else "probes"
            if all(x.finished for x in self._groups):
                what = "done"
            return (f"Schnee bake: pass {rec.pass_index} ({what}, cells down to {rec.smallest_cell:g} m): "
                    f"{self.done - self._pass_start}/{self.total - self._pass_start}, {self.done} points "
                    f"rendered, {elapsed:.1f} s elapsed, ~{eta:.0f} s left in this pass")
        return f"Schnee bake: probe {self.done}/{self.total}, {elapsed:.1f} s elapsed, ~{eta:.0f} s left"

    def fraction(self) -> float:
        """Progress in [0, 1] for a progress bar. Adaptive: by stages (each stage's share of the most
        stages the refinement can take), as the number of points of later stages is not known yet."""
        if not self.adaptive:
            return self.done / self.total if self.total else 1.0
        if all(g.finished for g in self._groups):
            return 1.0
        g = max(self._groups, key=lambda g: g.stage_index())
        n = self.total - self._pass_start
        within = (self.done - self._pass_start) / n if n else 1.0
        return min(1.0, (g.stage_index() + within) / g.stage_count())

    def capture_sky(self):
        """Render the world alone (every object hidden from the render) as an equirect panorama of
        ``sky_resolution`` x ``sky_resolution / 2`` from the probe camera (DESIGN.md §3's mapping).
        Works for any world node setup, since Cycles renders the world itself. Objects' render
        visibility is restored right after the render."""
        s, scene = self.settings, self.scene
        t0 = time.perf_counter()
        render = scene.render
        with render_settings.StateGuard() as sky_state:
            for ob in scene.objects:
                if ob is not self._camera:
                    sky_state.set(ob, "hide_render", True, f"object[{ob.name}].hide_render")
            sky_state.set(render, "resolution_x", s.sky_resolution, "render.resolution_x")
            sky_state.set(render, "resolution_y", s.sky_resolution // 2, "render.resolution_y")
            sky_state.set(render, "resolution_percentage", 100, "render.resolution_percentage")
            sky_state.set(render, "film_transparent", False, "render.film_transparent")  # issue 11
            self._camera.location = (0.0, 0.0, 0.0)
            bpy.ops.render.render(write_still=False, layer=self.view_layer.name, scene=scene.name)
            image = bpy.data.images.get("Render Result")
            if image is None:
                raise BakeError("Cycles produced no render result for the sky")
            path = os.path.join(self._tmpdir, SKY_FILE_NAME)
            image.save_render(path, scene=scene)
        if sky_state.failed:
            self.log("Schnee: could not restore " + ", ".join(sky_state.failed))
        sun = self._sky_sun_split()
        if sun is not None:
            self._remove_sun_from(path, sun)
        self._sky_exr = path
        self.timings["sky"] = time.perf_counter() - t0

    def _sky_sun_split(self):
        """The world's sun split off under Sky Sun "mixed" (native.SkySun), or None (the world is
        read or captured now if no panorama has needed it yet, e.g. a bake resumed whole)."""
        d = self._direct
        if d is None or not d.sky or self.settings.sky_sun != "mixed":
            return None
        d.sun_lamp(self)         # splits the world if no panorama needed it yet (a bake resumed whole)
        return d.sun

    def _remove_sun_from(self, path, sun):
        """sky.exr (the engine's background, image-based specular and fallback probe 0) without the
        sun the probes left out, else the engine would count it twice (direct_light.remove_sun);
        written back through Blender as a float EXR with the bake's image settings."""
        img = bpy.data.images.load(path, check_existing=False)
        try:
            w, h = img.size
            ch = img.channels
            buf = np.empty(w * h * ch, dtype=np.float32)
            img.pixels.foreach_get(buf)
            pixels = np.ascontiguousarray(buf.reshape(h, w, ch)[::-1])
            clipped = np.clip(pixels, 0.0, None)
            rest, how = direct_light.remove_sun(clipped, sun)
            changed = np.any(rest[:, :, :3] != clipped[:, :, :3], axis=2)   # the sun's texels only
            pixels[changed, :3] = rest[changed, :3]
            img.pixels.foreach_set(np.ascontiguousarray(pixels[::-1]).reshape(-1))
            img.save_render(path, scene=self.scene)
        finally:
            bpy.data.images.remove(img)
        self.log(f"Schnee: the sun removed from {SKY_FILE_NAME} too ({how})")

    # ------------------------------------------------------------------ end
    def finish(self) -> BakeResult:
        """Write every output file (all or none), restore the scene and return the result."""
        try:
            if self.shard is not None:
                # A shard writes its journal only (the merge writes the files); the stage may wait
                # for other shards (shard_waiting), which is this job's success.
                if self.done < self.total and not self.shard_waiting:
                    raise BakeError(f"finish() after {self.done} of {self.total} points")
                files = [self.journal_path] if os.path.exists(self.journal_path) else []
            else:
                if self.done < self.total or not all(g.finished for g in self._groups):
                    raise BakeError(f"finish() after {self.done} of {self.total} probes")
                self._check_cancel()
                if self.mode == "VOLUMES" and self.settings.capture_sky and self._sky_exr is None:
                    self.capture_sky()
                if self._direct is not None and not self.adaptive:  # --- issue 11 hook: lamps' direct
                    self._direct.add_to(self)  # light (Adaptive adds it per point, before deciding)
                self._check_cancel()
                files = self._write_outputs()
                if self.journal_path is not None:  # the output is complete: the local journal is spent
                    self._close_journal()
                    _remove_quietly(self.journal_path)
        finally:
            self._close()
        probes = self.total
        if self.adaptive and self.shard is None:  # the probes in the files (shared positions once), not the tests
            probes = len(np.unique(np.concatenate([g.probe_index for g in self._groups])))
        result = BakeResult(files=files, probe_count=probes,
                            seconds=time.perf_counter() - self._t0, timings=dict(self.timings),
                            messages=list(self.messages), renders=self.done,
                            passes=list(self._groups[0].passes) if self._groups else [])
        return result

    def cancel(self):
        """Abandon the bake: restore the scene and remove temporary files; write no output. The
        points already baked stay in the journal, and the same bake run again resumes from them."""
        self._close()

    @property
    def kept_message(self) -> str:
        """What a cancelled or failed bake kept in its journal, for the user ('' when nothing)."""
        kept = self._kept if self._journal is None else len(self._journal.values)
        if self.journal_path is None or kept <= 0:
            return ""
        what = f"{kept} of {self.total} probes" if not self.adaptive else f"{kept} baked point(s)"
        return f"{what} kept in {self.journal_path}; the same bake run again resumes from them"

    def _close_journal(self):
        if self._journal is not None:
            self._kept = len(self._journal.values)
            self._journal.close()
            self._journal = None

    def _close(self):
        if self._closed:
            return
        self._closed = True
        self._close_journal()
        failed = self._state.restore() if self._state is not None else []
        self._camera = None
        self._tmpdir = None
        if failed:
            self.log("Schnee: could not restore " + ", ".join(failed))

    def _write_outputs(self):
        """Write all targets to temporary names, then rename them into place one after another.

        The temporary names are unique per bake (``<name>.<pid>-<random>.partial`` beside the final
        file), so two bakes writing to the same folder at once never share one. A failure while
        writing removes every temporary file and leaves all final files unchanged. The renames are
        not one atomic step: should a later rename fail (a full disk does not, a permission change
        between two renames could), the files already renamed are new and the rest keep their old
        contents; the error names the file. Every OS error is raised as :class:`BakeError`.
        """
        s = self.settings
        tag = f"{os.getpid()}-{os.urandom(4).hex()}"
        pending = []  # (tmp, final)

        def tmp_name(final):
            return f"{final}.{tag}.partial"

        # Checked before the bake started; again now, as the folder may have changed meanwhile.
        for t in self.targets:
            check_replaceable(t.path, "shprobe")
        if self._sky_exr is not None:
            check_replaceable(os.path.join(os.path.dirname(_abspath(s.output_path)), SKY_FILE_NAME), "exr")
        if self.mode == "CURSOR":
            check_replaceable(self.debug_text_path, "text")
        sun_path = None
        sun = None
        if self.mode == "VOLUMES":
            sun_path = os.path.join(os.path.dirname(_abspath(s.output_path)), SUN_FILE_NAME)
            check_replaceable(sun_path, "sun")
            sun = self._sky_sun_split()
        current = None
        try:
            for t in self.targets:
                current = t.path
                os.makedirs(os.path.dirname(t.path), exist_ok=True)
                tmp = tmp_name(t.path)
                if t.group is not None:
                    self._write_adaptive(t, tmp)
                    pending.append((tmp, t.path))
                    continue
                coeffs = self.coeffs[t.probe_render_index].astype(np.float32)
                extra = {}
                if s.max_band > 2:
                    # Version 2 anyway (DESIGN.md §4): carry what placement knows. L <= 2 stays v1.
                    extra = dict(positions=self.positions[t.probe_render_index].astype(np.float32),
                                 validity=t.validity)
                native.write_shprobe(tmp, coeffs, t.grid, t.grid_dims, t.grid_origin, t.grid_spacing,
                                     default_sh_scale=s.default_sh_scale,
                                     default_ambient=s.default_ambient, **extra)
                pending.append((tmp, t.path))
            if self._sky_exr is not None:
                final = os.path.join(os.path.dirname(_abspath(s.output_path)), SKY_FILE_NAME)
                current = final
                tmp = tmp_name(final)
                shutil.copyfile(self._sky_exr, tmp)
                pending.append((tmp, final))
            if sun is not None:
                current = sun_path
                tmp = tmp_name(sun_path)
                record = dict(format=SUN_FORMAT, **direct_light.sun_record(sun, self._direct.sky_source))
                with open(tmp, "w", encoding="utf-8") as fh:
                    fh.write(json.dumps(record, indent=2) + "\n")
                    fh.flush()
                    os.fsync(fh.fileno())
                pending.append((tmp, sun_path))
            if self.mode == "CURSOR":
                current = self.debug_text_path
                tmp = tmp_name(self.debug_text_path)
                with open(tmp, "w", encoding="utf-8") as fh:
                    fh.write(debug_text(self.cursor, self.positions[0], self.coeffs[0], s))
                pending.append((tmp, self.debug_text_path))
        except native.SchneeError as exc:
            for tmp, _ in pending:
                _remove_quietly(tmp)
            raise BakeError(f"Writing the probe file failed: {exc}") from exc
        except OSError as exc:
            for tmp, _ in pending:
                _remove_quietly(tmp)
            if current is not None:
                _remove_quietly(tmp_name(current))
            raise BakeError(f"Cannot write {current}: {exc}") from exc
        except BaseException:
            for tmp, _ in pending:
                _remove_quietly(tmp)
            raise
        for i, (tmp, final) in enumerate(pending):
            try:
                os.replace(tmp, final)
            except OSError as exc:
                for t, _ in pending[i:]:
                    _remove_quietly(t)
                done = [f for _, f in pending[:i]]
                raise BakeError(f"Cannot write {final}: {exc}"
                                + (f" (already replaced: {', '.join(done)})" if done else "")) from exc
        if sun_path is not None and sun is None and os.path.lexists(sun_path):
            # An earlier bake's sun (Sky Sun "mixed") that these probes hold or that the world no
            # longer has: the export would add it twice or add a sun that is not there.
            try:
                os.unlink(sun_path)
                self.log(f"Schnee: removed {sun_path}: this bake split no sun off the sky")
            except OSError as exc:
                raise BakeError(f"Cannot remove the earlier bake's {sun_path}: {exc}") from exc
        return [final for _, final in pending]

    def _write_adaptive(self, target, tmp):
        """Version 3 (the corner octree), or with File Version 1 the same field resampled onto the
        dense grid of Min Cell Size (version 2 above L = 2), to ``tmp``."""
        s = self.settings
        coeffs, validity = target.group.probe_values(self._cache)
        kw = dict(default_sh_scale=s.default_sh_scale, default_ambient=s.default_ambient)
        if s.file_version == "V3":
            if s.probe_representation == "SH":
                native.write_shprobe_v3(tmp, target.group.tree, coeffs.astype(np.float32), validity=validity, **kw)
            else:  # issue 16: the ambient cube fitted to each probe's SH
                cubes = native.ambient_cube_from_sh(coeffs)
                if s.probe_representation == "CUBE_HALF":
                    check_half_range(cubes, target.group.lattice_positions(target.group.tree.probe_lattice()),
                                     target.path)
                native.write_shprobe_v3(tmp, target.group.tree, cubes, representation="ambientCube",
                                        storage="float16" if s.probe_representation == "CUBE_HALF" else "float32",
                                        validity=validity, **kw)
            return
        v3 = os.path.join(self._tmpdir, "octree.shprobe")
        native.write_shprobe_v3(v3, target.group.tree, coeffs.astype(np.float32), validity=validity, **kw)
        dense = native.resample_shprobe_dense(v3)
        os.remove(v3)
        native.write_shprobe(tmp, dense.coeffs, dense.grid, dense.grid_dims, dense.grid_origin,
                             dense.grid_spacing, version=1 if s.max_band <= 2 else 0, **kw)

    def run(self, progress=None) -> BakeResult:
        """prepare + every step + finish, synchronously; ``progress(bake)`` after each probe may
        return False to cancel (raises :class:`BakeCancelled`). Restores the scene on any exit."""
        try:
            self.prepare()
            while self.done < self.total and not self.shard_waiting:
                self.step()
                if progress is not None and progress(self) is False:
                    raise BakeCancelled("Bake cancelled")
            return self.finish()
        except BaseException:
            self.cancel()
            raise


# Largest finite binary16 value: what Probe Representation "Ambient cube (half)" can store.
HALF_MAX = 65504.0
# Ambient-cube face k (engine axes +X, -X, +Y, -Y, +Z, -Z; native.ambient_cube_from_sh) named by
# the Blender axis it faces (engine (x, y, z) = Blender (x, z, -y)).
_CUBE_FACES_BLENDER = ("+X", "-X", "+Z", "-Z", "-Y", "+Y")


def check_half_range(cubes, positions, path):
    """Raise :class:`BakeError` unless every ambient-cube colour of ``cubes`` (P, 6, 3) fits
    binary16 (|value| <= 65504): the native writer would refuse the file naming only a record
    (issue 14: an emission of 1e30). The message names the first probe beyond the range, its
    position in Blender coordinates (``positions`` (P, 3) are engine space) and what to do."""
    cubes = np.asarray(cubes, dtype=np.float64)
    over = np.abs(cubes) > HALF_MAX
    if not over.any():
        return
    p, face, channel = (int(v) for v in np.argwhere(over)[0])
    where = tuple(float(c) for c in scene_export.engine_to_blender(np.asarray(positions)[p]))
    raise BakeError(
        f"Probe Representation 'Ambient cube (half)' cannot store {os.path.basename(path)}: probe {p + 1} of "
        f"{len(cubes)} at Blender ({where[0]:.3f}, {where[1]:.3f}, {where[2]:.3f}) has the irradiance "
        f"{cubes[p, face, channel]:.4g} ({'RGB'[channel]}, face {_CUBE_FACES_BLENDER[face]}), beyond half "
        f"floats' largest value {HALF_MAX:g} ({int(over.any(axis=(1, 2)).sum())} probe(s) in all); choose "
        f"Probe Representation 'Ambient cube (float)' (--probe-representation CUBE_FLOAT), or lower the "
        f"emission that lights it; existing files are unchanged")


def bake_points(scene, view_layer, settings, points, log=print) -> np.ndarray:
    """Radiance SH (N, sh_count, 3) baked at engine-space ``points`` (N, 3) with ``settings``'
    render quality, one panorama each, writing nothing: the reference of tests and benchmarks (the
    light a probe at exactly that point would hold). The scene is restored as after any bake."""
    bake = ProbeBake(scene, view_layer, settings, mode="POINTS", points=points, log=log)
    bake.run()
    return np.array(bake.coeffs)


class BakeCancelled(BakeError):
    """The user cancelled the bake (Esc, Ctrl+C, SIGTERM)."""


class BakeTooLarge(BakeError):
    """More probes than ``settings.probe_limit``: the bake needs a confirmation (``allow_large``)."""

    def __init__(self, probes, seconds, limit):
        self.probes, self.seconds, self.limit = probes, seconds, limit
        super().__init__(
            f"{probes} probes (estimated {format_duration(seconds)}) is more than the limit of "
            f"{limit} (Confirm Above): confirm the bake (bake.py: --allow-large), raise the limit "
            "(--probe-limit), or use a larger Min/Max Cell Size or smaller volumes")


# ------------------------------------------------------------------ estimate
# The cost model and the probe-count bound are in estimate.py (plain Python, tested without Blender).
def volume_bound(scene, settings):
    """(upper bound of the probe count, upper time estimate) for the panel and the dialog, from the
    volume objects' bounding boxes (no placement); (None, None) when the volumes are not usable."""
    coll = bpy.data.collections.get(settings.volume_collection)
    try:
        settings.validate()
    except BakeError:
        return None, None
    if coll is None:
        return None, None
    vols = []
    for ob in coll.all_objects:
        if ob.type != 'MESH':
            return None, None
        corners = [ob.matrix_world @ _vector(c) for c in ob.bound_box]
        vols.append((ob.name, np.array([tuple(c) for c in corners]), None))
    if not vols:
        return None, None
    bound = grid_cell_bound(vols, settings.min_cell_size, settings.per_volume_files)
    return bound, estimate_seconds(bound, settings, sky=True)


def _vector(c):
    from mathutils import Vector
    return Vector(tuple(c))


# ------------------------------------------------------------------ what we may replace
def check_replaceable(path, kind):
    """Raise :class:`BakeError` unless ``path`` is absent or a file the bake wrote: ``kind``
    "shprobe" (magic SPHR), "exr" (the sky), "sun" (sun.json) or "text" (debug_probe.txt). Never the open .blend,
    never something that is not a regular file. Opens nothing that could block (no FIFO)."""
    blend = bpy.data.filepath
    try:
        st = os.stat(path)
    except FileNotFoundError:
        return
    except OSError as exc:
        raise BakeError(f"Cannot write {path}: {exc.strerror}") from exc
    if blend:
        try:
            if os.path.samefile(path, blend):
                raise BakeError(f"Refusing to write {path}: it is the open .blend file; choose an "
                                "output ending in .shprobe")
        except OSError:
            pass
    if not stat.S_ISREG(st.st_mode):
        raise BakeError(f"Refusing to replace {path}: it exists and is a {file_kind(st.st_mode)}; "
                        "the bake only replaces files it wrote")
    want = {"shprobe": SHPROBE_MAGIC, "exr": EXR_MAGIC, "text": DEBUG_TEXT_FIRST_LINE.encode(),
            "journal": journal.MAGIC, "sun": SUN_MAGIC}[kind]
    try:
        fd = os.open(path, os.O_RDONLY | getattr(os, "O_NONBLOCK", 0) | getattr(os, "O_NOCTTY", 0))
        try:
            if not stat.S_ISREG(os.fstat(fd).st_mode):  # swapped since the stat above
                raise BakeError(f"Refusing to replace {path}: it is not a regular file")
            head = os.read(fd, len(want))
        finally:
            os.close(fd)
    except OSError as exc:
        raise BakeError(f"Cannot check {path} before replacing it: {exc.strerror}") from exc
    if head != want:
        what = {"shprobe": "a .shprobe file (no Schnee probe header)", "exr": "an OpenEXR image",
                "journal": "a Schnee bake journal", "sun": "a sun.json written by a bake",
                "text": "a debug_probe.txt written by Bake SH at Cursor"}[kind]
        raise BakeError(f"Refusing to replace {path}: it exists and is not {what}; move it away or "
                        "choose another output")


# ------------------------------------------------------------------ temporary folders
def clean_stale_temp_dirs(folder=None):
    """Remove ``schnee_bake_<pid>_*`` folders of this user whose process no longer runs (left by a
    killed bake); returns their names. Folders of running processes, of other users, and
    anything else are left alone."""
    folder = folder or tempfile.gettempdir()
    removed = []
    try:
        names = os.listdir(folder)
    except OSError:
        return removed
    for name in names:
        m = re.fullmatch(re.escape(TMP_PREFIX) + r"(\d+)_[A-Za-z0-9_]+", name)
        if not m:
            continue
        pid = int(m.group(1))
        path = os.path.join(folder, name)
        try:
            st = os.lstat(path)
        except OSError:
            continue
        if not stat.S_ISDIR(st.st_mode) or st.st_uid != os.getuid() or pid == os.getpid():
            continue
        if _pid_alive(pid):
            continue
        shutil.rmtree(path, ignore_errors=True)
        if not os.path.exists(path):
            removed.append(name)
    return removed


def _pid_alive(pid) -> bool:
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except PermissionError:
        return True   # another user's process: alive
    return True


# ------------------------------------------------------------------ signals
class CancelOnSignals:
    """``with CancelOnSignals(bake, (signal.SIGINT, signal.SIGTERM)) as caught:`` the first of
    these signals asks ``bake`` to cancel (like Esc) instead of killing the process; ``caught``
    lists the signals received. Python runs the handler between two Python steps, so a render in
    progress finishes first (one probe's time at most). The previous handlers are put back on
    exit; a handler Python cannot restore (installed by C, e.g. Blender's own) is left alone
    unless ``force`` is set (bake.py, which exits afterwards). With ``force``, once a signal was
    caught the signals stay ignored after the block: the process is leaving with the first
    signal's status, and a repeated Ctrl+C must not kill it half way through Blender's exit (the
    default action that would otherwise be back; issue 14). SIGKILL and SIGQUIT still end it."""

    def __init__(self, bake, signals=(signal.SIGINT, signal.SIGTERM), force=False, log=print):
        self.bake = bake
        self.signals = signals
        self.force = force
        self.log = log
        self.caught = []
        self._previous = {}

    def _handler(self, signum, frame):
        self.caught.append(signum)
        if self.bake is not None:
            self.bake.request_cancel()
        if len(self.caught) == 1:
            self.log(f"\nSchnee: {signal.Signals(signum).name} received: cancelling the bake "
                     "(render settings and files are restored)")

    def __enter__(self):
        for sig in self.signals:
            previous = signal.getsignal(sig)
            if previous is None and not self.force:
                continue
            self._previous[sig] = previous
            signal.signal(sig, self._handler)
        return self

    def __exit__(self, *exc):
        leaving = self.force and bool(self.caught)
        for sig, previous in self._previous.items():
            if leaving:
                previous = signal.SIG_IGN
            signal.signal(sig, previous if previous is not None else signal.SIG_DFL)
        self._previous.clear()
        return False


# ------------------------------------------------------------------ values the probes cannot hold
# Blender stores an Inf typed into a float field as the largest float32: that is Inf too.
_FLT_MAX = 3.4028234663852886e38


def _non_finite(value):
    """The first value of ``value`` (a number or a vector) that is NaN, Inf or Blender's clamped
    Inf, as text; None if all are finite."""
    try:
        values = tuple(value)
    except TypeError:
        values = (value,)
    for v in values:
        if isinstance(v, float):
            if math.isnan(v):
                return "NaN"
            if abs(v) >= _FLT_MAX:
                return "Inf" if math.isinf(v) else "Inf (stored as the largest float, 3.4e38)"
    return None


def _tree_problems(tree, where, seen):
    out = []
    if tree is None or tree.name_full in seen:
        return out
    seen.add(tree.name_full)
    for node in tree.nodes:
        for sock in node.inputs:
            if sock.is_linked or not hasattr(sock, "default_value"):
                continue
            bad = _non_finite(sock.default_value)
            if bad:
                out.append(f"{where}: node '{node.name}' input '{sock.name}' is {bad}")
        if node.type == 'GROUP' and node.node_tree is not None:
            out += _tree_problems(node.node_tree, f"{where} (group '{node.node_tree.name}')", seen)
    return out


def check_finite_emission(scene):
    """Refuse NaN/Inf in what lights the scene: unlinked node inputs of the materials of
    render-visible objects (an Emission Strength of inf, a NaN colour), lamps' energy and colour,
    the world's nodes. Cycles silently drops such values, so the probes would miss that light."""
    problems, seen_trees = [], set()
    for ob in scene.objects:
        if ob.hide_render:
            continue
        if ob.type == 'LIGHT':
            for ident in ("energy", "color"):
                bad = _non_finite(getattr(ob.data, ident))
                if bad:
                    problems.append(f"light '{ob.name}': {ident} is {bad}")
            if ob.data.use_nodes:
                problems += _tree_problems(ob.data.node_tree, f"light '{ob.name}'", set())
            continue
        for slot in getattr(ob, "material_slots", ()):
            mat = slot.material
            if mat is not None and mat.use_nodes:
                problems += [p + f" (on object '{ob.name}')" for p in
                             _tree_problems(mat.node_tree, f"material '{mat.name}'", seen_trees)]
    world = scene.world
    if world is not None and world.use_nodes:
        problems += _tree_problems(world.node_tree, f"world '{world.name}'", set())
    if problems:
        more = f" (and {len(problems) - 3} more)" if len(problems) > 3 else ""
        raise BakeError("Values the probes cannot represent (Cycles drops NaN/Inf, so this light "
                        "would be missing without a warning): " + "; ".join(problems[:3]) + more
                        + ". Set finite values")


def _remove_camera(cam):
    cam_data = cam.data
    bpy.data.objects.remove(cam, do_unlink=True)
    if cam_data is not None and cam_data.users == 0:
        bpy.data.cameras.remove(cam_data)


def _remove_quietly(path):
    try:
        os.remove(path)
    except OSError:
        pass


def _is_single_probe_file(path) -> bool:
    try:
        h = native.read_shprobe_header(path)
    except (native.SchneeError, OSError):
        return False  # unreadable: not a bake we would destroy knowingly, but not ours either
    return h["probe_count"] == 1 and tuple(h["grid_dims"]) == (1, 1, 1)


_AXES = (("+X", (1, 0, 0)), ("-X", (-1, 0, 0)), ("+Y", (0, 1, 0)), ("-Y", (0, -1, 0)),
         ("+Z", (0, 0, 1)), ("-Z", (0, 0, -1)))


def debug_text(cursor_blender, pos_engine, coeffs, settings) -> str:
    """The readable ``debug_probe.txt``: position, coefficients and irradiance along the axes."""
    lines = ["# Schnee probes: Bake SH at Cursor",
             f"# blender position (Z-up): {cursor_blender[0]:.6f} {cursor_blender[1]:.6f} {cursor_blender[2]:.6f}",
             f"# engine position (Y-up):  {pos_engine[0]:.6f} {pos_engine[1]:.6f} {pos_engine[2]:.6f}",
             f"# max band {settings.max_band}, panorama {settings.panorama_resolution}x"
             f"{settings.panorama_resolution // 2}, {settings.samples} samples, {settings.max_bounces} bounces",
             "# radiance SH coefficients L_i = integral L(w) Y_i(w) dw, engine space (DESIGN.md §3)",
             "# i  l  m          R            G            B"]
    i = 0
    for band in range(settings.max_band + 1):
        for m in range(-band, band + 1):
            r, g, b = coeffs[i]
            lines.append(f"{i:3d} {band:2d} {m:2d} {r:12.6f} {g:12.6f} {b:12.6f}")
            i += 1
    normals = np.array([a[1] for a in _AXES], dtype=np.float64)
    irr = native.irradiance(np.asarray(coeffs, dtype=np.float64), normals)
    lines.append("# irradiance E(n) (W/m^2 in Cycles units) for normals along the engine axes "
                 "(engine +Y = Blender +Z, engine -Z = Blender +Y)")
    lines.append("# axis        R            G            B")
    for (label, _), (r, g, b) in zip(_AXES, irr):
        lines.append(f"{label:>6} {r:12.6f} {g:12.6f} {b:12.6f}")
    return "\n".join(lines) + "\n"
