"""The sky a volume bake captures beside the probe files (sky.exr) and the sun it may split off.

Part of the bake (bake_core.ProbeBake drives it); it works on the render session
(bake_session.RenderSession) and the direct-light plan (direct_light.DirectLightPlan), never on
the bake. The glTF exporter copies sky.exr and lists it as VULKAN_SCHNEE_engine_properties.sky
(docs/export.md); with Sky Sun "mixed" the sun split off the world is written as sun.json
(bake_outputs.sun_output) and removed from sky.exr here, else the engine would count it twice.
"""
from __future__ import annotations

import os
import time
from typing import Optional

import bpy
import numpy as np

from . import direct_light, native
from .bake_outputs import SKY_FILE_NAME, SUN_FILE_NAME, copy_output, sun_output


def capture_sky(session, direct) -> str:
    """Render the world alone (every object hidden from the render) as an equirect panorama of
    ``sky_resolution`` x ``sky_resolution / 2`` from the probe camera (DESIGN.md §3's mapping) into
    the session's temporary folder, without the sun ``direct`` split off (Sky Sun "mixed"); returns
    its path. Works for any world node setup, since Cycles renders the world itself. Timed as
    "sky"."""
    t0 = time.perf_counter()
    path = session.render_world(SKY_FILE_NAME, session.settings.sky_resolution)
    sun = sky_sun(session, direct)
    if sun is not None:
        remove_sun_from(session, path, sun)
    session.timings["sky"] = time.perf_counter() - t0
    return path


def sky_sun(session, direct) -> Optional[native.SkySun]:
    """The world's sun split off under Sky Sun "mixed" (native.SkySun), or None (the world is read
    or captured now if no panorama has needed it yet, e.g. a bake resumed whole)."""
    if direct is None or not direct.sky or session.settings.sky_sun != "mixed":
        return None
    direct.sun_lamp(session)   # splits the world if no panorama needed it yet (a bake resumed whole)
    return direct.sun


def remove_sun_from(session, path: str, sun: native.SkySun):
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
        img.save_render(path, scene=session.scene)
    finally:
        bpy.data.images.remove(img)
    session.log(f"Schnee: the sun removed from {SKY_FILE_NAME} too ({how})")


def outputs(session, direct, sky_exr: Optional[str], folder: str):
    """(outputs, stale) of a volume bake writing into ``folder``: sky.exr (when captured) and
    sun.json (when a sun was split off); ``stale`` is the sun.json path to remove when none was
    (bake_outputs.write_all)."""
    out = []
    if sky_exr is not None:
        out.append(copy_output(os.path.join(folder, SKY_FILE_NAME), "exr", sky_exr))
    sun_path = os.path.join(folder, SUN_FILE_NAME)
    sun = sky_sun(session, direct)
    if sun is None:
        return out, sun_path
    out.append(sun_output(sun_path, direct_light.sun_record(sun, direct.sky_source)))
    return out, None
