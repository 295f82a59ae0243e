"""Schnee probes: bake spherical-harmonics light probes in Blender for the Schnee Vulkan engine.

Submodules register themselves; this file only orders them. The glTF exporter finds
``glTF2ExportUserExtension`` on this package while the add-on is enabled.
"""

# Licence: GPL-3.0-or-later (Blender add-ons must be GPL-compatible). Blender 3.4-4.1 read bl_info
# (legacy add-on zip); 4.2+ read blender_manifest.toml of the extension package (docs/install.md).
bl_info = {
    "name": "Schnee Probes",
    "author": "Schnee probes team",
    "version": (0, 1, 0),
    "blender": (3, 4, 0),
    "location": "3D Viewport > Sidebar (N) > Schnee Engine",
    "description": "Bake SH light probes in probe volumes and export them with glTF",
    "category": "Lighting",
}

import importlib
import os

# Order matters: properties before the operators and panels that use them.
_MODULE_NAMES = ("properties", "nodes", "operators", "panel", "overlay", "gltf_export")


def _modules():
    """Every submodule, imported. A missing or broken one is an error that names it (Blender shows
    it when enabling the add-on); nothing is skipped. The compiled native module is not among
    them: native.py imports without it and says how to build it when a bake needs it."""
    mods = []
    for name in _MODULE_NAMES:
        try:
            mods.append(importlib.import_module("." + name, __name__))
        except Exception as exc:
            raise ImportError(
                f"Schnee Probes: the add-on's module '{name}' could not be loaded "
                f"({type(exc).__name__}: {exc}); the installed add-on is incomplete or broken: "
                "reinstall it from the add-on zip") from exc
    return mods


_cli_handle = None


def _cli_bake(argv):
    """``blender --command schnee_bake SCENE.blend [bake.py options]`` (Blender 4.2+): runs the bake.py
    this package carries, ``blender -b SCENE.blend -P <package>/bake.py -- options``, in a child
    Blender (same profile) and returns its exit status. ``--help`` prints the path of bake.py."""
    import subprocess
    import bpy
    script = os.path.join(os.path.dirname(os.path.abspath(__file__)), "bake.py")
    if not argv or argv[0] in ("-h", "--help"):
        print("usage: blender --command schnee_bake SCENE.blend [options]\n"
              f"runs: blender -b SCENE.blend -P {script} -- [options]\n"
              "options: blender -b -P <that bake.py> -- --help")
        return 0 if argv else 2
    return subprocess.call([bpy.app.binary_path, "-b", argv[0], "--python-exit-code", "1", "-P", script,
                            "--", *argv[1:]])


def register():
    try:
        import numpy  # noqa: F401
    except ImportError:
        raise ImportError("Schnee Probes needs numpy. Blender from blender.org bundles it; for a Blender "
                          "from a Linux distribution install its numpy package (Debian/Ubuntu: "
                          "apt install python3-numpy)") from None
    for mod in _modules():
        mod.register()
    global _cli_handle
    import bpy
    if hasattr(bpy.utils, "register_cli_command") and _cli_handle is None:  # Blender 4.2+
        try:
            _cli_handle = bpy.utils.register_cli_command("schnee_bake", _cli_bake)
        except (ValueError, RuntimeError) as exc:  # the add-on works without it; bake.py stays
            print(f"Schnee Probes: 'blender --command schnee_bake' not registered: {exc}")


def unregister():
    global _cli_handle
    if _cli_handle is not None:
        import bpy
        bpy.utils.unregister_cli_command(_cli_handle)
        _cli_handle = None
    for mod in reversed(_modules()):
        mod.unregister()


def __getattr__(name):
    # The glTF exporter looks this class up on the add-on module; to show the extension's checkbox
    # 3.4-4.1 call register_panel() and 4.2-4.3 read draw_export when its dialog opens (compat.py).
    if name in ("glTF2ExportUserExtension", "register_panel", "draw_export"):
        from . import gltf_export
        return getattr(gltf_export, name)
    raise AttributeError(name)
