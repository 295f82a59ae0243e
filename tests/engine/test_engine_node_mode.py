"""The object's own probe mode (issue 31 item 2; docs/export.md "Node: VULKAN_SCHNEE_node",
docs/engine.md "Probe mode"): a node's VULKAN_SCHNEE_node.probeMode / probeRepresentation replace
its materials' for that node's primitives; the command line still overrides both.

Four floor quads, one mesh and one material (white, shScale 1, ambientTerm 0, probeMode "object"),
side by side over the 4 x 2 x 4 grid of test_engine_perpixel.py and seen by a look-down orthographic
camera, so every pixel centre's world point is known: the EXR pixel is max(E, 0) / π. Expected E
from tests/engine/scripts/probe_ref.py (numpy, written from the documents): per pixel the trilinear
model, per object the grid's field at the quad's centre (docs/grid-field.md "Per object": the movable
rule, no probe hidden), off the fallback probe 0 (E = π·0.2), the ambient cube the least-squares cube of
that blend (the fit is linear: the blend of the probes' cubes).
"""
import copy
import json
import sys
from pathlib import Path

import numpy as np
import pytest

sys.path.insert(0, str(Path(__file__).parent / "scripts"))
import probe_ref as ref  # noqa: E402
import scenegen as sg  # noqa: E402
import viewer  # noqa: E402
from test_engine_perpixel import COEFFS, FALLBACK, GRID, N, down_camera_points, write_grid  # noqa: E402

Y = 0.1      # the floors' height: inside the grid's bottom layer, 0.4 spacings below its centres
SIZE = 1.8   # each floor 1.8 m square, centred in one 2 m quadrant of the 4 m grid
# name: (centre x, z), node extension (None: none, the material's "object")
FLOORS = {
    "PixelFloor": ((1.0, 1.0), {"probeMode": "pixel", "probeRepresentation": "sh"}),
    "OffFloor": ((3.0, 1.0), {"probeMode": "off", "probeRepresentation": "sh"}),
    "MaterialFloor": ((1.0, 3.0), None),
    "CubeFloor": ((3.0, 3.0), {"probeMode": "object", "probeRepresentation": "ambientCube"}),
}
UP = np.array([0.0, 1.0, 0.0])


def scene(d, name, node_ext):
    """The four floors, one mesh and one material; node_ext: {floor name: VULKAN_SCHNEE_node or None}."""
    entry = write_grid(d, "probes", COEFFS, GRID, (0, 0, 0), 1.0)
    b = sg.GltfBuilder()
    m = b.material("white", sh_scale=1.0, ambient_term=0.0, probe_mode="object")
    mesh = b.mesh("floor", sg.quad(SIZE, SIZE, 1), m)
    for floor, ((x, z), _) in FLOORS.items():
        ext = node_ext.get(floor)
        extra = {"extensions": {"VULKAN_SCHNEE_node": ext}} if ext is not None else {}
        b.node(floor, mesh=mesh, translation=(x, Y, z), **extra)
        if ext is not None:
            b._use("VULKAN_SCHNEE_node")
    b.node("Camera", camera=b.ortho_camera("top", 2.0), translation=(2.0, Y + 3, 2.0), rotation=sg.ROT_LOOK_DOWN)
    b.probe_grids([entry])
    return b.write(d / f"{name}.gltf")


def masks():
    """{floor: (N, N) bool} of the pixels whose centre lies on that floor (5 mm from its edges)."""
    p = down_camera_points(2.0, 2.0, Y, 2.0)
    out = {}
    for floor, ((x, z), _) in FLOORS.items():
        out[floor] = (np.abs(p[..., 0] - x) < SIZE / 2 - 5e-3) & (np.abs(p[..., 2] - z) < SIZE / 2 - 5e-3)
    return p, out


def cell_probe(x, z):
    """The probe of the cell holding (x, Y, z): the per-object rule before issue 30 item 3."""
    return GRID[int(np.floor(z)), int(np.floor(Y)), int(np.floor(x))]


def cube_of_sh(c, n):
    return ref.cube_irradiance(ref.cube_from_sh(c), n)


