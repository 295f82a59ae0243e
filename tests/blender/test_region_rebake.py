"""Region rebake of one probe volume (issue 31 item 3; docs/region-rebake.md), in real headless
Blender 3.4 through bake.py: after an edit inside the volume Left, ``--only-volume Left`` renders
Left's probes only, writes Left.shprobe and the bake record, and leaves Right.shprobe and sky.exr
byte for byte; its Left.shprobe is the bytes of a full bake of the edited scene (the expected value:
Cycles renders the same bits for the same position and seed). Killed, it resumes from its own
journal; sharded and merged it gives the same bytes; it refuses, in one line and without a
traceback, an unknown volume, a bake without a previous one, other settings (naming them) and
One File per Volume off. The panel's Rebake Selected Region (the box of the active object) writes
the bytes of the headless ``--region`` rebake with the same box, in Blender 3.4, 4.3 and 5.2 (the
chroots of scripts/blender-chroot.sh), and in a UI session (Xvfb) through Bake Many Probes? and the
modal bake. Scenes: scripts/region_scenes.py (the window room in two volumes, 1 m cells: 16 probes
each, 15 in Left once the crate is in). Runtime: about 2 minutes on 2 cores, plus about 30 s per
chroot."""
import contextlib
import hashlib
import json
import os
import re
import shutil
import signal
import subprocess
import time
from pathlib import Path

import numpy as np
import pytest

from conftest import ADDON_DIR, BLENDER_CHROOT as CHROOT, REPO, addon_chroot, requires_native, run_blender
from schnee_probes import journal, native
from test_bake_hazards import SCRIPTS, TINY, Running, bake, last_error, scenes_made_by

pytestmark = requires_native

CELLS = ["--min-cell-size", "1", "--max-cell-size", "1"]
PER_VOLUME = ["--per-volume-files", "on"]
ARGS = [*CELLS, *TINY, *PER_VOLUME]

scenes = scenes_made_by("region_scenes.py")


def _sha(path):
    return hashlib.sha256(path.read_bytes()).hexdigest()


def _baked(scenes, folder, name):
    """``name`` copied into ``folder`` and baked whole (both volumes): the folder's sh_coeffs."""
    folder.mkdir(parents=True, exist_ok=True)
    blend = folder / name
    shutil.copyfile(scenes / name, blend)
    proc = bake(blend, *ARGS)
    assert proc.returncode == 0, proc.stdout[-2000:] + proc.stderr[-2000:]
    return folder / "sh_coeffs"


@pytest.fixture(scope="module")
def previous(scenes, tmp_path_factory):
    """The full bake of the scene before the edit: its sh_coeffs folder."""
    return _baked(scenes, tmp_path_factory.mktemp("previous"), "two_rooms.blend")


@pytest.fixture(scope="module")
def edited_full(scenes, tmp_path_factory):
    """The full bake of the edited scene: the reference a rebake of Left must equal."""
    return _baked(scenes, tmp_path_factory.mktemp("edited_full"), "two_rooms_edited.blend")


def _edited(scenes, previous, tmp_path):
    """The previous bake's files and the edited scene in one folder: (blend, sh_coeffs)."""
    shutil.copytree(previous, tmp_path / "sh_coeffs")
    blend = tmp_path / "two_rooms_edited.blend"
    shutil.copyfile(scenes / "two_rooms_edited.blend", blend)
    return blend, tmp_path / "sh_coeffs"


def _arrays(path):
    """The probes as read back (a v1 file has no positions: its grid places them)."""
    f = native.read_shprobe(str(path))
    return [np.zeros(0) if getattr(f, k) is None else np.asarray(getattr(f, k))
            for k in ("positions", "coeffs", "validity", "grid")]


