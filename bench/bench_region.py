"""Region rebake against a full bake (issue 31 item 3, docs/region-rebake.md): the bundled room
(scenes/make_default_scene.py) with its probe volume split into four quarters (Blender x < 0 / x > 0
by y < 0 / y > 0, each 5 x 5 x 4 m, One File per Volume), baked whole; then the Table (in the
quarter x < 0, y < 0) moved 0.5 m along +x inside its quarter, and the edited scene baked twice: whole
(what one would do without a rebake) and ``--only-volume RoomSW`` beside the first bake's files.
Reports wall seconds, CPU seconds (the Blender process and its threads) and renders of each, and
checks that the rebake left the other three volumes' files and sky.exr byte for byte.

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
QUARTERS = {"RoomSW": ((-5.0, -5.0, 0.0), (0.0, 0.0, 4.0)), "RoomSE": ((0.0, -5.0, 0.0), (5.0, 0.0, 4.0)),
            "RoomNW": ((-5.0, 0.0, 0.0), (0.0, 5.0, 4.0)), "RoomNE": ((0.0, 0.0, 0.0), (5.0, 5.0, 4.0))}
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
    """bake.py on ``blend``: (wall s, CPU s of Blender and its threads, renders, probes, stdout)."""
    cmd = ["blender", "-b", blend, "--factory-startup", "-P", os.path.join(REPO, "bake.py"), "--", *args]
    cpu0 = resource.getrusage(resource.RUSAGE_CHILDREN)
    t0 = time.perf_counter()
    proc = subprocess.run(cmd, capture_output=True, text=True, env={**os.environ, "PYTHONPATH": ""})
    wall = time.perf_counter() - t0
    cpu1 = resource.getrusage(resource.RUSAGE_CHILDREN)
    if proc.returncode != 0:
        sys.exit(f"bake failed ({' '.join(cmd)}):\n{proc.stdout[-3000:]}\n{proc.stderr[-3000:]}")
    cpu = (cpu1.ru_utime - cpu0.ru_utime) + (cpu1.ru_stime - cpu0.ru_stime)
    probes = int(re.search(r"bake\.py: (\d+) probes in", proc.stdout).group(1))
    m = re.search(r"(\d+) points rendered \(probes and test points; (\d+) more rounds", proc.stdout)
    renders = int(m.group(1)) + int(m.group(2)) if m else probes
    return dict(wall=round(wall, 2), cpu=round(cpu, 2), renders=renders, probes=probes), proc.stdout


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
    prev, edit, full = (os.path.join(out, d) for d in ("previous", "rebake", "full"))
    for d in (prev, edit, full):
        shutil.rmtree(d, ignore_errors=True)
        os.makedirs(d)
    shutil.copy(os.path.join(out, "room4.blend"), prev)
    first, _ = _bake(os.path.join(prev, "room4.blend"), args)
    shutil.copytree(os.path.join(prev, "sh_coeffs"), os.path.join(edit, "sh_coeffs"))
    for d in (edit, full):
        shutil.copy(os.path.join(out, "room4_edited.blend"), d)
    whole, _ = _bake(os.path.join(full, "room4_edited.blend"), args)
    rebake, log = _bake(os.path.join(edit, "room4_edited.blend"), args + ["--only-volume", "RoomSW"])
    kept = sorted(n for n in os.listdir(os.path.join(prev, "sh_coeffs"))
                  if n not in ("RoomSW.shprobe", "probes.shprobe.bake.json"))
    same = {n: _sha(os.path.join(prev, "sh_coeffs", n)) == _sha(os.path.join(edit, "sh_coeffs", n)) for n in kept}
    rebaked_equal = _sha(os.path.join(full, "sh_coeffs", "RoomSW.shprobe")) == \
        _sha(os.path.join(edit, "sh_coeffs", "RoomSW.shprobe"))
    result = dict(bake_args=a.bake_args, first_full=first, full=whole, rebake=rebake, kept_identical=same,
                  rebaked_equals_full=rebaked_equal, load=os.getloadavg(),
                  ratio={k: round(rebake[k] / whole[k], 3) for k in ("wall", "cpu", "renders")})
    with open(os.path.join(out, "region.json"), "w") as fh:
        json.dump(result, fh, indent=2)
    print("| bake | probes | renders | wall s | CPU s |\n|---|---|---|---|---|")
    for name, r in (("full, before the edit", first), ("full, edited", whole), ("rebake RoomSW, edited", rebake)):
        print(f"| {name} | {r['probes']} | {r['renders']} | {r['wall']} | {r['cpu']} |")
    print(f"\nratio rebake / full: {result['ratio']}; kept files byte-identical: {same}; "
          f"RoomSW rebaked = RoomSW of the full edited bake: {rebaked_equal}")


if __name__ == "__main__":
    if "--make" in sys.argv:
        make_scenes(sys.argv[sys.argv.index("--make") + 1])
    else:
        main()
