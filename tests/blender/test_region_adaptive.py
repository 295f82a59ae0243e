"""Region rebake with Adaptive placement (issue 31 item 3; docs/region-rebake.md "What a region
keeps"), in real headless Blender 3.4 through bake.py on scripts/region_scenes.py's two volumes: the
previous bake is an Adaptive one (0.5 to 2 m cells, File Version 3); after the crate is put on
Left's floor, ``--only-volume Left --region`` around it keeps the previous octree outside the box
and every probe record there. Expected values come from the previous file itself: each probe of the
new Left.shprobe at a lattice node outside the box that the previous file also has holds the previous
coefficient and validity bits (region.KeptTree), every previous leaf that does not meet the box is
a leaf again (or lies inside a leaf the rebake decided anew), Right.shprobe keeps its bytes, and
the rebake renders fewer points than the previous bake of both volumes while some probe inside the
box sees the crate. Runtime: about 40 s on 2 cores."""
import hashlib
import re
import shutil

import numpy as np
import pytest

from conftest import requires_native, run_blender
from schnee_probes import bakeinfo, journal, native, scene_export
from test_bake_hazards import BAKE_PY, scenes_made_by

pytestmark = requires_native

# 8 samples: points get later rounds (a point on the volumes' shared face from both volumes in the
# full bake, from Left alone in the rebake): without the kept tree a record outside the box differs.
ARGS = ["--placement", "ADAPTIVE", "--file-version", "V3", "--min-cell-size", "0.5", "--max-cell-size", "2",
        "--samples", "8", "--panorama-resolution", "16", "--per-volume-files", "on"]
REGION = ["-2.1", "-2.1", "-0.1", "-0.6", "-0.6", "1"]   # Blender space: the crate and the room's corner

scenes = scenes_made_by("region_scenes.py")


def _bake(blend, *args):
    proc = run_blender(BAKE_PY, *ARGS, *args, blend=blend, check=False, timeout=600)
    assert proc.returncode == 0, proc.stdout[-3000:] + proc.stderr[-3000:]
    return proc


def _renders(proc):
    """Points rendered: a full bake's (adaptive placement summary) or a rebake's (this run's)."""
    m = re.search(r"bake\.py: (\d+) render\(s\) by this run", proc.stdout) or \
        re.search(r"bake\.py: adaptive placement: \d+ pass\(es\), (\d+) points rendered", proc.stdout)
    return int(m.group(1))


@pytest.fixture(scope="module")
def previous(scenes, tmp_path_factory):
    """The Adaptive bake of the scene before the edit: (its sh_coeffs folder, its renders)."""
    folder = tmp_path_factory.mktemp("previous")
    blend = folder / "two_rooms.blend"
    shutil.copyfile(scenes / "two_rooms.blend", blend)
    return folder / "sh_coeffs", _renders(_bake(blend))


def _tree(path):
    """(file, info of its octree, {lattice node: (coefficient bytes, validity bytes)})."""
    f = native.read_shprobe(str(path))
    info = native.interpolation_from_file(str(path)).info()
    records = {tuple(int(v) for v in n): (f.coeffs[i].tobytes(), f.validity[i].tobytes())
               for i, n in enumerate(info["probe_lattice"])}
    return f, info, records


def _leaf_boxes(info):
    lo = info["leaves"][:, :3].astype(np.int64)
    size = 1 << np.asarray(info["levels"], dtype=np.int64).reshape(-1, 3)
    return lo, lo + size


