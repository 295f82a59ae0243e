"""The "VS Movable Diffuse" shader node group and materials that use it.

A material marks itself as movable-diffuse for the engine by using this group as its surface
shader. Its inputs are the engine's per-material SH settings (DESIGN.md §3, §5):

    diffuse = albedo · (shScale · max(E(n), 0) / π + ambientTerm)

Inside Blender the group is a plain Diffuse BSDF driven by Base Color, which is the ``shScale = 1,
ambientTerm = 0`` case of that formula. SH Scale and Ambient Term deliberately do not change the
Cycles render: an emission for the ambient term would add light to the probe bake itself. They
reach the engine through the glTF exporter (``gltf_export.py``, extension
``VULKAN_SCHNEE_materials``).
"""
import math
import re

import bpy

from . import compat

GROUP_NAME = "VS Movable Diffuse"
# Custom property on the node tree: recognises our group even after a user renames it.
GROUP_TAG = "schnee_movable_diffuse"
GROUP_VERSION = 1

INPUT_BASE_COLOR = "Base Color"
INPUT_SH_SCALE = "SH Scale"
INPUT_AMBIENT = "Ambient Term"
OUTPUT_BSDF = "BSDF"

DEFAULT_SH_SCALE = 1.0
DEFAULT_AMBIENT = 0.1

# "VS Movable Diffuse", or the ".001" copy Blender makes when a .blend with the group is appended.
_NAME_RE = re.compile(r"^" + re.escape(GROUP_NAME) + r"(\.\d{3,})?$")


# Node-group sockets moved to ``tree.interface`` in Blender 4.0: compat.py reaches both.
_interface_sockets = compat.group_interface_sockets
_new_socket = compat.new_group_socket


def is_movable_diffuse_tree(tree):
    """True when ``tree`` is a "VS Movable Diffuse" group (by tag or by name) with our sockets."""
    if tree is None or getattr(tree, "bl_idname", "") != "ShaderNodeTree":
        return False
    if not (tree.get(GROUP_TAG) or _NAME_RE.match(tree.name)):
        return False
    inputs = _interface_sockets(tree, 'INPUT')
    outputs = _interface_sockets(tree, 'OUTPUT')
    return all(n in inputs for n in (INPUT_BASE_COLOR, INPUT_SH_SCALE, INPUT_AMBIENT)) \
        and OUTPUT_BSDF in outputs


def _build_group(tree):
    base = _new_socket(tree, 'INPUT', 'NodeSocketColor', INPUT_BASE_COLOR)
    base.default_value = (0.8, 0.8, 0.8, 1.0)
    scale = _new_socket(tree, 'INPUT', 'NodeSocketFloat', INPUT_SH_SCALE)
    scale.default_value = DEFAULT_SH_SCALE
    scale.min_value = 0.0
    scale.max_value = 100.0
    ambient = _new_socket(tree, 'INPUT', 'NodeSocketFloat', INPUT_AMBIENT)
    ambient.default_value = DEFAULT_AMBIENT
    ambient.min_value = 0.0
    ambient.max_value = 10.0
    for sock, text in ((scale, "Multiplier for all SH coefficients (engine only)"),
                       (ambient, "Constant added to the diffuse after SH evaluation (engine only)"),
                       (base, "Albedo")):
        if hasattr(sock, "description"):
            sock.description = text
    _new_socket(tree, 'OUTPUT', 'NodeSocketShader', OUTPUT_BSDF)

    nodes = tree.nodes
    group_in = nodes.new("NodeGroupInput")
    group_in.location = (-300, 0)
    diffuse = nodes.new("ShaderNodeBsdfDiffuse")
    diffuse.location = (0, 0)
    group_out = nodes.new("NodeGroupOutput")
    group_out.location = (250, 0)
    tree.links.new(group_in.outputs[INPUT_BASE_COLOR], diffuse.inputs["Color"])
    tree.links.new(diffuse.outputs["BSDF"], group_out.inputs[OUTPUT_BSDF])
    tree[GROUP_TAG] = GROUP_VERSION


