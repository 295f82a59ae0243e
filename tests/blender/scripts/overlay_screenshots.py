"""Pictures of the probe overlay for docs/user-guide.md ("Seeing the probes in Blender"), drawn
offscreen by the add-on's own drawing code (overlay_gpu.draw_offscreen, the viewport's shader with
sRGB encoding). Run with a GPU context (not -b; under Xvfb on a server):

    xvfb-run -a blender --factory-startup -P tests/blender/scripts/overlay_screenshots.py -- ROOM.shprobe OUT_DIR

ROOM.shprobe: a bake of the bundled room (scenes/make_default_scene.py, then bake.py; docs/overlay.md
gives the commands) and its bake-info sidecar ROOM.shprobe.bakeinfo (docs/bakeinfo.md). Writes
overlay-irradiance.png, overlay-validity.png, overlay-cells.png, overlay-noise.png,
overlay-refinement.png; quits.
"""
import math
import os
import sys
import traceback

import bpy
import numpy as np
from mathutils import Matrix, Vector

ARGS = sys.argv[sys.argv.index("--") + 1:]
SRC, OUT = ARGS[0], ARGS[1]
W, H = 480, 300


def perspective(fov_deg, aspect, near=0.05, far=50.0):
    f = 1.0 / math.tan(math.radians(fov_deg) / 2)
    return Matrix(((f / aspect, 0, 0, 0), (0, f, 0, 0),
                   (0, 0, (far + near) / (near - far), 2 * far * near / (near - far)), (0, 0, -1, 0)))


def look_at(eye, target):
    eye, target = Vector(eye), Vector(target)
    rot = (target - eye).to_track_quat('-Z', 'Y').to_matrix().to_4x4()
    return (Matrix.Translation(eye) @ rot).inverted()


def save_png(px, name):
    img = bpy.data.images.new(name, W, H, alpha=False)
    img.pixels.foreach_set((px.astype(np.float32) / 255.0).reshape(-1))
    img.filepath_raw = os.path.join(OUT, name)
    img.file_format = 'PNG'
    img.save()


def tick():
    try:
        import schnee_probes
        schnee_probes.register()
        from schnee_probes import overlay_data, overlay_gpu
        ps = overlay_data.load(SRC)
        assert ps.error is None, ps.error
        assert ps.has_noise and ps.has_refinement, ps.info_line()
        view = look_at((-4.6, -4.6, 3.7), (1.5, 1.5, 0.6))
        proj = perspective(70.0, W / H)
        shots = (("overlay-irradiance.png", dict(mode="IRRADIANCE", show_cells=True, cell_alpha=0.15)),
                 ("overlay-validity.png", dict(mode="VALIDITY", show_cells=False)),
                 ("overlay-cells.png", dict(mode="WHITE", show_probes=False, cell_alpha=1.0)),
                 ("overlay-noise.png", dict(mode="NOISE", show_cells=False)),
                 ("overlay-refinement.png", dict(mode="REFINEMENT", show_cells=True, cell_alpha=0.35)))
        for name, kw in shots:
            px = overlay_gpu.draw_offscreen([ps], view, proj, W, H, radius=0.07, exposure=0.0, **kw)
            save_png(px, name)
        print(f"SHOTS {ps.holds()}, {ps.cell_count} cells", flush=True)
        reasons = np.bincount(ps.info.leaf_reason, minlength=6).tolist()
        print(f"SHOTS noise / tolerance: median {np.nanmedian(ps.info.noise) / ps.info.tolerance:.3f}, "
              f"max {np.nanmax(ps.info.noise) / ps.info.tolerance:.3f}; leaves per reason "
              f"(unknown, passed, noise-limited, min cell, never tested, not compared) {reasons}", flush=True)
    except Exception:
        traceback.print_exc()
    bpy.ops.wm.quit_blender()


bpy.app.timers.register(tick, first_interval=0.5)
