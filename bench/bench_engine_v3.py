"""Engine frame time: a .shprobe version 3 corner octree vs the version 1 dense grid, per object and per
pixel (docs/engine.md "Version 3 grids").

The generated benchmark room (tests/engine/scripts/make_room.py: 56 objects, 58 k triangles, a
20 x 8 x 20 grid of 3200 L2 probes over 10 x 4 x 10 m) and the same room with its grid replaced by a
corner octree over the same box (Min Cell Size 0.5 m, 2 m roots; the lower root layer split to 1 m and
its bottom layer again to 0.5 m, so hanging nodes on two levels), holding the same analytic field at
its probe positions. Each configuration runs FRAMES frames per launch (schnee-view prints their
median), ROUNDS launches interleaved over the configurations; the table gives the median of the
launch medians and their range, and the median over rounds of the paired ratio octree / grid of one
mode (launched back to back, which cancels most of a shared machine's load drift).

Per pixel on the octree runs twice: the storage-buffer path (the default, --probe-path buffers: leaf
search, back faces, visibility) and the probe bricks (--probe-path bricks: docs/probe-bricks.md, 3D
textures with hardware trilinear filtering; dense grids have no bricks). "off" (--probe-mode off: the
fallback probe only) is the raster floor. Besides the frame, the scene pass's GPU time (timestamps) and,
for the bricks, the GPU memory per probe the engine reports (pool + indirection against the storage
buffers of the same grid).

Usage: /usr/bin/python3 bench/bench_engine_v3.py [--frames 5] [--rounds 3] [--width 640 --height 360] [--octree-only]
(--octree-only: the octree's four rows only, for large frames on lavapipe)

--bricks-table (issue 30, "What it must show"): per scene (the generated room's v1 grid, its v3 octree and,
with --bundled GLTF, the bundled room's export) four configurations: per object, per pixel from the
bricks, per pixel from the buffers, off (the raster floor); interleaved rounds, paired ratios per round,
each launch's wall and CPU seconds (the schnee-view child's rusage), the load average at the start and
end, GPU memory per probe from the engine's stderr (pool + indirection, + brick tables + visibility
records), --json OUT writes every launch. --memory-table: the GPU memory per probe the engine allocates (its
`probe memory:` line) on both paths, one 1-frame launch each, no timing. --scenes v1,v3,bundled picks scenes. --merge A.json B.json
[--json OUT] prints (and writes) several such runs of the same options as one.
Environment: SCHNEE_VIEW (default build/schnee-view), VK_ICD_FILENAMES as for the tests (lavapipe).
"""
import argparse
import json
import os
import re
import resource
import time
import statistics
import subprocess
import sys
import tempfile
from pathlib import Path

import numpy as np

REPO = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(REPO / "tests" / "engine" / "scripts"))
sys.path.insert(0, str(REPO / "addon"))
import make_room  # noqa: E402
from schnee_probes import native  # noqa: E402

# (probe mode, grid, probe path)
CONFIGS = [(mode, grid, "buffers") for mode in ("object", "pixel") for grid in ("v1 grid", "v3 octree")]
CONFIGS += [("pixel", "v3 octree", "bricks"), ("off", "v3 octree", "buffers")]


def field(pos):
    """make_room's analytic field (L0 colour gradient, L1 from above and along x) at positions."""
    u = (pos - [-5.0, 0.0, -5.0]) / [10.0, 4.0, 10.0]
    c = np.zeros((len(pos), 9, 3))
    c[:, 0] = np.stack([0.6 + 0.3 * u[:, 0], 0.5 + 0.2 * u[:, 1], 0.4 + 0.4 * u[:, 2]], -1) * 3.5449
    c[:, 1] = 0.3
    c[:, 3, 0] = 0.2 * (u[:, 0] - 0.5)
    return c


