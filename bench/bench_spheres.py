"""End to end: diffuse test spheres rendered by Cycles and by the engine from the same cameras.

    blender -b --factory-startup -P bench/bench_spheres.py -- OUT_DIR [options]

What it measures (issue 12, "an end-to-end measurement a user would trust"): the light the whole
pipeline puts on a movable diffuse object, against Cycles, where a user looks at it.

Scene. The bundled room (scenes/make_default_scene.py: 10 x 10 x 4 m, a window onto sunset.exr, an
emissive ceiling panel, three furniture boxes) without its two demo movables, plus a strongly red
wall patch (2.5 x 2.5 m on the west wall), plus grey test spheres (radius 0.3 m, UV sphere 64 x 32,
smooth) in the collection "Movable" with a "VS Movable Diffuse" material (base 0.8, SH Scale 1,
Ambient Term 0): next to the red patch, in open space, beside the emissive panel's edge, at the
window's edge and just above the floor (SPHERES below). Each sphere has its own camera (50 mm,
1.2 m away, SIZE x SIZE pixels). The room has no lamps: the panel and the sky through the window
reach the spheres only as emission / world light, so both Cycles and the probes carry all of it.

Quantity compared: the outgoing radiance of the sphere's Lambertian surface, albedo * E / pi, E the
irradiance at the surface point. This is exactly what both sides show:
- Cycles renders the "VS Movable Diffuse" group as a Diffuse BSDF of its base colour (the add-on's
  contract, docs/user-guide.md); on a non-emissive diffuse surface the Combined pass is Diffuse
  Direct + Diffuse Indirect = albedo * E / pi, nothing else (no glossy, no emission, no lamps).
  Linear EXR, Standard view, no denoising, no adaptive sampling, box pixel filter of 1 px, REF_SAMPLES
  per pixel split into two renders of half the samples with different seeds (their difference
  measures the reference's own noise), REF_BOUNCES bounces, Cycles' default indirect clamp (10,
  which the bake uses too). The other test spheres are hidden while a sphere's camera renders.
- The engine computes base * (shScale * max(E_probe(n), 0) / pi + ambientTerm) (docs/engine.md,
  Shading) = 0.8 * E_probe / pi with ambientTerm 0, written as linear EXR before exposure and tone
  mapping (--tonemap none), without sky reflections (--no-specular), per object
  (--probe-mode object: the probe field interpolated at the object's centre) and per pixel
  (--probe-mode pixel: at each fragment). Each sphere is moved by 0.1 mm with --move so the engine
  treats it as movable: probe visibility is then judged against the static scene only, as for an
  object moved at run time (docs/engine.md "Static scene"; a glTF has no movable flag yet).
- The floor: a probe baked at the sphere's centre (bake_core.bake_points, the bake's own settings,
  spheres hidden) shading the sphere analytically: for each pixel the camera ray hits the sphere at
  normal n, value = 0.8 * max(E(n), 0) / pi with E from that probe's L2 SH (native.irradiance,
  docs/sh.md). Also with a converged probe (FLOOR_RES px, FLOOR_SAMPLES spp, REF_BOUNCES bounces):
  what a perfect probe at the centre gives.
- The CPU model per pixel ("per_pixel_cpu_plain"): the file's own interpolation (native, with the
  probes' validity; the code the engine's per-object query mirrors) at each surface point, shaded
  at its normal. The engine's per-pixel mode adds to it the back-face weights and visibility masks
  made against leaks through walls (docs/engine.md "Per-pixel probes"), so the two columns show
  what those weights do on a small convex movable object.

Probes: the add-on's bake in-process (bake_core.ProbeBake, Bake SH in Volumes, Adaptive placement
by default) with the spheres hidden from render (docs/user-guide.md: movable objects should be
hidden from the bake), written to OUT_DIR/sh_coeffs/probes.shprobe next to OUT_DIR/scene.blend,
exported with Blender's glTF exporter and the add-on's hook (cameras included) to
OUT_DIR/gltf/scene.gltf, rendered by build/schnee-view.

Pixels compared: those whose whole footprint is on the sphere (the analytic ray/sphere test at the
pixel's centre and its four corners), so edge pixels, which Cycles averages over the pixel and the
engine samples at its centre, stay out. Geometry is checked before any number is trusted: the
analytic mask against a Cycles coverage render (alpha of the sphere alone, camera-visible only),
the analytic normals against Cycles' averaged normals and the engine's normals (--debug normals).

Errors per sphere: relative RMS over the mask's pixels and RGB, sqrt(sum (X - R)^2 / sum R^2), and
the relative error of the mean colour |mean X - mean R| / |mean R| (RGB vectors), plus the signed
luminance bias of the mean; rel_rms_net takes the reference's measured noise out in quadrature.
What no probe can hold is in Cycles and in none of the columns: the sphere's effect on its
surroundings (its shadow on the floor and wall next to it, the light it bounces back onto itself
via them; probes are baked without it) and the change of the light over the sphere's 0.6 m (a probe
is one point). So even the floor is not zero. The first is measured on its own: a third Cycles
render (ISOLATED_SAMPLES) with the sphere visible to camera rays only (no shadow, no bounce off it)
shows the room's light without the sphere; its difference from the reference is the sphere's effect
on its surroundings, and each column is also compared with it (errors_vs_isolated).

With --sun (the hard-shadow case): the same room with a Sun lamp (the sweep's sun_window lamp:
SUN_LAMP_STRENGTH W/m², SUN_LAMP_ANGLE; 35° up, straight along -Y, so the sunbeam through the
window is bounded by the vertical planes x = ±1.5 of the window's sides) marked "baked" (in the
probes: the bake adds its exact direct term; the engine then adds no direct term on probe-lit
surfaces, docs/engine.md "Lights: baked, mixed or realtime"), and the SUN_SPHERES: one in the sunbeam and
one in hard shadow 0.2 m beside it (next to the sunlit floor and to probes in the sun). On the
spheres' diffuse surfaces Cycles' Combined pass is still albedo * E / pi, E now holding the lamp's
direct light; which sphere points are sunlit is checked analytically (sun_lit) when the scene is
built.

With --scene daylight --case sun|hdri|both (issue 27, "Daylight right by default"): the box of
scenes/make_daylight_box.py (4 x 3 x 2.5 m, closed but for one 1.6 x 1.2 m window; one sun path 40 deg
up through it drawing a sharp patch on the floor) lit by a Sun lamp (sun; black world), by
sunrise.exr turned so that its sun comes along the same path (hdri; no lamp), or both, with its six
spheres (in the beam, across the beam's edge, in shadow below the beam by the window, beside the
sunlit floor patch, deep in the room, by a wall; each checked against the closed form sun_lit before
anything runs, tests/bench/test_daylight_box.py checks the same with Cycles and Blender's ray casts).
The bake uses the add-on's defaults (settings.py: Adaptive, Min/Max Cell 0.5/16 m, Error Tolerance
0.03, 128 x 64 px, 8 spp, 32 bounces) unless an option says otherwise, and the lamp's light mode is
the measured tree's default unless --sun-mode sets it. Mixed and realtime suns (the glTF's
directional lights, read from the exported file: the Sun lamp, and the sky's sun once the bake can
split it off, --sky-sun) are added by the engine per pixel with its shadow maps; the reference is
Cycles with everything; the CPU models get each such sun's exact direct term (albedo S cos / pi
where the surface point sees it through the window: sun_lit); the floor stays a probe baked at the
sphere's centre holding all the light: every lamp baked and the sky's sun not split, whatever the
bake did (issue 27's table). --root TREE measures another checkout's add-on and build/schnee-view
(e.g. a git worktree of an older commit, built there with scripts/build.sh) on this checkout's scenes
and method. The runs of bench/results/spheres.md "Daylight (issue 27)", one command per case:

    blender -b --factory-startup -P bench/bench_spheres.py -- OUT_sun --scene daylight --case sun
    blender -b --factory-startup -P bench/bench_spheres.py -- OUT_hdri --scene daylight --case hdri
    blender -b --factory-startup -P bench/bench_spheres.py -- OUT_both --scene daylight --case both

"Before" (the commit before issue 27's changes, suns baked by default): the same with
--root /work/before (git worktree add /work/before 24e5473; cd /work/before && scripts/build.sh).
The old behaviour on a new tree: --sun-mode baked --sky-sun <the setting's "baked" value>.

Writes OUT_DIR/spheres.json (all numbers, settings, timings), OUT_DIR/table.md (the table),
OUT_DIR/spheres.png (per sphere: Cycles | per object | per pixel | converged floor), the EXRs.
The report is bench/results/spheres.md (numbers copied from the JSON with the command).
A rerun with the same OUT_DIR resumes an unfinished bake from its journal; --reuse keeps the probe
file, the Cycles renders and the floor probes already there (same options assumed) and redoes the
engine renders and the comparison. --probe-path buffers|bricks is passed to schnee-view's renders
(issue 30: per pixel from the storage buffers or the probe bricks; default: the viewer's default).
"""
import argparse
import importlib.util
import json
import math
import os
import resource
import shlex
import struct
import subprocess
import sys
import time
import zlib

