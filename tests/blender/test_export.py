"""glTF export of probe grids and materials (issue 4, DESIGN.md §5), in real headless Blender.

One Blender launch builds a scene and exports it four ways (tests/blender/scripts/export_scene.py),
one more re-imports the results with Blender's own importer; the Khronos validator (node) checks
each file. Expected values come from what this test wrote with the native writer, so an entry
that merely repeats a wrong reader would still fail. Runtime here: 3-7 s in all.
"""
import importlib
import json
import shutil
import struct
import subprocess
from pathlib import Path

import numpy as np
import pytest

from conftest import REPO, run_blender

SCRIPTS = Path(__file__).resolve().parent / "scripts"
VALIDATOR = REPO / "tests" / "tools" / "validate_gltf.mjs"
ENGINE_EXT = "VULKAN_SCHNEE_engine_properties"
MATERIAL_EXT = "VULKAN_SCHNEE_materials"

# name -> (dims, origin, spacing, probe count, default SH scale, default ambient). Origins and
# spacings that are not exact in float32 (0.1, 0.3) check that the JSON repeats the header value.
GRIDS = {
    "a_room": ((2, 2, 2), (0.1, 0.2, 0.3), 0.25, 8, 1.0, 0.1),
    "b_hall": ((3, 2, 4), (-1.5, 0.0, -2.25), 0.5, 20, 0.75, 0.05),
    "y_rotated": ((2, 1, 3), (1.0, 2.0, 3.0), 1.0, 6, 1.0, 0.1),
    "z_last": ((1, 1, 1), (7.0, -3.5, 11.0), 2.0, 1, 1.0, 0.1),
}
# Version 2 files may carry a rotated grid and a higher band: name -> (max band, grid axes rows).
# This one is turned 90° about engine +Y (grid X = -Z, grid Z = +X).
V2 = {"y_rotated": (3, ((0.0, 0.0, -1.0), (0.0, 1.0, 0.0), (1.0, 0.0, 0.0)))}
IDENTITY = [[1, 0, 0], [0, 1, 0], [0, 0, 1]]
CORRUPT = ("c_bad_magic", "d_bad_grid", "e_truncated")
# Material name -> (shScale, ambientTerm, base colour), as export_scene.py builds them.
MATERIALS = {
    "MovA": (0.5, 0.25, (0.8, 0.2, 0.1, 1.0)),
    "MovB": (1.0, 0.1, (0.8, 0.8, 0.8, 1.0)),  # the node group's defaults
    "MovC": (2.0, 0.0, (0.3, 0.6, 0.9, 1.0)),
}
VOLUME_OBJECTS = {"VolumeA", "VolumeB"}


def _native():
    try:
        importlib.import_module("schnee_probes._schnee_native")
    except ImportError as exc:
        pytest.skip(f"the native module _schnee_native is not built ({exc}); "
                    f"build it with scripts/build.sh to run the export tests")
    from schnee_probes import native
    return native


def _write_grids(native, folder):
    folder.mkdir(parents=True)
    rng = np.random.default_rng(4)
    for name, (dims, origin, spacing, count, scale, ambient) in GRIDS.items():
        cells = dims[0] * dims[1] * dims[2]
        grid = np.full(cells, -1, dtype=np.int32)
        grid[rng.permutation(cells)[:count]] = np.arange(count, dtype=np.int32)
        band, axes = V2.get(name, (2, None))
        coeffs = rng.uniform(-1.0, 1.0, size=(count, (band + 1) ** 2, 3)).astype(np.float32)
        coeffs[:, 0, :] = np.abs(coeffs[:, 0, :]) + 1.0
        version = native.write_shprobe(str(folder / f"{name}.shprobe"), coeffs, grid, dims, origin,
                                       spacing, default_sh_scale=scale, default_ambient=ambient,
                                       grid_axes=None if axes is None else np.array(axes))
        assert version == (2 if name in V2 else 1)
    good = (folder / "b_hall.shprobe").read_bytes()
    (folder / "c_bad_magic.shprobe").write_bytes(b"XXXX" + good[4:])
    (folder / "e_truncated.shprobe").write_bytes(good[: len(good) - 7])
    # A sound header over a bad body: grid cell 0 names probe 999 of 20 (DESIGN.md §4 rejects it).
    bad_grid = bytearray(good)
    struct.pack_into("<i", bad_grid, 48 + 20 * 160, 999)
    (folder / "d_bad_grid.shprobe").write_bytes(bytes(bad_grid))
    (folder / "notes.txt").write_text("not a probe file")