def octree_scene(room):
    t = native.CornerOctree.uniform((-5.0, 0.0, -5.0), 0.5, 2, (5, 2, 5))
    for level in (2, 1):  # the bottom layer of leaves, twice
        leaves = t.info()["leaves"]
        t.split((leaves[:, 1] == 0) & (leaves[:, 3] == level))
    t.finalize()
    info = t.info()
    path = room.parent / "sh_coeffs" / "room_v3.shprobe"
    native.write_shprobe_v3(str(path), t, field(t.positions()))
    doc = json.loads(room.read_text())
    e = doc["scenes"][0]["extensions"]["VULKAN_SCHNEE_engine_properties"]["shProbeGrids"][0]
    e.update(uri="sh_coeffs/room_v3.shprobe", probeCount=t.probe_count, gridDims=list(map(int, info["dims"])),
             structure="octree")
    out = room.parent / "room_v3.gltf"
    out.write_text(json.dumps(doc))
    return out, t.probe_count, int(info["hanging_count"]), len(info["leaves"])


def run(view, scene, out, mode, frames, w, h, path="buffers"):
    proc = subprocess.run([view, str(scene), "--headless", "--output", str(out), "--width", str(w), "--height", str(h),
                           "--frames", str(frames), "--no-direct", "--probe-mode", mode, "--probe-path", path],
                          capture_output=True, text=True, timeout=600)
    if proc.returncode != 0:
        raise SystemExit(f"schnee-view failed ({proc.returncode}): {proc.stderr}")
    m = re.search(r"frame\(s\) at \d+x\d+: mean ([\d.]+) ms, median ([\d.]+) ms, min ([\d.]+) ms", proc.stderr)
    dev = re.search(r"device (.*?);", proc.stderr)
    scene_ms = re.search(r"GPU time per frame \(timestamps, median\):.*? scene ([\d.]+) ms", proc.stderr)
    mem = re.search(r"GPU memory ([\d.]+) B per probe \(storage buffers, \w+: ([\d.]+) B per probe\)", proc.stderr)
    return (float(m.group(2)), dev.group(1) if dev else "?", float(scene_ms.group(1)) if scene_ms else float("nan"),
            (float(mem.group(1)), float(mem.group(2))) if mem else None)


