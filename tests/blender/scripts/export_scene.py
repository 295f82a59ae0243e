"""Headless Blender: build a small scene, export it in every configuration the tests check.

    blender -b --factory-startup -P export_scene.py -- WORKDIR

WORKDIR/scene/sh_coeffs/*.shprobe must exist (the test writes them with the native writer).
Writes:
    WORKDIR/scene/scene.blend
    WORKDIR/out_gltf/scene.gltf      checkbox on, .gltf + .bin
    WORKDIR/out_glb/scene.glb        checkbox on, .glb
    WORKDIR/out_off/scene.gltf       checkbox off
    WORKDIR/scene/beside.gltf        exported next to the .blend (sh_coeffs/ is the source itself)
    WORKDIR/result.json              facts only Blender can see (hook idempotence, warnings, ...)
"""
import json
import os
import sys

import addon_utils
import bpy

work = os.path.abspath(sys.argv[sys.argv.index("--") + 1])
scene_dir = os.path.join(work, "scene")

# The add-on must be *enabled* (in preferences) for the exporter to find its user extension.
addon_utils.enable("io_scene_gltf2", default_set=True)
mod = addon_utils.enable("schnee_probes", default_set=True)
assert mod is not None, "schnee_probes could not be enabled"
import schnee_probes  # noqa: E402
from schnee_probes import gltf_export, nodes  # noqa: E402

# ---- scene: two movable-diffuse materials, one plain Principled, two probe volumes -----------
for obj in list(bpy.data.objects):
    bpy.data.objects.remove(obj)
scene = bpy.context.scene


def add_cube(name, location, collection, material=None, size=1.0):
    mesh = bpy.data.meshes.new(name)
    s = size / 2.0
    verts = [(x * s, y * s, z * s) for x in (-1, 1) for y in (-1, 1) for z in (-1, 1)]
    faces = [(0, 1, 3, 2), (4, 6, 7, 5), (0, 4, 5, 1), (2, 3, 7, 6), (0, 2, 6, 4), (1, 5, 7, 3)]
    mesh.from_pydata(verts, [], faces)
    mesh.uv_layers.new(name="UVMap")  # a texture needs TEXCOORD_0 (the validator checks)
    mesh.update()
    if material is not None:
        mesh.materials.append(material)
    obj = bpy.data.objects.new(name, mesh)
    obj.location = location
    collection.objects.link(obj)
    return obj


mat_a = nodes.make_movable_diffuse_material("MovA", base_color=(0.8, 0.2, 0.1, 1.0), sh_scale=0.5,
                                            ambient=0.25)
mat_b = nodes.make_movable_diffuse_material("MovB")  # the defaults: 1.0 / 0.1
mat_c = nodes.make_movable_diffuse_material("MovC", base_color=(0.3, 0.6, 0.9), sh_scale=2.0,
                                            ambient=0.0)
# An image on the group's Base Color must become glTF's baseColorTexture.
mat_tex = nodes.make_movable_diffuse_material("MovTex", sh_scale=0.75, ambient=0.5)
image = bpy.data.images.new("checker", 8, 8)
image.generated_type = 'COLOR_GRID'
tex_node = mat_tex.node_tree.nodes.new("ShaderNodeTexImage")
tex_node.image = image
mat_tex.node_tree.links.new(tex_node.outputs["Color"],
                            mat_tex.node_tree.nodes[nodes.GROUP_NAME].inputs[nodes.INPUT_BASE_COLOR])
plain = bpy.data.materials.new("Plain")
plain.use_nodes = True
plain.node_tree.nodes["Principled BSDF"].inputs["Base Color"].default_value = (0.1, 0.7, 0.2, 1.0)