@pytest.fixture(scope="module")
def exported(tmp_path_factory):
    native = _native()
    work = tmp_path_factory.mktemp("export")
    _write_grids(native, work / "scene" / "sh_coeffs")
    proc = run_blender(SCRIPTS / "export_scene.py", work, timeout=300)
    result = json.loads((work / "result.json").read_text())
    return {"work": work, "native": native, "log": proc.stdout + proc.stderr, "result": result}


def load_gltf_json(path):
    """The JSON of a .gltf, or of the JSON chunk of a .glb (glTF 2.0 §4.4)."""
    data = Path(path).read_bytes()
    if data[:4] == b"glTF":
        magic, version, length = struct.unpack_from("<4sII", data, 0)
        assert version == 2 and length == len(data), "GLB header does not match the file"
        chunk_len, chunk_type = struct.unpack_from("<I4s", data, 12)
        assert chunk_type == b"JSON"
        return json.loads(data[20:20 + chunk_len])
    return json.loads(data)


OUTPUTS = {"gltf": "out_gltf/scene.gltf", "glb": "out_glb/scene.glb"}


@pytest.mark.parametrize("fmt", sorted(OUTPUTS))
def test_probe_grids_repeat_the_headers_in_file_name_order(exported, fmt):
    doc = load_gltf_json(exported["work"] / OUTPUTS[fmt])
    assert ENGINE_EXT in doc["extensionsUsed"]
    assert ENGINE_EXT not in doc.get("extensionsRequired", [])
    assert MATERIAL_EXT not in doc.get("extensionsRequired", [])
    entries = doc["scenes"][doc.get("scene", 0)]["extensions"][ENGINE_EXT]["shProbeGrids"]
    # Sorted by file name; the two corrupt files are left out.
    assert [e["name"] for e in entries] == sorted(GRIDS)
    src = exported["work"] / "scene" / "sh_coeffs"
    for entry in entries:
        dims, origin, spacing, count, _, _ = GRIDS[entry["name"]]
        header = exported["native"].read_shprobe_header(str(src / f"{entry['name']}.shprobe"))
        assert entry["uri"] == f"sh_coeffs/{entry['name']}.shprobe"
        # Expected: the values written above; the header must agree with them too.
        assert entry["probeCount"] == count == header["probe_count"]
        band, axes = V2.get(entry["name"], (2, IDENTITY))
        assert entry["maxBand"] == band == header["max_band"]
        assert entry["gridDims"] == list(dims) == list(header["grid_dims"])
        # float32 in the file: equality after rounding the JSON number back to float32.
        np.testing.assert_array_equal(np.float32(entry["gridOrigin"]), np.float32(origin))
        np.testing.assert_array_equal(np.float32(entry["gridOrigin"]), np.float32(header["grid_origin"]))
        assert np.float32(entry["gridSpacing"]) == np.float32(spacing) == np.float32(header["grid_spacing"])
        assert entry["gridAxes"] == [list(row) for row in axes]


