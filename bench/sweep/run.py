#!/usr/bin/python3
"""Speed-accuracy sweep of the probe bake: one command regenerates the report (or some of its scenes).

    /usr/bin/python3 bench/sweep/run.py --full      # run time: bench/results/sweep.md
    /usr/bin/python3 bench/sweep/run.py --full --scenes sun_yard sun_window   # some scenes, merged
    /usr/bin/python3 bench/sweep/run.py --full --no-placement --scenes interior courtyard   # no placement study
    /usr/bin/python3 bench/sweep/run.py --analyse-only --workdir DIR   # report from kept raw output

With --scenes, only those scenes are baked; their analysis replaces theirs in the existing
bench/results/sweep.json and every other scene's figures (and the far/sun extremes) are kept from
it, so the report is regenerated whole without re-running them. --no-placement leaves out the
placement study of interior and courtyard (its sample points' references, the 10 km test: the most
expensive jobs); merged with --scenes, the earlier run's placement figures are kept and marked. sweep.json records each run
(``runs``: command, scenes, seconds, date).

Writes bench/results/sweep.md (tables, Pareto fronts, recommendations), sweep.png (error against
bake time) and sweep.json (every measured figure plus the reference coefficients, which the reduced
sweep in tests/bench/test_sweep_reduced.py compares against). Each scene is baked by one headless
Blender running bench/sweep/worker.py through the add-on's own stepper (bake_core.ProbeBake).

References (how each is obtained):
- sky-only scenes: exact, the HDRI file itself projected natively (negative="allow": the bundled
  HDRIs hold tiny negative texels);
- interior and courtyard: two bakes far above the sweep (256x128, 128 spp, 32 bounces, no clamping)
  with Cycles seeds 1 and 2; their mean is the reference, their disagreement is reported and checked
  against REF_TOL. The reference has the sweep's highest resolution, so these scenes sweep
  resolution only up to 128x64 (a 256x128 row would share the reference's resolution bias):
  resolution bias beyond 256x128 is not measured there;
- the 1e5 sun: the HDRI's projection plus the sphere's analytic projection, per probe;
- sun_yard and sun_window (issue 11: a Sun lamp plus a sky with a sun, outdoors and through a
  window): like interior and courtyard, two converged bakes checked against REF_TOL (no sample
  points' reference: their placement study is not run). Their sweep rows (sun_rows()) are the
  shipped defaults and cheaper rows around CENTRE32. The lamp is added analytically (hidden from
  camera rays); worker.py adds it after the renders as ProbeBake.finish() does, and its time per
  probe is in s/probe (column *direct*).

Noise: worker.py gives every probe its own Cycles seed (seed * 1000 + probe index), so a row's
error is a mean over independent noise samples; the report gives mean +- std over the probes.
"""
import argparse
import json
import math
import os
import subprocess
import sys
import tempfile
import time

import numpy as np

HERE = os.path.dirname(os.path.abspath(__file__))
REPO = os.path.dirname(os.path.dirname(HERE))
RESULTS = os.path.join(REPO, "bench", "results")
sys.path.insert(0, HERE)
import metrics  # noqa: E402
from metrics import native  # noqa: E402

STUDIOLIGHTS = "/usr/share/blender/datafiles/studiolights/world"
BLENDER_TO_ENGINE = np.array([[1.0, 0, 0], [0, 0, 1.0], [0, -1.0, 0]])

# The sweep's centre (the documented defaults before this sweep) and the reference quality.
BASE = dict(panorama_resolution=128, samples=64, max_bounces=12, clamp_indirect=10.0,
            pixel_filter="BOX", filter_width=1.0)
REF = dict(panorama_resolution=256, samples=128, max_bounces=32, clamp_indirect=0.0,
           pixel_filter="BOX", filter_width=1.0)
