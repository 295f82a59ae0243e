"""Dilation and SH windowing (issue 31 item 4, addon/schnee_probes/postprocess.py): their effect on the
error between probes, at the placement bench's points and on the sphere benchmark.

    blender -b --factory-startup -P bench/bench_postprocess.py -- OUT.json --keep DIR
        [--spheres TREE --spheres-out DIR2] [--variants NAME ...]

Points: DIR is a ``bench/bench_placement.py ... --keep DIR`` run (its points.npz: the seeded points,
the reference SH baked there, the mixed-sun direct term; its adaptive_*.shprobe: the bake). Each
variant post-processes the file's probes as the bake's write does (postprocess.apply with the
variant's settings), interpolates them at the points with the file's structure and validity (as
bench_placement does) and reports bench_placement.stats of adaptive.irradiance_error against the
reference: exactly the placement bench's error, the same points.

Spheres: TREE is a finished ``bench/bench_spheres.py`` output folder (sh_coeffs/probes.shprobe,
the Cycles renders, floor.npz). Per variant it is copied to DIR2/<variant>, its probe file
post-processed and rewritten, and ``bench_spheres.py DIR2/<variant> --reuse`` run (the engine
renders and the comparison redone on the same Cycles references); the per-sphere errors are read
from its spheres.json. The report is bench/results/postprocess.md.
"""
import argparse
import glob
import json
import os
import shutil
import subprocess
import sys
import time
from types import SimpleNamespace

REPO = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
sys.path.insert(0, os.path.join(REPO, "bench"))
sys.path.insert(0, os.path.join(REPO, "addon"))

import numpy as np  # noqa: E402

from bench_placement import stats  # noqa: E402
from schnee_probes import adaptive, native, postprocess  # noqa: E402

# name: (Dilate Invalid Probes, SH Windowing, SH Window Strength)
VARIANTS = {
    "off": (False, "NONE", 0.0),
    "dilate": (True, "NONE", 0.0),
    "laplacian_auto": (False, "LAPLACIAN", 0.0),
    "laplacian_0.002": (False, "LAPLACIAN", 0.002),
    "laplacian_0.01": (False, "LAPLACIAN", 0.01),
    "laplacian_0.05": (False, "LAPLACIAN", 0.05),
    "sinc4_auto": (False, "SINC4", 0.0),
    "sinc4_12": (False, "SINC4", 12.0),
    "sinc4_6": (False, "SINC4", 6.0),
    "dilate+laplacian_0.002": (True, "LAPLACIAN", 0.002),
    "dilate+laplacian_0.01": (True, "LAPLACIAN", 0.01),
}


def variant_settings(name):
    d, kind, strength = VARIANTS[name]
    return SimpleNamespace(dilate_invalid=d, sh_window=kind, sh_window_strength=strength)


def processed(path, name, log=None):
    """(file, structure, coeffs, validity) of ``path`` post-processed as variant ``name``."""
    f = native.read_shprobe(path)
    s = native.interpolation_from_file(path)
    c, v = postprocess.apply(f.coeffs, f.validity, s, variant_settings(name), log=log)
    return f, s, c, v


def write_variant(src, dst, name):
    f, s, c, v = processed(src, name, log=print)
    native.write_shprobe_v3(dst, s, c.astype(np.float32), validity=v, probe_scale=f.probe_scale,
                            probe_ambient=f.probe_ambient, default_sh_scale=f.default_sh_scale,
                            default_ambient=f.default_ambient)


