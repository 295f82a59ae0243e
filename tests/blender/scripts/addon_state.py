"""Scene state before and after a successful, a failed and a cancelled bake (and a refused one):
``blender -b sky.blend -P addon_state.py -- OUT_DIR``. Emits the differences found (expected: none)
and whether the previous .shprobe survived the failed and cancelled bakes byte for byte.

The snapshot here is deliberately independent of the add-on's own (render_settings.py): it walks
every RNA property, read-only ones included, of the structs a bake could touch.
"""
import hashlib
import os
import sys

import bpy

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import addon_common as common  # noqa: E402

import schnee_probes  # noqa: E402
from schnee_probes import bake_core, native  # noqa: E402

SKIP = {"rna_type", "depsgraph", "denoiser", "preview_denoiser", "linear_colorspace_settings",
        "is_evaluated", "original", "users", "session_uid", "is_dirty"}


def walk(struct, prefix, out, depth=0):
    for prop in struct.bl_rna.properties:
        ident = prop.identifier
        if ident in SKIP:
            continue
        key = prefix + "." + ident
        try:
            value = getattr(struct, ident)
        except Exception as exc:  # some properties refuse reading in background mode
            out[key] = f"<{type(exc).__name__}>"
            continue
        if prop.type == 'POINTER':
            if value is None or isinstance(value, bpy.types.ID):
                out[key] = getattr(value, "name", None)
            elif depth < 3:
                walk(value, key, out, depth + 1)
        elif prop.type == 'COLLECTION':
            items = list(value)
            out[key + ".len"] = len(items)
            if depth < 2 and ident in {"views", "aovs", "lightgroups"}:
                for i, item in enumerate(items):
                    walk(item, f"{key}[{i}]", out, depth + 1)
        else:
            out[key] = tuple(value) if getattr(prop, "is_array", False) else value
    return out


def snapshot():
    scene = bpy.context.scene
    out = {}
    walk(scene.render, "render", out)
    walk(scene.cycles, "cycles", out)
    walk(scene.view_settings, "view_settings", out)
    walk(bpy.context.view_layer, "view_layer", out)
    out["scene.camera"] = scene.camera.name if scene.camera else None
    out["scene.world"] = scene.world.name if scene.world else None
    out["scene.frame"] = (scene.frame_current, scene.frame_subframe)
    out["objects"] = tuple(sorted(o.name for o in bpy.data.objects))
    out["cameras"] = tuple(sorted(c.name for c in bpy.data.cameras))
    out["images"] = tuple(sorted(i.name for i in bpy.data.images if i.type != 'RENDER_RESULT'))
    for ob in bpy.data.objects:
        for ident in ("hide_render", "hide_viewport", "visible_camera", "location", "rotation_euler"):
            v = getattr(ob, ident)
            out[f"object[{ob.name}].{ident}"] = tuple(v) if not isinstance(v, bool) else v
        if ob.name in bpy.context.view_layer.objects:
            out[f"object[{ob.name}].hide_get"] = ob.hide_get()
        for mod in ob.modifiers:  # placement evaluates modifiers as rendered, then puts them back
            for ident in ("show_viewport", "show_render", "levels", "render_levels"):
                if hasattr(mod, ident):
                    out[f"object[{ob.name}].modifiers[{mod.name}].{ident}"] = getattr(mod, ident)
    for coll in bpy.data.collections:
        out[f"collection[{coll.name}].hide_viewport"] = coll.hide_viewport
    for cam in bpy.data.cameras:
        walk(cam, f"camera[{cam.name}]", out)
    return out


def diff(a, b):
    return sorted(k for k in set(a) | set(b) if a.get(k) != b.get(k))


def digest(path):
    with open(path, "rb") as fh:
        return hashlib.sha256(fh.read()).hexdigest()


