"""Run before bake.py (``-P count_renders.py -P bake.py``): every Cycles render appends one line,
``x y z seed samples`` (the scene camera's location to 1 µm, Cycles' seed and samples), to the file
named by ``SCHNEE_TEST_RENDER_LOG``, so a test can count the renders of each point and round
(issue 29: no point rendered twice). Several runs (a killed bake and its resume, the shards and the
merge) append to one file."""
import os

import bpy

LOG = os.environ["SCHNEE_TEST_RENDER_LOG"]


def _count(scene, *_args):
    cam = scene.camera
    loc = tuple(int(round(c * 1e6)) for c in cam.location) if cam is not None else (0, 0, 0)
    with open(LOG, "a", encoding="utf-8") as fh:
        fh.write(f"{loc[0]} {loc[1]} {loc[2]} {scene.cycles.seed} {scene.cycles.samples}\n")


bpy.app.handlers.render_pre.append(_count)
