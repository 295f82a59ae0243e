"""What the bake refuses before it changes anything, and the errors it raises.

Part of the bake (bake_core.ProbeBake drives it): NaN/Inf in what lights the scene
(:func:`check_finite_emission`), image files the render would not find (:func:`check_missing_images`), a bad light mode (:func:`check_light_modes`), more probes than the
limit (:class:`BakeTooLarge`), a cancel (:class:`BakeCancelled`). Whether an existing file may be
replaced is bake_outputs.check_replaceable.
"""
from __future__ import annotations

import math
import os
from typing import Optional

import bpy

from . import compat, light_modes, native
from .estimate import format_duration
from .settings import BakeError


class BakeCancelled(BakeError):
    """The user cancelled the bake (Esc, Ctrl+C, SIGTERM)."""


class BakeTooLarge(BakeError):
    """More probes than ``settings.probe_limit``: the bake needs a confirmation (``allow_large``)."""

    def __init__(self, probes, seconds, limit):
        self.probes, self.seconds, self.limit = probes, seconds, limit
        super().__init__(
            f"{probes} probes (estimated {format_duration(seconds)}) is more than the limit of "
            f"{limit} (Confirm Above): confirm the bake (bake.py: --allow-large), raise the limit "
            "(--probe-limit), or use a larger Min/Max Cell Size or smaller volumes")


def check_light_modes(scene, messages):
    """(the lamp objects marked realtime, the names of those marked mixed) by their
    ``schnee_light_mode`` (light_modes.py; a mixed lamp's direct light is left out of the probes,
    direct_light.prepare). Refuses a bad value before anything changes."""
    realtime, mixed = [], []
    for ob in compat.light_objects(scene):
        try:
            mode = light_modes.light_mode(ob)
        except light_modes.LightModeError as exc:
            raise BakeError(f"{exc}: set it in the Schnee Engine panel "
                            "(Light Mode) or remove the property") from exc
        if mode == light_modes.REALTIME:
            realtime.append(ob)
            if ob.data.type == 'AREA':
                messages.append(f"Light '{ob.name}' is realtime but an area light, which "
                                     "glTF cannot export: its light reaches neither the probes "
                                     "nor the engine")
        elif mode == light_modes.MIXED:
            mixed.append(ob.name)
            if ob.data.type == 'AREA':
                messages.append(f"Light '{ob.name}' is mixed but an area light, which glTF "
                                     "cannot export: only its bounced light reaches the probes "
                                     "and its direct light nothing")
    return realtime, frozenset(mixed)


# ------------------------------------------------------------------ values the probes cannot hold
# Blender stores an Inf typed into a float field as the largest float32: that is Inf too.
_FLT_MAX = 3.4028234663852886e38


def _non_finite(value):
    """The first value of ``value`` (a number or a vector) that is NaN, Inf or Blender's clamped
    Inf, as text; None if all are finite."""
    try:
        values = tuple(value)
    except TypeError:
        values = (value,)
    for v in values:
        if isinstance(v, float):
            if math.isnan(v):
                return "NaN"
            if abs(v) >= _FLT_MAX:
                return "Inf" if math.isinf(v) else "Inf (stored as the largest float, 3.4e38)"
    return None


def _tree_problems(tree, where, seen):
    out = []
    if tree is None or tree.as_pointer() in seen:
        return out
    seen.add(tree.as_pointer())  # embedded trees all share the name "Shader Nodetree"
    for node in tree.nodes:
        for sock in node.inputs:
            if sock.is_linked or not hasattr(sock, "default_value"):
                continue
            bad = _non_finite(sock.default_value)
            if bad:
                out.append(f"{where}: node '{node.name}' input '{sock.name}' is {bad}")
        if node.type == 'GROUP' and node.node_tree is not None:
            out += _tree_problems(node.node_tree, f"{where} (group '{node.node_tree.name}')", seen)
    return out


