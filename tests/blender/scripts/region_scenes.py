"""Scenes for tests/blender/test_region_rebake.py: ``-- OUT_DIR`` writes two_rooms.blend and
two_rooms_edited.blend: test_resume.py's window room (courtyard sky, 4 x 4 x 2 m, a window in its +Y
wall) split into two probe volumes, Left (Blender x -2..0) and Right (x 0..2), with One File per
Volume on. The edited file is the same scene with a 0.8 m crate on the floor of Left (x -1.6..-0.8,
y -1.6..-0.8): the edit a region rebake of Left follows."""
import os
import sys

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import addon_common as common  # noqa: E402
from addon_common import scene_lib as lib  # noqa: E402

import bpy  # noqa: E402

out = common.args()[0]
lib.clear_scene()
lib.hdri_world("courtyard.exr")
lib.probe_volume("Left", (-2.0, -2.0, 0.0), (0.0, 2.0, 2.0))
lib.probe_volume("Right", (0.0, -2.0, 0.0), (2.0, 2.0, 2.0))
plaster = lib.diffuse_material("Plaster", (0.7, 0.7, 0.7))
lib.room_walls((-2.0, -2.0, 0.0), (2.0, 2.0, 2.0), coll=lib.collection("Room"), material=plaster,
               window=(-1.0, 1.0, 0.5, 1.5))
lib.save(os.path.join(out, "two_rooms.blend"))
lib.box("Crate", (-1.6, -1.6, 0.0), (-0.8, -0.8, 0.8), coll=lib.collection("Room"),
        material=lib.diffuse_material("Red", (0.8, 0.1, 0.1)))
lib.save(os.path.join(out, "two_rooms_edited.blend"))
common.emit(ok=True, scene=bpy.context.scene.name)