REPO = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))


def _root_from_argv(argv):
    """--root's value, read before the add-on is imported (it decides which add-on that is)."""
    for i, arg in enumerate(argv):
        if arg == "--root" and i + 1 < len(argv):
            return os.path.abspath(argv[i + 1])
        if arg.startswith("--root="):
            return os.path.abspath(arg.split("=", 1)[1])
    return REPO


# The tree measured: its add-on (with its built native module) and its build/schnee-view. The
# scenes and this script always come from this checkout, so a "before" tree (a git worktree of an
# older commit, built there) is measured on exactly the scenes and method of an "after" run.
ROOT = _root_from_argv(sys.argv[sys.argv.index("--") + 1:] if "--" in sys.argv else [])
sys.path.insert(0, os.path.join(REPO, "scenes"))
sys.path.insert(0, os.path.join(ROOT, "addon"))
sys.path.insert(0, os.path.join(REPO, "bench"))

import addon_utils  # noqa: E402
import bpy  # noqa: E402
import numpy as np  # noqa: E402
from mathutils import Vector  # noqa: E402

import make_daylight_box  # noqa: E402
import make_default_scene  # noqa: E402
import scene_lib as lib  # noqa: E402
from bench_util import cpu_seconds  # noqa: E402

# The sweep's scene module (its Sun lamp and ray test), by path: "scenes" is also the scene folder.
_spec = importlib.util.spec_from_file_location("sweep_scenes", os.path.join(REPO, "bench", "sweep", "scenes.py"))
sweep_scenes = importlib.util.module_from_spec(_spec)
_spec.loader.exec_module(sweep_scenes)

ALBEDO = 0.8
RADIUS = 0.3
CAM_DISTANCE = 1.2
LENS_MM = 50.0           # 36 mm sensor, square image: vertical = horizontal FOV = 2 atan(18/50) = 39.6 deg
MOVE_EPS = 1e-4          # engine --move offset (m) that makes a sphere movable for the engine
ROOM_BAKE = dict(res=64, samples=16, bounces=16, placement="ADAPTIVE", min_cell=0.5, max_cell=16.0,
                 tolerance=0.05)  # --scene room's bake when no option is given (its committed results)
RED_PATCH = ((-5.0, -1.25, 0.0), (-4.97, 1.25, 2.5), (0.8, 0.05, 0.03))  # min, max, albedo

# name, centre (Blender x, y, z; room x, y in -5..5, z in 0..4), direction from the sphere to its camera
SPHERES = (
    ("red_wall", (-4.45, 0.0, 1.0), (0.35, -1.0, 0.25)),     # 0.22 m from the red patch
    ("open", (0.0, -1.8, 1.8), (-0.5, -1.0, 0.3)),          # mid-room, 1.8 m from anything
    ("panel_edge", (1.45, 0.0, 3.45), (0.0, -1.0, -0.25)),  # beside the emissive panel's +x edge
    ("window_edge", (1.4, 4.2, 2.0), (1.0, -0.3, 0.1)),     # 0.8 m from the window, at its +x edge
    ("floor", (-0.3, 1.2, 0.32), (0.3, -1.0, 0.55)),        # 2 cm above the floor
)

# --sun: direction towards the sun (Blender space), 35° up over the +Y window; spheres in the sunbeam
# and in hard shadow beside it (the beam's side is the plane x = -1.5).
SUN_TO_SUN = (0.0, math.cos(math.radians(35.0)), math.sin(math.radians(35.0)))
SUN_SPHERES = (
    ("sunlit", (0.0, 2.5, 0.6), (0.3, -1.0, 0.4)),          # wholly in the sunbeam
    ("sun_shadow", (-2.0, 2.5, 0.6), (0.6, -1.0, 0.35)),    # wholly in shadow, 0.2 m beside the beam
)


def sun_lit(point):
    """Whether the ray from ``point`` (Blender) towards the sun leaves the room through the window
    and misses the furniture (pure Python: the room's walls, window and boxes are axis-aligned)."""
    x0, x1, z0, z1 = make_default_scene.WINDOW
    wall_y = make_default_scene.ROOM_MAX[1]
    t = (wall_y - point[1]) / SUN_TO_SUN[1]
    x, z = point[0] + t * SUN_TO_SUN[0], point[2] + t * SUN_TO_SUN[2]
    if not (x0 < x < x1 and z0 < z < z1):
        return False
    return sweep_scenes.lamp_lit(point, SUN_TO_SUN, [(a, b) for _, a, b in make_default_scene.FURNITURE])


