"""Run before bake.py (``-P slow_render.py -P bake.py``): every render takes 0.2 s longer, so a
test can interrupt a tiny bake at a chosen probe (it polls the journal) without racing it.

Environment (tests/blender/test_bake_hazards.py, a second Ctrl+C): ``SCHNEE_TEST_RENDER_DELAY``
seconds instead of 0.2, and each sleep first prints ``SLOW_RENDER start`` (a signal sent after it lands
inside the sleep); ``SCHNEE_TEST_EXIT_DELAY`` seconds of sleep in an atexit hook, i.e. while Blender
exits after bake.py has cleaned up (the window a late signal can land in)."""
import atexit
import os
import time

import bpy

RENDER_DELAY = float(os.environ.get("SCHNEE_TEST_RENDER_DELAY", "0.2"))
SAY = "SCHNEE_TEST_RENDER_DELAY" in os.environ
EXIT_DELAY = float(os.environ.get("SCHNEE_TEST_EXIT_DELAY", "0"))


def _slow(*_args):
    if SAY:
        print("SLOW_RENDER start", flush=True)
    time.sleep(RENDER_DELAY)


def _slow_exit():
    print("SLOW_EXIT start", flush=True)
    time.sleep(EXIT_DELAY)
    print("SLOW_EXIT end", flush=True)


bpy.app.handlers.render_post.append(_slow)
if EXIT_DELAY > 0:
    atexit.register(_slow_exit)
