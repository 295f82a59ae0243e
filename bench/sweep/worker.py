"""Blender side of the sweep: build one reference scene and run a list of bake jobs on it.

    blender -b --factory-startup -P bench/sweep/worker.py -- SCENE JOBS.json OUT.json [--offset X Y Z]

Each job (a dict in JOBS.json) is one of

- ``{"id", "kind": "fixed", "points": "probes"|"samples"|"both", "settings": {...}}``: render the
  scene's fixed positions with ``bake_core.BakeSettings(**settings)`` through the add-on's own
  stepper (:class:`bake_core.ProbeBake`), keep the coefficients and per-probe stage times;
- ``{"id", "kind": "placement", "settings": {...}}``: a complete Bake SH in Volumes (octree placement
  with the settings' cell sizes; Min = Max gives the uniform grid), written to a real ``.shprobe``,
  then the file is read back and looked up at the sample points as the engine does.

OUT.json receives ``{"scene": spec, "jobs": {id: result}}`` (engine space, coefficients as lists).
Run by bench/sweep/run.py; not meant to be called by hand.
"""
import dataclasses
import json
import os
import sys
import tempfile
import time

import bpy
import numpy as np

_HERE = os.path.dirname(os.path.abspath(__file__))
_REPO = os.path.dirname(os.path.dirname(_HERE))
sys.path.insert(0, _HERE)
sys.path.insert(0, os.path.join(_REPO, "addon"))
import metrics  # noqa: E402
import scenes  # noqa: E402
import schnee_probes  # noqa: E402
from schnee_probes import bake_core, native, scene_export  # noqa: E402


def _args():
    argv = sys.argv[sys.argv.index("--") + 1:]
    offset = (0.0, 0.0, 0.0)
    if "--offset" in argv:
        i = argv.index("--offset")
        offset = tuple(float(v) for v in argv[i + 1:i + 4])
        del argv[i:i + 4]
    return argv[0], argv[1], argv[2], offset


def _say(msg):
    sys.stderr.write(msg + "\n")
    sys.stderr.flush()


def _stepped(bake, seed=0):
    """Step ``bake`` to the end; per-probe (render, write_exr, project) seconds.

    Each probe gets its own Cycles seed ``seed * 1000 + i``: the stepper applies one seed in
    ``prepare`` (render_settings.apply_bake_settings), so with it every probe of a sky-only scene
    would render the same noise and a row would hold one noise sample however many probes it has.
    Set on the scene after the stepper's override, before each render."""
    rows = []
    while bake.done < bake.total:
        before = dict(bake.timings)
        bake.scene.cycles.seed = seed * 1000 + bake.done
        bake.scene.update_tag()  # a property change alone does not reach a persistent Cycles session
        bake.step()
        rows.append([bake.timings[k] - before[k] for k in ("render", "write_exr", "project")])
    return rows


# The sweep measures probes against references holding every light (converged bakes, the HDRIs' own
# projections): the sky's sun stays in the probes (Sky Sun "baked", as when the sweep was measured;
# since issue 27 the add-on's default splits it off for the engine to add), unless a job says otherwise.
SWEEP_SETTINGS = {"sky_sun": "baked"}


def _settings(job, output_path):
    return bake_core.BakeSettings(output_path=output_path, **dict(SWEEP_SETTINGS, **job["settings"]))


def run_fixed(job, spec, tmp):
    s = _settings(job, os.path.join(tmp, "fixed.shprobe"))
    pts = {"probes": spec.probes, "samples": spec.samples,
           "both": list(spec.probes) + list(spec.samples)}[job.get("points", "probes")]
    eng = scene_export.blender_to_engine(np.array(pts, dtype=np.float64))
    bake = bake_core.ProbeBake(bpy.context.scene, bpy.context.view_layer, s, mode="CURSOR",
                               cursor=pts[0], log=lambda line: None)
    bake.prepare()
    try:
        # The cursor bake's stepper with our positions: same render settings, camera and projection.
        bake.bake_positions(eng)
        rows = _stepped(bake, s.seed)
        # The lamps added analytically (issue 11; hidden from the camera rays by prepare) join the
        # coefficients in ProbeBake.finish(), which a fixed-position bake does not reach: add them
        # here as finish() does, and report their time (all probes at once) on its own.
        direct = 0.0
        if bake.direct is not None and bake.direct.lamps:
            bake.direct.add_to(bake.coeffs, bake.positions, s.max_band, bake.timings)
            direct = bake.timings["direct"]
        return {"coeffs": bake.coeffs.tolist(), "times": rows, "positions": eng.tolist(),
                "direct_seconds": direct, "analytic_lamps": list(bake.direct.analytic) if bake.direct else [],
                "settings_effective": dataclasses.asdict(s)}
    finally:
        bake.cancel()


def run_placement(job, spec, tmp):
    out = os.path.join(tmp, job["id"] + ".shprobe")
    s = _settings(job, out)
    bake = bake_core.ProbeBake(bpy.context.scene, bpy.context.view_layer, s, log=lambda line: None)
    t0 = time.perf_counter()
    try:
        bake.prepare()
        rows = _stepped(bake, s.seed)
        result = bake.finish()
    except BaseException:
        bake.cancel()
        raise
    f = native.read_shprobe(result.files[0])
    samples = scene_export.blender_to_engine(np.array(spec.samples, dtype=np.float64)) \
        if spec.samples else np.zeros((0, 3))
    idx = f.lookup(samples) if len(samples) else np.zeros(0, dtype=np.int32)
    return {"probe_count": f.probe_count, "grid_dims": list(f.grid_dims),
            "file_bytes": os.path.getsize(result.files[0]), "seconds": time.perf_counter() - t0,
            "placement_seconds": result.timings["placement"], "times": rows,
            "lookup": idx.tolist(),
            "lookup_coeffs": [np.asarray(f.coeffs[i], dtype=np.float64).tolist() if i >= 0 else None
                              for i in idx],
            "lookup_positions": [bake.positions[i].tolist() if i >= 0 else None for i in idx],
            "interp_coeffs": metrics.interpolate_trilinear(f, samples) if len(samples) else []}


def main():
    name, jobs_path, out_path, offset = _args()
    with open(jobs_path, encoding="utf-8") as fh:
        jobs = json.load(fh)
    spec = scenes.build(name, offset)
    tmp = tempfile.mkdtemp(prefix="schnee_sweep_")
    bpy.ops.wm.save_as_mainfile(filepath=os.path.join(tmp, name + ".blend"))
    schnee_probes.register()
    results = {}
    for k, job in enumerate(jobs):
        t = time.perf_counter()
        try:
            fn = run_fixed if job["kind"] == "fixed" else run_placement
            results[job["id"]] = fn(job, spec, tmp)
        except (bake_core.BakeError, native.SchneeError) as exc:
            # Refusals are results too (e.g. a panorama too small for the band).
            results[job["id"]] = {"error": str(exc)}
        _say(f"sweep {name}: job {k + 1}/{len(jobs)} {job['id']} {time.perf_counter() - t:.1f} s")
    doc = {"scene": {"name": name, "hdri": spec.hdri, "offset": list(spec.offset),
                     "probes": scene_export.blender_to_engine(np.array(spec.probes)).tolist(),
                     "samples": scene_export.blender_to_engine(np.array(spec.samples)).tolist()
                     if spec.samples else [],
                     "placement": spec.placement},
           "jobs": results}
    tmp_out = out_path + ".partial"
    with open(tmp_out, "w", encoding="utf-8") as fh:
        json.dump(doc, fh)
    os.replace(tmp_out, out_path)


main()