# Reference at the placement study's 32 sample points: a quarter of REF's samples (32 points x 2
# seeds at full REF quality would take ~17 min in the room); placement errors are several percent,
# its convergence is reported and checked against REF_TOL_SAMPLES.
REF_SAMPLES = dict(REF, samples=32)
# The interior and courtyard sweep resolution, samples and filter around a 32-bounce centre (at 12
# bounces the room's ~6 % bounce bias hides their effect); bounces are their own series.
CENTRE32 = dict(BASE, max_bounces=32)
BOUNCE_SERIES = (2, 4, 8, 12, 16, 24)
# The reference bakes (mean of seeds 1 and 2) must agree with the truth to this relative RMS at
# L = 2, estimated as half their disagreement (mean of two independent estimates: its noise is
# 1/sqrt(2) of one, their difference sqrt(2) of one). Well below the smallest interior/courtyard
# errors the report compares (the shipped defaults': 0.4-3 %).
REF_TOL = 0.0025
REF_TOL_SAMPLES = 0.005
# Render quality of the placement study (every placed probe is baked; per-probe noise at this
# quality is measured in the same run at the exact sample points).
PLACE = dict(panorama_resolution=64, samples=32, max_bounces=12)
SYNC_RES = (32, 64, 128, 256)


def row(label, centre=BASE, **kw):
    s = dict(centre)
    s.update(kw)
    return label, s


def render_rows(bounces=True):
    """Sky scenes (bounces=False): around BASE, resolution up to 256x128 (exact reference).
    Interior/courtyard: around CENTRE32, resolution up to 128x64 (the reference's own resolution
    is 256x128), plus the bounce series at 128x64, 64 spp."""
    c = CENTRE32 if bounces else BASE
    rows = [row(f"base 128x64 64spp {c['max_bounces']}b", c)]
    rows += [row(f"res {r}x{r // 2}", c, panorama_resolution=r) for r in ((32, 64) if bounces else (32, 64, 256))]
    rows += [row(f"{n} spp", c, samples=n) for n in (8, 16, 32, 128)]
    if bounces:
        rows += [row(f"{b} bounces", c, max_bounces=b) for b in BOUNCE_SERIES]
        rows += [row("clamp indirect off", c, clamp_indirect=0.0)]
    rows += [row("Blackman-Harris 1.5 px", c, pixel_filter="BLACKMAN_HARRIS", filter_width=1.5)]
    combos = [(32, 16, 4), (64, 16, 4), (64, 16, 8), (64, 32, 12), (128, 32, 8), (128, 32, 16),
              (64, 64, 16), (128, 16, 12)]
    rows += [row(f"{r}x{r // 2} {n}spp {b}b", panorama_resolution=r, samples=n, max_bounces=b)
             for r, n, b in combos]
    return rows


def sun_rows():
    """sun_yard / sun_window: the shipped defaults' neighbourhood and cheaper rows, around CENTRE32
    (resolution up to 128x64: the reference is 256x128)."""
    c = CENTRE32
    rows = [row("base 128x64 64spp 32b", c)]
    rows += [row(f"res {r}x{r // 2}", c, panorama_resolution=r) for r in (32, 64)]
    rows += [row(f"{n} spp", c, samples=n) for n in (8, 16, 32, 128)]
    rows += [row(f"{b} bounces", c, max_bounces=b) for b in (4, 8, 16)]
    combos = [(64, 8, 8), (64, 16, 8), (64, 32, 16), (128, 8, 8), (128, 8, 16), (128, 16, 16),
              (128, 32, 8), (128, 32, 16)]
    rows += [row(f"{r}x{r // 2} {n}spp {b}b", panorama_resolution=r, samples=n, max_bounces=b)
             for r, n, b in combos]
    return rows


def fixed(jid, settings, points="probes", band=4, seed=0):
    s = dict(settings)
    s.update(max_band=band, seed=seed)
    return {"id": jid, "kind": "fixed", "points": points, "settings": s}


def sweep_jobs(rows):
    jobs = [fixed("row:" + label, s) for label, s in rows]
    jobs.append(fixed("row:defaults", {}))  # bake_core.BakeSettings() as shipped
    jobs += [fixed(f"sync:{r}", dict(BASE, panorama_resolution=r, samples=1)) for r in SYNC_RES]
    return jobs


