"""The "VS Movable Diffuse" operator headless: ``blender -b --factory-startup -P addon_nodes_ui.py``.
Runs schnee.add_movable_diffuse on the factory cube (which has a Principled material), on a mesh
without material, and a second time on the cube; emits what the node trees look like after."""
import os
import sys

import bpy

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import addon_common as common  # noqa: E402

import schnee_probes  # noqa: E402
from schnee_probes import nodes  # noqa: E402


def describe(material):
    node = nodes.find_movable_diffuse_node(material)
    out = material.node_tree.get_output_node('ALL')
    surface = out.inputs["Surface"].links
    return {
        "material": material.name,
        "found": node is not None,
        "sh_scale": node.inputs[nodes.INPUT_SH_SCALE].default_value if node else None,
        "ambient": node.inputs[nodes.INPUT_AMBIENT].default_value if node else None,
        "base_color": list(node.inputs[nodes.INPUT_BASE_COLOR].default_value) if node else None,
        "surface_from": surface[0].from_node.name if surface else None,
        "node_name": node.name if node else None,
        "feeds_active_output": bool(node) and nodes.feeds_active_output(node),
        "group_nodes": sum(1 for n in material.node_tree.nodes if n.bl_idname == "ShaderNodeGroup"),
    }


def main():
    schnee_probes.register()
    results = {"menu_registered": nodes.draw_add_menu in bpy.types.NODE_MT_add._dyn_ui_initialize()}
    vl = bpy.context.view_layer
    cube = bpy.data.objects["Cube"]
    principled = cube.active_material.node_tree.nodes["Principled BSDF"]
    principled.inputs["Base Color"].default_value = (0.2, 0.4, 0.6, 1.0)
    vl.objects.active = cube
    results["cube_result"] = sorted(bpy.ops.schnee.add_movable_diffuse())
    results["cube"] = describe(cube.active_material)

    mesh = bpy.data.meshes.new("Bare")
    bare = bpy.data.objects.new("Bare", mesh)
    bpy.context.scene.collection.objects.link(bare)
    vl.objects.active = bare
    results["bare_result"] = sorted(bpy.ops.schnee.add_movable_diffuse())
    results["bare"] = describe(bare.active_material)
    results["bare_slots"] = len(bare.material_slots)

    vl.objects.active = cube
    bpy.ops.schnee.add_movable_diffuse()
    results["cube_again"] = describe(cube.active_material)
    results["group_count"] = sum(1 for g in bpy.data.node_groups if nodes.is_movable_diffuse_tree(g))

    # The camera holds no material: the operator refuses it (poll) instead of failing.
    vl.objects.active = bpy.data.objects["Camera"]
    results["camera_poll"] = bpy.ops.schnee.add_movable_diffuse.poll()
    schnee_probes.unregister()
    results["menu_after_unregister"] = nodes.draw_add_menu in bpy.types.NODE_MT_add._dyn_ui_initialize()
    common.emit(**results)


main()
