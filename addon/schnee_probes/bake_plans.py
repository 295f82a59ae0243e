"""Where a bake's probes go: one placement plan per mode, behind one small interface.

Part of the bake (bake_core.ProbeBake drives it). Every plan answers the same questions:

- :meth:`PlacementPlan.place` places the probes and returns the first render queue (indices into
  ``positions``); ``targets`` are the output files and their probes;
- :meth:`~PlacementPlan.measure` renders point ``i`` through the render session
  (bake_session.RenderSession) and keeps its value; :meth:`~PlacementPlan.store` keeps a value
  taken from the journal (bake_points.py) instead;
- :meth:`~PlacementPlan.advance` queues the next stage once a stage is rendered (Adaptive only:
  the others are ``finished`` from the start);
- :meth:`~PlacementPlan.outputs` are the files to write (bake_outputs.Output).

The plans: :class:`UniformPlan` (Placement "Octree": the geometry octree's grid, native.place_probes),
:class:`AdaptivePlan` (Placement "Adaptive": the error-driven corner octree, adaptive.py),
:class:`CursorPlan` (Bake SH at Cursor: one debug probe) and :class:`PointsPlan` (bake_points:
given positions, nothing written).
"""
from __future__ import annotations

import math
import os
import time
from dataclasses import dataclass
from typing import Callable, List, Optional

import bpy
import numpy as np

from . import adaptive, bakeinfo, direct_light, journal, native, postprocess, region, render_settings, scene_export
from .adaptive import DEFAULT_POLICY, Policy
from .bake_checks import BakeCancelled
from .bake_outputs import (DEBUG_SHPROBE_NAME, DEBUG_SUBDIR, DEBUG_TEXT_NAME, SKY_FILE_NAME, SUN_FILE_NAME,
                           Output, abspath, check_replaceable, debug_text, dense_output, is_single_probe_file,
                           octree_output)
from .estimate import (SECONDS_PER_PIXEL_SAMPLE, adaptive_points, forecast_seconds, format_duration,
                       grid_cell_bound)
from .settings import BakeError


@dataclass
class Target:
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
class Placing:
    """What placement may use: the scene, where to report, and how to notice a cancel."""
    scene: object
    view_layer: object
    log: Callable[[str], None]
    messages: list
    timings: dict
    progress: Callable[[float, str], bool]   # False: cancel (placement's progress callback)
    check_cancel: Callable[[], None]         # raises BakeCancelled