def ref_jobs(samples=True):
    return ([fixed(f"ref:{seed}", REF, points="probes", seed=seed) for seed in (1, 2)]
            + ([fixed(f"refs:{seed}", REF_SAMPLES, points="samples", seed=seed) for seed in (1, 2)]
               if samples else []))


def placement_jobs(configs):
    jobs = [fixed("place:exact", PLACE, points="samples", band=2)]
    for mn, mx in configs:
        # The study's placements are the geometry octree (issue 12 made Adaptive the default; its
        # version-3 corner octree has no dense grid for the lookup and trilinear mirror below).
        s = dict(PLACE, min_cell_size=mn, max_cell_size=mx, max_band=2, placement="GEOMETRY_OCTREE")
        jobs.append({"id": f"place:{mn:g}/{mx:g}", "kind": "placement", "settings": s})
    return jobs


PLACEMENT_JOBS = ("place:", "refs:", "far:")  # the placement study, its references, the 10 km test


def plan(full=True, placement=True):
    """{scene: (offset, jobs)} of the full sweep (the reduced one lives in the test). placement=False
    leaves out the placement study, its sample points' references and the 10 km test (PLACEMENT_JOBS;
    merge() then keeps the earlier run's figures of those)."""
    p = _plan()
    if not placement:
        p = {k: (off, [j for j in jobs if not j["id"].startswith(PLACEMENT_JOBS)])
             for k, (off, jobs) in p.items() if k != "interior_10km"}
    return p


def _plan():
    p = {}
    p["sky_courtyard"] = ((0, 0, 0), sweep_jobs(render_rows(bounces=False)) + [
        fixed(f"tiny:{r}:L{b}", dict(BASE, panorama_resolution=r, samples=64), band=b)
        for r, b in ((8, 0), (8, 1), (8, 2), (16, 3), (16, 4), (20, 4))])
    p["sky_forest"] = ((0, 0, 0), sweep_jobs(render_rows(bounces=False)))
    p["sun"] = ((0, 0, 0), [fixed("row:defaults", {}),
                            fixed("row:res 128x64 64spp", dict(BASE, panorama_resolution=128)),
                            fixed("row:res 256x128 64spp", dict(BASE, panorama_resolution=256))])
    p["interior"] = ((0, 0, 0), sweep_jobs(render_rows()) + ref_jobs()
                     + placement_jobs([(1.0, 1.0), (1.0, 4.0), (2.0, 2.0)])
                     + [fixed("far:seed0", PLACE), fixed("far:seed1", PLACE, seed=1)])
    p["interior_10km"] = ((10000.0, 0, 0), [fixed("far:seed0", PLACE),
                                            placement_jobs([(1.0, 4.0)])[1]])
    p["courtyard"] = ((0, 0, 0), sweep_jobs(render_rows()) + ref_jobs()
                      + placement_jobs([(1.0, 1.0), (1.0, 2.0), (1.0, 4.0), (2.0, 2.0), (2.0, 8.0),
                                        (0.5, 16.0)]))  # 0.5/16 m: the shipped placement
    # Issue 11: a Sun lamp plus a sky with a sun, outdoors and through a window.
    p["sun_yard"] = ((0, 0, 0), sweep_jobs(sun_rows()) + ref_jobs(samples=False))
    p["sun_window"] = ((0, 0, 0), sweep_jobs(sun_rows()) + ref_jobs(samples=False))
    return p