def ensure_node_group():
    """Return the "VS Movable Diffuse" node group, creating it once per .blend (idempotent).

    An existing group of that name that is not ours (missing sockets) is left untouched and a new
    one is created beside it (Blender names it "VS Movable Diffuse.001").
    """
    for tree in bpy.data.node_groups:
        if tree.get(GROUP_TAG) and is_movable_diffuse_tree(tree):
            return tree
    existing = bpy.data.node_groups.get(GROUP_NAME)
    if is_movable_diffuse_tree(existing):
        existing[GROUP_TAG] = GROUP_VERSION
        return existing
    tree = bpy.data.node_groups.new(GROUP_NAME, "ShaderNodeTree")
    _build_group(tree)
    return tree


def _check_factor(name, value):
    value = float(value)
    if not math.isfinite(value) or value < 0.0:
        raise ValueError(f"{name} must be a finite number >= 0, got {value!r}")
    return value


def make_movable_diffuse_material(name, base_color=(0.8, 0.8, 0.8, 1.0), sh_scale=DEFAULT_SH_SCALE,
                                  ambient=DEFAULT_AMBIENT):
    """New material ``name`` whose surface is a "VS Movable Diffuse" group node.

    ``base_color`` is linear RGB or RGBA (alpha defaults to 1); ``sh_scale`` and ``ambient`` are the
    engine's SH Scale and Ambient Term (finite, >= 0). Returns the material.
    """
    color = tuple(float(c) for c in base_color)
    if len(color) == 3:
        color += (1.0,)
    if len(color) != 4 or not all(math.isfinite(c) for c in color):
        raise ValueError(f"base_color must be 3 or 4 finite numbers, got {base_color!r}")
    sh_scale = _check_factor("sh_scale", sh_scale)
    ambient = _check_factor("ambient", ambient)

    group = ensure_node_group()
    mat = bpy.data.materials.new(name)
    mat.use_nodes = True
    mat.diffuse_color = color  # solid-mode viewport colour
    nodes = mat.node_tree.nodes
    nodes.clear()
    node = nodes.new("ShaderNodeGroup")
    node.node_tree = group
    node.name = node.label = GROUP_NAME
    node.location = (0, 0)
    node.inputs[INPUT_BASE_COLOR].default_value = color
    node.inputs[INPUT_SH_SCALE].default_value = sh_scale
    node.inputs[INPUT_AMBIENT].default_value = ambient
    out = nodes.new("ShaderNodeOutputMaterial")
    out.location = (300, 0)
    mat.node_tree.links.new(node.outputs[OUTPUT_BSDF], out.inputs["Surface"])
    return mat


def find_movable_diffuse_node(material):
    """The "VS Movable Diffuse" group node of ``material``, or None.

    Several such nodes: the one feeding the active Material Output wins, else the first by name.
    """
    if material is None or not material.use_nodes or material.node_tree is None:
        return None
    found = [n for n in material.node_tree.nodes
             if n.bl_idname == "ShaderNodeGroup" and not n.mute and is_movable_diffuse_tree(n.node_tree)]
    if not found:
        return None
    linked = [n for n in found if feeds_active_output(n)]
    return sorted(linked or found, key=lambda n: n.name)[0]


def feeds_active_output(node):
    """True when an output of ``node`` reaches the active Material Output (through any nodes)."""
    seen = set()
    todo = [node]
    while todo:
        current = todo.pop()
        if current.name in seen:
            continue
        seen.add(current.name)
        for out in current.outputs:
            for link in out.links:
                to = link.to_node
                if to.bl_idname == "ShaderNodeOutputMaterial" and to.is_active_output:
                    return True
                todo.append(to)
    return False


# Object types that can hold materials and evaluate to a mesh (scene_export.MESH_LIKE).
_MATERIAL_OBJECTS = {'MESH', 'CURVE', 'SURFACE', 'FONT', 'META'}


def _surface_color(material):
    """Base colour of the shader currently feeding the active output's Surface, if it has an
    unlinked colour input (Principled "Base Color", Diffuse "Color"); else None."""
    out = material.node_tree.get_output_node('ALL') if material.node_tree else None
    if out is None or not out.inputs["Surface"].is_linked:
        return None
    shader = out.inputs["Surface"].links[0].from_node
    for name in (INPUT_BASE_COLOR, "Color"):
        sock = shader.inputs.get(name)
        if sock is not None and not sock.is_linked and getattr(sock, "type", "") == 'RGBA':
            return tuple(sock.default_value)
    return None


