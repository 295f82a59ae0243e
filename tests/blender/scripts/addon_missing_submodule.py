"""Enable a copy of the add-on with one submodule removed (``-- WORK_DIR NAME``) or broken
(``NAME:broken``, a syntax error) through Blender's own addon_utils, and report what the user gets.
"""
import os
import shutil
import sys

import addon_utils
import bpy

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import addon_common as common  # noqa: E402

work, what = common.args()[:2]
name, _, how = what.partition(":")
src = os.path.join(common.REPO, "addon", "schnee_probes")
addons = os.path.join(work, "scripts", "addons")
dst = os.path.join(addons, "schnee_probes")
shutil.copytree(src, dst, ignore=shutil.ignore_patterns("__pycache__"))
if how == "broken":
    with open(os.path.join(dst, name + ".py"), "a", encoding="utf-8") as fh:
        fh.write("\nthis is not python\n")
elif os.path.exists(os.path.join(dst, name + ".py")):
    os.remove(os.path.join(dst, name + ".py"))
sys.path.insert(0, addons)
for p in list(sys.path):  # only the copy may be found
    if os.path.abspath(p) == os.path.join(common.REPO, "addon"):
        sys.path.remove(p)
errors = []
mod = addon_utils.enable("schnee_probes", default_set=False, persistent=False,
                         handle_error=lambda exc: errors.append(f"{type(exc).__name__}: {exc}"))
common.emit(enabled=mod is not None and hasattr(bpy.types.Scene, "schnee_probes")
            and hasattr(bpy.types, "VIEW3D_PT_schnee_probes"),
            errors=errors, module_file=getattr(mod, "__file__", None))
