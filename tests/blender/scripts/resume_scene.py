"""Scene for tests/blender/test_resume.py: ``-- OUT_DIR`` writes window_room.blend: the courtyard
sky, a 4 x 4 x 2 m room (Blender -2..2, -2..2, 0..2) with a 2 x 1 m window in its +Y wall, plaster
walls, one probe volume filling the room. Light enters only through the window and bounces, so at
the tests' 1 sample per pixel every probe is noisy: a resumed bake that reused a wrong probe or
rendered one with another seed or size could not match the uninterrupted bake's bytes."""
import os
import sys

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import addon_common as common  # noqa: E402
from addon_common import scene_lib as lib  # noqa: E402

out = common.args()[0]
lib.clear_scene()
lib.hdri_world("courtyard.exr")
lib.probe_volume("RoomVolume", (-2.0, -2.0, 0.0), (2.0, 2.0, 2.0))
lib.room_walls((-2.0, -2.0, 0.0), (2.0, 2.0, 2.0), coll=lib.collection("Room"),
               material=lib.diffuse_material("Plaster", (0.7, 0.7, 0.7)), window=(-1.0, 1.0, 0.5, 1.5))
lib.save(os.path.join(out, "window_room.blend"))
common.emit(ok=True)
