"""The light-mode panels drawn by Blender itself in a real UI session (run under Xvfb): the startup
file's point lamp active, a Properties editor on its Light tab (DATA_PT_schnee_light) and the 3D
viewport's sidebar (VIEW3D_PT_schnee_light, registered once more on the sidebar's first tab, Item,
which a script cannot switch from in 3.4). ``-- OUT_DIR``.

panel.draw_light_mode, which both panels call, is recorded (ui_harness.py): emits RESULT with the
calls per editor; quits Blender itself.
"""
import os
import sys

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import ui_harness  # noqa: E402

from schnee_probes import panel  # noqa: E402

ui_harness.run("draw_light_mode", settings="schnee_light", sidebar_panel=panel.VIEW3D_PT_schnee_light,
               object_name="Light", properties_tab='DATA', choice='BAKED')