def points_rows(keep, names):
    z = np.load(os.path.join(keep, "points.npz"))
    pts, ref, direct = z["engine"], z["ref"], z["direct"]
    files = sorted(glob.glob(os.path.join(keep, "adaptive_*.shprobe")))
    if not files:
        sys.exit(f"bench_postprocess: no adaptive_*.shprobe in {keep}")
    rows = []
    for path in files:
        # the points whose cell has an invalid corner: the only ones dilation can change
        f0, s0 = native.read_shprobe(path), native.interpolation_from_file(path)
        idx, w = s0.query(pts)
        touched = int(np.sum(np.any((w > 0) & (f0.validity[np.maximum(idx, 0)] <= 0) & (idx >= 0), axis=1)))
        print(f"POINTS {os.path.basename(path)}: {f0.probe_count} probes, {int((f0.validity <= 0).sum())} invalid, "
              f"{touched} of {len(pts)} points in a cell with an invalid corner", flush=True)
        for name in names:
            t = time.perf_counter()
            f, s, c, v = processed(path, name)
            sec = time.perf_counter() - t
            got = s.interpolate(pts, c, v)
            err = adaptive.irradiance_error(got + direct, ref + direct)
            rows.append({"file": os.path.basename(path), "variant": name, "probes": int(f.probe_count),
                         "invalid": int((f.validity <= 0).sum()), "points_touching_invalid": touched,
                         "probes_changed": int(np.sum(np.any(c != f.coeffs, axis=(1, 2)))),
                         "seconds": round(sec, 3),
                         "error": stats(err), "point_errors": [round(float(e), 5) for e in err]})
            e = rows[-1]["error"]
            print(f"POINTS {name:24s} mean {100 * e['mean']:.3f} % median {100 * e['median']:.3f} % "
                  f"max {100 * e['max']:.2f} % uncovered {e['uncovered']}  ({sec:.2f} s)", flush=True)
    return rows


def near_invalid_points(keep, scene_name, n, seed, ref_samples, ref_res, ref_bounces):
    """``n`` seeded points in the cells that have an invalid corner (the only points dilation can
    change), inside the volume and outside the scene's solids by its margin (placement_scenes.points'
    rule), with a
    reference baked there at the --ref-* quality; cached in DIR/near_invalid.npz."""
    cache = os.path.join(keep, "near_invalid.npz")
    key = json.dumps([scene_name, n, seed, ref_samples, ref_res, ref_bounces])
    if os.path.exists(cache) and str(np.load(cache)["key"]) == key:
        z = np.load(cache)
        return z["engine"], z["ref"]
    import bpy
    import placement_scenes
    import schnee_probes
    from schnee_probes import bake_core, scene_export
    sc = placement_scenes.build(scene_name)
    schnee_probes.register()
    path = sorted(glob.glob(os.path.join(keep, "adaptive_*.shprobe")))[0]
    f, s = native.read_shprobe(path), native.interpolation_from_file(path)
    pos = s.positions()
    bad = np.flatnonzero(f.validity <= 0)
    if bad.size == 0:
        sys.exit(f"bench_postprocess: {path} has no invalid probe")
    p, q = postprocess.neighbour_pairs(s, pos, bad)
    reach = np.zeros(len(pos))
    np.maximum.at(reach, p, np.abs(pos[p] - pos[q]).max(axis=1))  # the cells' extent around each
    rng = np.random.default_rng(seed)
    out, tries = [], 0
    while len(out) < n and tries < 200 * n:
        tries += 1
        b = rng.choice(bad)
        cand = pos[b] + rng.uniform(-1, 1, size=(64, 3)) * reach[b]
        idx, w = s.query(cand)
        hit = np.any((w > 0) & (idx >= 0) & (f.validity[np.maximum(idx, 0)] <= 0), axis=1)
        for e in cand[hit]:
            bl = scene_export.engine_to_blender(e[None])[0]
            if not (np.all(bl > np.add(sc.volume[0], sc.margin)) and np.all(bl < np.subtract(sc.volume[1], sc.margin))):
                continue  # in the volume by the margin, as placement_scenes.points (not below the floor)
            if any(np.all(bl > np.subtract(a, sc.margin)) and np.all(bl < np.add(c, sc.margin)) for a, c in sc.solids):
                continue
            out.append(e)
            break
    print(f"NEAR {len(out)} points outside the solids in cells with an invalid corner ({tries} tries)", flush=True)
    pts = np.array(out).reshape(-1, 3)
    if len(pts) == 0:
        np.savez(cache, key=key, engine=pts, ref=np.zeros((0, 9, 3)))
        return pts, np.zeros((0, 9, 3))
    for ob in bpy.context.scene.objects:  # as bench_placement's default --sun-mode baked
        if ob.type == 'LIGHT' and ob.data.type == 'SUN':
            ob["schnee_light_mode"] = "baked"
    st = bake_core.BakeSettings(panorama_resolution=ref_res, samples=ref_samples, max_bounces=ref_bounces,
                                capture_sky=False, probe_limit=0,
                                output_path=os.path.join(keep, "near_invalid_scratch.shprobe"))
    ref = bake_core.bake_points(bpy.context.scene, bpy.context.view_layer, st, pts, log=lambda t: None)
    np.savez(cache, key=key, engine=pts, ref=ref)
    return pts, ref