# probeMode comes from a custom property on any material (docs/export.md): a plain material
# carrying it, a movable one carrying it, and one with a value the engine does not know.
plain_pixel = plain.copy()
plain_pixel.name = "PlainPixel"
plain_pixel["schnee_probe_mode"] = "pixel"
mov_object = nodes.make_movable_diffuse_material("MovObject", sh_scale=1.5, ambient=0.2)
mov_object["schnee_probe_mode"] = "object"
plain_bad = plain.copy()
plain_bad.name = "PlainBadMode"
plain_bad["schnee_probe_mode"] = "everywhere"
# probeRepresentation likewise (docs/ambient-cube.md §4): a movable material shaded per pixel with
# the ambient cube, a plain one asking for SH explicitly, and an unknown value.
mov_cube = nodes.make_movable_diffuse_material("MovCube", sh_scale=1.25, ambient=0.0)
mov_cube["schnee_probe_mode"] = "pixel"
mov_cube["schnee_probe_representation"] = "ambientCube"
plain_sh = plain.copy()
plain_sh.name = "PlainSH"
plain_sh["schnee_probe_representation"] = "sh"
plain_bad_rep = plain.copy()
plain_bad_rep.name = "PlainBadRep"
plain_bad_rep["schnee_probe_representation"] = "cube"

root = scene.collection
add_cube("Wall", (4, 4, 0), root, plain_pixel)
add_cube("MovingObject", (-4, 4, 0), root, mov_object)
add_cube("BadMode", (4, -4, 0), root, plain_bad)
add_cube("CubeLit", (-4, -4, 0), root, mov_cube)
add_cube("ShLit", (6, 4, 0), root, plain_sh)
add_cube("BadRep", (6, -4, 0), root, plain_bad_rep)
add_cube("MovingA", (2, 0, 0), root, mat_a)
add_cube("MovingB", (-2, 0, 0), root, mat_b)
add_cube("MovingC", (0, 3, 0), root, mat_c)
add_cube("Static", (0, 0, -1), root, plain, size=4.0)
add_cube("Textured", (0, -3, 0), root, mat_tex)

# With the add-on's settings registered, use a non-default collection name, and give the default
# name to an ordinary collection whose object must then be exported.
custom_volume_setting = hasattr(scene, "schnee_probes")
if custom_volume_setting:
    scene.schnee_probes.volume_collection = "BakeVolumes"
    decoy = bpy.data.collections.new(gltf_export.DEFAULT_VOLUME_COLLECTION)
    root.children.link(decoy)
    add_cube("NotAVolume", (4, 0, 0), decoy, mat_b, size=0.5)
volume_name = gltf_export.volume_collection_name(scene)
volumes = bpy.data.collections.new(volume_name)
root.children.link(volumes)
nested = bpy.data.collections.new("InnerVolumes")
volumes.children.link(nested)
vol_mat = bpy.data.materials.new("VolumeOnlyMat")
vol_a = add_cube("VolumeA", (0, 0, 1), volumes, vol_mat, size=6.0)
add_cube("VolumeB", (0, 0, 5), nested, vol_mat, size=2.0)
# A child of a volume that is not itself a volume: it must survive, re-parented to the root.
child = add_cube("VolumeChildProp", (0, 0, 0), root, mat_b, size=0.5)
child.parent = vol_a

os.makedirs(scene_dir, exist_ok=True)
bpy.ops.wm.save_as_mainfile(filepath=os.path.join(scene_dir, "scene.blend"))

# The 3.4 exporter calls register_panel() when its dialog opens and the returned function on
# unregister; the checkbox panel must come and go with it.
unregister_panel = schnee_probes.register_panel()
panel_registered = hasattr(bpy.types, "SCHNEE_PT_gltf_export")
schnee_probes.register_panel()  # a second dialog: no error
unregister_panel()
panel_unregistered = not hasattr(bpy.types, "SCHNEE_PT_gltf_export")

result = {
    "panel_registered": panel_registered,
    "panel_unregistered": panel_unregistered,
    "extension_found": hasattr(schnee_probes, "glTF2ExportUserExtension"),
    "register_panel_found": callable(getattr(schnee_probes, "register_panel", None)),
    "volume_collection": volume_name,
    "custom_volume_setting": custom_volume_setting,
    "group_count_after_three_materials": sum(
        1 for g in bpy.data.node_groups if nodes.is_movable_diffuse_tree(g)),
    "ensure_node_group_idempotent": nodes.ensure_node_group() == nodes.ensure_node_group(),
}