def test_rebake_renders_one_volume_and_keeps_the_others(scenes, previous, edited_full, tmp_path):
    blend, out = _edited(scenes, previous, tmp_path)
    kept = {p.name: _sha(p) for p in out.iterdir()}
    log = tmp_path / "renders.log"
    run = Running(blend, [*ARGS, "--only-volume", "Left"], {"SCHNEE_TEST_RENDER_LOG": str(log)},
                  pre=SCRIPTS / "count_renders.py")
    rc, stdout, stderr = run.finish()
    assert rc == 0, stdout[-2000:] + stderr[-2000:]
    # Left's probes only: 16 cells of 1 m, one inside the crate (the full bake rendered 32).
    assert len(log.read_text().splitlines()) == 15
    assert "bake.py: 15 probes in" in stdout
    assert sorted(re.findall(r"bake\.py: wrote (\S+)", stdout)) == [
        str(out / n) for n in ("Left.shprobe", "probes.shprobe.bake.json", "probes.shprobe.points")]
    # Right and the sky: the previous bake's bytes; Left: the full bake of the edited scene's bytes.
    assert _sha(out / "Right.shprobe") == kept["Right.shprobe"]
    assert _sha(out / "sky.exr") == kept["sky.exr"]
    for a, b in zip(_arrays(out / "Right.shprobe"), _arrays(previous / "Right.shprobe")):
        assert a.tobytes() == b.tobytes()
    assert _sha(out / "Left.shprobe") != kept["Left.shprobe"]
    assert _sha(out / "Left.shprobe") == _sha(edited_full / "Left.shprobe")
    # The record: Left's scene is the edited one, Right's the previous bake's.
    rec = json.loads((out / "probes.shprobe.bake.json").read_text())
    old = json.loads((previous / "probes.shprobe.bake.json").read_text())
    full = json.loads((edited_full / "probes.shprobe.bake.json").read_text())
    assert rec["volumes"]["Right"] == old["volumes"]["Right"]
    assert rec["volumes"]["Left"] == full["volumes"]["Left"] != old["volumes"]["Left"]
    assert not (out / "Left.shprobe.journal").exists()  # spent once the file is written


@pytest.mark.parametrize("args,expected", [
    (["--only-volume", "Kitchen"], "No probe volume named 'Kitchen' in collection 'ProbeVolumes' (its volumes: "
                                   "'Left', 'Right')"),
    (["--only-volume", "Left", "--samples", "2"], "was made with other settings: samples 1 then, 2 now"),
    (["--only-volume", "Left", "--per-volume-files", "off"], "needs One File per Volume"),
    (["--only-volume", "Left", "--max-band", "3"], "max_band 2 then, 3 now"),
], ids=["unknown-volume", "other-samples", "one-file", "other-band"])
def test_rebake_refuses_clearly(scenes, previous, tmp_path, args, expected):
    blend, out = _edited(scenes, previous, tmp_path)
    kept = {p.name: _sha(p) for p in out.iterdir()}
    proc = bake(blend, *ARGS, *args)
    assert proc.returncode == 3, proc.stdout[-2000:] + proc.stderr[-2000:]
    assert expected in last_error(proc) and last_error(proc).startswith("bake.py: error: ")
    assert "Traceback" not in proc.stderr
    assert {p.name: _sha(p) for p in out.iterdir()} == kept


def test_rebake_without_a_previous_bake_is_refused(scenes, previous, tmp_path):
    blend, out = _edited(scenes, previous, tmp_path)
    (out / "Right.shprobe").unlink()
    proc = bake(blend, *ARGS, "--only-volume", "Left")
    assert proc.returncode == 3 and "Traceback" not in proc.stderr
    assert last_error(proc) == (f"bake.py: error: No previous bake to keep for volume 'Right': {out / 'Right.shprobe'} "
                                "is missing; bake every volume once, then rebake 'Left'")
    (out / "probes.shprobe.bake.json").unlink()
    proc = bake(blend, *ARGS, "--only-volume", "Left")
    assert proc.returncode == 3 and "Traceback" not in proc.stderr
    assert "No previous bake to keep" in last_error(proc) and "probes.shprobe.bake.json is missing" in last_error(proc)
    assert not (out / "Left.shprobe.journal").exists()
    # --cursor with --only-volume: a usage error.
    proc = bake(blend, *ARGS, "--only-volume", "Left", "--cursor", "0", "0", "1")
    assert proc.returncode == 2 and "--cursor cannot be combined with --only-volume" in proc.stderr


