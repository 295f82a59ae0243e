"""Schnee probes: bake spherical-harmonics light probes in Blender for the Schnee Vulkan engine.

Submodules register themselves; this file only orders them. The glTF exporter finds
``glTF2ExportUserExtension`` on this package while the add-on is enabled.
"""

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

# Order matters: properties before the operators and panels that use them.
_MODULE_NAMES = ("properties", "nodes", "operators", "panel", "gltf_export")


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


def register():
    for mod in _modules():
        mod.register()


def unregister():
    for mod in reversed(_modules()):
        mod.unregister()


def __getattr__(name):
    # The glTF exporter looks this class up on the add-on module, and (3.4) calls register_panel()
    # when its dialog opens to show the extension's checkbox.
    if name in ("glTF2ExportUserExtension", "register_panel"):
        from . import gltf_export
        return getattr(gltf_export, name)
    raise AttributeError(name)
