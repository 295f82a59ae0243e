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

:class:`ProbeBake` is a driver over parts, each in its own module and owning its state (the
layout of glTF-Blender-IO's exporter: one driver, a module per concern):

- ``bake_plans.py``: where the probes go, one placement plan per mode (uniform, adaptive, cursor,
  points) behind one interface (``bake.plan``);
- ``bake_session.py``: the render session: the scene state guard, the probe camera, the temporary
  folder and one ``render(point)`` (``bake.session``); direct light (``direct_light.py``) and the
  sky capture (``bake_sky.py``) work on it, not on the bake;
- ``bake_points.py``: the point store: the journal, the shard filter and the merge of shards;
- ``bake_outputs.py``: which files may be replaced, and the atomic multi-file write;
- ``bake_checks.py``: what the bake refuses before it changes anything, and its errors.

Nothing is written to the output folder before :meth:`ProbeBake.finish`; a failed or cancelled bake
leaves existing ``.shprobe`` files untouched. Every scene setting the bake changes goes through one
:class:`render_settings.StateGuard` and is restored by ``finish`` and ``cancel``.

Before any work :meth:`ProbeBake.prepare` refuses outputs that are not ours
(:func:`check_replaceable`: the open .blend, a file that is not a .shprobe by content, anything
not a regular file) and NaN/Inf emission (:func:`check_finite_emission`); after placement it logs
the probe count with an estimate (estimate.py) and refuses more than ``settings.probe_limit``
probes unless ``allow_large``. :meth:`ProbeBake.request_cancel` (Esc, or a signal through
:class:`CancelOnSignals`) stops the bake at the next check point: placement's progress, each
probe, before the sky and before writing. The names scripts import from here (constants, checks,
errors) are re-exported from the parts.
"""
from __future__ import annotations

import os
import signal
import time
from dataclasses import dataclass, field
from typing import List, Optional, Sequence, Tuple

import bpy
import numpy as np

from . import bake_sky, direct_light, fingerprint, journal, native, render_settings
from . import region as rebake_region
from .adaptive import DEFAULT_POLICY, Policy
# The parts, and the names scripts import from bake_core (re-exported).
from .bake_checks import (BakeCancelled, BakeTooLarge, check_finite_emission, check_panorama_size,  # noqa: F401
                          check_light_modes, check_shading)
from .bake_outputs import (DEBUG_SHPROBE_NAME, DEBUG_SUBDIR, DEBUG_TEXT_FIRST_LINE,  # noqa: F401
                           DEBUG_TEXT_NAME, EXR_MAGIC, HALF_MAX, SHPROBE_MAGIC, SKY_FILE_NAME,
                           SUN_FILE_NAME, SUN_FORMAT, SUN_MAGIC, abspath, check_half_range, check_replaceable,
                           debug_text, remove_quietly, write_all)
from .bake_plans import (AdaptivePlan, CursorPlan, Placing, PlacementPlan, PointsPlan,  # noqa: F401
                         Target, UniformPlan)
from .bake_points import JOURNAL_SUFFIX, PointStore, check_shards, journal_path_for, shard_journal_path  # noqa: F401
from .bake_session import TMP_PREFIX, RenderSession, clean_stale_temp_dirs  # noqa: F401
# The settings are declared in settings.py; re-exported here for scripts that use bake_core.*.
from .settings import DEFAULT_OUTPUT, PIXEL_FILTERS, BakeError, BakeSettings  # noqa: F401
from .estimate import (SECONDS_PER_PIXEL_SAMPLE, device_note, estimate_seconds, format_duration,  # noqa: F401
                       grid_cell_bound)

_abspath = abspath   # the former private name, for scripts written before the split
_Target = Target


@dataclass
class BakeResult:
    """What a finished bake produced."""
    files: List[str]
    probe_count: int            # probes rendered (unique positions)
    seconds: float
    timings: dict = field(default_factory=dict)  # stage -> seconds summed over probes
    messages: List[str] = field(default_factory=list)
    renders: int = 0            # queue entries done (Adaptive: a point's first two rounds, or one more round)
    samples: int = 0            # samples per pixel summed over every Cycles render of this run
    points: int = 0             # distinct points with a value (Adaptive: probes and test points; else renders)
    passes: list = field(default_factory=list)  # Adaptive: adaptive.PassRecord per pass (first group)
    rendered: int = 0           # queue entries this run rendered (not taken from journals or kept points)
    resumed: int = 0            # queue entries taken from journals or (region.py) kept points


class ProbeBake:
    """One bake run. ``mode`` is "VOLUMES" (Bake SH in Volumes), "CURSOR" (Bake SH at Cursor,
    ``cursor`` = Blender-space position) or "POINTS" (``points``, engine space, nothing written).
    ``log`` receives human-readable lines. ``shard`` = (k, n) / ``merge_shards`` = n: farm bakes
    (bake_points.py); ``policy``: the Adaptive refinement's adaptive.Policy; ``only_volume`` / ``region``:
    a rebake of one volume / of a Blender-space box in it (region.py). The parts are public:
    ``plan`` (Adaptive: ``plan.cache``, ``plan.groups``), ``session``, ``store``, ``direct``."""

    def __init__(self, scene, view_layer, settings: BakeSettings, mode: str = "VOLUMES",
                 cursor: Optional[Sequence[float]] = None, log=print, allow_large=False, points=None,
                 shard: Optional[Tuple[int, int]] = None, merge_shards: Optional[int] = None,
                 restart: bool = False, policy: Policy = DEFAULT_POLICY, only_volume: Optional[str] = None,
                 region: Optional[Sequence[float]] = None):
        if mode not in ("VOLUMES", "CURSOR", "POINTS"):
            raise ValueError(f"unknown bake mode {mode!r}")
        if mode == "CURSOR" and cursor is None:
            raise ValueError("a cursor bake needs a cursor position")
        self.scene = scene
        self.view_layer = view_layer
        self.settings = settings
        self.mode = mode
        self.cursor = None if cursor is None else tuple(float(c) for c in cursor)
        self.log = log
        self.allow_large = allow_large      # bake above settings.probe_limit without asking
        self.shard = check_shards(shard, merge_shards)
        self.merge_shards = merge_shards
        self.restart = restart
        if mode == "CURSOR":
            self.plan: PlacementPlan = CursorPlan(settings, self.cursor)
        elif mode == "POINTS":
            self.plan = PointsPlan(settings, points)
        elif settings.placement == "ADAPTIVE":
            self.plan = AdaptivePlan(settings, policy)
        else:
            self.plan = UniformPlan(settings)
        # Region rebake (region.py): one volume's file, its journal beside it, no sky.
        self.rebake = (rebake_region.VolumeRebake(only_volume, region)
                       if only_volume is not None and mode == "VOLUMES" else None)
        self.plan.rebake = self.rebake
        self._writes_sky = self.plan.volumes and self.rebake is None  # sky.exr, sun.json: not a rebake's
        self._scene_parts = None            # the fingerprint's parts, for the bake record
        self._manifest = None               # the journal's manifest, for the kept points
        self.timings = {"placement": 0.0, "render": 0.0, "write_exr": 0.0, "project": 0.0}
        self.messages: List[str] = []
        self.session = RenderSession(scene, view_layer, settings, self.timings, log)
        self.store: Optional[PointStore] = None   # volume bakes: the journal (bake_points.py)
        self.direct = None                  # direct_light.DirectLightPlan, once the render is set up
        self.estimated_seconds = None       # the cost model's estimate, set after placement
        self.done = 0
        self.resumed = 0                    # points taken from journals instead of rendered
        self.rendered = 0                   # points rendered by this run
        self.shard_waiting = False          # a shard whose stage needs the other shards' points
        self.first_probe_seconds = None     # the first rendered point's time (the scene's upload)
        # The render queue: indices into the plan's positions, rendered in order. Adaptive
        # placement appends to it stage by stage; the other plans fill it once in prepare().
        self._todo: List[int] = []
        self._pass_start = 0                # self.done when the current stage began
        self._missing = 0                   # points of the current stage left to other shards
        self._sky_exr = None                # rendered sky (temporary folder) until finish()
        self._t0 = None
        self._closed = False
        self._cancel_requested = False

    @property
    def adaptive(self) -> bool:
        return self.plan.adaptive

    @property
    def renders_per_point(self) -> int:
        """Renders of one point's first request: two first rounds for the Adaptive noise estimate, else one."""
        return self.plan.renders_per_point

    positions = property(lambda self: self.plan.positions, doc="The unique render positions (engine space).")
    targets = property(lambda self: self.plan.targets, doc="The output files and their probes (bake_plans.Target).")
    coeffs = property(lambda self: self.plan.coeffs,
                      doc="(P, sh_count, 3) radiance SH per position; None for Adaptive (see plan.cache).")

    @property
    def journal_path(self) -> Optional[str]:
        return None if self.store is None else self.store.path

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

    @property
    def total(self) -> int:
        """Points to render so far (Adaptive: grows pass by pass until the refinement ends)."""
        return len(self._todo)

    # ------------------------------------------------------------------ prepare
    def prepare(self, placement_progress=None):
        """Validate the input, place the probes and set up rendering. Raises :class:`BakeError`."""
        self._t0 = time.perf_counter()
        # Before anything else: without the Cycles add-on nothing can be rendered (and scene.cycles
        # does not exist), so refuse with what to do instead of failing after placement.
        render_settings.require_cycles(self.scene)
        s = self.settings
        s.validate()
        realtime, mixed = check_light_modes(self.scene, self.messages)
        check_shading(self.scene)
        check_panorama_size(s)
        if self.rebake is not None:
            self.rebake.check_settings(s)
        if self.plan.volumes:  # before placement: a second bake of this output refuses (output_lock.py)
            output = abspath(s.output_path)
            self.store = PointStore.locked(output if self.rebake is None else self.rebake.output(output), self.shard,
                                           self.merge_shards, self.restart, self.log, self.messages)

        def progress(fraction, stage):
            if placement_progress is not None and placement_progress(fraction, stage) is False:
                return False
            return not self._cancel_requested
        self._todo = self.plan.place(Placing(self.scene, self.view_layer, self.log, self.messages, self.timings,
                                             progress, self._check_cancel))
        if self.total == 0:
            raise BakeError("No probe could be placed: every candidate position is inside solid "
                            "geometry. Check the probe volumes or use a smaller Min Cell Size.")
        self._check_cancel()
        self.estimated_seconds = estimate_seconds(self.total, s, sky=self._writes_sky,
                                                  renders=self.renders_per_point)
        self.log(f"{self.plan.estimate_line(self.total, self.estimated_seconds)}, {device_note(self.session.device)}")
        if s.probe_limit and self.total > s.probe_limit and not self.allow_large:
            raise BakeTooLarge(self.total, self.estimated_seconds, s.probe_limit)
        self.plan.allocate()
        if self.plan.volumes:
            self._open_store()  # before the render set-up: the fingerprint is of the user's settings
        self.session.apply_settings(hidden=realtime)
        # --- issue 11 hook: lamps added analytically are hidden from camera rays (direct_light.py).
        self.direct = direct_light.prepare(self.session, realtime, mixed)
        self.messages.extend(self.direct.messages)
        self.session.open_camera()
        self.plan.attach(self.session, self.direct)

    def _open_store(self):
        self._scene_parts = fingerprint.parts(self.scene, self.view_layer, self.settings)
        manifest = journal.make_manifest(self._scene_parts, scene=self.scene.name, blend=bpy.data.filepath)
        self._manifest = manifest
        self.store.open(manifest, native.sh_count(self.settings.max_band))
        if self.rebake is not None:  # after the journal's own points, which win
            self.rebake.open(self.store, abspath(self.settings.output_path), manifest, self.messages, self.log)
        self.store.log_resume([journal.key_of(self.positions[i]) for i in self._todo], self.adaptive)

    def bake_positions(self, positions):
        """After :meth:`prepare` of a cursor bake: render these engine-space positions instead (the
        benchmarks' references at arbitrary points, with the bake's own render settings and camera)."""
        if self.mode != "CURSOR":
            raise BakeError("bake_positions() is for cursor bakes")
        self.plan.set_positions(positions)
        self._todo = list(range(len(self.positions)))
        self.done = 0

    # ------------------------------------------------------------------ steps
    def step(self) -> bool:
        """Render and project the next point (points the journals hold are taken from them, and a
        shard passes over the other shards' points). Returns True while points remain (Adaptive
        placement: when the last point of a stage is done, the refinement decides the next stage
        here; a shard whose stage needs points of other shards stops there: ``shard_waiting``)."""
        if self.shard_waiting or self.done >= self.total:
            return False
        self._check_cancel()
        store = self.store
        while self.done < self.total:
            i = self._todo[self.done]
            pos = self.plan.position(i)
            key = journal.key_of(pos, self.plan.journal_flags(i)) if store is not None else None
            hit = store.lookup(key) if key is not None else None
            if hit is None and store is not None:  # a region rebake's kept node (AdaptivePlan.kept_value)
                hit = self.plan.kept_value(i, store)
            rendered = False
            if hit is not None:  # a kept point of an earlier bake (region.py) is replayed as it was
                self.plan.store(i, *hit, kept=store.seeded(key))
                self.resumed += 1
            elif store is not None and store.others(self.done - self._pass_start):
                self._missing += 1  # another shard's point
            elif store is not None and store.merging:
                raise store.not_merged(pos)
            else:
                t0 = time.perf_counter()
                value, noise = self.plan.measure(i, pos, self.session, self.direct)
                if store is not None:
                    store.append(key, value, noise)
                if self.rendered == 0:
                    self.first_probe_seconds = time.perf_counter() - t0
                self.rendered += 1
                rendered = True
            self.done += 1
            if self.adaptive and self.done == self.total:
                if self._missing:
                    self.shard_waiting = True
                    self.log(f"Schnee: shard {self.shard[0]}/{self.shard[1]}: its share of this pass is baked; "
                             "the next pass needs the other shards' points (the farm's next job continues)")
                    return False
                self._advance()
            if rendered:
                break
        return self.done < self.total

    def _advance(self):
        """Every queued point is rendered: the plan queues the next stage until something is queued
        or the refinement has finished."""
        while self.done == len(self._todo) and not self.plan.finished:
            self._check_cancel()
            self._todo += self.plan.advance()
        self._pass_start = self.done

    def remaining_seconds(self) -> float:
        """Time left: the cost model before the first probe, then the measured mean per probe
        (without the first probe's scene upload once a second one is done)."""
        left = self.total - self.done
        if self.rendered == 0:
            return estimate_seconds(left, self.settings, sky=self._writes_sky, renders=self.renders_per_point)
        spent = self.timings["render"] + self.timings["write_exr"] + self.timings["project"]
        if self.rendered >= 2 and self.first_probe_seconds is not None:
            per = (spent - self.first_probe_seconds) / (self.rendered - 1)
        else:
            per = spent / self.rendered
        return per * left

    def progress_line(self) -> str:
        elapsed = time.perf_counter() - (self._t0 or time.perf_counter())
        line = self.plan.progress_line(self.done, self.total, self._pass_start, elapsed, self.remaining_seconds())
        return f"{line}, on {self.session.device}"

    def fraction(self) -> float:
        """Progress in [0, 1] for a progress bar (Adaptive: by stages, bake_plans.AdaptivePlan)."""
        return self.plan.fraction(self.done, self.total, self._pass_start)

    def capture_sky(self):
        """Render the world alone as sky.exr into the temporary folder (bake_sky.capture_sky)."""
        self._sky_exr = bake_sky.capture_sky(self.session, self.direct)

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
                if self.done < self.total or not self.plan.finished:
                    raise BakeError(f"finish() after {self.done} of {self.total} probes")
                self._check_cancel()
                if self._writes_sky and self.settings.capture_sky and self._sky_exr is None:
                    self.capture_sky()
                self.plan.finish_values(self.direct, self.timings)
                self._check_cancel()
                files = write_outputs(self)
                if self.store is not None:  # the output is complete: the local journal is spent
                    self.store.close()
                    remove_quietly(self.store.path)
        finally:
            self._close()
        probes = self.total if self.shard is not None else self.plan.probe_count(self.total)
        return BakeResult(files=files, probe_count=probes, seconds=time.perf_counter() - self._t0,
                          timings=dict(self.timings), messages=list(self.messages), renders=self.done,
                          passes=self.plan.passes, samples=self.plan.samples_rendered,
                          points=self.plan.points_rendered(self.done), rendered=self.rendered, resumed=self.resumed)

    def cancel(self):
        """Abandon the bake: restore the scene and remove temporary files; write no output. The
        points already baked stay in the journal, and the same bake run again resumes from them."""
        self._close()

    def _close(self):
        if self._closed:
            return
        self._closed = True
        try:
            self.session.close()
        finally:
            if self.store is not None:  # unlocked last: the journal and the output as this bake leaves them
                self.store.close(unlock=True)

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


def kept_message(bake: ProbeBake) -> str:
    """What a cancelled or failed bake kept in its journal, for the user ('' when nothing)."""
    kept = 0 if bake.store is None else bake.store.kept
    if bake.journal_path is None or kept <= 0:
        return ""
    what = f"{kept} of {bake.total} probes" if not bake.adaptive else f"{kept} baked point(s)"
    return f"{what} kept in {bake.journal_path}; the same bake run again resumes from them"


def write_outputs(bake: ProbeBake) -> List[str]:
    """A finished bake's files (bake_outputs.write_all, all or none): the plan's, for a volume bake the sky
    and the sun (not a rebake's, which keeps them with the other volumes), and with One File per Volume the
    kept points and the bake record last, after the files they describe (region.py)."""
    s = bake.settings
    outputs, stale = bake.plan.outputs(bake.session.tmpdir), None
    if not bake.plan.volumes:  # a cursor or points bake: its own files only (no output folder needed)
        return write_all(outputs, stale, bake.log)
    main = abspath(s.output_path)
    if bake._writes_sky:
        more, stale = bake_sky.outputs(bake.session, bake.direct, bake._sky_exr, os.path.dirname(main))
        outputs += more
    if s.per_volume_files:
        outputs.append(rebake_region.points_output(main, bake._manifest, native.sh_count(s.max_band), bake.store))
        outputs.append(rebake_region.record_output(main, s, bake._scene_parts, [t.name for t in bake.plan.targets],
                                                   None if bake.rebake is None else bake.rebake.record))
    return write_all(outputs, stale, bake.log)


def bake_points(scene, view_layer, settings, points, log=print) -> np.ndarray:
    """Radiance SH (N, sh_count, 3) baked at engine-space ``points`` (N, 3) with ``settings``'
    render quality, one panorama each, writing nothing: the reference of tests and benchmarks (the
    light a probe at exactly that point would hold). The scene is restored as after any bake."""
    bake = ProbeBake(scene, view_layer, settings, mode="POINTS", points=points, log=log)
    bake.run()
    return np.array(bake.coeffs)


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
