"""Cost per probe of the direct-light step (issue 11, docs/direct-light.md) next to path tracing.

    blender -b --factory-startup -P bench/bench_direct.py -- [--cell 2.0] [--repeat-probes 1000]

One bake at the add-on's defaults (128x64, 32 spp, band 2) of a 6 x 6 x 3 m room with a window
(north wall), lit by a Sun lamp (2° disc, through the window), a point lamp (r 0.1 m), a spot lamp
(r 0.05 m) and a 1 m square area lamp under forest.exr, then the same room under a Nishita Sky
Texture (the world captured by Cycles instead of read). Prints a Markdown table per world: path
tracing (render) per probe, the sky's per-panorama add (alpha read + table sum) per probe, the sky
table (once per bake: world read or captured and binned), the lamps' projection with shadow rays
per probe (all probes at once in the bake; again over --repeat-probes probes spread in the room
for a steadier figure). bench/results/direct.md holds the last run.
"""
import argparse
import math
import os
import sys
import tempfile
import time

import bpy
import numpy as np

HERE = os.path.dirname(os.path.abspath(__file__))
REPO = os.path.dirname(HERE)
sys.path.insert(0, os.path.join(REPO, "scenes"))
sys.path.insert(0, os.path.join(REPO, "addon"))
import scene_lib as lib  # noqa: E402
import schnee_probes  # noqa: E402
from schnee_probes import bake_core, native  # noqa: E402

p = argparse.ArgumentParser()
p.add_argument("--cell", type=float, default=2.0, help="min = max cell size of the probe volume (m)")
p.add_argument("--repeat-probes", type=int, default=1000)
a = p.parse_args(sys.argv[sys.argv.index("--") + 1:] if "--" in sys.argv else [])


def lamp(name, kind, loc, rot=(0.0, 0.0, 0.0), **props):
    data = bpy.data.lights.new(name, kind)
    for k, v in props.items():
        setattr(data, k, v)
    ob = bpy.data.objects.new(name, data)
    ob.location = loc
    ob.rotation_euler = rot
    ob["schnee_light_mode"] = "baked"  # the analytic direct light is what is timed (a Sun defaults to mixed)
    bpy.context.scene.collection.objects.link(ob)
    return ob


def room():
    lib.clear_scene()
    white = lib.diffuse_material("White", (0.8, 0.8, 0.8))
    lib.room_walls((-3.0, -3.0, 0.0), (3.0, 3.0, 3.0), material=white, window=(-1.0, 1.0, 0.8, 2.4))
    lib.box("Table", (-0.6, -0.6, 0.0), (0.6, 0.6, 0.8), material=white)
    lamp("Sun", 'SUN', (0.0, 0.0, 10.0), (math.radians(50.0), 0.0, math.radians(180.0)), energy=3.0,
         angle=math.radians(2.0))
    lamp("Point", 'POINT', (-2.0, -2.0, 2.5), energy=200.0, shadow_soft_size=0.1)
    lamp("Spot", 'SPOT', (2.0, -2.0, 2.8), energy=300.0, shadow_soft_size=0.05, spot_size=math.radians(60.0),
         spot_blend=0.2)
    lamp("Area", 'AREA', (0.0, 0.0, 2.95), energy=100.0, size=1.0)
    lib.probe_volume("Volume", (-2.5, -2.5, 0.3), (2.5, 2.5, 2.7))


def nishita():
    world = bpy.context.scene.world
    nt = world.node_tree
    nt.nodes.clear()
    sky = nt.nodes.new("ShaderNodeTexSky")
    sky.sky_type = 'NISHITA'
    sky.sun_elevation = math.radians(25.0)
    bg = nt.nodes.new("ShaderNodeBackground")
    out = nt.nodes.new("ShaderNodeOutputWorld")
    nt.links.new(sky.outputs["Color"], bg.inputs["Color"])
    nt.links.new(bg.outputs["Background"], out.inputs["Surface"])


def run(label, out):
    settings = bake_core.BakeSettings(min_cell_size=a.cell, max_cell_size=a.cell, capture_sky=False,
                                      output_path=os.path.join(out, label, "probes.shprobe"))
    job = bake_core.ProbeBake(bpy.context.scene, bpy.context.view_layer, settings, log=lambda *_: None)
    result = job.run()
    t, n = result.timings, job.total
    plan = job.direct
    # The lamps' projection again over many probes (the bake did all its probes in one call).
    rng = np.random.default_rng(1)
    pts = np.column_stack([rng.uniform(-2.5, 2.5, a.repeat_probes), rng.uniform(0.3, 2.7, a.repeat_probes),
                           rng.uniform(-2.5, 2.5, a.repeat_probes)])   # engine space (x, z, -y)
    t0 = time.perf_counter()
    plan.project(pts, settings.max_band)
    many = (time.perf_counter() - t0) / a.repeat_probes
    sky_add = t.get("sky_direct", 0.0) / n
    direct = t.get("direct", 0.0) / n
    render = t["render"] / n
    print(f"\n### {label}: {n} probes, {len(plan.lamps)} lamps analytic ({plan.samples} shadow rays each), "
          f"world: {plan.sky_source}\n")
    print("| step | per probe | share of path tracing |\n|---|---|---|")
    print(f"| path tracing (Cycles render) | {render * 1e3:.0f} ms | 100 % |")
    print(f"| sky add (alpha read + table sum) | {sky_add * 1e3:.1f} ms | {100 * sky_add / render:.2f} % |")
    print(f"| lamps, in the bake ({n} probes in one call) | {direct * 1e3:.2f} ms | {100 * direct / render:.3f} % |")
    print(f"| lamps, {a.repeat_probes} probes in one call | {many * 1e3:.2f} ms | {100 * many / render:.3f} % |")
    print(f"| sky table, once per bake | {t.get('sky_table', 0.0):.2f} s total | "
          f"{100 * t.get('sky_table', 0.0) / (render * n):.1f} % of this bake's path tracing |")
    sys.stdout.flush()


def main():
    schnee_probes.register()
    out = tempfile.mkdtemp(prefix="bench_direct_")
    print(f"Blender {bpy.app.version_string}, {os.cpu_count()} CPUs, load {os.getloadavg()[0]:.1f}")
    room()
    lib.hdri_world("forest.exr")
    run("forest.exr", out)
    nishita()
    run("Nishita", out)


main()
