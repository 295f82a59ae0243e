"""Screenshots of the three.js page beside schnee-view (issue 32): docs/images/web-vs-view-object.png and
docs/images/web-vs-view-pixel.png, the bundled room (out/default/gltf/scene.gltf, `./run.sh`) from its
glTF camera, indirect light only.

Each image has two rows of three panels: the page, schnee-view, and their difference.
- Row 1, "linear": what tests/web/test_web_page.py compares. The page is
  `?mode=M&direct=0&sky=0&linear=1`: the float render target, through window.schnee.readLinear.
  schnee-view is `--probe-mode M --no-direct --no-sky --no-specular --tonemap none`, written as EXR.
  Both are shown through the same plain sRGB encoding, clamped at 1. The difference panel is
  max over RGB of |page − view|, white at 0.01 or more, on black. The background is masked in all three
  panels: the page's alpha 0 or the engine's black (the window, --no-sky) shows grey.
- Row 2, "tone mapped": each renderer's own output path. The page is `?mode=M&direct=0&sky=0&ui=0`
  (three's NeutralToneMapping + sRGB), a browser screenshot. schnee-view is the same options written
  as PNG (Khronos PBR Neutral + sRGB). The difference panel is |page − view| in 8-bit sRGB,
  white at 16 levels or more.

Headless Debian chromium (web/test-browser/drive_page.mjs, playwright-core, WebGL2 on SwiftShader);
schnee-view on lavapipe. The PNGs are 256-colour palettes (Pillow, Debian's python3-pil) to stay
under 300 KB.

usage: /usr/bin/python3 bench/web_screenshots.py [--out docs/images] [--width 480 --height 270]
"""
import argparse
import functools
import http.server
import json
import shutil
import subprocess
import sys
import tempfile
import threading
from pathlib import Path

import numpy as np
from PIL import Image, ImageDraw

REPO = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(REPO / "tests" / "engine" / "scripts"))
import viewer  # noqa: E402

SCENE = REPO / "out" / "default" / "gltf" / "scene.gltf"
DRIVER = REPO / "web" / "test-browser" / "drive_page.mjs"
ENGINE_OPTS = ("--no-direct", "--no-sky", "--no-specular")


class _Quiet(http.server.SimpleHTTPRequestHandler):
    def log_message(self, *a):
        pass


def _srgb(x):
    x = np.clip(x, 0.0, 1.0)
    return np.where(x <= 0.0031308, 12.92 * x, 1.055 * np.power(x, 1 / 2.4) - 0.055)


def _u8(x):
    return (np.clip(x, 0, 1) * 255 + 0.5).astype(np.uint8)


def page_frames(tmp, W, H, modes):
    chromium = shutil.which("chromium") or shutil.which("chromium-browser")
    if chromium is None or shutil.which("node") is None:
        sys.exit("needs Debian's chromium and node (scripts/deps.sh)")
    httpd = http.server.ThreadingHTTPServer(("127.0.0.1", 0), functools.partial(_Quiet, directory=str(REPO)))
    threading.Thread(target=httpd.serve_forever, daemon=True).start()
    base = f"http://127.0.0.1:{httpd.server_address[1]}/web/index.html"
    pages = []
    for m in modes:
        pages.append({"url": f"{base}?mode={m}&direct=0&sky=0&linear=1&width={W}&height={H}",
                      "frame": {"w": W, "h": H, "out": str(tmp / f"page_{m}.f32")}})
        pages.append({"url": f"{base}?mode={m}&direct=0&sky=0&ui=0&width={W}&height={H}",
                      "viewport": {"w": W, "h": H}, "screenshot": str(tmp / f"page_{m}.png")})
    job = tmp / "job.json"
    job.write_text(json.dumps({"chromium": chromium, "pages": pages}))
    try:
        r = subprocess.run(["node", str(DRIVER), str(job)], capture_output=True, text=True, timeout=300,
                           cwd=DRIVER.parent)
    finally:
        httpd.shutdown()
    if r.returncode != 0:
        sys.exit(f"drive_page.mjs failed:\n{r.stdout[-2000:]}\n{r.stderr[-4000:]}")
    for res in json.loads(r.stdout.strip().splitlines()[-1]):
        if res["errors"] or res["state"]["error"]:
            sys.exit(f"page errors: {res['errors']} {res['state']['error']}")
    out = {}
    for m in modes:
        lin = np.frombuffer((tmp / f"page_{m}.f32").read_bytes(), np.float32).reshape(H, W, 4)[::-1]
        tm = np.asarray(Image.open(tmp / f"page_{m}.png").convert("RGB"))
        out[m] = (lin.astype(np.float64), tm)
    return out


