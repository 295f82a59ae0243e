"""Load time of the probes in the browser (issue 32's bench row): the bundled room's .shprobe files and
two ~100k-probe files, through the three.js page's own code (web/src/shprobe.js, web/src/
schnee-gltf-plugin.js) in headless Debian chromium (playwright-core from web/node_modules, WebGL2 on
SwiftShader), driven by web/test-browser/bench_load.mjs; plus Node's parse of the same bytes.

Stages, per file, median of --runs runs in one page (run 0, the cold one, is kept in the JSON):
fetch (HTTP from a local server on a free port, cache: no-store) + parse (parseShprobe, every check of
the C reader) + build (tree cell map and the per-pixel texture's N / D texels on the CPU) + upload
(texImage3D of the 3D texture, synchronised by a 1-pixel readPixels).

Files (written with the project's writer, schnee_probes.native, random but valid L2 coefficients):
- room: out/default/gltf/scene.gltf's shProbeGrids (the main job's export; `./run.sh` writes it)
- dense47: a version 1 dense grid of 47^3 = 103 823 probes (write_shprobe)
- octree100k: a version 3 corner octree of ~100k probes (CornerOctree.uniform + random splits,
  write_shprobe_v3), with hanging corners
--tiny: a 4^3 dense grid and a small octree instead (tests/bench/test_bench_web_load.py).

usage: /usr/bin/python3 bench/bench_web_load.py [--json OUT.json] [--md bench/results/web.md]
                                                [--runs 5] [--tiny] [--no-room]
"""
import argparse
import functools
import http.server
import json
import os
import shutil
import statistics
import subprocess
import sys
import tempfile
import threading
import time
from pathlib import Path

import numpy as np

REPO = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(REPO / "addon"))
from schnee_probes import native  # noqa: E402

SCENE = REPO / "out" / "default" / "gltf" / "scene.gltf"
DRIVER = REPO / "web" / "test-browser" / "bench_load.mjs"
STAGES = ("fetch", "parse", "build", "upload", "total")


def _coeffs(rng, n):
    c = rng.normal(0.0, 0.2, (n, 9, 3)).astype(np.float32)
    c[:, 0, :] = rng.uniform(0.5, 2.0, (n, 3))
    return c


def write_dense(path, n, seed=1):
    rng = np.random.default_rng(seed)
    P = n ** 3
    native.write_shprobe(str(path), _coeffs(rng, P), np.arange(P, dtype=np.int32), (n, n, n),
                         (0.0, 0.0, 0.0), 0.5, version=1)
    return P


def write_octree(path, roots, frac, seed=1):
    t = native.CornerOctree.uniform((0.0, 0.0, 0.0), 0.25, 1, (roots, roots, roots))
    rng = np.random.default_rng(seed)
    if frac:
        t.split(rng.random(t.leaf_count) < frac)
    t.finalize()
    P = t.probe_count
    native.write_shprobe_v3(str(path), t, _coeffs(rng, P))
    return P


class _Handler(http.server.SimpleHTTPRequestHandler):
    """The repository root, and /__bench/NAME from the temporary folder."""
    extra = None

    def translate_path(self, path):
        p = path.split("?", 1)[0].split("#", 1)[0]
        if p.startswith("/__bench/"):
            return str(Path(self.extra) / Path(p[len("/__bench/"):]).name)
        return super().translate_path(path)

    def log_message(self, *a):
        pass


def chromium():
    for name in ("chromium", "chromium-browser"):
        p = shutil.which(name)
        if p:
            return p
    return None