class PlacementPlan:
    """The interface, and the plans whose values are one (P, C, 3) array (``coeffs``)."""
    adaptive = False
    volumes = False          # a volume bake: journal, sky and sun beside the probe files
    renders_per_point = 1

    def __init__(self, settings):
        self.settings = settings
        self.positions = np.zeros((0, 3))   # unique probe positions, engine space
        self.coeffs = None                  # (P, sh_count, 3) float64, after allocate()
        self.targets: List[Target] = []
        self.samples_rendered = 0           # pixel samples per pixel, summed over every render

    def place(self, placing: Placing) -> List[int]:
        raise NotImplementedError

    @property
    def finished(self) -> bool:
        """Nothing more to queue (Adaptive: the refinement is done)."""
        return True

    @property
    def passes(self) -> list:
        return []

    def allocate(self):
        self.coeffs = np.zeros((len(self.positions), native.sh_count(self.settings.max_band), 3))

    def attach(self, session, direct):
        """The render session and the direct-light plan, once the render is set up."""

    def position(self, i: int) -> np.ndarray:
        return self.positions[i]

    def journal_flags(self, i: int) -> int:
        return 0

    def kept_value(self, i: int, store):
        """A region rebake's value for point ``i`` when its own journal key misses: (coeffs, noise) or
        None (AdaptivePlan)."""
        return None

    def store(self, i: int, coeffs, noise: float, kept: bool = False):
        """Keep a value taken from a journal (``kept``: an earlier bake's kept point, region.py)."""
        self.coeffs[i] = coeffs

    def measure(self, i: int, pos, session, direct):
        """Render point ``i`` at ``pos`` and keep its value: (value, noise)."""
        value = session.render(pos, i, direct)
        self.samples_rendered += self.settings.samples
        self.coeffs[i] = value
        return value, 0.0

    def advance(self) -> List[int]:
        return []

    def points_rendered(self, done: int) -> int:
        """Distinct points with a value after ``done`` queue entries (one each here)."""
        return done

    def finish_values(self, direct, timings: dict):
        """Before writing: the lamps' exact direct light added to every probe at once."""
        if direct is not None:
            direct.add_to(self.coeffs, self.positions, self.settings.max_band, timings)

    def probe_count(self, total: int) -> int:
        return total

    def outputs(self, scratch: str) -> List[Output]:
        # SH Windowing (postprocess.py); Dilate Invalid Probes needs the octree's cells: Adaptive only.
        return [dense_output(t, postprocess.window(self.coeffs[t.probe_render_index], self.settings.sh_window,
                                                   self.settings.sh_window_strength),
                             self.positions[t.probe_render_index], self.settings) for t in self.targets]

    def estimate_line(self, total: int, seconds: float) -> str:
        return (f"Schnee: {total} probe(s) to bake, estimated {format_duration(seconds)} "
                f"(at most; {SECONDS_PER_PIXEL_SAMPLE * 1e6:.1f} µs per pixel-sample, refined after the "
                "first probes)")

    def progress_line(self, done, total, pass_start, elapsed, eta) -> str:
        return f"Schnee bake: probe {done}/{total}, {elapsed:.1f} s elapsed, ~{eta:.0f} s left"

    def fraction(self, done, total, pass_start) -> float:
        return done / total if total else 1.0


class PointsPlan(PlacementPlan):
    """Given engine-space positions, nothing written (bake_core.bake_points)."""

    def __init__(self, settings, points):
        super().__init__(settings)
        self.points = points

    def place(self, placing):
        self.positions = np.asarray(self.points, dtype=np.float64).reshape(-1, 3)
        return list(range(len(self.positions)))

    def outputs(self, scratch):
        return []


class CursorPlan(PlacementPlan):
    """Bake SH at Cursor: one probe at ``cursor`` (Blender space), its file and debug_probe.txt."""

    def __init__(self, settings, cursor):
        super().__init__(settings)
        self.cursor = cursor
        self.debug_text_path = None

    def place(self, placing):
        s = self.settings
        main_path = abspath(s.output_path)
        folder = os.path.dirname(main_path)
        path = main_path
        if os.path.exists(main_path) and not is_single_probe_file(main_path):
            # Never destroy a full bake for a debug probe.
            path = os.path.join(folder, DEBUG_SUBDIR, DEBUG_SHPROBE_NAME)
            placing.messages.append(f"'{os.path.basename(main_path)}' holds a full bake; the debug probe "
                                    f"goes to '{path}'")
        self.debug_text_path = os.path.join(folder, DEBUG_TEXT_NAME)
        check_replaceable(path, "shprobe")
        check_replaceable(self.debug_text_path, "text")
        pos = scene_export.blender_to_engine(np.array([self.cursor]))[0]
        h = s.min_cell_size / 2
        self.positions = pos.reshape(1, 3)
        self.targets.append(Target(path, "debug_probe", np.zeros(1, dtype=np.int64),
                                   np.zeros(1, dtype=np.int32), (1, 1, 1),
                                   tuple(float(c - h) for c in pos), float(s.min_cell_size)))
        return list(range(len(self.positions)))

    def set_positions(self, positions):
        """Render these engine-space positions instead (ProbeBake.bake_positions)."""
        self.positions = np.asarray(positions, dtype=np.float64).reshape(-1, 3)
        self.allocate()

    def outputs(self, scratch):
        def write_text(tmp):
            with open(tmp, "w", encoding="utf-8") as fh:
                fh.write(debug_text(self.cursor, self.positions[0], self.coeffs[0], self.settings))
        return super().outputs(scratch) + [Output(self.debug_text_path, "text", write_text)]