@pytest.mark.parametrize("fmt", sorted(OUTPUTS))
def test_materials_carry_sh_settings_and_base_color(exported, fmt):
    doc = load_gltf_json(exported["work"] / OUTPUTS[fmt])
    assert MATERIAL_EXT in doc["extensionsUsed"]
    by_name = {m["name"]: m for m in doc["materials"]}
    for name, (scale, ambient, color) in MATERIALS.items():
        ext = by_name[name]["extensions"][MATERIAL_EXT]
        # Node socket values are float32: compare after rounding to float32.
        assert np.float32(ext["shScale"]) == np.float32(scale), name
        assert np.float32(ext["ambientTerm"]) == np.float32(ambient), name
        assert set(ext) == {"shScale", "ambientTerm"}
        pbr = by_name[name]["pbrMetallicRoughness"]
        np.testing.assert_allclose(pbr["baseColorFactor"], color, atol=1e-6, err_msg=name)
        assert pbr["metallicFactor"] == 0, name  # diffuse; glTF's default would be 1
    # An image on the group's Base Color is exported as the base colour texture.
    tex = by_name["MovTex"]
    assert tex["extensions"][MATERIAL_EXT] == {"shScale": 0.75, "ambientTerm": 0.5}
    texture = doc["textures"][tex["pbrMetallicRoughness"]["baseColorTexture"]["index"]]
    assert doc["images"][texture["source"]]["name"] == "checker"
    assert "baseColorFactor" not in tex["pbrMetallicRoughness"]
    # A plain Principled material gets no Schnee extension.
    assert MATERIAL_EXT not in by_name["Plain"].get("extensions", {})
    # probeMode from the material's custom property, on a plain and on a movable material; a value
    # outside off/object/pixel is left out (and warned about, see the warnings test).
    assert by_name["PlainPixel"]["extensions"][MATERIAL_EXT] == {"probeMode": "pixel"}
    assert by_name["MovObject"]["extensions"][MATERIAL_EXT] == {
        "shScale": 1.5, "ambientTerm": 0.2, "probeMode": "object"}  # shortest float32 repr
    assert MATERIAL_EXT not in by_name["PlainBadMode"].get("extensions", {})


@pytest.mark.parametrize("fmt", sorted(OUTPUTS) + ["off"])
def test_probe_volumes_are_not_exported(exported, fmt):
    path = {"off": "out_off/scene.gltf", **OUTPUTS}[fmt]
    doc = load_gltf_json(exported["work"] / path)
    names = {n.get("name") for n in doc["nodes"]}
    assert not names & VOLUME_OBJECTS
    assert {"MovingA", "MovingB", "MovingC", "Static"} <= names
    # The volume's child is not a volume: kept, re-parented to the scene root.
    assert "VolumeChildProp" in names
    child = [i for i, n in enumerate(doc["nodes"]) if n["name"] == "VolumeChildProp"][0]
    assert child in doc["scenes"][0]["nodes"]
    assert "VolumeOnlyMat" not in {m["name"] for m in doc["materials"]}
    if exported["result"]["custom_volume_setting"]:
        # Scene.schnee_probes.volume_collection is honoured: "ProbeVolumes" is then ordinary.
        assert exported["result"]["volume_collection"] == "BakeVolumes"
        assert "NotAVolume" in names


@pytest.mark.parametrize("fmt", sorted(OUTPUTS))
def test_shprobe_files_are_copied_byte_identical(exported, fmt):
    src = exported["work"] / "scene" / "sh_coeffs"
    dst = (exported["work"] / OUTPUTS[fmt]).parent / "sh_coeffs"
    assert sorted(p.name for p in dst.iterdir()) == sorted(f"{n}.shprobe" for n in GRIDS)
    for name in GRIDS:
        assert (dst / f"{name}.shprobe").read_bytes() == (src / f"{name}.shprobe").read_bytes()


def test_corrupt_files_warn_and_are_left_out(exported):
    log = exported["log"]
    for name in CORRUPT:
        warning = [line for line in log.splitlines() if "WARNING" in line and f"{name}.shprobe" in line]
        assert warning, f"no warning for {name}.shprobe in Blender's output"
    # The warning names the file and the reader's reason; once per export (4 exports).
    assert sum(1 for line in log.splitlines()
               if "| WARNING: Schnee glTF export: skipped" in line and "c_bad_magic" in line) == 4
    assert "notes.txt" not in log  # other files in sh_coeffs/ are ignored silently


