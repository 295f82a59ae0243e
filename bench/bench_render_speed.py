"""Cycles' time per probe panorama in the bundled room, per Blender release, and what a light portal
at the room's window does to a probe's noise: why the room at the add-on's defaults bakes in about
12 minutes on 2 cores and not 5 (issue 12; bench/results/placement.md, "Targets").

Run on the host with its Python:

    /usr/bin/python3 bench/bench_render_speed.py [--spp 8] [--points 18] [--versions host trixie sid]

For each Blender (the host's 3.4; Debian 13's 4.3 and unstable's 5.2 in the chroots of
scripts/blender-chroot.sh, created when missing) this file runs inside Blender with ``time``: it
builds the bundled room (scenes/make_default_scene.py), sets the render up as the add-on's bake does
(128 x 64 px equirectangular camera, the given samples, 32 bounces, indirect clamp 10, no adaptive
sampling, no denoiser, persistent data) and renders one panorama at each of ``--points`` fixed
positions; the time per panorama is the mean over all but the first (which uploads the scene). It
also prints what each build offers that could cut the time: Cycles' path guiding and OpenImageDenoise.

On the host (where the add-on's native module is built) it then runs ``noise`` twice, without and
with a Cycles light portal filling the window: the add-on's ``bake_points`` at 18 seeded points with
seeds 1 and 2, the per-render noise = the relative irradiance difference of the two / sqrt(2).

Prints one ``RESULT {json}`` line per run and a summary; ``--json FILE`` keeps them.
"""
import argparse
import json
import math
import os
import shutil
import subprocess
import sys
import time

HERE = os.path.dirname(os.path.abspath(__file__))
REPO = os.path.dirname(HERE)
POINTS = [(x, y, z) for x in (-3.5, 0.0, 2.5) for y in (-3.0, 0.5, 3.5) for z in (0.6, 2.2)]


# ---------------------------------------------------------------- inside Blender
def _blender_args():
    argv = sys.argv[sys.argv.index("--") + 1:] if "--" in sys.argv else []
    ap = argparse.ArgumentParser(prog="bench_render_speed.py (in Blender)")
    ap.add_argument("mode", choices=["time", "noise"])
    ap.add_argument("--spp", type=int, default=8)
    ap.add_argument("--points", type=int, default=18)
    ap.add_argument("--portal", action="store_true")
    ap.add_argument("--scenes", default=os.path.join(REPO, "scenes"))
    return ap.parse_args(argv)


def _add_portal(scene, bpy):
    """A Cycles light portal filling the room's window (x -1.5..1.5, z 1..3 in the +Y wall at y = 5),
    emitting along -Y into the room (an area lamp emits along its local -Z)."""
    import make_default_scene as room
    x0, x1, z0, z1 = room.WINDOW
    lamp = bpy.data.lights.new("WindowPortal", 'AREA')
    lamp.shape = 'RECTANGLE'
    lamp.size, lamp.size_y = x1 - x0, z1 - z0
    if hasattr(lamp, "is_portal"):
        lamp.is_portal = True
    else:
        lamp.cycles.is_portal = True
    ob = bpy.data.objects.new("WindowPortal", lamp)
    ob.location = ((x0 + x1) / 2, room.ROOM_MAX[1], (z0 + z1) / 2)
    ob.rotation_euler = (-math.pi / 2, 0.0, 0.0)
    scene.collection.objects.link(ob)


def _time(a, bpy):
    import _cycles
    import make_default_scene as room
    scene = room.build()
    if a.portal:
        _add_portal(scene, bpy)
    for ob in bpy.data.collections["ProbeVolumes"].all_objects:
        ob.hide_render = True
    cam_data = bpy.data.cameras.new("Probe")
    cam_data.type = 'PANO'
    if hasattr(cam_data, "panorama_type"):      # Blender 4.0+
        cam_data.panorama_type = 'EQUIRECTANGULAR'
    else:
        cam_data.cycles.panorama_type = 'EQUIRECTANGULAR'
    cam = bpy.data.objects.new("Probe", cam_data)
    cam.rotation_euler = (math.pi / 2, 0.0, -math.pi / 2)
    scene.collection.objects.link(cam)
    scene.camera = cam
    r = scene.render
    r.resolution_x, r.resolution_y, r.resolution_percentage = 128, 64, 100
    r.use_persistent_data = True
    c = scene.cycles
    c.device = 'CPU'
    c.samples = a.spp
    c.max_bounces = c.diffuse_bounces = c.glossy_bounces = 32
    c.sample_clamp_indirect = 10.0
    c.use_adaptive_sampling = False
    c.use_denoising = False
    times = []
    for p in POINTS[:a.points]:
        cam.location = p
        t = time.perf_counter()
        bpy.ops.render.render(write_still=False)
        times.append(time.perf_counter() - t)
    rest = times[1:]
    return {"blender": bpy.app.version_string, "spp": a.spp, "portal": a.portal, "renders": len(times),
            "first_seconds": round(times[0], 3), "seconds_per_render": round(sum(rest) / len(rest), 4),
            "light_tree": bool(getattr(c, "use_light_tree", False)),
            "path_guiding_built": bool(getattr(_cycles, "with_path_guiding", False)),
            "openimagedenoise_built": bool(getattr(_cycles, "with_openimagedenoise", False))}


