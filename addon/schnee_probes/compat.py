"""Helpers for the Blender-version differences of the bake and the glTF export.

One add-on for Blender 3.4 through 5.x (tested: 3.4, 4.3, 5.2; docs/install.md). Most APIs that
differ between those versions are reached through a helper here. Not all: some checks stay where
they are used, each a feature test rather than a version number:

- ``__init__.register``: ``bpy.utils.register_cli_command`` (4.2+, ``blender --command schnee_bake``);
- ``gltf_export.py``: the entry points each exporter generation looks up (``register_panel`` for
  3.4-4.1, ``draw_export`` for 4.2-4.3, re-exported by ``__init__.__getattr__``), the exporter's
  texture gathering called under ``try`` (its internals differ), ``.get`` on a material hook's
  argument (not always a material);
- ``bake.py``: the installed package's module name (legacy ``schnee_probes`` or a 4.2+ extension's
  ``bl_ext.<repo>.schnee_probes``);
- ``direct_light.py``: Cycles' point/spot lamp model before 4.0 (``LEGACY_POINT``) and lamp
  properties that moved or are new (``use_soft_falloff``, 4.0+; ``is_portal`` on the lamp or on
  its ``cycles`` settings);
- ``nodes.py``: interface socket descriptions where the socket has one.
"""
import bpy

BLENDER_VERSION = bpy.app.version


def set_equirectangular(camera_data):
    """Make ``camera_data`` a full-sphere equirectangular panorama camera (Cycles).

    Blender 3.x keeps the panorama settings on ``camera.data.cycles``; 4.0 moved them onto the
    camera datablock itself (``camera.data.panorama_type``, ``latitude_min``, ...).
    """
    camera_data.type = 'PANO'
    holder = camera_data if hasattr(camera_data, "panorama_type") else camera_data.cycles
    holder.panorama_type = 'EQUIRECTANGULAR'
    # Full sphere, whatever the defaults of a given version are (angles in radians).
    holder.latitude_min = -1.5707963267948966
    holder.latitude_max = 1.5707963267948966
    holder.longitude_min = -3.141592653589793
    holder.longitude_max = 3.141592653589793


def panorama_settings_holder(camera_data):
    """The struct that carries the panorama settings of ``camera_data`` in this Blender."""
    return camera_data if hasattr(camera_data, "panorama_type") else camera_data.cycles


def group_interface_sockets(tree, in_out):
    """(name -> socket) of a node group's interface ('INPUT' or 'OUTPUT'); Blender 4.0 moved them
    from ``tree.inputs``/``tree.outputs`` to ``tree.interface``."""
    if hasattr(tree, "interface"):  # 4.0+
        return {item.name: item for item in tree.interface.items_tree
                if item.item_type == 'SOCKET' and item.in_out == in_out}
    return {s.name: s for s in (tree.inputs if in_out == 'INPUT' else tree.outputs)}


def new_group_socket(tree, in_out, socket_type, name):
    """Add an interface socket to node group ``tree`` (4.0+ ``tree.interface.new_socket``)."""
    if hasattr(tree, "interface"):  # 4.0+
        return tree.interface.new_socket(name, in_out=in_out, socket_type=socket_type)
    return (tree.inputs if in_out == 'INPUT' else tree.outputs).new(socket_type, name)


def light_objects(scene):
    """Light objects of ``scene`` (type 'LIGHT')."""
    return [ob for ob in scene.objects if ob.type == 'LIGHT']


def has_visible_camera(ob):
    """Blender 3.0+ has per-object ``visible_camera``; 2.9x used ``cycles_visibility.camera``."""
    return hasattr(ob, "visible_camera")


def cycles_settings(scene):
    """``scene.cycles`` where this Blender has Cycles settings on the scene, else None (Cycles
    disabled or absent): callers save/restore them only where they exist."""
    return getattr(scene, "cycles", None)


# ---- Cycles render devices (Preferences > System > Cycles Render Devices) ------------------------
# The Cycles add-on's preferences are the same in 3.4, 4.3 and 5.2 where the bake reads them:
# ``compute_device_type`` ('NONE', 'CUDA', 'OPTIX', 'HIP', 'METAL', 'ONEAPI'; only the types this
# build has, read as '' when the stored one is missing: get_compute_device_type() says 'NONE'), the
# ``devices`` collection (name, id, type, use) and ``get_devices_for_type(type)``, which lists the
# devices found now, adds them to ``devices``, and returns those entries (that type's, then the
# CPU). What differs: ``get_devices()`` returns None since 3.0 (2.9x returned the CUDA and OpenCL
# lists; scripts written for it unpack a None), 4.x added ``get_device_list`` (3.4 has none) and
# 5.x a ``device_list`` argument, and the raw device tuples grew from 4 to 8 fields; and Debian's
# builds (3.4, 4.3, 5.2) list CUDA and HIP among the types but have no OptiX.
GPU_DEVICE_TYPES = ('CUDA', 'OPTIX', 'HIP', 'METAL', 'ONEAPI')


def cycles_preferences():
    """The Cycles add-on's preferences (compute device type and devices), or None without it."""
    addon = bpy.context.preferences.addons.get("cycles")
    return getattr(addon, "preferences", None) if addon is not None else None


def cycles_gpu_devices(prefs):
    """``(compute device type, [names of that type's devices found now and enabled], CPU enabled
    beside them)`` per the user's Preferences; ``('NONE', [], False)`` without Cycles or a type."""
    if prefs is None:
        return 'NONE', [], False
    getter = getattr(prefs, "get_compute_device_type", None)
    kind = getter() if getter is not None else (prefs.compute_device_type or 'NONE')
    if kind not in GPU_DEVICE_TYPES:
        return 'NONE', [], False
    try:
        entries = list(prefs.get_devices_for_type(kind))
    except (AttributeError, RuntimeError, TypeError, KeyError):
        # A Cycles without the listing call: the stored entries (may name a device gone since).
        entries = [d for d in prefs.devices if d.type in (kind, 'CPU')]
    names = [d.name for d in entries if d.type == kind and d.use]
    return kind, names, bool(names) and any(d.type == 'CPU' and d.use for d in entries)