def test_checkbox_off_writes_no_extension_and_copies_nothing(exported):
    result = exported["result"]
    assert result["checkbox_default"] is True
    assert result["extension_found"] and result["register_panel_found"]
    assert result["panel_registered"] and result["panel_unregistered"]
    out = exported["work"] / "out_off"
    text = (out / "scene.gltf").read_text()
    assert "VULKAN_SCHNEE" not in text
    assert not (out / "sh_coeffs").exists()
    assert sorted(p.name for p in out.iterdir()) == ["checker.png", "scene.bin", "scene.gltf"]
    # The base colour of the node group is still right: it is plain glTF, not an extension.
    mat = {m["name"]: m for m in json.loads(text)["materials"]}["MovA"]
    np.testing.assert_allclose(mat["pbrMetallicRoughness"]["baseColorFactor"],
                               MATERIALS["MovA"][2], atol=1e-6)


def test_export_next_to_the_blend(exported):
    # sh_coeffs/ of the export is the source folder itself: nothing to copy, nothing may break.
    doc = load_gltf_json(exported["work"] / "scene" / "beside.gltf")
    entries = doc["scenes"][0]["extensions"][ENGINE_EXT]["shProbeGrids"]
    assert [e["name"] for e in entries] == sorted(GRIDS)
    src = exported["work"] / "scene" / "sh_coeffs"
    assert {p.name for p in src.iterdir()} >= {f"{n}.shprobe" for n in list(GRIDS) + list(CORRUPT)}
    assert not list(src.glob(".tmp-*"))


def test_hooks_are_idempotent(exported):
    idem = exported["result"]["idem"]
    assert idem["scene_same"] and idem["material_same"]
    assert idem["scene_extension_keys"] == [ENGINE_EXT]
    assert idem["material_extension_keys"] == [MATERIAL_EXT]
    assert [e["name"] for e in idem["scene_first"]["shProbeGrids"]] == sorted(GRIDS)
    assert idem["material_first"] == {"shScale": 0.5, "ambientTerm": 0.25}
    assert idem["required"] == [False, False]
    # One warning per corrupt file although the scene hook ran twice.
    assert len(idem["warnings"]) == len(CORRUPT)
    assert exported["result"]["group_count_after_three_materials"] == 1
    assert exported["result"]["ensure_node_group_idempotent"] is True


def _validator_available():
    if shutil.which("node") is None:
        pytest.skip("node is not installed (scripts/deps.sh installs nodejs)")
    if not (REPO / "node_modules" / "gltf-validator").is_dir():
        pytest.skip("node_modules/gltf-validator missing (scripts/deps.sh runs npm install)")


@pytest.mark.parametrize("path", sorted(OUTPUTS.values()) + ["out_off/scene.gltf", "scene/beside.gltf"])
def test_khronos_validator_reports_no_errors(exported, path):
    _validator_available()
    proc = subprocess.run(["node", str(VALIDATOR), str(exported["work"] / path)],
                          capture_output=True, text=True, timeout=120)
    assert proc.returncode in (0, 1), proc.stderr
    report = json.loads(proc.stdout)
    errors = [m for m in report["issues"]["messages"] if m["severity"] == 0]
    assert report["issues"]["numErrors"] == 0, errors
    assert proc.returncode == 0


def test_validator_script_catches_errors(tmp_path):
    # The check above must be able to fail: a glTF whose buffer is missing is an error.
    _validator_available()
    bad = tmp_path / "bad.gltf"
    bad.write_text(json.dumps({"asset": {"version": "2.0"},
                               "buffers": [{"uri": "missing.bin", "byteLength": 4}]}))
    proc = subprocess.run(["node", str(VALIDATOR), str(bad)], capture_output=True, text=True,
                          timeout=120)
    assert proc.returncode == 1
    assert json.loads(proc.stdout)["issues"]["numErrors"] >= 1


