"""Placements and interpolations against a reference at points between probes, in real Blender + Cycles.

    blender -b --factory-startup -P bench/bench_placement.py -- OUT.json [--scene room|courtyard|hall] [options]

Builds the scene (bench/placement_scenes.py: the bundled room, the sweep's courtyard, a large hall),
bakes reference probes at --points seeded random points of the volume (not inside solids) at
--ref-samples and a "floor" probe at each point with the bake's own settings, then each placement:
the Adaptive placement (each --tolerance x --tests; its probes interpolated by the corner octree,
the file's structure, and with --tetra also by a Delaunay tetrahedralisation of the same probes),
uniform grids of --uniform cell sizes (corner probes, trilinear; only the probes the points use are
baked, time = all the grid's probes x the measured time per probe) and, with --old / --old-points,
the geometry octree. Error = relative irradiance RMS over
directions and RGB (adaptive.irradiance_error, the refinement's metric) of each placement's
per-object value at the point (v3: the corner octree's interpolation with validity; v1: the grid
cell's probe, as the engine's per-object lookup) against the reference. Writes OUT.json; the
report is bench/results/placement.md (numbers copied by hand with the command line).
"""
import argparse
import dataclasses
import json
import os
import sys
import tempfile
import time

REPO = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
sys.path.insert(0, os.path.join(REPO, "scenes"))
sys.path.insert(0, os.path.join(REPO, "bench"))
sys.path.insert(0, os.path.join(REPO, "addon"))

import bpy  # noqa: E402
import numpy as np  # noqa: E402

import placement_scenes  # noqa: E402
from bench_util import cpu_seconds  # noqa: E402
import schnee_probes  # noqa: E402
from schnee_probes import adaptive, bake_core, native, scene_export  # noqa: E402


