"""Operators: Bake SH in Volumes (modal, one panorama per timer tick) and Bake SH at Cursor.

Both drive a :class:`bake_core.ProbeBake`. In a UI session Bake SH in Volumes runs modally (progress
bar, status bar text, Esc cancels); without a window (``blender -b``) modal operators cannot run, so
the same operator bakes synchronously, printing a progress line.
"""
import os
import time

import bpy

from .bake_core import BakeError, BakeSettings, ProbeBake
from .properties import draw_settings


def _record(props, result=None, message=""):
    if result is not None:
        props.last_probe_count = result.probe_count
        props.last_seconds = result.seconds
        props.last_files = ";".join(result.files)
    props.last_message = message


def _summary(result):
    names = ", ".join(os.path.basename(f) for f in result.files)
    return f"Baked {result.probe_count} probes in {result.seconds:.1f} s -> {names}"


class SCHNEE_OT_bake_sh_volumes(bpy.types.Operator):
    """Place probes in the probe volumes, render one Cycles panorama per probe and write the SH
    coefficients to a .shprobe file"""
    bl_idname = "schnee.bake_sh_volumes"
    bl_label = "Bake SH in Volumes"
    bl_options = {'REGISTER'}

    _timer = None
    _bake = None
    _running = False  # class-wide: one bake at a time

    @classmethod
    def poll(cls, context):
        return context.scene is not None and not SCHNEE_OT_bake_sh_volumes._running

    def invoke(self, context, event):
        return context.window_manager.invoke_props_dialog(self, width=380)

    def draw(self, context):
        draw_settings(self.layout, context.scene.schnee_probes)

    def execute(self, context):
        props = context.scene.schnee_probes
        bake = ProbeBake(context.scene, context.view_layer, BakeSettings.from_props(props))
        if context.window is None or bpy.app.background:
            return self._run_blocking(bake, props)
        try:
            bake.prepare()
        except (BakeError, OSError) as exc:
            bake.cancel()
            _record(props, message=str(exc))
            self.report({'ERROR'}, str(exc))
            return {'CANCELLED'}
        except BaseException:
            bake.cancel()
            raise
        self._bake = bake
        SCHNEE_OT_bake_sh_volumes._running = True
        wm = context.window_manager
        wm.progress_begin(0, bake.total)
        self._timer = wm.event_timer_add(0.01, window=context.window)
        wm.modal_handler_add(self)
        print(f"Schnee: baking {bake.total} probes (Esc cancels)")
        return {'RUNNING_MODAL'}

    def _run_blocking(self, bake, props):
        def progress(b):
            print("\r" + b.progress_line(), end="", flush=True)
        try:
            result = bake.run(progress)
        except (BakeError, OSError) as exc:
            print()
            _record(props, message=str(exc))
            self.report({'ERROR'}, str(exc))
            return {'CANCELLED'}
        print()
        _record(props, result, _summary(result))
        for msg in result.messages:
            self.report({'INFO'}, msg)
        self.report({'INFO'}, _summary(result))
        return {'FINISHED'}

    def modal(self, context, event):
        bake = self._bake
        if event.type == 'ESC':
            return self._end(context, cancelled=True)
        if event.type != 'TIMER':
            return {'PASS_THROUGH'}
        try:
            more = bake.step()
        except BaseException as exc:  # restore the scene whatever went wrong, then report
            return self._end(context, error=exc)
        context.window_manager.progress_update(bake.done)
        line = bake.progress_line()
        context.workspace.status_text_set(line + "  (Esc cancels)")
        print("\r" + line, end="", flush=True)
        if more:
            return {'RUNNING_MODAL'}
        return self._end(context)

    def cancel(self, context):
        # Blender calls this when the operator is stopped from outside (e.g. file reload).
        self._end(context, cancelled=True)

    def _end(self, context, cancelled=False, error=None):
        wm = context.window_manager
        if self._timer is not None:
            wm.event_timer_remove(self._timer)
            self._timer = None
        wm.progress_end()
        if context.workspace is not None:
            context.workspace.status_text_set(None)
        SCHNEE_OT_bake_sh_volumes._running = False
        print()
        props = context.scene.schnee_probes
        bake, self._bake = self._bake, None
        if bake is None:
            return {'CANCELLED'}
        if cancelled or error is not None:
            bake.cancel()
            msg = "Bake cancelled; existing files are unchanged" if cancelled else f"Bake failed: {error}"
            _record(props, message=msg)
            self.report({'WARNING'} if cancelled else {'ERROR'}, msg)
            return {'CANCELLED'}
        try:
            result = bake.finish()
        except BaseException as exc:
            msg = f"Bake failed: {exc}"
            _record(props, message=msg)
            self.report({'ERROR'}, msg)
            return {'CANCELLED'}
        _record(props, result, _summary(result))
        for msg in result.messages:
            self.report({'INFO'}, msg)
        self.report({'INFO'}, _summary(result))
        return {'FINISHED'}


class SCHNEE_OT_bake_sh_cursor(bpy.types.Operator):
    """Bake one probe at the 3D cursor: debug_probe.txt (coefficients and irradiance along the axes)
    and a single-probe .shprobe"""
    bl_idname = "schnee.bake_sh_cursor"
    bl_label = "Bake SH at Cursor"
    bl_options = {'REGISTER'}

    @classmethod
    def poll(cls, context):
        return context.scene is not None and not SCHNEE_OT_bake_sh_volumes._running

    def execute(self, context):
        props = context.scene.schnee_probes
        t0 = time.perf_counter()
        bake = ProbeBake(context.scene, context.view_layer, BakeSettings.from_props(props),
                         mode="CURSOR", cursor=tuple(context.scene.cursor.location))
        try:
            result = bake.run()
        except (BakeError, OSError) as exc:
            _record(props, message=str(exc))
            self.report({'ERROR'}, str(exc))
            return {'CANCELLED'}
        _record(props, result, f"Cursor probe baked in {time.perf_counter() - t0:.1f} s -> "
                + ", ".join(os.path.basename(f) for f in result.files))
        for msg in result.messages:
            self.report({'INFO'}, msg)
        self.report({'INFO'}, props.last_message)
        return {'FINISHED'}


classes = (SCHNEE_OT_bake_sh_volumes, SCHNEE_OT_bake_sh_cursor)

register, unregister = bpy.utils.register_classes_factory(classes)
