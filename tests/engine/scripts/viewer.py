"""Running build/schnee-view from the engine tests: lavapipe, validation on, EXR/PNG reading."""
import os
import re
import subprocess
from pathlib import Path

import numpy as np

REPO = Path(__file__).resolve().parents[3]
VIEWER = REPO / "build" / "schnee-view"
LAVAPIPE_ICD = Path("/usr/share/vulkan/icd.d/lvp_icd.x86_64.json")


def env():
    e = dict(os.environ)
    if LAVAPIPE_ICD.exists():
        e["VK_ICD_FILENAMES"] = str(LAVAPIPE_ICD)  # CI has no GPU: always the software driver
    e.setdefault("LP_NUM_THREADS", "2")  # 2-core CI machines
    return e


def run(*args, validation=True, timeout=120, xvfb=False):
    """Runs schnee-view with args (validation layer on unless told otherwise)."""
    assert VIEWER.exists(), f"{VIEWER} is missing: build it with cmake --build build"
    cmd = [str(VIEWER)] + [str(a) for a in args]
    if validation:
        cmd.append("--validation")
    if xvfb:
        cmd = ["xvfb-run", "-a", "-s", "-screen 0 640x480x24"] + cmd
    return subprocess.run(cmd, capture_output=True, text=True, timeout=timeout, env=env())


def check(proc):
    assert proc.returncode == 0, f"schnee-view exited {proc.returncode}\n{proc.stdout}\n{proc.stderr}"
    assert "validation" not in proc.stderr.replace("--validation", ""), proc.stderr
    return proc


def read_image(path):
    """Pixels (H, W, C) float64 of any image OpenImageIO reads, through `oiiotool --dumpdata`
    (9 decimals: exact enough for float32 comparisons at 1e-6 relative)."""
    out = subprocess.run(["oiiotool", "--dumpdata", str(path)], capture_output=True, text=True, check=True).stdout
    head = re.search(r":\s+(\d+) x\s+(\d+), (\d+) channel, (\w+)", out)
    w, h, c = (int(x) for x in head.groups()[:3])
    scale = {"uint8": 255.0, "uint16": 65535.0}.get(head.group(4), 1.0)  # integer formats dump raw codes
    img = np.zeros((h, w, c))
    for m in re.finditer(r"Pixel \((\d+), (\d+)\):((?: [-+0-9.eE]+| -?nan| -?inf)+)", out):
        x, y = int(m.group(1)), int(m.group(2))
        img[y, x] = [float(v) for v in m.group(3).split()]
    return img / scale


def assignments(stdout):
    """{object name: probe index} from --print-assignments output."""
    return {m.group(1): int(m.group(2)) for m in re.finditer(r"^object \d+ '([^']*)' probe (\d+)", stdout, re.M)}