def run_full(view, scene, out, mode, frames, w, h, path):
    """One launch: the frame median, scene-pass GPU median, wall and CPU seconds, the memory lines. A path
    "bricks-fragment" is the bricks with --probe-pass fragment (the per-pixel probes in the scene pass's
    fragment shader); the others take the default, the probe pass (docs/engine.md "The per-pixel probe pass")."""
    r0 = resource.getrusage(resource.RUSAGE_CHILDREN)
    t0 = time.perf_counter()
    extra = ["--probe-pass", "fragment"] if path.endswith("-fragment") else []
    proc = subprocess.run([view, str(scene), "--headless", "--output", str(out), "--width", str(w), "--height", str(h),
                           "--frames", str(frames), "--no-direct", "--probe-mode", mode, "--probe-path",
                           path.removesuffix("-fragment")] + extra, capture_output=True, text=True, timeout=1800)
    wall = time.perf_counter() - t0
    r1 = resource.getrusage(resource.RUSAGE_CHILDREN)
    if proc.returncode != 0:
        raise SystemExit(f"schnee-view failed ({proc.returncode}): {proc.stderr}")
    err = proc.stderr
    m = re.search(r"frame\(s\) at \d+x\d+: mean ([\d.]+) ms, median ([\d.]+) ms, min ([\d.]+) ms", err)
    dev = re.search(r"device (.*?);", err)
    scene_ms = re.search(r"GPU time per frame \(timestamps, median\):.*? scene ([\d.]+) ms", err)
    pass_ms = re.search(r"after the objects' raster \(the probe pass\) ([\d.]+) ms", err)
    rec = {"frame_median_ms": float(m.group(2)), "frame_mean_ms": float(m.group(1)), "frame_min_ms": float(m.group(3)),
           "scene_pass_ms": float(scene_ms.group(1)) if scene_ms else None, "device": dev.group(1) if dev else "?",
           "probe_pass_ms": float(pass_ms.group(1)) if pass_ms else None,
           "wall_s": wall, "cpu_s": (r1.ru_utime - r0.ru_utime) + (r1.ru_stime - r0.ru_stime),
           "load_after": os.getloadavg()[0]}
    b = re.search(r"probe bricks: (\d+) bricks \((\d+) texels\) of (\d+) probes; pool (\d+) x (\d+) x (\d+) (\w+) "
                  r"\((\d+) groups\), (\d+) B; indirection (\d+) x (\d+) x (\d+), (\d+) B; GPU memory ([\d.]+) B per "
                  r"probe \(storage buffers, (\w+): ([\d.]+) B per probe\)", err)
    if b:
        g = b.groups()
        rec["bricks"] = {"bricks": int(g[0]), "texels": int(g[1]), "probes": int(g[2]),
                         "pool": [int(g[3]), int(g[4]), int(g[5])], "format": g[6], "groups": int(g[7]),
                         "pool_bytes": int(g[8]), "indirection": [int(g[9]), int(g[10]), int(g[11])],
                         "indirection_bytes": int(g[12]), "engine_bytes_per_probe": float(g[13]),
                         "buffers_storage": g[14], "engine_buffers_bytes_per_probe": float(g[15]),
                         "dense_grids": int(re.search(r"probe bricks: (\d+) dense grid", err).group(1))
                         if "dense grid(s)" in err else 0}
    v = re.search(r"probe brick visibility: (\d+) record\(s\) \(([\d.]+) KiB\) for (\d+) traced brick cell\(s\) in "
                  r"(\d+) blocked leaf/leaves, (\d+) B of brick tables; (\d+) segment\(s\) against (\d+) triangle\(s\), "
                  r"bricks built in ([\d.]+) ms", err)
    if v:
        g = v.groups()
        rec["brick_vis"] = {"records": int(g[0]), "record_bytes": int(g[0]) * 64, "traced_cells": int(g[2]),
                            "blocked_leaves": int(g[3]), "table_bytes": int(g[4]), "segments": int(g[5]),
                            "triangles": int(g[6]), "build_ms": float(g[7])}
    pm = re.search(r"probe memory: (\d+) B on the GPU for (\d+) file probe\(s\), ([\d.]+) B per probe: pool (\d+) B, "
                   r"indirection (\d+) B, brick tables and records (\d+) B, storage buffers (\d+) B .*?; "
                   r"(file probes (?:not )?uploaded)", err)
    if pm:
        g = pm.groups()
        rec["probe_memory"] = {"total_bytes": int(g[0]), "file_probes": int(g[1]), "bytes_per_probe": float(g[2]),
                               "pool_bytes": int(g[3]), "indirection_bytes": int(g[4]), "brick_vis_bytes": int(g[5]),
                               "storage_bytes": int(g[6]), "file_probes_uploaded": g[7] == "file probes uploaded"}
    loaded = re.search(r"loaded .*?: (\d+) object\(s\), (\d+) probe grid\(s\), (\d+) probe\(s\)", err)
    if loaded:
        rec["objects"], rec["grids"], rec["probe_entries"] = map(int, loaded.groups())
    return rec


BRICK_CONFIGS = [("object", "buffers"), ("pixel", "bricks"), ("pixel", "bricks-fragment"), ("pixel", "buffers"),
                 ("off", "buffers")]


def dense_buffer_bytes(scene):
    """The storage buffers a dense SH grid takes on the buffers path (shaders/sv_gpu.h): one sv_gpu_probe
    (416 B float, L4 stride) per probe + per cell a 4-B probe index and a 4-B neighbour mask."""
    doc = json.loads(Path(scene).read_text())
    g = doc["scenes"][0]["extensions"]["VULKAN_SCHNEE_engine_properties"]["shProbeGrids"][0]
    cells = int(np.prod(g["gridDims"]))
    return g["probeCount"] * 416 + cells * 8, g["probeCount"], cells


