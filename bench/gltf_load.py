#!/usr/bin/env python3
"""Load time of the engine's glTF loader on a generated .glb (a grid mesh with float positions,
normals, uv and uint32 indices, the layout Blender writes), timed through sv-gltf-dump.

Usage: /usr/bin/python3 bench/gltf_load.py [--side N] [--repeat R] [--dump build/engine/gltf/sv-gltf-dump]
Prints one line per size: vertices, triangles, file MB, median wall time (process start included)."""
import argparse
import json
import os
import statistics
import struct
import subprocess
import sys
import tempfile
import time

import numpy as np


def grid_glb(side, path):
    n = side * side
    u, v = np.meshgrid(np.linspace(0, 1, side, dtype=np.float32), np.linspace(0, 1, side, dtype=np.float32))
    pos = np.stack([u.ravel() * 10, np.sin(u.ravel() * 6) * 0.2, v.ravel() * 10], axis=1).astype(np.float32)
    nrm = np.tile(np.array([0, 1, 0], np.float32), (n, 1))
    uv = np.stack([u.ravel(), v.ravel()], axis=1).astype(np.float32)
    i = np.arange(side - 1, dtype=np.uint32)
    a = (i[None, :] + side * i[:, None]).ravel()
    idx = np.stack([a, a + side, a + 1, a + 1, a + side, a + side + 1], axis=1).astype(np.uint32).ravel()
    blobs = [pos.tobytes(), nrm.tobytes(), uv.tobytes(), idx.tobytes()]
    offs, off = [], 0
    for b in blobs:
        offs.append(off)
        off += len(b)
    doc = {
        "asset": {"version": "2.0"}, "scenes": [{"nodes": [0]}], "nodes": [{"mesh": 0}],
        "meshes": [{"primitives": [{"attributes": {"POSITION": 0, "NORMAL": 1, "TEXCOORD_0": 2}, "indices": 3}]}],
        "accessors": [
            {"bufferView": 0, "componentType": 5126, "count": n, "type": "VEC3",
             "min": pos.min(0).tolist(), "max": pos.max(0).tolist()},
            {"bufferView": 1, "componentType": 5126, "count": n, "type": "VEC3"},
            {"bufferView": 2, "componentType": 5126, "count": n, "type": "VEC2"},
            {"bufferView": 3, "componentType": 5125, "count": len(idx), "type": "SCALAR"}],
        "bufferViews": [{"buffer": 0, "byteOffset": o, "byteLength": len(b)} for o, b in zip(offs, blobs)],
        "buffers": [{"byteLength": off}],
    }
    j = json.dumps(doc).encode()
    j += b" " * (-len(j) % 4)
    body = b"".join(blobs)
    with open(path, "wb") as f:
        f.write(struct.pack("<III", 0x46546C67, 2, 12 + 8 + len(j) + 8 + len(body)))
        f.write(struct.pack("<II", len(j), 0x4E4F534A) + j)
        f.write(struct.pack("<II", len(body), 0x004E4942) + body)
    return n, len(idx) // 3


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--side", type=int, nargs="+", default=[100, 500, 1000])
    ap.add_argument("--repeat", type=int, default=5)
    ap.add_argument("--dump", default=os.path.join(os.path.dirname(__file__), "..", "build", "engine", "gltf",
                                                   "sv-gltf-dump"))
    args = ap.parse_args()
    with tempfile.TemporaryDirectory() as tmp:
        for side in args.side:
            path = os.path.join(tmp, f"grid{side}.glb")
            nv, nt = grid_glb(side, path)
            mb = os.path.getsize(path) / 1e6
            times = []
            for _ in range(args.repeat):
                t0 = time.perf_counter()
                subprocess.run([args.dump, path], check=True, stdout=subprocess.DEVNULL)
                times.append(time.perf_counter() - t0)
            med = statistics.median(times)
            print(f"{nv:>9} vertices {nt:>9} triangles {mb:8.1f} MB  median {med * 1e3:8.1f} ms"
                  f"  ({mb / med:6.0f} MB/s)")
            sys.stdout.flush()


if __name__ == "__main__":
    main()
