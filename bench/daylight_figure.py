"""The user guide's daylight figure (docs/images/daylight-spheres.png) from two runs of the daylight
sphere bench (bench_spheres.py --scene daylight, issue 27): rows = spheres, columns = Cycles | before:
per object, per pixel | after: per object, per pixel, cut from each run's spheres.png (whose rows are
the spheres in spheres.json order and whose columns are Cycles | per object | per pixel | floor, one
square tile each).

    /usr/bin/python3 bench/daylight_figure.py BEFORE AFTER [OUT_PNG] [--spheres beam,beam_edge,below_beam]

BEFORE, AFTER: a run's output folder (spheres.json, spheres.png) or a results JSON with its PNG beside
it under the same name (bench/results/spheres_daylight_before_sun.json and .png). The guide's figure:

    /usr/bin/python3 bench/daylight_figure.py bench/results/spheres_daylight_before_sun.json \
        bench/results/spheres_daylight_after_sun.json
"""
import argparse
import json
import os

import numpy as np
from matplotlib import image as mpimg

HERE = os.path.dirname(os.path.abspath(__file__))


def tiles(run):
    """(names, tile size, image) of one run's spheres.png."""
    if os.path.isdir(run):
        js, png = os.path.join(run, "spheres.json"), os.path.join(run, "spheres.png")
    else:
        js, png = run, os.path.splitext(run)[0] + ".png"
    with open(js) as f:
        names = [s["name"] for s in json.load(f)["spheres"]]
    img = mpimg.imread(png)
    size = img.shape[0] // len(names)
    if img.shape[1] != 4 * size:
        raise SystemExit(f"{png} is {img.shape[1]}x{img.shape[0]}: not 4 columns of "
                         f"{len(names)} square tiles")
    return names, size, img


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("before")
    ap.add_argument("after")
    ap.add_argument("out", nargs="?", default=os.path.join(HERE, "..", "docs", "images", "daylight-spheres.png"))
    ap.add_argument("--spheres", default="beam,beam_edge,below_beam")
    a = ap.parse_args()
    nb, sb, ib = tiles(a.before)
    na, sa, ia = tiles(a.after)
    if sb != sa:
        raise SystemExit(f"tile sizes differ: {sb} vs {sa}")
    rows = []
    for name in a.spheres.split(","):
        if name not in nb or name not in na:
            raise SystemExit(f"sphere {name!r} is not in both runs ({nb} / {na})")
        rb, ra = nb.index(name) * sb, na.index(name) * sa
        cut = [ib[rb:rb + sb, c * sb:(c + 1) * sb] for c in (0, 1, 2)] + \
              [ia[ra:ra + sa, c * sa:(c + 1) * sa] for c in (1, 2)]
        rows.append(np.concatenate(cut, axis=1))
    out = np.concatenate(rows, axis=0)
    mpimg.imsave(a.out, np.clip(out, 0.0, 1.0))
    print(f"wrote {a.out}: {out.shape[1]}x{out.shape[0]}")


if __name__ == "__main__":
    main()