def bricks_table(a, view):
    names = [x.strip() for x in a.scenes.split(",") if x.strip()]
    load_start = os.getloadavg()
    t_start = time.perf_counter()
    with tempfile.TemporaryDirectory() as tmp:
        room = make_room.main(Path(tmp) / "room")
        v3, probes, hanging, leaves = octree_scene(room)
        scenes = {"v1": room, "v3": v3}
        if "bundled" in names:
            if not a.bundled or not Path(a.bundled).exists():
                raise SystemExit("--scenes bundled needs --bundled GLTF (an export of the bundled room)")
            scenes["bundled"] = Path(a.bundled)
        label = {"v1": "generated room, v1 grid (3200 probes)",
                 "v3": f"generated room, v3 octree ({probes} probes, {hanging} hanging, {leaves} leaves)",
                 "bundled": f"bundled room ({a.bundled})"}
        configs = [(n, m, p) for n in names for (m, p) in BRICK_CONFIGS]
        runs = {c: [] for c in configs}
        for rnd in range(a.rounds):
            order = configs if rnd % 2 == 0 else [c for n in names for c in reversed([x for x in configs if x[0] == n])]
            for c in order:
                rec = run_full(view, scenes[c[0]], Path(tmp) / "f.png", c[1], a.frames, a.width, a.height, c[2])
                rec["round"] = rnd
                runs[c].append(rec)
                print(c, f"frame {rec['frame_median_ms']:.0f} ms, scene pass {rec['scene_pass_ms']:.0f} ms, "
                      f"wall {rec['wall_s']:.1f} s, CPU {rec['cpu_s']:.1f} s, load {rec['load_after']:.1f}",
                      file=sys.stderr, flush=True)
        dense = {n: dense_buffer_bytes(scenes[n]) for n in names if n == "v1"}
    load_end = os.getloadavg()
    tree = Path(view).resolve().parent.parent
    git = [subprocess.run(["git", "-C", str(tree)] + x, capture_output=True, text=True).stdout.strip()
           for x in (["rev-parse", "HEAD"], ["status", "--porcelain", "--untracked-files=no"])]
    result = {"command": "bench/bench_engine_v3.py " + " ".join(sys.argv[1:]), "viewer": view,
              "viewer_tree": {"path": str(tree), "commit": git[0], "modified": git[1].splitlines()},
              "width": a.width, "height": a.height, "frames": a.frames, "rounds": a.rounds,
              "load_start": load_start, "load_end": load_end, "wall_s": time.perf_counter() - t_start,
              "cpus": os.cpu_count(), "scenes": {}}
    for n in names:
        s = {"label": label[n], "runs": {f"{m} {p}": runs[(n, m, p)] for (m, p) in BRICK_CONFIGS}}
        b = next((r["bricks"] for r in runs[(n, "pixel", "bricks")] if "bricks" in r), None)
        vis = next((r["brick_vis"] for r in runs[(n, "pixel", "bricks")] if "brick_vis" in r), None)
        if b:
            extra = (vis["table_bytes"] + vis["record_bytes"]) if vis else 0
            texel_bytes = 8 * b["groups"] if b["format"] == "RGBA16F" else 16 * b["groups"]
            mem = {"probes": b["probes"], "pool_bytes": b["pool_bytes"], "indirection_bytes": b["indirection_bytes"],
                   "brick_table_bytes": vis["table_bytes"] if vis else 0, "record_bytes": vis["record_bytes"] if vis else 0,
                   "bytes_per_texel": texel_bytes, "bricks": b["bricks"], "texels_used": b["texels"],
                   "dense_grids": b["dense_grids"],
                   "engine_bytes_per_probe": b["engine_bytes_per_probe"],
                   "total_bytes_per_probe": (b["pool_bytes"] + b["indirection_bytes"] + extra) / b["probes"],
                   "buffers_bytes_per_probe_engine": b["engine_buffers_bytes_per_probe"]}
            if n in dense:
                mem["buffers_bytes_per_probe_dense"] = dense[n][0] / dense[n][1]
                mem["dense_cells"] = dense[n][2]
            s["memory"] = mem
        result["scenes"][n] = s
    summarise(result)
    if a.json:
        Path(a.json).write_text(json.dumps(result, indent=1))
    print_tables(result)


