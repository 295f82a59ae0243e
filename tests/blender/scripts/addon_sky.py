"""Sky-only scene lit by a bundled HDRI: bake probes and compare them with the HDRI's own projection.

Args after --: OUT_DIR [--hdri NAME] [--res W] [--samples N] [--filter BOX] [--width 1.0]
[--cursor] [--band L]. Emits RESULT lines with the per-probe coefficient and irradiance errors.
"""
import argparse
import os
import sys

import bpy
import numpy as np

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import addon_common as common  # noqa: E402
from addon_common import scene_lib as lib

p = argparse.ArgumentParser()
p.add_argument("out_dir")
p.add_argument("--hdri", default="courtyard.exr")
p.add_argument("--res", type=int, default=64)
p.add_argument("--samples", type=int, default=16)
p.add_argument("--filter", default="BOX")
p.add_argument("--width", type=float, default=1.0)
p.add_argument("--band", type=int, default=2)
p.add_argument("--cursor", action="store_true")
a = p.parse_args(common.args())

import schnee_probes  # noqa: E402
from schnee_probes import bake_core, native  # noqa: E402

lib.clear_scene()
lib.hdri_world(a.hdri)
# Blender x, y in -2..2, z in 0..2; with Min = Max Cell Size = 2 m: 2 x 1 x 2 cells, 4 probes.
lib.probe_volume("SkyVolume", (-2.0, -2.0, 0.0), (2.0, 2.0, 2.0))
blend = lib.save(os.path.join(a.out_dir, "sky.blend"))
schnee_probes.register()

settings = bake_core.BakeSettings(placement="OCTREE", min_cell_size=2.0, max_cell_size=2.0, panorama_resolution=a.res,
                                  samples=a.samples, pixel_filter=a.filter, filter_width=a.width,
                                  max_band=a.band)
if a.cursor:
    bake = bake_core.ProbeBake(bpy.context.scene, bpy.context.view_layer, settings, mode="CURSOR",
                               cursor=(0.3, -0.7, 1.1))
else:
    bake = bake_core.ProbeBake(bpy.context.scene, bpy.context.view_layer, settings)
result = bake.run()

# Reference: the HDRI file itself projected natively; the world texture's default mapping is the
# panorama mapping of DESIGN.md §3, so the default rotation gives engine space.
# The bundled HDRIs hold a few tiny negative texels (-1e-5): project them as they are.
ref = native.project_file(lib.studiolight_path(a.hdri), a.band, negative="allow")
f = native.read_shprobe(result.files[0])
coeffs = np.asarray(f.coeffs, dtype=np.float64)
l0 = np.abs(ref[0]).max()
errors = [float(np.abs(c - ref).max() / l0) for c in coeffs]
irr = [common.irradiance_rel_rms(native, c, ref) for c in coeffs]
ref_blender = native.project_file(lib.studiolight_path(a.hdri), a.band, rotation=np.eye(3), negative="allow")
common.emit(blender_space_irradiance_rel_rms=common.irradiance_rel_rms(native, coeffs[0], ref_blender),
            probe_count=f.probe_count, grid_dims=list(f.grid_dims), coeff_max_rel=errors,
            irradiance_rel_rms=irr, ref_l0=ref[0].tolist(), l0=[c[0].tolist() for c in coeffs],
            seconds=result.seconds, timings=result.timings, files=result.files)