def main():
    argv = sys.argv[sys.argv.index("--") + 1:] if "--" in sys.argv else []
    ap = argparse.ArgumentParser(prog="bench_spheres.py", description=__doc__.split("\n")[0])
    ap.add_argument("out", help="output folder")
    ap.add_argument("--scene", default="room", choices=("room", "daylight"),
                    help="room: the bundled room (default); daylight: scenes/make_daylight_box.py (issue 27)")
    ap.add_argument("--case", default="sun", choices=make_daylight_box.CASES,
                    help="--scene daylight: what shines through the window (Sun lamp, sunrise.exr, both)")
    ap.add_argument("--root", default=REPO,
                    help="the tree whose add-on and build/schnee-view are measured (default: this checkout; "
                         "build it first)")
    # Bake settings: unset = the add-on's default (settings.py) for --scene daylight, and the values
    # this script has always used for --scene room (ROOM_BAKE), so its committed results reproduce.
    ap.add_argument("--res", type=int, default=None, help="bake: panorama width (px)")
    ap.add_argument("--samples", type=int, default=None, help="bake: samples per panorama pixel")
    ap.add_argument("--bounces", type=int, default=None, help="bake: max bounces")
    ap.add_argument("--placement", default=None, choices=("ADAPTIVE", "OCTREE"))
    ap.add_argument("--min-cell", type=float, default=None)
    ap.add_argument("--max-cell", type=float, default=None)
    ap.add_argument("--tolerance", type=float, default=None, help="Adaptive: Error Tolerance")
    ap.add_argument("--size", type=int, default=96, help="camera image side (px)")
    ap.add_argument("--ref-samples", type=int, default=512, help="Cycles reference spp (two halves)")
    ap.add_argument("--ref-bounces", type=int, default=32, help="Cycles reference bounces")
    ap.add_argument("--floor-res", type=int, default=128, help="converged floor probe: panorama width")
    ap.add_argument("--floor-samples", type=int, default=256, help="converged floor probe: spp")
    ap.add_argument("--isolated-samples", type=int, default=256,
                    help="spp of the Cycles render with the sphere invisible to all but the camera (0: none)")
    ap.add_argument("--sun", action="store_true",
                    help="--scene room: the hard-shadow case, a Sun lamp through the window and SUN_SPHERES")
    ap.add_argument("--sun-mode", default=None, choices=("baked", "mixed"),
                    help="the Sun lamp's light mode, set as its object's custom property schnee_light_mode "
                         "(room --sun: baked when unset; daylight: unset = the measured tree's default); "
                         "mixed = its bounced light in the probes, its direct light from the engine's shadow maps")
    ap.add_argument("--sky-sun", default=None,
                    help="the bake setting sky_sun (the sky's sun split off as a light, issue 27), passed only "
                         "when given (a tree without the setting refuses it)")
    ap.add_argument("--spheres", nargs="*", default=None, help="subset of sphere names")
    ap.add_argument("--reuse", action="store_true",
                    help="keep the probe file, Cycles renders and floor probes already in OUT")
    ap.add_argument("--viewer", default=None, help="schnee-view (default: ROOT/build/schnee-view)")
    ap.add_argument("--probe-path", default=None, choices=("buffers", "bricks"),
                    help="schnee-view --probe-path for the engine renders (default: the viewer's own default)")
    a = ap.parse_args(argv)
    a.root = os.path.abspath(a.root)
    if a.root != ROOT:
        sys.exit(f"bench_spheres: --root {a.root} was not seen before the add-on import ({ROOT})")
    a.viewer = a.viewer or os.path.join(ROOT, "build", "schnee-view")
    if not os.access(a.viewer, os.X_OK):
        sys.exit(f"bench_spheres: no schnee-view at {a.viewer} (build the tree first: scripts/build.sh)")
    if a.scene == "daylight" and a.sun:
        sys.exit("bench_spheres: --sun is the room's sun case; the daylight scene takes --case")
    if a.scene == "room":
        for key, value in ROOM_BAKE.items():
            if getattr(a, key) is None:
                setattr(a, key, value)
        if a.sun and a.sun_mode is None:
            a.sun_mode = "baked"
    out = os.path.abspath(a.out)
    os.makedirs(out, exist_ok=True)
    if a.scene == "daylight":
        if make_daylight_box.RADIUS != RADIUS or make_daylight_box.CAM_DISTANCE != CAM_DISTANCE:
            sys.exit("bench_spheres: the daylight box's spheres and cameras differ from RADIUS / CAM_DISTANCE")
        problems = make_daylight_box.layout_problems()
        if problems:
            sys.exit("bench_spheres: daylight layout: " + "; ".join(problems))
        all_spheres = tuple(s[:3] for s in make_daylight_box.SPHERES)
    else:
        all_spheres = SUN_SPHERES if a.sun else SPHERES
    spheres = [s for s in all_spheres if a.spheres is None or s[0] in a.spheres]
    if not spheres:
        sys.exit(f"bench_spheres: no sphere named {a.spheres} (there are {[s[0] for s in all_spheres]})")
    t_start, cpu_start = time.perf_counter(), cpu_seconds()
    timings = {}
    result = {"command": "blender -b --factory-startup -P bench/bench_spheres.py -- " + " ".join(
        shlex.quote(x) for x in argv), "settings": vars(a), "load_start": os.getloadavg(),
        "blender": bpy.app.version_string, "root": tree_state(ROOT), "bench_tree": tree_state(REPO),
        "spheres": []}

    # ---------------------------------------------------------------- scene
    addon_utils.enable("io_scene_gltf2", default_set=True)
    if addon_utils.enable("schnee_probes", default_set=True) is None:
        sys.exit("bench_spheres: the schnee_probes add-on could not be enabled (build it first)")
    import schnee_probes
    from schnee_probes import bake_core, light_modes, native, nodes
    from schnee_probes.scene_export import blender_to_engine as to_engine
    if not os.path.abspath(schnee_probes.__file__).startswith(os.path.join(ROOT, "addon") + os.sep):
        sys.exit(f"bench_spheres: imported {schnee_probes.__file__}, not the add-on of {ROOT}")
    bake_extra = {}
    if a.sky_sun is not None:
        bake_extra["sky_sun"] = setting_value(bake_core, "sky_sun", a.sky_sun)
    if a.scene == "daylight":
        scene = build_daylight_scene(a.case, spheres, a.size, nodes)
        lamp = bpy.data.objects.get("SunLamp")
        if lamp is not None and a.sun_mode is not None:
            set_light_mode(light_modes, lamp, a.sun_mode)
        result["daylight"] = {
            "case": a.case, "to_sun": make_daylight_box.TO_SUN, "window": make_daylight_box.WINDOW,
            "sun_strength": make_daylight_box.SUN_STRENGTH if lamp is not None else None,
            "sun_mode": light_modes.light_mode(lamp) if lamp is not None else None,
            "hdri_sun": list(scene.get("daylight_hdri_sun", [])) or None,
            "sky_sun": bake_extra.get("sky_sun", "(the tree's default)"),
            "spheres_lit": {}}
        dirs = np.random.default_rng(7).normal(size=(400, 3))
        dirs /= np.linalg.norm(dirs, axis=1, keepdims=True)
        for name, centre, _ in spheres:
            result["daylight"]["spheres_lit"][name] = float(
                make_daylight_box.sun_lit_many(np.array(centre) + RADIUS * dirs).mean())
    else:
        scene = build_scene(spheres, a.size, nodes)
    if a.sun:
        lamp = sweep_scenes._sun_lamp(SUN_TO_SUN, (0.0, 0.0, 0.0))
        lamp["schnee_light_mode"] = a.sun_mode
        result["sun"] = {"to_sun": SUN_TO_SUN, "strength": sweep_scenes.SUN_LAMP_STRENGTH,
                         "angle_deg": math.degrees(sweep_scenes.SUN_LAMP_ANGLE), "spheres_lit": {}}
        # Each sphere is wholly in the sun or wholly in shadow, as its name says (200 surface points).
        dirs = np.random.default_rng(7).normal(size=(200, 3))
        dirs /= np.linalg.norm(dirs, axis=1, keepdims=True)
        for name, centre, _ in spheres:
            lit = [sun_lit(np.array(centre) + RADIUS * d) for d in dirs]
            result["sun"]["spheres_lit"][name] = sum(lit) / len(lit)
            if sum(lit) not in (0, len(lit)) or (sum(lit) > 0) != (name == "sunlit"):
                sys.exit(f"bench_spheres: sphere {name} is {sum(lit)}/{len(lit)} sunlit")
    layer = bpy.context.view_layer
    blend = os.path.join(out, "scene.blend")
    lib.save(blend)

    def settings(**kw):
        """The bake's settings: the options given, the add-on's defaults for the rest."""
        base = {k: v for k, v in dict(
            placement=a.placement, min_cell_size=a.min_cell, max_cell_size=a.max_cell,
            error_tolerance=a.tolerance, panorama_resolution=a.res, samples=a.samples,
            max_bounces=a.bounces).items() if v is not None}
        base.update(bake_extra, probe_limit=0, output_path=os.path.join(out, "sh_coeffs", "probes.shprobe"))
        base.update(kw)
        return bake_core.BakeSettings(**base)
    result["bake_settings"] = {k: v for k, v in vars(settings()).items() if not k.startswith("_")}

    sphere_obs = [bpy.data.objects["Sphere_" + s[0]] for s in spheres]
    blender_c = np.array([s[1] for s in spheres], dtype=np.float64)
    engine_c = to_engine(blender_c)

    # ---------------------------------------------------------------- bake (spheres hidden)
    for ob in sphere_obs:
        ob.hide_render = True
    path = os.path.join(out, "sh_coeffs", "probes.shprobe")
    if a.reuse and os.path.exists(path):  # a finished bake leaves no journal to resume from
        result["bake"] = {"probes": native.read_shprobe(path).probe_count, "reused": True,
                          "file_bytes": os.path.getsize(path)}
    else:
        t, cpu = time.perf_counter(), cpu_seconds()
        bake = bake_core.ProbeBake(scene, layer, settings(), log=print)
        r = bake.run()
        timings["bake"] = {"seconds": time.perf_counter() - t, "cpu_seconds": cpu_seconds() - cpu}
        fc = getattr(bake.plan, "first_forecast", None)
        result["bake"] = {"probes": r.probe_count, "renders": getattr(r, "renders", None),
                          "points": r.points, "samples": r.samples,
                          "forecast": None if fc is None else {"points": round(fc[0], 1), "seconds": round(fc[1], 1)},
                          "resumed": bake.resumed, "file_bytes": os.path.getsize(path),
                          "lights": {ob.name: light_modes.light_mode(ob) for ob in scene.objects
                                     if ob.type == 'LIGHT'}}
    print("BAKE", json.dumps(result["bake"]), json.dumps(timings.get("bake")), flush=True)

    floor_path = os.path.join(out, "floor.npz")
    if a.reuse and os.path.exists(floor_path):
        z = np.load(floor_path)
        floor, floor_conv = z["floor"], z["floor_conv"]
    else:
        t = time.perf_counter()
        # Daylight: the floor is a probe holding all the light, every sun in it (issue 27's table):
        # lamps baked and the sky's sun not split off, whatever the bake above did.
        floor_kw, restore = {}, []
        if a.scene == "daylight":
            for ob in scene.objects:
                if ob.type == 'LIGHT' and light_modes.light_mode(ob) != "baked":
                    restore.append((ob, ob.get("schnee_light_mode")))
                    set_light_mode(light_modes, ob, "baked")
            if any(x.name == "sky_sun" for x in settings_module(bake_core).SETTINGS):
                floor_kw["sky_sun"] = setting_value(bake_core, "sky_sun", "baked")
            result["floor_bake"] = {"lights": {ob.name: light_modes.light_mode(ob) for ob in scene.objects
                                               if ob.type == 'LIGHT'},
                                    "sky_sun": floor_kw.get("sky_sun", "(no such setting)")}
        try:
            floor = bake_core.bake_points(scene, layer, settings(**floor_kw), engine_c, log=lambda s: None)
            floor_conv = bake_core.bake_points(
                scene, layer, settings(panorama_resolution=a.floor_res, samples=a.floor_samples,
                                       max_bounces=a.ref_bounces, **floor_kw), engine_c, log=lambda s: None)
        finally:
            for ob, value in restore:
                if value is None:
                    del ob["schnee_light_mode"]
                else:
                    ob["schnee_light_mode"] = value
        timings["floor_probes"] = time.perf_counter() - t
        np.savez(floor_path, floor=floor, floor_conv=floor_conv)
    for ob in sphere_obs:
        ob.hide_render = False
    # The probe volumes are render-visible boxes (the bake hides them itself); they must not cover
    # the walls in the Cycles references. The glTF export leaves them out anyway.
    for ob in bpy.data.collections[bake_core.BakeSettings().volume_collection].all_objects:
        ob.hide_render = True

    # The CPU model of the lookups: the file's interpolation with validity (native, the code the
    # engine's per-object query mirrors) at the centre, and at each surface point (plain, without
    # the engine's per-pixel back-face weights and visibility masks, docs/engine.md "Per-pixel").
    f = native.read_shprobe(path)
    try:
        interp = native.interpolation_from_file(path)

        def cpu_model(points):
            return interp.interpolate(points, f.coeffs, f.validity)
    except Exception as exc:  # a v1 file (Geometry Octree): the grid cell's probe
        print("bench_spheres: no v3 interpolation:", exc)

        def cpu_model(points):
            return f.coeffs[np.maximum(f.lookup(points), 0)]
    cpu_obj = cpu_model(engine_c)

    # ---------------------------------------------------------------- glTF export (add-on hook)
    gltf = os.path.join(out, "gltf", "scene.gltf")
    os.makedirs(os.path.dirname(gltf), exist_ok=True)
    t = time.perf_counter()
    bpy.ops.export_scene.gltf(filepath=gltf, export_format="GLTF_SEPARATE", export_cameras=True,
                              export_lights=True, export_apply=True)
    timings["export"] = time.perf_counter() - t
    with open(gltf, encoding="utf-8") as fh:
        doc = json.load(fh)
    ext = doc["scenes"][0].get("extensions", {}).get("VULKAN_SCHNEE_engine_properties", {})
    result["gltf"] = {"grids": [g.get("uri") for g in ext.get("shProbeGrids", [])], "sky": "sky" in ext,
                      "cameras": [c.get("name") for c in doc.get("cameras", [])]}
    if not result["gltf"]["grids"]:
        sys.exit("bench_spheres: the glTF lists no probe grid (is the add-on's export hook enabled?)")
    # Directional lights whose direct light the engine adds (mixed / realtime) as the glTF has them.
    direct_lights = [x for x in gltf_directional_lights(doc) if x["mode"] in ("mixed", "realtime")]
    result["gltf"]["directional_lights"] = gltf_directional_lights(doc)
    if a.scene == "daylight":
        for x in direct_lights:
            off = math.degrees(math.acos(min(1.0, float(np.dot(x["to_sun"], make_daylight_box.TO_SUN)))))
            if off > 1.0:   # the closed form of which points see the sun holds for TO_SUN only
                sys.exit(f"bench_spheres: light {x['name']} is {off:.2f} deg from the daylight sun path")

    # ---------------------------------------------------------------- per sphere
    timings["cycles"] = 0.0
    timings["engine"] = 0.0
    rows = []
    for k, (name, centre, _) in enumerate(spheres):
        cam = bpy.data.objects["Cam_" + name]
        rays = camera_rays(cam, a.size)
        hit_c, n_c, hit_any_corner, hit_all = sphere_hits(cam, a.size, np.array(centre), RADIUS)
        mask = hit_all                      # whole pixel footprint on the sphere
        rowcol = np.argwhere(hit_any_corner)
        border = (max(rowcol[:, 0].min() - 2, 0), min(rowcol[:, 0].max() + 3, a.size),
                  max(rowcol[:, 1].min() - 2, 0), min(rowcol[:, 1].max() + 3, a.size))
        base = os.path.join(out, name)

        # Cycles: coverage + normals (geometry check), then the reference in two seeded halves; the
        # other test spheres are hidden (each sphere is compared with the room alone around it).
        t = time.perf_counter()
        for j, ob in enumerate(sphere_obs):
            ob.hide_render = j != k
        cov_path = base + "_cycles_normals.exr"
        if not (a.reuse and os.path.exists(cov_path)):
            render_normals(scene, cam, sphere_obs[k], a.size, border, cov_path)
        halves = []
        for seed in (1, 2):
            p = f"{base}_cycles_seed{seed}.exr"
            if not (a.reuse and os.path.exists(p)):
                render_reference(scene, cam, a.size, border, a.ref_samples // 2, a.ref_bounces, seed, p)
            halves.append(native.read_image(p)[..., :3].astype(np.float64))
        # The sphere seen by the camera only (no shadow, no bounce off it): the light at its surface
        # as if it did not change its surroundings, what a probe at the surface point would see.
        iso = None
        if a.isolated_samples > 0:
            p = base + "_cycles_isolated.exr"
            if not (a.reuse and os.path.exists(p)):
                render_isolated(scene, cam, sphere_obs[k], a.size, border, a.isolated_samples,
                                a.ref_bounces, p)
            iso = native.read_image(p)[..., :3].astype(np.float64)
        for ob in sphere_obs:
            ob.hide_render = False
        timings["cycles"] += time.perf_counter() - t
        ref = 0.5 * (halves[0] + halves[1])
        ref_noise = 0.5 * (halves[0] - halves[1])   # per-pixel error estimate of the mean of two halves
        cov = native.read_image(cov_path).astype(np.float64)

        # Engine: normals (geometry check), per object, per pixel.
        t = time.perf_counter()
        node = sphere_obs[k].name
        ec = engine_c[k]
        move = ["--move", node, f"{ec[0] + MOVE_EPS:.6f}", f"{ec[1]:.6f}", f"{ec[2]:.6f}"]
        if a.scene == "daylight":
            # Cycles renders each sphere alone; in the small box another sphere can stand between a
            # camera and its sphere or shadow it, so the engine gets the others 2 m under the floor
            # slab (out of view and of every sunbeam, inside the scene's bounds for the shadow maps).
            for j, (other, oc, _) in enumerate(spheres):
                if j != k:
                    e = to_engine(np.array([oc[0], oc[1], make_daylight_box.ROOM_MIN[2] - 2.0]))
                    move += ["--move", sphere_obs[j].name] + [f"{v:.6f}" for v in e]
        eng = {}
        for mode, extra in (("normals", ["--debug", "normals"]), ("object", ["--probe-mode", "object"]),
                            ("pixel", ["--probe-mode", "pixel"])):
            p = f"{base}_engine_{mode}.exr"
            path_opt = ["--probe-path", a.probe_path] if a.probe_path else []
            run_engine(a.viewer, gltf, p, "Cam_" + name, a.size, extra + path_opt + move)
            eng[mode] = native.read_image(p)[..., :3].astype(np.float64)
        timings["engine"] += time.perf_counter() - t

        # Floors: the probe at the centre shading the analytic normals.
        n_eng = to_engine(n_c[mask])
        floor_img = ALBEDO * np.maximum(native.irradiance(floor[k], n_eng), 0.0) / math.pi
        conv_img = ALBEDO * np.maximum(native.irradiance(floor_conv[k], n_eng), 0.0) / math.pi
        cpu_img = ALBEDO * np.maximum(native.irradiance(cpu_obj[k], n_eng), 0.0) / math.pi
        surf = cpu_model(engine_c[k] + RADIUS * n_eng)                # (pixels, sh, 3); NaN outside
        surf = np.nan_to_num(surf)
        plain_img = ALBEDO * np.maximum(np.array(
            [native.irradiance(c, nn) for c, nn in zip(surf, n_eng)]), 0.0) / math.pi
        if a.scene == "daylight" and direct_lights:
            # The probes lack the direct light of mixed and realtime suns (the Sun lamp, the sky's sun
            # when split off); the engine adds it per pixel with its shadow maps, so the CPU models
            # get it exactly: S cos / pi where the surface point sees the sun through the window.
            # The floors are baked with every sun in them and get nothing added.
            pts = np.array(centre) + RADIUS * n_c[mask]
            sun_img = np.zeros((len(pts), 3))
            for light in direct_lights:
                lit = make_daylight_box.sun_lit_many(pts, light["to_sun"])
                cos = np.maximum(n_c[mask] @ np.asarray(light["to_sun"]), 0.0) * lit
                sun_img += ALBEDO / math.pi * cos[:, None] * np.asarray(light["irradiance"])[None, :]
            cpu_img, plain_img = cpu_img + sun_img, plain_img + sun_img
        if a.sun and a.sun_mode == "mixed":
            # The probes hold no direct sun: every model gets the engine's term, the sun's exact
            # direct light on a Lambert surface, S cos / pi where the point is lit (sun_lit: the
            # sphere is wholly in the beam or in shadow; the 0.5 degree disc is a direction here).
            to_sun = np.asarray(SUN_TO_SUN, dtype=np.float64) / np.linalg.norm(SUN_TO_SUN)
            lit = float(sun_lit(np.array(centre)))
            sun_img = (ALBEDO * sweep_scenes.SUN_LAMP_STRENGTH * lit / math.pi
                       * np.maximum(n_c[mask] @ to_sun, 0.0))[:, None] * np.ones(3)
            floor_img, conv_img, cpu_img, plain_img = (x + sun_img for x in (floor_img, conv_img, cpu_img, plain_img))

        R = ref[mask]
        row = {"name": name, "centre_blender": list(centre), "pixels": int(mask.sum()),
               "geometry": geometry_check(hit_c, n_c, mask, cov, eng["normals"]),
               "reference": {"mean_rgb": R.mean(0).tolist(),
                             "noise_rel_rms": rel_rms(ref_noise[mask], np.zeros_like(R), R)},
               "engine_object_vs_cpu_model": rel_rms(eng["object"][mask], cpu_img, cpu_img),
               "errors": {}}
        for label, X in (("per_object", eng["object"][mask]), ("per_pixel", eng["pixel"][mask]),
                         ("per_pixel_cpu_plain", plain_img), ("floor", floor_img), ("floor_converged", conv_img)):
            row["errors"][label] = errors(X, R, ref_noise[mask])
        row["engine_pixel_vs_cpu_plain"] = rel_rms(eng["pixel"][mask], plain_img, plain_img)
        if iso is not None:
            # both renders' noise: the isolated one has ref_samples / isolated_samples times the variance
            both = ref_noise[mask] * math.sqrt(1 + a.ref_samples / a.isolated_samples)
            row["isolated_reference"] = errors(iso[mask], R, both)  # the sphere's effect on its surroundings
            for label, X in (("per_object", eng["object"][mask]), ("per_pixel", eng["pixel"][mask]),
                             ("per_pixel_cpu_plain", plain_img), ("floor", floor_img),
                             ("floor_converged", conv_img)):
                row["errors_vs_isolated"] = row.get("errors_vs_isolated", {})
                row["errors_vs_isolated"][label] = errors(X, iso[mask])
        rows.append(row)
        print("SPHERE", json.dumps(row), flush=True)
        np.savez(base + "_pixels.npz", mask=mask, ref=ref, noise=ref_noise, object=eng["object"],
                 pixel=eng["pixel"], floor=floor_img, floor_converged=conv_img, rays=rays)

    result["spheres"] = rows
    timings["total"] = time.perf_counter() - t_start
    timings["total_cpu_seconds"] = cpu_seconds() - cpu_start   # this process; Cycles runs in it
    ch = resource.getrusage(resource.RUSAGE_CHILDREN)
    timings["children_cpu_seconds"] = ch.ru_utime + ch.ru_stime   # the schnee-view runs (and git)
    result["timings"] = timings
    result["load_end"] = os.getloadavg()
    with open(os.path.join(out, "spheres.json"), "w", encoding="utf-8") as fh:
        json.dump(result, fh, indent=1)
    write_montage(os.path.join(out, "spheres.png"), [os.path.join(out, r["name"] + "_pixels.npz") for r in rows])
    table = markdown_table(rows, result)
    with open(os.path.join(out, "table.md"), "w", encoding="utf-8") as fh:
        fh.write(table)
    print(table)
    print("WROTE", os.path.join(out, "spheres.json"), "in", f"{timings['total']:.0f} s")


# -------------------------------------------------------------------- helpers
def tree_state(root):
    """The commit of ``root`` and whether its tracked files differ from it (for the JSON)."""
    def git(*args):
        p = subprocess.run(["git", "-C", root] + list(args), capture_output=True, text=True)
        return p.stdout.strip() if p.returncode == 0 else None
    return {"path": root, "commit": git("rev-parse", "HEAD"),
            "modified": [line[3:] for line in (git("status", "--porcelain", "--untracked-files=no") or "").splitlines()]}


def settings_module(bake_core):
    return sys.modules[bake_core.BakeSettings.__module__]


def setting_value(bake_core, name, text):
    """``text`` as the value of bake setting ``name`` (settings.py's declaration): an enum's
    identifier (case-insensitive), a bool from on/off/true/false, else the text; a clear exit when
    the measured tree has no such setting."""
    decl = next((x for x in settings_module(bake_core).SETTINGS if x.name == name), None)
    if decl is None:
        sys.exit(f"bench_spheres: the tree at {ROOT} has no bake setting '{name}'")
    if decl.kind == "enum":
        ids = {c.lower(): c for c in decl.choice_ids}
        if text.lower() not in ids:
            sys.exit(f"bench_spheres: {name} {text!r} is not one of {', '.join(decl.choice_ids)}")
        return ids[text.lower()]
    if decl.kind == "bool":
        words = {"on": True, "true": True, "1": True, "off": False, "false": False, "0": False}
        if text.lower() not in words:
            sys.exit(f"bench_spheres: {name} is on/off, not {text!r}")
        return words[text.lower()]
    return text


def set_light_mode(light_modes, ob, mode):
    """Sets the lamp object's custom property schnee_light_mode (the form every tree reads) and
    checks that the measured tree's add-on now reports ``mode``."""
    ob["schnee_light_mode"] = mode
    if light_modes.light_mode(ob) != mode:
        sys.exit(f"bench_spheres: {ob.name}: schnee_light_mode = {mode!r} but the add-on reports "
                 f"{light_modes.light_mode(ob)!r}")


def gltf_directional_lights(doc):
    """The glTF's KHR_lights_punctual directional lights: name, mode (VULKAN_SCHNEE_light, "baked"
    when absent), to_sun (unit, Blender space: the light shines along the node's -Z) and irradiance
    (colour * intensity * intensityScale, W/m^2: docs/export.md)."""
    lights = doc.get("extensions", {}).get("KHR_lights_punctual", {}).get("lights", [])
    nodes_ = doc.get("nodes", [])
    out = []

    def matrix(node):
        if "matrix" in node:
            return np.array(node["matrix"], dtype=np.float64).reshape(4, 4).T
        x, y, z, w = node.get("rotation", (0.0, 0.0, 0.0, 1.0))
        r = np.array([[1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w)],
                      [2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w)],
                      [2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y)]])
        m = np.eye(4)
        m[:3, :3] = r * np.asarray(node.get("scale", (1.0, 1.0, 1.0)))[None, :]
        m[:3, 3] = node.get("translation", (0.0, 0.0, 0.0))
        return m

    def walk(index, parent):
        node = nodes_[index]
        m = parent @ matrix(node)
        k = node.get("extensions", {}).get("KHR_lights_punctual", {}).get("light")
        if k is not None and lights[k].get("type") == "directional":
            light = lights[k]
            ext = light.get("extensions", {}).get("VULKAN_SCHNEE_light", {})
            d = m[:3, :3] @ np.array([0.0, 0.0, -1.0])             # glTF (Y-up) direction of travel
            d = np.array([d[0], -d[2], d[1]]) / np.linalg.norm(d)   # Blender space
            irr = (np.asarray(light.get("color", (1.0, 1.0, 1.0))) * light.get("intensity", 1.0)
                   * ext.get("intensityScale", 1.0))
            out.append({"name": light.get("name", node.get("name")), "mode": ext.get("mode", "baked"),
                        "to_sun": (-d).tolist(), "irradiance": irr.tolist()})
        for c in node.get("children", []):
            walk(c, m)
    for root in doc.get("scenes", [{}])[doc.get("scene", 0)].get("nodes", []):
        walk(root, np.eye(4))
    return out


