"""The farm bake on a real Slurm cluster (issue 15; docs/farm.md): a one-node cluster of Debian's
slurm-wlm on localhost, started and stopped here (slurm_cluster.py). `bake.py --farm slurm
--shards 2` writes and submits one requeueable job array per stage of the adaptive placement, each
after the previous (afterok), and a merge job after the last; one task of the first array is killed
mid-run and requeued by Slurm (`scontrol requeue`, what Slurm does on a node failure
or preemption); it resumes from its shard journal; the merged .shprobe equals a local bake of the
same scene byte for byte (the expected bytes come from that local bake). A region rebake of one volume
(`--farm slurm --only-volume Left --region ...`) reaches every job and writes the bytes of the same
rebake made here (docs/region-rebake.md "Journal and farm"). Runtime: ~2 min."""
import hashlib
import json
import re
import shutil
import sys
import time
from pathlib import Path

import pytest

from conftest import REPO, requires_native, run_blender
from schnee_probes import adaptive, journal

sys.path.insert(0, str(Path(__file__).resolve().parent))
from slurm_cluster import SlurmCluster  # noqa: E402

pytestmark = requires_native
SCRIPTS = REPO / "tests" / "blender" / "scripts"
# Adaptive placement from 1 m cells down to 0.5 m: 3 stages (first layer, tests, finer probes), so 3
# chained job arrays.
BAKE_ARGS = ["--min-cell-size", "0.5", "--max-cell-size", "1", "--panorama-resolution", "16", "--samples", "2"]


@pytest.fixture(scope="module")
def cluster():
    if not shutil.which("slurmctld") or not shutil.which("munged"):
        pytest.fail("slurm-wlm and munge are not installed (scripts/deps.sh installs them)")
    c = SlurmCluster(cpus=2).start()
    try:
        yield c
    finally:
        c.stop()


def _sha(path):
    return hashlib.sha256(Path(path).read_bytes()).hexdigest()


def test_farm_bake_with_a_requeued_task_equals_a_local_bake(cluster, tmp_path):
    run_blender(SCRIPTS / "resume_scene.py", tmp_path, timeout=120)
    local, farm = tmp_path / "local", tmp_path / "farm"
    for d in (local, farm):
        d.mkdir()
        shutil.copy(tmp_path / "window_room.blend", d / "scene.blend")
    proc = run_blender(REPO / "bake.py", *BAKE_ARGS, blend=local / "scene.blend", timeout=600)
    count = int(re.search(r"bake\.py: adaptive placement: \d+ pass\(es\), (\d+) points rendered", proc.stdout).group(1))

    proc = run_blender(REPO / "bake.py", *BAKE_ARGS, "--farm", "slurm", "--shards", "2",
                       blend=farm / "scene.blend", env={"SLURM_CONF": cluster.env["SLURM_CONF"]})
    m = re.search(r"submitted (\d+) shard array\(s\) (\d+)[\d, ]* \(2 tasks each.* merge job (\d+)", proc.stdout)
    assert m, proc.stdout[-2000:]
    assert int(m.group(1)) == adaptive.stage_bound(0.5, 1.0)   # one array per stage (3 per pass + 2)
    array, merge = m.group(2), m.group(3)
    out = farm / "sh_coeffs"
    assert (out / "probes.shprobe.farm" / "shards.sbatch").exists()

    # Kill shard 1 mid-run: once its journal holds 10 probes, Slurm requeues it (the running task
    # is killed). A requeued job waits 120 s before it is eligible again (Slurm's rule); the test
    # makes it eligible at once.
    shard1 = out / "probes.shprobe.shard-1-of-2.journal"
    end = time.monotonic() + 300
    while time.monotonic() < end:
        info = journal.summary(str(shard1))
        if info and info["records"] >= 10:
            break
        time.sleep(0.05)
    else:
        pytest.fail("shard 1 never got going:\n" + cluster.logs())
    cluster.run("scontrol", "requeue", f"{array}_1")
    kept_at_requeue = journal.summary(str(shard1))["records"]
    assert 10 <= kept_at_requeue < count // 2 + 1
    time.sleep(2)
    cluster.run("scontrol", "update", f"jobid={array}_1", "StartTime=now", check=False)

    end = time.monotonic() + 600
    while time.monotonic() < end and cluster.job_state(merge) not in (["COMPLETED"], ["FAILED"], ["CANCELLED"]):
        time.sleep(1)
    logs = "\n".join(p.read_text(errors="replace")[-3000:] for p in sorted((out / "probes.shprobe.farm").glob("*.log")))
    assert cluster.job_state(merge) == ["COMPLETED"], logs + cluster.logs()
    # The requeued task resumed from its journal instead of starting over.
    shard_log = (out / "probes.shprobe.farm" / f"shard-{array}_1.log").read_text(errors="replace")
    resumed = re.search(r"resuming from .*shard-1-of-2\.journal: \d+ of \d+ probes already baked", shard_log)
    assert resumed, shard_log[-3000:]
    assert _sha(out / "probes.shprobe") == _sha(local / "sh_coeffs" / "probes.shprobe")


