"""The README's main job end to end (generate → bake → export → engine render), at coarse settings.

Expected values come from the artefacts themselves, read back by independent readers: the glTF JSON
(the exporter's entry must repeat the .shprobe header, DESIGN.md §5), the native reader, and OIIO's
oiiotool for the image statistics.
"""
import json
import subprocess
import sys

import numpy as np

from conftest import REPO

from schnee_probes import native


def test_main_job_end_to_end(tmp_path):
    out = tmp_path / "job"
    proc = subprocess.run(
        [sys.executable, str(REPO / "scripts" / "main_job.py"), "--out", str(out),
         "--width", "320", "--height", "180",
         "--bake-args", "--min-cell-size 2 --max-cell-size 4 --panorama-resolution 32 --samples 4 "
                        "--max-bounces 2"],
        capture_output=True, text=True, timeout=900)
    assert proc.returncode == 0, proc.stdout[-4000:] + proc.stderr[-2000:]
    assert f"main job: image   {out / 'frame.png'}" in proc.stdout

    probes = native.read_shprobe(str(out / "sh_coeffs" / "probes.shprobe"))
    # Adaptive placement (the default) refines per axis and writes a version 4 kd corner tree (a
    # version 3 octree where every leaf stays a cube): its lattice of Min Cell Size 2 m spans whole
    # 4 m root cells over the 10 x 4 x 10 m room, ceil(10 / 4) x 4 / 2 = 6 and 4 / 2 = 2 min cells
    # per axis (docs/placement.md, docs/shprobe-format.md "Version 3", "Version 4").
    assert (probes.version, probes.structure) in ((3, "octree"), (4, "kdtree"))
    assert probes.grid_dims == (6, 2, 6)
    assert probes.probe_count > 0

    gltf = json.loads((out / "gltf" / "scene.gltf").read_text())
    grids = gltf["scenes"][0]["extensions"]["VULKAN_SCHNEE_engine_properties"]["shProbeGrids"]
    assert len(grids) == 1 and grids[0]["probeCount"] == probes.probe_count
    assert grids[0]["gridDims"] == list(probes.grid_dims)
    assert (grids[0]["version"], grids[0]["structure"]) == (probes.version, probes.structure)
    assert (out / "gltf" / grids[0]["uri"]).read_bytes() == (out / "sh_coeffs" / "probes.shprobe").read_bytes()
    assert "VULKAN_SCHNEE_engine_properties" not in gltf.get("extensionsRequired", [])

    stats = subprocess.run(["oiiotool", "--stats", str(out / "frame.png")], capture_output=True,
                           text=True, check=True).stdout
    assert "320 x  180" in stats or "320 x 180" in stats
    # oiiotool reports 8-bit images in 0..255. Not an empty frame: the stddev over the image is far
    # above quantisation noise (lit room with objects), and the mean is neither black nor white.
    stddev = [float(v) for v in stats.split("Stats StdDev:")[1].split("(")[0].split()]
    assert max(stddev) > 10.0, stats
    means = [float(v) for v in stats.split("Stats Avg:")[1].split("(")[0].split()]
    assert 13.0 < np.mean(means[:3]) < 242.0, stats
