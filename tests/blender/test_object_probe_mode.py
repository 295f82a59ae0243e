"""The per-object probe mode end to end (issue 31 item 2): Object.schnee_probe.mode set in Blender,
exported as nodes[i].extensions.VULKAN_SCHNEE_node (docs/export.md "Node"), validated by the Khronos
validator and rendered by schnee-view per object (docs/user-guide.md "Per-object probe mode").

One headless Blender launch (tests/blender/scripts/object_probe_mode.py, about 3 s) and one under
Xvfb (object_probe_mode_ui.py: the panels drawn by Blender itself): four planes sharing one
mesh and one material (custom property schnee_probe_mode "object") with the modes Off, Per Pixel,
as its materials say and Ambient Cube, over a version 1 grid of random probes written here with the
tests' independent numpy writer. The engine's pixels (--no-direct: the lamp, which is there to show
that a node without a mesh gets no field, adds nothing; no sky) are E/π + ambientTerm for the white
material (shScale 1, ambientTerm 0.1), E from tests/engine/scripts/probe_ref.py (numpy, from the
documents).
"""
import json
import os
import shutil
import subprocess
import sys

import numpy as np
import pytest

from conftest import ADDON_DIR, REPO, run_blender

SCRIPTS = REPO / "tests" / "blender" / "scripts"
sys.path.insert(0, str(REPO / "tests" / "engine" / "scripts"))
import probe_ref as ref  # noqa: E402
import scenegen as sg  # noqa: E402
import viewer  # noqa: E402

VALIDATOR = REPO / "tests" / "tools" / "validate_gltf.mjs"
EXT = "VULKAN_SCHNEE_node"
# Engine space (Y-up; Blender (x, y, z) -> (x, z, -y)): 12 x 2 x 3 cells of 1 m under the planes.
ORIGIN, DIMS = (-6.0, 0.0, -1.5), (12, 2, 3)
GRID = np.arange(np.prod(DIMS), dtype=np.int32).reshape(DIMS[2], DIMS[1], DIMS[0])
rng = np.random.default_rng(31)
COEFFS = rng.normal(0.0, 0.3, (GRID.size, 9, 3))
COEFFS[:, 0] = rng.uniform(1.0, 4.0, (GRID.size, 3))
FALLBACK = 0.2   # schnee-view's default fallback radiance: E/π = 0.2
AMBIENT = 0.1    # VULKAN_SCHNEE_materials.ambientTerm's default (the material has no movable node)
UP = np.array([0.0, 1.0, 0.0])
FIELDS = {"OffPlane": {"probeMode": "off", "probeRepresentation": "sh"},
          "PixelPlane": {"probeMode": "pixel", "probeRepresentation": "sh"},
          "MaterialPlane": None,
          "CubePlane": {"probeMode": "object", "probeRepresentation": "ambientCube"}}
CENTRES_X = {"OffPlane": -4.5, "PixelPlane": -1.5, "MaterialPlane": 1.5, "CubePlane": 4.5}


def _results(stdout):
    return [json.loads(line[7:]) for line in stdout.splitlines() if line.startswith("RESULT ")]


@pytest.fixture(scope="module")
def exported(tmp_path_factory):
    work = tmp_path_factory.mktemp("object_probe_mode")
    (work / "scene" / "sh_coeffs").mkdir(parents=True)
    sg.write_shprobe_v1(work / "scene" / "sh_coeffs" / "probes.shprobe", COEFFS, GRID, ORIGIN, 1.0)
    proc = run_blender(SCRIPTS / "object_probe_mode.py", work, timeout=300)
    r = _results(proc.stdout)
    assert r, proc.stdout[-3000:] + proc.stderr[-3000:]
    return {"work": work, "r": r[0], "doc": json.loads((work / "on" / "scene.gltf").read_text()),
            "off": json.loads((work / "off" / "scene.gltf").read_text())}