def add_movable_diffuse_node(material):
    """Add a "VS Movable Diffuse" group node to ``material`` and connect it to the Surface of the
    active Material Output (created if missing), replacing the previous surface link. The previous
    shader stays in the tree, unlinked; its unlinked base colour is copied. Returns the node."""
    group = ensure_node_group()
    material.use_nodes = True
    tree = material.node_tree
    out = tree.get_output_node('ALL')
    if out is None:
        out = tree.nodes.new("ShaderNodeOutputMaterial")
        out.location = (300, 0)
    color = _surface_color(material)
    node = tree.nodes.new("ShaderNodeGroup")
    node.node_tree = group
    node.label = GROUP_NAME
    node.location = (out.location.x - 250, out.location.y - 200)
    if color is not None:
        node.inputs[INPUT_BASE_COLOR].default_value = color
    node.inputs[INPUT_SH_SCALE].default_value = DEFAULT_SH_SCALE
    node.inputs[INPUT_AMBIENT].default_value = DEFAULT_AMBIENT
    for link in list(out.inputs["Surface"].links):
        tree.links.remove(link)
    tree.links.new(node.outputs[OUTPUT_BSDF], out.inputs["Surface"])
    for n in tree.nodes:
        n.select = False
    node.select = True
    tree.nodes.active = node
    return node


def _target_material(context):
    """(material or None, object or None): the shader editor's material, else the active
    object's active material."""
    space = getattr(context, "space_data", None)
    if getattr(space, "type", "") == 'NODE_EDITOR' and getattr(space, "tree_type", "") == "ShaderNodeTree":
        if isinstance(space.id, bpy.types.Material):
            return space.id, context.object
    ob = context.object
    if ob is None or ob.type not in _MATERIAL_OBJECTS:
        return None, None
    return ob.active_material, ob


class SCHNEE_OT_add_movable_diffuse(bpy.types.Operator):
    """Make the active material "VS Movable Diffuse" (the engine's SH-lit diffuse with SH Scale and
    Ambient Term): adds the group node wired to the Material Output, or a new material when the
    object has none"""
    bl_idname = "schnee.add_movable_diffuse"
    bl_label = "VS Movable Diffuse"
    bl_options = {'REGISTER', 'UNDO'}

    @classmethod
    def poll(cls, context):
        material, ob = _target_material(context)
        return material is not None or ob is not None

    def execute(self, context):
        material, ob = _target_material(context)
        if material is None:
            material = make_movable_diffuse_material(f"{ob.name} Movable Diffuse")
            if ob.material_slots and ob.active_material_index < len(ob.material_slots):
                ob.material_slots[ob.active_material_index].material = material
            else:
                ob.data.materials.append(material)
                ob.active_material_index = len(ob.material_slots) - 1
            self.report({'INFO'}, f"New material '{material.name}' on '{ob.name}'")
            return {'FINISHED'}
        add_movable_diffuse_node(material)
        self.report({'INFO'}, f"'{material.name}' now uses {GROUP_NAME}")
        return {'FINISHED'}


def draw_add_menu(self, context):
    """Shader editor > Add menu entry (appended to NODE_MT_add; other node trees see nothing)."""
    if getattr(context.space_data, "tree_type", "") != "ShaderNodeTree":
        return
    layout = self.layout
    layout.separator()
    layout.operator(SCHNEE_OT_add_movable_diffuse.bl_idname, icon='NODE_MATERIAL')


def register():
    # The node group itself lives in .blend data (ensure_node_group); only the operator and the
    # Add-menu entry are registered.
    bpy.utils.register_class(SCHNEE_OT_add_movable_diffuse)
    bpy.types.NODE_MT_add.append(draw_add_menu)


def unregister():
    bpy.types.NODE_MT_add.remove(draw_add_menu)
    bpy.utils.unregister_class(SCHNEE_OT_add_movable_diffuse)
