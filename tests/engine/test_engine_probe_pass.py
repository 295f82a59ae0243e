"""The deferred per-pixel probe pass (docs/engine.md "The per-pixel probe pass", issue 30): per-pixel probes
shaded once per pixel in a compute dispatch after the scene pass (--probe-pass compute, the default) against
the forward path, the scene pass's fragment shader (--probe-pass fragment, the reference that the oracle
tests of test_engine_perpixel, test_engine_bricks, test_engine_grid_field, test_engine_v3/v4 compared with
numpy and the C before the pass existed; they now run the pass, the default).

The pass evaluates the same GLSL at the same float point and normal (the G-buffer holds their bits) and
regroups the colour's sum (rest + diffuse max(E, 0) + specular ratio(E) + (lit ? 0 : baked)), so the two
paths agree to float32 rounding: within 2e-6 of the frame's peak (measured 1.2e-7 at a peak of 0.84 on the
room's octree). Each case also shows that what it exercises changes the image (the probe term per pixel,
the baked lamp outside the grid, the sky's specular ratio), so equality is not two blank frames.

Scenes: the generated benchmark room (tests/engine/scripts/make_room.py: 56 objects, a realtime point lamp,
a v1 dense grid) and the same room with bench_engine_v3's corner octree; variants written here (the lamp
baked, an octree over part of the room so that pixels lie outside every grid, a sky, a material asking for
per pixel). Real lavapipe, Khronos validation layer on (viewer.run).
"""
import json
import sys

import numpy as np
import pytest

from test_engine_ibl import smooth_sky
from test_engine_v3 import ref, sg, viewer

sys.path.insert(0, str(viewer.REPO / "tests" / "engine" / "scripts"))
sys.path.insert(0, str(viewer.REPO / "bench"))
import bench_engine_v3  # noqa: E402
import make_room  # noqa: E402

from schnee_probes import native  # noqa: E402

W, H = 160, 90
TOL = 2e-6  # of the frame's peak: float32 rounding of the regrouped sum


@pytest.fixture(scope="module")
def rooms(tmp_path_factory):
    d = tmp_path_factory.mktemp("rooms")
    room = make_room.main(d / "room")
    v3 = bench_engine_v3.octree_scene(room)[0]
    return {"v1": room, "v3": v3, "dir": room.parent}


def variant(rooms, name, edit):
    """A copy of the octree room's glTF beside it (its sh_coeffs/ shared), changed by edit(doc)."""
    doc = json.loads(rooms["v3"].read_text())
    edit(doc)
    out = rooms["dir"] / f"{name}.gltf"
    out.write_text(json.dumps(doc))
    return out


def render(scene, out, *args):
    proc = viewer.check(viewer.run(scene, "--headless", "--output", out, "--width", W, "--height", H, *args))
    return viewer.read_image(out)[..., :3], proc


def both(tmp_path, scene, *args):
    """The frame from the probe pass and from the fragment shader; asserts the stderr names each path."""
    img_c, proc_c = render(scene, tmp_path / "c.exr", "--probe-pass", "compute", *args)
    img_f, proc_f = render(scene, tmp_path / "f.exr", "--probe-pass", "fragment", *args)
    assert "; per-pixel probes in the probe pass (compute)" in proc_c.stderr, proc_c.stderr
    assert "; per-pixel probes in the scene pass (fragment)" in proc_f.stderr, proc_f.stderr
    return img_c, img_f, proc_c


def assert_same(img_c, img_f):
    peak = img_f.max()
    assert peak > 0.05
    diff = np.abs(img_c - img_f)
    assert diff.max() <= TOL * peak, (diff.max(), np.unravel_index(diff.argmax(), diff.shape), peak)


@pytest.mark.parametrize("grid,args", [
    ("v1", ()),
    ("v3", ()),
    ("v3", ("--probe-path", "buffers")),
    ("v3", ("--probe-storage", "half", "--probe-representation", "ambientCube")),
    ("v3", ("--normal-bias", "0.3", "--no-direct")),
], ids=["v1-grid", "v3-bricks", "v3-buffers", "v3-half-cubes", "v3-bias"])
def test_probe_pass_equals_the_fragment_path(tmp_path, rooms, grid, args):
    img_c, img_f, proc = both(tmp_path, rooms[grid], "--probe-mode", "pixel", *args)
    assert_same(img_c, img_f)
    # The per-pixel term is in the frame: per object differs.
    obj, _ = render(rooms[grid], tmp_path / "o.exr", "--probe-mode", "object", *args)
    assert np.abs(obj - img_c).max() > 0.01 * img_c.max()
    # The pass's time is reported apart (timestamp 4 to the end of the scene pass).
    assert "of the scene, after the objects' raster (the probe pass)" in proc.stderr


