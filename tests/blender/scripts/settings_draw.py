"""Which settings the panel and the Bake SH in Volumes dialog draw: ``blender -b -P`` this.

Blender's ``UILayout`` cannot be created from Python, and headless Blender (``-b``) has no window
that would hand a panel or a dialog one, so every draw below is given :class:`RecordingLayout`
instead: it accepts what a layout accepts (sub-layouts, labels, operators, attributes such as
``scale_y``) and records each ``prop``/``prop_search`` call with the layout object it was made on.
Drawn: ``properties.draw_settings`` for each UI section (``volumes=True``: the panel and the
dialog; ``volumes=False``: settings without a volume-only place), then the panel's and the dialog's
own ``draw`` methods, called as Blender calls them (``self.layout``, the context).
Prints one ``RESULT {json}`` line (tests/blender/test_settings_blender.py).
"""
import os
import sys
import types

import bpy

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import addon_common as common  # noqa: E402

import schnee_probes  # noqa: E402
from schnee_probes import operators, panel, properties  # noqa: E402


class RecordingLayout:
    """A stand-in for ``bpy.types.UILayout`` that records the properties drawn into it."""

    def __init__(self, calls, kind="layout"):
        self._calls = calls
        self._kind = kind

    def _sub(self, kind):
        return RecordingLayout(self._calls, kind)

    def column(self, **kw):
        return self._sub("column")

    def row(self, **kw):
        return self._sub("row")

    def box(self):
        return self._sub("box")

    def split(self, **kw):
        return self._sub("split")

    def prop(self, data, name, **kw):
        self._calls.append({"data": data, "name": name, "layout": id(self), "kind": self._kind,
                            "text": kw.get("text"), "search": None})

    def prop_search(self, data, name, search_data, search_name, **kw):
        self._calls.append({"data": data, "name": name, "layout": id(self), "kind": self._kind,
                            "text": kw.get("text"), "search": search_name,
                            "search_is_bpy_data": search_data == bpy.data})

    def label(self, **kw):
        pass

    def separator(self, **kw):
        pass

    def operator(self, idname, **kw):
        return types.SimpleNamespace()  # operator properties are set on it (panel.py's light mode)


def drawn(draw, props):
    """The setting properties of ``props`` drawn by ``draw(layout)``, as JSON-friendly records."""
    calls = []
    draw(RecordingLayout(calls))
    ours = [c for c in calls if getattr(c["data"], "as_pointer", lambda: None)() == props.as_pointer()]
    others = [c["name"] for c in calls if c not in ours]
    return {"names": [c["name"] for c in ours], "others": others,
            "layouts": [[c["name"], c["layout"], c["kind"], c["text"], c["search"], c.get("search_is_bpy_data")]
                        for c in ours]}


schnee_probes.register()
context = bpy.context
props = context.scene.schnee_probes
out = {
    "section_volumes": drawn(lambda lay: properties.draw_settings(lay, props, volumes=True), props),
    "section_all": drawn(lambda lay: properties.draw_settings(lay, props, volumes=False), props),
    # The panel's and the dialog's draw methods (Blender calls them with self.layout set).
    "panel": drawn(lambda lay: panel.VIEW3D_PT_schnee_probes.draw(types.SimpleNamespace(layout=lay), context),
                   props),
    "dialog": drawn(lambda lay: operators.SCHNEE_OT_bake_sh_volumes.draw(types.SimpleNamespace(layout=lay),
                                                                         context), props),
}
common.emit(**out)