class _VolumePlan(PlacementPlan):
    """Bake SH in Volumes: the volumes, the render geometry and the output files per volume.
    ``rebake`` (region.VolumeRebake, set by the driver): bake that volume alone, keeping the rest."""
    volumes = True
    rebake = None

    def _gather(self, placing: Placing):
        """(groups [(name, path, volumes)], geometry) after refusing what is not ours to replace."""
        s = self.settings
        main_path = abspath(s.output_path)
        objects = volume_objects(s.volume_collection)
        volumes, groups = volume_groups(objects, s, main_path)
        if self.rebake is not None:  # one volume; the sky, the sun and the other files are kept
            groups = self.rebake.select(groups, s, main_path, s.volume_collection)
            volumes = groups[0][2]
        # Refuse before any work is done to replace something that is not ours.
        for _, path, _ in groups:
            check_replaceable(path, "shprobe")
            check_replaceable(bakeinfo.path_for(path), "bakeinfo")
        if s.per_volume_files:
            check_replaceable(region.record_path(main_path), "record")
            check_replaceable(region.points_path(main_path), "journal")
        if s.capture_sky and self.rebake is None:
            check_replaceable(os.path.join(os.path.dirname(main_path), SKY_FILE_NAME), "exr")
        # Written (Sky Sun "mixed" and a sun) or removed (else: a stale sun would be added twice); a rebake
        # keeps it.
        if self.rebake is None:
            check_replaceable(os.path.join(os.path.dirname(main_path), SUN_FILE_NAME), "sun")
        exclude = frozenset(ob.name for ob in objects)
        # Solid geometry as Cycles renders it, not as the viewport shows it (render_settings.py).
        coll = bpy.data.collections.get(s.volume_collection)
        evaluation = render_settings.RenderEvaluation(placing.scene, placing.view_layer,
                                                      keep=exclude | {coll.name})
        with evaluation as render_depsgraph:
            geometry = scene_export.gather_geometry(render_depsgraph, exclude)
        if evaluation.skipped:
            placing.messages.append("Placement could not match the viewport to the render for "
                                    + ", ".join(evaluation.skipped) + " (read-only data)")
        if evaluation.failed:
            placing.log("Schnee: could not restore " + ", ".join(evaluation.failed))
        placing.log(f"Schnee: {len(volumes)} volume(s), {len(geometry)} geometry mesh(es), "
                    f"{sum(len(g[2]) for g in geometry)} triangles")
        bound = self.cells = grid_cell_bound(volumes, s.min_cell_size, s.per_volume_files)
        placing.log(f"Schnee: placing probes (at most {bound} = the grid cells of Min Cell Size "
                    f"{s.min_cell_size:g} m; Esc / Ctrl+C cancels)")
        return groups, geometry


class UniformPlan(_VolumePlan):
    """Placement "Octree": the probes of the geometry octree's grid (native.place_probes), one
    render each, positions shared between files rendered once."""

    def place(self, placing):
        s = self.settings
        groups, geometry = self._gather(placing)
        t = time.perf_counter()
        unique = {}
        positions = []
        for name, path, vols in groups:
            try:
                pl = native.place_probes(vols, geometry, s.min_cell_size, s.max_cell_size,
                                         progress=placing.progress)
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
            placing.log(f"Schnee: '{name}': {len(pl.positions)} probes ({pl.pruned_count} pruned inside "
                        f"solid geometry), grid {pl.grid_dims[0]}x{pl.grid_dims[1]}x{pl.grid_dims[2]}")
            if len(pl.positions) == 0:
                raise BakeError(f"No probe could be placed in '{name}': every candidate position is "
                                "inside solid geometry")
            validity = np.clip(1.0 - np.asarray(pl.backface_ratio, dtype=np.float32), 0.0, 1.0)
            self.targets.append(Target(path, name, index, np.asarray(pl.grid, dtype=np.int32),
                                       tuple(pl.grid_dims), tuple(pl.grid_origin), float(pl.grid_spacing),
                                       validity.astype(np.float32)))
        placing.timings["placement"] = time.perf_counter() - t
        self.positions = np.array(positions, dtype=np.float64).reshape(-1, 3)
        return list(range(len(self.positions)))


