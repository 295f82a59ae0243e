"""Headless Blender: import each given .gltf/.glb with Blender's importer (a real client).

    blender -b --factory-startup -P export_reimport.py -- OUT.json FILE...

Writes OUT.json: {FILE: {"objects": [...], "materials": {name: [r, g, b, a]}} or {"error": "..."}}.
Each file is imported into a fresh, empty session so nothing leaks between them.
"""
import json
import sys

import bpy
import numpy as np

# Blender 3.4's importer uses np.bool, which numpy 1.24 (Debian 12) removed; the fix
# (KhronosGroup/glTF-Blender-IO#1831) shipped in 3.5 and was not backported (#1844). Restore the
# alias exactly as numpy < 1.24 had it (np.bool was the builtin bool) in this process only.
if "bool" not in np.__dict__:
    np.bool = bool

argv = sys.argv[sys.argv.index("--") + 1:]
out_path, files = argv[0], argv[1:]
results = {}
for path in files:
    bpy.ops.wm.read_factory_settings(use_empty=True)
    try:
        status = bpy.ops.import_scene.gltf(filepath=path)
    except Exception as exc:  # noqa: BLE001 - the test wants the message, not a traceback
        results[path] = {"error": str(exc)}
        continue
    materials = {}
    for mat in bpy.data.materials:
        bsdf = mat.node_tree.nodes.get("Principled BSDF") if mat.use_nodes else None
        if bsdf is not None:
            materials[mat.name] = list(bsdf.inputs["Base Color"].default_value)
    results[path] = {
        "status": sorted(status),
        "objects": sorted(o.name for o in bpy.data.objects),
        "meshes": sum(1 for o in bpy.data.objects if o.type == 'MESH'),
        "materials": materials,
    }
with open(out_path, "w") as f:
    json.dump(results, f, indent=2)
