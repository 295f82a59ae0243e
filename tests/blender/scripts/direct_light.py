"""Direct light against real Cycles: ``blender -b --factory-startup -P direct_light.py -- OUT_DIR``.

1. Conventions: 512x256 panoramas (256 spp, box filter, black world, no bounces) of camera-visible
   lamps at the origin's camera — point (radius 0.5, 100 W at 2 m), spot (same, axis 10° and 25° off
   the camera, cone 60°, blend 0.5), area rectangle 1 x 0.5 m and disk 1 m (100 W at 2 m, facing the
   camera) — projected with native.project_file, next to native.direct_project of the same lamp
   (lamp records built by direct_light.lamp_record from the Blender objects).
   And a Sun of strength 3 (angle 0 and 40°) straight above a white diffuse plane seen from 0.5 m:
   the mean radiance of the lower panorama rows against the irradiance the native sun disc
   projection gives, √(4π/3)·L_1(up) / π (exact: cos θ is band 1 and the disc is above the horizon).
2. Add-on bakes (bake_core.ProbeBake) under a black world with one Sun lamp of strength 3 pointing
   straight down and an opaque box over half of the probe volume: every probe's coefficients, the
   lamp's visible_camera before/during/after, the bake's messages. A second bake with a point lamp
   of radius 0 (invisible to camera rays) and nothing else in the scene.
Emits RESULT lines (JSON).
"""
import math
import os
import sys

import bpy
import numpy as np
from mathutils import Vector

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import addon_common as common  # noqa: E402
from addon_common import scene_lib as lib  # noqa: E402

from schnee_probes import bake_core, direct_light, native  # noqa: E402


def black_world():
    scene = bpy.context.scene
    if scene.world is None:
        scene.world = bpy.data.worlds.new("World")
    w = scene.world
    w.use_nodes = True
    w.node_tree.nodes["Background"].inputs["Color"].default_value = (0.0, 0.0, 0.0, 1.0)
    w.node_tree.nodes["Background"].inputs["Strength"].default_value = 0.0


def camera():
    scene = bpy.context.scene
    cd = bpy.data.cameras.new("Pano")
    cd.type = 'PANO'
    cd.cycles.panorama_type = 'EQUIRECTANGULAR'
    cam = bpy.data.objects.new("Pano", cd)
    scene.collection.objects.link(cam)
    cam.rotation_euler = (math.pi / 2, 0.0, -math.pi / 2)
    scene.camera = cam
    return cam


def lamp(kind, loc, **props):
    data = bpy.data.lights.new(kind, kind)
    for k, v in props.items():
        setattr(data, k, v)
    ob = bpy.data.objects.new(kind, data)
    bpy.context.scene.collection.objects.link(ob)
    ob.location = loc
    ob.visible_camera = True
    return ob


def aim(ob, target):
    ob.rotation_euler = (Vector(target) - ob.location).to_track_quat('-Z', 'Y').to_euler()
    bpy.context.view_layer.update()


def render(out, name):
    path = os.path.join(out, name + ".exr")
    bpy.ops.render.render(write_still=False)
    bpy.data.images["Render Result"].save_render(path, scene=bpy.context.scene)
    return path


