"""The probe overlay in the 3D Viewport (docs/overlay.md): its settings (``Scene.schnee_overlay``),
its panel under Sidebar > Schnee Engine > SH Probes, and the draw handler.

The handler is registered with the add-on and returns at once while the overlay is off. When on, it
draws every ``.shprobe`` the scene's bakes wrote (overlay_data.scene_files), each read once and again
only after its mtime or size changes. A file is parsed on a native thread that runs no Python
(:func:`probe_set`; Blender 3.4 crashes when a Python thread runs while it draws) and turned into
the overlay's arrays in short steps of a timer, so a large file never stalls the UI: the viewport
draws the other files meanwhile and is redrawn when the read is done. A file that cannot be drawn is listed
in the panel with the reason, and a drawing error is kept for the panel instead of raising in
Blender's draw loop.
"""
import os
import time

import bpy
from bpy.props import BoolProperty, EnumProperty, FloatProperty, PointerProperty

from . import overlay_data
from .panel import SidebarSubpanel

COLOUR_MODES = (
    ("IRRADIANCE", "Irradiance", "Each sphere shaded per pixel with its probe's SH irradiance E(n)/π times "
                                 "its scale (the engine's movable-diffuse shading of a white surface)"),
    ("VALIDITY", "Validity", "Red (0, the probe sees mostly back faces) through yellow to green (1); "
                             "files without validity (version 1) are all green"),
    ("NOISE", "Noise", "Each probe's Monte-Carlo noise σ relative to the bake's Error Tolerance: green 0, yellow "
                       "half the tolerance (the bake's target for a probe), red the tolerance or more; grey: not "
                       "measured. Needs the file's bake-info sidecar (Adaptive bakes)"),
    ("REFINEMENT", "Refinement", "Per octree leaf (a sphere at its centre and its lines): why it is a leaf and its "
                                 "worst test error / threshold. Needs the file's bake-info sidecar (Adaptive bakes)"),
    ("WHITE", "White", "Plain white spheres (positions only)"),
)
# The panel's legends of the modes Noise and Refinement (overlay_data.noise_colours, refinement_colours).
LEGENDS = {
    "NOISE": ("Green: σ 0, yellow: ½ Error Tolerance (the bake's target),",
              "red: σ ≥ Error Tolerance, grey: not measured"),
    "REFINEMENT": ("Green → yellow: passed, error / threshold 0 → 1",
                   "Magenta: noise-limited (error > tolerance, within the noise)",
                   "Red: at Min Cell Size, parent's error here > threshold",
                   "Orange: at Min Cell Size, parent's error here within it",
                   "Blue: never tested (predicted to pass), grey: not compared"),
}

_state = {"handler": None, "error": None}
_loading = {}   # path -> its overlay_data.Reader
STEP_SECONDS = 0.02   # main-thread time per timer tick spent turning read files into ProbeSets


def probe_set(path):
    """The file's :class:`overlay_data.ProbeSet` when it is read and current; else None, with a
    read started (once per path: the file parsed on a native thread) and a timer that finishes it in
    short steps on the main thread and redraws the viewports when it is done."""
    ps = overlay_data.cached(path)
    if ps is not None:
        return ps
    if path not in _loading:
        _loading[path] = overlay_data.Reader(path)
        if not bpy.app.timers.is_registered(_poll_reads):
            bpy.app.timers.register(_poll_reads, first_interval=0.05)
    return None


def wait_for_reads(timeout=60.0):
    """Block until the reads started by :func:`probe_set` end (tests, scripts)."""
    end = time.monotonic() + timeout
    while _loading and time.monotonic() < end:
        _step_reads(time.perf_counter() + 1.0)
        if _loading:
            time.sleep(0.005)
    _redraw()


def _step_reads(deadline):
    done = [p for p, reader in list(_loading.items()) if reader.step(deadline)]
    for p in done:
        del _loading[p]
    return bool(done)


def _poll_reads():
    if _step_reads(time.perf_counter() + STEP_SECONDS):
        _redraw()
    return 0.05 if _loading else None


def _redraw(_self=None, context=None):
    for window in getattr(bpy.context.window_manager, "windows", ()):
        for area in window.screen.areas:
            if area.type == 'VIEW_3D':
                area.tag_redraw()


# Built with type() as properties.SchneeProbeSettings is (bpy.props calls as annotations read as
# forward references to pyflakes).
SchneeOverlaySettings = type("SchneeOverlaySettings", (bpy.types.PropertyGroup,), {
    "__doc__": "What the probe overlay shows (Scene.schnee_overlay).",
    "__module__": __name__,
    "__annotations__": dict(
        show=BoolProperty(name="Show Probes in Viewport", default=False, update=_redraw, options=set(),
                          description="Draw the baked probes (.shprobe files of this scene's bakes) in the "
                                      "3D Viewport"),
        show_probes=BoolProperty(name="Spheres", default=True, update=_redraw, options=set(),
                                 description="A sphere per probe"),
        show_cells=BoolProperty(name="Cells", default=True, update=_redraw, options=set(),
                                description="The interpolation cells (grid cells, octree leaves coloured by "
                                            "level, tetrahedra) as lines"),
        colour_mode=EnumProperty(name="Colour", items=COLOUR_MODES, default="IRRADIANCE", update=_redraw,
                                 options=set()),
        sphere_size=FloatProperty(name="Sphere Radius", default=0.08, min=0.001, soft_max=1.0, unit='LENGTH',
                                  update=_redraw, options=set(), description="Radius of a probe's sphere"),
        exposure=FloatProperty(name="Exposure", default=0.0, soft_min=-10.0, soft_max=10.0, update=_redraw,
                               options=set(),
                               description="Exposure in stops: the irradiance colour times 2^exposure"),
        cell_alpha=FloatProperty(name="Cell Opacity", default=0.5, min=0.0, max=1.0, subtype='FACTOR',
                                 update=_redraw, options=set()),
    ),
})