# The Adaptive bake logs its estimate in all at the end of the first pass with at least this many
# points rendered by this run (the room and the courtyard have rendered 14 points after their first
# pass, 28 after the second, 75 after the third: about 3 % of their points): the wall time per point
# of the first 14 still carries the sky's and the scene's one-off costs (the courtyard: 0.16 s per
# point after its first pass, 0.117 s over the whole bake).
FORECAST_MIN_POINTS = 40


class AdaptivePlan(_VolumePlan):
    """Placement "Adaptive": every output file's corner octree refined pass by pass where the light
    needs it (adaptive.AdaptiveGroup), its points shared in one adaptive.PointCache (``cache``),
    each rendered in rounds of independent seeds (two first rounds for its noise, then more only
    where its noise or its test's decision needs them). ``policy``: adaptive.Policy."""
    adaptive = True
    renders_per_point = 2

    def __init__(self, settings, policy: Policy = DEFAULT_POLICY):
        super().__init__(settings)
        self.policy = policy
        self.cache: Optional[adaptive.PointCache] = None
        self.groups: List[adaptive.AdaptiveGroup] = []
        self.lamps = RefinementLamps(settings)
        self.log = print
        self.cells = 0                  # grid_cell_bound of the volumes (the expected points' base)
        self.measured = 0               # points this run rendered (not taken from journals)
        self._t_start = None            # when placement began (the bake's clock, for the forecast)
        self._first_end = None          # when the first rendered point was done (after the scene upload)
        self.first_forecast = None      # (points, seconds in all) logged once FORECAST_MIN_POINTS are measured
        self.forecasts = []             # the forecast at the end of each pass (the benchmarks' record)
        self.known_points = 0           # points rendered or queued when the last stage was queued
        self.kept_values = 0            # region rebake: kept nodes that took the previous bake's value

    @property
    def positions(self):
        return self.cache.positions if self.cache is not None else np.zeros((0, 3))

    @positions.setter
    def positions(self, value):
        pass  # the cache's, set by place()

    @property
    def finished(self) -> bool:
        return all(g.finished for g in self.groups)

    @property
    def passes(self) -> list:
        return list(self.groups[0].passes) if self.groups else []

    def place(self, placing):
        """The first layer of every group's corner octree; its probes start the queue."""
        s = self.settings
        self.log = placing.log
        self._t_start = time.perf_counter()
        groups, geometry = self._gather(placing)
        t = time.perf_counter()
        self.cache = adaptive.PointCache(s.max_band, self.policy, s.samples)
        todo_all = []
        for name, path, vols in groups:
            placing.check_cancel()
            try:
                group = adaptive.AdaptiveGroup(name, path, vols, geometry, s.min_cell_size, s.max_cell_size,
                                               s.error_tolerance, s.refinement_tests, direct=self.lamps.check_at,
                                               engine_direct=self.lamps.engine_at, policy=self.policy)
                if self.rebake is not None:  # a region: the previous tree outside it (region.KeptTree)
                    group.kept = self.rebake.kept_tree(group)
                todo = group.start(self.cache)
            except native.SchneeError as exc:
                raise BakeError(f"Probe placement failed: {exc}") from exc
            self.groups.append(group)
            todo_all += todo
            rec = group.passes[0]
            placing.log(f"Schnee: '{name}': Adaptive placement, lattice {s.min_cell_size:g} m, first layer "
                        f"{rec.leaves} cell(s) of {rec.smallest_cell:g} m with {rec.probes} probes "
                        f"({rec.probes - len(todo)} inside solid geometry or shared)")
            self.targets.append(Target(path, name, np.zeros(0, dtype=np.int64), np.zeros(0, dtype=np.int32),
                                       (0, 0, 0), (0.0, 0.0, 0.0), float(s.min_cell_size), None, group))
        placing.timings["placement"] = time.perf_counter() - t
        return todo_all

    def allocate(self):
        pass  # the values live in the cache

    def attach(self, session, direct):
        self.lamps.attach(session, direct)

    def stage_count(self) -> int:
        return max(g.stage_count() for g in self.groups)

    def position(self, i):
        return self.cache.positions[i]

    def journal_flags(self, i):
        # The round the point's next record holds: 0 for its two first rounds (one record: their
        # mean and σ), then the round's index (2, 3, ...: its own value; the record's noise field
        # holds the round's samples).
        return int(self.cache.rounds[i])

    def kept_value(self, i, store):
        """Region rebake (region.KeptTree): (coeffs, noise) for entry ``i``'s first rounds when ``i`` is
        a probe at a node whose record the rebake keeps and ``store`` lacks its own key, else None.
        Such a node's record is the previous file's in the end, so a render there would be overwritten:
        it only feeds the decisions of the leaves around it that meet the region, which take what the
        previous bake had there: its point rendered beside the node (KeptTree.stand_in). The previous
        bake rendered the node elsewhere when another volume's group asked for it first (a node on a
        face two volumes share renders Policy.render_inset inside the volume that asked)."""
        if self.rebake is None or self.rebake.first_points is None or self.cache.rounds[i] != 0:
            return None
        for g in self.groups:
            j = np.flatnonzero(np.asarray(g.probe_index) == i)[:1] if g.kept is not None else []
            if len(j) == 0:
                continue
            lattice = g.tree.probe_lattice()[j]
            if g.kept.previous_rows(lattice)[0] < 0:
                continue
            p = g.kept.stand_in(g.lattice_positions(lattice)[0], self.rebake.first_points, g.stand_in_radius())
            key = None if p is None else journal.key_of(p, 0)
            value = store.lookup(key) if key is not None and store.seeded(key) else None
            self.kept_values += value is not None
            return value
        return None

    def store(self, i, coeffs, noise, kept=False):
        # A later round holds its samples in the noise field. A kept round (region.py) is replayed
        # with the samples it had, so a point outside a rebake's region keeps its previous mean.
        cache = self.cache
        if cache.rounds[i] == 0:
            cache.set_first(i, coeffs, noise)
        elif int(noise) != int(cache.pending[i]) and not kept:
            raise BakeError(f"The bake journal's round {int(cache.rounds[i])} of the point at "
                            f"{tuple(np.round(cache.positions[i], 3))} has {noise:g} samples, this bake "
                            f"wants {int(cache.pending[i])}: bake with --restart")
        else:
            cache.add(i, coeffs, int(noise))

    def measure(self, i, pos, session, direct):
        # A new point: two rounds of the first round's samples with seeds Seed and Seed + 1, their
        # difference measures this point's Monte-Carlo noise (which the refinement must not mistake
        # for light changing). Later rounds (seed Seed + round) add the samples its noise or its
        # test's decision needs; the point's value is the sample-weighted mean of all of them.
        s, cache = self.settings, self.cache
        k = int(cache.rounds[i])
        if k == 0:
            a = self._render(cache.first, s.seed, i, pos, session, direct)
            b = self._render(cache.first, s.seed + 1, i, pos, session, direct)
            mean, noise = adaptive.combine_halves(a, b, cache.first, cache.first)
            cache.set_first(i, mean, noise)
            value, noise = mean, float(noise)
            self.measured += 1
            if self._first_end is None:
                self._first_end = time.perf_counter()
        else:
            n = int(cache.pending[i])
            value = self._render(n, s.seed + k, i, pos, session, direct)
            cache.add(i, value, n)
            noise = float(n)
        session.set_samples(s.samples, s.seed, tag=False)
        return value, noise

    def _render(self, samples, seed, i, pos, session, direct):
        session.set_samples(samples, seed)
        self.samples_rendered += samples
        c = session.render(pos, i, direct)
        if direct is not None and direct.lamps:
            # Issue 11: the lamps' direct light is exact (no noise), so it goes into every round
            # before the noise estimate, and into every point before the refinement decides
            # (a sun's shadow edge must draw refinement like any other change of the light).
            t_d = time.perf_counter()
            c = c + direct.project(np.asarray(pos)[None, :], self.settings.max_band)[0]
            session.timings["direct"] = session.timings.get("direct", 0.0) + time.perf_counter() - t_d
        return c

    def points_rendered(self, done):
        return int(self.cache.rendered.sum()) if self.cache is not None else done

    def forecast(self):
        """(expected points, seconds in all) of the bake, None before two points are rendered: the
        expected points (estimate.adaptive_points of the grid bound, or the points known so far if
        more: rendered and queued) at the wall time per point this run measured after its first
        point (which also paid the scene's upload)."""
        if self.measured < 2 or self._first_end is None:
            return None
        rendered = self.points_rendered(0)
        expected = max(adaptive_points(self.cells, self.settings.error_tolerance), self.known_points, rendered)
        return expected, forecast_seconds(time.perf_counter() - self._t_start, rendered, expected,
                                          self._seconds_per_point())

    def advance(self) -> List[int]:
        """Every queued point is rendered: move each group on (tests -> decision -> split -> new
        probes); returns the points queued."""
        todo = []
        log = self.log
        for g in self.groups:
            if g.finished:
                continue
            before = len(g.passes)
            try:
                todo += g.advance(self.cache)
            except native.SchneeError as exc:
                raise BakeError(f"Refinement of '{g.name}' failed: {exc}") from exc
            if len(g.passes) > before:
                prev, rec = g.passes[-2], g.passes[-1]
                extra = "".join([f", {prev.kept} kept from the previous bake" if prev.kept else "",
                                 f", {prev.predicted} predicted to pass" if prev.predicted else "",
                                 f", {prev.rounds} given more samples" if prev.rounds else "",
                                 f", {prev.probe_rounds} probes given more samples" if prev.probe_rounds else "",
                                 f", {prev.direct_split} split by the lamps' direct light"
                                 if prev.direct_split else ""])
                log(f"Schnee: '{g.name}': pass {prev.pass_index}: {prev.split} of {prev.leaves} "
                    f"cell(s) split ({prev.tests} test points{extra}); pass {rec.pass_index}: "
                    f"{rec.leaves} cells down to {rec.smallest_cell:g} m, {rec.probes} probes")
            elif g.finished:
                rec = g.passes[-1]
                log(f"Schnee: '{g.name}': refinement done after {rec.pass_index} pass(es): "
                    f"{rec.leaves} cells, {rec.probes} probes")
        self.known_points = self.points_rendered(0) + sum(1 for i in todo if self.cache.rounds[i] == 0)
        fc = None if self.finished else self.forecast()
        done_passes = len(self.passes) - 1  # pass records begin with the pass under way
        if fc is not None and done_passes and (not self.forecasts or self.forecasts[-1]["pass"] < done_passes):
            self.forecasts.append({"pass": done_passes, "points_rendered": self.points_rendered(0),
                                   "elapsed": round(time.perf_counter() - self._t_start, 2),
                                   "points": round(fc[0], 1), "seconds": round(fc[1], 1)})
        if self.first_forecast is None and fc is not None and self.measured >= FORECAST_MIN_POINTS:
            self.first_forecast = fc
            points, seconds = fc
            log(f"Schnee: estimated {format_duration(seconds)} in all (about {points:.0f} points: "
                f"{adaptive_points(1, self.settings.error_tolerance):.2f} per cell of Min Cell Size, "
                f"at this scene's {self._seconds_per_point():.2f} s per point so far; "
                "the progress line refines it)")
        return todo

    def _seconds_per_point(self):
        """The mean wall time per point this run rendered, after its first (the scene's upload)."""
        return (time.perf_counter() - self._first_end) / max(1, self.measured - 1)

    def finish_values(self, direct, timings):
        pass  # Adaptive adds the lamps' direct light per point, before deciding

    def probe_count(self, total):
        # The probes in the files (shared positions once), not the tests.
        return len(np.unique(np.concatenate([g.probe_index for g in self.groups])))

    def outputs(self, scratch):
        if self.kept_values:
            self.log(f"Schnee: {self.kept_values} kept probe(s) outside the region took the previous bake's point "
                     "beside them instead of a render (the file keeps their previous records)")
        out = []
        for t in self.targets:
            coeffs, validity = t.group.probe_values(self.cache)
            coeffs, validity = postprocess.apply(coeffs, validity, t.group.tree, self.settings, log=self.log)
            kept = t.group.kept   # a region rebake: the previous records outside the region, bit for bit
            rows = None if kept is None else kept.previous_rows(t.group.tree.probe_lattice())
            shprobe = octree_output(t, coeffs, validity, self.settings, os.path.join(scratch, "octree.shprobe"),
                                    None if kept is None else kept.records(rows))
            if self.settings.file_version == "V3":  # File Version 1 resamples: no probe or leaf of the tree
                arrays = bakeinfo.adaptive_arrays(t.group, self.cache, self.settings)
                if kept is not None:
                    kept.patch_sidecar(arrays, t.group, rows)
                out += bakeinfo.with_sidecar(shprobe, arrays, Output, self.log)
            else:
                out.append(shprobe)
        return out

    def estimate_line(self, total, seconds):
        return (f"Schnee: pass 1: {total} probe(s) of Max Cell Size to bake, estimated "
                f"{format_duration(seconds)} (at most; then test points and finer "
                f"cells only where the light needs them, at most {self.stage_count()} stages)")

    def progress_line(self, done, total, pass_start, elapsed, eta):
        g = max(self.groups, key=lambda g: g.stage_index())
        rec = g.passes[-1]
        points = self.points_rendered(done)
        what = {"tests": "test points", "rounds": "unclear tests", "last": "more rounds"}.get(g.stage, "probes")
        if self.finished:
            what = "done"
        fc = None if self.finished else self.forecast()
        in_all = "" if fc is None else f", ~{format_duration(max(0.0, fc[1] - elapsed))} left in all"
        return (f"Schnee bake: pass {rec.pass_index} ({what}, cells down to {rec.smallest_cell:g} m): "
                f"{done - pass_start}/{total - pass_start}, {points} points rendered (+{done - points} "
                f"more rounds), {elapsed:.1f} s elapsed, ~{eta:.0f} s left in this pass{in_all}")

    def fraction(self, done, total, pass_start):
        """By stages (each stage's share of the most stages the refinement can take), as the number
        of points of later stages is not known yet."""
        if self.finished:
            return 1.0
        g = max(self.groups, key=lambda g: g.stage_index())
        n = total - pass_start
        within = (done - pass_start) / n if n else 1.0
        return min(1.0, (g.stage_index() + within) / g.stage_count())


