"""The modal Bake SH in Volumes in a real UI session (run under Xvfb with --enable-event-simulate):
a bake that finishes, then a bake cancelled with a simulated Esc, one cancelled by SIGINT (Ctrl+C
in the terminal), and one above Confirm Above (refused until confirmed). ``-- OUT_DIR``.
Emits RESULT with what happened; quits Blender itself."""
import os
import signal
import sys

import bpy

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import addon_common as common  # noqa: E402
from addon_common import scene_lib as lib  # noqa: E402

import schnee_probes  # noqa: E402
from schnee_probes import operators  # noqa: E402

# Ctrl+C's handler when Blender started (the bake installs its own and must put this one back).
SIGINT_BEFORE = signal.getsignal(signal.SIGINT)
out = common.args()[0]
lib.clear_scene()
lib.hdri_world("courtyard.exr")
# SCHNEE_MODAL_PLACEMENT=ADAPTIVE: the Adaptive placement in a 4 x 2 x 2 m volume (12 corner probes
# of 2 m cells, then its test points: long enough to cancel in between); default the geometry octree
# in a 3 x 2 x 2 m volume (12 probes of 1 m). Both stay above Confirm Above = 10, and each finished
# bake renders 12 panoramas (32 and 18 before).
placement = os.environ.get("SCHNEE_MODAL_PLACEMENT", "OCTREE")
lib.probe_volume("SkyVolume", (-2.0, -1.0, 0.0), (2.0, 1.0, 2.0)) if placement == "ADAPTIVE" else \
    lib.probe_volume("SkyVolume", (-1.5, -1.0, 0.0), (1.5, 1.0, 2.0))
lib.save(os.path.join(out, "modal.blend"))
schnee_probes.register()
props = bpy.context.scene.schnee_probes
props.placement = placement
props.min_cell_size = props.max_cell_size = 1.0
if props.placement == "ADAPTIVE":
    props.max_cell_size = 2.0
props.panorama_resolution = 16
props.samples = 1
shprobe = os.path.join(out, "sh_coeffs", "probes.shprobe")
results = {}
phase = ["start"]
Op = operators.SCHNEE_OT_bake_sh_volumes


def override():
    win = bpy.context.window_manager.windows[0]
    area = next(a for a in win.screen.areas if a.type == 'VIEW_3D') if any(
        a.type == 'VIEW_3D' for a in win.screen.areas) else win.screen.areas[0]
    return win, dict(window=win, screen=win.screen, area=area)


def tick():
    win, ctx = override()
    if phase[0] == "start":
        with bpy.context.temp_override(**ctx):
            results["start"] = sorted(bpy.ops.schnee.bake_sh_volumes('EXEC_DEFAULT'))
        results["running_after_start"] = Op._running
        phase[0] = "wait1"
    elif phase[0] == "wait1":
        if not Op._running:
            results["finished_message"] = props.last_message
            results["file"] = os.path.exists(shprobe)
            results["mtime"] = os.path.getmtime(shprobe) if results["file"] else None
            results["engine_after"] = bpy.context.scene.render.engine
            with bpy.context.temp_override(**ctx):
                bpy.ops.schnee.bake_sh_volumes('EXEC_DEFAULT')
            phase[0] = "esc"
    elif phase[0] == "esc":
        win.event_simulate(type='ESC', value='PRESS')
        phase[0] = "wait2"
    elif phase[0] == "wait2":
        if not Op._running:
            results["cancel_message"] = props.last_message
            results["file_unchanged"] = os.path.getmtime(shprobe) == results["mtime"]
            results["engine_after_cancel"] = bpy.context.scene.render.engine
            with bpy.context.temp_override(**ctx):
                bpy.ops.schnee.bake_sh_volumes('EXEC_DEFAULT')
            results["sigint_handler_during_bake"] = signal.getsignal(signal.SIGINT) is not None and \
                signal.getsignal(signal.SIGINT) is not SIGINT_BEFORE
            phase[0] = "sigint"
    elif phase[0] == "sigint":
        os.kill(os.getpid(), signal.SIGINT)  # what Ctrl+C in the terminal sends
        phase[0] = "wait3"
    elif phase[0] == "wait3":
        if not Op._running:
            results["sigint_message"] = props.last_message
            results["sigint_file_unchanged"] = os.path.getmtime(shprobe) == results["mtime"]
            results["engine_after_sigint"] = bpy.context.scene.render.engine
            # The handler Blender started with is back: Python's default_int_handler from a terminal,
            # SIG_IGN when started in the background by a shell without job control (nohup cmd &).
            results["sigint_handler_after"] = signal.getsignal(signal.SIGINT) is SIGINT_BEFORE
            # Above Confirm Above: refused (a confirmation dialog opens), nothing changes.
            props.probe_limit = 10
            with bpy.context.temp_override(**ctx):
                results["large_result"] = sorted(bpy.ops.schnee.bake_sh_volumes('EXEC_DEFAULT'))
            results["large_running"] = Op._running
            results["large_message"] = props.last_message
            results["large_file_unchanged"] = os.path.getmtime(shprobe) == results["mtime"]
            # What the dialog's OK runs: the bake with allow_large.
            with bpy.context.temp_override(**ctx):
                results["confirmed_result"] = sorted(bpy.ops.schnee.bake_sh_volumes('EXEC_DEFAULT', allow_large=True))
            phase[0] = "wait4"
    elif phase[0] == "wait4":
        if not Op._running:
            results["confirmed_message"] = props.last_message
            common.emit(**results)
            bpy.ops.wm.quit_blender()
            return None
    return 0.05


bpy.context.scene.render.engine = 'BLENDER_EEVEE'
bpy.app.timers.register(tick, first_interval=1.0)
