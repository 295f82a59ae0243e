"""The sky's sun as a mixed light (issue 27): ``blender -b --factory-startup -P sky_sun_bake.py -- OUT_DIR``.

Under Blender's bundled sunrise.exr (strength 1, read as it is):

- ``sky``: a probe volume alone (one probe, nothing else): bakes with Sky Sun "mixed" and "baked"
  into the same folder (mixed first, so baked must remove its sun.json), each with sky.exr
  (512x256, 16 spp, the same seed: the same capture before the sun is removed).
- ``scene``: a 10 m ground (albedo 0.8/0.7/0.6, roughness 1) with a 1 m box (0.15..0.65 m up) placed towards the
  sun so its shadow crosses the ground's centre, an orthographic camera 10 m above looking down
  (8 m wide, 160x160 px), one probe volume above the ground; a mixed bake, the .blend saved, then a
  glTF export (cameras on, Punctual Lights off: the sky's sun is added all the same); one more
  export with a broken sun.json.
- ``nishita``: a Nishita sky (sun 25° up, 60° around), captured by Cycles, baked mixed.

Emits one RESULT line per case.
"""
import json
import os
import sys

import addon_utils
import bpy
import numpy as np

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import addon_common as common  # noqa: E402
from addon_common import scene_lib as lib  # noqa: E402

addon_utils.enable("io_scene_gltf2", default_set=True)
assert addon_utils.enable("schnee_probes", default_set=True) is not None
from schnee_probes import bake_core, native  # noqa: E402

OUT = common.args()[0]
HDRI = "sunrise.exr"


def settings(folder, **kw):
    base = dict(placement="OCTREE", min_cell_size=4.0, max_cell_size=4.0, panorama_resolution=32, samples=1,
                max_bounces=2, sky_resolution=512, output_path=os.path.join(folder, "sh_coeffs", "probes.shprobe"))
    base.update(kw)
    return bake_core.BakeSettings(**base)


def bake(s):
    logs = []
    job = bake_core.ProbeBake(bpy.context.scene, bpy.context.view_layer, s, log=logs.append)
    result = job.run()
    return job, result, logs


def read_json(path):
    if not os.path.exists(path):
        return None
    with open(path, encoding="utf-8") as fh:
        return json.load(fh)


def exr_pixels(path):
    img = bpy.data.images.load(path, check_existing=False)
    try:
        w, h = img.size
        buf = np.empty(w * h * img.channels, dtype=np.float32)
        img.pixels.foreach_get(buf)
        return buf.reshape(h, w, img.channels)[::-1, :, :3].copy()
    finally:
        bpy.data.images.remove(img)


def sky_case():
    lib.clear_scene()
    lib.hdri_world(HDRI)
    lib.probe_volume("SkyVolume", (-2.0, -2.0, 0.0), (2.0, 2.0, 4.0))
    folder = os.path.join(OUT, "sky")
    capture = dict(sky_resolution=512, capture_sky=True)
    out = {}
    for mode in ("mixed", "baked"):
        job, result, logs = bake(settings(folder, sky_sun=mode, samples=16, **capture))
        sky = exr_pixels(os.path.join(folder, "sh_coeffs", "sky.exr"))
        out[mode] = dict(coeffs=job.coeffs[0].tolist(), files=sorted(os.path.basename(f) for f in result.files),
                         sun=read_json(os.path.join(folder, "sh_coeffs", "sun.json")),
                         sun_file=os.path.exists(os.path.join(folder, "sh_coeffs", "sun.json")),
                         sky_sh=native.sky_table(np.ascontiguousarray(sky), 1, 1, 2)[0, 0].tolist(),
                         sky_path=os.path.join(OUT, f"sky_{mode}.npy"), logs=logs)
        np.save(out[mode]["sky_path"], sky)
    # The journal's fingerprint (fingerprint.parts): mixed and baked differ; baked is the digest of
    # the settings as they were before Sky Sun existed (a journal of an earlier bake resumes).
    from dataclasses import asdict
    from schnee_probes import fingerprint
    fp = {m: fingerprint.parts(bpy.context.scene, bpy.context.view_layer, settings(folder, sky_sun=m))["settings"]
          for m in ("mixed", "baked")}
    # (Render Device at its default is left out the same way: fingerprint._LEGACY_VALUES; Adaptive
    # bakes name their sampling scheme, issue 29, so journals of the two-halves scheme do not resume.)
    from schnee_probes import adaptive
    s = settings(folder)
    legacy = fingerprint._digest(sorted((k, v) for k, v in asdict(s).items()
                                        if k not in fingerprint._NOT_VALUES and k not in fingerprint._LEGACY_VALUES)
                                 + ([("sampling", adaptive.SAMPLING)] if s.placement == "ADAPTIVE" else []))
    out["fingerprint"] = dict(fp, legacy=legacy)
    # The world as the bake reads it (Blender's pixels x strength 1), for the expected values.
    world = np.clip(native.read_image(lib.studiolight_path(HDRI))[:, :, :3], 0.0, None).astype(np.float32)
    np.save(os.path.join(OUT, "world.npy"), world)
    common.emit(case="sky", world=os.path.join(OUT, "world.npy"), **out)