def _noise(a, bpy):
    import numpy as np
    sys.path.insert(0, HERE)
    sys.path.insert(0, os.path.join(REPO, "addon"))
    import placement_scenes
    import schnee_probes
    from schnee_probes import adaptive, bake_core, scene_export
    sc = placement_scenes.build("room")
    if a.portal:
        _add_portal(bpy.context.scene, bpy)
    schnee_probes.register()
    scene, layer = bpy.context.scene, bpy.context.view_layer
    pts = scene_export.blender_to_engine(np.array(placement_scenes.points(sc, a.points, 2024)))
    out = {}
    for seed in (1, 2):
        s = bake_core.BakeSettings(panorama_resolution=128, samples=a.spp, max_bounces=32, capture_sky=False,
                                   probe_limit=0, seed=seed, output_path=os.path.join("/tmp", "unused.shprobe"))
        t = time.perf_counter()
        out[seed] = bake_core.bake_points(scene, layer, s, pts, log=lambda m: None)
        out[f"t{seed}"] = (time.perf_counter() - t) / len(pts)
    noise = adaptive.irradiance_error(out[1], out[2]) / math.sqrt(2)
    return {"blender": bpy.app.version_string, "spp": a.spp, "portal": a.portal, "points": len(pts),
            "noise_per_render_mean": round(float(noise.mean()), 5),
            "noise_per_render_median": round(float(np.median(noise)), 5),
            "seconds_per_point": round(0.5 * (out["t1"] + out["t2"]), 4),
            "coefficients_seed1": np.asarray(out[1]).round(6).tolist()}


def blender_main():
    import bpy
    a = _blender_args()
    sys.path.insert(0, a.scenes)
    res = _time(a, bpy) if a.mode == "time" else _noise(a, bpy)
    print("RESULT " + json.dumps(res), flush=True)


# ---------------------------------------------------------------- driver on the host
def _result(text):
    lines = [ln[ln.index("RESULT {") + 7:] for ln in text.splitlines() if "RESULT {" in ln]
    if not lines:
        raise SystemExit("bench_render_speed: no RESULT line:\n" + text[-3000:])
    return json.loads(lines[-1])


def _run_host(args, timeout=1800):
    p = subprocess.run(["blender", "-b", "--factory-startup", "-P", os.path.abspath(__file__), "--", *args],
                       capture_output=True, text=True, timeout=timeout)
    return _result(p.stdout + p.stderr)


def _run_chroot(suite, args, timeout=1800):
    chroot = os.path.join(REPO, "scripts", "blender-chroot.sh")
    root = subprocess.run([chroot, "ensure", suite], capture_output=True, text=True, check=True,
                          timeout=1800).stdout.strip().splitlines()[-1]
    inner = f"/tmp/schnee-render-speed-{os.getpid()}"
    outer = root + inner
    shutil.rmtree(outer, ignore_errors=True)
    os.makedirs(outer)
    try:
        shutil.copy(os.path.abspath(__file__), outer)
        shutil.copytree(os.path.join(REPO, "scenes"), os.path.join(outer, "scenes"))
        p = subprocess.run([chroot, "run", suite, "--", "blender", "-b", "--factory-startup", "-P",
                            f"{inner}/bench_render_speed.py", "--", *args, "--scenes", f"{inner}/scenes"],
                           capture_output=True, text=True, timeout=timeout)
        return _result(p.stdout + p.stderr)
    finally:
        shutil.rmtree(outer, ignore_errors=True)


def driver_main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--spp", type=int, default=8)
    ap.add_argument("--points", type=int, default=18)
    ap.add_argument("--versions", nargs="+", default=["host", "trixie", "sid"])
    ap.add_argument("--no-noise", action="store_true", help="skip the portal noise runs (host add-on)")
    ap.add_argument("--json", default=None, help="write every RESULT here")
    a = ap.parse_args()
    common = ["--spp", str(a.spp), "--points", str(a.points)]
    results = []
    for v in a.versions:
        r = _run_host(["time", *common]) if v == "host" else _run_chroot(v, ["time", *common])
        results.append(r)
        print(f"Blender {r['blender']}: {r['seconds_per_render']:.3f} s per 128x64 panorama at {a.spp} spp "
              f"(light tree {r['light_tree']}, path guiding built {r['path_guiding_built']}, "
              f"OpenImageDenoise built {r['openimagedenoise_built']})", flush=True)
    if not a.no_noise:
        for portal in (False, True):
            r = _run_host(["noise", *common] + (["--portal"] if portal else []))
            results.append(r)
            print(f"host add-on, portal {portal}: noise per render {100 * r['noise_per_render_mean']:.2f} % mean, "
                  f"{100 * r['noise_per_render_median']:.2f} % median, {r['seconds_per_point']:.3f} s per point",
                  flush=True)
        a0, a1 = results[-2]["coefficients_seed1"], results[-1]["coefficients_seed1"]
        diff = max(abs(x - y) for p, q in zip(a0, a1) for u, w in zip(p, q) for x, y in zip(u, w))
        print(f"largest coefficient change the portal made at seed 1: {diff:.4g}")
        for r in results[-2:]:
            r.pop("coefficients_seed1")
        results.append({"portal_max_coefficient_change_seed1": diff})
    if a.json:
        with open(a.json, "w", encoding="utf-8") as f:
            json.dump(results, f, indent=1)


if __name__ == "__main__":
    import importlib.util
    if importlib.util.find_spec("bpy") is None:
        driver_main()
    else:
        blender_main()