def memory_table(a, view):
    """--memory-table: the GPU memory per probe the engine allocates (its `probe memory:` line), one 1-frame
    launch per scene and probe path (per pixel), no timing. "before" = the bricks plus the storage buffers the
    buffers path uploads: what a --probe-path bricks process held until the engine uploaded the file's probes
    only where a shader reads them (docs/engine.md "Probe buffers")."""
    names = [x.strip() for x in a.scenes.split(",") if x.strip()]
    rows = {}
    with tempfile.TemporaryDirectory() as tmp:
        room = make_room.main(Path(tmp) / "room")
        v3 = octree_scene(room)[0]
        scenes = {"v1": room, "v3": v3, "bundled": Path(a.bundled)}
        for n in names:
            rows[n] = {p: run_full(view, scenes[n], Path(tmp) / "f.png", "pixel", 1, a.width, a.height, p)
                       for p in ("bricks", "buffers")}
    tree = Path(view).resolve().parent.parent
    commit = subprocess.run(["git", "-C", str(tree), "rev-parse", "--short", "HEAD"], capture_output=True,
                            text=True).stdout.strip()
    print(f"Viewer {view} (tree at {commit}); {a.width} x {a.height}, 1 frame, per pixel.\n")
    print("| scene | probes | pool | indirection | brick tables + records | storage buffers (bricks path) | "
          "B per probe (pool + indirection) | B per probe (all, allocated) | before: + the full storage buffers | "
          "buffers path, allocated |")
    print("|---|---|---|---|---|---|---|---|---|---|")
    out = {}
    for n in names:
        b, f = rows[n]["bricks"]["probe_memory"], rows[n]["buffers"]["probe_memory"]
        P = b["file_probes"]
        before = b["pool_bytes"] + b["indirection_bytes"] + b["brick_vis_bytes"] + f["storage_bytes"]
        uploaded = "file probes" if b["file_probes_uploaded"] else "slots only"
        print(f"| {n} | {P} | {b['pool_bytes']} B | {b['indirection_bytes']} B | {b['brick_vis_bytes']} B | "
              f"{b['storage_bytes']} B ({uploaded}) | {(b['pool_bytes'] + b['indirection_bytes']) / P:.1f} | "
              f"{b['bytes_per_probe']:.1f} | {before / P:.1f} | {f['bytes_per_probe']:.1f} |")
        out[n] = {"bricks": b, "buffers": f, "before_bytes_per_probe": before / P}
    if a.json:
        Path(a.json).write_text(json.dumps({"command": "bench/bench_engine_v3.py " + " ".join(sys.argv[1:]),
                                            "viewer_commit": commit, "scenes": out}, indent=1))


