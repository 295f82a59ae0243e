"""Five errors a new user hit on their first tries with bake.py (issue 31 item 5), in real headless
Blender 3.4: each ends with one clear line on stderr naming what is wrong and what to do, no Python
traceback, and nothing lost or half written.

1. two bakes of the same output started together: the second refuses, naming the first's process;
   the first's output is the bytes of a lone bake;
2. ``--shard`` with ``--merge-shards``: a usage error naming both;
3. ``--farm slurm`` without sbatch on PATH: the message names the real ``--sbatch PATH`` option,
   and a shortened option is an error, not another option taken by its prefix (the real
   submission through ``--sbatch``: tests/farm/test_slurm.py);
4. a 240-character output name: the bake completes and resumes (no temporary name over 255 bytes);
5. ``--min-cell-size 20 --max-cell-size 40``: no maximum of 16 m that was never given.

Scenes: test_bake_hazards.py's generated sky.blend (one 4 x 4 x 2 m volume under the courtyard
sky). Runtime: about a minute on 2 cores.
"""
import re
import shutil
import signal
import time

import pytest

from conftest import requires_native, run_blender
from schnee_probes import journal as journal_mod
from schnee_probes import native
from test_bake_hazards import BAKE_PY, CELLS_2M, SCRIPTS, TINY, Running, copy_blend, digest, last_error, scenes_made_by

pytestmark = requires_native

scenes = scenes_made_by("hazard_scenes.py")


@pytest.fixture(scope="module")
def lone_bake(scenes, tmp_path_factory):
    """sha256 of probes.shprobe from sky.blend baked alone (geometry octree, 2 m cells: 4 probes, 16 px
    panoramas, 1 sample): Cycles renders the same bits for the same seed, so any bake of these
    settings that ran undisturbed writes these bytes."""
    blend = copy_blend(scenes, "sky.blend", tmp_path_factory.mktemp("lone_bake"))
    proc = bake_py(blend, "--placement", "OCTREE", *CELLS_2M, *TINY)
    assert proc.returncode == 0, proc.stdout[-2000:] + proc.stderr[-2000:]
    return digest(blend.parent / "sh_coeffs" / "probes.shprobe")


def bake_py(blend, *args, env=None, timeout=300):
    return run_blender(BAKE_PY, *args, blend=blend, check=False, timeout=timeout, env=env)


def files_under(folder):
    return sorted(str(p.relative_to(folder)) for p in folder.rglob("*"))


# ------------------------------------------------------------------ 1. two bakes of one output
def test_two_bakes_of_one_output_started_together(scenes, tmp_path, lone_bake):
    # Before: both rendered; at the first probe the second died with a JournalError traceback
    # ("created by another process at the same time", exit 1). Now the one that takes the output's
    # lock first bakes (each render slowed to 1 s: 4 s or more), the other refuses before placement.
    blend = copy_blend(scenes, "sky.blend", tmp_path)
    runs = [Running(blend, [*CELLS_2M, *TINY], {"SCHNEE_TEST_RENDER_DELAY": "1"}, pre=SCRIPTS / "slow_render.py")
            for _ in range(2)]  # started a few milliseconds apart
    results = [run.finish() for run in runs]
    assert sorted(rc for rc, _, _ in results) == [0, 3], [r[1][-1500:] + r[2][-1500:] for r in results]
    first, second = (0, 1) if results[0][0] == 0 else (1, 0)
    out = blend.parent / "sh_coeffs" / "probes.shprobe"
    _, stdout, stderr = results[second]
    assert stderr.strip().splitlines()[-1] == (
        f"bake.py: error: Another bake is writing {out} (pid {runs[first].proc.pid}); wait for it to finish "
        "or choose another output")
    assert "Traceback" not in stderr and "placing probes" not in stdout  # refused before placement
    assert "Traceback" not in results[first][2]
    # The first bake was not disturbed: the bytes of a lone bake, and nothing else left behind
    # (no journal, lock, .previous or temporary file).
    assert digest(out) == lone_bake
    assert files_under(out.parent) == ["probes.shprobe", "sky.exr"]


