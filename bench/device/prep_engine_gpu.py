"""The engine on a real GPU: prepares what bench/device/engine_gpu.sh runs on a lent GPU machine, and
compares the frame it brings back with lavapipe's (bench/results/engine_gpu.md).

The GPU machines have no OpenImageIO and no Debian packages, so this puts into DIR (default .devgpu,
a folder of the repo root that .git/info/exclude ignores and the device call carries):
  bin/schnee-view-noimage  the viewer without OpenImageIO (engine/CMakeLists.txt)
  lib.tar.xz               (lib/ packed: the tree and DIR travel within 64 MiB; engine_gpu.sh unpacks it)
                           its shared libraries outside glibc and libstdc++ (Vulkan loader, Embree,
                           TBB, qhull, cJSON, GLFW and GLFW's X11 libraries), from this machine
  scenes/                  the generated benchmark room (tests/engine/scripts/make_room.py: 56 objects,
                           58 k triangles, a realtime point lamp, a 20 x 8 x 20 v1 grid of 3200 probes),
                           the same room with bench_engine_v3's corner octree, and that octree room
                           with a mixed sun added (4 cascades + the lamp's 6 cube faces: 10 layers)
  ref_lavapipe.exr         the frame engine_gpu.sh writes as a PFM, rendered here on lavapipe
  scenes/bundled/          the bundled room's export (out/default/gltf, scripts/main_job.py), when there,
                           and ref_bundled_lavapipe.exr: its frame per pixel from the bricks, --no-sky (no
                           EXR reader there); SET=bricks writes frame_bundled.pfm, and compare picks the
                           reference by the frame's name

Usage:
  /usr/bin/python3 bench/device/prep_engine_gpu.py prep [DIR] [--old BINARY]
      (--old: a schnee-view-noimage of an earlier commit, timed beside the current one)
  (device) bash bench/device/engine_gpu.sh DIR          -> $OUT/engine_gpu.log, $OUT/frame.pfm
  /usr/bin/python3 bench/device/prep_engine_gpu.py compare FRAME.pfm [DIR]
"""
import json
import math
import shutil
import subprocess
import sys
from pathlib import Path

import numpy as np

REPO = Path(__file__).resolve().parents[2]
sys.path.insert(0, str(REPO / "bench"))
sys.path.insert(0, str(REPO / "tests" / "engine" / "scripts"))
import bench_engine_v3  # noqa: E402
import make_room  # noqa: E402
import viewer  # noqa: E402

SKIP = ("libc.so", "libm.so", "libdl.so", "libpthread.so", "librt.so", "libstdc++.so", "libgcc_s.so", "ld-linux",
        "linux-vdso")
FRAME_ARGS = ["--width", "640", "--height", "360", "--probe-mode", "pixel"]  # the frame compared (engine_gpu.sh)
BUNDLED = REPO / "out" / "default" / "gltf"  # the bundled room's export (scripts/main_job.py), SET=bricks


def add_sun(src, dst):
    """src's glTF plus a mixed directional light (the sun, 50° up, from the south-west)."""
    doc = json.loads(Path(src).read_text())
    lights = doc.setdefault("extensions", {}).setdefault("KHR_lights_punctual", {}).setdefault("lights", [])
    lights.append({"name": "Sun", "type": "directional", "color": [1.0, 0.95, 0.9], "intensity": 3.0,
                   "extensions": {"VULKAN_SCHNEE_light": {"mode": "mixed"}}})
    d = np.array([0.5, -math.tan(math.radians(50.0)), -0.7])
    d /= np.linalg.norm(d)
    # The node's -Z turned onto d: axis (-Z) x d, angle acos(-Z . d).
    axis = np.cross([0.0, 0.0, -1.0], d)
    angle = math.acos(float(np.clip(-d[2], -1, 1)))
    q = list(axis / np.linalg.norm(axis) * math.sin(angle / 2)) + [math.cos(angle / 2)]
    doc["nodes"].append({"name": "Sun", "rotation": q, "extensions": {"KHR_lights_punctual": {"light": len(lights) - 1}}})
    doc["scenes"][0]["nodes"].append(len(doc["nodes"]) - 1)
    Path(dst).write_text(json.dumps(doc))
    return Path(dst)