# -------------------------------------------------------------------- scene
def add_camera(scene, name, centre, cam_dir):
    cam_data = bpy.data.cameras.new("Cam_" + name)
    cam_data.lens = LENS_MM
    cam_data.sensor_width = 36.0
    cam_data.sensor_fit = 'AUTO'
    cam = bpy.data.objects.new("Cam_" + name, cam_data)
    d = Vector(cam_dir).normalized()
    cam.location = Vector(centre) + CAM_DISTANCE * d
    cam.rotation_euler = (-d).to_track_quat('-Z', 'Y').to_euler()
    scene.collection.objects.link(cam)


def build_daylight_scene(case, spheres, size, nodes):
    """scenes/make_daylight_box.py's box for ``case`` with the spheres asked for, the benchmark's
    grey material (SH Scale 1, Ambient Term 0) and a camera per sphere."""
    def material():
        return nodes.make_movable_diffuse_material("TestGrey", base_color=(ALBEDO, ALBEDO, ALBEDO, 1.0),
                                                   sh_scale=1.0, ambient=0.0)
    chosen = [s for s in make_daylight_box.SPHERES if s[0] in {x[0] for x in spheres}]
    scene = make_daylight_box.build(case, spheres=chosen, make_material=material)
    for name, centre, cam_dir in spheres:
        add_camera(scene, name, centre, cam_dir)
    scene.render.resolution_x = scene.render.resolution_y = size
    scene.render.resolution_percentage = 100
    bpy.context.view_layer.update()
    return scene