# ------------------------------------------------------------------ 2. --shard with --merge-shards
@pytest.mark.parametrize("args,both", [
    (["--shard", "0/2", "--merge-shards", "2"], ("--shard", "--merge-shards")),
    (["--cursor", "0", "0", "1", "--shard", "1/2"], ("--cursor", "--shard")),
    (["--cursor", "0", "0", "1", "--merge-shards", "2"], ("--cursor", "--merge-shards")),
], ids=["shard+merge", "cursor+shard", "cursor+merge"])
def test_options_that_exclude_each_other_are_a_usage_error(scenes, tmp_path, args, both):
    # Before: "bake.py: error: unexpected ValueError: a bake is either one shard or the merge of the
    # shards" after a traceback (exit 1), and --cursor --shard a TypeError at the end of the bake.
    blend = copy_blend(scenes, "sky.blend", tmp_path)
    proc = bake_py(blend, *CELLS_2M, *TINY, *args)
    assert proc.returncode == 2, proc.stdout[-2000:] + proc.stderr[-2000:]
    msg = last_error(proc)
    assert msg.startswith("blender -b scene.blend -P bake.py --: error: "), msg
    assert all(re.search(re.escape(o) + r"(?![\w-])", msg) for o in both) and "cannot be combined" in msg, msg
    assert "Traceback" not in proc.stderr
    assert files_under(tmp_path) == ["sky.blend"]  # nothing written


# ------------------------------------------------------------------ 3. --farm slurm without sbatch
@pytest.fixture
def path_without_sbatch(tmp_path):
    """An environment whose PATH holds blender (linked) and nothing else: no sbatch."""
    bin_dir = tmp_path / "bin"
    bin_dir.mkdir()
    (bin_dir / "blender").symlink_to(shutil.which("blender"))
    return {"PATH": str(bin_dir)}


def test_farm_without_sbatch_names_a_real_option(scenes, tmp_path, path_without_sbatch):
    # Before: "'sbatch' not found: ... (or pass --sbatch)", an option that did not exist; argparse
    # then took "--sbatch /usr/bin/sbatch" as --sbatch-option and wrote "#SBATCH /usr/bin/sbatch".
    blend = copy_blend(scenes, "sky.blend", tmp_path / "scene")
    proc = bake_py(blend, *CELLS_2M, *TINY, "--farm", "slurm", env=path_without_sbatch)
    assert proc.returncode == 3, proc.stdout[-2000:] + proc.stderr[-2000:]
    msg = last_error(proc)
    assert msg == ("bake.py: error: farm submission failed: 'sbatch' not found on PATH "
                   f"({path_without_sbatch['PATH']}): run the submission on a Slurm login node, add the "
                   "folder that holds sbatch to PATH, or give its path with --sbatch PATH (e.g. --sbatch "
                   "/usr/bin/sbatch)"), msg
    assert "Traceback" not in proc.stderr
    assert files_under(blend.parent) == ["sky.blend"]  # checked before any batch script is written

    # The suggested option exists: it is taken as the sbatch program (a path that is not one is
    # refused naming it), not as --sbatch-option.
    missing = tmp_path / "no" / "sbatch"
    proc = bake_py(blend, *CELLS_2M, *TINY, "--farm", "slurm", "--sbatch", missing, env=path_without_sbatch)
    assert proc.returncode == 3, proc.stdout[-2000:] + proc.stderr[-2000:]
    assert last_error(proc) == (f"bake.py: error: farm submission failed: --sbatch {missing}: no executable "
                                "file there; give the path of Slurm's sbatch program (e.g. --sbatch "
                                "/usr/bin/sbatch)"), last_error(proc)
    assert files_under(blend.parent) == ["sky.blend"]
    assert "--sbatch PATH" in bake_py(None, "--help").stdout


@pytest.mark.parametrize("short,meant", [("--sbatch-opt=--partition=bake", "--sbatch-option"),
                                         ("--merge", "--merge-shards"), ("--out", "--output")])
def test_a_shortened_option_is_an_error(scenes, tmp_path, short, meant):
    # allow_abbrev=False: argparse no longer completes a prefix to the one option it starts.
    blend = copy_blend(scenes, "sky.blend", tmp_path)
    extra = [] if "=" in short else ["2" if short == "--merge" else "//x.shprobe"]
    proc = bake_py(blend, *CELLS_2M, *TINY, short, *extra)
    assert proc.returncode == 2, proc.stdout[-2000:] + proc.stderr[-2000:]
    assert last_error(proc) == ("blender -b scene.blend -P bake.py --: error: unrecognized arguments: "
                                + " ".join([short, *extra])), last_error(proc)
    assert meant in proc.stderr  # the usage lines above it show the real option
    assert files_under(tmp_path) == ["sky.blend"]


