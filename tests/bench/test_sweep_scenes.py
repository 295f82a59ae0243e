"""The sweep's sun scenes (bench/sweep/scenes.py, issue 11) put probes both in the Sun lamp's light
and in shadow, as their docstrings say.

Expected values: a ray from each probe towards the sun against the scene's solid boxes (slab test,
scenes.lamp_lit) - hand-checked for two probes below: in sun_yard the probe (-3, -3, 1) looks
towards the sun (-0.612, -0.612, 0.5) and reaches the west wing's face x = -5 after t = 3.27 m at
height 1 + 1.63 = 2.63 m < 4 m (shadow); (4, 4, 2.5) clears both wings (reaches x = -5 at
z = 9.85 m) and the pillar. No Blender: bpy and scene_lib are stubbed for the import only.
"""
import importlib.util
import sys
import types

import pytest

from conftest import REPO


@pytest.fixture
def scenes(monkeypatch):
    monkeypatch.setitem(sys.modules, "bpy", types.ModuleType("bpy"))
    monkeypatch.setitem(sys.modules, "scene_lib", types.ModuleType("scene_lib"))
    spec = importlib.util.spec_from_file_location("sweep_scenes_under_test",
                                                  REPO / "bench" / "sweep" / "scenes.py")
    mod = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mod)
    return mod


def test_sun_yard_probes_in_sun_and_in_shadow(scenes):
    boxes = [(a, b) for _, a, b in scenes.YARD_BOXES]
    lit = [scenes.lamp_lit(p, scenes.SUN_YARD_TO_SUN, boxes) for p in scenes.SUN_YARD_PROBES]
    assert lit == [False, True, False, True, False, True]


def test_sun_window_probes_in_the_beam_and_out_of_it(scenes):
    lit = [scenes.lamp_lit(p, scenes.SUN_WINDOW_TO_SUN, scenes.room_boxes()) for p in scenes.SUN_WINDOW_PROBES]
    assert lit == [True, True, False, False, False, False]
    # A floor point under the window's beam is lit (the sun patch), one by the south wall is not.
    assert scenes.lamp_lit((-0.5, 0.2, 0.001), scenes.SUN_WINDOW_TO_SUN, scenes.room_boxes())
    assert not scenes.lamp_lit((0.0, -1.8, 0.001), scenes.SUN_WINDOW_TO_SUN, scenes.room_boxes())


def test_sun_directions_are_unit_and_above_the_horizon(scenes):
    for d in (scenes.SUN_YARD_TO_SUN, scenes.SUN_WINDOW_TO_SUN):
        assert abs(sum(x * x for x in d) - 1.0) < 1e-12
        assert d[2] > 0.4
