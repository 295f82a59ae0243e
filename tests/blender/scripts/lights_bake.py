"""Light modes in the bake: ``blender -b --factory-startup -P lights_bake.py -- OUT_DIR``.

A small open scene (grey floor, dim constant world) with two point lamps: "KeyLamp" is marked
baked with the registered property (Object.schnee_light.mode = 'BAKED'; a 0.25 m point lamp
defaults to mixed) and stays in every bake; "TestLamp" is switched between the cases below.
Tiny bakes (4 probes, 32x16 panoramas, 16 spp, 4 bounces, same seed, no sky):

- realtime: TestLamp marked realtime (through the panel's operator);
- baked:    TestLamp marked baked;
- mixed:    TestLamp marked mixed (bounced light only; mixed_during: its flags during a bake);
- deleted:  TestLamp deleted from the scene (seeds 0 and 1: the second measures the noise);
- bad:      TestLamp's legacy custom property set to "Realtime" (wrong case): refused before
            anything changes;
- cancelled: TestLamp realtime, one probe rendered, then cancelled;
- sun_default / sun_baked: TestLamp deleted, a Sun lamp (angle 0) added, left at its default
  (mixed) / marked baked with the legacy custom property ``schnee_light_mode`` = "baked".

Also the light-mode panels (sidebar and Properties > Light) drawn into a recording stub, the
modes lamps of each type resolve to (modes), and the engine's shadow-map layers that three small
point lamps would need (layers).

Emits RESULT lines: each bake's coefficients, each lamp's visibility flags before and after every
bake, the bad value's message.
"""
import math
import os
import sys

import bpy
from mathutils import Vector

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


def mark_key_lamp_baked():
    bpy.data.objects["KeyLamp"].schnee_light.mode = 'BAKED'


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
    """Records what a panel's draw() puts into its layout (panels cannot draw in background mode).
    prop() checks that the property exists on the struct, as Blender's layout would."""

    def __init__(self, log):
        self.log = log

    def column(self, **_):
        return self

    row = box = column

    def label(self, text="", **_):
        self.log.append(("label", text))

    def prop(self, data, name, text=None, **_):
        if name not in data.bl_rna.properties:
            raise AttributeError(f"layout.prop: {data!r} has no property {name!r}")
        self.log.append(("prop", type(data).__name__, name, getattr(data, name)))

    def operator_menu_enum(self, idname, prop, text="", **_):
        self.log.append(("menu", idname, prop, text))

    def operator(self, idname, text="", depress=False, **_):
        log = self.log

        class Props:
            def __setattr__(self, key, value):
                log.append(("operator", idname, text, depress, value))
        return Props()


def draw_light_panel(cls="VIEW3D_PT_schnee_light"):
    """What the sidebar's Light Mode panel (or Properties > Light's, DATA_PT_schnee_light) draws
    for the active lamp; the panel's poll() must accept it."""
    from schnee_probes import panel
    log = []
    panel_cls = getattr(panel, cls)
    ctx = bpy.context.copy()
    ctx["object"] = bpy.context.view_layer.objects.active  # what the Properties editor's data tab sets
    ctx = type("Ctx", (), ctx)()
    assert panel_cls.poll(ctx)
    stub = type("StubPanel", (), {"layout": _StubLayout(log)})()
    panel_cls.draw(stub, ctx)
    return [list(x) for x in log]