def draw_native_problem(layout):
    """When the compiled bake core did not load: an error box saying what is missing and what the
    user can do (native.native_problem), wrapped to the sidebar width. Draws nothing otherwise."""
    from . import native
    problem = native.native_problem()
    if not problem:
        return False
    import textwrap
    box = layout.box()
    col = box.column(align=True)
    for i, line in enumerate(textwrap.wrap(problem, 42)):
        col.label(text=line, icon='ERROR' if i == 0 else 'BLANK1')
    return True


# ---- glTF exporter (io_scene_gltf2) differences ---------------------------------------------------
# Option panel: 3.4-4.1 call the add-on module's register_panel() when the dialog opens; 4.2-4.3 read
# the module-level draw_export(context, layout) into io_scene_gltf2.exporter_extension_layout_draw
# when the dialog opens; 4.4+ only draw what is registered in that dict (gltf_export.register()).

def gltf_layout_draw_registry():
    """io_scene_gltf2.exporter_extension_layout_draw (4.2+), None before (or without the exporter)."""
    try:
        import io_scene_gltf2
    except ImportError:
        return None
    return getattr(io_scene_gltf2, "exporter_extension_layout_draw", None)


def gltf_original_material(material):
    """The Blender material a glTF material hook is about. Some exporter versions hand the hook an
    inlined (flattened) copy of the material, whose node tree no longer has our group node; map it
    back to the original datablock (``.original``, else by name)."""
    if material is None:
        return None
    original = getattr(material, "original", None)
    if isinstance(original, bpy.types.Material):
        material = original
    if isinstance(material, bpy.types.Material) and material.name in bpy.data.materials:
        found = bpy.data.materials[material.name]
        if found == material or getattr(material, "library", None) is None:
            return found
    if not isinstance(material, bpy.types.Material):
        for attr in ("material", "id_data"):
            cand = getattr(material, attr, None)
            if isinstance(cand, bpy.types.Material):
                return cand
    return material


def gltf_gather_texture_info():
    """The exporter's gather_texture_info(socket, sockets, export_settings): module path of 3.4-4.1
    (blender.exp.gltf2_blender_gather_texture_info) or 4.2+ (blender.exp.material.texture_info)."""
    import importlib
    for name in ("io_scene_gltf2.blender.exp.material.texture_info",
                 "io_scene_gltf2.blender.exp.gltf2_blender_gather_texture_info"):
        try:
            return importlib.import_module(name).gather_texture_info
        except (ImportError, AttributeError):
            continue
    return None


def set_existing(struct, **values):
    """Set the properties of ``struct`` that this Blender has; skip the ones it removed (e.g.
    ``ImageFormatSettings.use_zbuffer``, gone in 4.x). Returns the names skipped."""
    skipped = []
    for name, value in values.items():
        if hasattr(struct, name):
            setattr(struct, name, value)
        else:
            skipped.append(name)
    return skipped


# ---- gpu module (the viewport overlay, overlay_gpu.py) --------------------------------------------
# What differs among 3.4, 4.3 and 5.2 where the overlay draws: GPUShader(vertexcode, fragcode) is
# deprecated in 4.x and gone in 5.x, while gpu.shader.create_from_info (GPUShaderCreateInfo) exists in
# all three, so shaders are made from a create-info only; the built-in shader names changed in 4.0
# ('3D_UNIFORM_COLOR' -> 'UNIFORM_COLOR'), so the overlay brings its own line shader;
# GPUBatch.draw_instanced is 4.x+ only (overlay_gpu draws a batch of spheres several times instead);
# the 3D viewport's overlay framebuffer encodes sRGB on write in all three, an RGBA8 GPUOffScreen not.

def gpu_shader(name, vertex, fragment, *, attrs, varyings, constants, samplers, defines):
    """A GPUShader from a GPUShaderCreateInfo: ``attrs`` ((type, name), ...) vertex inputs in order,
    ``varyings`` ((kind 'smooth'|'flat', type, name), ...), ``constants`` push constants,
    ``samplers`` ((type, name), ...) bound at slots 0.., ``defines`` name -> value."""
    import gpu
    iface = gpu.types.GPUStageInterfaceInfo(name + "_iface")
    for kind, typ, var in varyings:
        getattr(iface, kind)(typ, var)
    info = gpu.types.GPUShaderCreateInfo()
    for key, value in defines.items():
        info.define(key, str(value))
    for slot, (typ, attr) in enumerate(attrs):
        info.vertex_in(slot, typ, attr)
    info.vertex_out(iface)
    for typ, const in constants:
        info.push_constant(typ, const)
    for slot, (typ, sampler) in enumerate(samplers):
        info.sampler(slot, typ, sampler)
    info.fragment_out(0, 'VEC4', "fragColor")
    info.vertex_source(vertex)
    info.fragment_source(fragment)
    return gpu.shader.create_from_info(info)


def gpu_read_framebuffer(fb, width, height):
    """(height, width, 4) uint8 of the bound framebuffer ``fb`` (row 0 at the bottom). Through
    ``to_list``: a 'UBYTE' Buffer's memoryview reads the bytes as wider integers in 3.4."""
    import numpy as np
    buf = fb.read_color(0, 0, width, height, 4, 0, 'UBYTE')
    return np.array(buf.to_list(), dtype=np.uint8).reshape(height, width, 4)