def build_scene(spheres, size, nodes):
    scene = make_default_scene.build()
    for name in ("MovableSphere", "MovableMonkey"):  # the demo movables: not part of this test
        ob = bpy.data.objects.get(name)
        if ob is not None:
            bpy.data.objects.remove(ob)
    lo, hi, colour = RED_PATCH
    lib.box("RedPatch", lo, hi, bpy.data.collections["Room"], lib.diffuse_material("RedPaint", colour))
    movable = lib.collection("Movable")
    mat = nodes.make_movable_diffuse_material("TestGrey", base_color=(ALBEDO, ALBEDO, ALBEDO, 1.0),
                                              sh_scale=1.0, ambient=0.0)
    for name, centre, cam_dir in spheres:
        lib.movable_sphere(name, centre, RADIUS, mat, movable)
        add_camera(scene, name, centre, cam_dir)
    scene.render.resolution_x = scene.render.resolution_y = size  # also the exported cameras' aspect
    scene.render.resolution_percentage = 100
    bpy.context.view_layer.update()
    return scene


# -------------------------------------------------------------------- camera geometry
def camera_rays(cam, size, offsets=(0.5, 0.5)):
    """World (Blender) ray directions (size, size, 3) through pixel (row from the top, column) at the
    given offsets inside the pixel; Blender's square-image perspective (tan(fov/2) = 18 / lens)."""
    tan_half = (cam.data.sensor_width / 2) / cam.data.lens
    idx = np.arange(size)
    x = ((idx + offsets[0]) / size * 2 - 1) * tan_half
    y = (1 - (idx + offsets[1]) / size * 2) * tan_half
    X, Y = np.meshgrid(x, y)
    d = np.stack([X, Y, -np.ones_like(X)], axis=-1)
    rot = np.array(cam.matrix_world.to_3x3())
    d = d @ rot.T
    return d / np.linalg.norm(d, axis=-1, keepdims=True)