def modes_by_type():
    """(mode, source) of a fresh lamp object of each type and two point radii, then (custom
    property, mode, source) after each step of the legacy-property / registered-property story."""
    from schnee_probes import light_modes
    out = {}
    for kind, radius in (('SUN', None), ('POINT', 0.1), ('POINT', 0.25), ('POINT', 0.3), ('SPOT', 0.25),
                         ('SPOT', 1.0), ('AREA', None)):
        data = bpy.data.lights.new("ModeLamp", kind)
        if radius is not None:
            data.shadow_soft_size = radius
        ob = bpy.data.objects.new("ModeLamp", data)
        out[f"{kind} {radius}"] = list(light_modes.resolve(ob))
        bpy.data.objects.remove(ob)
        bpy.data.lights.remove(data)
    ob = bpy.data.objects.new("StoryLamp", bpy.data.lights.new("StoryLamp", 'SUN'))
    story = []

    def step(what):
        story.append([what, ob.get(light_modes.PROPERTY), ob.schnee_light.mode] + list(light_modes.resolve(ob)))
    step("fresh")
    ob[light_modes.PROPERTY] = "baked"          # a script or a file from before the UI
    step("legacy baked")
    ob.schnee_light.mode = 'REALTIME'           # then a choice in the UI: removes the legacy one
    step("chose realtime")
    ob[light_modes.PROPERTY] = "baked"          # a script again: the latest, and explicit, wins
    step("legacy baked again")
    ob.schnee_light.mode = 'DEFAULT'            # By Type chosen: the legacy one goes, the default rules
    step("chose by type")
    bpy.data.objects.remove(ob)
    out["story"] = story
    from schnee_probes import properties
    out["items"] = [[i.identifier, i.name, i.description]
                    for i in properties.SchneeLightSettings.bl_rna.properties["mode"].enum_items]
    return out


def main():
    out = common.args()[0]
    build_scene()
    schnee_probes.register()
    mark_key_lamp_baked()
    common.emit(case="modes", **modes_by_type())
    # A legacy custom property on the lamp: the operator replaces it by the registered property.
    bpy.data.objects["TestLamp"]["schnee_light_mode"] = "baked"
    legacy_panel = draw_light_panel_of(bpy.data.objects["TestLamp"])
    set_mode_with_operator("REALTIME")
    test = bpy.data.objects["TestLamp"]
    common.emit(case="operator", value=test.get("schnee_light_mode"), chosen=test.schnee_light.mode,
                panel=draw_light_panel(), data_panel=draw_light_panel("DATA_PT_schnee_light"),
                legacy_panel=legacy_panel)
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

    set_mode_with_operator("BAKED")
    bake(out, "baked")
    set_mode_with_operator("MIXED")
    test = bpy.data.objects["TestLamp"]
    common.emit(case="mixed_during", **flags_around_cancelled_bake(out, "mixed_during", steps=0),
                panel=draw_light_panel(), lamp_engine=scene_export.blender_to_engine([test.location])[0].tolist(),
                lamp_power=float(test.data.energy), lamp_radius=float(test.data.shadow_soft_size))
    bake(out, "mixed")
    set_mode_with_operator("BAKED")
    bpy.data.objects.remove(bpy.data.objects["TestLamp"], do_unlink=True)
    bake(out, "deleted")
    bake(out, "deleted_seed1", seed=1)

    # A Sun lamp at its default (mixed), then marked baked with the legacy custom property (as
    # scripts from before the UI do, e.g. bench/bench_spheres.py): same seed, same panoramas.
    sun = bpy.data.objects.new("SunLamp", bpy.data.lights.new("SunLamp", 'SUN'))
    sun.data.energy, sun.data.angle = 3.0, 0.0
    sun.rotation_euler = (math.radians(30.0), 0.0, math.radians(40.0))
    bpy.context.scene.collection.objects.link(sun)
    bpy.context.view_layer.update()
    travel = (sun.matrix_world.to_3x3() @ Vector((0.0, 0.0, -1.0))).normalized()
    common.emit(case="sun_info", to_sun_engine=scene_export.blender_to_engine([-travel])[0].tolist(),
                strength=3.0, panel=draw_light_panel_of(sun))
    bake(out, "sun_default")
    sun["schnee_light_mode"] = "baked"
    bake(out, "sun_baked")

    # Three small point lamps (mixed by default, 6 shadow-map layers each in the engine) beside the
    # baked Sun and KeyLamp: 18 of 16 layers, and the panel says so.
    for i in range(3):
        p = bpy.data.objects.new(f"Small{i}", bpy.data.lights.new(f"Small{i}", 'POINT'))
        p.data.shadow_soft_size = 0.05
        bpy.context.scene.collection.objects.link(p)
    from schnee_probes import light_modes
    common.emit(case="layers", need=light_modes.scene_shadow_layers(bpy.context.scene.objects),
                panel=draw_light_panel_of(bpy.data.objects["Small0"]))


def draw_light_panel_of(ob):
    for other in bpy.context.view_layer.objects:
        other.select_set(False)
    bpy.context.view_layer.objects.active = ob
    return draw_light_panel()


if __name__ == "__main__":
    main()