def draw_viewport():
    """SpaceView3D POST_VIEW handler."""
    scene = bpy.context.scene
    ov = getattr(scene, "schnee_overlay", None)
    if ov is None or not ov.show:
        return
    region_data = bpy.context.region_data
    if region_data is None:
        return
    try:
        from . import overlay_gpu
        vp = region_data.perspective_matrix
        for path in overlay_data.scene_files(scene.schnee_probes):
            ps = probe_set(path)
            if ps is None:   # being read
                continue
            overlay_gpu.draw(ps, vp, radius=ov.sphere_size, exposure=ov.exposure, mode=ov.colour_mode,
                             show_probes=ov.show_probes, show_cells=ov.show_cells, cell_alpha=ov.cell_alpha)
        _state["error"] = None
    except Exception as exc:  # never raise in Blender's draw loop: the panel shows it
        _state["error"] = f"{type(exc).__name__}: {exc}"


class SCHNEE_OT_overlay_reload(bpy.types.Operator):
    """Read the scene's .shprobe files again (the overlay also does when a file changes)"""
    bl_idname = "schnee.overlay_reload"
    bl_label = "Reload Probe Files"

    def execute(self, context):
        overlay_data.clear_cache()
        try:
            from . import overlay_gpu
            overlay_gpu.free_resources()
        except ImportError:
            pass
        _redraw()
        return {'FINISHED'}


class VIEW3D_PT_schnee_overlay(SidebarSubpanel, bpy.types.Panel):
    bl_label = "Probe Overlay"
    bl_idname = "VIEW3D_PT_schnee_overlay"

    def draw_header(self, context):
        self.layout.prop(context.scene.schnee_overlay, "show", text="")

    def draw(self, context):
        draw_overlay_panel(self.layout, context.scene)


def draw_overlay_panel(layout, scene):
    """The overlay's settings and, per file, what was read (or why it cannot be drawn)."""
    ov = scene.schnee_overlay
    col = layout.column()
    col.active = ov.show
    row = col.row(align=True)
    row.prop(ov, "show_probes", toggle=True)
    row.prop(ov, "show_cells", toggle=True)
    col.prop(ov, "colour_mode")
    for line in LEGENDS.get(ov.colour_mode, ()):
        col.label(text=line)
    col.prop(ov, "sphere_size")
    col.prop(ov, "exposure")
    col.prop(ov, "cell_alpha")
    files = overlay_data.scene_files(scene.schnee_probes)
    if not files:
        col.label(text="No baked files (save the .blend or bake first)", icon='INFO')
    for path in files:
        ps = probe_set(path) if ov.show else None
        box = col.box()
        box.label(text=os.path.basename(path), icon='FILE')
        if ps is None:
            if path in _loading:
                box.label(text="Reading…", icon='SORTTIME')
            continue
        if ps.error:
            box.label(text=ps.error, icon='ERROR')
            continue
        box.label(text=f"v{ps.version} {ps.structure}, {ps.probe_count} probes, {ps.cell_count} cells")
        box.label(text="Validity stored" if ps.has_validity else "No validity in the file (all 1)")
        box.label(text=ps.info_line(), icon='ERROR' if ps.info is not None and ps.info.error else 'NONE')
        if ps.cells_left_out:
            box.label(text=f"{ps.cells_left_out} cells not drawn (over {overlay_data.MAX_CELLS})", icon='INFO')
    if _state["error"]:
        col.label(text=_state["error"], icon='ERROR')
    col.operator(SCHNEE_OT_overlay_reload.bl_idname, icon='FILE_REFRESH')


classes = (SchneeOverlaySettings, SCHNEE_OT_overlay_reload, VIEW3D_PT_schnee_overlay)


def register():
    for cls in classes:
        bpy.utils.register_class(cls)
    bpy.types.Scene.schnee_overlay = PointerProperty(type=SchneeOverlaySettings, name="Schnee Probe Overlay")
    if _state["handler"] is None:
        _state["handler"] = bpy.types.SpaceView3D.draw_handler_add(draw_viewport, (), 'WINDOW', 'POST_VIEW')


def unregister():
    if _state["handler"] is not None:
        bpy.types.SpaceView3D.draw_handler_remove(_state["handler"], 'WINDOW')
        _state["handler"] = None
    overlay_data.clear_cache()
    if not bpy.app.background:
        try:
            from . import overlay_gpu
            overlay_gpu.free_resources()
        except (ImportError, SystemError):
            pass
    del bpy.types.Scene.schnee_overlay
    for cls in reversed(classes):
        bpy.utils.unregister_class(cls)