class RefinementLamps:
    """The exact direct light the refinement judges besides the renders (adaptive.AdaptiveGroup's
    ``direct`` and ``engine_direct``), from the direct-light plan once the render is set up."""

    def __init__(self, settings):
        self.settings = settings
        self.session = None
        self.direct = None
        self._sky_sun = None     # [the world image's sun as a Sun lamp] or [] (check_lamps)

    def attach(self, session, direct):
        self.session, self.direct = session, direct

    def check_lamps(self) -> list:
        """The lamps of the refinement's direct-light check: the lamps added analytically, and with
        Sky Sun "baked" a Sun standing in for a sun in the world image (adaptive.sky_sun; only where
        the shadow geometry was gathered, i.e. with Lamps Seen by Probes, and the world is an image
        read as it is). With "mixed" the world's sun is not in the probes: it is one of the engine's
        lamps (engine_lamps), like a mixed Sun lamp."""
        if self._sky_sun is None:
            self._sky_sun = []
            d = self.direct
            if d is not None and d.geometry and self.settings.sky_sun == "baked":
                src = direct_light.world_image(self.session.scene.world)
                sun = None if src is None else adaptive.sky_sun(np.clip(src[0][:, :, :3] * src[1], 0.0, None))
                if sun is not None:
                    self._sky_sun = [sun]
                    deg = math.degrees(sun.radius)
                    self.session.log(f"Schnee: the world's sun ({deg:.2g}° wide) is checked like a lamp where the "
                             "probes' light is interpolated")
        return (list(self.direct.lamps) if self.direct is not None else []) + self._sky_sun

    def engine_lamps(self) -> list:
        """The lights whose direct part the engine adds and the probes leave out: the mixed lamps,
        and with Sky Sun "mixed" the world's sun split off (direct_light.DirectLightPlan.sun_lamp;
        only with Lamps Seen by Probes, when the shadow geometry is gathered, as for mixed lamps)."""
        d = self.direct
        if d is None:
            return []
        lamps = list(d.mixed_lamps)
        if self.settings.sky_sun == "mixed" and self.settings.lights_visible:
            sun = d.sun_lamp(self.session)
            if sun is not None:
                lamps.append(sun)
        return lamps

    def check_at(self, positions: np.ndarray) -> Optional[np.ndarray]:
        """The check lamps' exact direct light (radiance SH) at engine-space positions, or None when
        there is none: the refinement's direct-light check."""
        return self._project(positions, self.check_lamps())

    def engine_at(self, positions: np.ndarray) -> Optional[np.ndarray]:
        """The engine lamps' exact direct light at engine-space positions, or None without such
        lamps: the refinement judges the probes' error against the light a moving object gets,
        probe + this (adaptive.AdaptiveGroup.seen)."""
        return self._project(positions, self.engine_lamps())

    def _project(self, positions, lamps) -> Optional[np.ndarray]:
        if not lamps:
            return None
        t = time.perf_counter()
        out = self.direct.project(np.asarray(positions, dtype=np.float64).reshape(-1, 3), self.settings.max_band,
                                  lamps)
        timings = self.session.timings
        timings["direct"] = timings.get("direct", 0.0) + time.perf_counter() - t
        return out


