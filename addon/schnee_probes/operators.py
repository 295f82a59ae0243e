"""Operators: Bake SH in Volumes (modal, one panorama per timer tick), Rebake Selected Volume (the
same bake of the active probe volume alone, keeping the other volumes' files: region.py), Rebake
Selected Region (the probes inside the active object's box, in the one volume that box meets) and
Bake SH at Cursor.

Both drive a :class:`bake_core.ProbeBake`. In a UI session Bake SH in Volumes runs modally (progress
bar, status bar text, Esc or Ctrl+C in the terminal cancels); without a window (``blender -b``)
modal operators cannot run, so the same operator bakes synchronously, printing a progress line.
A bake of more probes than the settings' Confirm Above asks first (:class:`SCHNEE_OT_confirm_large_bake`).
"""
import os
import signal
import time

import bpy
import numpy as np
from mathutils import Vector

from .bake_core import (BakeCancelled, BakeError, BakeSettings, BakeTooLarge, CancelOnSignals, ProbeBake,
                        format_duration, kept_message)
from .bake_plans import volume_objects
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
    # A FloatVectorProperty cannot be None: use_region says whether region is given.
    use_region: bpy.props.BoolProperty(
        name="Use Region", default=False, options={'HIDDEN', 'SKIP_SAVE'},
        description="Bake only the probes of Only Volume inside Region (Rebake Selected Region)")
    region: bpy.props.FloatVectorProperty(
        name="Region", size=6, default=(0.0,) * 6, options={'HIDDEN', 'SKIP_SAVE'},
        description="Two opposite corners of a box, Blender coordinates (x0, y0, z0, x1, y1, z1)")

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
        if self.use_region and not self.only_volume:
            self.report({'ERROR'}, "A region rebake needs the volume it lies in (Only Volume)")
            return {'CANCELLED'}
        bake = ProbeBake(context.scene, context.view_layer, BakeSettings.from_props(props),
                         allow_large=self.allow_large, only_volume=self.only_volume or None,
                         region=tuple(self.region) if self.use_region else None)
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
                                              only_volume=self.only_volume, use_region=self.use_region,
                                              region=self.region)
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
    use_region: bpy.props.BoolProperty(name="Use Region", options={'HIDDEN', 'SKIP_SAVE'})
    region: bpy.props.FloatVectorProperty(name="Region", size=6, options={'HIDDEN', 'SKIP_SAVE'})

    def invoke(self, context, event):
        return context.window_manager.invoke_props_dialog(self, width=420)

    def draw(self, context):
        col = self.layout.column(align=True)
        col.label(text=f"{self.probes} probes, estimated {self.estimate} (upper estimate)", icon='ERROR')
        col.label(text=f"That is more than Confirm Above ({self.limit} probes).")
        col.label(text="OK bakes them all; click outside to leave everything as it is.")

    def execute(self, context):
        return _bake_volume(self, allow_large=True, only_volume=self.only_volume, use_region=self.use_region,
                            region=self.region)


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
        return _bake_volume(self, only_volume=context.active_object.name)


def _bake_volume(op, **options):
    """Bake SH in Volumes with ``options`` on behalf of ``op``. A refusal reaches ``op``'s caller as its
    own report (bpy.ops turns the inner operator's ERROR report into a RuntimeError, which would end
    ``op`` with a Python traceback); a bake running on (modal) or done is FINISHED for ``op``."""
    try:
        result = bpy.ops.schnee.bake_sh_volumes('EXEC_DEFAULT', **options)
    except RuntimeError as exc:
        op.report({'ERROR'}, str(exc).removeprefix("Error: ").strip())
        return {'CANCELLED'}
    return {'FINISHED'} if result & {'FINISHED', 'RUNNING_MODAL'} else {'CANCELLED'}


# Object types whose bound_box is the box of their geometry (an Empty's is all zeros: its Cube display
# is taken from empty_display_size instead).
BOX_TYPES = frozenset({'MESH', 'CURVE', 'SURFACE', 'META', 'FONT', 'LATTICE'})
# Boxes that only touch (an overlap this thin, metres) do not meet: a box drawn up to a wall shared
# by two volumes belongs to the volume it is in.
TOUCH = 1e-6