def summarise(result):
    """Paired ratios (per round: launches of one scene back to back) and differences above the floor."""
    from statistics import median

    def stat(r):
        return {"median": median(r), "min": min(r), "max": max(r), "rounds": r}

    for s in result["scenes"].values():
        runs = s["runs"]

        def pair(num, den, key="frame_median_ms"):
            return stat([x[key] / y[key] for x, y in zip(runs[num], runs[den])])

        def above(num, key="frame_median_ms"):
            return stat([x[key] - y[key] for x, y in zip(runs[num], runs["off buffers"])])

        s["ratios"] = {
            "bricks_per_object": pair("pixel bricks", "object buffers"),
            "fragment_per_object": pair("pixel bricks-fragment", "object buffers"),
            "pass_per_fragment": pair("pixel bricks", "pixel bricks-fragment"),
            "cpu_fragment_per_object": pair("pixel bricks-fragment", "object buffers", "cpu_s"),
            "buffers_per_object": pair("pixel buffers", "object buffers"),
            "bricks_per_buffers": pair("pixel bricks", "pixel buffers"),
            "off_per_object": pair("off buffers", "object buffers"),
            "bricks_per_object_scene_pass": pair("pixel bricks", "object buffers", "scene_pass_ms"),
            "buffers_per_object_scene_pass": pair("pixel buffers", "object buffers", "scene_pass_ms"),
            # CPU-s of whole launches (load, shader JIT, bricks build and the frames): steadier under load
            # than the wall clock, diluted towards 1 by the fixed part
            "cpu_bricks_per_object": pair("pixel bricks", "object buffers", "cpu_s"),
            "cpu_buffers_per_object": pair("pixel buffers", "object buffers", "cpu_s"),
            "cpu_bricks_per_buffers": pair("pixel bricks", "pixel buffers", "cpu_s")}
        s["above_floor_ms"] = {"bricks": above("pixel bricks"), "buffers": above("pixel buffers"),
                               "fragment": above("pixel bricks-fragment"),
                               "object": above("object buffers")}


def merge(paths):
    """Several --json results of the same options as one (their rounds one after another)."""
    docs = [json.loads(Path(x).read_text()) for x in paths]
    out = dict(docs[0])
    out["merged_from"] = [str(x) for x in paths]
    out["commands"] = [d["command"] for d in docs]
    out["rounds"] = sum(d["rounds"] for d in docs)
    out["load_end"] = docs[-1]["load_end"]
    out["load_ranges"] = [[d["load_start"][0], d["load_end"][0]] for d in docs]
    out["wall_s"] = sum(d["wall_s"] for d in docs)
    out["scenes"] = {}
    for n, s in docs[0]["scenes"].items():
        t = {k: v for k, v in s.items() if k not in ("runs", "ratios", "above_floor_ms")}
        t["runs"] = {}
        for key in s["runs"]:
            rs, off = [], 0
            for d in docs:
                for r in d["scenes"][n]["runs"][key]:
                    rs.append(dict(r, round=r["round"] + off))
                off += d["rounds"]
            t["runs"][key] = rs
        out["scenes"][n] = t
    summarise(out)
    return out


