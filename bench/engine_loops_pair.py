"""Two schnee-view builds on lavapipe, paired: launches of OLD and NEW interleaved per configuration, on the
generated room's v3 octree and the bundled room, per object (buffers) and per pixel (bricks), 1920 x 1080,
3 frames each, --no-direct --no-sky; prints each launch's frame median and CPU-seconds, then the medians'
ratios NEW / OLD (bench/results/engine_gpu.md "Probe bricks (issue 30)": the unrolled channel-group loops
on lavapipe, and the plain build against 3ed7a26).

Usage: /usr/bin/python3 bench/engine_loops_pair.py OLD_VIEW NEW_VIEW [--rounds 2] [--dir .devgpu]
(DIR: bench/device/prep_engine_gpu.py prep's folder, whose scenes/room_v3.gltf and scenes/bundled/ it renders;
extra arguments after -- go to NEW only, e.g. -- --shader-loops unrolled).
"""
import argparse
import collections
import re
import resource
import statistics
import subprocess
from pathlib import Path

REPO = Path(__file__).resolve().parent.parent


def launch(exe, scene, mode, path, extra):
    r0 = resource.getrusage(resource.RUSAGE_CHILDREN)
    p = subprocess.run([exe, str(scene), "--headless", "--output", "/tmp/engine_loops_pair.pfm", "--width", "1920",
                        "--height", "1080", "--frames", "3", "--no-direct", "--no-sky", "--probe-mode", mode,
                        "--probe-path", path, *extra], capture_output=True, text=True, timeout=1800)
    r1 = resource.getrusage(resource.RUSAGE_CHILDREN)
    if p.returncode != 0:
        raise SystemExit(f"{exe} failed ({p.returncode}): {p.stderr}")
    cpu = r1.ru_utime - r0.ru_utime + r1.ru_stime - r0.ru_stime
    return float(re.search(r"median ([\d.]+) ms", p.stderr).group(1)), cpu


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("old")
    ap.add_argument("new")
    ap.add_argument("--rounds", type=int, default=2)
    ap.add_argument("--dir", default=str(REPO / ".devgpu"))
    ap.add_argument("extra", nargs="*")
    a = ap.parse_args()
    d = Path(a.dir) / "scenes"
    scenes = {"v3": d / "room_v3.gltf", "bundled": d / "bundled" / "scene.gltf"}
    res = collections.defaultdict(list)
    for r in range(a.rounds):
        for sc, path in scenes.items():
            for mode, pp in (("object", "buffers"), ("pixel", "bricks")):
                for b, exe in (("old", a.old), ("new", a.new)):
                    ms, cpu = launch(exe, path, mode, pp, a.extra if b == "new" else [])
                    res[(sc, mode, b)].append((ms, cpu))
                    print(f"round {r + 1} {sc} {mode} {b}: frame median {ms:.0f} ms, {cpu:.1f} CPU-s", flush=True)
    for sc in scenes:
        for mode in ("object", "pixel"):
            o, n = res[(sc, mode, "old")], res[(sc, mode, "new")]
            f = statistics.median(x[0] for x in n) / statistics.median(x[0] for x in o)
            c = statistics.median(x[1] for x in n) / statistics.median(x[1] for x in o)
            print(f"{sc} {mode}: new / old frame {f:.2f}, CPU-s {c:.2f}")


if __name__ == "__main__":
    main()
