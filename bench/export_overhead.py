"""Cost of the glTF exporter hook per .shprobe file: header read, full validation, copy.

    /usr/bin/python3 bench/export_overhead.py

Writes one dense file (50 000 probes in a 64 x 32 x 64 grid, about 8.5 MB) with the native writer
into a temporary folder and prints the best of 5 runs of each step the hook performs
(addon/schnee_probes/gltf_export.py: collect_probe_grids). Results: bench/results/export.md.
"""
import os
import shutil
import sys
import tempfile
import time

sys.path.insert(0, os.path.join(os.path.dirname(os.path.abspath(__file__)), "..", "addon"))
import numpy as np  # noqa: E402

from schnee_probes import native  # noqa: E402

X, Y, Z, P = 64, 32, 64, 50000


def best(fn, runs=5):
    times = []
    for _ in range(runs):
        t0 = time.perf_counter()
        fn()
        times.append(time.perf_counter() - t0)
    return min(times)


def main():
    folder = tempfile.mkdtemp(prefix="schnee-export-bench-")
    try:
        grid = np.full(X * Y * Z, -1, np.int32)
        grid[:P] = np.arange(P, dtype=np.int32)
        path = os.path.join(folder, "big.shprobe")
        native.write_shprobe(path, np.ones((P, 9, 3), np.float32), grid, (X, Y, Z), (0, 0, 0), 0.5)
        size = os.path.getsize(path)
        t_header = best(lambda: native.read_shprobe_header(path))
        t_full = best(lambda: native.read_shprobe(path))
        t_copy = best(lambda: shutil.copyfile(path, path + ".copy"))
        print(f"{size / 1e6:.1f} MB ({P} probes, {X}x{Y}x{Z} grid): header {t_header * 1e3:.3f} ms, "
              f"full validation {t_full * 1e3:.1f} ms, copy {t_copy * 1e3:.1f} ms")
    finally:
        shutil.rmtree(folder)


if __name__ == "__main__":
    main()
