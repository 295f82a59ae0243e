"""Running build/schnee-view from the engine tests: lavapipe, validation on, EXR/PNG reading."""
import os
import re
import struct
import subprocess
import sys
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
    """Pixels (H, W, C) float64 of an image: schnee-view's EXR outputs (single-part scanline, R, G, B
    [, A] only, data window at 0, 0; codecs none/RLE/ZIPS/ZIP) through the add-on's exr.py, exact
    and in-process (tests/python/test_exr_reader.py checks it against OpenImageIO); anything else
    through OpenImageIO (:func:`read_image_oiio`). An oiiotool start costs 1-3 s on the 2-core CI
    machines, once per render before."""
    img = _read_plain_exr(path)
    return read_image_oiio(path) if img is None else img


def _read_plain_exr(path):
    if str(REPO / "addon") not in sys.path:
        sys.path.insert(0, str(REPO / "addon"))
    from schnee_probes import exr
    with open(path, "rb") as f:
        data = f.read(1 << 16)
    if not exr.has_magic(data[:4]):
        return None
    try:
        attrs, _ = exr._header(data)
        names = {n for n, _ in exr._channels(attrs["channels"][1])}
        origin = struct.unpack("<2i", attrs["dataWindow"][1][:8])
        if names not in ({"R", "G", "B"}, {"R", "G", "B", "A"}) or origin != (0, 0):
            return None
        return exr.read(str(path)).astype(np.float64)
    except (exr.Unsupported, exr.Malformed, KeyError, struct.error):
        return None  # OpenImageIO reads it, or says what is wrong


def read_image_oiio(path):
    """Pixels (H, W, C) float64 of any image OpenImageIO reads, through `oiiotool --dumpdata`
    (9 decimals: exact enough for float32 comparisons at 1e-6 relative); independent of exr.py."""
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