def run(tmp, runs=5, tiny=False, room=True):
    tmp = Path(tmp)
    files = []
    if room and SCENE.exists():
        ext = json.loads(SCENE.read_text())["scenes"][0]["extensions"]["VULKAN_SCHNEE_engine_properties"]
        for i, g in enumerate(ext.get("shProbeGrids", [])):
            p = SCENE.parent / g["uri"]
            files.append({"label": "room" if i == 0 else f"room{i}",
                          "url": "/" + p.relative_to(REPO).as_posix(), "path": str(p)})
    if tiny:
        write_dense(tmp / "dense4.shprobe", 4)
        write_octree(tmp / "octree_small.shprobe", 2, 0.5)
        names = ("dense4", "octree_small")
    else:
        write_dense(tmp / "dense47.shprobe", 47)
        write_octree(tmp / "octree100k.shprobe", 36, 0.4)
        names = ("dense47", "octree100k")
    for nm in names:
        files.append({"label": nm, "url": f"/__bench/{nm}.shprobe", "path": str(tmp / f"{nm}.shprobe")})

    handler = type("H", (_Handler,), {"extra": str(tmp)})
    httpd = http.server.ThreadingHTTPServer(("127.0.0.1", 0), functools.partial(handler, directory=str(REPO)))
    th = threading.Thread(target=httpd.serve_forever, daemon=True)
    th.start()
    try:
        job = tmp / "job.json"
        base = f"http://127.0.0.1:{httpd.server_address[1]}"
        job.write_text(json.dumps({"chromium": chromium(), "base": base, "runs": runs,
                                   "files": [dict(f, url=base + f["url"]) for f in files]}))
        r = subprocess.run(["node", str(DRIVER), str(job)], capture_output=True, text=True, timeout=600,
                           cwd=DRIVER.parent)
    finally:
        httpd.shutdown()
    if r.returncode != 0:
        raise RuntimeError(f"bench_load.mjs failed ({r.returncode}):\n{r.stdout[-3000:]}\n{r.stderr[-5000:]}")
    raw = json.loads(r.stdout.strip().splitlines()[-1])
    rows = []
    for f in files:
        lab = f["label"]
        nd, br = raw["node"][lab], raw["browser"][lab]
        row = {"file": lab, "probes": nd["probes"], "version": nd["version"], "structure": nd["structure"],
               "bytes": nd["bytes"], "dims": nd["dims"], "texture": br["texture"],
               "node_parse_ms": statistics.median(nd["parse"])}
        for s in STAGES:
            row[f"{s}_ms"] = statistics.median(br[s])
        row["cold_total_ms"] = br["total"][0]
        rows.append(row)
    return {"runs": runs, "rows": rows, "raw": raw, "uptime": _uptime(),
            "chromium": raw.get("userAgent"), "gpu": raw.get("gpu"), "errors": raw.get("errors")}


def _uptime():
    try:
        return subprocess.run(["uptime"], capture_output=True, text=True).stdout.strip()
    except OSError:
        return ""


def markdown(res, cmd):
    lines = ["| file | probes | .shprobe | 3D texture | fetch | parse | build (CPU texels) | GPU upload | total "
             "(cold run) | Node parse |", "|---|---|---|---|---|---|---|---|---|---|"]
    for r in res["rows"]:
        t = r["texture"]
        lines.append(
            f"| {r['file']} | {r['probes']} (v{r['version']} {r['structure']}, lattice {'x'.join(map(str, r['dims']))}) "
            f"| {r['bytes'] / 1e6:.2f} MB | {t['w']}x{t['h']}x{t['d']} {t['type']}, {t['bytes'] / 1e6:.1f} MB "
            f"| {r['fetch_ms']:.1f} | {r['parse_ms']:.1f} | {r['build_ms']:.1f} | {r['upload_ms']:.1f} "
            f"| {r['total_ms']:.1f} ({r['cold_total_ms']:.1f}) | {r['node_parse_ms']:.1f} |")
    return "\n".join(lines)


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--json", type=Path)
    ap.add_argument("--md", type=Path, help="write this table (with uptime and the command) as markdown")
    ap.add_argument("--runs", type=int, default=5)
    ap.add_argument("--tiny", action="store_true")
    ap.add_argument("--no-room", action="store_true")
    a = ap.parse_args()
    if chromium() is None or shutil.which("node") is None:
        sys.exit("needs Debian's chromium and node (scripts/deps.sh)")
    t0 = time.time()
    with tempfile.TemporaryDirectory(prefix="bench_web_load_") as tmp:
        res = run(tmp, a.runs, a.tiny, not a.no_room)
    res["wall_s"] = time.time() - t0
    res["command"] = "/usr/bin/python3 bench/bench_web_load.py " + " ".join(sys.argv[1:])
    table = markdown(res, res["command"])
    print(table)
    print(f"uptime: {res['uptime']}\nbrowser: {res['chromium']}\nGL: {res['gpu']}\nwall {res['wall_s']:.1f} s")
    if a.json:
        a.json.write_text(json.dumps(res, indent=1))
    if a.md:
        a.md.write_text(table + "\n")


if __name__ == "__main__":
    main()
