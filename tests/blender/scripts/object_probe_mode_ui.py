"""The object probe-mode panels drawn by Blender itself in a real UI session (run under Xvfb, issue 31
item 2): the startup file's cube active, a Properties editor on its Object tab
(OBJECT_PT_schnee_probes) and the 3D viewport's sidebar (VIEW3D_PT_schnee_object, registered once
more on the sidebar's first tab, Item, which a script cannot switch from in 3.4). ``-- OUT_DIR``.

panel.draw_object_probe_mode, which both panels call, is recorded (ui_harness.py): emits RESULT
with the calls per editor; quits Blender itself.
"""
import os
import sys

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import ui_harness  # noqa: E402

from schnee_probes import panel  # noqa: E402

ui_harness.run("draw_object_probe_mode", settings="schnee_probe", sidebar_panel=panel.VIEW3D_PT_schnee_object,
               object_name="Cube", properties_tab='OBJECT', choice='PIXEL')
