"""Region rebake against a full bake (issue 31 item 3, docs/region-rebake.md): the bundled room
(scenes/make_default_scene.py) with its probe volume split into four quarters (Blender x < 0 / x > 0
by y < 0 / y > 0, each 5 x 5 x 4 m, One File per Volume), baked whole; then the Table (in the
quarter x < 0, y < 0) moved 0.5 m along +x inside its quarter, and the edited scene baked twice: whole
(what one would do without a rebake), ``--only-volume RoomSW`` beside the first bake's files, and
``--only-volume RoomSW --region`` a box around the Table's old and new places (REGION). Reports
wall seconds, CPU seconds (the Blender process and its threads) and renders of each, checks that
the rebakes left the other three volumes' files and sky.exr byte for byte, and counts RoomSW's
probes outside the region whose coefficients are the previous bake's bits.

    /usr/bin/python3 bench/bench_region.py OUT_DIR [--bake-args "..."]

The default bake arguments are the main job's preview settings (Adaptive, Min/Max Cell 1/4 m,
64x32 px, 16 spp, 6 bounces). Writes OUT_DIR/region.json and prints a Markdown table.
"""
import argparse
import hashlib
import json
import os
import re
import resource
import shutil
import subprocess
import sys
import time

HERE = os.path.dirname(os.path.abspath(__file__))
REPO = os.path.dirname(HERE)
COUNT = os.path.join(REPO, "tests", "blender", "scripts", "count_renders.py")
QUARTERS = {"RoomSW": ((-5.0, -5.0, 0.0), (0.0, 0.0, 4.0)), "RoomSE": ((0.0, -5.0, 0.0), (5.0, 0.0, 4.0)),
            "RoomNW": ((-5.0, 0.0, 0.0), (0.0, 5.0, 4.0)), "RoomNE": ((0.0, 0.0, 0.0), (5.0, 5.0, 4.0))}
# Blender coordinates: the Table's old (x -3..-1) and new (-2.5..-0.5) places, y -3..-2, z 0..1, with 0.5 m.
REGION = ("-3.5", "-3.5", "0", "0", "-1.5", "1.5")
PREVIEW = ("--placement ADAPTIVE --min-cell-size 1 --max-cell-size 4 --panorama-resolution 64 --samples 16 "
           "--max-bounces 6")


def make_scenes(out):
    """In Blender: room4.blend (the bundled room, four volumes) and room4_edited.blend (Table moved)."""
    import bpy
    sys.path.insert(0, os.path.join(REPO, "scenes"))
    sys.path.insert(0, os.path.join(REPO, "addon"))
    import make_default_scene
    import scene_lib as lib
    make_default_scene.build()
    bpy.data.objects.remove(bpy.data.objects["RoomVolume"], do_unlink=True)
    for name, (a, b) in QUARTERS.items():
        lib.probe_volume(name, a, b)
    lib.save(os.path.join(out, "room4.blend"))
    bpy.data.objects["Table"].location.x += 0.5   # -3..-1 -> -2.5..-0.5: still inside RoomSW
    lib.save(os.path.join(out, "room4_edited.blend"))


def _sha(path):
    with open(path, "rb") as fh:
        return hashlib.sha256(fh.read()).hexdigest()


def _bake(blend, args):
    """bake.py on ``blend``: (wall s, CPU s of Blender and its threads, Cycles renders (counted by
    tests/blender/scripts/count_renders.py, the sky's included), probes, stdout)."""
    log = blend + ".renders"
    cmd = ["blender", "-b", blend, "--factory-startup", "-P", COUNT, "-P", os.path.join(REPO, "bake.py"), "--", *args]
    cpu0 = resource.getrusage(resource.RUSAGE_CHILDREN)
    t0 = time.perf_counter()
    proc = subprocess.run(cmd, capture_output=True, text=True,
                          env={**os.environ, "PYTHONPATH": "", "SCHNEE_TEST_RENDER_LOG": log})
    wall = time.perf_counter() - t0
    cpu1 = resource.getrusage(resource.RUSAGE_CHILDREN)
    if proc.returncode != 0:
        sys.exit(f"bake failed ({' '.join(cmd)}):\n{proc.stdout[-3000:]}\n{proc.stderr[-3000:]}")
    cpu = (cpu1.ru_utime - cpu0.ru_utime) + (cpu1.ru_stime - cpu0.ru_stime)
    probes = int(re.search(r"bake\.py: (\d+) probes in", proc.stdout).group(1))
    with open(log) as fh:
        renders = len(fh.read().splitlines())
    return dict(wall=round(wall, 2), cpu=round(cpu, 2), renders=renders, probes=probes), proc.stdout


