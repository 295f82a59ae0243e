"""The object probe-mode panels drawn by Blender itself in a real UI session (run under Xvfb, issue 31
item 2): the startup file's cube active, a Properties editor on its Object tab
(OBJECT_PT_schnee_probes) and the 3D viewport's sidebar (VIEW3D_PT_schnee_object, registered once
more on the sidebar's first tab, Item, which a script cannot switch from in 3.4). ``-- OUT_DIR``.
Modelled on light_modes_ui.py.

panel.draw_object_probe_mode, which both panels call, is wrapped to record each call and any
exception (Blender prints a panel's exception and goes on, so the drawing itself must be watched).
Emits RESULT with the calls per editor; quits Blender itself.
"""
import os
import sys
import traceback

import bpy

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import addon_common as common  # noqa: E402

import schnee_probes  # noqa: E402
from schnee_probes import panel  # noqa: E402

schnee_probes.register()
calls = []
_draw = panel.draw_object_probe_mode


def recording_draw(layout, ob, context=None):
    area = getattr(getattr(context, "area", None), "type", None)
    try:
        _draw(layout, ob, context)
    except Exception:
        calls.append([area, ob.name, "error", traceback.format_exc()])
        raise
    calls.append([area, ob.name, "ok", ob.schnee_probe.mode])


panel.draw_object_probe_mode = recording_draw


class SidebarCopy(panel.VIEW3D_PT_schnee_object):
    bl_idname = "VIEW3D_PT_schnee_object_item_test"
    bl_category = "Item"
    bl_parent_id = ""
steps = ["setup", "draw", "choose", "draw_again", "report"]


def tick():
    step = steps.pop(0)
    win = bpy.context.window_manager.windows[0]
    if step == "setup":
        cube = bpy.data.objects["Cube"]
        bpy.context.view_layer.objects.active = cube
        cube.select_set(True)
        areas = sorted(win.screen.areas, key=lambda a: -a.width * a.height)
        view3d = next(a for a in areas if a.type == 'VIEW_3D')
        # A second editor becomes the Properties editor on the Object tab.
        props = next(a for a in areas if a is not view3d)
        props.type = 'PROPERTIES'
        props.spaces.active.context = 'OBJECT'
        view3d.spaces.active.show_region_ui = True
        # The sidebar shows its first tab (Item) and a script cannot switch tabs in 3.4: the same
        # panel class is registered once more, top-level on the Item tab, so that Blender draws
        # its draw() in the sidebar too.
        bpy.utils.register_class(SidebarCopy)
    elif step == "choose":
        bpy.data.objects["Cube"].schnee_probe.mode = 'PIXEL'
    if step in ("setup", "choose"):
        for area in win.screen.areas:
            area.tag_redraw()
        return 1.0
    if step in ("draw", "draw_again"):
        with bpy.context.temp_override(window=win) if hasattr(bpy.context, "temp_override") else _null():
            bpy.ops.wm.redraw_timer(type='DRAW_WIN_SWAP', iterations=2)
        return 0.5
    common.emit(calls=calls)
    bpy.ops.wm.quit_blender()
    return None


class _null:
    def __enter__(self):
        return self

    def __exit__(self, *exc):
        return False


bpy.app.timers.register(tick, first_interval=1.0)