def ray_sphere(origin, dirs, centre, radius):
    oc = origin - centre
    b = dirs @ oc
    disc = b * b - (oc @ oc - radius * radius)
    hit = disc > 0
    t = -b - np.sqrt(np.maximum(disc, 0))
    return hit & (t > 0), t


def sphere_hits(cam, size, centre, radius):
    """(centre hit, normals at the centre ray's hit (Blender), hit at any corner or the centre,
    hit at every corner and the centre)."""
    origin = np.array(cam.matrix_world.translation)
    d = camera_rays(cam, size)
    hit_c, t = ray_sphere(origin, d, centre, radius)
    p = origin + t[..., None] * d
    n = (p - centre) / radius
    any_h, all_h = hit_c.copy(), hit_c.copy()
    for off in ((0, 0), (1, 0), (0, 1), (1, 1)):
        h, _ = ray_sphere(origin, camera_rays(cam, size, off), centre, radius)
        any_h |= h
        all_h &= h
    return hit_c, n, any_h, all_h


def geometry_check(hit_c, n_c, mask, cov, eng_normals):
    """Alignment of the analytic sphere with Cycles' coverage / normals and the engine's normals."""
    from schnee_probes.scene_export import blender_to_engine as to_engine
    alpha = cov[..., 3]
    cyc_n = cov[..., :3] / np.maximum(alpha, 1e-9)[..., None]
    cyc_n /= np.maximum(np.linalg.norm(cyc_n, axis=-1, keepdims=True), 1e-9)
    e_n = to_engine(n_c)
    g_n = eng_normals * 2 - 1
    g_n /= np.maximum(np.linalg.norm(g_n, axis=-1, keepdims=True), 1e-9)

    def angle(a_, b_):
        return np.degrees(np.arccos(np.clip(np.sum(a_ * b_, -1), -1, 1)))
    cyc_ang = angle(cyc_n[mask], n_c[mask])
    eng_ang = angle(g_n[mask], e_n[mask])
    # The engine's sphere pixels: its normal within 10 deg of the analytic one (walls are far off).
    eng_on = np.zeros_like(hit_c)
    eng_on[hit_c] = angle(g_n[hit_c], e_n[hit_c]) < 10
    return {"analytic_centre_hits": int(hit_c.sum()),
            "cycles_alpha_sum": float(alpha.sum()),          # = covered pixel area
            "cycles_coverage_mismatch": int(((alpha > 0.5) != hit_c).sum()),
            "cycles_alpha_min_in_mask": float(alpha[mask].min()),
            "cycles_normal_deg_max": float(cyc_ang.max()), "cycles_normal_deg_mean": float(cyc_ang.mean()),
            "engine_normal_deg_max": float(eng_ang.max()), "engine_normal_deg_mean": float(eng_ang.mean()),
            "engine_hits_missing": int((hit_c & ~eng_on).sum())}