def object_e(x, z, cube=False):
    """Per object: E(UP) of the field at the floor's centre (x, Y, z), movable rule (the floors sit 0.4
    spacings below the probes' layer and block none of the segments probe -> centre). Each floor's
    centre is a cell corner in x and z: four cells blended, with the grid's holes renormalised."""
    e, held = ref.grid_irradiance([[x, Y, z]], [UP], GRID, (0, 0, 0), 1.0, COEFFS, backface=False,
                                  evaluate=cube_of_sh if cube else ref.irradiance)
    assert held[0]
    return e[0]


def expected_image():
    """(N, N, 3) expected pixels, NaN off the floors, for the node fields of FLOORS."""
    p, ms = masks()
    out = np.full((N, N, 3), np.nan)
    for floor, ((x, z), ext) in FLOORS.items():
        mode = (ext or {}).get("probeMode", "object")
        rep = (ext or {}).get("probeRepresentation", "sh")
        if mode == "pixel":
            pts = p[ms[floor]]
            e, held = ref.grid_irradiance(pts, np.tile(UP, (len(pts), 1)), GRID, (0, 0, 0), 1.0, COEFFS)
            assert held.all()
        elif mode == "off":
            e = np.full(3, np.pi * FALLBACK)
        elif rep == "ambientCube":
            e = object_e(x, z, cube=True)
        else:
            e = object_e(x, z)
        out[ms[floor]] = np.maximum(e, 0.0) / np.pi
    return out


def render(path, out, *args):
    proc = viewer.check(viewer.run(path, "--headless", "--output", out, "--width", N, "--height", N, *args))
    return viewer.read_image(out), proc


@pytest.fixture(scope="module")
def renders(tmp_path_factory):
    d = tmp_path_factory.mktemp("node_mode")
    with_nodes = scene(d, "nodes", {f: ext for f, (_, ext) in FLOORS.items()})
    material_only = scene(d, "materials", {})
    done = {}

    def get(which, *args):
        key = (which, args)
        if key not in done:
            path = {"nodes": with_nodes, "materials": material_only}.get(which, which)
            done[key] = render(path, d / f"r{len(done)}.exr", *args)
        return done[key]
    get.dir = d
    return get


def test_each_object_follows_its_own_mode(renders):
    img, _ = renders("nodes")
    expected = expected_image()
    _, ms = masks()
    # The per-pixel floor on the default path (the probe bricks, binary16 texels N and D): the bound of
    # test_engine_grid_field.py's floor over this grid, 4 x 2^-11 x the largest |E_k| / pi of any probe.
    emax = max(np.abs(ref.irradiance(c, UP)).max() for c in COEFFS) / np.pi
    for floor in FLOORS:
        err = np.abs(img[ms[floor]] - expected[ms[floor]])
        # float32 on the GPU vs float64 here (test_engine_perpixel: 1.7e-6 measured)
        bound = 1e-4 + 1e-4 * np.abs(expected[ms[floor]]).max()
        assert err.max() < (4 * 2.0 ** -11 * emax + 1e-4 if floor == "PixelFloor" else bound), (floor, err.max())
        print(f"{floor}: {ms[floor].sum()} pixels, max abs error {err.max():.2e}")
    # The modes really differ: the per-pixel floor varies, the others are one colour each.
    assert np.ptp(img[ms["PixelFloor"]][:, 0]) > 0.1
    for floor in ("OffFloor", "MaterialFloor", "CubeFloor"):
        assert np.ptp(img[ms[floor]], axis=0).max() < 1e-5, floor
    # The cube differs measurably from the SH of the same probe (a silent SH path would fail).
    sh = object_e(3.0, 3.0) / np.pi
    assert np.abs(img[ms["CubeFloor"]][0] - sh).max() > 20 * (1e-4 + 1e-4 * np.abs(sh).max())


