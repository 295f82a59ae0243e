"""Sky-only bakes with the world seen directly (issue 11): ``... -P direct_sky.py -- OUT_DIR [NAMES...]``.

For every bundled HDRI (datafiles/studiolights/world/*.exr, or the NAMES given) and for a Nishita
Sky Texture world: one volume bake of 1 probe at the add-on's defaults (128x64, 8 spp, band 2,
box filter) with seeds 0 and 1. Reference: the HDRI file projected natively (project_file); for the
Nishita sky, the world rendered alone at 4096x2048 with 16 spp and another seed (0.07 % from
another seed's), projected the same way. Emits RESULT lines with the coefficients, the reference and the bake's sky source.

The Nishita reference (a 4096x2048 16-spp render, about half this script's CPU time) is kept in
build/test-cache/ under a key of everything that decides it: Blender's version and build, the render
settings, this script, scenes/scene_lib.py (the world) and the native module (the projection). A
changed input is a new key, so a cached reference is the render this run would make;
SCHNEE_TEST_CACHE=0 renders it anyway.
"""
import glob
import hashlib
import json
import math
import os
import sys
import time

import bpy
import numpy as np

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import addon_common as common  # noqa: E402
from addon_common import scene_lib as lib  # noqa: E402

import schnee_probes  # noqa: E402
from schnee_probes import bake_core, compat, native  # noqa: E402


REFERENCE = dict(width=4096, height=2048, samples=16, seed=7, filter="BOX", filter_width=1.0, band=2)


def _file_digest(path):
    with open(path, "rb") as fh:
        return hashlib.sha256(fh.read()).hexdigest()


def reference_key():
    """The cache key of the Nishita reference: every input that decides its coefficients."""
    parts = dict(REFERENCE, blender=bpy.app.version_string, build=bpy.app.build_hash.decode(errors="replace"),
                 script=_file_digest(os.path.abspath(__file__)), scene_lib=_file_digest(lib.__file__),
                 native=_file_digest(native._native.__file__), native_py=_file_digest(native.__file__))
    return hashlib.sha256(json.dumps(parts, sort_keys=True).encode()).hexdigest()[:32]


def cached_reference(out):
    """(coefficients, where from): the cached reference when its key matches, else a fresh
    reference_capture (then stored)."""
    folder = os.path.join(common.REPO, "build", "test-cache")
    path = os.path.join(folder, f"direct_sky_nishita_ref-{reference_key()}.json")
    use_cache = os.environ.get("SCHNEE_TEST_CACHE", "1") != "0"
    if use_cache and os.path.exists(path):
        with open(path, encoding="utf-8") as fh:
            return np.array(json.load(fh)["coeffs"]), f"cached {os.path.basename(path)}"
    t0 = time.perf_counter()
    coeffs = reference_capture(out)
    seconds = time.perf_counter() - t0
    if use_cache:
        os.makedirs(folder, exist_ok=True)
        tmp = path + f".{os.getpid()}.tmp"
        with open(tmp, "w", encoding="utf-8") as fh:
            json.dump({"coeffs": coeffs.tolist(), "settings": REFERENCE, "seconds": seconds}, fh)
        os.replace(tmp, path)
    return coeffs, f"rendered in {seconds:.1f} s"


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
    r.resolution_x, r.resolution_y, r.resolution_percentage = REFERENCE["width"], REFERENCE["height"], 100
    r.film_transparent = False
    r.image_settings.file_format = 'OPEN_EXR'
    r.image_settings.color_depth = '32'
    scene.cycles.samples = REFERENCE["samples"]
    scene.cycles.seed = REFERENCE["seed"]
    scene.cycles.pixel_filter_type = REFERENCE["filter"]
    scene.cycles.filter_width = REFERENCE["filter_width"]
    scene.cycles.use_denoising = False
    scene.cycles.use_adaptive_sampling = False
    path = os.path.join(out, "nishita_ref.exr")
    bpy.ops.render.render(write_still=False)
    bpy.data.images["Render Result"].save_render(path, scene=scene)
    for ob, was in hidden:
        ob.hide_render = was
    scene.camera = old_cam
    bpy.data.objects.remove(cam, do_unlink=True)
    coeffs = native.project_file(path, REFERENCE["band"], negative="clamp")
    os.remove(path)  # 128 MB
    return coeffs


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
            reference, origin = cached_reference(out)
        else:
            lib.hdri_world(name)
            reference = native.project_file(lib.studiolight_path(name), 2, negative="clamp")
            origin = "native.project_file of the HDRI"
        # Seeds 0 and 1 for the first HDRI (a plain image's projection must not depend on the seed),
        # seed 0 for the rest and for the Nishita sky (each Nishita bake captures 2048x1024 at 32 spp).
        for seed in ((0, 1) if name == names[0] else (0,)):
            job, result = bake(out, name, seed)
            common.emit(case="sky", name=name, seed=seed, coeffs=job.coeffs.tolist(),
                        reference=reference.tolist(), reference_origin=origin, source=job.direct.sky_source,
                        timings=result.timings, probes=job.total)


main()
