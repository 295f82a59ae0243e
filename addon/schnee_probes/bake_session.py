"""The bake's render session: the Blender state it changes, its probe camera, its temporary folder,
and one :meth:`RenderSession.render` per point.

One of the parts :class:`bake_core.ProbeBake` drives (the others: ``bake_plans.py`` places the
probes, ``bake_points.py`` keeps the journal, ``bake_outputs.py`` writes the files)::

    session = RenderSession(scene, view_layer, settings, timings, log)
    session.apply_settings(hidden=realtime_lamps)   # render settings, volumes and lamps hidden
    direct = direct_light.prepare(session, ...)     # its changes go through session.guard
    session.open_camera()                           # the equirect camera and the temporary folder
    coeffs = session.render(position, index, direct)  # (C, 3) radiance SH, engine space
    session.close()                                 # every change undone (finish and cancel)

Every scene setting goes through one :class:`render_settings.StateGuard` (``guard``), restored by
:meth:`close`. Direct light (direct_light.py) and the sky capture (bake_sky.py) get the session,
not the bake: the scene, settings, guard, camera, temporary folder, timings and log are public
here.
"""
from __future__ import annotations

import math
import os
import re
import shutil
import stat
import tempfile
import time

import bpy
import numpy as np

from . import compat, images, native, render_settings, scene_export
from .settings import BakeError

# Temporary folders: schnee_bake_<pid>_<random> in the system temporary folder; a folder whose
# process is gone was left by a killed bake and is removed by the next one.
TMP_PREFIX = "schnee_bake_"


