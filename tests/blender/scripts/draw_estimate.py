"""Run on a .blend with a probe volume (``blender -b sky.blend -P draw_estimate.py -- JSON``):
calls properties.draw_estimate, which the panel and the bake dialog draw, with a recording layout
and prints ``RESULT {"cases": {name: [[text, icon], ...]}}``.

Blender's UILayout cannot be created headless (bpy.types.UILayout has no constructor; a layout
exists only while a region draws a panel or an operator dialog, and ``blender -b`` draws none), so
a small stand-in records what draw_estimate asks for: ``column``/``row``/``box``/``split`` return a
recorder, ``label(text=, icon=)`` is recorded. JSON sets the scene's Schnee settings (name -> value)."""
import json
import os
import sys

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import addon_common as common  # noqa: E402

import bpy  # noqa: E402

import schnee_probes  # noqa: E402
from schnee_probes import properties  # noqa: E402


class RecordingLayout:
    """What draw_estimate uses of a UILayout, recorded."""

    def __init__(self, labels=None):
        self.labels = [] if labels is None else labels

    def _sub(self, *_args, **_kwargs):
        return RecordingLayout(self.labels)

    column = row = box = split = _sub

    def label(self, text="", icon='NONE', **_kwargs):
        self.labels.append([text, icon])


if not hasattr(bpy.types.Scene, "schnee_probes"):
    schnee_probes.register()
scene = bpy.context.scene
props = scene.schnee_probes
for name, value in json.loads(common.args()[0]).items():
    setattr(props, name, value)


def draw():
    layout = RecordingLayout()
    properties.draw_estimate(layout, scene, props)
    return layout.labels


cases = {"as_set": draw()}
limit = props.probe_limit
props.probe_limit = 3
cases["limit_3"] = draw()
props.probe_limit = limit
props.volume_collection = "NoSuchCollection"
cases["no_volumes"] = draw()
common.emit(cases=cases)
