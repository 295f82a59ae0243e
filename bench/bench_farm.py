"""Farm bake timing (issue 15; docs/farm.md): the bundled default scene (scenes/make_default_scene.py)
at the main job's preview settings, baked (1) locally by one Blender using every core, (2) on a
one-node Slurm cluster on this machine (tests/farm/slurm_cluster.py) as N shards of one CPU each
plus the merge. Prints a Markdown table and the projected wall time for W workers from the measured
per-probe cost: T(W) = first-probe upload + ceil(P / W) x (per-probe render at one worker's CPUs) +
merge. On this 2-core machine two 1-CPU workers can at best match one 2-CPU bake: the point is the
overhead, not a speed-up.

    /usr/bin/python3 bench/bench_farm.py [--shards 2]      (~5 min on 2 cores)
"""
import argparse
import math
import re
import shutil
import subprocess
import sys
import tempfile
import time
from pathlib import Path

REPO = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(REPO / "tests" / "farm"))
sys.path.insert(0, str(REPO / "addon"))
from slurm_cluster import SlurmCluster  # noqa: E402

PREVIEW = ["--min-cell-size", "1.0", "--max-cell-size", "4", "--panorama-resolution", "64", "--samples", "16",
           "--max-bounces", "6"]


def blender(*args, env=None):
    t = time.perf_counter()
    p = subprocess.run(["blender", "-b", *map(str, args)], capture_output=True, text=True, env=env)
    if p.returncode != 0:
        raise SystemExit(p.stdout[-3000:] + p.stderr[-3000:])
    return p, time.perf_counter() - t


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--shards", type=int, default=2)
    a = ap.parse_args()
    work = Path(tempfile.mkdtemp(prefix="bench_farm_"))
    blend = work / "scene.blend"
    blender("--factory-startup", "-P", REPO / "scenes" / "make_default_scene.py", "--", blend)
    local, farm = work / "local", work / "farm"
    for d in (local, farm):
        d.mkdir()
        shutil.copy(blend, d / "scene.blend")
    env = {**__import__("os").environ, "PYTHONPATH": str(REPO / "addon")}
    p, t_local = blender(local / "scene.blend", "-P", REPO / "bake.py", "--", *PREVIEW, env=env)
    m = re.search(r"bake\.py: (\d+) probes in ([\d.]+) s \(placement ([\d.]+) s, render ([\d.]+) s", p.stdout)
    probes, _, placement, render = int(m.group(1)), *map(float, m.group(2, 3, 4))
    r = re.search(r"adaptive placement: \d+ pass\(es\), (\d+) points rendered", p.stdout)
    points = int(r.group(1)) if r else probes  # Adaptive: test points are rendered too

    cluster = SlurmCluster(cpus=2).start()
    try:
        t0 = time.perf_counter()
        p, _ = blender(farm / "scene.blend", "-P", REPO / "bake.py", "--", *PREVIEW, "--farm", "slurm",
                       "--shards", a.shards, "--sbatch-option=--cpus-per-task=1", env={**env, **cluster.env})
        merge = re.search(r"merge job (\d+)", p.stdout).group(1)
        stages = int(re.search(r"submitted (\d+) shard array", p.stdout).group(1))
        while cluster.job_state(merge) not in (["COMPLETED"], ["FAILED"], ["CANCELLED"]):
            time.sleep(0.5)
        t_farm = time.perf_counter() - t0
        assert cluster.job_state(merge) == ["COMPLETED"], cluster.logs()
        logs = farm / "sh_coeffs" / "probes.shprobe.farm"
        merge_log = next(logs.glob("merge-*.log")).read_text()
        t_merge = float(re.search(r"bake\.py: \d+ probes in ([\d.]+) s", merge_log).group(1))
        shard_times = {}  # per array task: summed over the stages' arrays (one log per array task)
        for f in sorted(logs.glob("shard-*.log")):
            task = f.name.rsplit("_", 1)[1]
            shard_times[task] = shard_times.get(task, 0.0) + sum(
                float(x) for x in re.findall(r"bake\.py: \d+ probes in ([\d.]+) s", f.read_text()))
        shard_times = list(shard_times.values())
    finally:
        cluster.stop()
    same = (farm / "sh_coeffs" / "probes.shprobe").read_bytes() == (local / "sh_coeffs" / "probes.shprobe").read_bytes()
    per_probe_2cpu = render / points
    print(f"| bake | probes | wall time |\n|---|---|---|")
    print(f"| local, 1 Blender, 2 CPUs | {probes} | {t_local:.1f} s (placement {placement:.2f} s, render {render:.1f} s) |")
    print(f"| Slurm, {a.shards} shards x 1 CPU, {stages} chained arrays + merge | {probes} | {t_farm:.1f} s (shards "
          + ", ".join(f"{t:.1f}" for t in shard_times) + f" s; merge {t_merge:.1f} s) |")
    print(f"\nmerged file equals the local bake byte for byte: {same}")
    one_cpu = max(shard_times) / math.ceil(points / a.shards)
    print(f"points rendered: {points}; per point at 2 CPUs: {per_probe_2cpu:.3f} s; at 1 CPU (shards): "
          f"{one_cpu:.3f} s incl. each job's scene upload")
    # Per stage, the farm adds a barrier: Slurm starts the next array once every task finished, and
    # each task starts Blender and loads the scene again. Measured here as the wall time not spent
    # in the slowest shard's bakes or the merge, per stage.
    per_stage = max(0.0, t_farm - max(shard_times) - t_merge) / stages
    print(f"per-stage overhead (scheduling, Blender start, scene load): {per_stage:.1f} s over {stages} stages")
    print("\n| workers W (1 CPU each) | projected wall time |\n|---|---|")
    for w in (1, 2, 4, 8, 16, 64):
        print(f"| {w} | {math.ceil(points / w) * one_cpu + stages * per_stage + t_merge:.0f} s |")


if __name__ == "__main__":
    main()