def main():
    argv = sys.argv[sys.argv.index("--") + 1:] if "--" in sys.argv else []
    ap = argparse.ArgumentParser()
    ap.add_argument("out")
    ap.add_argument("--scene", default="room", choices=placement_scenes.SCENES)
    ap.add_argument("--seed", type=int, default=2024, help="seed of the evaluation points")
    ap.add_argument("--uniform", type=float, nargs="*", default=[],
                    help="cell sizes (m) of uniform corner grids to compare (trilinear)")
    ap.add_argument("--tetra", action="store_true",
                    help="also interpolate each Adaptive bake's probes by Delaunay tetrahedra")
    ap.add_argument("--res", type=int, default=128)
    ap.add_argument("--samples", type=int, default=32)
    ap.add_argument("--bounces", type=int, default=32)
    ap.add_argument("--min-cell", type=float, default=0.5)
    ap.add_argument("--max-cell", type=float, default=16.0)
    ap.add_argument("--tolerance", type=float, nargs="*", default=[0.05],
                    help="Error Tolerance values of the adaptive bakes (none: only --old)")
    ap.add_argument("--tests", nargs="+", default=["CENTRE_FACES"], choices=["CENTRE_FACES", "CENTRE"],
                    help="Refinement Tests of the adaptive bakes (each tolerance is baked with each)")
    ap.add_argument("--predict", type=float, nargs="+", default=[adaptive.DEFAULT_POLICY.predict],
                    help="adaptive.Policy.predict factors of the adaptive bakes (default: the add-on's; 0 = every "
                         "child tested; each tolerance x tests is baked with each)")
    ap.add_argument("--probe-noise", type=float, nargs="+", default=[adaptive.DEFAULT_POLICY.probe_noise],
                    help="adaptive.Policy.probe_noise of the adaptive bakes: a probe gets samples until its noise "
                         "is below this x Error Tolerance (default: the add-on's; each tolerance x tests x "
                         "predict is baked with each)")
    ap.add_argument("--axes", choices=("on", "off"), nargs="+",
                    default=["on" if adaptive.DEFAULT_POLICY.axes else "off"],
                    help="adaptive.Policy.axes of the adaptive bakes: per-axis splits (on) or the octree's (off); "
                         "both: one row each")
    ap.add_argument("--first-round", type=float, default=adaptive.DEFAULT_POLICY.first_round,
                    help="adaptive.Policy.first_round: each of a point's two first rounds renders this x --samples")
    ap.add_argument("--max-samples", type=float, default=adaptive.DEFAULT_POLICY.max_samples,
                    help="adaptive.Policy.max_samples: the most samples of a point, x --samples (0.5 = the two "
                         "first rounds only, no more rounds)")
    ap.add_argument("--points", type=int, default=64)
    ap.add_argument("--ref-samples", type=int, default=128)
    ap.add_argument("--ref-res", type=int, default=None,
                    help="reference panorama width (default --res): runs at different render "
                         "qualities share one reference with the same --ref-* options")
    ap.add_argument("--ref-bounces", type=int, default=None, help="reference bounces (default --bounces)")
    ap.add_argument("--ref-cache", default=None,
                    help="npz of the references: read when its key (scene, points, seed, --ref-*) matches, "
                         "else baked and written (runs at different qualities share one reference)")
    ap.add_argument("--sun-mode", choices=["baked", "mixed"], default="baked",
                    help="light mode of the scene's Sun lamps (schnee_light_mode): mixed = the probes hold "
                         "their bounced light only and the engine adds their direct light, shadowed; the "
                         "error is then of probe + the exact direct term (shadow-map error not included)")
    ap.add_argument("--old", action="store_true", help="also bake the geometry octree")
    ap.add_argument("--old-points", action="store_true",
                    help="the geometry octree's per-object error without baking all its probes: place it, "
                         "bake only the probes the points look up (the same renders a full bake makes "
                         "there: same settings and seed), time = probes x the measured time per probe")
    ap.add_argument("--keep", default=None, metavar="DIR",
                    help="bake into DIR and keep the files there, with points.npz (the points, engine and "
                         "Blender axes, and the reference) for bench/bench_postprocess.py")
    a = ap.parse_args(argv)

    sc = placement_scenes.build(a.scene)
    schnee_probes.register()
    if a.keep:
        os.makedirs(a.keep, exist_ok=True)
    tmp = a.keep or tempfile.mkdtemp(prefix="bench_placement_")
    scene, layer = bpy.context.scene, bpy.context.view_layer

    def settings(**kw):
        base = dict(min_cell_size=a.min_cell, max_cell_size=a.max_cell, panorama_resolution=a.res,
                    samples=a.samples, max_bounces=a.bounces, capture_sky=False, probe_limit=0,
                    output_path=os.path.join(tmp, "probes.shprobe"))
        base.update(kw)
        return bake_core.BakeSettings(**base)

    # Seeded points in the volume, outside the solids (placement_scenes.points; the room keeps the
    # points of the first run of this benchmark).
    blender_pts = np.array(placement_scenes.points(sc, a.points, a.seed))
    engine_pts = scene_export.blender_to_engine(blender_pts)

    # Mixed suns: what a moving object gets is the probes' value plus the engine's direct term,
    # which per pixel with shadow maps is the sun's exact shadowed direct light (direct_light's
    # projection, the one a baked sun adds to the probes). It is added to every value compared.
    direct = 0.0
    for ob in scene.objects:  # explicit either way: a Sun lamp's default is mixed (light_modes.py)
        if ob.type == 'LIGHT' and ob.data.type == 'SUN':
            ob["schnee_light_mode"] = a.sun_mode
    if a.sun_mode == "mixed":
        b = bake_core.ProbeBake(scene, layer, settings(), log=lambda s: None)
        b.prepare()
        direct = b.plan.lamps.engine_at(engine_pts)
        b.cancel()
        if direct is None:
            sys.exit("bench_placement: --sun-mode mixed but the scene has no Sun lamp added analytically")

    def error(got):
        return adaptive.irradiance_error(got + direct, ref + direct)

    out = {"settings": vars(a), "rows": [], "load_start": os.getloadavg()}
    t = time.perf_counter()
    ref_key = json.dumps([a.scene, a.points, a.seed, a.ref_samples, a.ref_res or a.res, a.ref_bounces or a.bounces]
                         + ([a.sun_mode] if a.sun_mode != "baked" else []))
    cached = np.load(a.ref_cache) if a.ref_cache and os.path.exists(a.ref_cache) else None
    if cached is not None and str(cached["key"]) == ref_key:
        ref = cached["ref"]
        out["reference_cached"] = a.ref_cache
    else:
        ref = bake_core.bake_points(scene, layer, settings(samples=a.ref_samples, panorama_resolution=a.ref_res or a.res,
                                                           max_bounces=a.ref_bounces or a.bounces),
                                    engine_pts, log=lambda s: None)
        if a.ref_cache:
            np.savez(a.ref_cache, key=ref_key, ref=ref)
    out["reference_seconds"] = time.perf_counter() - t
    if a.keep:
        np.savez(os.path.join(a.keep, "points.npz"), engine=engine_pts, blender=blender_pts, ref=ref,
                 direct=np.asarray(direct), key=ref_key)
    floor = bake_core.bake_points(scene, layer, settings(), engine_pts, log=lambda s: None)
    out["floor"] = stats(error(floor))
    out["floor_point_errors"] = [round(float(e), 5) for e in error(floor)]
    out["points_blender"] = blender_pts.round(4).tolist()

    for tol, tests, pred, pn, axes in [(tol, tests, pred, pn, axes) for tol in a.tolerance for tests in a.tests
                                       for pred in a.predict for pn in a.probe_noise for axes in a.axes]:
        path = os.path.join(tmp, f"adaptive_{tol:g}_{tests}_{pred:g}_{pn:g}_{axes}.shprobe")
        policy = dataclasses.replace(adaptive.DEFAULT_POLICY, predict=pred, probe_noise=pn,
                                     max_samples=a.max_samples, first_round=a.first_round, axes=axes == "on")
        b = bake_core.ProbeBake(scene, layer, settings(placement="ADAPTIVE", error_tolerance=tol,
                                                       refinement_tests=tests, output_path=path), log=print,
                                policy=policy)
        t, cpu = time.perf_counter(), cpu_seconds()
        r = b.run()
        sec, cpu = time.perf_counter() - t, cpu_seconds() - cpu
        f = native.read_shprobe(path)
        got = native.interpolation_from_file(path).interpolate(engine_pts, f.coeffs, f.validity)
        err = error(got)
        cache = b.plan.cache
        kept = np.zeros(len(cache), dtype=bool)
        kept[np.concatenate([g.probe_index for g in b.plan.groups])] = True
        dropped = cache.rendered & ~kept
        out["rows"].append({"placement": "adaptive", "tolerance": tol, "tests": tests, "predict": pred,
                            "probe_noise": pn, "max_samples": a.max_samples, "first_round": a.first_round,
                            "axes": axes == "on", "leaves": int(sum(g.tree.leaf_count for g in b.plan.groups)),
                            "forced_splits": int(sum(getattr(g.tree, "forced_splits", 0) for g in b.plan.groups)),
                            "file_version": int(f.version), "seconds": sec,
                            "forecast": None if b.plan.first_forecast is None else
                            {"points": round(b.plan.first_forecast[0], 1),
                             "seconds": round(b.plan.first_forecast[1], 1)},
                            "forecasts": b.plan.forecasts,
                            "cpu_seconds": cpu,
                            "probes": r.probe_count, "render_seconds": r.timings["render"],
                            "timings": {k: round(v, 2) for k, v in r.timings.items()},
                            "renders": r.renders, "points": int(cache.rendered.sum()),
                            "nodes": cache.node_count, "samples": r.samples,
                            "dropped_points": int(dropped.sum()), "dropped_samples": int(cache.samples[dropped].sum()),
                            "samples_per_point": np.bincount(cache.samples[cache.rendered].astype(int)).tolist(),
                            "passes": [vars(p) for p in r.passes],
                            "file_bytes": os.path.getsize(path), "error": stats(err),
                            "point_errors": [round(float(e), 5) for e in err]})
        print("ROW", json.dumps(out["rows"][-1]), flush=True)
        if a.tetra:
            # The same probes, interpolated by a Delaunay tetrahedralisation of the valid ones.
            pos = native.interpolation_from_file(path).positions()
            keep = np.asarray(f.validity) > 0
            tet = native.Tetrahedra.create(pos[keep])
            got_t = tet.interpolate(engine_pts, np.asarray(f.coeffs)[keep])
            err_t = error(got_t)
            out["rows"].append({"placement": "adaptive", "interpolation": "tetrahedra", "tolerance": tol,
                                "tests": tests, "predict": pred, "probe_noise": pn, "probes": int(keep.sum()),
                                "renders": r.renders,
                                "cpu_seconds": cpu, "seconds": sec, "error": stats(err_t),
                                "point_errors": [round(float(e), 5) for e in err_t]})
            print("ROW", json.dumps(out["rows"][-1]), flush=True)
    for cell in a.uniform:
        # A uniform grid of corner probes: the Adaptive placement's first layer with Min = Max Cell
        # Size (same lattice rules, same solid test, same render positions), never refined.
        b = bake_core.ProbeBake(scene, layer, settings(placement="ADAPTIVE", min_cell_size=cell,
                                                       max_cell_size=cell), log=lambda s: None)
        b.prepare()
        group, cache = b.plan.groups[0], b.plan.cache
        pidx = group.probe_index
        validity = cache.validity(pidx)
        probes, w = group.tree.query(engine_pts, validity)
        need = np.unique(probes[(w > 0) & (probes >= 0)])
        count = int((validity > 0).sum())
        b.cancel()
        t, cpu = time.perf_counter(), cpu_seconds()
        vals = np.zeros((len(pidx),) + ref.shape[1:])
        vals[need] = bake_core.bake_points(scene, layer, settings(), cache.positions[pidx[need]], log=lambda s: None)
        sec, cpu = time.perf_counter() - t, cpu_seconds() - cpu
        got = group.tree.interpolate(engine_pts, vals, validity)
        err = error(got)
        out["rows"].append({"placement": f"uniform grid {cell:g} m", "interpolation": "trilinear",
                            "probes": count, "renders": count, "baked": int(len(need)),
                            "seconds_estimate": count * sec / max(1, len(need)),
                            "cpu_seconds_estimate": count * cpu / max(1, len(need)),
                            "error": stats(err), "point_errors": [round(float(e), 5) for e in err]})
        print("ROW", json.dumps(out["rows"][-1]), flush=True)
    if a.old:
        path = os.path.join(tmp, "octree.shprobe")
        b = bake_core.ProbeBake(scene, layer, settings(placement="OCTREE", output_path=path), log=print)
        t, cpu = time.perf_counter(), cpu_seconds()
        r = b.run()
        sec, cpu = time.perf_counter() - t, cpu_seconds() - cpu
        f = native.read_shprobe(path)
        idx = f.lookup(engine_pts)
        got = f.coeffs[np.maximum(idx, 0)]
        out["rows"].append({"placement": "geometry octree", "seconds": sec, "cpu_seconds": cpu,
                            "probes": r.probe_count, "render_seconds": r.timings["render"],
                            "renders": r.renders or r.probe_count, "file_bytes": os.path.getsize(path),
                            "error": stats(error(got))})
        print("ROW", json.dumps(out["rows"][-1]), flush=True)
    if a.old_points:
        b = bake_core.ProbeBake(scene, layer, settings(placement="OCTREE"), log=print)
        t0 = time.perf_counter()
        b.prepare()
        place_s = time.perf_counter() - t0
        tg = b.targets[0]
        cell = np.floor((engine_pts - np.array(tg.grid_origin)) / tg.grid_spacing).astype(int)
        X, Y, Z = tg.grid_dims
        probe = tg.grid[cell[:, 0] + cell[:, 1] * X + cell[:, 2] * X * Y]
        assert (probe >= 0).all()
        pos = b.positions[tg.probe_render_index[probe]]
        count = len(b.positions)
        b.cancel()
        uniq, inv = np.unique(pos, axis=0, return_inverse=True)
        t, cpu = time.perf_counter(), cpu_seconds()
        vals = bake_core.bake_points(scene, layer, settings(), uniq, log=lambda s: None)
        sec, cpu = time.perf_counter() - t, cpu_seconds() - cpu
        got = vals[inv.reshape(-1)]
        out["rows"].append({"placement": "geometry octree (probes at the points baked)", "probes": count,
                            "renders": count, "placement_seconds": place_s,
                            "seconds_estimate": place_s + count * sec / len(uniq),
                            "cpu_seconds_estimate": count * cpu / len(uniq), "baked": len(uniq),
                            "error": stats(error(got))})
        print("ROW", json.dumps(out["rows"][-1]), flush=True)
    out["scene"] = a.scene
    out["load_end"] = os.getloadavg()
    with open(a.out, "w", encoding="utf-8") as fh:
        json.dump(out, fh, indent=1)
    print("WROTE", a.out)


def stats(e):
    """Error statistics; a point no probe covers (NaN: every corner invalid) counts as 100 %."""
    e = np.asarray(e, dtype=float)
    missing = int(np.isnan(e).sum())
    e = np.where(np.isnan(e), 1.0, e)
    return {"mean": float(e.mean()), "median": float(np.median(e)), "p90": float(np.percentile(e, 90)),
            "max": float(e.max()), "n": int(len(e)), "uncovered": missing}


if __name__ == "__main__":
    main()
