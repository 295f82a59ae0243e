"""One bake per output (addon/schnee_probes/output_lock.py, issue 31), with real processes and real
flock: a second taker is refused naming the holder's process id; a holder killed with SIGKILL leaves
a file that the next taker takes over; four processes taking and freeing the lock 150 times each
never hold it together (a shared counter incremented under it, read-sleep-write, loses no update,
the unlink-on-release race included); a refused or finished taker leaves no folder it created; a
FIFO at the lock's path is refused without blocking. Runtime: ~3 s."""
import os
import signal
import subprocess
import sys
import textwrap
import time

import pytest

from conftest import ADDON_DIR
from schnee_probes import output_lock


def _holder(journal_path):
    """A plain Python process holding the lock of ``journal_path`` until its stdin closes."""
    code = textwrap.dedent(f"""
        import sys
        sys.path.insert(0, {str(ADDON_DIR)!r})
        from schnee_probes import output_lock
        lock = output_lock.OutputLock({str(journal_path)!r})
        lock.acquire()
        print("LOCKED", flush=True)
        sys.stdin.read()
        lock.release()
        print("RELEASED", flush=True)
    """)
    proc = subprocess.Popen([sys.executable, "-c", code], stdin=subprocess.PIPE, stdout=subprocess.PIPE, text=True)
    assert proc.stdout.readline().strip() == "LOCKED"
    return proc


def test_a_second_taker_is_refused_naming_the_holder(tmp_path):
    journal = tmp_path / "probes.shprobe.journal"
    holder = _holder(journal)
    try:
        lock = output_lock.OutputLock(str(journal))
        assert lock.path == str(journal) + ".lock"
        with pytest.raises(output_lock.OutputBusy) as busy:
            lock.acquire()
        assert busy.value.pid == holder.pid
        assert busy.value.holder_text() == f"pid {holder.pid}"  # same host: no host named
        assert not lock.held
    finally:
        holder.stdin.close()
        assert holder.stdout.readline().strip() == "RELEASED"
        holder.wait(10)
    assert not os.path.exists(lock.path)  # the holder removed its file
    with lock:  # free now
        assert open(lock.path).read().split()[0] == str(os.getpid())
    assert os.listdir(tmp_path) == []


def test_a_killed_holder_leaves_a_file_the_next_taker_takes_over(tmp_path):
    journal = tmp_path / "j"
    holder = _holder(journal)
    holder.send_signal(signal.SIGKILL)
    holder.wait(10)
    path = str(journal) + ".lock"
    assert open(path).read().split()[0] == str(holder.pid)  # left behind, but not locked any more
    with output_lock.OutputLock(str(journal)) as lock:
        assert open(lock.path).read().split()[0] == str(os.getpid())
    assert not os.path.exists(path)


def test_a_second_lock_in_the_same_process_is_refused(tmp_path):
    # flock belongs to the open file: two bakes in one Blender exclude each other as well.
    with output_lock.OutputLock(str(tmp_path / "j")):
        with pytest.raises(output_lock.OutputBusy) as busy:
            output_lock.OutputLock(str(tmp_path / "j")).acquire()
        assert busy.value.pid == os.getpid()


_WORKER = textwrap.dedent("""
    import sys, time
    sys.path.insert(0, sys.argv[1])
    from schnee_probes import output_lock
    journal, counter, rounds = sys.argv[2], sys.argv[3], int(sys.argv[4])
    done = 0
    while done < rounds:
        lock = output_lock.OutputLock(journal)
        try:
            lock.acquire()
        except output_lock.OutputBusy:
            continue
        try:
            n = int(open(counter).read())
            time.sleep(0.0005)
            with open(counter, "w") as f:
                f.write(str(n + 1))
        finally:
            lock.release()
        done += 1
""")


def test_four_processes_never_hold_it_together(tmp_path):
    counter = tmp_path / "counter"
    counter.write_text("0")
    journal = tmp_path / "out" / "j"  # its folder made and removed by the takers, over and over
    procs = [subprocess.Popen([sys.executable, "-c", _WORKER, str(ADDON_DIR), str(journal), str(counter), "150"])
             for _ in range(4)]
    for p in procs:
        assert p.wait(120) == 0
    assert counter.read_text() == "600"  # no two holders ever read the same value
    # No lock file is left. The folder stays when its maker freed the lock while another process's
    # lock file was in it (that one does not remove a folder it did not make).
    assert not journal.parent.exists() or os.listdir(journal.parent) == []


def test_folders_made_for_the_lock_are_removed_unless_used(tmp_path):
    journal = tmp_path / "a" / "b" / "probes.shprobe.journal"
    lock = output_lock.OutputLock(str(journal))
    lock.acquire()
    assert journal.parent.is_dir()
    lock.release()
    assert os.listdir(tmp_path) == []  # a refused bake leaves no empty sh_coeffs/ behind
    lock.acquire()
    (journal.parent / "probes.shprobe").write_bytes(b"SPHR")  # the bake wrote its output
    lock.release()
    assert os.listdir(journal.parent) == ["probes.shprobe"]


def test_a_fifo_at_the_lock_path_is_refused_without_blocking(tmp_path):
    journal = tmp_path / "j"
    os.mkfifo(str(journal) + ".lock")
    t0 = time.monotonic()
    with pytest.raises(OSError, match=r"j\.lock exists and is a FIFO \(named pipe\), not the bake's lock file"):
        output_lock.OutputLock(str(journal)).acquire()
    assert time.monotonic() - t0 < 5
