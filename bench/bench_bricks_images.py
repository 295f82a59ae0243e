"""Per-pixel images from the probe bricks against the storage-buffer path on the engine bench scenes
(issue 30, "per-pixel images equal the CPU model within 0.5 % RMS").

The storage-buffer path is the one the engine tests hold to the CPU model at about 1e-4
(tests/engine/test_engine_v3.py, test_engine_perpixel.py: --probe-path buffers); the bricks' own GLSL is
compared with the C core in test_engine_bricks*.py and test_engine_grid_field.py. This script renders the
same frames both ways and reports the relative RMS over the image (linear EXR, --no-direct, per pixel):
the generated room (tests/engine/scripts/make_room.py) as a v1 dense grid and as a v3 octree (the scenes
of bench/bench_engine_v3.py), and the bundled room's export when given.

Usage: /usr/bin/python3 bench/bench_bricks_images.py [--bundled out/default/gltf/scene.gltf] [--json OUT]
Environment: SCHNEE_VIEW (default build/schnee-view), VK_ICD_FILENAMES for lavapipe.
"""
import argparse
import json
import os
import subprocess
import sys
import tempfile
from pathlib import Path

import numpy as np

REPO = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(REPO / "bench"))
sys.path.insert(0, str(REPO / "addon"))
import bench_engine_v3  # noqa: E402
from schnee_probes import exr  # noqa: E402


def render(view, scene, out, path, w, h):
    subprocess.run([view, str(scene), "--headless", "--output", str(out), "--width", str(w), "--height", str(h),
                    "--frames", "1", "--no-direct", "--probe-mode", "pixel", "--probe-path", path],
                   check=True, capture_output=True, timeout=600)
    return np.asarray(exr.read(str(out)), dtype=np.float64)[..., :3]


def compare(bricks, buffers):
    lit = buffers.max(-1) > 1e-4
    d = bricks[lit] - buffers[lit]
    rel = np.abs(d).max(-1) / np.maximum(buffers[lit].max(-1), 1e-6)
    return {"pixels": int(lit.sum()),
            "rel_rms": float(np.sqrt((d ** 2).mean() / (buffers[lit] ** 2).mean())),
            "max_abs": float(np.abs(d).max()),
            "p99_rel": float(np.quantile(rel, 0.99)),
            "max_rel": float(rel.max())}


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--bundled", default=str(REPO / "out" / "default" / "gltf" / "scene.gltf"))
    ap.add_argument("--width", type=int, default=640)
    ap.add_argument("--height", type=int, default=360)
    ap.add_argument("--json", default=None)
    a = ap.parse_args()
    view = os.environ.get("SCHNEE_VIEW", str(REPO / "build" / "schnee-view"))
    result = {}
    with tempfile.TemporaryDirectory() as tmp:
        tmp = Path(tmp)
        room = bench_engine_v3.make_room.main(tmp / "room")
        scenes = {"v1": room, "v3": bench_engine_v3.octree_scene(room)[0]}
        if a.bundled and Path(a.bundled).exists():
            scenes["bundled"] = Path(a.bundled)
        for name, scene in scenes.items():
            images = {p: render(view, scene, tmp / f"{name}_{p}.exr", p, a.width, a.height)
                      for p in ("bricks", "buffers")}
            result[name] = compare(images["bricks"], images["buffers"])
            r = result[name]
            print(f"{name}: relative RMS {100 * r['rel_rms']:.3f} %, p99 {100 * r['p99_rel']:.3f} %, "
                  f"max {100 * r['max_rel']:.2f} % ({r['pixels']} pixels)", flush=True)
    if a.json:
        Path(a.json).write_text(json.dumps(result, indent=1) + "\n")


if __name__ == "__main__":
    main()