def near_rows(keep, names, pts, ref):
    path = sorted(glob.glob(os.path.join(keep, "adaptive_*.shprobe")))[0]
    # a point inside geometry (the reference's DC below 1e-3 of the median: the bake's solid test
    # left it unrendered, or it sees only the inside of an object) is not where a movable object's
    # centre can be; bench_placement's room has its demo movables in the scene, and they are solid
    dc = np.abs(ref[:, 0]).max(axis=1)
    inside = dc < 1e-3 * np.median(dc)
    print(f"NEAR {int(inside.sum())} of {len(pts)} points inside geometry by the solid test: left out", flush=True)
    pts, ref = pts[~inside], ref[~inside]
    rows = []
    for name in names if len(pts) else []:
        f, s, c, v = processed(path, name)
        base = s.interpolate(pts, f.coeffs, f.validity)
        got = s.interpolate(pts, c, v)
        err = adaptive.irradiance_error(got, ref)
        rows.append({"file": os.path.basename(path), "variant": name, "set": "near_invalid", "probes": int(f.probe_count),
                     "invalid": int((f.validity <= 0).sum()), "seconds": 0.0, "error": stats(err),
                     "changed_points": int(np.sum(np.any(np.abs(got - base) > 0, axis=(1, 2)))),
                     "point_errors": [round(float(e), 5) for e in err]})
        e = rows[-1]["error"]
        print(f"NEAR {name:24s} mean {100 * e['mean']:.3f} % median {100 * e['median']:.3f} % "
              f"max {100 * e['max']:.2f} % uncovered {e['uncovered']}", flush=True)
    return rows


def sphere_rows(tree, out, names, blender):
    rows = []
    src = os.path.join(tree, "sh_coeffs", "probes.shprobe")
    for name in names:
        d = os.path.join(out, name)
        if os.path.exists(d):
            shutil.rmtree(d)
        shutil.copytree(tree, d, ignore=shutil.ignore_patterns("gltf"))
        write_variant(src, os.path.join(d, "sh_coeffs", "probes.shprobe"), name)
        cmd = [blender, "-b", "--factory-startup", "-P", os.path.join(REPO, "bench", "bench_spheres.py"), "--",
               d, "--reuse"]
        t = time.perf_counter()
        r = subprocess.run(cmd, stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True)
        with open(os.path.join(d, "bench_spheres.log"), "w", encoding="utf-8") as fh:
            fh.write(r.stdout)
        if r.returncode != 0:
            sys.exit(f"bench_postprocess: {' '.join(cmd)} failed ({r.returncode}); log in {d}/bench_spheres.log")
        with open(os.path.join(d, "spheres.json"), encoding="utf-8") as fh:
            res = json.load(fh)
        rows.append({"variant": name, "seconds": round(time.perf_counter() - t, 1), "spheres": res.get("spheres"),
                     "table": open(os.path.join(d, "table.md"), encoding="utf-8").read()})
        print("SPHERES", name, flush=True)
    return rows


COLUMNS = ("per_object", "per_pixel", "per_pixel_cpu_plain")