def print_tables(result):
    from statistics import median
    names = list(result["scenes"])
    first = result["scenes"][names[0]]["runs"]["object buffers"][0]
    loads = result.get("load_ranges") or [[result["load_start"][0], result["load_end"][0]]]
    wall_cpu = [(r["wall_s"], r["cpu_s"]) for s in result["scenes"].values() for rs in s["runs"].values() for r in rs]
    print(f"Device: {first['device']}; {result['cpus']} CPUs; load average (start-end of each invocation) "
          + ", ".join(f"{x:.1f}-{y:.1f}" for x, y in loads)
          + f"; {result['rounds']} rounds (order reversed within a scene every other round) x {result['frames']} frames "
          f"per launch at {result['width']} x {result['height']}, --no-direct; {result['wall_s'] / 60:.1f} min wall, "
          f"schnee-view launches {sum(w for w, _ in wall_cpu) / 60:.1f} min wall / "
          f"{sum(c for _, c in wall_cpu) / 60:.1f} min CPU.\n")
    print("| scene | configuration | median frame | launch medians | scene pass (GPU) | wall / CPU s per launch |")
    print("|---|---|---|---|---|---|")
    for n in names:
        for key, rs in result["scenes"][n]["runs"].items():
            m, p = key.split()
            fm = [r["frame_median_ms"] for r in rs]
            path = {"bricks": "bricks, probe pass", "bricks-fragment": "bricks, fragment shader",
                    "buffers": "buffers, probe pass"}.get(p, p)
            what = {"object": "per object", "pixel": f"per pixel ({path})", "off": "off (raster floor)"}[m]
            print(f"| {n} | {what} | {median(fm):.0f} ms | {min(fm):.0f}-{max(fm):.0f} ms | "
                  f"{median([r['scene_pass_ms'] for r in rs]):.0f} ms | "
                  f"{median([r['wall_s'] for r in rs]):.1f} / {median([r['cpu_s'] for r in rs]):.1f} |")

    def f(q, k, fmt="{:.2f}"):
        return f"{fmt.format(q[k]['median'])} ({fmt.format(q[k]['min'])} to {fmt.format(q[k]['max'])})"

    print("\n| scene | bricks / per object | buffers / per object | bricks / buffers | off / per object | "
          "scene pass: bricks / object, buffers / object | above the floor, paired: bricks, buffers (ms) |")
    print("|---|---|---|---|---|---|---|")
    for n in names:
        q, ab = result["scenes"][n]["ratios"], result["scenes"][n]["above_floor_ms"]
        print(f"| {n} | {f(q, 'bricks_per_object')} | {f(q, 'buffers_per_object')} | {f(q, 'bricks_per_buffers')} | "
              f"{f(q, 'off_per_object')} | {f(q, 'bricks_per_object_scene_pass')}, "
              f"{f(q, 'buffers_per_object_scene_pass')} | {f(ab, 'bricks', '{:.0f}')}, {f(ab, 'buffers', '{:.0f}')} |")
    print("\n| scene | launch CPU-s, paired: bricks / per object | buffers / per object | bricks / buffers |")
    print("|---|---|---|---|")
    for n in names:
        q = result["scenes"][n]["ratios"]
        print(f"| {n} | {f(q, 'cpu_bricks_per_object')} | {f(q, 'cpu_buffers_per_object')} | "
              f"{f(q, 'cpu_bricks_per_buffers')} |")
    if all("pass_per_fragment" in result["scenes"][n]["ratios"] for n in names):
        print("\n| scene | probe pass / per object | fragment shader / per object | probe pass / fragment shader | "
              "CPU-s: probe pass / per object, fragment / per object | probe pass's own GPU time (median) |")
        print("|---|---|---|---|---|---|")
        for n in names:
            q = result["scenes"][n]["ratios"]
            pp = [r["probe_pass_ms"] for r in result["scenes"][n]["runs"]["pixel bricks"] if r.get("probe_pass_ms")]
            own = f"{median(pp):.0f} ms" if pp else "n/a"
            print(f"| {n} | {f(q, 'bricks_per_object')} | {f(q, 'fragment_per_object')} | {f(q, 'pass_per_fragment')} | "
                  f"{f(q, 'cpu_bricks_per_object')}, {f(q, 'cpu_fragment_per_object')} | {own} |")
    print("\n| scene | probes | bricks / texels | pool | indirection | brick tables | records | B per probe "
          "(pool + indirection) | B per probe (all) | B per texel | buffers B per probe |")
    print("|---|---|---|---|---|---|---|---|---|---|---|")
    for n in names:
        mem = result["scenes"][n].get("memory")
        if not mem:
            continue
        buf = mem.get("buffers_bytes_per_probe_dense", mem["buffers_bytes_per_probe_engine"])
        print(f"| {n} | {mem['probes']} | {mem['bricks']} / {mem['texels_used']} | {mem['pool_bytes']} B | "
              f"{mem['indirection_bytes']} B | {mem['brick_table_bytes']} B | {mem['record_bytes']} B | "
              f"{mem['engine_bytes_per_probe']:.1f} | {mem['total_bytes_per_probe']:.1f} | {mem['bytes_per_texel']} | "
              f"{buf:.1f} |")