def test_sbatch_option_names_the_program_when_path_has_none(cluster, tmp_path):
    # Issue 31: with no sbatch on PATH the message suggests --sbatch PATH. That option is real: the
    # jobs are submitted with the program it names (held with --hold and cancelled here: what is
    # checked is the submission), and it is not taken for --sbatch-option by its prefix (before,
    # argparse wrote "#SBATCH /usr/bin/sbatch" into both batch scripts).
    run_blender(SCRIPTS / "resume_scene.py", tmp_path, timeout=120)
    bin_dir = tmp_path / "bin"
    bin_dir.mkdir()
    (bin_dir / "blender").symlink_to(shutil.which("blender"))
    env = {"SLURM_CONF": cluster.env["SLURM_CONF"], "PATH": str(bin_dir)}
    sbatch = shutil.which("sbatch")
    proc = run_blender(REPO / "bake.py", *BAKE_ARGS, "--farm", "slurm", "--shards", "2", "--sbatch", sbatch,
                       "--sbatch-option=--hold", blend=tmp_path / "window_room.blend", env=env, timeout=300)
    m = re.search(r"submitted (\d+) shard array\(s\) ([\d, ]+) \(2 tasks each.* merge job (\d+)", proc.stdout)
    assert m, proc.stdout[-2000:] + proc.stderr[-2000:]
    ids = [j.strip() for j in m.group(2).split(",")] + [m.group(3)]
    assert len(ids) == adaptive.stage_bound(0.5, 1.0) + 1
    try:
        for job in ids:
            out = cluster.run("scontrol", "-o", "show", "job", job).stdout
            assert "JobState=PENDING" in out and "Reason=JobHeldUser" in out, out
    finally:
        cluster.run("scancel", *ids, check=False)
    folder = tmp_path / "sh_coeffs" / "probes.shprobe.farm"
    for name in ("shards.sbatch", "merge.sbatch"):
        lines = (folder / name).read_text().splitlines()
        assert [l for l in lines if l.startswith("#SBATCH --hold")] == ["#SBATCH --hold"]
        assert not any(sbatch in l for l in lines), lines  # neither an #SBATCH line nor a bake option


# A region rebake on the farm (issue 31 item 3; docs/region-rebake.md "Journal and farm"): the window
# room in two volumes of tests/blender/scripts/region_scenes.py, 1 m cells of the geometry octree (one
# stage: one shard array), test_region_rebake.py's tiny settings and crate region.
REGION_ARGS = ["--placement", "OCTREE", "--min-cell-size", "1", "--max-cell-size", "1", "--panorama-resolution",
               "16", "--samples", "1", "--per-volume-files", "on"]
REBAKE = ["--only-volume", "Left", "--region", "-1.8", "-1.8", "0", "-0.2", "-0.2", "1"]
SUBMITTED = r"submitted 1 shard array\(s\) (\d+) \(2 tasks each.* merge job (\d+)"


def _wait(cluster, job, timeout=300):
    end = time.monotonic() + timeout
    while time.monotonic() < end and cluster.job_state(job) not in (["COMPLETED"], ["FAILED"], ["CANCELLED"]):
        time.sleep(1)
    return cluster.job_state(job)