def report(out):
    """Markdown tables of an OUT.json (the numbers bench/results/postprocess.md quotes)."""
    lines = []
    if out.get("points"):
        lines += ["| variant | mean | median | p90 | worst | uncovered | probes changed | post-process s |",
                  "|---|---|---|---|---|---|---|---|"]
        for r in out["points"]:
            e = r["error"]
            label = r["variant"] + (" (near invalid)" if r.get("set") == "near_invalid" else "")
            lines.append(f"| {label} | {100 * e['mean']:.2f} % | {100 * e['median']:.2f} % | "
                         f"{100 * e['p90']:.2f} % | {100 * e['max']:.2f} % | {e['uncovered']} | {r.get('probes_changed', '')} | "
                         f"{r['seconds']:.2f} |")
    if out.get("spheres"):
        names = [sp["name"] for sp in out["spheres"][0]["spheres"]]
        lines += ["", "Relative RMS net of the reference's noise, % (mean colour error in brackets); "
                  "per pixel cpu plain = the file's interpolation with validity at each surface point.", "",
                  "| variant | " + " | ".join(f"{c} (mean of {len(names)})" for c in COLUMNS) + " | "
                  + " | ".join(f"{n} per pixel" for n in names) + " |",
                  "|---" * (1 + len(COLUMNS) + len(names)) + "|"]
        for r in out["spheres"]:
            cells = []
            for c in COLUMNS:
                net = np.mean([sp["errors"][c]["rel_rms_net"] for sp in r["spheres"]])
                mean = np.mean([sp["errors"][c]["mean_rel"] for sp in r["spheres"]])
                cells.append(f"{100 * net:.2f} ({100 * mean:.2f})")
            cells += [f"{100 * sp['errors']['per_pixel']['rel_rms_net']:.2f}" for sp in r["spheres"]]
            lines.append(f"| {r['variant']} | " + " | ".join(cells) + " |")
    return "\n".join(lines)


def main():
    argv = sys.argv[sys.argv.index("--") + 1:] if "--" in sys.argv else sys.argv[1:]
    ap = argparse.ArgumentParser()
    ap.add_argument("out")
    ap.add_argument("--keep", default=None, help="a bench_placement.py --keep folder (points.npz, the bake)")
    ap.add_argument("--spheres", default=None, help="a finished bench_spheres.py output folder")
    ap.add_argument("--spheres-out", default=None, help="where the sphere variants' folders go")
    ap.add_argument("--variants", nargs="+", default=list(VARIANTS), choices=list(VARIANTS))
    ap.add_argument("--sphere-variants", nargs="+", default=None, choices=list(VARIANTS),
                    help="variants of the sphere benchmark (default: --variants)")
    ap.add_argument("--blender", default="blender")
    ap.add_argument("--report", action="store_true", help="print the tables of OUT (an earlier run's JSON)")
    ap.add_argument("--merge", nargs="*", default=[], help="with --report: more JSON files whose rows are added")
    ap.add_argument("--near-invalid", type=int, default=0, metavar="N",
                    help="with --keep and --scene: also N seeded points in the cells with an invalid corner, "
                         "outside the solids, with a reference baked there (cached in DIR/near_invalid.npz)")
    ap.add_argument("--scene", default=None, help="the placement scene of --keep (for --near-invalid)")
    ap.add_argument("--seed", type=int, default=31)
    ap.add_argument("--ref-samples", type=int, default=128)
    ap.add_argument("--ref-res", type=int, default=128)
    ap.add_argument("--ref-bounces", type=int, default=32)
    a = ap.parse_args(argv)
    if a.report:
        out = {"points": [], "spheres": []}
        for path in [a.out] + a.merge:
            with open(path, encoding="utf-8") as fh:
                d = json.load(fh)
            out["points"] += d.get("points", [])
            out["spheres"] += d.get("spheres", [])
        print(report(out))
        return
    out = {"argv": argv, "variants": {k: VARIANTS[k] for k in a.variants}}
    if a.keep:
        out["points"] = points_rows(a.keep, a.variants)
        if a.near_invalid:
            pts, ref = near_invalid_points(a.keep, a.scene, a.near_invalid, a.seed, a.ref_samples, a.ref_res,
                                           a.ref_bounces)
            out["points"] += near_rows(a.keep, a.variants, pts, ref)
    if a.spheres:
        if not a.spheres_out:
            sys.exit("bench_postprocess: --spheres needs --spheres-out")
        out["spheres"] = sphere_rows(a.spheres, a.spheres_out, a.sphere_variants or a.variants, a.blender)
    with open(a.out, "w", encoding="utf-8") as fh:
        json.dump(out, fh, indent=1)
    print("WROTE", a.out)


if __name__ == "__main__":
    main()
