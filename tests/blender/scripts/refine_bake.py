"""Adaptive placement in real Blender + Cycles (tests/blender/test_refine_bake.py).

Usage: blender -b SCENE.blend --factory-startup -P refine_bake.py -- CASE OUT_DIR [options]

CASE:
  shadow   bake the shadow scene (refine_scenes.py), then bake reference probes at seeded random
           points and compare them with the file's interpolation there
  shadow_axes  the same with the per-axis refinement (adaptive.Policy(axes=True): version 4 boxes)
  open     bake the uniformly lit open scene (V3, then File Version 1)
  cancel   bake once, then bake again and cancel in pass 2 (Esc/SIGINT path) and fail in pass 2
           (an error while rendering): the first file must stay byte for byte, temp folders gone,
           the scene's settings back
  export   bake into //sh_coeffs of a saved copy, export glTF, report the entry
  skysun   the lamps of the direct-light check (bake_plans.RefinementLamps.check_lamps) under sunrise.exr (a sun
           in the image), a constant world, and with Lamps Seen by Probes off (prepare only)
Prints one RESULT line (addon_common.emit).
"""
import glob
import json
import os
import sys
import tempfile

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import addon_common  # noqa: E402
from addon_common import emit  # noqa: E402

import bpy  # noqa: E402
import numpy as np  # noqa: E402

import schnee_probes  # noqa: E402
from schnee_probes import adaptive, bake_core, native  # noqa: E402

args = addon_common.args()
CASE, OUT = args[0], args[1]
if CASE == "export":
    # The add-on must be *enabled* (in preferences) for the exporter to find its user extension.
    import addon_utils
    addon_utils.enable("io_scene_gltf2", default_set=True)
    assert addon_utils.enable("schnee_probes", default_set=True) is not None
else:
    schnee_probes.register()
RES, SAMPLES = 64, 16          # tiny panoramas: the suite stays fast (measured 2-4 s per bake)


def settings(**kw):
    # Error Tolerance 0.05 (the default before issue 12's prediction made 0.03 affordable): these
    # scenes' smooth light (a uniform sky, the bright plane's falloff) varies by 3-5 % over a 2 m
    # cell, so at 0.03 cells far from the shadow split too and "nowhere else" would not be a
    # property of the shadow any more (measured: cells 2.8 m from it split at 0.03).
    base = dict(placement="ADAPTIVE", min_cell_size=0.5, max_cell_size=2.0, panorama_resolution=RES,
                samples=SAMPLES, capture_sky=False, error_tolerance=0.05,
                output_path=os.path.join(OUT, "probes.shprobe"))
    base.update(kw)
    return bake_core.BakeSettings(**base)


LOG = []


def bake(s, **kw):
    def log(line):
        LOG.append(line)
        print(line)
    b = bake_core.ProbeBake(bpy.context.scene, bpy.context.view_layer, s, log=log, **kw)
    return b, b.run()


def file_summary(path):
    f = native.read_shprobe(path)
    out = {"version": f.version, "structure": f.structure, "probe_count": f.probe_count,
           "grid_origin": list(f.grid_origin), "grid_spacing": f.grid_spacing, "grid_dims": list(f.grid_dims)}
    if f.leaves is not None:
        out["leaves"] = f.leaves.tolist()
    return f, out


def scene_state():
    sc = bpy.context.scene
    return {"samples": sc.cycles.samples, "seed": sc.cycles.seed, "res": sc.render.resolution_x,
            "camera": sc.camera.name if sc.camera else None,
            "objects": sorted(o.name for o in bpy.data.objects)}


def temp_dirs():
    return sorted(glob.glob(os.path.join(tempfile.gettempdir(), f"{bake_core.TMP_PREFIX}{os.getpid()}_*")))


if CASE in ("shadow", "shadow_axes"):
    # Error Tolerance 0.2. At 0.07 (the noise adds to the light's error in quadrature, threshold
    # sqrt(tol² + (2σ)²)) the cells far from the shadow passed only while the noise of the dark
    # probes hid the bright plane's falloff: since the probes get the samples the tolerance asks
    # (issue 29) the +x cell's face centre at the volume's end (4, 1, 0) errs by 11.7-14.5 % (at
    # 1/3 and 1/2 of the tolerance as the probes' noise target) at σ 0.3 %, a real change of the
    # light, and splits. The penumbra's error is ~100 %: at 0.2 it refines to Min Cell Size as
    # before, and the falloff does not.
    s = settings(error_tolerance=0.2)
    b, r = bake(s, policy=adaptive.Policy(axes=CASE == "shadow_axes"))
    f, out = file_summary(r.files[0])
    out["passes"] = [vars(p) for p in r.passes]
    out["renders"] = r.renders
    # The estimate in all (bake_plans.AdaptivePlan.forecast), logged once 40 points are measured.
    out["forecast"] = list(b.plan.first_forecast)
    out["cells"] = b.plan.cells
    out["points_rendered"] = r.points
    out["seconds"] = r.seconds
    out["forecast_lines"] = [line for line in LOG if " in all (about " in line]
    out["forecasts"] = b.plan.forecasts
    # Reference probes at seeded random points of the volume (engine x in [-4, 4], y in [0, 2],
    # z in [-1, 1]) baked at 4x the samples, against the file's interpolation there.
    rng = np.random.default_rng(12)
    pts = rng.uniform([-3.9, 0.1, -0.9], [3.9, 1.9, 0.9], size=(16, 3))
    ref = bake_core.bake_points(bpy.context.scene, bpy.context.view_layer,
                                settings(samples=4 * SAMPLES), pts, log=lambda line: None)
    interp = native.interpolation_from_file(r.files[0])
    got = interp.interpolate(pts, f.coeffs, f.validity)
    out["points"] = pts.tolist()
    out["point_error"] = adaptive.irradiance_error(got, ref).tolist()
    out["point_l0"] = ref[:, 0, 0].tolist()
    emit(**out)