def test_blender_reimports_the_exports(exported, tmp_path):
    files = [str(exported["work"] / p) for p in sorted(OUTPUTS.values())]
    out = tmp_path / "reimport.json"
    run_blender(SCRIPTS / "export_reimport.py", out, *files, timeout=300)
    results = json.loads(out.read_text())
    for path in files:
        res = results[path]
        assert "error" not in res, res
        assert res["status"] == ["FINISHED"]
        assert {"MovingA", "MovingB", "MovingC", "Static", "VolumeChildProp"} <= set(res["objects"])
        assert not set(res["objects"]) & VOLUME_OBJECTS
        np.testing.assert_allclose(res["materials"]["MovA"], MATERIALS["MovA"][2], atol=1e-6)


@pytest.mark.parametrize("fmt", sorted(OUTPUTS))
def test_materials_carry_the_probe_representation(exported, fmt):
    # docs/ambient-cube.md §4 "glTF": the custom property schnee_probe_representation becomes
    # VULKAN_SCHNEE_materials.probeRepresentation next to probeMode; an unknown value is left out.
    doc = load_gltf_json(exported["work"] / OUTPUTS[fmt])
    by_name = {m["name"]: m for m in doc["materials"]}
    assert by_name["MovCube"]["extensions"][MATERIAL_EXT] == {
        "shScale": 1.25, "ambientTerm": 0.0, "probeMode": "pixel", "probeRepresentation": "ambientCube"}
    assert by_name["PlainSH"]["extensions"][MATERIAL_EXT] == {"probeRepresentation": "sh"}
    assert MATERIAL_EXT not in by_name["PlainBadRep"].get("extensions", {})
    # Materials without the property say nothing (the engine's default is sh).
    assert all("probeRepresentation" not in m.get("extensions", {}).get(MATERIAL_EXT, {})
               for name, m in by_name.items() if name not in ("MovCube", "PlainSH"))
    assert MATERIAL_EXT in doc["extensionsUsed"] and MATERIAL_EXT not in doc.get("extensionsRequired", [])


def test_probe_representation_hook_is_idempotent(exported):
    idem = exported["result"]["idem_cube"]
    assert idem["same"] and idem["keys"] == [MATERIAL_EXT]
    assert idem["first"]["probeRepresentation"] == "ambientCube"


def test_unknown_probe_representation_is_warned_about(exported):
    lines = [line for line in exported["log"].splitlines() if "WARNING" in line and "PlainBadRep" in line]
    assert lines, "no warning for the material with schnee_probe_representation = 'cube'"
    assert "schnee_probe_representation = 'cube' is not one of sh, ambientCube" in lines[0]


def test_engine_loads_the_exported_representation(exported, tmp_path):
    # The engine parses the exported field (a value it refuses would exit 1 naming the material;
    # tests/engine/test_engine_ambient_cube.py checks the shading itself).
    view = REPO / "build" / "schnee-view"
    if not view.exists():
        pytest.skip("build/schnee-view is not built")
    out = tmp_path / "x.exr"
    proc = subprocess.run([str(view), str(exported["work"] / OUTPUTS["gltf"]), "--headless", "--output", str(out),
                           "--width", "32", "--height", "32"], capture_output=True, text=True, timeout=120)
    assert proc.returncode == 0, proc.stderr
    assert out.stat().st_size > 0


def test_unknown_probe_mode_is_warned_about(exported):
    lines = [line for line in exported["log"].splitlines()
             if "WARNING" in line and "PlainBadMode" in line]
    assert lines, "no warning for the material with schnee_probe_mode = 'everywhere'"
    assert "'everywhere' is not one of off, object, pixel" in lines[0]
