"""Draws the SH Probes panel's journal box (panel._draw_journal) of the open .blend into a stub
layout that records labels, and prints ``RESULT {"labels": [...]}``."""
import os
import sys

import bpy

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import addon_common as common  # noqa: E402
import schnee_probes  # noqa: E402
from schnee_probes import panel  # noqa: E402


class _Layout:
    def __init__(self, log):
        self.log = log

    def box(self):
        return self

    def label(self, text="", **_):
        self.log.append(text)


schnee_probes.register()
labels = []
panel._draw_journal(_Layout(labels), bpy.context.scene.schnee_probes)
common.emit(labels=labels)
