"""Light modes in the bake: ``blender -b --factory-startup -P lights_bake.py -- OUT_DIR``.

A small open scene (grey floor, dim constant world) with two point lamps: "KeyLamp" carries no
``schnee_light_mode`` (= baked) and stays in every bake; "TestLamp" is switched between the
cases below. Tiny bakes (4 probes, 32x16 panoramas, 16 spp, 4 bounces, same seed, no sky):

- realtime: TestLamp marked realtime (through the panel's operator);
- baked:    TestLamp marked baked;
- mixed:    TestLamp marked mixed (bounced light only; mixed_during: its flags during a bake);
- deleted:  TestLamp deleted from the scene (seeds 0 and 1: the second measures the noise);
- bad:      TestLamp's property set to "Realtime" (wrong case): refused before anything changes;
- cancelled: TestLamp realtime, one probe rendered, then cancelled.

Emits RESULT lines: each bake's coefficients, each lamp's visibility flags before and after every
bake, the bad value's message.
"""
import os
import sys

import bpy

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import addon_common as common  # noqa: E402
from addon_common import scene_lib as lib  # noqa: E402

import schnee_probes  # noqa: E402
from schnee_probes import bake_core, scene_export  # noqa: E402

FLAGS = ("hide_render", "hide_viewport", "hide_select", "visible_camera", "visible_diffuse",
         "visible_glossy", "visible_transmission", "visible_volume_scatter", "visible_shadow")


def build_scene():
    lib.clear_scene()
    world = bpy.context.scene.world
    world.use_nodes = True
    world.node_tree.nodes["Background"].inputs["Color"].default_value = (0.05, 0.05, 0.05, 1.0)
    world.node_tree.nodes["Background"].inputs["Strength"].default_value = 1.0
    lib.box("Floor", (-3.0, -3.0, -0.2), (3.0, 3.0, 0.0), material=lib.diffuse_material("Grey", (0.5, 0.5, 0.5)))
    lib.probe_volume("Volume", (-1.0, -1.0, 0.5), (1.0, 1.0, 1.5))
    for name, loc, power in (("KeyLamp", (-2.0, 0.0, 2.5), 300.0), ("TestLamp", (1.5, 0.5, 2.0), 200.0)):
        data = bpy.data.lights.new(name, 'POINT')
        data.energy = power
        ob = bpy.data.objects.new(name, data)
        ob.location = loc
        bpy.context.scene.collection.objects.link(ob)
    # Flags a user may have set: a bake must give them back exactly, not reset them to defaults.
    test = bpy.data.objects["TestLamp"]
    test.visible_glossy = False
    test.hide_select = True
    test.visible_camera = True  # (a new lamp object's is off in 3.4): the mixed case must switch it


def flags():
    return {ob.name: {f: bool(getattr(ob, f)) for f in FLAGS}
            for ob in bpy.data.objects if ob.type == 'LIGHT'}


def settings(out, name, seed=0):
    return bake_core.BakeSettings(placement="OCTREE", min_cell_size=1.0, max_cell_size=1.0, panorama_resolution=32,
                                  samples=16, max_bounces=4, seed=seed, capture_sky=False,
                                  output_path=os.path.join(out, name, "probes.shprobe"))


def bake(out, name, seed=0):
    before = flags()
    scene, layer = bpy.context.scene, bpy.context.view_layer
    job = bake_core.ProbeBake(scene, layer, settings(out, name, seed), log=lambda *_: None)
    result = job.run()
    common.emit(case=name, coeffs=job.coeffs.tolist(), positions=job.positions.tolist(),
                flags_before=before, flags_after=flags(), messages=result.messages)


def flags_around_cancelled_bake(out, name, steps):
    """Lamp flags before a bake, after its prepare() (what the probe renders see) and after it is
    cancelled having rendered ``steps`` probes."""
    before = flags()
    job = bake_core.ProbeBake(bpy.context.scene, bpy.context.view_layer, settings(out, name),
                              log=lambda *_: None)
    job.prepare()
    during = flags()
    for _ in range(steps):
        job.step()
    job.cancel()
    return dict(flags_before=before, flags_during=during, flags_after=flags())


def set_mode_with_operator(mode):
    test = bpy.data.objects["TestLamp"]
    for ob in bpy.context.view_layer.objects:
        ob.select_set(False)
    bpy.context.view_layer.objects.active = test
    assert bpy.ops.schnee.set_light_mode(mode=mode) == {'FINISHED'}


class _StubLayout:
    """Records what a panel's draw() puts into its layout (panels cannot draw in background mode)."""

    def __init__(self, log):
        self.log = log

    def column(self, **_):
        return self

    row = column

    def label(self, text="", **_):
        self.log.append(("label", text))

    def operator(self, idname, text="", depress=False, **_):
        log = self.log

        class Props:
            def __setattr__(self, key, value):
                log.append(("operator", idname, text, depress, value))
        return Props()


def draw_light_panel():
    from schnee_probes import panel
    log = []
    stub = type("StubPanel", (), {"layout": _StubLayout(log)})()
    panel.VIEW3D_PT_schnee_light.draw(stub, bpy.context)
    return [list(x) for x in log]


def main():
    out = common.args()[0]
    build_scene()
    schnee_probes.register()
    set_mode_with_operator("realtime")
    common.emit(case="operator", value=bpy.data.objects["TestLamp"].get("schnee_light_mode"),
                panel=draw_light_panel())
    bake(out, "realtime")

    # Cancelled after one probe: flags restored all the same.
    common.emit(case="cancelled", **flags_around_cancelled_bake(out, "cancelled", steps=1))

    # A bad value is refused before anything changes.
    bpy.data.objects["TestLamp"]["schnee_light_mode"] = "Realtime"
    before = flags()
    job = bake_core.ProbeBake(bpy.context.scene, bpy.context.view_layer, settings(out, "bad"),
                              log=lambda *_: None)
    try:
        job.run()
        message = None
    except bake_core.BakeError as exc:
        message = str(exc)
    common.emit(case="bad", message=message, flags_before=before, flags_after=flags(),
                wrote=os.path.exists(os.path.join(out, "bad")))

    set_mode_with_operator("baked")
    bake(out, "baked")
    set_mode_with_operator("mixed")
    test = bpy.data.objects["TestLamp"]
    common.emit(case="mixed_during", **flags_around_cancelled_bake(out, "mixed_during", steps=0),
                panel=draw_light_panel(), lamp_engine=scene_export.blender_to_engine([test.location])[0].tolist(),
                lamp_power=float(test.data.energy), lamp_radius=float(test.data.shadow_soft_size))
    bake(out, "mixed")
    set_mode_with_operator("baked")
    bpy.data.objects.remove(bpy.data.objects["TestLamp"], do_unlink=True)
    bake(out, "deleted")
    bake(out, "deleted_seed1", seed=1)


if __name__ == "__main__":
    main()