def prep(out, old=None):
    out = Path(out)
    view = REPO / "build" / "schnee-view-noimage"
    if not view.exists():
        raise SystemExit(f"{view} is missing: cmake --build build")
    shutil.rmtree(out, ignore_errors=True)
    (out / "bin").mkdir(parents=True)
    (out / "lib").mkdir()
    shutil.copy2(view, out / "bin")
    if old:
        shutil.copy2(old, out / "bin" / "schnee-view-noimage.old")
    ldd = subprocess.run(["ldd", str(view)], capture_output=True, text=True, check=True).stdout
    for line in ldd.splitlines():
        parts = line.split("=>")
        if len(parts) != 2 or not parts[1].strip().startswith("/"):
            continue
        name, path = parts[0].strip(), parts[1].split()[0]
        if not name.startswith(SKIP):
            shutil.copy2(Path(path).resolve(), out / "lib" / name)
    subprocess.run(["tar", "cJf", "lib.tar.xz", "lib"], cwd=out, check=True)
    shutil.rmtree(out / "lib")
    room = make_room.main(out / "scenes")
    v3, probes, hanging, leaves = bench_engine_v3.octree_scene(room)
    sun = add_sun(v3, out / "scenes" / "room_v3_sun.gltf")
    print(f"room: 3200-probe grid; octree: {probes} probes, {hanging} hanging, {leaves} leaves; {sun.name}")
    viewer.check(viewer.run(sun, "--headless", "--output", out / "ref_lavapipe.exr", *FRAME_ARGS, validation=False))
    if BUNDLED.joinpath("scene.gltf").exists():
        shutil.copytree(BUNDLED, out / "scenes" / "bundled")
        viewer.check(viewer.run(out / "scenes" / "bundled" / "scene.gltf", "--headless", "--output",
                                out / "ref_bundled_lavapipe.exr", *FRAME_ARGS, "--probe-path", "bricks", "--no-sky",
                                validation=False))
    else:
        print(f"note: {BUNDLED / 'scene.gltf'} is missing (scripts/main_job.py makes it): SET=bricks needs it")
    size = sum(f.stat().st_size for f in out.rglob("*") if f.is_file())
    print(f"{out}: {size / 2**20:.1f} MiB")


def compare(frame, out):
    ref_name = "ref_bundled_lavapipe.exr" if Path(frame).name == "frame_bundled.pfm" else "ref_lavapipe.exr"
    got = viewer.read_image(frame)[..., :3]
    ref = viewer.read_image(Path(out) / ref_name)[..., :3]
    d = np.abs(got - ref)
    rel = d.max(-1) / np.maximum(ref.max(-1), 1e-3)
    print(f"GPU frame vs lavapipe ({ref.shape[1]}x{ref.shape[0]}, linear HDR): max abs {d.max():.3g}, mean abs "
          f"{d.mean():.3g}, mean |ref| {np.abs(ref).mean():.3g}; relative per pixel: median {np.median(rel):.2g}, "
          f"99th percentile {np.percentile(rel, 99):.2g}, max {rel.max():.2g}; pixels off by > 1 %: "
          f"{(rel > 0.01).mean() * 100:.2f} %")


if __name__ == "__main__":
    if len(sys.argv) >= 2 and sys.argv[1] == "prep":
        args = sys.argv[2:]
        old = None
        if "--old" in args:
            k = args.index("--old")
            old = args[k + 1]
            del args[k:k + 2]
        prep(args[0] if args else REPO / ".devgpu", old)
    elif len(sys.argv) >= 3 and sys.argv[1] == "compare":
        compare(sys.argv[2], sys.argv[3] if len(sys.argv) > 3 else REPO / ".devgpu")
    else:
        raise SystemExit(__doc__)
