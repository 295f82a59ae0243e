"""Operators: Bake SH in Volumes (modal, one panorama per timer tick), Rebake Selected Volume (the
same bake of the active probe volume alone, keeping the other volumes' files: region.py) and Bake SH
at Cursor.

Both drive a :class:`bake_core.ProbeBake`. In a UI session Bake SH in Volumes runs modally (progress
bar, status bar text, Esc or Ctrl+C in the terminal cancels); without a window (``blender -b``)
modal operators cannot run, so the same operator bakes synchronously, printing a progress line.
A bake of more probes than the settings' Confirm Above asks first (:class:`SCHNEE_OT_confirm_large_bake`).
"""
import os
import signal
import time

import bpy

from .bake_core import (BakeCancelled, BakeError, BakeSettings, BakeTooLarge, CancelOnSignals, ProbeBake,
                        format_duration, kept_message)
from .properties import draw_estimate, draw_settings


def _record(props, result=None, message=""):
    if result is not None:
        props.last_probe_count = result.probe_count
        props.last_seconds = result.seconds
        props.last_files = ";".join(result.files)
    props.last_message = message


def _summary(result):
    names = ", ".join(os.path.basename(f) for f in result.files)
    if result.passes:
        return (f"Baked {result.probe_count} probes ({result.points} points rendered in "
                f"{len(result.passes)} pass{'' if len(result.passes) == 1 else 'es'}) in "
                f"{result.seconds:.1f} s -> {names}")
    return f"Baked {result.probe_count} probes in {result.seconds:.1f} s -> {names}"


class SCHNEE_OT_bake_sh_volumes(bpy.types.Operator):
    """Place probes in the probe volumes, render one Cycles panorama per probe and write the SH
    coefficients to a .shprobe file"""
    bl_idname = "schnee.bake_sh_volumes"
    bl_label = "Bake SH in Volumes"
    bl_options = {'REGISTER'}

    _timer = None
    _bake = None
    _signals = None
    _running = False  # class-wide: one bake at a time

    allow_large: bpy.props.BoolProperty(
        name="Allow Large", default=False, options={'HIDDEN', 'SKIP_SAVE'},
        description="Bake even above Confirm Above (set by the confirmation dialog)")
    only_volume: bpy.props.StringProperty(
        name="Only Volume", default="", options={'HIDDEN', 'SKIP_SAVE'},
        description="Bake this probe volume alone and keep the other volumes' files (Rebake Selected Volume)")

    @classmethod
    def poll(cls, context):
        return context.scene is not None and not SCHNEE_OT_bake_sh_volumes._running

    def invoke(self, context, event):
        return context.window_manager.invoke_props_dialog(self, width=380)

    def draw(self, context):
        props = context.scene.schnee_probes
        draw_settings(self.layout, props)
        draw_estimate(self.layout, context.scene, props)

    def execute(self, context):
        props = context.scene.schnee_probes
        bake = ProbeBake(context.scene, context.view_layer, BakeSettings.from_props(props),
                         allow_large=self.allow_large, only_volume=self.only_volume or None)
        if context.window is None or bpy.app.background:
            return self._run_blocking(bake, props)
        try:
            bake.prepare()
        except BakeTooLarge as exc:
            # Nothing is changed yet (placement only): ask, and bake again if confirmed.
            bake.cancel()
            _record(props, message=str(exc))
            self.report({'WARNING'}, str(exc))
            bpy.ops.schnee.confirm_large_bake('INVOKE_DEFAULT', probes=exc.probes,
                                              estimate=format_duration(exc.seconds), limit=exc.limit,
                                              only_volume=self.only_volume)
            return {'CANCELLED'}
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
        # Ctrl+C in the terminal cancels like Esc (instead of Python's KeyboardInterrupt).
        self._signals = CancelOnSignals(bake, (signal.SIGINT,))
        self._signals.__enter__()
        wm = context.window_manager
        wm.progress_begin(0, 1000)  # per mille of bake.fraction(): Adaptive's total grows pass by pass
        self._timer = wm.event_timer_add(0.01, window=context.window)
        wm.modal_handler_add(self)
        if bake.adaptive:
            msg = (f"Baking pass 1: {bake.total} probes, estimated {format_duration(bake.estimated_seconds)}; "
                   "finer passes follow where the light needs them (Esc cancels)")
        else:
            msg = f"Baking {bake.total} probes, estimated {format_duration(bake.estimated_seconds)} (Esc cancels)"
        self.report({'INFO'}, msg)
        if context.workspace is not None:
            context.workspace.status_text_set(msg)
        return {'RUNNING_MODAL'}

    def _run_blocking(self, bake, props):
        def progress(b):
            print("\r" + b.progress_line(), end="", flush=True)
        try:
            result = bake.run(progress)
        except (BakeError, OSError) as exc:
            print()
            if kept_message(bake):
                exc = f"{exc}; {kept_message(bake)}"
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
        if event.type == 'ESC' or bake.cancel_requested:
            return self._end(context, cancelled=True)
        if event.type != 'TIMER':
            return {'PASS_THROUGH'}
        try:
            more = bake.step()
        except BakeCancelled:
            return self._end(context, cancelled=True)
        except BaseException as exc:  # restore the scene whatever went wrong, then report
            return self._end(context, error=exc)
        context.window_manager.progress_update(int(1000 * bake.fraction()))
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
        if self._signals is not None:
            self._signals.__exit__(None, None, None)
            self._signals = None
        SCHNEE_OT_bake_sh_volumes._running = False
        print()
        props = context.scene.schnee_probes
        bake, self._bake = self._bake, None
        if bake is None:
            return {'CANCELLED'}
        if cancelled or error is not None:
            bake.cancel()
            msg = "Bake cancelled; existing files are unchanged" if cancelled else f"Bake failed: {error}"
            if kept_message(bake):
                msg += "; " + kept_message(bake)
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


