"""Summary tables of bench_spheres.py runs (issue 27's daylight cases; any spheres.json works):

    /usr/bin/python3 bench/spheres_daylight_table.py [LABEL=]spheres.json ...

Prints, in markdown, one summary row per run (the mean over its spheres of the relative RMS over the
pixels, net of the reference's noise, and of the relative error of the mean colour, per object, per
pixel and for the floor, the probe at the sphere's centre, at the bake's settings and converged;
the bake's probes, points rendered, wall and CPU seconds), then a per-sphere table per run (mean
colour error / luminance bias, %). The numbers are the JSON's (bench_spheres.py "errors").
Plain Python + numpy, no Blender.
"""
import json
import os
import sys

import numpy as np

COLS = (("per_object", "per object"), ("per_pixel", "per pixel"), ("floor", "floor (bake settings)"),
        ("floor_converged", "floor (converged)"))


def load(arg):
    label, _, path = arg.rpartition("=")
    with open(path, encoding="utf-8") as fh:
        doc = json.load(fh)
    return label or os.path.splitext(os.path.basename(path))[0], doc


def pct(x):
    return f"{100 * x:.1f}"


def summary(runs):
    lines = ["| run | " + " | ".join(f"{name}: RMS net / mean colour" for _, name in COLS)
             + " | probes / points | bake wall / CPU-s | command wall / CPU-s |",
             "|---|" + "---|" * len(COLS) + "---|---|---|"]
    for label, doc in runs:
        rows = doc["spheres"]
        cells = []
        for key, _ in COLS:
            rms = np.mean([r["errors"][key].get("rel_rms_net", np.nan) for r in rows])
            mean = np.mean([r["errors"][key]["mean_rel"] for r in rows])
            cells.append(f"{pct(rms)} / {pct(mean)}")
        b, t = doc.get("bake", {}), doc.get("timings", {})
        tb = t.get("bake", {})
        cpu_total = t.get("total_cpu_seconds", np.nan) + t.get("children_cpu_seconds", 0.0)
        lines.append(f"| {label} | " + " | ".join(cells)
                     + f" | {b.get('probes')} / {b.get('renders')} | {tb.get('seconds', np.nan):.0f} s / "
                     f"{tb.get('cpu_seconds', np.nan):.0f} | {t.get('total', np.nan):.0f} s / {cpu_total:.0f} |")
    return "\n".join(lines) + "\n"


def per_sphere(label, doc):
    lines = [f"{label}: RMS net / mean colour / luminance bias of the mean, %", "",
             "| sphere | sunlit fraction | ref. noise | " + " | ".join(n for _, n in COLS) + " |",
             "|---|---|---|" + "---|" * len(COLS)]
    lit = doc.get("daylight", {}).get("spheres_lit", {})
    for r in doc["spheres"]:
        cells = []
        for key, _ in COLS:
            e = r["errors"][key]
            cells.append(f"{pct(e.get('rel_rms_net', np.nan))} / {pct(e['mean_rel'])} / "
                         f"{100 * e['mean_lum_bias']:+.1f}")
        frac = lit.get(r["name"])
        lines.append(f"| {r['name']} | {'—' if frac is None else f'{frac:.2f}'} | "
                     f"{pct(r['reference']['noise_rel_rms'])} | " + " | ".join(cells) + " |")
    return "\n".join(lines) + "\n"


def main(argv):
    if not argv or argv[0] in ("-h", "--help"):
        print(__doc__)
        return 0 if argv else 2
    runs = [load(a) for a in argv]
    print(summary(runs))
    for label, doc in runs:
        print(per_sphere(label, doc))
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
