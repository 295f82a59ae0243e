"""Inside a Blender of any version with the add-on installed (as version_checks.py): the lamp
conventions the direct-light step (docs/direct-light.md) assumes, against this Blender's Cycles.
``-- WORK_DIR``. Prints one ``RESULT {json}`` line; test_blender_versions.py checks it.

- sun_bake: a Sun lamp (strength 3, angle 0) under a black world, baked at the cursor: the probe
  must hold exactly S·Y(d) (the issue-11 example: L0 = 3 · 0.2821; before issue 11, zero).
- sun_plane: a white diffuse plane (albedo 0.8) lit by a Sun of strength 3 and angle 10° at 40°
  from the normal, seen from above by an orthographic camera: a pixel renders 0.8·S·cos 40°/π.
- {point,spot}_{soft,hard}_render_l0: a point/spot lamp (P = 100 W, radius 0.25 m) 1 m from an
  equirect camera, black world, rendered with the lamp visible to the camera and projected, with
  Soft Falloff on/off (Blender 4.0+); L0 reported next to the two closed forms, radiance
  P/(4π²r²) over a sphere (half-angle asin(r/d)) or a disc facing the viewer (atan(r/d)).
- {...}_bake_l0: the same lamp baked at the cursor (hidden from camera rays, added analytically).
  Every lamp above is marked baked with the legacy custom property ``schnee_light_mode``.
- modes, default_sun_*: the light-mode defaults by type and the choices (light_mode_checks).
"""
import importlib
import json
import math
import os
import sys
import traceback

import addon_utils
import bpy

work = sys.argv[sys.argv.index("--") + 1]
out = {"blender": list(bpy.app.version)}


def black_world(scene):
    world = bpy.data.worlds.new("Black")
    world.use_nodes = True
    bg = next(n for n in world.node_tree.nodes if n.type == 'BACKGROUND')
    bg.inputs["Color"].default_value = (0.0, 0.0, 0.0, 1.0)
    scene.world = world


def lamp(scene, kind, loc, rot=(0.0, 0.0, 0.0), **props):
    data = bpy.data.lights.new(kind.title(), kind)
    for k, v in props.items():
        setattr(data, k, v)
    ob = bpy.data.objects.new(kind.title(), data)
    ob.location = loc
    ob.rotation_euler = rot
    if hasattr(ob, "visible_camera"):
        ob.visible_camera = True   # lamps default to invisible to camera rays
    # Baked explicitly (the legacy custom property): these checks compare the lamp's direct light
    # in the probes with the render; a Sun and a small point or spot lamp default to mixed.
    ob["schnee_light_mode"] = "baked"
    scene.collection.objects.link(ob)
    return ob


def light_mode_checks(scene, name, bake_core):
    """The light-mode defaults and choices in this Blender (light_modes.py, properties.py): each
    lamp type's default, the registered property, the legacy custom property and a Sun left at
    its default baked at the cursor (its direct light out of the probe: exactly 0 here)."""
    light_modes = importlib.import_module(name + ".light_modes")
    clear(scene)
    modes = {}
    for kind, radius in (('SUN', None), ('POINT', 0.25), ('POINT', 0.5), ('SPOT', 0.25), ('AREA', None)):
        data = bpy.data.lights.new(f"{kind}{radius}", kind)
        if radius is not None:
            data.shadow_soft_size = radius
        ob = bpy.data.objects.new(f"{kind}{radius}", data)
        scene.collection.objects.link(ob)
        modes[f"{kind}{radius}"] = light_modes.resolve(ob)
    ob = bpy.data.objects["SUN" + "None"]
    ob.schnee_light.mode = 'BAKED'
    modes["chosen"] = light_modes.resolve(ob)
    ob["schnee_light_mode"] = "realtime"
    modes["legacy_over_chosen"] = light_modes.resolve(ob)
    ob.schnee_light.mode = 'MIXED'              # a choice in the UI removes the legacy property
    modes["chosen_again"] = light_modes.resolve(ob) + (light_modes.PROPERTY in ob.keys(),)
    out["modes"] = modes
    # Properties > Light's panel drawn into a recording layout (no window in background mode) that
    # checks each property it is given exists, as Blender's layout does.
    log = []

    class Layout:
        def column(self, **_):
            return self
        row = box = column

        def label(self, text="", **_):
            log.append(["label", text])

        def prop(self, data, prop, **_):
            assert prop in data.bl_rna.properties, prop
            log.append(["prop", prop, getattr(data, prop)])

        def operator_menu_enum(self, *args, **_):
            log.append(["menu"])
    panel = importlib.import_module(name + ".panel")
    ctx = type("Ctx", (), {"object": ob, "scene": scene, "active_object": ob, "selected_objects": [ob]})()
    assert panel.DATA_PT_schnee_light.poll(ctx)
    panel.DATA_PT_schnee_light.draw(type("P", (), {"layout": Layout()})(), ctx)
    out["data_panel"] = log
    clear(scene)
    sun = bpy.data.objects.new("DefaultSun", bpy.data.lights.new("DefaultSun", 'SUN'))
    sun.data.energy, sun.data.angle = 3.0, 0.0
    scene.collection.objects.link(sun)
    out["default_sun_mode"] = light_modes.light_mode(sun)
    out["default_sun_bake"] = cursor_bake(scene, bake_core, "default_sun", (0.0, 0.0, 1.0))


