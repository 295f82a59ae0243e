"""The uniform grid of equal error to an Adaptive bake (bench/results/placement.md, "Targets"): how
many probes a uniform corner grid would need for the Adaptive row's mean / median / p90 / max error
at the benchmark's 64 points.

    /usr/bin/python3 bench/placement_equal_grid.py ADAPTIVE.json [GRIDS.json]

ADAPTIVE.json: a bench_placement.py output with an Adaptive row (corner octree); GRIDS.json: one with
the uniform-grid rows (default: the same file). Between the two grids whose errors enclose the
Adaptive error, error and probe count are taken as power laws of the spacing h (e = a·h^p,
n = b·h^-q through the two grids): h where e equals the Adaptive error, then n(h). Outside the
measured grids' range no figure is given (no extrapolation).
"""
import json
import math
import sys


def equal_grid(target, grids, stat):
    """(h, probes) of the power-law grid with error ``target`` in ``stat``, or None."""
    hs = sorted(grids)
    found = None
    for a, b in zip(hs, hs[1:]):
        ea, eb = grids[a]["error"][stat], grids[b]["error"][stat]
        if min(ea, eb) <= target <= max(ea, eb) and ea != eb:
            found = (a, b)
    if found is None:
        return None
    a, b = found
    ea, eb = grids[a]["error"][stat], grids[b]["error"][stat]
    na, nb = grids[a]["probes"], grids[b]["probes"]
    p = math.log(eb / ea) / math.log(b / a)
    h = a * (target / ea) ** (1.0 / p)
    q = math.log(nb / na) / math.log(b / a)
    return h, na * (h / a) ** q


def main(argv):
    if not argv or len(argv) > 2:
        raise SystemExit(__doc__)
    with open(argv[0], encoding="utf-8") as f:
        rows = json.load(f)["rows"]
    with open(argv[-1], encoding="utf-8") as f:
        grid_rows = json.load(f)["rows"]
    adaptive = [r for r in rows if r["placement"] == "adaptive" and "passes" in r]
    grids = {float(r["placement"].split()[2]): r for r in grid_rows if r["placement"].startswith("uniform grid")}
    if not adaptive or len(grids) < 2:
        raise SystemExit("need an Adaptive row and at least two uniform-grid rows")
    for ad in adaptive:
        print(f"Adaptive {ad.get('tolerance')}: {ad['probes']} probes, {ad['renders']} points rendered")
        for stat in ("mean", "median", "p90", "max"):
            e = ad["error"][stat]
            res = equal_grid(e, grids, stat)
            where = ", ".join(f"{h:g} m {100 * grids[h]['error'][stat]:.2f} %" for h in sorted(grids))
            if res is None:
                print(f"  {stat:6s} {100 * e:6.2f} %: outside the grids' range ({where})")
            else:
                h, n = res
                print(f"  {stat:6s} {100 * e:6.2f} %: uniform grid of equal error ~{h:.2f} m, ~{n:.0f} probes "
                      f"= {n / ad['probes']:.2f}x the Adaptive's ({where})")


if __name__ == "__main__":
    main(sys.argv[1:])