elif CASE == "rounds":
    # Issue 29: a point rendered progressively (two first rounds of 2 samples, then one more round of
    # 12: 16 in all with at most 2 x Samples, seeds Seed .. Seed + 2) against one render of 16
    # samples (seed 100): the same value within the noise, the estimate's sigma calibrated. (At 8 in
    # all the difference is 2 sigma: renders of different seeds at 2-4 samples are correlated in
    # Cycles 3.4, bench/results/placement.md "Samples where a decision needs them".)
    s = settings(samples=8)
    b = bake_core.ProbeBake(bpy.context.scene, bpy.context.view_layer, s, log=lambda line: None,
                            policy=adaptive.Policy(max_samples=2.0))
    b.prepare()
    plan, cache = b.plan, b.plan.cache
    rows = []
    for i in [int(i) for i in np.flatnonzero(~cache.solid(np.arange(len(cache))))][:12]:
        pos = cache.positions[i]
        plan.measure(i, pos, b.session, b.direct)
        first = float(cache.samples[i])
        assert cache.more([i], cache.most) == [i]
        plan.measure(i, pos, b.session, b.direct)
        b.session.set_samples(16, 100)
        one = b.session.render(pos, i, b.direct)
        rows.append({"first": first, "samples": float(cache.samples[i]), "rounds": int(cache.rounds[i]),
                     "sigma": float(cache.noise[i]), "err": float(adaptive.irradiance_error(cache.coeffs[i], one)),
                     "samples_rendered": plan.samples_rendered})
    b.cancel()
    emit(rows=rows, most=cache.most, first_round=cache.first)

elif CASE == "open":
    b, r = bake(settings())
    _, out = file_summary(r.files[0])
    out["passes"] = [vars(p) for p in r.passes]
    out["noise"] = b.plan.cache.noise.tolist()
    b1, r1 = bake(settings(file_version="V1", output_path=os.path.join(OUT, "v1.shprobe")))
    f1, out1 = file_summary(r1.files[0])
    # The dense file's probe at each cell centre against the octree file's field there.
    f3 = native.read_shprobe(r.files[0])
    centres = np.array(f1.positions) if f1.positions is not None else None
    cells = np.argwhere(np.ones(tuple(reversed(f1.grid_dims)), dtype=bool))[:, ::-1]
    centres = np.asarray(f1.grid_origin) + (cells + 0.5) * f1.grid_spacing
    flat = f1.grid.reshape(-1)
    v3 = native.interpolation_from_file(r.files[0]).interpolate(centres, f3.coeffs, f3.validity)
    v1 = f1.coeffs[flat[flat >= 0]]
    out["v1"] = out1
    out["v1_cells"] = int((flat >= 0).sum())
    out["v1_max_diff"] = float(np.max(np.abs(v1 - v3[flat >= 0])))
    emit(**out)

elif CASE == "cancel":
    path = os.path.join(OUT, "probes.shprobe")
    bake(settings())
    before = open(path, "rb").read()
    state0 = scene_state()
    results = {}
    # Cancel as Esc / SIGINT do (request_cancel) once pass 2 has started.
    b = bake_core.ProbeBake(bpy.context.scene, bpy.context.view_layer, settings(), log=print)
    try:
        b.prepare()
        while b.step():
            if len(b.plan.groups[0].passes) >= 2:
                b.request_cancel()
        b.finish()
        results["cancel"] = "finished"
    except bake_core.BakeCancelled as exc:
        b.cancel()
        results["cancel"] = str(exc)
    results["cancel_pass"] = len(b.plan.groups[0].passes)
    results["cancel_same_file"] = open(path, "rb").read() == before
    results["cancel_state"] = scene_state() == state0
    results["cancel_temp"] = temp_dirs()
    # An error while rendering in pass 2 (the projection fails): run() restores and raises.
    real = native.project_pixels
    calls = {"n": 0}

    def failing(*a, **k):
        calls["n"] += 1
        if calls["n"] > 100:  # pass 1 renders 20 probes and 25 tests, 2 halves each
            raise native.SchneeError("injected failure", "I/O error")
        return real(*a, **k)
    native.project_pixels = failing
    b = bake_core.ProbeBake(bpy.context.scene, bpy.context.view_layer, settings(), log=print)
    try:
        b.run()
        results["error"] = "finished"
    except bake_core.BakeError as exc:
        results["error"] = str(exc)
    finally:
        native.project_pixels = real
    results["error_pass"] = len(b.plan.groups[0].passes)
    results["error_same_file"] = open(path, "rb").read() == before
    results["error_state"] = scene_state() == state0
    results["error_temp"] = temp_dirs()
    results["partials"] = sorted(os.path.basename(p) for p in glob.glob(os.path.join(OUT, "*.partial")))
    emit(**results)