def _outside(prev, part):
    """RoomSW's probes of the region rebake whose position lies outside REGION, in three kinds:
    corners of a leaf that meets REGION (decided again, their rounds too), on a face RoomSW shares
    with another volume (a full bake gives those the rounds either volume asks for, a rebake of one
    only its own) and the rest; how many of each hold the previous bake's coefficient bits."""
    sys.path.insert(0, os.path.join(REPO, "addon"))
    import numpy as np
    from schnee_probes import native
    old, new = (native.read_shprobe(os.path.join(d, "sh_coeffs", "RoomSW.shprobe")) for d in (prev, part))
    box = np.array([float(v) for v in REGION]).reshape(2, 3)
    lo = np.array([box[0, 0], box[0, 2], -box[1, 1]])   # Blender (x, y, z) -> engine (x, z, -y)
    hi = np.array([box[1, 0], box[1, 2], -box[0, 1]])
    leaves = np.asarray(new.leaves, dtype=np.float64)
    llo = np.asarray(new.grid_origin) + leaves[:, :3] * new.grid_spacing
    lhi = llo + new.grid_spacing * 2.0 ** leaves[:, 3:4]
    meets = np.all((llo <= hi) & (lhi >= lo), axis=1)
    corners = {tuple(np.round([(a if i >> k & 1 == 0 else b)[k] for k in range(3)], 4))
               for a, b in zip(llo[meets], lhi[meets]) for i in range(8)}
    before = {tuple(p): c.tobytes() for p, c in zip(np.asarray(old.positions), np.asarray(old.coeffs))}
    kinds = {k: [0, 0] for k in ("meeting_leaves", "shared_faces", "rest")}
    for p, c in zip(np.asarray(new.positions), np.asarray(new.coeffs)):
        if np.all(p >= lo) and np.all(p <= hi):
            continue
        kind = ("meeting_leaves" if tuple(np.round(p.astype(np.float64), 4)) in corners
                else "shared_faces" if abs(p[0]) < 0.02 or abs(p[2]) < 0.02 else "rest")
        kinds[kind][0] += 1
        kinds[kind][1] += before.get(tuple(p)) == c.tobytes()
    return dict(probes=int(len(new.positions)), previous_probes=int(len(old.positions)),
                **{k: dict(probes=v[0], identical=v[1]) for k, v in kinds.items()})


def main():
    p = argparse.ArgumentParser()
    p.add_argument("out")
    p.add_argument("--bake-args", default=PREVIEW)
    a = p.parse_args()
    out = os.path.abspath(a.out)
    os.makedirs(out, exist_ok=True)
    subprocess.run(["blender", "-b", "--factory-startup", "-P", os.path.abspath(__file__), "--", "--make", out],
                   check=True, capture_output=True)
    args = a.bake_args.split() + ["--per-volume-files", "on"]
    prev, edit, full, part = (os.path.join(out, d) for d in ("previous", "rebake", "full", "region"))
    for d in (prev, edit, full, part):
        shutil.rmtree(d, ignore_errors=True)
        os.makedirs(d)
    shutil.copy(os.path.join(out, "room4.blend"), prev)
    first, _ = _bake(os.path.join(prev, "room4.blend"), args)
    for d in (edit, part):
        shutil.copytree(os.path.join(prev, "sh_coeffs"), os.path.join(d, "sh_coeffs"))
    for d in (edit, full, part):
        shutil.copy(os.path.join(out, "room4_edited.blend"), d)
    whole, _ = _bake(os.path.join(full, "room4_edited.blend"), args)
    rebake, _ = _bake(os.path.join(edit, "room4_edited.blend"), args + ["--only-volume", "RoomSW"])
    region, _ = _bake(os.path.join(part, "room4_edited.blend"), args + ["--only-volume", "RoomSW", "--region", *REGION])
    kept = sorted(n for n in os.listdir(os.path.join(prev, "sh_coeffs"))
                  if n not in ("RoomSW.shprobe", "probes.shprobe.bake.json", "probes.shprobe.points"))
    same = {f"{d}/{n}": _sha(os.path.join(prev, "sh_coeffs", n)) == _sha(os.path.join(out, d, "sh_coeffs", n))
            for n in kept for d in ("rebake", "region")}
    rebaked_equal = _sha(os.path.join(full, "sh_coeffs", "RoomSW.shprobe")) == \
        _sha(os.path.join(edit, "sh_coeffs", "RoomSW.shprobe"))
    result = dict(bake_args=a.bake_args, first_full=first, full=whole, rebake=rebake, region=region,
                  region_box=REGION, kept_identical=same, rebaked_equals_full=rebaked_equal,
                  region_probes=_outside(prev, part), load=os.getloadavg(),
                  ratio={k: round(rebake[k] / whole[k], 3) for k in ("wall", "cpu", "renders")},
                  ratio_region={k: round(region[k] / whole[k], 3) for k in ("wall", "cpu", "renders")})
    with open(os.path.join(out, "region.json"), "w") as fh:
        json.dump(result, fh, indent=2)
    print("| bake | probes | renders | wall s | CPU s |\n|---|---|---|---|---|")
    for name, r in (("full, before the edit", first), ("full, edited", whole), ("rebake RoomSW, edited", rebake),
                    ("rebake RoomSW --region, edited", region)):
        print(f"| {name} | {r['probes']} | {r['renders']} | {r['wall']} | {r['cpu']} |")
    print(f"\nratio rebake / full: {result['ratio']}; region / full: {result['ratio_region']}; kept files "
          f"byte-identical: {same}; RoomSW rebaked = RoomSW of the full edited bake: {rebaked_equal}; RoomSW's "
          f"probes outside the region: {result['region_probes']}")


if __name__ == "__main__":
    if "--make" in sys.argv:
        make_scenes(sys.argv[sys.argv.index("--make") + 1])
    else:
        main()
