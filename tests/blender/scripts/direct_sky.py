"""Sky-only bakes with the world seen directly (issue 11): ``... -P direct_sky.py -- OUT_DIR [NAMES...]``.

For every bundled HDRI (datafiles/studiolights/world/*.exr, or the NAMES given) and for a Nishita
Sky Texture world: one volume bake of 1 probe at the add-on's defaults (128x64, 8 spp, band 2,
box filter) with seeds 0 and 1. Reference: the HDRI file projected natively (project_file); for the
Nishita sky, the world rendered alone at 4096x2048 with 16 spp and another seed (0.07 % from
another seed's), projected the same way. Emits RESULT lines with the coefficients, the reference and the bake's sky source.
"""
import glob
import math
import os
import sys

import bpy
import numpy as np

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import addon_common as common  # noqa: E402
from addon_common import scene_lib as lib  # noqa: E402

import schnee_probes  # noqa: E402
from schnee_probes import bake_core, compat, native  # noqa: E402


def reference_capture(out):
    """The world alone at 4096x2048, 16 spp, seed 7, from the DESIGN.md §3 camera."""
    scene = bpy.context.scene
    cd = bpy.data.cameras.new("RefPano")
    compat.set_equirectangular(cd)
    cam = bpy.data.objects.new("RefPano", cd)
    scene.collection.objects.link(cam)
    cam.rotation_euler = (math.pi / 2, 0.0, -math.pi / 2)
    old_cam = scene.camera
    scene.camera = cam
    hidden = [(ob, ob.hide_render) for ob in scene.objects if ob is not cam]
    for ob, _ in hidden:
        ob.hide_render = True
    r = scene.render
    r.engine = 'CYCLES'
    r.resolution_x, r.resolution_y, r.resolution_percentage = 4096, 2048, 100
    r.film_transparent = False
    r.image_settings.file_format = 'OPEN_EXR'
    r.image_settings.color_depth = '32'
    scene.cycles.samples = 16
    scene.cycles.seed = 7
    scene.cycles.pixel_filter_type = 'BOX'
    scene.cycles.filter_width = 1.0
    scene.cycles.use_denoising = False
    scene.cycles.use_adaptive_sampling = False
    path = os.path.join(out, "nishita_ref.exr")
    bpy.ops.render.render(write_still=False)
    bpy.data.images["Render Result"].save_render(path, scene=scene)
    for ob, was in hidden:
        ob.hide_render = was
    scene.camera = old_cam
    bpy.data.objects.remove(cam, do_unlink=True)
    return native.project_file(path, 2, negative="clamp")


def bake(out, name, seed):
    settings = bake_core.BakeSettings(placement="OCTREE", min_cell_size=4.0, max_cell_size=4.0, seed=seed, capture_sky=False,
                                      sky_sun="baked",  # the whole world in the probes (Sky Sun "mixed": test_sky_sun_bake.py)
                                      output_path=os.path.join(out, f"{name}_{seed}", "probes.shprobe"))
    job = bake_core.ProbeBake(bpy.context.scene, bpy.context.view_layer, settings, log=lambda *_: None)
    result = job.run()
    return job, result


def main():
    args = common.args()
    out = args[0]
    folder = os.path.dirname(lib.studiolight_path("sunrise.exr"))
    names = args[1:] or sorted(os.path.basename(p) for p in glob.glob(os.path.join(folder, "*.exr")))
    schnee_probes.register()
    for name in [n for n in names if n != "nishita"] + ["nishita"]:
        lib.clear_scene()
        lib.probe_volume("SkyVolume", (-2.0, -2.0, 0.0), (2.0, 2.0, 4.0))
        if name == "nishita":
            lib.nishita_world()
            reference = reference_capture(out)
        else:
            lib.hdri_world(name)
            reference = native.project_file(lib.studiolight_path(name), 2, negative="clamp")
        for seed in (0, 1):
            job, result = bake(out, name, seed)
            common.emit(case="sky", name=name, seed=seed, coeffs=job.coeffs.tolist(),
                        reference=reference.tolist(), source=job.direct.sky_source,
                        timings=result.timings, probes=job.total)


main()
