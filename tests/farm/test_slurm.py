"""The farm bake on a real Slurm cluster (issue 15; docs/farm.md): a one-node cluster of Debian's
slurm-wlm on localhost, started and stopped here (slurm_cluster.py). `bake.py --farm slurm
--shards 2` writes and submits one requeueable job array per stage of the adaptive placement, each
after the previous (afterok), and a merge job after the last; one task of the first array is killed
mid-run and requeued by Slurm (`scontrol requeue`, what Slurm does on a node failure
or preemption); it resumes from its shard journal; the merged .shprobe equals a local bake of the
same scene byte for byte (the expected bytes come from that local bake). Runtime: ~2 min."""
import hashlib
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