def make_odd_settings():
    """Settings far from the bake's, so a missed restore shows."""
    scene = bpy.context.scene
    r = scene.render
    r.engine = 'BLENDER_EEVEE'
    r.resolution_x, r.resolution_y, r.resolution_percentage = 1234, 567, 37
    r.film_transparent = True
    r.use_persistent_data = False
    r.use_compositing = True
    r.filepath = "//odd/frame_"
    r.image_settings.file_format = 'PNG'
    r.image_settings.color_mode = 'RGBA'
    r.image_settings.color_depth = '16'
    c = scene.cycles
    c.samples, c.max_bounces, c.diffuse_bounces = 7, 3, 2
    c.pixel_filter_type, c.filter_width = 'GAUSSIAN', 2.25
    c.use_denoising = False
    c.use_adaptive_sampling = True
    c.film_exposure = 1.7
    c.sample_clamp_indirect = 3.0
    bpy.context.view_layer.samples = 5
    scene.frame_set(17)
    cam_data = bpy.data.cameras.new("UserCamera")
    cam = bpy.data.objects.new("UserCamera", cam_data)
    scene.collection.objects.link(cam)
    scene.camera = cam
    light = bpy.data.objects.new("UserLamp", bpy.data.lights.new("UserLamp", 'POINT'))
    light.location = (0.0, 0.0, 1.0)
    light.visible_camera = False
    scene.collection.objects.link(light)
    # Render-only geometry far outside the volume: placement switches its viewport flags and
    # modifiers to the render's for a moment (render_settings.RenderEvaluation).
    coll = bpy.data.collections.new("UserProps")
    scene.collection.children.link(coll)
    coll.hide_viewport = True
    for name, z in (("UserHidden", 20.0), ("UserEyeHidden", 23.0)):
        mesh = bpy.data.meshes.new(name)
        mesh.from_pydata([(0, 0, 0), (1, 0, 0), (0, 1, 0), (0, 0, 1)], [], [(0, 1, 2), (0, 1, 3), (0, 2, 3), (1, 2, 3)])
        ob = bpy.data.objects.new(name, mesh)
        ob.location = (0.0, 0.0, z)
        scene.collection.objects.link(ob)
        sub = ob.modifiers.new("Subdiv", 'SUBSURF')
        sub.levels, sub.render_levels = 0, 2
        arr = ob.modifiers.new("Array", 'ARRAY')
        arr.show_viewport = False
    bpy.data.objects["UserHidden"].hide_viewport = True
    bpy.data.objects["UserEyeHidden"].hide_set(True)


def main():
    out_dir = common.args()[0]
    schnee_probes.register()
    make_odd_settings()
    scene = bpy.context.scene
    output = os.path.join(out_dir, "sh_coeffs", "probes.shprobe")
    settings = bake_core.BakeSettings(placement="OCTREE", min_cell_size=2.0, max_cell_size=2.0, panorama_resolution=16,
                                      samples=1, output_path=output)
    results = {}
    before = snapshot()
    # The snapshot must see a change of the kind a bake makes, or the comparisons prove nothing.
    scene.cycles.samples += 1
    results["selfcheck"] = diff(before, snapshot())
    scene.cycles.samples -= 1

    # 1. success
    bake_core.ProbeBake(scene, bpy.context.view_layer, settings).run()
    results["success"] = diff(before, snapshot())
    good = digest(output)

    # 2. failure in the middle: the projection of the second probe raises
    original = native.project_pixels
    calls = [0]

    def failing(*a, **k):
        calls[0] += 1
        if calls[0] == 2:
            raise native.SchneeError("injected failure", "io error")
        return original(*a, **k)

    native.project_pixels = failing
    try:
        bake_core.ProbeBake(scene, bpy.context.view_layer, settings).run()
        results["failure_raised"] = False
    except bake_core.BakeError as exc:
        results["failure_raised"] = "injected failure" in str(exc)
    finally:
        native.project_pixels = original
    results["failure"] = diff(before, snapshot())
    results["failure_file_unchanged"] = digest(output) == good

    # 3. cancel after one probe (what Esc does in the modal operator)
    bake = bake_core.ProbeBake(scene, bpy.context.view_layer, settings)
    bake.prepare()
    bake.step()
    bake.cancel()
    results["cancel"] = diff(before, snapshot())
    results["cancel_file_unchanged"] = digest(output) == good

    # 4. refused input (non-mesh in the volume collection): nothing may change either
    empty = bpy.data.objects.new("NotAMesh", None)
    bpy.data.collections["ProbeVolumes"].objects.link(empty)
    before_refused = snapshot()
    try:
        bake_core.ProbeBake(scene, bpy.context.view_layer, settings).run()
        results["refused_raised"] = False
    except bake_core.BakeError:
        results["refused_raised"] = True
    results["refused"] = diff(before_refused, snapshot())
    bpy.data.objects.remove(empty)

    # 5. the operator (synchronous in background mode) leaves the scene as it found it too
    scene.schnee_probes.output_path = output
    scene.schnee_probes.placement = "OCTREE"  # the 4-probe geometry octree this test counts
    scene.schnee_probes.min_cell_size = scene.schnee_probes.max_cell_size = 2.0
    scene.schnee_probes.panorama_resolution = 16
    scene.schnee_probes.samples = 1
    before_op = snapshot()
    results["operator_result"] = sorted(bpy.ops.schnee.bake_sh_volumes())
    after_op = snapshot()
    results["operator"] = [k for k in diff(before_op, after_op)]
    results["operator_probe_count"] = scene.schnee_probes.last_probe_count
    common.emit(**results)


main()