class RenderSession:
    """The scene as the probes render it. ``timings`` is the bake's stage -> seconds dict (render,
    write_exr and project are summed here; direct light adds its own stages)."""

    def __init__(self, scene, view_layer, settings, timings: dict, log=print):
        self.scene = scene
        self.view_layer = view_layer
        self.settings = settings
        self.timings = timings
        self.log = log
        self.guard = None       # render_settings.StateGuard, from apply_settings() until close()
        self._camera = None
        self._tmpdir = None
        self._device = None     # render_settings.apply_bake_settings' device label, from apply_settings()

    @property
    def device(self) -> str:
        """What renders the panoramas (render_settings.device_label): as set by apply_settings(), or
        before it what Render Device will select."""
        return self._device or render_settings.device_label(self.scene, self.settings.render_device)

    @property
    def camera(self):
        """The probe camera (an equirect panorama, DESIGN.md §3's orientation), or None."""
        return self._camera

    @property
    def tmpdir(self) -> str:
        """The session's temporary folder (removed by :meth:`close`)."""
        return self._tmpdir

    def temp_path(self, name: str) -> str:
        return os.path.join(self._tmpdir, name)

    def apply_settings(self, hidden=()):
        """Override the render settings (render_settings.apply_bake_settings), hide the probe
        volumes (a camera inside a closed volume would see its inside, so a cursor bake hides them
        too) and ``hidden`` (the realtime lamps: the engine's direct light, in no panorama), and set
        the lamps' camera visibility to Lamps Seen by Probes; all through :attr:`guard`."""
        scene, s = self.scene, self.settings
        coll = bpy.data.collections.get(s.volume_collection)
        volume_objects = list(coll.all_objects) if coll is not None else []
        lights = compat.light_objects(scene)
        state = self.guard = render_settings.StateGuard()
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
        self._device = render_settings.apply_bake_settings(scene, self.view_layer, s, log=self.log)
        for ob in volume_objects:
            state.set(ob, "hide_render", True, f"object[{ob.name}].hide_render")
        for ob in lights:
            if compat.has_visible_camera(ob):
                state.set(ob, "visible_camera", s.lights_visible, f"object[{ob.name}].visible_camera")
        for ob in hidden:
            state.set(ob, "hide_render", True, f"object[{ob.name}].hide_render")

    def open_camera(self):
        """Add the probe camera as the scene camera and make the temporary folder (removing those
        of killed bakes first)."""
        scene, state = self.scene, self.guard
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

    def set_samples(self, samples: int, seed: int, tag: bool = True):
        """Cycles' samples and seed for the next renders. Persistent data ignores changed
        integrator settings unless the scene is tagged (measured: identical renders for seeds 0 and
        1 without update_tag)."""
        cycles = self.scene.cycles
        cycles.samples, cycles.seed = samples, seed
        if tag:
            self.scene.update_tag()

    def render(self, position, index: int, direct=None) -> np.ndarray:
        """Render the panorama at an engine-space position and project it: (C, 3) radiance SH;
        with ``direct`` (direct_light.DirectLightPlan) the world seen directly is added exactly.
        ``index`` names the probe in errors."""
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
            # Read once: the projection and (Sky Light exact) the film's alpha both come from it.
            pixels = images.read_image(exr)
            coeffs = native.project_pixels(pixels, s.max_band, negative="clamp", name=exr)
        except native.SchneeError as exc:
            where = tuple(float(c) for c in scene_export.engine_to_blender(position))
            hint = ""
            if getattr(exc, "code", None) == "non-finite value":
                hint = (": the render holds NaN or Inf, which the probes cannot represent (an "
                        "infinite or NaN value in the world, a texture or a shader); find it by "
                        "rendering from that position")
            raise BakeError(f"Projecting the panorama of probe {index + 1} at Blender "
                            f"({where[0]:.3f}, {where[1]:.3f}, {where[2]:.3f}) failed: {exc}{hint}") from exc
        if direct is not None:         # --- issue 11 hook: the world seen directly
            sky = direct.sky_coeffs(self, exr, pixels[:, :, 3] if pixels.shape[2] == 4 else None)
            if sky is not None:
                coeffs = coeffs + sky
        t3 = time.perf_counter()
        if not np.isfinite(coeffs).all():
            raise BakeError(f"Probe {index + 1}: the projected coefficients are not finite (NaN/Inf in "
                            "the render, e.g. an infinite emission)")
        self.timings["render"] += t1 - t0
        self.timings["write_exr"] += t2 - t1
        self.timings["project"] += t3 - t2
        return coeffs

    def render_world(self, name: str, width: int, samples=None) -> str:
        """Render the world alone (every object but the camera hidden, opaque film) from the probe
        camera at the origin as a ``width`` x ``width / 2`` panorama into the temporary file
        ``name``; returns its path. Every change is put back right after the render."""
        scene, cam, r = self.scene, self._camera, self.scene.render
        path = self.temp_path(name)
        with render_settings.StateGuard() as state:
            for ob in scene.objects:
                if ob is not cam:
                    state.set(ob, "hide_render", True, f"object[{ob.name}].hide_render")
            state.set(r, "resolution_x", width, "render.resolution_x")
            state.set(r, "resolution_y", width // 2, "render.resolution_y")
            state.set(r, "resolution_percentage", 100, "render.resolution_percentage")
            state.set(r, "film_transparent", False, "render.film_transparent")  # issue 11
            if samples is not None:
                state.set(scene.cycles, "samples", samples, "cycles.samples")
            location = tuple(cam.location)
            state.on_restore(lambda: setattr(cam, "location", location), "the probe camera's location")
            cam.location = (0.0, 0.0, 0.0)
            bpy.ops.render.render(write_still=False, layer=self.view_layer.name, scene=scene.name)
            image = bpy.data.images.get("Render Result")
            if image is None:
                raise BakeError("Cycles produced no render result for the sky")
            image.save_render(path, scene=scene)
        if state.failed:
            self.log("Schnee: could not restore " + ", ".join(state.failed))
        return path

    def close(self):
        """Undo every change (idempotent); the labels of what could not be restored are logged."""
        failed = self.guard.restore() if self.guard is not None else []
        self._camera = None
        self._tmpdir = None
        if failed:
            self.log("Schnee: could not restore " + ", ".join(failed))


def _remove_camera(cam):
    cam_data = cam.data
    bpy.data.objects.remove(cam, do_unlink=True)
    if cam_data is not None and cam_data.users == 0:
        bpy.data.cameras.remove(cam_data)


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