def run_scene(scene, offset, jobs, workdir, log=print):
    """Bake ``jobs`` on ``scene`` in one headless Blender; returns the worker's document."""
    base = scene.replace("_10km", "")
    jobs_path = os.path.join(workdir, f"{scene}.jobs.json")
    out_path = os.path.join(workdir, f"{scene}.out.json")
    with open(jobs_path, "w", encoding="utf-8") as fh:
        json.dump(jobs, fh)
    cmd = ["blender", "-b", "--factory-startup", "--python-exit-code", "1", "-P",
           os.path.join(HERE, "worker.py"), "--", base, jobs_path, out_path,
           "--offset", *[str(v) for v in offset]]
    t = time.perf_counter()
    proc = subprocess.Popen(cmd, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True)
    tail = []
    for line in proc.stderr:
        tail = (tail + [line])[-40:]
        if line.startswith("sweep "):
            log(line.rstrip())
    if proc.wait() != 0:
        raise RuntimeError(f"worker failed on {scene} ({' '.join(cmd)}):\n{''.join(tail)}")
    seconds = time.perf_counter() - t
    log(f"{scene}: {len(jobs)} jobs in {seconds:.0f} s")
    with open(out_path, encoding="utf-8") as fh:
        doc = json.load(fh)
    doc["seconds"] = seconds
    with open(out_path, "w", encoding="utf-8") as fh:  # kept for --analyse-only
        json.dump(doc, fh)
    return doc


# ---------------------------------------------------------------- analysis

def hdri_ref(name):
    return native.project_file(os.path.join(STUDIOLIGHTS, name), 4, negative="allow")


def sun_ref():
    import importlib.util  # scenes.py needs bpy; read its constants without importing Blender
    consts = {}
    src = open(os.path.join(HERE, "scenes.py"), encoding="utf-8").read()
    for key in ("SUN_RADIANCE", "SUN_RADIUS", "SUN_CENTRE", "SUN_PROBE", "SUN_PROBE2"):
        line = next(l for l in src.splitlines() if l.startswith(key + " "))
        consts[key] = eval(line.split("=", 1)[1].split("#")[0])  # noqa: S307 (our own constants)
    del importlib
    sky = hdri_ref("courtyard.exr")
    out = []
    for probe in (consts["SUN_PROBE"], consts["SUN_PROBE2"]):  # the scene's probes, in order
        d = np.subtract(consts["SUN_CENTRE"], probe)
        dist = float(np.linalg.norm(d))
        omega = 2 * math.pi * (1 - math.sqrt(1 - (consts["SUN_RADIUS"] / dist) ** 2))
        out.append((BLENDER_TO_ENGINE @ (d / dist), omega))
    return sky, consts["SUN_RADIANCE"], out


def probe_times(res):
    """Per-probe (render, write_exr, project) means, the first probe (scene upload) left out."""
    t = np.asarray(res["times"], dtype=np.float64)
    t = t[1:] if len(t) > 1 else t
    return t.mean(axis=0)


def timing(res, sync_by_res, settings):
    render, write, proj = probe_times(res)
    # The analytic lamps (issue 11), added for all probes at once after the renders.
    direct = float(res.get("direct_seconds", 0.0)) / max(len(res["times"]), 1)
    sync = sync_by_res.get(settings.get("panorama_resolution", 128))
    n = settings.get("samples", 64)
    if sync is None:
        sync_s = float("nan")
    else:
        # 1-spp render = sync + one sample of tracing (bench_bake.py's split).
        sync_s = max(0.0, sync - (render - sync) / max(n - 1, 1))
    first = res["times"][0]
    return {"s_per_probe": render + write + proj + direct, "render": render, "sync": sync_s,
            "direct_lamps": direct,
            "trace": render - sync_s, "exr_write": write, "projection": proj,
            "exr_and_projection": write + proj,
            # The first probe also uploads the scene (Persistent Data keeps it for the rest).
            "first_probe": float(sum(first)) + direct,
            "first_probe_setup": float(sum(first)) - (render + write + proj)}