def volume_groups(objects, s, main_path: str):
    """(volumes, groups [(name, path, volumes)]) of the volume ``objects``: one group per volume with
    One File per Volume (``s.per_volume_files``), else one for all; BakeError for a volume without
    faces or two volumes written to one file."""
    depsgraph = bpy.context.evaluated_depsgraph_get()
    volumes = [scene_export.volume_mesh(ob, depsgraph) for ob in objects]
    for name, _, tris in volumes:
        if len(tris) == 0:
            raise BakeError(f"Probe volume '{name}' has no faces: a volume must be a closed mesh")
    if not s.per_volume_files:
        return volumes, [(os.path.splitext(os.path.basename(main_path))[0], main_path, volumes)]
    groups, seen = [], {}
    for vol in volumes:
        stem = region.volume_file_stem(vol[0])
        if stem in seen:
            raise BakeError(f"Volumes '{seen[stem]}' and '{vol[0]}' would both be written to "
                            f"'{stem}.shprobe': rename one of them")
        seen[stem] = vol[0]
        groups.append((vol[0], region.volume_file(main_path, vol[0]), [vol]))
    return volumes, groups


def check_rebake(rebake: "region.VolumeRebake", s, main_path: str) -> None:
    """The checks a rebake of ``rebake.name`` makes before it places anything (region.py), made
    where nothing is baked: bake.py --farm, before it submits jobs that would each refuse."""
    rebake.check_settings(s)
    _, groups = volume_groups(volume_objects(s.volume_collection), s, main_path)
    rebake.select(groups, s, main_path, s.volume_collection)


def volume_objects(name: str) -> list:
    """The objects of the probe volume collection ``name``; BakeError unless it exists and holds
    only meshes."""
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
