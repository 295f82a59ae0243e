"""What a bake is, as digests: the parts of a journal's manifest (journal.py, docs/farm.md
"Fingerprint"). Two bakes with equal parts render the same probes to the same bits, so a journal
(or a shard) of one can be resumed (or merged) by the other; a part that differs is named in the
error.

Covered: the bake settings (seed included); every object Cycles renders (type, transform, render
visibility flags, evaluated mesh: vertices and triangles, material slots); the node trees and
properties of the materials, world and lamps it uses (node types, properties, input values, links,
node groups, image files by path, size and modification time); the scene's Cycles and render
settings. Not covered (documented): edits to image pixels that keep a file's size and time, and
drivers or handlers that change the scene while it renders.
"""
from __future__ import annotations

import hashlib
import json
import os
from dataclasses import asdict
from typing import Dict

import numpy as np

import bpy

from . import adaptive, light_modes

# UI-only properties: moving a node in the editor or selecting an object does not change the light.
_IGNORED = frozenset({
    "rna_type", "name_full", "select", "location", "width", "width_hidden", "height", "dimensions",
    "hide", "show_options", "show_preview", "show_texture", "show_expanded", "use_custom_color",
    "color", "label", "is_evaluated", "original", "users", "is_dirty", "session_uid", "tag",
    "is_runtime_data", "is_missing", "is_library_indirect", "use_fake_user", "use_extra_user",
    "preview", "is_embedded_data", "library_weak_reference", "asset_data", "override_library",
})


# Settings that change where or how the values are written, not the values (the journal holds the
# baked SH; the ambient cube, float or half, is fitted from them when the file is written).
# Write-time choices: they change the written file, not a journal record (a render), so a resumed bake
# with other values reuses the records and applies its own (probe representation; Dilate Invalid Probes
# and SH Windowing, postprocess.py, applied to the final probes in bake_plans' outputs).
_NOT_VALUES = frozenset({"output_path", "probe_limit", "per_volume_files", "probe_representation",
                         "dilate_invalid", "sh_window", "sh_window_strength"})


# Settings added after journals existed, with the value that bakes as before them: left out of the
# digest at that value, so a journal of an earlier bake still resumes (Sky Sun "baked" is the bake
# before issue 27 byte for byte; "mixed" changes the probes' sky and is digested).
_LEGACY_VALUES = {"sky_sun": "baked", "render_device": "SCENE"}


def _at_legacy_value(name, value) -> bool:
    return name in _LEGACY_VALUES and value == _LEGACY_VALUES[name]


def _simple(struct) -> list:
    """Every simple RNA property of ``struct`` (booleans, numbers, enums, strings and their
    arrays) as (identifier, repr): repr of a float is exact."""
    out = []
    for prop in struct.bl_rna.properties:
        ident = prop.identifier
        if ident in _IGNORED or prop.type in ("POINTER", "COLLECTION"):
            continue
        try:
            value = getattr(struct, ident)
        except Exception:  # properties that raise in some contexts are not data
            continue
        if not isinstance(value, (str, bytes, int, float, bool)) and value is not None:
            try:
                value = np.asarray(value, dtype=np.float64).tolist()
            except (TypeError, ValueError):
                value = str(value)
        out.append((ident, repr(value)))
    return out


def _image(img) -> list:
    if img is None:
        return ["none"]
    data = [img.name, img.source, _simple(img.colorspace_settings)]
    if img.packed_file is not None:
        data.append(hashlib.sha256(bytes(img.packed_file.data)).hexdigest())
    else:
        path = bpy.path.abspath(img.filepath, library=img.library)
        try:
            st = os.stat(path)
            data.append((path, st.st_size, st.st_mtime_ns))
        except OSError:
            data.append((path, "missing"))
    return data


