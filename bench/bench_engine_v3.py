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
Environment: SCHNEE_VIEW (default build/schnee-view), VK_ICD_FILENAMES as for the tests (lavapipe).
"""
import argparse
import json
import os
import re
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


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--frames", type=int, default=5)
    ap.add_argument("--rounds", type=int, default=3)
    ap.add_argument("--width", type=int, default=640)
    ap.add_argument("--height", type=int, default=360)
    ap.add_argument("--octree-only", action="store_true")
    a = ap.parse_args()
    configs = [c for c in CONFIGS if not (a.octree_only and c[1] == "v1 grid")]
    view = os.environ.get("SCHNEE_VIEW", str(REPO / "build" / "schnee-view"))
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
