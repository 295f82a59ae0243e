"""A closed box lit only through one window (issue 27, daylight):
``blender -b --factory-startup -P scenes/make_daylight_box.py -- OUT.blend [--case sun|hdri|both]``

The room: interior 4 x 3 x 2.5 m (Blender x in -2..2, y in -1.5..1.5, z in 0..2.5), walls, floor and
ceiling 0.2 m thick (plaster, albedo about 0.8), closed except for a window of 1.6 x 1.2 m in the +Y
wall (x in -0.9..0.7, z in 1.15..2.35). One sun shines through the window, 40 deg up and 15 deg
east of +Y (TO_SUN), and draws a sharp-edged parallelogram of sunlight on the floor; no other light
enters. Cases (what lights the box from outside):

- ``sun``: a Sun lamp (SUN_STRENGTH W/m^2, SUN_ANGLE) along -TO_SUN; the world is black.
- ``hdri``: Blender's bundled ``sunrise.exr`` as the world, no lamp. Its sun (a disc of four texels,
  8 deg above its horizon, over half of the image's energy) is turned onto TO_SUN by a Mapping node
  (the rotation that takes the image's sun direction to TO_SUN), so it shines through the window
  along the lamp's path; the rest of the sky (its horizon tilted by the same rotation) lights the
  room through the window too.
- ``both``: the lamp and the HDRI together (two suns along one path).

Because the lamp and the HDRI's sun share one direction, one closed form (:func:`sun_lit`) says which
points are sunlit in every case. A ProbeVolumes collection holds one volume filling the interior.
SPHERES are six movable diffuse spheres (radius RADIUS, albedo 0.8, the add-on's "VS Movable
Diffuse" material with SH Scale 1 and Ambient Term 0, so the engine shows 0.8 E / pi) where daylight
is hard for probes; each has the direction from its centre to a camera 1.2 m away (the benchmark's
viewpoint, bench/bench_spheres.py ``--scene daylight``). tests/bench/test_daylight_box.py checks
the sunlit floor patch (Cycles) and the spheres' sun/shadow classes against :func:`sun_lit`.

The module imports without Blender (:func:`sun_lit`, the constants) so that tests and benchmarks
can use the closed form.
"""
import argparse
import math
import os
import sys

_HERE = os.path.dirname(os.path.abspath(__file__))

ROOM_MIN, ROOM_MAX = (-2.0, -1.5, 0.0), (2.0, 1.5, 2.5)
WALL = 0.2                               # thickness of walls, floor and ceiling
WINDOW = (-0.9, 0.7, 1.15, 2.35)         # x0, x1, z0, z1 of the opening in the +Y wall
SUN_ELEVATION = math.radians(40.0)
SUN_AZIMUTH = math.radians(15.0)         # from +Y towards +X
TO_SUN = (math.sin(SUN_AZIMUTH) * math.cos(SUN_ELEVATION),
          math.cos(SUN_AZIMUTH) * math.cos(SUN_ELEVATION),
          math.sin(SUN_ELEVATION))       # unit vector from the room towards the sun (Blender space)
SUN_STRENGTH = 4.0                       # W/m^2, as the sweep's sun lamps (bench/sweep/scenes.py)
SUN_ANGLE = math.radians(0.5)
HDRI = "sunrise.exr"
CASES = ("sun", "hdri", "both")
RADIUS = 0.3
ALBEDO = 0.8
CAM_DISTANCE = 1.2

# name, centre (Blender), direction from the centre to its camera, intended sunlit fraction class:
# "lit" (every surface point in the sun), "edge" (some are), "shadow" (none is; checked by sun_lit).
SPHERES = (
    ("beam", (-0.45, 0.45, 0.75), (1.0, -0.5, 0.3), "lit"),           # wholly in the sunbeam
    ("beam_edge", (0.33, 0.45, 0.75), (0.0, 0.2, 1.0), "edge"),       # across the beam's east side, from above
    ("below_beam", (-0.3, 1.15, 0.40), (0.0, -1.0, 0.6), "shadow"),   # under the beam by the window
    ("floor_patch", (0.62, -0.45, 0.32), (-0.4, -0.6, 0.6), "shadow"),  # beside the sunlit floor patch
    ("deep", (1.35, -0.9, 1.3), (-1.0, 0.5, 0.0), "shadow"),          # the far corner from the window
    ("wall", (-1.66, 0.3, 1.4), (1.0, -0.3, -0.1), "shadow"),         # 4 cm from the west wall
)


def sun_lit(point, to_sun=TO_SUN):
    """Whether the ray from ``point`` (inside the room, Blender space) towards the sun leaves the box
    through the window: the ray meets the wall's inner face y = ROOM_MAX.y and its outer face
    y = ROOM_MAX.y + WALL inside the opening. The interior and the opening's tunnel are convex, so a
    ray inside the opening at both faces touches nothing else (pure Python, no Blender)."""
    if to_sun[1] <= 0.0:
        return False
    x0, x1, z0, z1 = WINDOW
    for wall_y in (ROOM_MAX[1], ROOM_MAX[1] + WALL):
        t = (wall_y - point[1]) / to_sun[1]
        x, z = point[0] + t * to_sun[0], point[2] + t * to_sun[2]
        if not (x0 < x < x1 and z0 < z < z1):
            return False
    return True


