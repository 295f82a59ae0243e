"""The bake journal (addon/schnee_probes/journal.py, docs/farm.md "Journal file"): records read back
bit for bit; a writer killed with SIGKILL at random instants leaves a file readable up to its last
complete record, and the next writer cuts the torn tail off; another bake's journal is refused with
the parts that changed; shards merge, and disagreeing shards are refused. Runtime: ~5 s."""
import os
import random
import signal
import struct
import subprocess
import sys
import textwrap
import time

import numpy as np
import pytest

from conftest import ADDON_DIR
from schnee_probes import journal

PARTS = {"settings": "a" * 64, "geometry": "b" * 64, "materials": "c" * 64}


def _manifest(**changes):
    return journal.make_manifest(dict(PARTS, **changes), scene="test")


def _values(n, count=9, seed=0):
    rng = np.random.default_rng(seed)
    return [(journal.key_of(rng.normal(size=3) * 10), rng.normal(size=(count, 3))) for _ in range(n)]


def test_round_trip_bits(tmp_path):
    path = str(tmp_path / "probes.shprobe.journal")
    vals = _values(50)
    with journal.Writer(path, _manifest(), 9) as w:
        for k, v in vals:
            w.append(k, v)
    c = journal.read(path, expect_manifest=_manifest())
    assert len(c.values) == 50 and c.torn_bytes == 0
    for k, v in vals:
        assert c.values[k].tobytes() == v.astype("<f8").tobytes()
    # Header + manifest + 50 records: nothing else in the file.
    assert os.path.getsize(path) == c.good_bytes
    assert journal.record_size(9) == 24 + 4 + 9 * 3 * 8 + 8 + 4


def test_noise_round_trip(tmp_path):
    path = str(tmp_path / "j")
    vals = _values(3)
    with journal.Writer(path, _manifest(), 9) as w:
        for i, (k, v) in enumerate(vals):
            w.append(k, v, noise=0.001 * (i + 1))
    c = journal.read(path)
    assert [c.noise[k] for k, _ in vals] == [0.001, 0.002, 0.003]


def test_resume_appends(tmp_path):
    path = str(tmp_path / "j")
    vals = _values(10)
    with journal.Writer(path, _manifest(), 9) as w:
        for k, v in vals[:4]:
            w.append(k, v)
    with journal.Writer(path, _manifest(), 9) as w:
        assert set(w.values) == {k for k, _ in vals[:4]}
        for k, v in vals[4:]:
            w.append(k, v)
    assert len(journal.read(path).values) == 10


# One interpreter imports numpy and the journal once, then forks a fresh writer per round (a fork is a
# new process with its own file descriptors: SIGKILL stops it at an arbitrary instant as it stopped a
# freshly started interpreter, without the ~1 s of a new interpreter importing numpy each round).
# The parent reaps each writer and reports how it ended.
WRITER = textwrap.dedent("""
    import os, sys, numpy as np
    sys.path.insert(0, sys.argv[2])
    from schnee_probes import journal
    m = journal.make_manifest({"settings": "a" * 64, "geometry": "b" * 64, "materials": "c" * 64}, scene="test")
    for line in sys.stdin:
        sys.stdout.flush()
        pid = os.fork()
        if pid == 0:
            try:
                with journal.Writer(sys.argv[1], m, 9) as w:
                    w.append(journal.key_of((-1, 0.5, -1.0)), np.full((9, 3), -1.0))  # the file exists from here
                    print("ready", os.getpid(), flush=True)
                    for i in range(100000):
                        w.append(journal.key_of((i, 0.5, -1.0)), np.full((9, 3), float(i)))
            finally:
                os._exit(0)
        _, status = os.waitpid(pid, 0)
        print("ended", os.WTERMSIG(status) if os.WIFSIGNALED(status) else -1, flush=True)
""")


def test_kill_at_random_instants(tmp_path):
    """SIGKILL a writer 8 times at random instants: every time the file reads without error, every
    record read is one the writer wrote (value = index), and the next writer continues from it."""
    path = str(tmp_path / "killed.journal")
    script = tmp_path / "writer.py"
    script.write_text(WRITER)
    rnd = random.Random(12)
    total_seen = 0
    forker = subprocess.Popen([sys.executable, str(script), path, str(ADDON_DIR)],
                              stdin=subprocess.PIPE, stdout=subprocess.PIPE, text=True)
    try:
        for round_ in range(8):
            forker.stdin.write(f"{round_}\n")
            forker.stdin.flush()
            ready, pid = forker.stdout.readline().split()
            assert ready == "ready"
            time.sleep(rnd.uniform(0.0, 0.15))
            os.kill(int(pid), signal.SIGKILL)
            assert forker.stdout.readline().split() == ["ended", str(int(signal.SIGKILL))]  # killed, not done
            c = journal.read(path, expect_manifest=_manifest())
            assert c.torn_bytes < journal.record_size(9)
            for key, v in c.values.items():
                x, y, z, _ = journal.KEY.unpack(key)
                assert (y, z) == (0.5, -1.0) and np.all(v == x)
            assert len(c.values) >= total_seen  # nothing already durable is lost
            total_seen = len(c.values)
    finally:
        forker.stdin.close()
        assert forker.wait(timeout=30) == 0
    assert total_seen > 0