def test_adaptive_region_rebake_keeps_the_previous_tree_and_bits_outside(scenes, previous, tmp_path):
    prev_dir, prev_renders = previous
    shutil.copytree(prev_dir, tmp_path / "sh_coeffs")
    out = tmp_path / "sh_coeffs"
    blend = tmp_path / "two_rooms_edited.blend"
    shutil.copyfile(scenes / "two_rooms_edited.blend", blend)
    right = hashlib.sha256((out / "Right.shprobe").read_bytes()).hexdigest()
    proc = _bake(blend, "--only-volume", "Left", "--region", *REGION)
    renders = _renders(proc)
    assert 0 < renders < prev_renders / 2, (renders, prev_renders)
    assert hashlib.sha256((out / "Right.shprobe").read_bytes()).hexdigest() == right

    old_f, old_info, old = _tree(prev_dir / "Left.shprobe")
    new_f, new_info, new = _tree(out / "Left.shprobe")
    origin, h = np.asarray(new_info["origin"]), float(new_info["min_cell"])
    assert np.allclose(origin, old_info["origin"]) and h == old_info["min_cell"]
    corners = scene_export.blender_to_engine(np.array(REGION, dtype=np.float64).reshape(2, 3))
    lo, hi = corners.min(axis=0), corners.max(axis=0)

    def outside(node):
        p = origin + np.array(node) * h
        return bool(np.any(p < lo) or np.any(p > hi))
    shared = [n for n in new if outside(n) and n in old]
    assert len(shared) > 20
    assert [n for n in shared if new[n] != old[n]] == []     # the previous bits, every one
    inside = [n for n in new if not outside(n) and n in old]
    assert any(new[n][0] != old[n][0] for n in inside)       # the crate is seen inside the box

    # The sidecar (the overlay's Noise mode): valid for the new file, the previous noise at the kept probes.
    side = bakeinfo.read(str(out / "Left.shprobe.bakeinfo"), str(out / "Left.shprobe"), new_f.probe_count,
                         new_f.leaves)
    before = bakeinfo.read(str(prev_dir / "Left.shprobe.bakeinfo"), str(prev_dir / "Left.shprobe"),
                           old_f.probe_count, old_f.leaves)
    assert side.error is None and before.error is None
    new_row = {n: i for i, n in enumerate(map(tuple, new_info["probe_lattice"].tolist()))}
    old_row = {n: i for i, n in enumerate(map(tuple, old_info["probe_lattice"].tolist()))}
    assert all(side.noise[new_row[n]].tobytes() == before.noise[old_row[n]].tobytes() for n in shared)

    def meets(a, b):
        return np.all((origin + a * h <= hi) & (origin + b * h >= lo), axis=1)
    olo, ohi = _leaf_boxes(old_info)
    nlo, nhi = _leaf_boxes(new_info)
    new_keys = {tuple(r) for r in np.concatenate([nlo, nhi], axis=1).tolist()}
    redone = meets(nlo, nhi)
    for a, b, m in zip(olo, ohi, meets(olo, ohi)):
        if not m:   # a previous leaf outside the box: a leaf again, or inside a leaf decided anew
            assert tuple(np.concatenate([a, b]).tolist()) in new_keys or \
                np.any(redone & np.all((nlo <= a) & (nhi >= b), axis=1))


# Blender space: Right's far corner. The full bake asked for the nodes on the x = 0 face Left and Right
# share from Left first (Left's group is first), so it rendered them 1 cm inside Left; a rebake of Right
# would render them 1 cm inside Right, and its file keeps their previous records.
RIGHT_REGION = ["0.6", "-2.1", "-0.1", "2.1", "-0.6", "1"]