class SCHNEE_OT_confirm_large_bake(bpy.types.Operator):
    """Confirm a bake of more probes than Confirm Above"""
    bl_idname = "schnee.confirm_large_bake"
    bl_label = "Bake Many Probes?"
    bl_options = {'INTERNAL'}

    probes: bpy.props.IntProperty(name="Probes", options={'SKIP_SAVE'})
    estimate: bpy.props.StringProperty(name="Estimate", options={'SKIP_SAVE'})
    limit: bpy.props.IntProperty(name="Limit", options={'SKIP_SAVE'})
    only_volume: bpy.props.StringProperty(name="Only Volume", options={'HIDDEN', 'SKIP_SAVE'})

    def invoke(self, context, event):
        return context.window_manager.invoke_props_dialog(self, width=420)

    def draw(self, context):
        col = self.layout.column(align=True)
        col.label(text=f"{self.probes} probes, estimated {self.estimate} (upper estimate)", icon='ERROR')
        col.label(text=f"That is more than Confirm Above ({self.limit} probes).")
        col.label(text="OK bakes them all; click outside to leave everything as it is.")

    def execute(self, context):
        bpy.ops.schnee.bake_sh_volumes('EXEC_DEFAULT', allow_large=True, only_volume=self.only_volume)
        return {'FINISHED'}


class SCHNEE_OT_rebake_selected_volume(bpy.types.Operator):
    """Bake the active probe volume again after an edit: only its own .shprobe is rewritten; every
    other volume's file, the sky and the sun stay as the previous bake left them (needs One File
    per Volume and a previous bake with the same settings)"""
    bl_idname = "schnee.rebake_selected_volume"
    bl_label = "Rebake Selected Volume"
    bl_options = {'REGISTER'}

    @classmethod
    def poll(cls, context):
        ob, scene = context.active_object, context.scene
        if ob is None or scene is None or SCHNEE_OT_bake_sh_volumes._running:
            return False
        coll = bpy.data.collections.get(scene.schnee_probes.volume_collection)
        return coll is not None and ob.name in coll.all_objects

    def execute(self, context):
        return bpy.ops.schnee.bake_sh_volumes('EXEC_DEFAULT', only_volume=context.active_object.name)


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


classes = (SCHNEE_OT_bake_sh_volumes, SCHNEE_OT_confirm_large_bake, SCHNEE_OT_rebake_selected_volume,
           SCHNEE_OT_bake_sh_cursor)

register, unregister = bpy.utils.register_classes_factory(classes)
