"""farm.job_journals / farm.prepare_journals (docs/farm.md "Slurm"), plain Python: before a farm bake
is submitted, the journals its jobs open must be this bake's (every shard and the merge refuse
another bake's), and --restart removes them unless a job holds one. The journals are written here with
journal.write_whole; the manifests differ in one part, as after an edit of the scene. The real
submission (sbatch, Blender, a second rebake after an edit): test_slurm.py."""
import numpy as np
import pytest

from conftest import requires_native
from schnee_probes import farm, journal
from schnee_probes.output_lock import OutputLock

pytestmark = requires_native   # farm.job_journals names a volume's file with region.py, which loads the core

THIS = journal.make_manifest({"geometry": "aa", "settings": "11"}, scene="Scene")
EDITED = journal.make_manifest({"geometry": "bb", "settings": "11"}, scene="Scene")


def _journal(path, manifest):
    key = journal.key_of((0.5, 0.5, 0.5))
    journal.write_whole(str(path), manifest, 1, {key: np.ones((1, 3))}, {key: 0.0})


def test_job_journals_are_named_after_the_rebaked_volume(tmp_path):
    out = str(tmp_path / "probes.shprobe")
    assert farm.job_journals(out, 2) == [str(tmp_path / n) for n in (
        "probes.shprobe.shard-0-of-2.journal", "probes.shprobe.shard-1-of-2.journal", "probes.shprobe.journal")]
    assert farm.job_journals(out, 1, "Left wing") == [str(tmp_path / n) for n in (
        "Left_wing.shprobe.shard-0-of-1.journal", "Left_wing.shprobe.journal")]


def test_journals_of_this_bake_are_kept_and_another_bakes_refused(tmp_path):
    paths = farm.job_journals(str(tmp_path / "probes.shprobe"), 2, "Left")
    asked = []

    def manifest():
        asked.append(1)
        return THIS
    assert farm.prepare_journals(paths, manifest) == [] and asked == []   # no journal: no fingerprint
    _journal(paths[0], THIS)
    _journal(paths[2], THIS)
    assert farm.prepare_journals(paths, manifest) == [] and asked == [1]
    before = [open(p, "rb").read() for p in (paths[0], paths[2])]
    _journal(paths[1], EDITED)
    with pytest.raises(farm.FarmError) as err:
        farm.prepare_journals(paths, lambda: THIS)
    assert str(err.value) == (
        f"{paths[1]} belongs to another bake (changed since it was written: geometry); delete it to bake from "
        "scratch, or submit with --restart (removes Left.shprobe.shard-0-of-2.journal, "
        "Left.shprobe.shard-1-of-2.journal, Left.shprobe.journal); nothing was submitted: every job would refuse it")
    assert [open(p, "rb").read() for p in (paths[0], paths[2])] == before
    # Not a journal at all: refused the same way, naming the file.
    (tmp_path / "Left.shprobe.shard-1-of-2.journal").write_bytes(b"not a journal")
    with pytest.raises(farm.FarmError, match="Left.shprobe.shard-1-of-2.journal: not a Schnee bake journal"):
        farm.prepare_journals(paths, lambda: THIS)


def test_restart_removes_them_unless_a_job_holds_one(tmp_path):
    paths = farm.job_journals(str(tmp_path / "probes.shprobe"), 2)
    _journal(paths[0], THIS)
    _journal(paths[1], EDITED)
    held = OutputLock(paths[1])
    held.acquire()   # a running shard job's lock (flock: another open file description, as another process)
    try:
        with pytest.raises(farm.FarmError) as err:
            farm.prepare_journals(paths, lambda: THIS, restart=True)
        assert str(err.value).startswith(f"a job is writing {paths[1]} (pid ")
        assert str(err.value).endswith("); wait for it or cancel it (scancel), then submit again")
        assert sorted(p.name for p in tmp_path.iterdir() if p.suffix == ".journal") == [
            "probes.shprobe.shard-0-of-2.journal", "probes.shprobe.shard-1-of-2.journal"]   # nothing removed
    finally:
        held.release()
    assert farm.prepare_journals(paths, lambda: THIS, restart=True) == paths[:2]
    assert sorted(p.name for p in tmp_path.iterdir()) == []   # the journals and their lock files