def test_material_only_scene_and_absent_fields(renders):
    """No node extension: every floor per object, the field at its centre (the material says
    "object"); a node with the material's own mode renders the same pixels."""
    img, _ = renders("materials")
    _, ms = masks()
    for floor, ((x, z), _) in FLOORS.items():
        e = np.maximum(object_e(x, z), 0.0) / np.pi
        err = np.abs(img[ms[floor]] - e)
        # the old rule (the cell holding the centre) is far from it: the case tells the rules apart
        old = np.maximum(ref.irradiance(COEFFS[cell_probe(x, z)], UP), 0.0) / np.pi
        assert np.abs(old - e).max() > 0.02, (floor, old, e)
        assert err.max() < 1e-4 + 1e-4 * np.abs(e).max(), (floor, err.max())
    same = scene(renders.dir, "same", {f: {"probeMode": "object"} for f in FLOORS})
    img2, _ = renders(same)
    assert np.array_equal(img, img2)


def test_command_line_overrides_the_node(renders):
    for mode in ("pixel", "object", "off"):
        a, _ = renders("nodes", "--probe-mode", mode, "--probe-representation", "sh")
        b, _ = renders("materials", "--probe-mode", mode, "--probe-representation", "sh")
        assert np.array_equal(a, b), mode


def test_unknown_values_warn_and_follow_the_materials(renders):
    bad = {"PixelFloor": {"probeMode": "everywhere"}, "OffFloor": {"probeMode": 2, "probeRepresentation": "cube"},
           "CubeFloor": {"probeRepresentation": "ambientCube", "probeMode": "perPixel"}}
    path = scene(renders.dir, "bad", bad)
    doc = json.loads(path.read_text())
    node = doc["nodes"][0]
    assert node["extensions"]["VULKAN_SCHNEE_node"] == {"probeMode": "everywhere"}
    img, proc = renders(path)
    warnings = [ln for ln in proc.stderr.splitlines() if "VULKAN_SCHNEE_node" in ln]
    assert any("nodes[0] ('PixelFloor').extensions.VULKAN_SCHNEE_node.probeMode: 'everywhere' is not off, "
               "object or pixel; the node follows its materials" in ln for ln in warnings), proc.stderr
    assert any("('OffFloor')" in ln and "probeMode: expected a string (off, object or pixel), got a number" in ln
               for ln in warnings), proc.stderr
    assert any("('OffFloor')" in ln and "probeRepresentation: 'cube' is not sh or ambientCube" in ln
               for ln in warnings), proc.stderr
    assert all("warning" in ln for ln in warnings) and len(warnings) == 4, warnings
    # Each bad field follows the material ("object", SH); CubeFloor's good field still counts.
    ref_img, _ = renders("materials")
    _, ms = masks()
    for floor in ("PixelFloor", "OffFloor", "MaterialFloor"):
        assert np.array_equal(img[ms[floor]], ref_img[ms[floor]]), floor
    cube = np.maximum(object_e(3.0, 3.0, cube=True), 0) / np.pi
    assert np.abs(img[ms["CubeFloor"]] - cube).max() < 1e-4 + 1e-4 * np.abs(cube).max()
    # Not an object: a warning too, and the node follows its materials.
    doc2 = copy.deepcopy(doc)
    doc2["nodes"][0]["extensions"]["VULKAN_SCHNEE_node"] = ["pixel"]
    p2 = renders.dir / "bad2.gltf"
    p2.write_text(json.dumps(doc2))
    img2, proc2 = renders(p2)
    assert "nodes[0] ('PixelFloor').extensions.VULKAN_SCHNEE_node: expected an object, got an array; the node " \
           "follows its materials" in proc2.stderr
    assert np.array_equal(img2[ms["PixelFloor"]], ref_img[ms["PixelFloor"]])


def test_print_assignments_names_the_own_modes(renders):
    proc = viewer.check(viewer.run(scene(renders.dir, "nodes_pa", {f: e for f, (_, e) in FLOORS.items()}),
                                   "--headless", "--print-assignments"))
    lines = proc.stdout.splitlines()
    own = {lines[i - 1].split("'")[1]: lines[i].strip() for i in range(1, len(lines))
           if lines[i].startswith("  own probe mode")}
    assert own == {"PixelFloor": "own probe mode pixel representation sh (VULKAN_SCHNEE_node)",
                   "OffFloor": "own probe mode off representation sh (VULKAN_SCHNEE_node)",
                   "CubeFloor": "own probe mode object representation ambientCube (VULKAN_SCHNEE_node)"}, lines