def test_property_registered_and_kept(exported):
    r = exported["r"]
    everything = {"object_property": True, "object_panel": True, "sidebar_panel": True, "operator": True}
    assert r["enabled"] == r["enabled_again"] == everything
    assert r["disabled"] == {k: False for k in everything}
    chosen = {"OffPlane": "OFF", "PixelPlane": "PIXEL", "MaterialPlane": "MATERIALS", "CubePlane": "AMBIENT_CUBE"}
    assert r["default"] == "MATERIALS"
    assert r["set"] == r["enabled_again_choices"] == r["reopened_choices"] == chosen
    assert r["enum_items"] == ["MATERIALS", "OFF", "OBJECT", "PIXEL", "AMBIENT_CUBE"]
    # Set All Selected Objects: the active and the selected planes, not the lamp (no mesh).
    assert r["set_selected"] == ["FINISHED"]
    assert r["after_set_selected"] == dict(chosen, OffPlane="OBJECT", MaterialPlane="OBJECT", Lamp="PIXEL")
    # Every choice writes values the engine and the material extension know (gltf_export's tables).
    for fields in filter(None, r["choice_fields"].values()):
        assert fields["probeMode"] in r["exporter_modes"]
        assert fields["probeRepresentation"] in r["exporter_representations"]


def test_object_panel_draws_the_choice_and_the_materials(exported):
    r = exported["r"]
    assert r["panel_material"] == [["prop", "mode", "MATERIALS"], ["label", "Shared: Per Object"]]
    assert r["panel_pixel"] == [["prop", "mode", "PIXEL"], ["label", "Replaces its materials' modes for this object"]]
    assert r["panel_poll_lamp"] is False


def test_export_writes_the_node_fields(exported):
    r, doc = exported["r"], exported["doc"]
    assert r["export_on"] == r["export_off"] == ["FINISHED"]
    nodes = {n["name"]: n for n in doc["nodes"]}
    for name, fields in FIELDS.items():
        got = nodes[name].get("extensions", {}).get(EXT)
        assert got == fields, (name, got)
    assert len({nodes[name]["mesh"] for name in FIELDS}) == 1  # one glTF mesh shared by the four nodes
    assert EXT not in nodes["Lamp"].get("extensions", {})       # no mesh, no field
    assert EXT in doc["extensionsUsed"] and EXT not in doc.get("extensionsRequired", [])
    # The material's own property still travels (the node's mode overrides it per node).
    mat = doc["materials"][doc["meshes"][nodes["MaterialPlane"]["mesh"]]["primitives"][0]["material"]]
    assert mat["extensions"]["VULKAN_SCHNEE_materials"] == {"probeMode": "object"}
    off = exported["off"]
    assert not any(EXT in n.get("extensions", {}) for n in off["nodes"])
    assert EXT not in off.get("extensionsUsed", [])


def test_khronos_validator_clean(exported):
    proc = subprocess.run(["node", str(VALIDATOR), str(exported["work"] / "on" / "scene.gltf")],
                          capture_output=True, text=True, timeout=120)
    report = json.loads(proc.stdout)
    assert report["issues"]["numErrors"] == 0, report["issues"]["messages"]
    assert report["issues"]["numWarnings"] == 0, report["issues"]["messages"]


def _planes(img):
    """{plane name: (H, W) mask} from the lit pixels (the background is 0), grouped into the four runs
    of columns from left to right (the planes are 1 m apart along X, the camera's right)."""
    lit = img.max(axis=2) > 0.0
    cols = np.nonzero(lit.any(axis=0))[0]
    runs = np.split(cols, np.nonzero(np.diff(cols) > 1)[0] + 1)
    assert len(runs) == 4, [len(c) for c in runs]
    out = {}
    for name, c in zip(sorted(CENTRES_X, key=CENTRES_X.get), runs):
        m = np.zeros_like(lit)
        m[:, c[0]:c[-1] + 1] = lit[:, c[0]:c[-1] + 1]
        # one pixel in from each edge: no pixel shared with the background
        m[:, [c[0], c[-1]]] = False
        rows = np.nonzero(m.any(axis=1))[0]
        m[[rows[0], rows[-1]], :] = False
        out[name] = m
    return out


def _cell_probe(x):
    """The probe of the cell holding a plane's centre (x, 0.1, 0): the per-object rule (v1 grid)."""
    ix, iy, iz = (np.floor((np.array([x, 0.1, 0.0]) - ORIGIN) / 1.0)).astype(int)
    return GRID[iz, iy, ix]