def test_torn_tail_is_cut(tmp_path):
    path = str(tmp_path / "j")
    vals = _values(3)
    with journal.Writer(path, _manifest(), 9) as w:
        for k, v in vals:
            w.append(k, v)
    good = os.path.getsize(path)
    with open(path, "ab") as f:
        f.write(b"\x01" * 100)  # half a record, as a crash mid-write leaves it
    c = journal.read(path)
    assert len(c.values) == 3 and c.torn_bytes == 100
    with journal.Writer(path, _manifest(), 9) as w:
        assert w.torn_bytes == 100
    assert os.path.getsize(path) == good
    # A flipped bit in the last record: its CRC fails, the record is dropped, the others stay.
    with open(path, "r+b") as f:
        f.seek(good - 10)
        b = f.read(1)
        f.seek(good - 10)
        f.write(bytes([b[0] ^ 0x10]))
    assert len(journal.read(path).values) == 2


def test_other_bake_is_refused_with_the_changed_part(tmp_path):
    path = str(tmp_path / "j")
    with journal.Writer(path, _manifest(), 9) as w:
        w.append(*_values(1)[0])
    with pytest.raises(journal.JournalError, match=r"belongs to another bake \(changed since it was written: "
                       r"geometry, materials\); delete it"):
        journal.Writer(path, _manifest(geometry="x", materials="y"), 9)
    with pytest.raises(journal.JournalError, match="another band or shard"):
        journal.Writer(path, _manifest(), 4)


@pytest.mark.parametrize("content,message", [
    (b"", "not a Schnee bake journal"),
    (b"SCHNJRNL", "not a Schnee bake journal"),
    (b"not a journal at all" * 10, "not a Schnee bake journal"),
    (struct.pack("<8sIIIIII32s", b"SCHNJRNL", 2, 9, 3, 0, 0, 2, b"\0" * 32), "journal version 2"),
    (struct.pack("<8sIIIIII32s", b"SCHNJRNL", 1, 9, 3, 0, 0, 1 << 20, b"\0" * 32), "malformed journal header"),
    (struct.pack("<8sIIIIII32s", b"SCHNJRNL", 1, 9, 3, 3, 2, 2, b"\0" * 32), "malformed journal header"),
    (struct.pack("<8sIIIIII32s", b"SCHNJRNL", 1, 9, 3, 0, 0, 2, b"\0" * 32) + b"{]", "malformed journal manifest"),
    (struct.pack("<8sIIIIII32s", b"SCHNJRNL", 1, 9, 3, 0, 0, 2, b"\0" * 32) + b"{}", "does not match its header"),
])
def test_malformed_files(tmp_path, content, message):
    path = tmp_path / "j"
    path.write_bytes(content)
    with pytest.raises(journal.JournalError, match=message):
        journal.read(str(path))


def test_special_files_do_not_block(tmp_path):
    fifo = tmp_path / "fifo"
    os.mkfifo(fifo)
    with pytest.raises(journal.JournalError, match="not a regular file"):
        journal.read(str(fifo))


def test_merge_shards(tmp_path):
    vals = _values(20)
    paths = []
    for k in range(3):
        p = str(tmp_path / f"s{k}")
        with journal.Writer(p, _manifest(), 9, shard=(k, 3)) as w:
            for i, (key, v) in enumerate(vals):
                if i % 3 == k or i == 0:  # probe 0 in every shard: duplicates with equal bits are fine
                    w.append(key, v)
        paths.append(p)
    merged, noise, contents = journal.merge(paths, _manifest())
    assert len(merged) == 20 and [c.shard for c in contents] == [(0, 3), (1, 3), (2, 3)]
    assert all(noise[k] == 0.0 for k in merged)
    # A shard holding different bits for a probe another shard has: refused.
    bad = str(tmp_path / "bad")
    with journal.Writer(bad, _manifest(), 9, shard=(0, 3)) as w:
        w.append(vals[1][0], vals[1][1] + 1e-12)
    with pytest.raises(journal.JournalError, match="differs from the same probe in another shard"):
        journal.merge(paths + [bad], _manifest())
    # A shard of another bake: refused, naming the part.
    other = str(tmp_path / "other")
    with journal.Writer(other, _manifest(settings="z"), 9, shard=(1, 3)) as w:
        w.append(*vals[2])
    with pytest.raises(journal.JournalError, match="changed since it was written: settings"):
        journal.merge(paths + [other], _manifest())


def test_two_creators_of_one_file(tmp_path):
    """Creation is link()-based: a second process creating the same journal at the same instant
    gets an error instead of silently replacing the first one's file."""
    path = str(tmp_path / "j")
    journal._create(path, _manifest(), 9, None)
    with pytest.raises(journal.JournalError, match="created by another process"):
        journal._create(path, _manifest(), 9, None)