def sun_lit_many(points, to_sun=TO_SUN):
    """:func:`sun_lit` for an (N, 3) array (numpy), as a bool array."""
    import numpy as np
    p = np.asarray(points, dtype=np.float64).reshape(-1, 3)
    s = np.asarray(to_sun, dtype=np.float64)
    ok = np.full(len(p), s[1] > 0.0)
    if s[1] <= 0.0:
        return ok
    x0, x1, z0, z1 = WINDOW
    for wall_y in (ROOM_MAX[1], ROOM_MAX[1] + WALL):
        t = (wall_y - p[:, 1]) / s[1]
        x, z = p[:, 0] + t * s[0], p[:, 2] + t * s[2]
        ok &= (x0 < x) & (x < x1) & (z0 < z) & (z < z1)
    return ok


def camera_position(centre, cam_dir):
    n = math.sqrt(sum(c * c for c in cam_dir))
    return tuple(c + CAM_DISTANCE * d / n for c, d in zip(centre, cam_dir))


def hdri_sun_direction(pixels):
    """Direction (Blender world space, default mapping) of the image's sun: the luminance-weighted
    centroid of its texels brighter than half the brightest. ``pixels``: (H, W, >=3), row 0 at the
    top; DESIGN.md §3: column i, row r look along phi = pi - 2 pi (i + 1/2) / W, theta = pi (r + 1/2) / H."""
    import numpy as np
    lum = np.asarray(pixels)[..., :3] @ np.array([0.2126, 0.7152, 0.0722])
    h, w = lum.shape
    rows, cols = np.nonzero(lum > 0.5 * lum.max())
    wgt = lum[rows, cols]
    phi = math.pi - 2 * math.pi * (cols + 0.5) / w
    theta = math.pi * (rows + 0.5) / h
    d = np.stack([np.sin(theta) * np.cos(phi), np.sin(theta) * np.sin(phi), np.cos(theta)], -1)
    v = (d * wgt[:, None]).sum(0)
    return tuple(v / np.linalg.norm(v))


def layout_problems(samples=400, seed=7):
    """What is wrong with SPHERES (empty when nothing): each sphere inside the room, clear of the
    walls and of the other spheres, its camera inside the room, and its surface points (``samples``
    random directions) in the sun as its class says ("lit": all, "edge": some but not all,
    "shadow": none). Pure Python + numpy."""
    import numpy as np
    d = np.random.default_rng(seed).normal(size=(samples, 3))
    d /= np.linalg.norm(d, axis=1, keepdims=True)
    lo, hi = np.array(ROOM_MIN), np.array(ROOM_MAX)
    out = []
    for k, (name, centre, cam_dir, cls) in enumerate(SPHERES):
        c = np.array(centre)
        if np.any(c - RADIUS < lo + 0.02) or np.any(c + RADIUS > hi - 0.02):
            out.append(f"{name}: closer than 2 cm to a wall")
        cam = np.array(camera_position(centre, cam_dir))
        if np.any(cam < lo + 0.05) or np.any(cam > hi - 0.05):
            out.append(f"{name}: camera {cam.round(3).tolist()} not inside the room")
        for other in SPHERES[k + 1:]:
            if np.linalg.norm(c - np.array(other[1])) < 2 * RADIUS + 0.02:
                out.append(f"{name} and {other[0]} overlap")
        frac = float(sun_lit_many(c + RADIUS * d).mean())
        if {"lit": frac < 1.0, "edge": not 0.2 < frac < 0.8, "shadow": frac > 0.0}[cls]:
            out.append(f"{name}: {frac:.3f} of its surface sunlit, class {cls}")
    return out


# ------------------------------------------------------------------ Blender
def _image_pixels(img):
    import numpy as np
    w, h = img.size
    buf = np.empty(w * h * img.channels, dtype=np.float32)
    img.pixels.foreach_get(buf)
    return buf.reshape(h, w, img.channels)[::-1]           # row 0 at the top