def analyse(docs):
    """Every figure of the report from the workers' documents."""
    out = {"scenes": {}, "settings": {"base": BASE, "centre32": CENTRE32, "reference": REF,
                                      "placement": PLACE, "ref_tol": REF_TOL,
                                      "reference_samples": REF_SAMPLES, "ref_tol_samples": REF_TOL_SAMPLES}}
    for scene, doc in docs.items():
        jobs = doc["jobs"]
        sc = {"spec": doc["scene"], "rows": [], "placement": [], "notes": {}}
        out["scenes"][scene] = sc
        # References.
        if scene.startswith("sky_"):
            r = hdri_ref(doc["scene"]["hdri"])
            n = len(doc["scene"]["probes"])
            refs = {"probes": np.repeat(r[None], n, axis=0), "samples": None}
            sc["reference"] = f"exact: native.project_file({doc['scene']['hdri']}, L=4)"
        elif scene == "sun":
            sky, rad, per_probe = sun_ref()
            refs = {"probes": np.array([metrics.sun_reference(sky, rad, d, om) for d, om in per_probe]),
                    "samples": None}
            d, omega = per_probe[0]
            sc["reference"] = (f"analytic per probe: courtyard.exr projection + {rad:g} x "
                               + " / ".join(f"{om:.3e}" for _, om in per_probe) + " sr sphere")
            sc["sun"] = {"radiance": rad, "solid_angle": omega, "direction_engine": d.tolist()}
        elif "ref:1" in jobs:
            a, b = (np.asarray(jobs[f"ref:{s}"]["coeffs"]) for s in (1, 2))
            refs = {"probes": (a + b) / 2, "samples": None}
            if "refs:1" in jobs:
                sa, sb = (np.asarray(jobs[f"refs:{s}"]["coeffs"]) for s in (1, 2))
                refs["samples"] = (sa + sb) / 2
                sconv = [metrics.errors(sa[i], sb[i], 2)[0] for i in range(len(sa))]
                sc["ref_samples_convergence"] = {
                    "settings": REF_SAMPLES, "seed1_vs_seed2_rel_rms_mean": float(np.mean(sconv)),
                    "seed1_vs_seed2_rel_rms_max": float(np.max(sconv)),
                    "estimated_error": float(np.mean(sconv)) / 2, "tolerance": REF_TOL_SAMPLES,
                    "pass": bool(float(np.mean(sconv)) / 2 <= REF_TOL_SAMPLES),
                    "seconds_per_probe": float(probe_times(jobs["refs:1"]).sum())}
            conv = [metrics.errors(a[i], b[i], 2) for i in range(len(a))]
            est = float(np.mean([c[0] for c in conv])) / 2
            sc["reference"] = "mean of two bakes (256x128, 128 spp, 32 bounces, clamp off), seeds 1 and 2"
            sc["ref_convergence"] = {"seed1_vs_seed2_rel_rms_mean": float(np.mean([c[0] for c in conv])),
                                     "seed1_vs_seed2_rel_rms_max": float(np.max([c[0] for c in conv])),
                                     "seed1_vs_seed2_rel_max_max": float(np.max([c[1] for c in conv])),
                                     "seconds_per_probe": float(probe_times(jobs["ref:1"]).sum()),
                                     "estimated_error": est, "tolerance": REF_TOL,
                                     "pass": bool(est <= REF_TOL)}
            sc["reference_coeffs"] = {"probes": refs["probes"].tolist(),
                                      "samples": None if refs["samples"] is None else refs["samples"].tolist(),
                                      "seed1": a.tolist(), "seed2": b.tolist()}
            if jobs["ref:1"].get("analytic_lamps"):
                sc["reference"] += "; lamps added analytically: " + ", ".join(jobs["ref:1"]["analytic_lamps"])
        else:
            refs = None
        if scene.startswith("sky_") or scene == "sun":
            sc["reference_coeffs"] = {"probes": refs["probes"].tolist()}
        sync_by_res = {}
        for jid, res in jobs.items():
            if jid.startswith("sync:") and "error" not in res:
                sync_by_res[int(jid[5:])] = float(probe_times(res)[0])
        sc["sync_1spp"] = sync_by_res
        for jid, res in jobs.items():
            if not (jid.startswith("row:") or jid.startswith("tiny:")):
                continue
            label = jid.split(":", 1)[1]
            entry = {"label": label, "id": jid}
            if "error" in res:
                entry["refused"] = res["error"]
                sc["rows"].append(entry)
                continue
            settings = res.get("settings_effective") or {}
            entry["settings"] = settings
            c = np.asarray(res["coeffs"])
            band = int(math.isqrt(c.shape[1]) - 1)
            entry.update(timing(res, sync_by_res, settings))
            entry["coeffs_probe0"] = c[0].tolist()
            if refs is not None:
                per = {}
                for L in range(band + 1):
                    errs = [metrics.errors(c[i], refs["probes"][i], L) for i in range(len(c))]
                    per[L] = {"rel_rms": float(np.mean([e[0] for e in errs])),
                              # spread over the probes (each its own seed); 0 with one probe
                              "rel_rms_std": float(np.std([e[0] for e in errs], ddof=1)) if len(errs) > 1 else 0.0,
                              "rel_max": float(np.max([e[1] for e in errs]))}
                entry["errors"] = per
                if band == 4:
                    # Band truncation: the bake at L against the reference's L=4 irradiance.
                    entry["vs_L4"] = {L: float(np.mean([metrics.errors_vs_values(
                        c[i], L, metrics.irradiance(refs["probes"][i], 4))[0] for i in range(len(c))]))
                        for L in range(5)}
            sc["rows"].append(entry)
        # Placement study.
        if refs is not None and refs.get("samples") is not None and "place:exact" in jobs:
            ref_s = refs["samples"]
            ex = np.asarray(jobs["place:exact"]["coeffs"])
            ex_err = [metrics.errors(ex[i], ref_s[i], 2) for i in range(len(ex))]
            sc["placement_exact"] = {"rel_rms_mean": float(np.mean([e[0] for e in ex_err])),
                                     "per_point": [e[0] for e in ex_err]}
            for jid, res in jobs.items():
                if not jid.startswith("place:") or jid == "place:exact":
                    continue
                mn, mx = (float(v) for v in jid[6:].split("/"))
                errs = [metrics.errors(np.asarray(cf), ref_s[i], 2) if cf is not None else (math.nan, math.nan)
                        for i, cf in enumerate(res["lookup_coeffs"])]
                dist = [float(np.linalg.norm(np.subtract(p, doc["scene"]["samples"][i]))) if p else math.nan
                        for i, p in enumerate(res["lookup_positions"])]
                # Per-pixel mode of the engine (trilinear between probes) at the same points.
                ierrs = [metrics.errors(np.asarray(cf), ref_s[i], 2) if cf is not None else (math.nan, math.nan)
                         for i, cf in enumerate(res.get("interp_coeffs", []))]
                t = np.asarray(res["times"])
                sc["placement"].append({
                    "min": mn, "max": mx, "kind": "uniform grid" if mn == mx else "octree",
                    "probes": res["probe_count"], "grid": res["grid_dims"], "file_bytes": res["file_bytes"],
                    "bake_seconds": float(t.sum()), "placement_seconds": res["placement_seconds"],
                    "rel_rms_mean": float(np.nanmean([e[0] for e in errs])),
                    "rel_rms_max": float(np.nanmax([e[0] for e in errs])),
                    "rel_max_max": float(np.nanmax([e[1] for e in errs])),
                    "per_point": [e[0] for e in errs], "probe_distance": dist,
                    "interp_rel_rms_mean": float(np.nanmean([e[0] for e in ierrs])) if ierrs else math.nan,
                    "interp_rel_rms_max": float(np.nanmax([e[0] for e in ierrs])) if ierrs else math.nan})
        if "far:seed0" in jobs:
            sc["far"] = {k: jobs[k]["coeffs"] for k in ("far:seed0", "far:seed1") if k in jobs}
            for jid, res in jobs.items():
                if jid.startswith("place:") and "probe_count" in res:
                    sc["far_placement"] = {"probes": res["probe_count"], "grid": res["grid_dims"]}
    _far(out)
    _sun(out)
    return out


