"""The module releases the GIL around long core calls.

Deterministic part: a read from a FIFO blocks inside the C call (in open()) until another Python
thread opens the FIFO for writing; if the call held the GIL, that thread could never run and the
child process would hang until its timeout. Statistical part: a Python thread keeps ticking during
a long irradiance evaluation (with the GIL held it would stall for the whole call)."""
import subprocess
import sys
import textwrap
import threading
import time

import numpy as np

from conftest import ADDON_DIR
from schnee_probes import native

FIFO_SCRIPT = textwrap.dedent("""
    import os, sys, tempfile, threading, time
    sys.path.insert(0, sys.argv[1])
    from schnee_probes import native
    for fn in (native.read_shprobe, native.read_shprobe_header):
        tmp = tempfile.TemporaryDirectory()
        fifo = os.path.join(tmp.name, "pipe.shprobe")
        os.mkfifo(fifo)
        errors = []
        def reader():
            try:
                fn(fifo)
            except native.SchneeError as exc:
                errors.append(exc)
        t = threading.Thread(target=reader)
        t.start()
        time.sleep(0.2)            # the reader is now blocked inside the C call, in open()
        fd = os.open(fifo, os.O_WRONLY)   # needs the GIL: only possible if the C call released it
        os.close(fd)
        t.join()
        assert len(errors) == 1 and errors[0].code == "I/O error", errors
        assert "not a regular file" in str(errors[0]), errors[0]
        tmp.cleanup()
    print("released")
""")


def test_file_reads_release_the_gil():
    proc = subprocess.run([sys.executable, "-c", FIFO_SCRIPT, str(ADDON_DIR)], capture_output=True,
                          text=True, timeout=30)
    assert proc.returncode == 0, proc.stderr
    assert proc.stdout.strip() == "released"


def test_thread_runs_during_long_call():
    rng = np.random.default_rng(3)
    coeffs = rng.normal(size=(25, 3))
    # Grow the input until one call clearly lasts long enough to tell (machine speed varies:
    # 1M normals take ~0.1 s on an idle core, ~0.3 s on a loaded one).
    n = 1_000_000
    while True:
        normals = rng.normal(size=(n, 3))
        normals /= np.linalg.norm(normals, axis=1, keepdims=True)
        s0 = time.perf_counter()
        native.irradiance(coeffs, normals)
        if time.perf_counter() - s0 > 0.25 or n >= 16_000_000:
            break
        n *= 2
    stamps = []
    stop = threading.Event()

    def tick():
        while not stop.is_set():
            stamps.append(time.perf_counter())
            time.sleep(0.002)

    t = threading.Thread(target=tick)
    t.start()
    time.sleep(0.05)
    t0 = time.perf_counter()
    native.irradiance(coeffs, normals)   # ~0.3 s in C (25 basis values + sums per normal)
    t1 = time.perf_counter()
    stop.set()
    t.join()
    during = np.array([s for s in stamps if t0 <= s <= t1])
    # Held GIL: no tick inside [t0, t1] except around its ends. Released: one every ~2 ms, so the
    # largest silence is far below the call's length even on a busy 2-core machine.
    gaps = np.diff(np.concatenate([[t0], during, [t1]]))
    assert t1 - t0 > 0.1, "call too short to tell"
    assert len(during) >= 5 and gaps.max() < 0.5 * (t1 - t0), (len(during), gaps.max(), t1 - t0)