def _tree(tree, seen) -> list:
    """Nodes (type, properties, input values, images, groups) and links of a node tree."""
    if tree is None:
        return ["none"]
    if tree.name in seen:
        return ["group", tree.name]
    seen.add(tree.name)
    nodes = []
    for node in sorted(tree.nodes, key=lambda n: n.name):
        entry = [node.bl_idname, node.name, _simple(node)]
        for sock in node.inputs:
            v = getattr(sock, "default_value", None)
            if v is not None and not isinstance(v, (str, int, float, bool)):
                try:
                    v = np.asarray(v, dtype=np.float64).tolist()
                except (TypeError, ValueError):
                    v = str(v)
            entry.append((sock.identifier, repr(v), sock.is_linked))
        if getattr(node, "image", None) is not None:
            entry.append(_image(node.image))
        if getattr(node, "node_tree", None) is not None:
            entry.append(_tree(node.node_tree, seen))
        nodes.append(entry)
    links = sorted((l.from_node.name, l.from_socket.identifier, l.to_node.name, l.to_socket.identifier,
                    l.is_muted) for l in tree.links)
    return [nodes, links]


def _digest(data) -> str:
    return hashlib.sha256(json.dumps(data, default=repr, separators=(",", ":")).encode()).hexdigest()


def _mesh_digest(ob, depsgraph, h):
    ev = ob.evaluated_get(depsgraph)
    mesh = ev.to_mesh()
    try:
        mesh.calc_loop_triangles()
        co = np.empty(len(mesh.vertices) * 3, dtype=np.float32)
        mesh.vertices.foreach_get("co", co)
        tris = np.empty(len(mesh.loop_triangles) * 3, dtype=np.int32)
        mesh.loop_triangles.foreach_get("vertices", tris)
        mats = np.empty(len(mesh.loop_triangles), dtype=np.int32)
        mesh.loop_triangles.foreach_get("material_index", mats)
        h.update(co.tobytes() + tris.tobytes() + mats.tobytes())
    finally:
        ev.to_mesh_clear()


def parts(scene, view_layer, settings) -> Dict[str, str]:
    """The fingerprint's parts of the bake of ``scene`` with ``settings`` (a BakeSettings)."""
    depsgraph = bpy.context.evaluated_depsgraph_get()
    geometry = hashlib.sha256()
    materials, lights, seen = [], [], set()
    for ob in sorted(scene.objects, key=lambda o: o.name):
        if ob.hide_render:
            continue
        placed = repr((ob.name, ob.type, np.asarray(ob.matrix_world, dtype=np.float64).tolist(), _simple(ob)))
        if ob.type != "LIGHT":
            geometry.update(placed.encode())
        if ob.type in ("MESH", "CURVE", "SURFACE", "META", "FONT"):
            _mesh_digest(ob, depsgraph, geometry)
            for slot in ob.material_slots:
                mat = slot.material
                if mat is not None and mat.name not in seen:
                    seen.add(mat.name)
                    materials.append([mat.name, _simple(mat), _tree(mat.node_tree if mat.use_nodes else None,
                                                                     set())])
        elif ob.type == "LIGHT":
            light = ob.data
            # The lamp's light mode decides whether its direct light is in the probes: a resumed bake
            # must not mix probes of two modes (the mode is a custom property or a pointer property,
            # which _simple leaves out; a bad value is the bake's error to report).
            try:
                mode = light_modes.light_mode(ob)
            except light_modes.LightModeError:
                mode = repr(ob.get(light_modes.PROPERTY))
            lights.append([placed, _simple(light), getattr(light, "cycles", None) and _simple(light.cycles),
                           _tree(light.node_tree if light.use_nodes else None, set()), mode])
    world = scene.world
    world_data = ["none"] if world is None else [_simple(world), _tree(world.node_tree if world.use_nodes else None,
                                                                        set())]
    render = [_simple(scene.render), _simple(scene.cycles) if hasattr(scene, "cycles") else [],
              _simple(scene.view_settings), _simple(view_layer)]
    return {
        # Where the files go, how they store the values and when to ask for confirmation do not
        # change a probe's value.
        "settings": _digest(sorted((k, v) for k, v in asdict(settings).items()
                                   if k not in _NOT_VALUES and not _at_legacy_value(k, v))
                            + ([("sampling", adaptive.SAMPLING)] if settings.placement == "ADAPTIVE" else [])),
        "geometry": geometry.hexdigest(),
        "materials": _digest(materials),
        "lights": _digest(lights),
        "world": _digest(world_data),
        "render": _digest(render),
    }