# ------------------------------------------------------------------ 5. cells above 16 m
def test_cells_of_20_to_40_m_bake_without_a_bound_never_given(scenes, tmp_path):
    # Before: "bake.py: error: Probe placement failed: max_cell_size (16 m) is smaller than
    # min_cell_size (20 m)" (exit 3): the Adaptive placement's classification left Max Cell Size
    # out and the native default of 16 m was checked instead. Now the given sizes hold: the 4 x 4 x 2 m
    # volume lies in one 40 m cell, whose 8 corners are the probes.
    blend = copy_blend(scenes, "sky.blend", tmp_path)
    proc = bake_py(blend, "--placement", "ADAPTIVE", "--min-cell-size", "20", "--max-cell-size", "40", *TINY)
    assert proc.returncode == 0, proc.stdout[-2000:] + proc.stderr[-2000:]
    assert "16 m" not in proc.stdout + proc.stderr
    assert "bake.py: 8 probes in" in proc.stdout
    f = native.read_shprobe(str(tmp_path / "sh_coeffs" / "probes.shprobe"))
    assert f.probe_count == 8 and f.structure == "octree"
    assert f.grid_spacing == 20.0 and [int(l[3]) for l in f.leaves] == [1]  # one leaf of 20 m x 2^1
    # The geometry octree's message for the same sizes names the real limit: the volume is thinner
    # than Min Cell Size.
    proc = bake_py(blend, "--placement", "OCTREE", "--min-cell-size", "20", "--max-cell-size", "40", *TINY)
    assert proc.returncode == 3
    assert last_error(proc) == ("bake.py: error: Probe placement failed: no probe could be placed: no "
                                "occupancy-grid cell centre (spacing 20 m) lies inside the probe volumes; are "
                                "the volumes thinner than Min Cell Size?"), last_error(proc)


# ------------------------------------------------------------------ 4. a 240-character output name
LONG_NAME = "probes_" + "x" * (240 - len("probes_.shprobe")) + ".shprobe"  # 240 characters, legal


def _resumable_bake(blend, args, at):
    """bake.py with each render slowed (0.2 s), sent SIGINT once ``blend``'s long-named journal
    holds ``at`` records; (returncode, stdout, stderr)."""
    journal_path = str(blend.parent / "sh_coeffs" / (LONG_NAME + ".journal"))
    run = Running(blend, args, {}, pre=SCRIPTS / "slow_render.py")
    end = time.monotonic() + 240
    while time.monotonic() < end and run.proc.poll() is None:
        info = journal_mod.summary(journal_path)
        if info and info["records"] >= at:
            break
        time.sleep(0.01)
    run.proc.send_signal(signal.SIGINT)
    return run.finish()


def test_a_240_character_output_name_bakes_and_resumes(scenes, tmp_path, lone_bake):
    # Before: "Cannot write the bake journal …: [Errno 36] File name too long: '….journal.<pid>-<random>
    # .partial'" after the first render (exit 3): the journal's temporary name was 240 + 33 bytes.
    assert len(LONG_NAME) == 240
    expected = lone_bake

    blend = copy_blend(scenes, "sky.blend", tmp_path / "long")
    args = [*CELLS_2M, *TINY, "--output", "//sh_coeffs/" + LONG_NAME]
    rc, out, err = _resumable_bake(blend, args, at=2)
    assert rc == 130, out[-2000:] + err[-2000:]
    kept = re.search(r"; (\d+) of 4 probes kept in (\S+); the same bake run again", err)
    assert kept and 2 <= int(kept.group(1)) < 4, err[-2000:]
    assert kept.group(2) == str(blend.parent / "sh_coeffs" / (LONG_NAME + ".journal"))
    proc = bake_py(blend, "--placement", "OCTREE", *args)  # run again: resumes from the journal
    assert proc.returncode == 0, proc.stdout[-2000:] + proc.stderr[-2000:]
    assert f"{kept.group(1)} of 4 probes already baked" in proc.stdout
    assert "Traceback" not in err + proc.stderr
    folder = blend.parent / "sh_coeffs"
    assert digest(folder / LONG_NAME) == expected  # the bytes of an uninterrupted bake
    assert files_under(folder) == sorted([LONG_NAME, "sky.exr"])  # journal spent, no temporary left

    # Farm bakes of that output: the shard journals' names (240 + 21 bytes) are shortened the same
    # way by every job, so the merge finds them; the merged file has the same bytes.
    blend = copy_blend(scenes, "sky.blend", tmp_path / "farm")
    args = ["--placement", "OCTREE", *CELLS_2M, *TINY, "--output", "//sh_coeffs/" + LONG_NAME]
    for job in (["--shard", "0/2"], ["--shard", "1/2"], ["--merge-shards", "2"]):
        proc = bake_py(blend, *args, *job)
        assert proc.returncode == 0, proc.stdout[-2000:] + proc.stderr[-2000:]
    folder = blend.parent / "sh_coeffs"
    assert digest(folder / LONG_NAME) == expected
    shards = [n for n in files_under(folder) if n.endswith(".journal")]
    assert len(shards) == 2 and all(len(n.encode()) <= 255 and ".shard-" in n for n in shards), shards
