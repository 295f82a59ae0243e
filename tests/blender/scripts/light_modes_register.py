"""The light-mode property across register / unregister and a save and reload:
``blender -b --factory-startup -P light_modes_register.py -- WORK_DIR``.

Enables the add-on (addon_utils, as the preferences do), marks Sun "Chosen" baked through
Object.schnee_light.mode and Sun "Legacy" realtime through the legacy custom property, saves, then
records what each resolves to (light_modes.resolve) after: disabling the add-on, enabling it again,
and reopening the saved file. Emits one RESULT line.
"""
import os
import sys

import addon_utils
import bpy

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import addon_common as common  # noqa: E402

work = common.args()[0]
out = {}


def registered():
    return {"object_property": hasattr(bpy.types.Object, "schnee_light"),
            "data_panel": hasattr(bpy.types, "DATA_PT_schnee_light"),
            "sidebar_panel": hasattr(bpy.types, "VIEW3D_PT_schnee_light"),
            "operator": hasattr(bpy.ops.schnee, "set_light_mode") and "set_light_mode" in dir(bpy.ops.schnee)}


def modes():
    from schnee_probes import light_modes
    return {name: list(light_modes.resolve(bpy.data.objects[name])) for name in ("Chosen", "Legacy")}


for ob in list(bpy.data.objects):
    bpy.data.objects.remove(ob)
assert addon_utils.enable("schnee_probes", default_set=True) is not None
out["enabled"] = registered()
for name in ("Chosen", "Legacy"):
    ob = bpy.data.objects.new(name, bpy.data.lights.new(name, 'SUN'))
    bpy.context.scene.collection.objects.link(ob)
bpy.data.objects["Chosen"].schnee_light.mode = 'BAKED'
bpy.data.objects["Legacy"]["schnee_light_mode"] = "realtime"
out["set"] = modes()
path = os.path.join(work, "modes.blend")
bpy.ops.wm.save_as_mainfile(filepath=path)

addon_utils.disable("schnee_probes", default_set=True)
out["disabled"] = registered()
out["disabled_modes"] = modes()       # the module still reads the objects: the choice is invisible

assert addon_utils.enable("schnee_probes", default_set=True) is not None
out["enabled_again"] = registered()
out["enabled_again_modes"] = modes()  # the choice was kept on the object

bpy.ops.wm.open_mainfile(filepath=path)
out["reopened_modes"] = modes()
common.emit(**out)