def test_kept_probes_take_the_previous_value_instead_of_a_render(scenes, previous, tmp_path):
    """A region rebake of Right renders no probe whose record it keeps: the nodes on the face it
    shares with Left (rendered from Left's side before) take the previous bake's point beside them
    (AdaptivePlan.kept_value). Expected from the files: those nodes are kept (outside the box, in both
    trees, the previous bits), and the rebake's own points (its points file less the previous one's)
    lie more than the stand-in radius (sqrt(3) cm + 5 cm) from every one of them."""
    prev_dir, _ = previous
    shutil.copytree(prev_dir, tmp_path / "sh_coeffs")
    out = tmp_path / "sh_coeffs"
    blend = tmp_path / "two_rooms_edited.blend"
    shutil.copyfile(scenes / "two_rooms_edited.blend", blend)
    proc = _bake(blend, "--only-volume", "Right", "--region", *RIGHT_REGION)

    _, old_info, old = _tree(prev_dir / "Right.shprobe")
    _, new_info, new = _tree(out / "Right.shprobe")
    origin, h = np.asarray(new_info["origin"]), float(new_info["min_cell"])
    corners = scene_export.blender_to_engine(np.array(RIGHT_REGION, dtype=np.float64).reshape(2, 3))
    lo, hi = corners.min(axis=0), corners.max(axis=0)
    face = []   # kept nodes on the shared face (engine x = 0), rendered before from Left's side
    for n in new:
        p = origin + np.array(n) * h
        if abs(p[0]) < 1e-9 and (np.any(p < lo) or np.any(p > hi)) and n in old and \
                np.frombuffer(old[n][1], np.float32)[0] > 0:
            assert new[n] == old[n]
            face.append(p)
    assert len(face) > 5

    def keys(path):
        return set(journal.read(str(path)).values)
    own = [np.array(journal.KEY.unpack(k)[:3]) for k in keys(out / "probes.shprobe.points")
           - keys(prev_dir / "probes.shprobe.points")]
    assert own   # the box's points are rendered
    radius = 3 ** 0.5 * 0.01 + 0.05
    near = [p for p in own if min(np.linalg.norm(np.array(face) - p, axis=1)) <= radius]
    assert near == []
    m = re.search(r"Schnee: (\d+) kept probe\(s\) outside the region took the previous bake's point", proc.stdout)
    assert m and int(m.group(1)) >= len(face), proc.stdout[-3000:]


def _refused(proc):
    lines = proc.stderr.strip().splitlines()
    assert proc.returncode == 3 and "Traceback" not in proc.stderr and "Traceback" not in proc.stdout
    return lines[-1]


def test_adaptive_region_rebake_refusals(scenes, previous, tmp_path):
    prev_dir, _ = previous
    shutil.copytree(prev_dir, tmp_path / "sh_coeffs")
    blend = tmp_path / "two_rooms_edited.blend"
    shutil.copyfile(scenes / "two_rooms_edited.blend", blend)
    left = tmp_path / "sh_coeffs" / "Left.shprobe"
    kept = left.read_bytes()
    region = ["--only-volume", "Left", "--region", *REGION]
    proc = run_blender(BAKE_PY, *ARGS, "--file-version", "V1", *region, blend=blend, check=False, timeout=300)
    assert _refused(proc).startswith("bake.py: error: A region rebake with Adaptive placement needs File Version 3")
    # A previous file cut short (its header intact): named, nothing written.
    left.write_bytes(kept[:len(kept) // 2])
    proc = run_blender(BAKE_PY, *ARGS, *region, blend=blend, check=False, timeout=300)
    assert _refused(proc).startswith("bake.py: error: Cannot read the previous bake of this volume, ")
    assert left.read_bytes() == kept[:len(kept) // 2]


def test_farm_rebake_refused_at_submission(scenes, previous, tmp_path):
    """What every farm job of a rebake would refuse is refused once by bake.py --farm, before
    sbatch is looked for: exit 3, the rebake's own message, no job script or log folder written."""
    prev_dir, _ = previous
    shutil.copytree(prev_dir, tmp_path / "sh_coeffs")
    blend = tmp_path / "two_rooms_edited.blend"
    shutil.copyfile(scenes / "two_rooms_edited.blend", blend)
    before = sorted(p.name for p in tmp_path.rglob("*"))
    farm = ["--farm", "slurm", "--shards", "2", "--sbatch", str(tmp_path / "no-sbatch-here")]
    proc = run_blender(BAKE_PY, *ARGS, *farm, "--only-volume", "Kitchen", blend=blend, check=False, timeout=300)
    assert _refused(proc) == ("bake.py: error: farm submission failed: No probe volume named 'Kitchen' in "
                              "collection 'ProbeVolumes' (its volumes: 'Left', 'Right')")
    proc = run_blender(BAKE_PY, *ARGS, "--samples", "4", *farm, "--only-volume", "Left", "--region", *REGION,
                       blend=blend, check=False, timeout=300)
    assert _refused(proc).startswith("bake.py: error: farm submission failed: The previous bake "
                                     "(probes.shprobe.bake.json) was made with other settings: samples 8 then, 4 now")
    assert sorted(p.name for p in tmp_path.rglob("*")) == before
