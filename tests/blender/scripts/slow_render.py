"""Run before bake.py (``-P slow_render.py -P bake.py``): every render takes 0.2 s longer, so a
test can interrupt a tiny bake at a chosen probe (it polls the journal) without racing it."""
import time

import bpy


def _slow(*_args):
    time.sleep(0.2)


bpy.app.handlers.render_post.append(_slow)
