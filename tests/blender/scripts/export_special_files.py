"""Headless Blender: export a one-cube scene whose sh_coeffs/ holds special files (issue 14).

    blender -b --factory-startup -P export_special_files.py -- WORKDIR

WORKDIR/scene/sh_coeffs/ is prepared by tests/blender/test_export_special_files.py: good
.shprobe files, a FIFO, a device link, a symbolic link loop, a FIFO named sky.exr. Three good
files are swapped *after* the exporter validated them (native.read_shprobe wrapped below) for a
FIFO, a link to /dev/zero and another regular file: the copy must refuse them without blocking.
Writes WORKDIR/out/scene.gltf and prints ``RESULT {...}`` (the swaps made, the warnings).
"""
import json
import os
import sys

import addon_utils
import bpy

work = os.path.abspath(sys.argv[sys.argv.index("--") + 1])
scene_dir = os.path.join(work, "scene")
sh_dir = os.path.join(scene_dir, "sh_coeffs")

addon_utils.enable("io_scene_gltf2", default_set=True)
assert addon_utils.enable("schnee_probes", default_set=True) is not None
from schnee_probes import gltf_export, native  # noqa: E402

for obj in list(bpy.data.objects):
    bpy.data.objects.remove(obj)
mesh = bpy.data.meshes.new("Cube")
mesh.from_pydata([(x, y, z) for x in (-1, 1) for y in (-1, 1) for z in (-1, 1)], [],
                 [(0, 1, 3, 2), (4, 6, 7, 5), (0, 4, 5, 1), (2, 3, 7, 6), (0, 2, 6, 4), (1, 5, 7, 3)])
bpy.context.scene.collection.objects.link(bpy.data.objects.new("Cube", mesh))
bpy.ops.wm.save_as_mainfile(filepath=os.path.join(scene_dir, "scene.blend"))

# What each file becomes right after the exporter's validation (the race of issue 14).
SWAPS = {"b_fifo_later.shprobe": "fifo", "c_device_later.shprobe": "device", "d_other_later.shprobe": "other"}
swapped = []
real_read = native.read_shprobe


def read_then_swap(path):
    result = real_read(path)
    how = SWAPS.get(os.path.basename(path))
    if how:
        os.unlink(path)
        if how == "fifo":
            os.mkfifo(path)
        elif how == "device":
            os.symlink("/dev/zero", path)
        else:  # another regular file (new inode, other bytes): not what was validated
            with open(path, "wb") as f:
                f.write(b"SPHR" + b"\0" * 60)
        swapped.append(os.path.basename(path))
    return result


native.read_shprobe = read_then_swap
warnings = []
real_warn = gltf_export._warn


def record_warn(settings, message):
    warnings.append(message)
    real_warn(settings, message)


gltf_export._warn = record_warn
bpy.context.scene.schnee_gltf_export.enabled = True
out = os.path.join(work, "out", "scene.gltf")
os.makedirs(os.path.dirname(out))
print("SCHNEE-TEST export start", flush=True)
bpy.ops.export_scene.gltf(filepath=out, export_format="GLTF_SEPARATE")
print("SCHNEE-TEST export done", flush=True)
print("RESULT " + json.dumps({"swapped": sorted(swapped), "warnings": warnings}), flush=True)