def _far(out):
    """10 km test: the same probes baked at the origin (seeds 0, 1) and 10 km away (seed 0)."""
    sc, far = out["scenes"].get("interior"), out["scenes"].get("interior_10km")
    if not sc or not far or "far" not in sc or "far" not in far:
        return
    a, b = (np.asarray(sc["far"][k]) for k in ("far:seed0", "far:seed1"))
    f = np.asarray(far["far"]["far:seed0"])
    noise = [metrics.errors(a[i], b[i], 2)[0] for i in range(len(a))]
    shift = [metrics.errors(f[i], a[i], 2)[0] for i in range(len(a))]
    res = {"origin_seed0_vs_seed1": noise, "far_vs_origin_seed0": shift,
           "placement_origin": next((p for p in sc["placement"] if p["min"] == 1 and p["max"] == 4), None),
           "placement_far": far.get("far_placement")}
    if res["placement_origin"]:
        res["placement_origin"] = {"probes": res["placement_origin"]["probes"],
                                   "grid": res["placement_origin"]["grid"]}
    out["far"] = res


def _sun(out):
    """1e5 sun: bake vs analytic at L=2 and L=4, and ringing at L=4 with and without windows."""
    sc = out["scenes"].get("sun")
    if not sc:
        return
    s = sc["sun"]
    sky = hdri_ref("courtyard.exr")
    true_e = metrics.sun_true_irradiance(sky, s["radiance"], s["direction_engine"], s["solid_angle"])
    ref = np.asarray(sc["reference_coeffs"]["probes"][0])
    rows = []
    dense = metrics.fibonacci_sphere(20000)
    for label, c in [("analytic SH", ref)] + [(r["label"], np.asarray(r.get("coeffs_probe0")))
                                             for r in sc["rows"] if r.get("coeffs_probe0") is not None]:
        for L in (2, 4):
            for kind in ("none", "sinc4", "laplacian"):
                if L == 2 and kind != "none":
                    continue
                cw = metrics.truncate(c, L)
                if kind != "none":
                    cw, _ = native.window(cw, kind)
                e_min = float(native.irradiance(cw, dense).min())
                rms, mx = metrics.errors_vs_values(cw, L, true_e)
                rows.append({"source": label, "band": L, "window": kind, "min_irradiance": e_min,
                             "rel_rms_vs_true": rms, "rel_max_vs_true": mx})
    out["sun"] = {"rows": rows, "true_peak": float(true_e.max()), "true_min": float(true_e.min())}


