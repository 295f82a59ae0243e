"""Shared by the *_ui.py scripts (run under Xvfb): one add-on panel pair drawn by Blender itself in a
real UI session, a Properties editor tab and the 3D viewport's sidebar, before and after a choice.

The panel module's draw function, which both panels call, is wrapped to record each call and any
exception (Blender prints a panel's exception and goes on, so the drawing itself must be watched).
The sidebar shows its first tab (Item) and a script cannot switch tabs in 3.4, so the sidebar panel
class is registered once more, top-level on the Item tab. Emits RESULT with the calls per editor;
quits Blender itself.
"""
import contextlib
import traceback

import bpy

import addon_common as common


def run(draw_name, settings, sidebar_panel, object_name, properties_tab, choice):
    """Register the add-on, wrap ``panel.<draw_name>`` and start the UI steps on a timer: make
    ``object_name`` active, one editor the Properties editor on ``properties_tab``, the sidebar
    shown; draw; set ``object_name.<settings>.mode = choice``; draw again; report. Each recorded
    call is [area type, object name, "ok" and the object's mode, or "error" and the traceback]."""
    import schnee_probes
    from schnee_probes import panel

    schnee_probes.register()
    calls = []
    draw = getattr(panel, draw_name)

    def recording_draw(layout, ob, context=None):
        area = getattr(getattr(context, "area", None), "type", None)
        try:
            draw(layout, ob, context)
        except Exception:
            calls.append([area, ob.name, "error", traceback.format_exc()])
            raise
        calls.append([area, ob.name, "ok", getattr(ob, settings).mode])

    setattr(panel, draw_name, recording_draw)

    class SidebarCopy(sidebar_panel):
        bl_idname = sidebar_panel.bl_idname + "_item_test"
        bl_category = "Item"
        bl_parent_id = ""

    steps = ["setup", "draw", "choose", "draw_again", "report"]

    def tick():
        step = steps.pop(0)
        win = bpy.context.window_manager.windows[0]
        if step == "setup":
            ob = bpy.data.objects[object_name]
            bpy.context.view_layer.objects.active = ob
            ob.select_set(True)
            areas = sorted(win.screen.areas, key=lambda a: -a.width * a.height)
            view3d = next(a for a in areas if a.type == 'VIEW_3D')
            # A second editor becomes the Properties editor on the panel's tab.
            props = next(a for a in areas if a is not view3d)
            props.type = 'PROPERTIES'
            props.spaces.active.context = properties_tab
            view3d.spaces.active.show_region_ui = True
            bpy.utils.register_class(SidebarCopy)  # so that Blender draws its draw() in the sidebar too
        elif step == "choose":
            getattr(bpy.data.objects[object_name], settings).mode = choice
        if step in ("setup", "choose"):
            for area in win.screen.areas:
                area.tag_redraw()
            return 1.0
        if step in ("draw", "draw_again"):
            override = getattr(bpy.context, "temp_override", None)
            with override(window=win) if override is not None else contextlib.nullcontext():
                bpy.ops.wm.redraw_timer(type='DRAW_WIN_SWAP', iterations=2)
            return 0.5
        common.emit(calls=calls)
        bpy.ops.wm.quit_blender()
        return None

    bpy.app.timers.register(tick, first_interval=1.0)