def conventions(out):
    lib.clear_scene()
    black_world()
    scene = bpy.context.scene
    scene.render.engine = 'CYCLES'
    scene.cycles.device = 'CPU'
    scene.cycles.samples = 256
    scene.cycles.use_denoising = False
    scene.cycles.max_bounces = 0
    scene.cycles.pixel_filter_type = 'BOX'
    scene.cycles.filter_width = 1.0
    scene.cycles.seed = 0
    scene.render.image_settings.file_format = 'OPEN_EXR'
    scene.render.image_settings.color_depth = '32'
    scene.render.resolution_x, scene.render.resolution_y = 512, 256
    scene.render.resolution_percentage = 100
    cam = camera()

    def case(name, ob):
        ob.visible_camera = True
        bpy.context.view_layer.update()
        path = render(out, name)
        rendered = native.project_file(path, 2)
        rec = direct_light.lamp_record(ob.data, ob.matrix_world, (1.0, 1.0, 1.0))
        analytic = native.direct_project([rec], np.zeros(3), 2, 4096)[0]
        common.emit(case="convention", name=name, rendered=rendered.tolist(), analytic=analytic.tolist())
        bpy.data.objects.remove(ob, do_unlink=True)

    case("point", lamp('POINT', (2.0, 0.0, 0.0), energy=100.0, shadow_soft_size=0.5))
    for deg in (10, 25):
        ob = lamp('SPOT', (2.0, 0.0, 0.0), energy=100.0, shadow_soft_size=0.5, spot_size=math.radians(60),
                  spot_blend=0.5)
        a = math.radians(deg)
        aim(ob, (2.0 - 2.0 * math.cos(a), 2.0 * math.sin(a), 0.0))
        case(f"spot{deg}", ob)
    ob = lamp('AREA', (2.0, 0.0, 0.0), energy=100.0, shape='RECTANGLE', size=1.0, size_y=0.5)
    aim(ob, (0.0, 0.0, 0.0))
    case("rectangle", ob)
    ob = lamp('AREA', (2.0, 0.0, 0.0), energy=100.0, shape='DISK', size=1.0)
    aim(ob, (0.0, 0.0, 0.0))
    case("disk", ob)

    # Sun on a white diffuse plane.
    sun = lamp('SUN', (0.0, 0.0, 5.0), energy=3.0, angle=0.0)
    bpy.ops.mesh.primitive_plane_add(size=40.0)
    plane = bpy.context.active_object
    mat = bpy.data.materials.new("White")
    mat.use_nodes = True
    nodes = mat.node_tree.nodes
    nodes.remove(nodes["Principled BSDF"])
    diffuse = nodes.new("ShaderNodeBsdfDiffuse")
    diffuse.inputs["Color"].default_value = (1.0, 1.0, 1.0, 1.0)
    mat.node_tree.links.new(diffuse.outputs[0], nodes["Material Output"].inputs[0])
    plane.data.materials.append(mat)
    cam.location = (0.0, 0.0, 0.5)
    for deg in (0, 40):
        sun.data.angle = math.radians(deg)
        path = render(out, f"sun{deg}")
        img = bpy.data.images.load(path)
        w, h = img.size
        px = np.array(img.pixels[:], dtype=np.float64).reshape(h, w, 4)  # bottom-up: row 0 looks down
        below = px[: h // 8, :, 0].mean()
        bpy.data.images.remove(img)
        rec = direct_light.lamp_record(sun.data, sun.matrix_world, (1.0, 1.0, 1.0))
        coeffs = native.direct_project([rec], np.zeros(3), 1, 4096)[0]
        common.emit(case="sun_plane", angle=deg, rendered=below, l1_up=coeffs[1].tolist())


def bake_scene(out, name, kind, placement="OCTREE"):
    lib.clear_scene()
    black_world()
    lib.probe_volume("Volume", (-2.0, -0.5, 0.0), (2.0, 0.5, 1.0))
    if kind == "sun":
        lib.box("Roof", (0.0, -3.0, 3.0), (6.0, 3.0, 3.2), material=lib.diffuse_material("Grey", (0.5, 0.5, 0.5)))
        ob = lamp('SUN', (0.0, 0.0, 10.0), energy=3.0)  # default angle, pointing straight down
    elif kind == "portal":  # a Cycles light portal over the volume: it emits nothing
        ob = lamp('AREA', (0.0, 0.0, 2.5), energy=200.0, size=1.0)
        ob.data.cycles.is_portal = True
    else:
        ob = lamp('POINT', (-1.5, 0.0, 2.5), energy=200.0, shadow_soft_size=0.0)
    ob.visible_camera = True
    ob.name = "Lamp"
    # Baked explicitly: a Sun and a small point lamp default to mixed (light_modes.py), and these
    # bakes check the lamp's direct light in the probes.
    ob["schnee_light_mode"] = "baked"
    before = ob.visible_camera
    settings = bake_core.BakeSettings(placement=placement, min_cell_size=0.5 if placement == "ADAPTIVE" else 1.0,
                                      max_cell_size=1.0, panorama_resolution=32, samples=16,
                                      max_bounces=4, capture_sky=False,
                                      output_path=os.path.join(out, name, "probes.shprobe"))
    job = bake_core.ProbeBake(bpy.context.scene, bpy.context.view_layer, settings, log=lambda *_: None)
    job.prepare()
    during = bpy.data.objects["Lamp"].visible_camera
    while job.step():
        pass
    result = job.finish()
    if placement == "ADAPTIVE":  # every rendered point (probes and test points) of the refinement
        done = job.plan.cache.rendered
        common.emit(case="bake", name=name, coeffs=job.plan.cache.coeffs[done].tolist(),
                    positions=job.plan.cache.positions[done].tolist(), noise=job.plan.cache.noise[done].tolist())
        return
    common.emit(case="bake", name=name, coeffs=job.coeffs.tolist(), positions=job.positions.tolist(),
                visible_camera=[before, during, bpy.data.objects["Lamp"].visible_camera],
                messages=result.messages, direct_seconds=result.timings.get("direct"),
                render_seconds=result.timings.get("render"))


def main():
    out = common.args()[0]
    conventions(out)
    bake_scene(out, "sun", "sun")
    bake_scene(out, "point0", "point")
    bake_scene(out, "portal", "portal")
    bake_scene(out, "point0_adaptive", "point", placement="ADAPTIVE")


main()