def export(path, fmt, enabled=True):
    scene.schnee_gltf_export.enabled = enabled
    os.makedirs(os.path.dirname(path), exist_ok=True)
    bpy.ops.export_scene.gltf(filepath=path, export_format=fmt)
    scene.schnee_gltf_export.enabled = True


print("SCHNEE-TEST export gltf", flush=True)
export(os.path.join(work, "out_gltf", "scene.gltf"), "GLTF_SEPARATE")
print("SCHNEE-TEST export glb", flush=True)
export(os.path.join(work, "out_glb", "scene.glb"), "GLB")
print("SCHNEE-TEST export off", flush=True)
export(os.path.join(work, "out_off", "scene.gltf"), "GLTF_SEPARATE", enabled=False)
print("SCHNEE-TEST export beside", flush=True)
export(os.path.join(scene_dir, "beside.gltf"), "GLTF_SEPARATE")
result["checkbox_default"] = type(scene.schnee_gltf_export).bl_rna.properties["enabled"].default

# ---- hook idempotence, called directly (the exporter may call a hook twice) -------------------
from io_scene_gltf2.io.com import gltf2_io  # noqa: E402

ext = gltf_export.glTF2ExportUserExtension()
settings = {"gltf_filepath": os.path.join(work, "out_idem", "x.gltf")}
os.makedirs(os.path.dirname(settings["gltf_filepath"]), exist_ok=True)
gscene = gltf2_io.Scene(extensions=None, extras=None, name="S", nodes=[])
ext.gather_scene_hook(gscene, scene, settings)
first = json.dumps(gscene.extensions[gltf_export.EXT_ENGINE].extension, sort_keys=True)
ext.gather_scene_hook(gscene, scene, settings)
second = json.dumps(gscene.extensions[gltf_export.EXT_ENGINE].extension, sort_keys=True)
gmat = gltf2_io.Material(alpha_cutoff=None, alpha_mode=None, double_sided=None,
                         emissive_factor=None, emissive_texture=None, extensions=None, extras=None,
                         name="MovA", normal_texture=None, occlusion_texture=None,
                         pbr_metallic_roughness=None)
ext.gather_material_hook(gmat, mat_a, settings)
mat_first = (json.dumps(gmat.extensions[gltf_export.EXT_MATERIALS].extension, sort_keys=True),
             list(gmat.pbr_metallic_roughness.base_color_factor))
ext.gather_material_hook(gmat, mat_a, settings)
mat_second = (json.dumps(gmat.extensions[gltf_export.EXT_MATERIALS].extension, sort_keys=True),
              list(gmat.pbr_metallic_roughness.base_color_factor))
gcube = gltf2_io.Material(alpha_cutoff=None, alpha_mode=None, double_sided=None,
                          emissive_factor=None, emissive_texture=None, extensions=None, extras=None,
                          name="MovCube", normal_texture=None, occlusion_texture=None,
                          pbr_metallic_roughness=None)
ext.gather_material_hook(gcube, mov_cube, settings)
cube_first = json.dumps(gcube.extensions[gltf_export.EXT_MATERIALS].extension, sort_keys=True)
ext.gather_material_hook(gcube, mov_cube, settings)
cube_second = json.dumps(gcube.extensions[gltf_export.EXT_MATERIALS].extension, sort_keys=True)
result["idem_cube"] = {"first": json.loads(cube_first), "same": cube_first == cube_second,
                       "keys": sorted(gcube.extensions)}
result["idem"] = {
    "scene_first": json.loads(first), "scene_same": first == second,
    "scene_extension_keys": sorted(gscene.extensions),
    "material_first": json.loads(mat_first[0]), "material_same": mat_first == mat_second,
    "material_extension_keys": sorted(gmat.extensions),
    "warnings": settings.get("schnee_warnings", []),
    "required": [e.required for e in list(gscene.extensions.values()) + list(gmat.extensions.values())],
}

with open(os.path.join(work, "result.json"), "w") as f:
    json.dump(result, f, indent=2)
print("SCHNEE-TEST done", flush=True)