def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--frames", type=int, default=5)
    ap.add_argument("--rounds", type=int, default=3)
    ap.add_argument("--width", type=int, default=640)
    ap.add_argument("--height", type=int, default=360)
    ap.add_argument("--octree-only", action="store_true")
    ap.add_argument("--bricks-table", action="store_true", help="issue 30's table (see the docstring)")
    ap.add_argument("--memory-table", action="store_true",
                    help="GPU memory per probe only (the engine's probe memory line), 1 frame per launch")
    ap.add_argument("--scenes", default="v1,v3,bundled", help="--bricks-table / --memory-table: v1,v3,bundled")
    ap.add_argument("--bundled", default=str(REPO / "out" / "default" / "gltf" / "scene.gltf"),
                    help="--bricks-table: the bundled room's glTF (scripts/main_job.py's export)")
    ap.add_argument("--json", default=None, help="--bricks-table: write every launch here")
    ap.add_argument("--merge", nargs="+", default=None,
                    help="--bricks-table results (JSON) of the same options: print them as one (rounds appended)")
    a = ap.parse_args()
    configs = [c for c in CONFIGS if not (a.octree_only and c[1] == "v1 grid")]
    view = os.environ.get("SCHNEE_VIEW", str(REPO / "build" / "schnee-view"))
    if a.merge:
        result = merge(a.merge)
        if a.json:
            Path(a.json).write_text(json.dumps(result, indent=1))
        print_tables(result)
        return
    if a.bricks_table:
        bricks_table(a, view)
        return
    if a.memory_table:
        memory_table(a, view)
        return
    with tempfile.TemporaryDirectory() as tmp:
        room = make_room.main(Path(tmp) / "room")
        v3, probes, hanging, leaves = octree_scene(room)
        scenes = {"v1 grid": room, "v3 octree": v3}
        times = {c: [] for c in configs}
        scene_times = {c: [] for c in configs}
        device, memory = "?", None
        for _ in range(a.rounds):
            for c in configs:
                t, device, st, mem = run(view, scenes[c[1]], Path(tmp) / "f.png", c[0], a.frames, a.width, a.height,
                                         c[2])
                times[c].append(t)
                scene_times[c].append(st)
                memory = mem or memory
                print(c, f"{t:.0f} ms (scene pass {st:.0f} ms)", file=sys.stderr, flush=True)
    load = os.getloadavg()[0]
    print(f"Device: {device}; {os.cpu_count()} CPUs, load average {load:.1f} at the end; {a.rounds} launches x "
          f"{a.frames} frames per configuration at {a.width} x {a.height}, --no-direct. Octree: {probes} probes, "
          f"{hanging} hanging nodes, {leaves} leaves; grid: 3200 probes.\n")
    print("| probe mode | probes | path | median frame | launch medians | scene pass (GPU) | paired ratio |")
    print("|---|---|---|---|---|---|---|")
    for c in configs:
        ts = times[c]
        ratio = "—"
        base = {("v3 octree", "buffers"): (c[0], "v1 grid", "buffers"),
                ("v3 octree", "bricks"): ("object", "v3 octree", "buffers")}.get((c[1], c[2]))
        if base in times and c[0] != "off":
            r = [x / y for x, y in zip(ts, times[base])]
            what = "octree / grid" if c[2] == "buffers" else "bricks / per object"
            ratio = f"{what} {statistics.median(r):.2f} ({min(r):.2f}-{max(r):.2f})"
        if c[2] == "bricks":
            r = [x / y for x, y in zip(ts, times[("pixel", "v3 octree", "buffers")])]
            ratio += f"; bricks / buffers {statistics.median(r):.2f} ({min(r):.2f}-{max(r):.2f})"
        print(f"| {c[0]} | {c[1]} | {c[2] if c[0] == 'pixel' else '—'} | {statistics.median(ts):.0f} ms | "
              f"{min(ts):.0f}-{max(ts):.0f} ms | {statistics.median(scene_times[c]):.0f} ms | {ratio} |")
    if memory:
        print(f"\nGPU memory per probe of the octree file: bricks {memory[0]:.1f} B (pool + indirection), storage "
              f"buffers {memory[1]:.1f} B (entries for probes and hanging nodes, leaves, visibility tables).")


if __name__ == "__main__":
    main()