# -------------------------------------------------------------------- Cycles
def _common_render(scene, cam, size, border):
    scene.camera = cam
    r = scene.render
    r.engine = 'CYCLES'
    r.resolution_x = r.resolution_y = size
    r.resolution_percentage = 100
    r0, r1, c0, c1 = border              # rows from the top, columns; Blender's border is from the bottom
    r.use_border, r.use_crop_to_border = True, False
    r.border_min_x, r.border_max_x = c0 / size, c1 / size
    r.border_min_y, r.border_max_y = 1 - r1 / size, 1 - r0 / size
    r.image_settings.file_format = 'OPEN_EXR'
    r.image_settings.color_depth = '32'
    r.image_settings.exr_codec = 'ZIP'
    r.image_settings.color_mode = 'RGBA'
    scene.view_settings.view_transform = 'Standard'
    scene.view_settings.look = 'None'
    scene.view_settings.exposure = 0.0
    scene.view_settings.gamma = 1.0
    cy = scene.cycles
    cy.use_denoising = False
    cy.use_adaptive_sampling = False
    cy.pixel_filter_type = 'BOX'
    cy.filter_width = 1.0
    scene.render.use_persistent_data = False


def render_reference(scene, cam, size, border, samples, bounces, seed, path):
    _common_render(scene, cam, size, border)
    cy = scene.cycles
    cy.samples = samples
    cy.seed = seed
    cy.max_bounces = cy.diffuse_bounces = cy.glossy_bounces = bounces
    cy.transmission_bounces = cy.transparent_max_bounces = bounces
    cy.sample_clamp_direct = 0.0
    cy.sample_clamp_indirect = 10.0   # Cycles' default and the bake's
    scene.render.film_transparent = False
    scene.render.filepath = path
    bpy.ops.render.render(write_still=True)


def render_isolated(scene, cam, sphere, size, border, samples, bounces, path):
    """The reference with the sphere visible to camera rays only: it casts no shadow and bounces no
    light onto the room, so its pixels show the light of the room without it."""
    flags = ("visible_diffuse", "visible_glossy", "visible_transmission", "visible_volume_scatter",
             "visible_shadow")
    old = {f: getattr(sphere, f) for f in flags}
    try:
        for f in flags:
            setattr(sphere, f, False)
        render_reference(scene, cam, size, border, samples, bounces, 3, path)
    finally:
        for f, v in old.items():
            setattr(sphere, f, v)