def world_box(ob, depsgraph):
    """The world-space axis-aligned box of object ``ob`` as evaluated (its 8 bound_box corners through
    matrix_world), Blender coordinates: (lo, hi) as numpy arrays; None for an object without a box."""
    ev = ob.evaluated_get(depsgraph)
    if ob.type == 'EMPTY' and ob.empty_display_type == 'CUBE':
        r = ob.empty_display_size
        corners = [(x, y, z) for x in (-r, r) for y in (-r, r) for z in (-r, r)]
    elif ob.type in BOX_TYPES:
        corners = [tuple(c) for c in ev.bound_box]
    else:
        return None
    pts = np.array([tuple(ev.matrix_world @ Vector(c)) for c in corners], dtype=np.float64)
    return pts.min(axis=0), pts.max(axis=0)


def boxes_meet(a, b) -> bool:
    """Whether boxes ``a`` and ``b`` ((lo, hi)) share more than a face: they overlap by more than
    TOUCH along every axis where both have an extent (a flat box meets what it lies in)."""
    overlap = np.minimum(a[1], b[1]) - np.maximum(a[0], b[0])
    thin = np.minimum(a[1] - a[0], b[1] - b[0]) <= TOUCH
    return bool(np.all(np.where(thin, overlap >= -TOUCH, overlap > TOUCH)))


def _names(names):
    quoted = [f"'{n}'" for n in names]
    return quoted[0] if len(quoted) == 1 else ", ".join(quoted[:-1]) + " and " + quoted[-1]


def _coords(v):
    return "(" + ", ".join(f"{x:g}" for x in v) + ")"


class SCHNEE_OT_rebake_selected_region(bpy.types.Operator):
    """Bake again only the probes inside the active object's bounding box (world axes), in the one
    probe volume that box meets: the volume's probes outside the box keep the previous bake's values,
    only that volume's .shprobe is rewritten, every other file stays as it was. Needs One File per
    Volume and a previous bake with the same settings. The active object: a mesh (or curve, text,
    Cube empty...) that is not a probe volume"""
    bl_idname = "schnee.rebake_selected_region"
    bl_label = "Rebake Selected Region"
    bl_options = {'REGISTER'}

    @classmethod
    def poll(cls, context):
        ob, scene = context.active_object, context.scene
        why = None
        if scene is None or SCHNEE_OT_bake_sh_volumes._running:
            why = "A bake is running"
        elif ob is None:
            why = "Select an object whose box holds the probes to rebake (a mesh or a Cube empty)"
        elif not (ob.type in BOX_TYPES or (ob.type == 'EMPTY' and ob.empty_display_type == 'CUBE')):
            why = f"The active object '{ob.name}' has no box: select a mesh (or curve, text, Cube empty)"
        else:
            coll = bpy.data.collections.get(scene.schnee_probes.volume_collection)
            if coll is not None and ob.name in coll.all_objects:
                why = f"'{ob.name}' is a probe volume: Rebake Selected Volume rebakes it whole"
        if why is not None:
            cls.poll_message_set(why)
        return why is None

    def execute(self, context):
        ob, props = context.active_object, context.scene.schnee_probes
        depsgraph = context.evaluated_depsgraph_get()
        box = world_box(ob, depsgraph)
        try:
            volumes = volume_objects(props.volume_collection)
        except BakeError as exc:
            return self._refuse(props, str(exc))
        met = [v.name for v in volumes if boxes_meet(box, world_box(v, depsgraph))]
        if not met:
            return self._refuse(props, f"The box of '{ob.name}' meets no probe volume of collection "
                                f"'{props.volume_collection}' (its volumes: {_names([v.name for v in volumes])}): "
                                "move or scale it so that it lies in the volume to rebake")
        if len(met) > 1:
            return self._refuse(props, f"The box of '{ob.name}' meets volumes {_names(met)}: a region rebake "
                                "works in one volume; make the box smaller or rebake each volume")
        self.report({'INFO'}, f"Rebaking the probes of volume '{met[0]}' inside the box of '{ob.name}': "
                    f"{_coords(box[0])} .. {_coords(box[1])} (Blender coordinates)")
        return _bake_volume(self, only_volume=met[0], use_region=True,
                            region=tuple(float(x) for x in (*box[0], *box[1])))

    def _refuse(self, props, msg):
        _record(props, message=msg)
        self.report({'ERROR'}, msg)
        return {'CANCELLED'}


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
           SCHNEE_OT_rebake_selected_region, SCHNEE_OT_bake_sh_cursor)

register, unregister = bpy.utils.register_classes_factory(classes)
