"""Engine frame time per probe representation (docs/ambient-cube.md §6 step 4).

The generated benchmark room (tests/engine/scripts/make_room.py: 56 objects, 58 k triangles, 3200
L2 probes) rendered headless at 1280 x 720 with --probe-mode object|pixel x --probe-representation
sh|ambientCube x --probe-storage float|half, --no-direct (the probe term alone). Each
configuration runs FRAMES frames per launch (schnee-view prints their median), ROUNDS launches
interleaved over the configurations, SH and cube of one mode and storage back to back. The table
gives the median of the launch medians, their range, and the median over rounds of the paired
ratio cube / SH (the two launches next to each other in time), which cancels most of the slow load
drift of a shared machine.

Usage: /usr/bin/python3 bench/bench_engine_representations.py [--frames 7] [--rounds 3] [--out FILE]
Environment: SCHNEE_VIEW (default build/schnee-view), VK_ICD_FILENAMES as for the tests (lavapipe).
"""
import argparse
import os
import re
import statistics
import subprocess
import sys
import tempfile
from pathlib import Path

REPO = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(REPO / "tests" / "engine" / "scripts"))
import make_room  # noqa: E402

CONFIGS = [(mode, rep, storage) for mode in ("object", "pixel") for storage in ("float", "half")
           for rep in ("sh", "ambientCube")]


def run(view, scene, out, mode, rep, storage, frames):
    proc = subprocess.run([view, str(scene), "--headless", "--output", str(out), "--width", "1280", "--height", "720",
                           "--frames", str(frames), "--no-direct", "--probe-mode", mode, "--probe-representation", rep,
                           "--probe-storage", storage], capture_output=True, text=True, timeout=600)
    if proc.returncode != 0:
        raise SystemExit(f"schnee-view failed ({proc.returncode}): {proc.stderr}")
    m = re.search(r"frame\(s\) at \d+x\d+: mean ([\d.]+) ms, median ([\d.]+) ms, min ([\d.]+) ms", proc.stderr)
    dev = re.search(r"device (.*?);", proc.stderr)
    return float(m.group(2)), dev.group(1) if dev else "?"


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--frames", type=int, default=7)
    ap.add_argument("--rounds", type=int, default=3)
    ap.add_argument("--out", default=None, help="write the markdown table here (else stdout)")
    a = ap.parse_args()
    view = os.environ.get("SCHNEE_VIEW", str(REPO / "build" / "schnee-view"))
    with tempfile.TemporaryDirectory() as tmp:
        scene = make_room.main(Path(tmp) / "room")
        times = {c: [] for c in CONFIGS}
        device = "?"
        for _ in range(a.rounds):
            for c in CONFIGS:  # sh before ambientCube of the same mode and storage (CONFIGS order)
                t, device = run(view, scene, Path(tmp) / "f.png", *c, a.frames)
                times[c].append(t)
                print(c, f"{t:.0f} ms", file=sys.stderr, flush=True)
    try:
        load = os.getloadavg()[0]
    except OSError:
        load = float("nan")
    lines = [f"Device: {device}; {os.cpu_count()} CPUs, load average {load:.1f} at the end; "
             f"{a.rounds} launches x {a.frames} frames per configuration.",
             "",
             "| probe mode | representation | storage | median frame | launch medians |",
             "|---|---|---|---|---|"]
    lines[2] = "| probe mode | representation | storage | median frame | launch medians | paired cube / SH |"
    lines[3] = "|---|---|---|---|---|---|"
    for c in CONFIGS:
        med = statistics.median(times[c])
        sh = times[(c[0], "sh", c[2])]
        ratios = [x / y for x, y in zip(times[c], sh)]
        paired = "—" if c[1] == "sh" else (f"{statistics.median(ratios):.2f} "
                                           f"({min(ratios):.2f}-{max(ratios):.2f})")
        lines.append(f"| {c[0]} | {c[1]} | {c[2]} | {med:.0f} ms | {min(times[c]):.0f}-{max(times[c]):.0f} ms | "
                     f"{paired} |")
    text = "\n".join(lines) + "\n"
    if a.out:
        Path(a.out).write_text(text)
    print(text)


if __name__ == "__main__":
    main()