def test_engine_renders_each_object_in_its_mode(exported, tmp_path):
    gltf = exported["work"] / "on" / "scene.gltf"

    def render(*args):
        out = tmp_path / f"r{len(list(tmp_path.iterdir()))}.exr"
        viewer.check(viewer.run(gltf, "--headless", "--output", out, "--width", 120, "--height", 40,
                                "--no-direct", *args))
        return viewer.read_image(out)
    img = render()
    planes = _planes(img)
    for name, m in planes.items():
        assert m.sum() > 100, (name, m.sum())
    tol = lambda e: 1e-4 + 1e-4 * np.abs(e).max()  # noqa: E731 - float32 on the GPU (engine tests)
    # Off: the fallback probe 0, E/π = 0.2, plus the ambient term.
    off = img[planes["OffPlane"]]
    assert np.abs(off - (FALLBACK + AMBIENT)).max() < tol(off)
    # As its materials say ("object"): the probe of the cell at the plane's centre, one colour.
    e = np.maximum(ref.irradiance(COEFFS[_cell_probe(1.5)], UP), 0) / np.pi + AMBIENT
    got = img[planes["MaterialPlane"]]
    assert np.abs(got - e).max() < tol(e), np.abs(got - e).max()
    # Ambient cube per object: the least-squares cube of the same rule's probe (docs/ambient-cube.md).
    e = np.maximum(ref.cube_irradiance(ref.cube_from_sh(COEFFS[_cell_probe(4.5)]), UP), 0) / np.pi + AMBIENT
    got = img[planes["CubePlane"]]
    assert np.abs(got - e).max() < tol(e), np.abs(got - e).max()
    sh = np.maximum(ref.irradiance(COEFFS[_cell_probe(4.5)], UP), 0) / np.pi + AMBIENT
    assert np.abs(got[0] - sh).max() > 20 * tol(sh)  # measurably not the SH
    # Per pixel: the pixels the engine gives the whole scene under --probe-mode pixel (which
    # tests/engine/test_engine_perpixel.py checks against the numpy model), varying over the plane.
    pix = render("--probe-mode", "pixel", "--probe-representation", "sh")
    m = planes["PixelPlane"]
    assert np.array_equal(img[m], pix[m])
    assert np.ptp(img[m][:, 0]) > 0.1
    # The same file with every node following its material: all four planes per object.
    obj = render("--probe-mode", "object", "--probe-representation", "sh")
    assert not np.array_equal(img[m], obj[m])
    e = np.maximum(ref.irradiance(COEFFS[_cell_probe(-4.5)], UP), 0) / np.pi + AMBIENT
    assert np.abs(obj[planes["OffPlane"]] - e).max() < tol(e)
    proc = viewer.check(viewer.run(gltf, "--headless", "--print-assignments"))
    own = [ln.strip() for ln in proc.stdout.splitlines() if ln.startswith("  own probe mode")]
    assert own == ["own probe mode off representation sh (VULKAN_SCHNEE_node)",
                   "own probe mode pixel representation sh (VULKAN_SCHNEE_node)",
                   "own probe mode object representation ambientCube (VULKAN_SCHNEE_node)"], proc.stdout


@pytest.mark.skipif(shutil.which("xvfb-run") is None, reason="xvfb-run not installed")
def test_panels_drawn_by_blender_in_a_real_ui(tmp_path):
    """scripts/object_probe_mode_ui.py under Xvfb: Blender itself draws Properties > Object's Schnee
    Probes panel and the sidebar's Object Probe Mode panel for the startup cube, before and after a
    choice, without an exception (each draw recorded; Blender would only print a panel's exception)."""
    cmd = ["xvfb-run", "-a", "-s", "-screen 0 1280x800x24", "blender", "--factory-startup",
           "--python-exit-code", "1", "-P", str(SCRIPTS / "object_probe_mode_ui.py"), "--", str(tmp_path)]
    env = {**os.environ, "PYTHONPATH": str(ADDON_DIR), "SCHNEE_REPO": str(REPO)}
    proc = subprocess.run(cmd, capture_output=True, text=True, timeout=300, env=env)
    results = _results(proc.stdout)
    assert results, proc.stdout[-3000:] + proc.stderr[-3000:]
    calls = results[0]["calls"]
    assert [c for c in calls if c[2] != "ok"] == []
    for area in ("PROPERTIES", "VIEW_3D"):
        seen = [c[3] for c in calls if c[0] == area]
        assert "MATERIALS" in seen and "PIXEL" in seen, calls
    assert "Traceback" not in proc.stderr, proc.stderr[-3000:]