def test_baked_lamp_is_added_where_no_grid_holds_the_pixel(tmp_path, rooms):
    # An octree over x in [-5, 1] m only (3 of the room's 5 root columns) and the lamp baked: pixels inside
    # the grid take the probes and not the lamp's direct light, pixels beyond x = 1 m the fallback probe 0
    # plus the lamp (meta's "baked" target added where E is not lit). The forward path decides per fragment.
    t = native.CornerOctree.uniform((-5.0, 0.0, -5.0), 0.5, 2, (3, 2, 5))
    t.finalize()
    native.write_shprobe_v3(str(rooms["dir"] / "sh_coeffs" / "part.shprobe"), t, bench_engine_v3.field(t.positions()))

    def edit(doc, mode):
        e = doc["scenes"][0]["extensions"]["VULKAN_SCHNEE_engine_properties"]["shProbeGrids"][0]
        e.update(uri="sh_coeffs/part.shprobe", probeCount=t.probe_count,
                 gridDims=list(map(int, t.info()["dims"])))
        doc["extensions"]["KHR_lights_punctual"]["lights"][0]["extensions"] = {"VULKAN_SCHNEE_light": {"mode": mode}}
        doc.setdefault("extensionsUsed", []).append("VULKAN_SCHNEE_light")

    baked = variant(rooms, "part_baked", lambda d: edit(d, "baked"))
    realtime = variant(rooms, "part_realtime", lambda d: edit(d, "realtime"))
    img_c, img_f, _ = both(tmp_path, baked, "--probe-mode", "pixel")
    assert_same(img_c, img_f)
    rt, _ = render(realtime, tmp_path / "rt.exr", "--probe-mode", "pixel")
    # The lamp is missing where the probes light the pixel and present elsewhere: both kinds of pixels exist.
    lamp_missing = np.abs(rt - img_c).max(axis=-1) > 1e-3 * rt.max()
    assert 0.05 < lamp_missing.mean() < 0.95, lamp_missing.mean()


def test_sky_specular_ratio_and_material_modes(tmp_path, rooms):
    # A sky (background, probe 0 = its SH, split-sum specular scaled by the ratio of E to the sky's E) and
    # --probe-mode material with only the "object" material asking for per pixel: the walls stay per object,
    # in the forward part of the deferred shader; the objects go through the pass.
    img = smooth_sky()
    sg.write_exr(rooms["dir"] / "sky.exr", img)

    def edit(doc):
        doc["scenes"][0]["extensions"]["VULKAN_SCHNEE_engine_properties"]["sky"] = sg.sky_entry(
            "sky.exr", ref.project_l2(img))
        for m in doc["materials"]:
            m["pbrMetallicRoughness"]["roughnessFactor"] = 0.4
            if m["name"] == "object":
                m["extensions"]["VULKAN_SCHNEE_materials"]["probeMode"] = "pixel"

    scene = variant(rooms, "sky_modes", edit)
    img_c, img_f, _ = both(tmp_path, scene)
    assert_same(img_c, img_f)
    # The ratio matters (the room is darker than the sky) and so does the per-pixel material.
    no_renorm, _ = render(scene, tmp_path / "nr.exr", "--no-renorm")
    assert np.abs(no_renorm - img_c).max() > 0.01 * img_c.max()
    per_object, _ = render(scene, tmp_path / "po.exr", "--probe-mode", "object")
    assert np.abs(per_object - img_c).max() > 0.01 * img_c.max()


def test_probe_view_is_drawn_over_the_pass(tmp_path, rooms):
    # The probe view is drawn after the dispatch, on the kept depth: spheres and outlines occlude the room as
    # in the forward path, and no probe term is added over them.
    img_c, img_f, _ = both(tmp_path, rooms["v3"], "--probe-mode", "pixel", "--probe-view")
    assert_same(img_c, img_f)
    plain, _ = render(rooms["v3"], tmp_path / "p.exr", "--probe-mode", "pixel")
    assert np.abs(plain - img_c).max() > 0.05


def test_bad_probe_pass_value_and_debug_views(tmp_path, rooms):
    bad = viewer.run(rooms["v1"], "--headless", "--output", tmp_path / "x.exr", "--probe-pass", "fast")
    assert bad.returncode == 2 and "bad value 'fast' for --probe-pass" in bad.stderr
    # A debug view takes the forward path whatever --probe-pass says: equal frames.
    a, _ = render(rooms["v3"], tmp_path / "a.exr", "--probe-mode", "pixel", "--debug", "normals")
    b, _ = render(rooms["v3"], tmp_path / "b.exr", "--probe-mode", "pixel", "--debug", "normals", "--probe-pass",
                  "fragment")
    assert np.array_equal(a, b)


@pytest.mark.parametrize("mode", ["object", "off", "material"])
def test_frames_without_per_pixel_take_the_lean_shader_alike(tmp_path, rooms, mode):
    # Without a per-pixel fragment (per object, off, or --probe-mode material where no material or node asks
    # for per pixel) the scene pass takes mesh.frag built without the grid lookup (SV_LEAN_SCENE); the
    # forward shader (--probe-pass fragment) shades the same.
    lean, proc = render(rooms["v3"], tmp_path / "l.exr", "--probe-mode", mode)
    full, _ = render(rooms["v3"], tmp_path / "f.exr", "--probe-mode", mode, "--probe-pass", "fragment")
    assert_same(lean, full)
    assert "after the objects' raster (the probe pass)" in proc.stderr