def scene_case():
    lib.clear_scene()
    scene = bpy.context.scene
    lib.hdri_world(HDRI)
    world = np.clip(native.read_image(lib.studiolight_path(HDRI))[:, :, :3], 0.0, None).astype(np.float32)
    travel = np.array(native.sky_sun_split(world).sun.direction)              # engine space
    toward = np.array([-travel[0], travel[2], 0.0])                           # Blender, horizontal, to the sun
    toward /= np.linalg.norm(toward)
    mat = lib.diffuse_material("Ground", (0.8, 0.7, 0.6))
    mat.node_tree.nodes["Principled BSDF"].inputs["Roughness"].default_value = 1.0
    mat.node_tree.nodes["Principled BSDF"].inputs["Metallic"].default_value = 0.0
    lib.box("Ground", (-5.0, -5.0, -0.1), (5.0, 5.0, 0.0), material=mat)
    c = toward * 3.0
    lib.box("Blocker", (c[0] - 0.5, c[1] - 0.5, 0.15), (c[0] + 0.5, c[1] + 0.5, 0.65), material=mat)
    lib.probe_volume("Volume", (-2.0, -2.0, 0.5), (2.0, 2.0, 4.5))
    cam_data = bpy.data.cameras.new("Top")
    cam_data.type = 'ORTHO'
    cam_data.ortho_scale = 8.0
    cam = bpy.data.objects.new("Top", cam_data)
    cam.location = (0.0, 0.0, 10.0)
    scene.collection.objects.link(cam)
    scene.camera = cam
    scene.render.resolution_x = scene.render.resolution_y = 160
    scene.render.resolution_percentage = 100
    folder = os.path.join(OUT, "scene")
    os.makedirs(folder, exist_ok=True)
    blend = os.path.join(folder, "scene.blend")
    bpy.ops.wm.save_as_mainfile(filepath=blend)
    job, result, logs = bake(settings(folder, output_path="//sh_coeffs/probes.shprobe", capture_sky=True,
                                      sky_resolution=128))
    gltf = os.path.join(folder, "export", "scene.gltf")
    os.makedirs(os.path.dirname(gltf), exist_ok=True)
    bpy.ops.export_scene.gltf(filepath=gltf, export_format='GLTF_SEPARATE', export_cameras=True,
                              export_lights=False)
    # A broken sun.json (direction not a unit vector): the export warns and writes no light.
    sun_path = os.path.join(folder, "sh_coeffs", "sun.json")
    good = read_json(sun_path)
    with open(sun_path, "w", encoding="utf-8") as fh:
        json.dump(dict(good, direction=[0.0, 2.0, 0.0]), fh, indent=2)
    bad_gltf = os.path.join(folder, "export_bad", "scene.gltf")
    os.makedirs(os.path.dirname(bad_gltf), exist_ok=True)
    bpy.ops.export_scene.gltf(filepath=bad_gltf, export_format='GLTF_SEPARATE', export_lights=False)
    with open(sun_path, "w", encoding="utf-8") as fh:
        json.dump(good, fh, indent=2)
    box_lo = (c[0] - 0.5, 0.15, -(c[1] + 0.5))   # engine (x, z, -y)
    box_hi = (c[0] + 0.5, 0.65, -(c[1] - 0.5))
    common.emit(case="scene", gltf=gltf, bad_gltf=bad_gltf, sun=read_json(os.path.join(folder, "sh_coeffs", "sun.json")),
                box=[list(box_lo), list(box_hi)], files=sorted(os.path.basename(f) for f in result.files), logs=logs)


def nishita_case():
    lib.clear_scene()
    lib.nishita_world(25.0, 60.0)
    lib.probe_volume("SkyVolume", (-2.0, -2.0, 0.0), (2.0, 2.0, 4.0))
    folder = os.path.join(OUT, "nishita")
    job, result, logs = bake(settings(folder, capture_sky=False))
    common.emit(case="nishita", sun=read_json(os.path.join(folder, "sh_coeffs", "sun.json")),
                source=job.direct.sky_source, coeffs=job.coeffs[0].tolist(), logs=logs)


sky_case()
scene_case()
if "--no-nishita" not in sys.argv:
    nishita_case()