elif CASE == "export":
    blend = os.path.join(OUT, "scene.blend")
    bpy.ops.wm.save_as_mainfile(filepath=blend, check_existing=False)
    bake(settings(output_path="//sh_coeffs/probes.shprobe"))
    # Issue 16: the same bake written as ambient cubes in half floats (same seeds: same renders).
    bake(settings(output_path="//sh_coeffs/cube.shprobe", probe_representation="CUBE_HALF"))
    sh = native.read_shprobe(os.path.join(OUT, "sh_coeffs", "probes.shprobe"))
    cube = native.read_shprobe(os.path.join(OUT, "sh_coeffs", "cube.shprobe"))
    want = native.ambient_cube_from_sh(sh.coeffs.astype(np.float64))
    cube_rel = float(np.max(np.abs(cube.coeffs - want)) / np.max(np.abs(want)))
    gltf = os.path.join(OUT, "export", "scene.gltf")
    os.makedirs(os.path.dirname(gltf), exist_ok=True)
    bpy.ops.export_scene.gltf(filepath=gltf, export_format="GLTF_SEPARATE")
    with open(gltf, encoding="utf-8") as fh:
        doc = json.load(fh)
    ext = doc["scenes"][0]["extensions"]["VULKAN_SCHNEE_engine_properties"]
    f = native.read_shprobe(os.path.join(OUT, "sh_coeffs", "probes.shprobe"))
    emit(gltf=gltf, grids=ext["shProbeGrids"], used=doc.get("extensionsUsed", []),
         required=doc.get("extensionsRequired", []), file_origin=list(f.grid_origin),
         file_spacing=f.grid_spacing, file_dims=list(f.grid_dims), file_probes=f.probe_count,
         copied=os.path.isfile(os.path.join(OUT, "export", "sh_coeffs", "probes.shprobe")),
         cube_representation=cube.representation, cube_storage=cube.storage, cube_rel=cube_rel,
         cube_positions_equal=bool(np.array_equal(cube.positions, sh.positions)))
elif CASE == "skysun":
    sys.path.insert(0, os.path.join(os.path.dirname(os.path.abspath(__file__)), "..", "..", "..", "scenes"))
    import scene_lib  # noqa: E402
    results = {}
    scene_lib.hdri_world("sunrise.exr", strength=2.0)

    def check_lamps(**kw):
        b = bake_core.ProbeBake(bpy.context.scene, bpy.context.view_layer, settings(**kw), log=print)
        try:
            b.prepare()
            return [dict(kind=lp.kind, color=list(lp.color), direction=list(lp.direction), angle=lp.radius)
                    for lp in b.plan.lamps.check_lamps()]
        finally:
            b.cancel()
    # Sky Sun "baked": the probes keep the sun, so the check stands in for it; "mixed" (the
    # default): the sun is the engine's (bake_plans.RefinementLamps.engine_lamps), the check leaves it out.
    results["image"] = check_lamps(sky_sun="baked")
    results["mixed_check"] = check_lamps()
    b = bake_core.ProbeBake(bpy.context.scene, bpy.context.view_layer, settings(), log=print)
    try:
        b.prepare()
        results["mixed_engine"] = [dict(kind=lp.kind, color=list(lp.color), direction=list(lp.direction),
                                        angle=lp.radius) for lp in b.plan.lamps.engine_lamps()]
    finally:
        b.cancel()
    # The same image read by OIIO (not Blender's pixels), times the Background strength.
    own = adaptive.sky_sun(native.read_image(scene_lib.studiolight_path("sunrise.exr")) * 2.0)
    results["oiio"] = dict(color=list(own.color), direction=list(own.direction), angle=own.radius)
    results["lamps_off"] = check_lamps(lights_visible=False, sky_sun="baked")
    world = bpy.context.scene.world
    world.node_tree.nodes.clear()
    out_node = world.node_tree.nodes.new("ShaderNodeOutputWorld")
    bg = world.node_tree.nodes.new("ShaderNodeBackground")
    world.node_tree.links.new(bg.outputs["Background"], out_node.inputs["Surface"])
    results["constant"] = check_lamps(sky_sun="baked")
    emit(**results)
else:
    raise SystemExit(f"unknown case {CASE}")
