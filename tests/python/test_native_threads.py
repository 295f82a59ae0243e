"""The module releases the GIL around long core calls: a Python thread keeps ticking during a long
call (with the GIL held it would stall for the whole call). Checked for a long irradiance evaluation
and for a large .shprobe read. (This used to be made deterministic with a reader blocked in open()
on a FIFO; since issue 14 the readers refuse a FIFO at once without blocking, so there is no
blocking read left to use.)"""
import threading
import time

import numpy as np
import pytest

from schnee_probes import native


def assert_ticks_during(call):
    """Runs call() while a thread appends a timestamp every ~2 ms; asserts the thread kept running."""
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
    call()
    t1 = time.perf_counter()
    stop.set()
    t.join()
    during = np.array([s for s in stamps if t0 <= s <= t1])
    # Held GIL: no tick inside [t0, t1] except around its ends. Released: one every ~2 ms, so the
    # largest silence is far below the call's length even on a busy 2-core machine.
    gaps = np.diff(np.concatenate([[t0], during, [t1]]))
    assert t1 - t0 > 0.1, "call too short to tell"
    assert len(during) >= 5 and gaps.max() < 0.5 * (t1 - t0), (len(during), gaps.max(), t1 - t0)


def test_file_reads_release_the_gil(tmp_path):
    # One probe and a grid of X x 1024 x 4 cells (all -1): grow X until one read clearly lasts long
    # enough to tell (16 MiB of grid per 1024 in X; ~0.1 s per 64 MiB on an idle core).
    coeffs = np.ones((1, 9, 3), np.float32)
    path = str(tmp_path / "big.shprobe")
    x = 1024
    while True:
        dims = (x, 1024, 4)
        grid = np.full(x * 1024 * 4, -1, np.int32)
        native.write_shprobe(path, coeffs, grid, dims, (0, 0, 0), 1.0)
        s0 = time.perf_counter()
        native.read_shprobe(path)
        if time.perf_counter() - s0 > 0.25 or x >= 16384:
            break
        x *= 2
    assert_ticks_during(lambda: native.read_shprobe(path))


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
    assert_ticks_during(lambda: native.irradiance(coeffs, normals))


def test_background_read_runs_no_python_and_equals_the_read(tmp_path):
    """native.ShprobeRead (the viewport overlay's read): the file is parsed on a native thread, no
    Python thread is started (Blender 3.4 crashes when one runs while it draws), poll() is None until
    the parse ends and then gives what read_shprobe gives, on every call; a malformed file's error
    comes from poll() with read_shprobe's message; dropping a job mid-read frees it safely."""
    rng = np.random.default_rng(5)
    path = str(tmp_path / "big.shprobe")
    dims = (64, 64, 64)
    n = 64 ** 3
    grid = np.arange(n, dtype=np.int32)
    native.write_shprobe(path, rng.normal(size=(n, 9, 3)).astype(np.float32), grid, dims, (0, 0, 0), 0.5)
    before = threading.active_count()
    job = native.ShprobeRead(path)
    assert threading.active_count() == before
    f = None
    while f is None:
        f = job.poll()
        time.sleep(0.001)
    ref = native.read_shprobe(path)
    for got in (f, job.poll()):
        assert got.probe_count == n and np.array_equal(got.coeffs, ref.coeffs)
        assert np.array_equal(got.grid, ref.grid) and got.grid_spacing == ref.grid_spacing
    bad = tmp_path / "bad.shprobe"
    bad.write_bytes(open(path, "rb").read()[:1000])
    with pytest.raises(native.SchneeError) as want:
        native.read_shprobe(str(bad))
    job = native.ShprobeRead(str(bad))
    while True:
        try:
            assert job.poll() is None
        except native.SchneeError as exc:
            assert str(exc) == str(want.value) and exc.code == want.value.code
            break
        time.sleep(0.001)
    for _ in range(20):   # jobs dropped before their thread ends: the thread frees them
        native.ShprobeRead(path)
    time.sleep(0.5)
