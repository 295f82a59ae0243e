"""Dilate Invalid Probes and SH Windowing reach the file (tests/blender/test_postprocess_bake.py).

    blender -b --factory-startup -P postprocess_bake.py -- OUT_DIR

A 4 m probe volume lit by interior.exr with a solid 1 m box at its centre; Adaptive with Min = Max
Cell Size 2 m: 27 corner probes, the centre one inside the box (validity 0). Bakes it twice with the
same seed, settings off and Dilate Invalid Probes on + SH Windowing Laplacian 0.01, and writes both
files' coefficients, validity and positions to OUT_DIR/bakes.npz."""
import os
import sys

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from addon_common import args, emit  # noqa: E402

import bpy  # noqa: E402
import numpy as np  # noqa: E402
import scene_lib  # noqa: E402

import schnee_probes  # noqa: E402
from schnee_probes import bake_core, native  # noqa: E402

out = args()[0]
scene_lib.clear_scene()
scene_lib.hdri_world("interior.exr")
scene_lib.probe_volume("Volume", (0, 0, 0), (4, 4, 4))
scene_lib.box("Solid", (1.5, 1.5, 1.5), (2.5, 2.5, 2.5), material=scene_lib.diffuse_material("Grey", (0.5, 0.5, 0.5)))
schnee_probes.register()
scene, layer = bpy.context.scene, bpy.context.view_layer
files = {}
for name, kw in (("off", {}), ("on", dict(dilate_invalid=True, sh_window="LAPLACIAN", sh_window_strength=0.01))):
    path = os.path.join(out, name, "probes.shprobe")
    s = bake_core.BakeSettings(min_cell_size=2.0, max_cell_size=2.0, panorama_resolution=16, samples=2,
                               max_bounces=2, capture_sky=False, probe_limit=0, output_path=path, **kw)
    bake_core.ProbeBake(scene, layer, s, log=print).run()
    f = native.read_shprobe(path)
    files[name] = f
    print("BAKED", name, f.probe_count, flush=True)
np.savez(os.path.join(out, "bakes.npz"), **{f"{k}_{a}": getattr(f, a) for k, f in files.items()
                                          for a in ("coeffs", "validity", "positions")})
emit(done=True)
