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
leaves existing ``.shprobe`` files untouched. Every scene setting the bake changes is captured first
(:class:`render_settings.SceneState`) and restored by ``finish`` and ``cancel``.
"""
from __future__ import annotations

import dataclasses
import math
import os
import re
import shutil
import tempfile
import time
from dataclasses import dataclass, field
from typing import List, Optional, Sequence

import bpy
import numpy as np

from . import compat, direct_light, light_modes, native, render_settings, scene_export

DEFAULT_OUTPUT = "//sh_coeffs/probes.shprobe"
# The world (sky) alone, captured by a volume bake next to the probe files; the glTF exporter
# copies it and lists it as VULKAN_SCHNEE_engine_properties.sky (docs/export.md).
SKY_FILE_NAME = "sky.exr"
DEBUG_TEXT_NAME = "debug_probe.txt"
# Where Bake SH at Cursor puts its single-probe file when probes.shprobe holds a full bake:
# a subfolder, so the glTF exporter (which scans sh_coeffs/*.shprobe) never exports it.
DEBUG_SUBDIR = "debug"
DEBUG_SHPROBE_NAME = "debug_probe.shprobe"

PIXEL_FILTERS = ('BOX', 'GAUSSIAN', 'BLACKMAN_HARRIS')


class BakeError(RuntimeError):
    """A bake that cannot start or continue; the message is meant for the user as is."""


@dataclass
class BakeSettings:
    """Every setting of a bake. Field names equal the ``Scene.schnee_probes`` property names and
    the ``bake.py`` options; the defaults here are the documented defaults (docs/user-guide.md)."""
    volume_collection: str = "ProbeVolumes"
    min_cell_size: float = 0.5
    max_cell_size: float = 16.0
    panorama_resolution: int = 128
    max_band: int = 2
    samples: int = 32          # measured: bench/results/sweep.md (error vs time per setting)
    max_bounces: int = 32
    clamp_direct: float = 0.0
    clamp_indirect: float = 10.0
    pixel_filter: str = 'BOX'
    filter_width: float = 1.0
    lights_visible: bool = True
    per_volume_files: bool = False
    persistent_data: bool = True
    seed: int = 0
    default_sh_scale: float = 1.0
    default_ambient: float = 0.1
    output_path: str = DEFAULT_OUTPUT
    capture_sky: bool = True          # volume bakes also render the world alone to sky.exr
    sky_resolution: int = 512         # sky.exr width; height = width / 2

    @classmethod
    def from_props(cls, props, **overrides) -> "BakeSettings":
        """Settings from a ``Scene.schnee_probes`` PropertyGroup, with keyword overrides."""
        values = {f.name: getattr(props, f.name) for f in dataclasses.fields(cls) if hasattr(props, f.name)}
        values.update(overrides)
        return cls(**values)

    def validate(self):
        """Raise :class:`BakeError` naming the first invalid setting."""
        def bad(msg):
            raise BakeError("Invalid setting: " + msg)
        if not self.min_cell_size > 0 or not math.isfinite(self.min_cell_size):
            bad(f"Min Cell Size must be > 0 m (got {self.min_cell_size})")
        if not self.max_cell_size >= self.min_cell_size:
            bad(f"Max Cell Size ({self.max_cell_size} m) must be >= Min Cell Size ({self.min_cell_size} m)")
        if not 0 <= self.max_band <= 4:
            bad(f"Max SH Band must be 0..4 (got {self.max_band})")
        if self.panorama_resolution < 4 or self.panorama_resolution % 2:
            bad(f"Panorama Resolution must be an even width >= 4 (got {self.panorama_resolution})")
        if self.samples < 1:
            bad(f"Samples must be >= 1 (got {self.samples})")
        if self.max_bounces < 0:
            bad(f"Bounces must be >= 0 (got {self.max_bounces})")
        if self.pixel_filter not in PIXEL_FILTERS:
            bad(f"Pixel Filter must be one of {', '.join(PIXEL_FILTERS)} (got {self.pixel_filter!r})")
        if not self.filter_width > 0:
            bad(f"Filter Width must be > 0 px (got {self.filter_width})")
        if self.clamp_direct < 0 or self.clamp_indirect < 0:
            bad("clamps must be >= 0 (0 = no clamping)")
        if not self.output_path:
            bad("the output path is empty")
        if self.sky_resolution < 4 or self.sky_resolution % 2:
            bad(f"Sky Resolution must be an even width >= 4 (got {self.sky_resolution})")


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


@dataclass
class BakeResult:
    """What a finished bake produced."""
    files: List[str]
    probe_count: int            # probes rendered (unique positions)
    seconds: float
    timings: dict = field(default_factory=dict)  # stage -> seconds summed over probes
    messages: List[str] = field(default_factory=list)


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
                 cursor: Optional[Sequence[float]] = None, log=print):
        if mode not in ("VOLUMES", "CURSOR"):
            raise ValueError(f"unknown bake mode {mode!r}")
        if mode == "CURSOR" and cursor is None:
            raise ValueError("a cursor bake needs a cursor position")
        self.scene = scene
        self.view_layer = view_layer
        self.settings = settings
        self.mode = mode
        self.cursor = None if cursor is None else tuple(float(c) for c in cursor)
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
        self._direct = None                 # direct_light.DirectLightPlan (issue 11 hook)

    # ------------------------------------------------------------------ prepare
    @property
    def total(self) -> int:
        return int(len(self.positions))

    def prepare(self, placement_progress=None):
        """Validate the input, place the probes and set up rendering. Raises :class:`BakeError`."""
        self._t0 = time.perf_counter()
        s = self.settings
        s.validate()
        self._realtime_lights = self._check_light_modes()
        min_w, min_h = native.min_panorama_size(s.max_band)
        if s.panorama_resolution < min_w or s.panorama_resolution // 2 < min_h:
            raise BakeError(f"Panorama Resolution {s.panorama_resolution} is too small for Max SH Band "
                            f"{s.max_band}: at least {min_w}x{min_h} is needed")
        if self.mode == "CURSOR":
            self._prepare_cursor()
        else:
            self._prepare_volumes(placement_progress)
        if self.total == 0:
            raise BakeError("No probe could be placed: every candidate position is inside solid "
                            "geometry. Check the probe volumes or use a smaller Min Cell Size.")
        self.coeffs = np.zeros((self.total, native.sh_count(s.max_band), 3))
        self._setup_render()

    def _check_light_modes(self):
        """The lamps marked realtime (``schnee_light_mode``, light_modes.py); refuses a bad value
        before anything changes."""
        realtime = []
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
        return realtime

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

        t = time.perf_counter()
        unique = {}
        positions = []
        for name, path, vols in groups:
            try:
                pl = native.place_probes(vols, geometry, s.min_cell_size, s.max_cell_size,
                                         progress=placement_progress)
            except native.SchneeError as exc:
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
        self._state = render_settings.SceneState(scene, self.view_layer, volume_objects + lights)
        render_settings.apply_bake_settings(scene, self.view_layer, s)
        for ob in volume_objects:
            ob.hide_render = True
        for ob in lights:
            if compat.has_visible_camera(ob):
                ob.visible_camera = s.lights_visible
        # Realtime lamps are the engine's direct light (VULKAN_SCHNEE_light): the probes must not
        # hold them too, so they are left out of every panorama render. hide_render of every lamp
        # was recorded by the SceneState above and is restored on success, error and cancel.
        for ob in self._realtime_lights:
            ob.hide_render = True
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
        scene.collection.objects.link(cam)
        self._camera = cam
        scene.camera = cam
        self._tmpdir = tempfile.mkdtemp(prefix="schnee_bake_")

    # ------------------------------------------------------------------ steps
    def step(self) -> bool:
        """Render and project the next probe. Returns True while probes remain."""
        if self.done >= self.total:
            return False
        s = self.settings
        i = self.done
        self._camera.location = tuple(scene_export.engine_to_blender(self.positions[i]))
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
            self.coeffs[i] = native.project_file(exr, s.max_band, negative="clamp")
        except native.SchneeError as exc:
            raise BakeError(f"Projecting the panorama of probe {i} failed: {exc}") from exc
        if self._direct is not None:         # --- issue 11 hook: the world seen directly
            self._direct.add_sky(self, i, exr)
        t3 = time.perf_counter()
        self.timings["render"] += t1 - t0
        self.timings["write_exr"] += t2 - t1
        self.timings["project"] += t3 - t2
        self.done += 1
        return self.done < self.total

    def progress_line(self) -> str:
        elapsed = time.perf_counter() - (self._t0 or time.perf_counter())
        per = self.timings["render"] + self.timings["write_exr"] + self.timings["project"]
        eta = per / max(self.done, 1) * (self.total - self.done)
        return f"Schnee bake: probe {self.done}/{self.total}, {elapsed:.1f} s elapsed, ~{eta:.0f} s left"

    def capture_sky(self):
        """Render the world alone (every object hidden from the render) as an equirect panorama of
        ``sky_resolution`` x ``sky_resolution / 2`` from the probe camera (DESIGN.md §3's mapping).
        Works for any world node setup, since Cycles renders the world itself. Objects' render
        visibility is restored right after the render."""
        s, scene = self.settings, self.scene
        t0 = time.perf_counter()
        hidden = [(ob, ob.hide_render) for ob in scene.objects if ob is not self._camera]
        render = scene.render
        res = (render.resolution_x, render.resolution_y, render.resolution_percentage)
        try:
            for ob, _ in hidden:
                ob.hide_render = True
            render.resolution_x, render.resolution_y = s.sky_resolution, s.sky_resolution // 2
            render.resolution_percentage = 100
            self._camera.location = (0.0, 0.0, 0.0)
            bpy.ops.render.render(write_still=False, layer=self.view_layer.name, scene=scene.name)
            image = bpy.data.images.get("Render Result")
            if image is None:
                raise BakeError("Cycles produced no render result for the sky")
            path = os.path.join(self._tmpdir, SKY_FILE_NAME)
            image.save_render(path, scene=scene)
        finally:
            for ob, was in hidden:
                if ob.hide_render != was:
                    ob.hide_render = was
            render.resolution_x, render.resolution_y, render.resolution_percentage = res
        self._sky_exr = path
        self.timings["sky"] = time.perf_counter() - t0

    # ------------------------------------------------------------------ end
    def finish(self) -> BakeResult:
        """Write every output file (all or none), restore the scene and return the result."""
        try:
            if self.done < self.total:
                raise BakeError(f"finish() after {self.done} of {self.total} probes")
            if self.mode == "VOLUMES" and self.settings.capture_sky and self._sky_exr is None:
                self.capture_sky()
            if self._direct is not None:     # --- issue 11 hook: add the lamps' direct light
                self._direct.add_to(self)
            files = self._write_outputs()
        finally:
            self._close()
        result = BakeResult(files=files, probe_count=self.total,
                            seconds=time.perf_counter() - self._t0, timings=dict(self.timings),
                            messages=list(self.messages))
        return result

    def cancel(self):
        """Abandon the bake: restore the scene and remove temporary files; write nothing."""
        self._close()

    def _close(self):
        if self._closed:
            return
        self._closed = True
        failed = []
        if self._state is not None:
            failed = self._state.restore()
        if self._camera is not None:
            cam_data = self._camera.data
            bpy.data.objects.remove(self._camera, do_unlink=True)
            if cam_data.users == 0:
                bpy.data.cameras.remove(cam_data)
            self._camera = None
        if self._tmpdir:
            shutil.rmtree(self._tmpdir, ignore_errors=True)
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

        current = None
        try:
            for t in self.targets:
                current = t.path
                os.makedirs(os.path.dirname(t.path), exist_ok=True)
                tmp = tmp_name(t.path)
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
        return [final for _, final in pending]

    def run(self, progress=None) -> BakeResult:
        """prepare + every step + finish, synchronously; ``progress(bake)`` after each probe may
        return False to cancel (raises :class:`BakeCancelled`). Restores the scene on any exit."""
        try:
            self.prepare()
            while self.done < self.total:
                self.step()
                if progress is not None and progress(self) is False:
                    raise BakeCancelled("Bake cancelled")
            return self.finish()
        except BaseException:
            self.cancel()
            raise


class BakeCancelled(BakeError):
    """The user cancelled the bake."""


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