def test_rebake_killed_resumes_and_shards_merge(scenes, previous, edited_full, tmp_path):
    expected = _sha(edited_full / "Left.shprobe")
    blend, out = _edited(scenes, previous, tmp_path / "killed")
    right = _sha(out / "Right.shprobe")
    run = Running(blend, [*ARGS, "--only-volume", "Left"], {}, pre=SCRIPTS / "slow_render.py")
    path = out / "Left.shprobe.journal"
    end = time.monotonic() + 240
    while time.monotonic() < end and run.proc.poll() is None:   # killed once 3 probes are journaled
        info = journal.summary(str(path))
        if info and info["records"] >= 3:
            break
        time.sleep(0.01)
    run.proc.send_signal(signal.SIGKILL)
    run.finish()
    kept = len(journal.read(str(path)).values)
    assert 3 <= kept < 15
    proc = bake(blend, *ARGS, "--only-volume", "Left")
    assert proc.returncode == 0, proc.stdout[-2000:] + proc.stderr[-2000:]
    assert f"resuming from {path} and the previous bake's kept points: {kept} of 15 probes already baked, " \
           f"{15 - kept} to render" in proc.stdout
    assert _sha(out / "Left.shprobe") == expected and _sha(out / "Right.shprobe") == right
    # Two shards and their merge, beside Left's file.
    blend, out = _edited(scenes, previous, tmp_path / "shards")
    for k in range(2):
        proc = bake(blend, *ARGS, "--only-volume", "Left", "--shard", f"{k}/2")
        assert proc.returncode == 0, proc.stdout[-2000:] + proc.stderr[-2000:]
        assert (out / f"Left.shprobe.shard-{k}-of-2.journal").exists()
    proc = bake(blend, *ARGS, "--only-volume", "Left", "--merge-shards", "2")
    assert proc.returncode == 0, proc.stdout[-2000:] + proc.stderr[-2000:]
    assert "15 of 15 probes already baked, 0 to render" in proc.stdout
    assert _sha(out / "Left.shprobe") == expected and _sha(out / "Right.shprobe") == right


def test_panel_button_rebakes_the_active_volume(scenes, previous, edited_full, tmp_path):
    blend, out = _edited(scenes, previous, tmp_path)
    right, sky = _sha(out / "Right.shprobe"), _sha(out / "sky.exr")
    proc = run_blender(SCRIPTS / "region_operator.py", blend=blend, timeout=300)
    r = json.loads([line for line in proc.stdout.splitlines() if line.startswith("RESULT ")][-1][7:])
    assert r["label"] == "Rebake Selected Volume"
    assert (r["poll_none"], r["poll_crate"], r["poll_left"]) == (False, False, True)
    assert r["result"] == ["FINISHED"], r
    assert r["files"] == ["Left.shprobe", "probes.shprobe.bake.json", "probes.shprobe.points"] and r["message"].startswith("Baked 15 probes")
    assert _sha(out / "Left.shprobe") == _sha(edited_full / "Left.shprobe")
    assert _sha(out / "Right.shprobe") == right and _sha(out / "sky.exr") == sky


# The crate's corner of Left with a margin (Blender coordinates): the probe centres (-1.5|-0.5,
# -1.5|-0.5, 0.5) lie inside, (-1.5, -1.5, 0.5) within the crate itself (pruned).
REGION = ["-1.8", "-1.8", "0", "-0.2", "-0.2", "1"]