def render_normals(scene, cam, sphere, size, border, path):
    """The sphere alone (every other object invisible to the camera, black world, transparent film):
    alpha = its coverage of each pixel, RGB = alpha x its averaged shading normal (emission)."""
    mat = bpy.data.materials.new("NormalCheck")
    mat.use_nodes = True
    nt = mat.node_tree
    nt.nodes.clear()
    geo = nt.nodes.new("ShaderNodeNewGeometry")
    em = nt.nodes.new("ShaderNodeEmission")
    outn = nt.nodes.new("ShaderNodeOutputMaterial")
    nt.links.new(geo.outputs["Normal"], em.inputs["Color"])
    nt.links.new(em.outputs["Emission"], outn.inputs["Surface"])
    old_mat = sphere.data.materials[0]
    hidden = [ob for ob in scene.objects if ob is not sphere and ob.type == 'MESH' and ob.visible_camera]
    world_strength = None
    bg = scene.world.node_tree.nodes.get("Background")
    try:
        sphere.data.materials[0] = mat
        for ob in hidden:
            ob.visible_camera = False
        if bg is not None:
            world_strength = bg.inputs["Strength"].default_value
            bg.inputs["Strength"].default_value = 0.0
        _common_render(scene, cam, size, border)
        scene.cycles.samples = 16
        scene.cycles.max_bounces = 0
        scene.render.film_transparent = True
        scene.render.filepath = path
        bpy.ops.render.render(write_still=True)
    finally:
        sphere.data.materials[0] = old_mat
        for ob in hidden:
            ob.visible_camera = True
        if world_strength is not None:
            bg.inputs["Strength"].default_value = world_strength
        scene.render.film_transparent = False
        bpy.data.materials.remove(mat)


# -------------------------------------------------------------------- engine
def run_engine(viewer, gltf, path, camera, size, extra):
    cmd = [viewer, gltf, "--headless", "--output", path, "--camera", camera, "--width", str(size),
           "--height", str(size), "--tonemap", "none", "--no-specular"] + extra
    proc = subprocess.run(cmd, capture_output=True, text=True)
    if proc.returncode != 0 or not os.path.exists(path):
        sys.exit(f"bench_spheres: schnee-view failed ({proc.returncode}): {' '.join(cmd)}\n{proc.stderr[-2000:]}")
    for line in proc.stderr.splitlines():
        if "warning" in line.lower():
            print("schnee-view:", line)


# -------------------------------------------------------------------- errors
def rel_rms(x, y, ref):
    return float(np.sqrt(np.sum((x - y) ** 2) / np.sum(ref ** 2)))


def luminance(rgb):
    return rgb @ np.array([0.2126, 0.7152, 0.0722])


def errors(X, R, noise=None):
    """Relative RMS over pixels and RGB, relative error of the mean colour, signed luminance bias of
    the mean; with the reference's own noise estimate (per pixel), the RMS with that noise taken
    out in quadrature (rel_rms_net)."""
    mx, mr = X.mean(0), R.mean(0)
    out = {"rel_rms": rel_rms(X, R, R), "mean_rel": float(np.linalg.norm(mx - mr) / np.linalg.norm(mr)),
           "mean_lum_bias": float(luminance(mx) / luminance(mr) - 1), "mean_rgb": mx.tolist()}
    if noise is not None:
        nz = rel_rms(noise, np.zeros_like(noise), R)
        out["rel_rms_net"] = float(np.sqrt(max(out["rel_rms"] ** 2 - nz ** 2, 0.0)))
    return out


def write_montage(path, npz_paths):
    """One row per sphere: Cycles, engine per object, engine per pixel, converged floor probe (sphere
    pixels only, the rest from Cycles); x / (1 + x), gamma 2.2, 8-bit PNG (zlib, no dependencies)."""
    rows = []
    for p in npz_paths:
        z = np.load(p)
        mask, ref = z["mask"], z["ref"]
        floor = ref.copy()
        floor[mask] = z["floor_converged"]
        obj, pix = ref.copy(), ref.copy()
        obj[mask], pix[mask] = z["object"][mask], z["pixel"][mask]
        rows.append(np.concatenate([ref, obj, pix, floor], axis=1))
    img = np.concatenate(rows, axis=0)
    img = (np.clip(img / (1 + img), 0, 1) ** (1 / 2.2) * 255 + 0.5).astype(np.uint8)
    h, w, _ = img.shape
    raw = b"".join(b"\0" + img[r].tobytes() for r in range(h))

    def chunk(tag, data):
        return struct.pack(">I", len(data)) + tag + data + struct.pack(">I", zlib.crc32(tag + data) & 0xFFFFFFFF)
    with open(path, "wb") as fh:
        fh.write(b"\x89PNG\r\n\x1a\n" + chunk(b"IHDR", struct.pack(">IIBBBBB", w, h, 8, 2, 0, 0, 0))
                 + chunk(b"IDAT", zlib.compress(raw, 9)) + chunk(b"IEND", b""))


def markdown_table(rows, result=None):
    """Per sphere: RMS (net of the reference's noise) / mean-colour error / luminance bias, in %."""
    cols = ("per_object", "per_pixel", "per_pixel_cpu_plain", "floor", "floor_converged")
    lines = ["| sphere | pixels | ref. noise | " + " | ".join(c.replace("_", " ") for c in cols)
             + " | sphere off (isolated) | engine obj. vs CPU model |",
             "|---|---|---|" + "---|" * len(cols) + "---|---|"]

    def cell(e):
        return (f"{100 * e['rel_rms']:.1f} ({100 * e.get('rel_rms_net', float('nan')):.1f}) / "
                f"{100 * e['mean_rel']:.1f} / {100 * e['mean_lum_bias']:+.1f}")
    for r in rows:
        iso = cell(r["isolated_reference"]) if "isolated_reference" in r else "—"
        lines.append(f"| {r['name']} | {r['pixels']} | {100 * r['reference']['noise_rel_rms']:.1f} | "
                     + " | ".join(cell(r["errors"][c]) for c in cols)
                     + f" | {iso} | {100 * r['engine_object_vs_cpu_model']:.2f} |")
    if len(rows) > 1:
        def mean_cell(get):
            es = [get(r) for r in rows]
            if any(e is None for e in es):
                return "—"
            return cell({k: float(np.mean([e.get(k, float("nan")) for e in es]))
                         for k in ("rel_rms", "rel_rms_net", "mean_rel", "mean_lum_bias")})
        lines.append(f"| **mean of {len(rows)}** | | {100 * np.mean([r['reference']['noise_rel_rms'] for r in rows]):.1f} | "
                     + " | ".join(mean_cell(lambda r, c=c: r["errors"][c]) for c in cols)
                     + f" | {mean_cell(lambda r: r.get('isolated_reference'))} | "
                     + f"{100 * np.mean([r['engine_object_vs_cpu_model'] for r in rows]):.2f} |")
    text = ("Each cell: relative RMS over the pixels (net of the reference's noise) / relative error of "
            "the mean colour / luminance bias of the mean, all in %.\n\n" + "\n".join(lines) + "\n")
    if result is not None:
        b, t = result.get("bake", {}), result.get("timings", {})
        tb = t.get("bake", {})
        text += (f"\nBake: {b.get('probes')} probes, {b.get('renders')} points rendered, "
                 f"{tb.get('seconds', float('nan')):.0f} s wall, {tb.get('cpu_seconds', float('nan')):.0f} CPU-s "
                 f"(lights {b.get('lights')}). Whole command: {t.get('total', float('nan')):.0f} s wall, "
                 f"{t.get('total_cpu_seconds', float('nan')):.0f} CPU-s (Blender and Cycles) + "
                 f"{t.get('children_cpu_seconds', float('nan')):.0f} CPU-s (schnee-view).\n")
    return text


if __name__ == "__main__":
    main()