def check_finite_emission(scene):
    """Refuse NaN/Inf in what lights the scene: unlinked node inputs of the materials of
    render-visible objects (an Emission Strength of inf, a NaN colour), lamps' energy and colour,
    the world's nodes. Cycles silently drops such values, so the probes would miss that light."""
    problems, seen_trees = [], set()
    for ob in scene.objects:
        if ob.hide_render:
            continue
        if ob.type == 'LIGHT':
            for ident in ("energy", "color"):
                bad = _non_finite(getattr(ob.data, ident))
                if bad:
                    problems.append(f"light '{ob.name}': {ident} is {bad}")
            if ob.data.use_nodes:
                problems += _tree_problems(ob.data.node_tree, f"light '{ob.name}'", set())
            continue
        for slot in getattr(ob, "material_slots", ()):
            mat = slot.material
            if mat is not None and mat.use_nodes:
                problems += [p + f" (on object '{ob.name}')" for p in
                             _tree_problems(mat.node_tree, f"material '{mat.name}'", seen_trees)]
    world = scene.world
    if world is not None and world.use_nodes:
        problems += _tree_problems(world.node_tree, f"world '{world.name}'", set())
    if problems:
        more = f" (and {len(problems) - 3} more)" if len(problems) > 3 else ""
        raise BakeError("Values the probes cannot represent (Cycles drops NaN/Inf, so this light "
                        "would be missing without a warning): " + "; ".join(problems[:3]) + more
                        + ". Set finite values")


def _tree_images(tree, where, seen):
    """(image, where) of the image nodes of ``tree`` and its groups (Image / Environment Texture)."""
    out = []
    if tree is None or tree.as_pointer() in seen:
        return out
    seen.add(tree.as_pointer())  # embedded trees all share the name "Shader Nodetree"
    for node in tree.nodes:
        image = getattr(node, "image", None)
        if image is not None:
            out.append((image, f"{where} (node '{node.name}')"))
        if node.type == 'GROUP' and node.node_tree is not None:
            out += _tree_images(node.node_tree, f"{where} (group '{node.node_tree.name}')", seen)
    return out


def image_missing(image) -> Optional[str]:
    """The absolute path of an image file that is not there, else None: a packed, generated or
    rendered image, a UDIM set or a movie (their files are Blender's to resolve) is never missing."""
    if image.source not in ('FILE', 'SEQUENCE') or image.packed_file is not None or not image.filepath:
        return None
    path = bpy.path.abspath(image.filepath, library=image.library)
    return None if os.path.isfile(path) else path


def check_missing_images(scene):
    """Refuse image files the render would not find: an Image or Environment Texture of the world,
    of a lamp or of a material of a render-visible object whose file is missing renders magenta
    (Cycles' missing-texture colour) and the probes would hold that colour without a warning."""
    found, seen_trees, seen_images = [], set(), set()
    trees = []
    if scene.world is not None and scene.world.use_nodes:
        trees.append((scene.world.node_tree, f"world '{scene.world.name}'"))
    for ob in scene.objects:
        if ob.hide_render:
            continue
        if ob.type == 'LIGHT':
            if ob.data.use_nodes:
                trees.append((ob.data.node_tree, f"light '{ob.name}'"))
            continue
        for slot in getattr(ob, "material_slots", ()):
            mat = slot.material
            if mat is not None and mat.use_nodes:
                trees.append((mat.node_tree, f"material '{mat.name}' (on object '{ob.name}')"))
    for tree, where in trees:
        for image, at in _tree_images(tree, where, seen_trees):
            path = image_missing(image)
            if path is not None and image.name_full not in seen_images:
                seen_images.add(image.name_full)
                found.append(f"image '{image.name}' of {at}: {path}")
    if found:
        more = f" (and {len(found) - 3} more)" if len(found) > 3 else ""
        raise BakeError("Image files are missing (Cycles would render them magenta, and the probes would "
                        "hold that colour): " + "; ".join(found[:3]) + more + ". Find them (File > "
                        "External Data > Find Missing Files) or pack them")


def check_shading(scene):
    """What the render would get wrong without a word: NaN/Inf (:func:`check_finite_emission`) and
    missing image files (:func:`check_missing_images`)."""
    check_finite_emission(scene)
    check_missing_images(scene)


def check_panorama_size(settings):
    """Panorama Resolution too small for Max SH Band: :class:`BakeError` with the size needed."""
    min_w, min_h = native.min_panorama_size(settings.max_band)
    if settings.panorama_resolution < min_w or settings.panorama_resolution // 2 < min_h:
        raise BakeError(f"Panorama Resolution {settings.panorama_resolution} is too small for Max SH Band "
                        f"{settings.max_band}: at least {min_w}x{min_h} is needed")