# ---------------------------------------------------------------- report

def shprobe_bytes():
    """Bytes per probe and header+grid size of a .shprobe for each band (written for real)."""
    out = {}
    with tempfile.TemporaryDirectory() as tmp:
        for L in range(5):
            sizes = []
            for n in (1, 2):
                p = os.path.join(tmp, f"b{L}_{n}.shprobe")
                grid = np.arange(n, dtype=np.int32)
                native.write_shprobe(p, np.zeros((n, (L + 1) ** 2, 3), np.float32), grid, (n, 1, 1),
                                     (0, 0, 0), 1.0)
                sizes.append(os.path.getsize(p))
            out[L] = {"per_probe": sizes[1] - sizes[0] - 4, "version": native.read_shprobe(p).version}
    return out


def merge(result, old):
    """``result`` (some scenes) merged into ``old`` (a previous sweep.json): the scenes run now
    replace theirs, every other scene, the extremes computed from scenes not run now (far, sun) and
    the earlier runs are kept. Returns the merged document (JSON types: keys are strings)."""
    new = json.loads(json.dumps(result, default=float))
    out = dict(old)
    out["scenes"] = dict(old.get("scenes", {}))
    out["scenes"].update(new["scenes"])
    # A scene re-run with --no-placement keeps the earlier run's placement study (its sample points'
    # reference and the 10 km test's origin bakes), marked with the run that measured it.
    carried = {}
    for name, sc in new["scenes"].items():
        prev = old.get("scenes", {}).get(name) or {}
        if sc.get("placement") or not prev.get("placement"):
            continue
        for k in ("placement", "placement_exact", "ref_samples_convergence", "far", "far_placement"):
            if k in prev:
                sc[k] = prev[k]
        if (prev.get("reference_coeffs") or {}).get("samples") is not None:
            sc.setdefault("reference_coeffs", {})["samples"] = prev["reference_coeffs"]["samples"]
        src = prev.get("placement_run") or next(
            (r["command"] for r in (old.get("runs") or []) if name in r["scenes"]), old.get("command"))
        sc["placement_run"] = src
        carried[name] = src
    for key in ("far", "sun"):
        if key in new:
            out[key] = new[key]
    out["settings"] = dict(old.get("settings", {}), **new["settings"])
    out["shprobe_bytes"] = new["shprobe_bytes"]
    runs = old.get("runs") or [{"command": old.get("command"), "scenes": sorted(old.get("scenes", {})),
                                "seconds": old.get("sweep_seconds")}]
    # Each earlier run keeps the scenes whose figures still come from it (its seconds as measured).
    stale = {f"{n} (placement study)" for n in new["scenes"] if n not in carried}
    runs = [dict(r, scenes=[n for n in r["scenes"] if n not in new["scenes"] and n not in stale]
                 + [f"{n} (placement study)" for n, src in carried.items()
                    if src == r["command"] and n in r["scenes"]]) for r in runs]
    out["runs"] = [r for r in runs if r["scenes"]] + new["runs"]
    out["sweep_seconds"] = sum(r["seconds"] or 0.0 for r in out["runs"])
    out.pop("pareto", None)
    out.pop("recommended", None)
    return out


