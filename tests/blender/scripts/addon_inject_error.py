"""Run before bake.py (``blender -b -P addon_inject_error.py -P bake.py -- ...``): makes
``ProbeBake.run`` raise a RuntimeError, an error no bake.py handler expects, so the test sees how
bake.py reports an unexpected exception."""
import os
import sys

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import addon_common  # noqa: E402,F401  (puts addon/ on sys.path, the same package bake.py imports)

from schnee_probes import bake_core  # noqa: E402


def _broken_run(self, progress=None):
    raise RuntimeError("injected unexpected failure")


bake_core.ProbeBake.run = _broken_run