def _by_cell(path):
    """{engine-space cell centre (rounded to 1 mm): coefficient bytes} of a dense-grid file."""
    f = native.read_shprobe(str(path))
    dims, origin, h = f.grid_dims, np.asarray(f.grid_origin), f.grid_spacing
    out = {}
    for flat, probe in enumerate(np.asarray(f.grid)):
        if probe >= 0:
            ijk = np.array([flat % dims[0], flat // dims[0] % dims[1], flat // (dims[0] * dims[1])])
            out[tuple(np.round(origin + (ijk + 0.5) * h, 3))] = np.asarray(f.coeffs[probe]).tobytes()
    return out


def test_region_inside_a_volume_keeps_the_probes_outside(scenes, previous, edited_full, tmp_path):
    blend, out = _edited(scenes, previous, tmp_path)
    right = _sha(out / "Right.shprobe")
    log = tmp_path / "renders.log"
    run = Running(blend, [*ARGS, "--only-volume", "Left", "--region", *REGION], {"SCHNEE_TEST_RENDER_LOG": str(log)},
                  pre=SCRIPTS / "count_renders.py")
    rc, stdout, stderr = run.finish()
    assert rc == 0, stdout[-2000:] + stderr[-2000:]
    assert len(log.read_text().splitlines()) == 3   # the region's probes outside the crate, nothing else
    assert "rebake of 'Left': 28 point(s) of the previous bake kept outside the region, 4 inside it baked again" \
        in stdout   # the 4th inside: the one in the crate, pruned now
    assert "kept points: 12 of 15 probes already baked, 3 to render" in stdout
    assert "bake.py: 3 render(s) by this run, 12 taken from journals or the previous bake's kept points" in stdout
    new, old, full = (_by_cell(d / "Left.shprobe") for d in (out, previous, edited_full))
    assert set(new) == set(full) and len(new) == 16  # the crate's cell maps to a neighbour's probe
    lo, hi = np.array([-1.8, 0.0, 0.2]), np.array([-0.2, 1.0, 1.8])   # REGION in engine space (x, z, -y)
    inside = [c for c in new if np.all(np.array(c) >= lo) and np.all(np.array(c) <= hi)]
    assert len(inside) == 4
    for c in new:  # outside: the previous bake's bits; inside: the edited scene's
        assert new[c] == (full[c] if c in inside else old[c])
    assert _sha(out / "Right.shprobe") == right
    # The kept points: the 28 outside the region and the region's 3 new ones (the crate's is gone).
    assert len(journal.read(str(out / "probes.shprobe.points")).values) == 31


def test_region_refusals(scenes, previous, tmp_path):
    blend, out = _edited(scenes, previous, tmp_path)
    proc = bake(blend, *ARGS, "--only-volume", "Left", "--region", "1", "1", "0.5", "1.5", "1.5", "1")
    assert proc.returncode == 3 and "Traceback" not in proc.stderr
    assert last_error(proc) == ("bake.py: error: The region lies outside volume 'Left' (its bounds, Blender "
                                "coordinates: (-2, -2, 0) .. (0, 2, 2)); give a box that meets the volume")
    proc = bake(blend, *ARGS, "--region", *REGION)
    assert proc.returncode == 2 and "--region needs --only-volume NAME" in proc.stderr
    (out / "probes.shprobe.points").unlink()
    proc = bake(blend, *ARGS, "--only-volume", "Left", "--region", *REGION)
    assert proc.returncode == 3 and "Traceback" not in proc.stderr
    assert "No previous bake to keep" in last_error(proc) and "probes.shprobe.points is missing" in last_error(proc)


# Rebake Selected Region (the panel's button): the box of a selected object instead of --region. The
# same box as REGION, drawn by a hidden cube mesh "RegionBox" (and then a Cube empty) in the edited scene.
BOX_SCRIPT = SCRIPTS / "region_box_operator.py"
BOX_VERSIONS = {"host": (3, 4), "trixie": (4, 3), "sid": (5, 2)}


@contextlib.contextmanager
def _blender_in(suite, tmp_path):
    """(run, host_dir, inner_dir) for Blender of ``suite``: ``run(args, env)`` runs ``blender -b
    --factory-startup --python-exit-code 1 ARGS`` there; host_dir (a folder this process writes) is
    inner_dir for that Blender. The host: tmp_path itself; a chroot (scripts/blender-chroot.sh): a folder
    in it holding this tree's add-on with the package's bundled libraries (build/addon_zip, which the
    chroots lack), bake.py, the test scripts; removed at the end. Also gives the paths of the add-on's
parent folder, bake.py and the scripts as that Blender sees them."""
    cmd = ["blender", "-b", "--factory-startup", "--python-exit-code", "1"]
    if suite == "host":
        def run(args, env=None):
            full = {**os.environ, "PYTHONPATH": str(ADDON_DIR), "SCHNEE_REPO": str(REPO), **(env or {})}
            return subprocess.run([*cmd, *map(str, args)], capture_output=True, text=True, timeout=300, env=full)
        yield run, tmp_path, tmp_path, {"addon": ADDON_DIR, "bake": REPO / "bake.py", "scripts": SCRIPTS}
        return
    root, libs = addon_chroot(suite)
    inner = Path("/tmp") / f"schnee-region-box-{os.getpid()}-{suite}"
    outer = root / inner.relative_to("/")
    shutil.rmtree(outer, ignore_errors=True)
    shutil.copytree(ADDON_DIR / "schnee_probes", outer / "addon" / "schnee_probes",
                    ignore=shutil.ignore_patterns("__pycache__"))
    shutil.copytree(libs, outer / "addon" / "schnee_probes" / "lib")
    shutil.copy(REPO / "bake.py", outer / "bake.py")   # finds addon/ beside it
    for name in (BOX_SCRIPT.name, "count_renders.py"):
        shutil.copy(SCRIPTS / name, outer / name)

    def run(args, env=None):
        envs = [f"{k}={v}" for k, v in (env or {}).items()]
        return subprocess.run([str(CHROOT), "run", suite, "--", "env", *envs, *cmd, *map(str, args)],
                              capture_output=True, text=True, timeout=300)
    try:
        yield run, outer, inner, {"addon": inner / "addon", "bake": inner / "bake.py", "scripts": inner}
    finally:
        shutil.rmtree(outer, ignore_errors=True)


def _tracebacks(text):
    """Each Python traceback in ``text``: its frames (the indented lines) and the exception's line."""
    out, lines = [], text.splitlines()
    for i, line in enumerate(lines):
        if line.startswith("Traceback (most recent call last):"):
            j = i + 1
            while j < len(lines) and lines[j].startswith(" "):
                j += 1
            out.append("\n".join(lines[i:j + 1]))
    return out


def _box_result(proc):
    lines = [line[line.index("RESULT {") + 7:] for line in proc.stdout.splitlines() if "RESULT {" in line]
    assert proc.returncode == 0 and lines, proc.stdout[-4000:] + proc.stderr[-3000:]
    return json.loads(lines[-1])


@pytest.mark.parametrize("suite", ["host", pytest.param("trixie", marks=pytest.mark.chroot),
                                   pytest.param("sid", marks=pytest.mark.chroot)])
def test_panel_region_button_rebakes_the_box_of_the_active_object(scenes, previous, request, suite, tmp_path):
    """In Blender 3.4, 4.3 and 5.2: the previous bake and the headless ``--only-volume Left --region
    REGION`` rebake made by the same Blender are the expected values; the button with the box of
    "RegionBox" (then of a Cube empty) must write the bytes of that headless rebake, render only the
    region's 3 probes and refuse a box over both volumes or outside them, writing nothing."""
    with _blender_in(suite, tmp_path) as (run, host, inner, paths):  # the chroot's folder goes at the end
        if suite == "host":
            prev = previous
        else:   # this Blender's own previous bake (Cycles' bits differ between releases)
            (host / "prev").mkdir()
            shutil.copyfile(scenes / "two_rooms.blend", host / "prev" / "two_rooms.blend")
            proc = run([inner / "prev" / "two_rooms.blend", "-P", paths["bake"], "--", "--placement", "OCTREE", *ARGS])
            assert proc.returncode == 0, proc.stdout[-3000:] + proc.stderr[-3000:]
            prev = host / "prev" / "sh_coeffs"
        for name in ("head", "op"):
            shutil.copytree(prev, host / name / "sh_coeffs")
            shutil.copyfile(scenes / "two_rooms_edited.blend", host / name / "two_rooms_edited.blend")
        proc = run([inner / "head" / "two_rooms_edited.blend", "-P", paths["bake"], "--", "--placement", "OCTREE",
                    *ARGS, "--only-volume", "Left", "--region", *REGION])
        assert proc.returncode == 0, proc.stdout[-3000:] + proc.stderr[-3000:]
        before = {p.name: _sha(p) for p in (host / "op" / "sh_coeffs").iterdir()}
        proc = run([inner / "op" / "two_rooms_edited.blend", "-P", paths["scripts"] / BOX_SCRIPT.name, "--",
                    paths["addon"], *REGION], env={"SCHNEE_TEST_RENDER_LOG": inner / "op" / "renders.log"})
        r = _box_result(proc)
        renders = (host / "op" / "renders.log").read_text().splitlines()
        head, out = host / "head" / "sh_coeffs", host / "op" / "sh_coeffs"
        by_cell = {name: _by_cell(d / "Left.shprobe") for name, d in (("prev", prev), ("head", head), ("op", out))}
        head_points, op_points = (journal.read(str(d / "probes.shprobe.points")) for d in (head, out))
        head_sha = {p.name: _sha(p) for p in head.iterdir()}
    assert tuple(r["version"][:2]) == BOX_VERSIONS[suite] and r["label"] == "Rebake Selected Region"
    # No traceback of ours (5.2's Debian package prints one of its own bl_pkg at every start: cattrs missing).
    assert not [t for t in _tracebacks(proc.stdout + proc.stderr) if "schnee" in t or "region_box" in t]
    # poll: an object with a box that is not a volume (the mesh, the Cube empty); not nothing, a lamp,
    # a Plain Axes empty or the volume itself.
    assert r["polls"] == {"None": False, "Lamp": False, "Left": False, "CubeEmpty": True, "Axes": False,
                          "RegionBox": True}
    # The refusals: one sentence each, the operator's report (background mode raises it), nothing written;
    # the third is the bake's own (region.py's text), passed on by the button as its report.
    assert r["before"] == before
    both = ("The box of 'RegionBox' meets volumes 'Left' and 'Right': a region rebake works in one volume; "
            "make the box smaller or rebake each volume")
    none = ("The box of 'RegionBox' meets no probe volume of collection 'ProbeVolumes' (its volumes: 'Left' and "
            "'Right'): move or scale it so that it lies in the volume to rebake")
    one_file = ("Rebaking volume 'Left' alone needs One File per Volume (--per-volume-files on): without it every "
                "volume is in one probes.shprobe, which a rebake would replace whole; turn it on and bake every volume "
                "once")
    for key, text in (("both", both), ("none", none), ("one_file", one_file)):
        assert r[key]["result"] == ["CANCELLED"] and r[key]["message"] == text
        assert r[key]["error"].strip() == f"Error: {text}" and r[key]["files"] == []
        assert r[f"after_{key}"] == before
    # The box's rebake: FINISHED, the 3 probes of the region outside the crate rendered (the headless
    # --region test's count), Left's file, the record and the kept points written; the bytes of the
    # headless rebake with REGION, Right and the sky the previous bake's.
    for key in ("box", "empty"):
        assert r[key]["result"] == ["FINISHED"] and r[key]["error"] is None, r[key]
        assert r[key]["files"] == ["Left.shprobe", "probes.shprobe.bake.json", "probes.shprobe.points"]
        assert r[key]["message"].startswith("Baked 15 probes in ")
    assert len(renders) == 6 and renders[:3] == renders[3:]   # 3 for the box, the same 3 for the empty
    after = r["after_box"]
    assert after["Left.shprobe"] == head_sha["Left.shprobe"] != before["Left.shprobe"]
    assert after["probes.shprobe.bake.json"] == head_sha["probes.shprobe.bake.json"]
    assert (after["Right.shprobe"], after["sky.exr"]) == (before["Right.shprobe"], before["sky.exr"])
    assert r["after_empty"] == after   # the Cube empty of the same world box: the same bytes again
    # The kept points: the headless rebake's (their manifest names the .blend, which differs).
    assert len(op_points.values) == len(head_points.values) == 31
    assert {k: v.tobytes() for k, v in op_points.values.items()} == \
        {k: v.tobytes() for k, v in head_points.values.items()}
    # Per probe: outside the box the previous bake's bits, inside (3 rendered + the crate's cell)
    # new ones; on the host, the inside ones are the full edited bake's (as the --region test).
    lo, hi = np.array([-1.8, 0.0, 0.2]), np.array([-0.2, 1.0, 1.8])   # REGION in engine space (x, z, -y)
    new, old = by_cell["op"], by_cell["prev"]
    inside = [c for c in new if np.all(np.array(c) >= lo) and np.all(np.array(c) <= hi)]
    assert len(new) == 16 and len(inside) == 4 and new == by_cell["head"]
    assert all(new[c] == old[c] for c in new if c not in inside)
    assert sum(new[c] != old[c] for c in inside) >= 3
    if suite == "host":
        full = _by_cell(request.getfixturevalue("edited_full") / "Left.shprobe")
        assert all(new[c] == full[c] for c in inside)


@pytest.mark.skipif(shutil.which("xvfb-run") is None, reason="xvfb-run not installed")
def test_panel_region_button_in_a_ui_session(scenes, previous, tmp_path):
    """Blender 3.4 with a window (Xvfb, scripts/region_box_modal.py): the button's bake above Confirm
    Above asks first and writes nothing; a simulated Return on Bake Many Probes? runs it modally with
    the region the dialog was given: the bytes of the headless ``--region`` rebake with the same box
    (the expected value, made here by bake.py); then a box over both volumes is refused."""
    head = tmp_path / "head"
    shutil.copytree(previous, head / "sh_coeffs")
    shutil.copyfile(scenes / "two_rooms_edited.blend", head / "two_rooms_edited.blend")
    proc = bake(head / "two_rooms_edited.blend", *ARGS, "--only-volume", "Left", "--region", *REGION)
    assert proc.returncode == 0, proc.stdout[-2000:] + proc.stderr[-2000:]
    blend, out = _edited(scenes, previous, tmp_path / "ui")
    before = {p.name: _sha(p) for p in out.iterdir()}
    cmd = ["xvfb-run", "-a", "-s", "-screen 0 1280x800x24", "blender", str(blend), "--factory-startup",
           "--enable-event-simulate", "--python-exit-code", "1", "-P", str(SCRIPTS / "region_box_modal.py"), "--",
           str(ADDON_DIR), *REGION]
    env = {**os.environ, "PYTHONPATH": str(ADDON_DIR), "SCHNEE_REPO": str(REPO)}
    r = _box_result(subprocess.run(cmd, capture_output=True, text=True, timeout=600, env=env))
    assert r["before"] == r["after_large"] == before
    assert r["large"] == [["CANCELLED"], None] and not r["large_running"]
    assert r["large_message"].startswith("15 probes (estimated ") and "limit of 10 (Confirm Above)" in r["large_message"]
    assert r["running_seen"] and r["ticks_waited"] <= 1200
    assert r["confirmed_message"].startswith("Baked 15 probes in ")
    assert r["files"] == ["Left.shprobe", "probes.shprobe.bake.json", "probes.shprobe.points"]
    after = r["after_confirmed"]
    for name in ("Left.shprobe", "probes.shprobe.bake.json"):
        assert after[name] == _sha(head / "sh_coeffs" / name)
    assert after["Left.shprobe"] != before["Left.shprobe"]
    assert (after["Right.shprobe"], after["sky.exr"]) == (before["Right.shprobe"], before["sky.exr"])
    text = ("The box of 'RegionBox' meets volumes 'Left' and 'Right': a region rebake works in one volume; "
            "make the box smaller or rebake each volume")
    assert r["both"] == [["CANCELLED"], f"Error: {text}\n"] and r["both_message"] == text
    assert r["after_both"] == after