def engine_frames(tmp, W, H, m):
    exr, png = tmp / f"view_{m}.exr", tmp / f"view_{m}.png"
    common = ("--headless", "--width", W, "--height", H, "--probe-mode", m) + ENGINE_OPTS
    viewer.check(viewer.run(SCENE, *common, "--output", exr, "--tonemap", "none"))
    viewer.check(viewer.run(SCENE, *common, "--output", png))
    return viewer.read_image(exr)[:, :, :3], np.asarray(Image.open(png).convert("RGB"))


def compose(page, view, W, H, title):
    (plin, ptm), (vlin, vtm) = page, view
    bg = (plin[:, :, 3] <= 0.5) | (vlin.max(axis=2) <= 0)
    grey = np.array([40, 40, 40], np.uint8)
    d = np.abs(plin[:, :, :3] - vlin).max(axis=2)
    row1 = [_u8(_srgb(plin[:, :, :3])), _u8(_srgb(vlin)), _u8(np.repeat((d / 0.01)[:, :, None], 3, 2))]
    for panel in row1:
        panel[bg] = grey
    d8 = np.abs(ptm.astype(int) - vtm.astype(int)).max(axis=2)
    row2 = [ptm, vtm, _u8(np.repeat((d8 / 16.0)[:, :, None], 3, 2))]
    row2[2][bg] = grey
    lab_h, top = 16, 20
    img = Image.new("RGB", (3 * W, top + 2 * (H + lab_h)), (20, 20, 20))
    dr = ImageDraw.Draw(img)
    dr.text((4, 4), title, fill=(235, 235, 235))
    labels = [["three.js page (linear)", "schnee-view (linear, EXR)", "|page - view|, white = 0.01"],
              ["three.js page (PBR Neutral, sRGB)", "schnee-view (PBR Neutral, PNG)", "|page - view|, white = 16/255"]]
    for r, row in enumerate((row1, row2)):
        y = top + r * (H + lab_h)
        for c, panel in enumerate(row):
            dr.text((c * W + 4, y + 2), labels[r][c], fill=(200, 200, 200))
            img.paste(Image.fromarray(panel), (c * W, y + lab_h))
    stats = {"compared_px": int((~bg).sum()), "median_abs": float(np.median(d[~bg])),
             "within_1e-3": float((d[~bg] <= 1e-3 + 5e-3 * vlin.max(axis=2)[~bg]).mean()),
             "tonemapped_median_u8": float(np.median(d8[~bg])), "tonemapped_p99_u8": float(np.percentile(d8[~bg], 99))}
    return img, stats


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--out", type=Path, default=REPO / "docs" / "images")
    ap.add_argument("--width", type=int, default=480)
    ap.add_argument("--height", type=int, default=270)
    a = ap.parse_args()
    if not SCENE.exists():
        sys.exit(f"{SCENE} is missing: run ./run.sh first")
    W, H = a.width, a.height
    modes = ("object", "pixel")
    with tempfile.TemporaryDirectory(prefix="web_screens_") as tmp:
        tmp = Path(tmp)
        pages = page_frames(tmp, W, H, modes)
        for m in modes:
            title = (f"bundled room, glTF camera, indirect only, per {m}: three.js page (left) beside "
                     f"schnee-view (middle)")
            img, st = compose(pages[m], engine_frames(tmp, W, H, m), W, H, title)
            path = a.out / f"web-vs-view-{m}.png"
            img.quantize(256, method=Image.Quantize.MEDIANCUT, dither=Image.Dither.NONE).save(path, optimize=True)
            print(f"{path}: {path.stat().st_size // 1024} KB; {json.dumps(st)}")


if __name__ == "__main__":
    main()