def test_farm_region_rebake_equals_a_local_rebake(cluster, tmp_path):
    # The previous bake: both volumes of the scene before the edit, baked here. Then the edited scene
    # (the crate in Left) beside a copy of that bake twice: rebaked here, and through sbatch with 2 shards.
    run_blender(SCRIPTS / "region_scenes.py", tmp_path, timeout=120)
    previous = tmp_path / "previous"
    previous.mkdir()
    shutil.copy(tmp_path / "two_rooms.blend", previous / "scene.blend")
    run_blender(REPO / "bake.py", *REGION_ARGS, blend=previous / "scene.blend", timeout=300)
    old = previous / "sh_coeffs"
    kept = {p.name: _sha(p) for p in old.iterdir()}
    assert {"Left.shprobe", "Right.shprobe", "sky.exr", "probes.shprobe.bake.json",
            "probes.shprobe.points"} <= set(kept)
    local, farm = tmp_path / "local", tmp_path / "farm"
    for d in (local, farm):
        shutil.copytree(old, d / "sh_coeffs")
        shutil.copy(tmp_path / "two_rooms_edited.blend", d / "scene.blend")
    run_blender(REPO / "bake.py", *REGION_ARGS, *REBAKE, blend=local / "scene.blend", timeout=300)

    proc = run_blender(REPO / "bake.py", *REGION_ARGS, *REBAKE, "--farm", "slurm", "--shards", "2",
                       blend=farm / "scene.blend", env={"SLURM_CONF": cluster.env["SLURM_CONF"]}, timeout=120)
    m = re.search(SUBMITTED, proc.stdout)
    assert m, proc.stdout[-2000:]
    array, merge = m.groups()
    out = farm / "sh_coeffs"
    folder = out / "probes.shprobe.farm"   # the main output's farm folder, not Left's
    state = _wait(cluster, merge)
    logs = {p.name: p.read_text(errors="replace") for p in sorted(folder.glob("*.log"))}
    assert state == ["COMPLETED"], "\n".join(t[-3000:] for t in logs.values()) + cluster.logs()

    # The option reached every job: both batch scripts carry it, both shards and the merge rebaked Left
    # (each job's log), and the shards journaled beside Left's file.
    for name in ("shards.sbatch", "merge.sbatch"):
        assert " --only-volume Left --region -1.8 -1.8 0 -0.2 -0.2 1 " in (folder / name).read_text()
    assert sorted(logs) == [f"merge-{merge}.log", f"shard-{array}_0.log", f"shard-{array}_1.log"]
    for name, text in logs.items():
        assert "rebake of 'Left': 28 point(s) of the previous bake kept outside the region, 4 inside it baked " \
               "again" in text, (name, text[-3000:])
    renders = {name: int(re.search(r"bake\.py: (\d+) render\(s\) by this run, (\d+) taken", text).group(1))
               for name, text in logs.items()}
    # The region's 3 probes outside the crate, split between the shards (2 + 1); the merge renders none.
    assert sorted(renders.values()) == [0, 1, 2] and renders[f"merge-{merge}.log"] == 0, renders
    assert f"bake.py: wrote {out / 'Left.shprobe'}" in logs[f"merge-{merge}.log"]
    assert sorted(p.name for p in out.glob("*.journal")) == ["Left.shprobe.shard-0-of-2.journal",
                                                            "Left.shprobe.shard-1-of-2.journal"]

    # The farm's files are the local rebake's bytes; what the rebake keeps, the previous bake's bytes.
    here = local / "sh_coeffs"
    files = sorted(p.name for p in out.iterdir() if not p.name.startswith("Left.shprobe.shard-")
                   and p.name != "probes.shprobe.farm")
    assert files == sorted(p.name for p in here.iterdir())
    for name in files:
        if name != "probes.shprobe.points":
            assert _sha(out / name) == _sha(here / name), name
    # The kept points: the same records in the same order; the manifest names the .blend each run opened.
    a, b = journal.read(str(out / "probes.shprobe.points")), journal.read(str(here / "probes.shprobe.points"))
    assert a.manifest["info"].pop("blend") == str(farm / "scene.blend")
    assert b.manifest["info"].pop("blend") == str(local / "scene.blend")
    assert (a.manifest, a.fingerprint, a.shard, a.coeff_count, a.torn_bytes) == \
        (b.manifest, b.fingerprint, b.shard, b.coeff_count, b.torn_bytes)
    assert list(a.values) == list(b.values) and len(a.values) == 31   # 28 kept outside the region, 3 new
    assert all(a.values[k].tobytes() == b.values[k].tobytes() and a.noise[k] == b.noise[k] for k in a.values)
    assert _sha(out / "Left.shprobe") != kept["Left.shprobe"]
    for name in set(kept) - {"Left.shprobe", "probes.shprobe.bake.json", "probes.shprobe.points"}:
        assert _sha(out / name) == kept[name], name   # Right.shprobe, sky.exr, (sun.json)
    rec = json.loads((out / "probes.shprobe.bake.json").read_text())
    before = json.loads((old / "probes.shprobe.bake.json").read_text())
    assert rec["volumes"]["Right"] == before["volumes"]["Right"] and rec["settings"] == before["settings"]
    assert rec["volumes"]["Left"] != before["volumes"]["Left"]   # the edited scene's geometry

    # A second edit (the crate taken out again) and a second farm rebake of Left. The shard journals of
    # the first are of another bake: every job would refuse them, so the submission does, and submits
    # nothing; --restart removes them and the rebake runs. Its Left.shprobe is the first bake's bytes
    # (the unedited scene again: the region's 4 probes render the same bits, the 28 outside are kept).
    shutil.copy(tmp_path / "two_rooms.blend", farm / "scene.blend")
    farm_env = {"SLURM_CONF": cluster.env["SLURM_CONF"]}
    proc = run_blender(REPO / "bake.py", *REGION_ARGS, *REBAKE, "--farm", "slurm", "--shards", "2",
                       blend=farm / "scene.blend", env=farm_env, timeout=120, check=False)
    assert proc.returncode == 3, proc.stdout[-2000:] + proc.stderr[-2000:]
    assert proc.stderr.strip().splitlines()[-1] == (
        f"bake.py: error: farm submission failed: {out / 'Left.shprobe.shard-0-of-2.journal'} belongs to another "
        "bake (changed since it was written: geometry, materials); delete it to bake from scratch, or submit with "
        "--restart (removes Left.shprobe.shard-0-of-2.journal, Left.shprobe.shard-1-of-2.journal); nothing was "
        "submitted: every job would refuse it")
    assert cluster.run("squeue", "-h").stdout.strip() == ""
    proc = run_blender(REPO / "bake.py", *REGION_ARGS, *REBAKE, "--farm", "slurm", "--shards", "2", "--restart",
                       blend=farm / "scene.blend", env=farm_env, timeout=120)
    assert re.findall(r"bake\.py: --restart: removed (\S+)", proc.stdout) == [
        str(out / f"Left.shprobe.shard-{k}-of-2.journal") for k in range(2)]
    array, merge = re.search(SUBMITTED, proc.stdout).groups()
    state = _wait(cluster, merge)
    logs = {p.name: p.read_text(errors="replace") for p in sorted(folder.glob(f"*-{array}_*.log"))}
    assert state == ["COMPLETED"], "\n".join(t[-3000:] for t in logs.values()) + cluster.logs()
    assert sum(int(re.search(r"bake\.py: (\d+) render\(s\) by this run", t).group(1)) for t in logs.values()) == 4
    assert _sha(out / "Left.shprobe") == kept["Left.shprobe"]
    for name in set(kept) - {"Left.shprobe", "probes.shprobe.bake.json", "probes.shprobe.points"}:
        assert _sha(out / name) == kept[name], name
    assert json.loads((out / "probes.shprobe.bake.json").read_text())["volumes"] == before["volumes"]
    # Submitted again unchanged: the journals are this bake's, kept for the jobs to resume from (held
    # and cancelled here: what is checked is that the submission accepts them).
    proc = run_blender(REPO / "bake.py", *REGION_ARGS, *REBAKE, "--farm", "slurm", "--shards", "2",
                       "--sbatch-option=--hold", blend=farm / "scene.blend", env=farm_env, timeout=120)
    ids = re.search(SUBMITTED, proc.stdout).groups()
    cluster.run("scancel", *ids, check=False)
    assert "--restart: removed" not in proc.stdout
    assert sorted(p.name for p in out.glob("*.journal")) == ["Left.shprobe.shard-0-of-2.journal",
                                                            "Left.shprobe.shard-1-of-2.journal"]
