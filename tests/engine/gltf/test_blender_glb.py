"""The real client: Blender 3.4's glTF exporter writes the factory-startup scene (cube, camera, point
light) as .glb and as .gltf + .bin; the engine's loader (through build/engine/gltf/sv-gltf-dump)
must read both, identically, with the values Blender put in. One headless Blender run (~5-15 s)."""
import json
import math
import shutil
import subprocess
import textwrap

import pytest

from conftest import BUILD_DIR

DUMP = BUILD_DIR / "engine" / "gltf" / "sv-gltf-dump"

EXPORT_SCRIPT = textwrap.dedent("""
    import sys
    import bpy
    out = sys.argv[sys.argv.index("--") + 1]
    scene = bpy.context.scene
    scene.render.resolution_x, scene.render.resolution_y = 1920, 1080
    common = dict(export_cameras=True, export_lights=True, use_selection=False)
    bpy.ops.export_scene.gltf(filepath=out + "/cube.glb", export_format="GLB", **common)
    bpy.ops.export_scene.gltf(filepath=out + "/cube sep.gltf", export_format="GLTF_SEPARATE", **common)
""")


def dump(path):
    proc = subprocess.run([str(DUMP), str(path)], capture_output=True, text=True, timeout=60)
    assert proc.returncode == 0, proc.stderr
    return json.loads(proc.stdout)


@pytest.fixture(scope="module")
def exported(tmp_path_factory):
    if not DUMP.exists():
        pytest.skip(f"{DUMP} not built (cmake --build build)")
    if shutil.which("blender") is None:
        pytest.skip("blender not installed")
    from conftest import run_blender
    out = tmp_path_factory.mktemp("blender_gltf")
    script = out / "export.py"
    script.write_text(EXPORT_SCRIPT)
    run_blender(script, out, timeout=300)
    return out


def test_blender_default_scene_glb(exported):
    d = dump(exported / "cube.glb")
    assert d["warnings"] == []
    # The default cube: 6 faces x 4 split-normal corners, 12 triangles, normals and UVs exported.
    assert len(d["mesh_instances"]) == 1
    inst = d["mesh_instances"][0]
    assert inst["node_name"] == "Cube"
    prim = d["meshes"][inst["mesh"]]["primitives"][0]
    assert prim["vertices"] == 24 and prim["indices"] == 36
    assert prim["normals"] and not prim["normals_generated"] and prim["texcoords0"]
    # A 2 m cube at the origin: world bounds [-1, 1]^3 (exact in float).
    assert d["scene_aabb_min"] == pytest.approx([-1, -1, -1], abs=1e-6)
    assert d["scene_aabb_max"] == pytest.approx([1, 1, 1], abs=1e-6)
    # Blender's default material "Material": base colour 0.8 grey (Principled BSDF default).
    mat = d["materials"][prim["material"]]
    assert mat["name"] == "Material"
    assert mat["base_color_factor"] == pytest.approx([0.8, 0.8, 0.8, 1.0], abs=1e-6)
    assert not mat["has_schnee"] and mat["sh_scale"] == 1.0 and mat["ambient_term"] == pytest.approx(0.1)
    # Camera at Blender (7.3589, -6.9258, 4.9583) → engine (x, z, -y) (DESIGN.md §2).
    cams = d["cameras"]
    assert len(cams) == 1
    assert cams[0]["world"][12:15] == pytest.approx([7.3589, 4.9583, 6.9258], abs=1e-3)
    # 50 mm lens on a 36 mm sensor fitted horizontally at 16:9: yfov = 2 atan(18/50 / (16/9)).
    assert cams[0]["yfov"] == pytest.approx(2 * math.atan(18 / 50 / (1920 / 1080)), rel=1e-3)
    # Point light at Blender (4.0762, 1.0055, 5.9039) → engine (4.0762, 5.9039, -1.0055).
    lights = d["lights"]
    assert len(lights) == 1 and lights[0]["type"] == 1  # SV_GLTF_LIGHT_POINT
    assert lights[0]["position"] == pytest.approx([4.0762, 5.9039, -1.0055], abs=1e-3)
    assert lights[0]["intensity"] > 0


def test_blender_default_scene_separate_gltf_matches_glb(exported):
    a = dump(exported / "cube.glb")
    b = dump(exported / "cube sep.gltf")
    for key in ("counts", "meshes", "mesh_instances", "scene_aabb_min", "scene_aabb_max", "materials",
                "cameras", "lights", "warnings"):
        assert a[key] == b[key], key