if __name__ == "__main__":
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--full", action="store_true", help="run the whole sweep (required)")
    ap.add_argument("--scenes", "--only", nargs="*", dest="scenes",
                    help="scenes to run (default: all); with some, merge into the existing sweep.json")
    ap.add_argument("--workdir", help="keep the workers' raw output here (default: a temp folder)")
    ap.add_argument("--analyse-only", action="store_true", help="rebuild the report from --workdir")
    ap.add_argument("--no-placement", action="store_true",
                    help="skip the placement study (and its sample points' references and the 10 km "
                         "test) of interior/courtyard; with --scenes, their earlier figures are kept")
    args = ap.parse_args()
    if not (args.full or args.analyse_only):
        ap.error("pass --full (the reduced sweep runs in tests/bench/test_sweep_reduced.py)")
    workdir = args.workdir or tempfile.mkdtemp(prefix="schnee_sweep_")
    os.makedirs(workdir, exist_ok=True)
    p = plan(placement=not args.no_placement)
    unknown = sorted(set(args.scenes or ()) - set(p))
    if unknown:
        ap.error(f"unknown scenes {unknown}; known: {sorted(p)}")
    subset = bool(args.scenes) and set(args.scenes) != set(p)
    docs = {}
    for scene, (offset, jobs) in p.items():
        if args.scenes and scene not in args.scenes:
            continue
        out_path = os.path.join(workdir, f"{scene}.out.json")
        if args.analyse_only:
            if os.path.exists(out_path):
                docs[scene] = json.load(open(out_path, encoding="utf-8"))
            continue
        docs[scene] = run_scene(scene, offset, jobs, workdir)
    result = analyse(docs)
    result["shprobe_bytes"] = shprobe_bytes()
    seconds = sum(d.get("seconds", 0.0) for d in docs.values())
    command = "/usr/bin/python3 bench/sweep/run.py --full" + (
        " --scenes " + " ".join(args.scenes) if subset else "") + (" --no-placement" if args.no_placement else "")
    result["runs"] = [{"command": command, "scenes": sorted(docs), "seconds": seconds,
                       "date": time.strftime("%Y-%m-%d", time.gmtime())}]
    result["sweep_seconds"] = seconds
    result["command"] = command
    stored = os.path.join(RESULTS, "sweep.json")
    if subset:
        with open(stored, encoding="utf-8") as fh:
            result = merge(result, json.load(fh))
    import report  # noqa: E402  (bench/sweep/report.py)
    report.write(result, RESULTS)
    print(f"wrote {RESULTS}/sweep.md, sweep.png, sweep.json ({seconds / 60:.1f} min this run, "
          f"{result['sweep_seconds'] / 60:.1f} min over {len(result['runs'])} run(s))")