def clear(scene):
    for ob in list(bpy.data.objects):
        bpy.data.objects.remove(ob)
    scene.render.engine = 'CYCLES'
    c = scene.cycles
    c.use_denoising = False
    c.use_adaptive_sampling = False
    c.pixel_filter_type = 'BOX'
    c.filter_width = 1.0
    c.sample_clamp_direct = 0.0
    c.sample_clamp_indirect = 0.0
    black_world(scene)


def cursor_bake(scene, bake_core, name, location):
    settings = bake_core.BakeSettings(output_path=os.path.join(work, name, "probes.shprobe"))
    job = bake_core.ProbeBake(scene, bpy.context.view_layer, settings, mode="CURSOR", cursor=location,
                              log=lambda *_: None)
    job.run()
    return job.coeffs[0].tolist()


def render(scene, path):
    scene.render.image_settings.file_format = 'OPEN_EXR'
    scene.render.image_settings.color_depth = '32'
    scene.render.resolution_percentage = 100
    bpy.ops.render.render(write_still=False)
    bpy.data.images["Render Result"].save_render(path, scene=scene)


def main():
    name = next((m.__name__ for m in addon_utils.modules() if m.__name__.split(".")[-1] == "schnee_probes"), None)
    if name is not None:
        assert addon_utils.enable(name, default_set=True) is not None, "enabling the add-on failed"
    else:  # the host's source tree on PYTHONPATH (a run by hand in Blender 3.4)
        name = "schnee_probes"
        importlib.import_module(name).register()
    native = importlib.import_module(name + ".native")
    compat = importlib.import_module(name + ".compat")
    bake_core = importlib.import_module(name + ".bake_core")
    direct_light = importlib.import_module(name + ".direct_light")
    scene = bpy.context.scene

    light_mode_checks(scene, name, bake_core)

    # --- Sun, angle 0, pointing along (sin 30°, 0, -cos 30°) in Blender space
    clear(scene)
    lamp(scene, 'SUN', (0.0, 0.0, 5.0), (0.0, math.radians(30.0), 0.0), energy=3.0, angle=0.0)
    out["sun_bake"] = cursor_bake(scene, bake_core, "sun", (0.0, 0.0, 1.0))

    # --- Sun of angle 10° on a white plane at 40° incidence
    clear(scene)
    bpy.ops.mesh.primitive_plane_add(size=20.0)
    plane = bpy.context.active_object
    mat = bpy.data.materials.new("White")
    mat.use_nodes = True
    nt = mat.node_tree
    nt.nodes.clear()
    diffuse = nt.nodes.new("ShaderNodeBsdfDiffuse")   # roughness 0: Lambert in every version
    diffuse.inputs["Color"].default_value = (0.8, 0.8, 0.8, 1.0)
    diffuse.inputs["Roughness"].default_value = 0.0
    mat_out = nt.nodes.new("ShaderNodeOutputMaterial")
    nt.links.new(diffuse.outputs["BSDF"], mat_out.inputs["Surface"])
    plane.data.materials.append(mat)
    lamp(scene, 'SUN', (0.0, 0.0, 5.0), (math.radians(40.0), 0.0, 0.0), energy=3.0, angle=math.radians(10.0))
    cd = bpy.data.cameras.new("Ortho")
    cd.type = 'ORTHO'
    cd.ortho_scale = 2.0
    cam = bpy.data.objects.new("Ortho", cd)
    cam.location = (0.0, 0.0, 3.0)
    scene.collection.objects.link(cam)
    scene.camera = cam
    scene.render.resolution_x = scene.render.resolution_y = 16
    scene.cycles.samples = 64
    scene.cycles.max_bounces = 0
    path = os.path.join(work, "sun_plane.exr")
    render(scene, path)
    im = bpy.data.images.load(path)
    px = list(im.pixels)
    img_mean = sum(px[0::4]) / (len(px) // 4)
    out["sun_plane"] = img_mean
    out["sun_plane_expected"] = 0.8 * 3.0 * math.cos(math.radians(40.0)) / math.pi

    # --- point and spot lamps, radius 0.25, 1 m from an equirect camera (visible to camera rays),
    # with Cycles 4.0+'s Soft Falloff on (its default) and off; the spot (90°, blend 0) points 20°
    # away from the camera, so only a cos γ factor (Cycles 3.x) can change what is seen.
    r, d, p = 0.25, 1.0, 100.0
    radiance = p / (4.0 * math.pi ** 2 * r * r)
    y00 = 0.5 / math.sqrt(math.pi)
    out["point_sphere_l0"] = radiance * 2.0 * math.pi * (1.0 - math.sqrt(1.0 - (r / d) ** 2)) * y00
    out["point_disc_l0"] = radiance * 2.0 * math.pi * (1.0 - d / math.hypot(d, r)) * y00
    out["cos_gamma"] = math.cos(math.radians(20.0))
    out["legacy_point"] = bool(direct_light.LEGACY_POINT)
    for kind in ('POINT', 'SPOT'):
        for soft in (True, False):
            clear(scene)
            # Blender: the camera at (0, 0, 1) looks at the lamp at (1, 0, 1); the spot's axis
            # (its local -Z) is turned to point at the camera, then 20° further about Blender Z.
            rot = (0.0, math.pi / 2, math.radians(20.0))
            ob = lamp(scene, kind, (1.0, 0.0, 1.0), rot, energy=p, shadow_soft_size=r)
            if kind == 'SPOT':
                ob.data.spot_size = math.radians(90.0)
                ob.data.spot_blend = 0.0
            if hasattr(ob.data, "use_soft_falloff"):
                ob.data.use_soft_falloff = soft
            elif not soft:
                continue                      # Cycles 3.x: no such switch
            key = f"{kind.lower()}_{'soft' if soft else 'hard'}"
            cd = bpy.data.cameras.new("Pano")
            compat.set_equirectangular(cd)
            cam = bpy.data.objects.new("Pano", cd)
            cam.location = (0.0, 0.0, 1.0)
            cam.rotation_euler = (math.pi / 2, 0.0, -math.pi / 2)
            scene.collection.objects.link(cam)
            scene.camera = cam
            scene.render.resolution_x, scene.render.resolution_y = 512, 256
            scene.cycles.samples = 64
            path = os.path.join(work, key + ".exr")
            render(scene, path)
            out[key + "_render_l0"] = native.project_file(path, 0, negative="clamp")[0][0]
            out[key + "_bake_l0"] = cursor_bake(scene, bake_core, key, (0.0, 0.0, 1.0))[0][0]


try:
    main()
except Exception:  # the pytest side shows the traceback with the RESULT so far
    out["error"] = traceback.format_exc()
print("RESULT " + json.dumps(out), flush=True)