def rotated_hdri_world(lib, name=HDRI, to_sun=TO_SUN):
    """The bundled HDRI as the world, turned by a Mapping node so that its sun is seen along
    ``to_sun``. The lookup direction is R d (Mapping, type Point, on the Generated coordinate =
    the view direction); R is the shortest rotation taking ``to_sun`` to the image's sun direction.
    Returns (world, the image's sun direction, the Euler XYZ rotation)."""
    import bpy
    from mathutils import Vector
    world = lib.hdri_world(name)
    nt = world.node_tree
    env = next(n for n in nt.nodes if n.type == 'TEX_ENVIRONMENT')
    d0 = hdri_sun_direction(_image_pixels(env.image))
    rot = Vector(to_sun).normalized().rotation_difference(Vector(d0)).to_euler('XYZ')
    coord = nt.nodes.new("ShaderNodeTexCoord")
    mapping = nt.nodes.new("ShaderNodeMapping")
    mapping.vector_type = 'POINT'
    mapping.inputs["Rotation"].default_value = rot
    nt.links.new(coord.outputs["Generated"], mapping.inputs["Vector"])
    nt.links.new(mapping.outputs["Vector"], env.inputs["Vector"])
    bpy.context.scene["daylight_hdri_sun"] = list(d0)
    return world, d0, tuple(rot)


def black_world():
    import bpy
    world = bpy.context.scene.world
    world.use_nodes = True
    nt = world.node_tree
    nt.nodes.clear()
    bg = nt.nodes.new("ShaderNodeBackground")
    bg.inputs["Color"].default_value = (0.0, 0.0, 0.0, 1.0)
    bg.inputs["Strength"].default_value = 0.0
    out = nt.nodes.new("ShaderNodeOutputWorld")
    nt.links.new(bg.outputs["Background"], out.inputs["Surface"])
    return world


def sun_lamp(to_sun=TO_SUN):
    """The Sun lamp (no light mode set: the add-on's default applies)."""
    import bpy
    from mathutils import Vector
    data = bpy.data.lights.new("SunLamp", type='SUN')
    data.energy = SUN_STRENGTH
    data.angle = SUN_ANGLE
    ob = bpy.data.objects.new("SunLamp", data)
    bpy.context.scene.collection.objects.link(ob)
    ob.location = (0.0, 0.0, 5.0)                  # a Sun's position does not matter
    ob.rotation_euler = (-Vector(to_sun)).to_track_quat('-Z', 'Y').to_euler()
    return ob


def movable_material(name="TestGrey"):
    """The "VS Movable Diffuse" material (SH Scale 1, Ambient Term 0) when the add-on's nodes module
    is importable, else a plain diffuse of the same albedo."""
    import scene_lib as lib
    try:
        from schnee_probes import nodes
        return nodes.make_movable_diffuse_material(name, base_color=(ALBEDO, ALBEDO, ALBEDO, 1.0),
                                                   sh_scale=1.0, ambient=0.0)
    except ImportError as exc:
        print(f"make_daylight_box: movable material fallback ({exc})")
        return lib.diffuse_material(name, (ALBEDO, ALBEDO, ALBEDO))


def build(case="sun", spheres=SPHERES, make_material=None):
    """Builds the box for ``case`` into an emptied scene; returns the scene. Spheres are named
    ``Sphere_<name>`` in the collection "Movable", their material made by ``make_material()``
    (after the scene is emptied; default: :func:`movable_material`)."""
    if case not in CASES:
        raise ValueError(f"case {case!r} is not one of {', '.join(CASES)}")
    sys.path.insert(0, _HERE)
    import scene_lib as lib
    scene = lib.clear_scene()
    if case == "sun":
        black_world()
    else:
        _, d0, rot = rotated_hdri_world(lib)
        print(f"make_daylight_box: {HDRI}'s sun at {tuple(round(c, 4) for c in d0)}, "
              f"Mapping rotation {tuple(round(math.degrees(r), 3) for r in rot)} deg")
    if case in ("sun", "both"):
        sun_lamp()
    walls = lib.collection("Room")
    plaster = lib.diffuse_material("Plaster", (0.8, 0.78, 0.75))
    plaster["schnee_probe_mode"] = "pixel"    # large static surfaces: per pixel (as the default scene)
    lib.room_walls(ROOM_MIN, ROOM_MAX, thickness=WALL, coll=walls, material=plaster, window=WINDOW)
    lib.probe_volume("RoomVolume", ROOM_MIN, ROOM_MAX)

    movable = lib.collection("Movable")
    mat = (make_material or movable_material)()
    for name, centre, _cam, _cls in spheres:
        lib.movable_sphere(name, centre, RADIUS, mat, movable)
    scene["daylight_case"] = case
    scene.render.engine = 'CYCLES'
    scene.cycles.use_denoising = False          # Debian's Blender has no OpenImageDenoise
    return scene


def main():
    argv = sys.argv[sys.argv.index("--") + 1:] if "--" in sys.argv else []
    p = argparse.ArgumentParser(prog="make_daylight_box.py")
    p.add_argument("output", help="the .blend to write")
    p.add_argument("--case", default="sun", choices=CASES)
    args = p.parse_args(argv)
    sys.path.insert(0, _HERE)
    sys.path.append(os.path.join(os.path.dirname(_HERE), "addon"))  # schnee_probes.nodes, if present
    import scene_lib as lib
    build(args.case)
    print("saved", lib.save(args.output))


if __name__ == "__main__":
    main()
