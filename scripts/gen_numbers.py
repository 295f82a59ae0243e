#!/usr/bin/env python3
"""The figures README.md and docs/user-guide.md quote, computed from the benchmark JSON in one place.

    /usr/bin/python3 scripts/gen_numbers.py            rewrite the marked spans in both documents
    /usr/bin/python3 scripts/gen_numbers.py --check    exit 1 and list what differs, change nothing

The JSON under bench/results/ is the source of truth (written by bench/bench_placement.py; each
figure below names its file). In the documents a figure is marked inline,

    <!-- num:room_defaults_probes -->1593<!-- /num -->

and a whole table sits between `<!-- table:NAME -->` and `<!-- /table:NAME -->` lines. A new figure
gets a function in NUMBERS (or TABLES) and a marker in the text; tests/python/test_numbers.py fails
when a marked figure differs from what this script computes.

Rounding: percentages and minutes below 20 with one decimal, from 20 on whole (26 %, 44 min); counts
exact. Errors are the mean (or median / worst) over the 64 points between probes of bench_placement.
"""
import argparse
import json
import re
import sys
from decimal import ROUND_HALF_UP, Decimal
from functools import lru_cache
from pathlib import Path

REPO = Path(__file__).resolve().parent.parent
RESULTS = REPO / "bench" / "results"
DOCS = [REPO / "README.md", REPO / "docs" / "user-guide.md"]

NUM = re.compile(r"<!-- num:([a-z0-9_]+) -->(.*?)<!-- /num -->", re.S)
TABLE = re.compile(r"(<!-- table:([a-z0-9_]+) -->\n)(.*?)(<!-- /table:\2 -->)", re.S)


@lru_cache(maxsize=None)
def load(name):
    return json.loads((RESULTS / f"{name}.json").read_text(encoding="utf-8"))


def row(name, placement="adaptive"):
    """The first row of a bench_placement JSON with this placement (the Adaptive row with its own
    interpolation comes before the one re-interpolated on tetrahedra)."""
    return next(r for r in load(name)["rows"] if r["placement"] == placement)


def fig(x, decimals=None):
    """A percentage or a number of minutes: one decimal below 20, whole from 20 on (or `decimals`).
    Halves round up, on the value to 6 decimals (1.65 -> 1.7, as the figures were rounded by hand)."""
    d = Decimal(f"{x:.6f}")
    if decimals is None:
        decimals = 1 if d < 20 else 0
    return str(d.quantize(Decimal(1).scaleb(-decimals), rounding=ROUND_HALF_UP))


def pct(x, decimals=None):
    return fig(100.0 * x, decimals)


def minutes(seconds):
    return fig(seconds / 60.0)


def errors3(err):
    """mean / median / worst of the points, in % (the tables' form)."""
    return f"{pct(err['mean'])} / {pct(err['median'])} / {pct(err['max'])} %"


def wall(r):
    return r.get("seconds", r.get("seconds_estimate"))


# The bundled room at the add-on's defaults (128×64 px, 8 spp, 32 bounces, Error Tolerance 0.03):
# placement_room_issue29.json (issue 29: progressive samples). It ran beside two other bakes on the 2
# cores, and so did the same bake of the code before it (placement_room_issue29_before.json: 2298
# CPU-s, bit-identical probes to placement_room_defaults_faces.json, which took 1458 CPU-s with one
# job beside it). The time alone is estimated from its CPU-s scaled by that ratio (the contention
# factor of the same work) and the wall/CPU ratio of the same settings measured alone
# (placement_room_defaults_pnoise.json: 733 s wall for 1408 CPU-s).
ROOM_DEFAULTS = "placement_room_issue29"
ROOM_BEFORE = "placement_room_issue29_before"
ROOM_BEFORE_QUIET = "placement_room_defaults_faces"
ALONE = "placement_room_defaults_pnoise"


def room_defaults_cpu_alone():
    return row(ROOM_DEFAULTS)["cpu_seconds"] * row(ROOM_BEFORE_QUIET)["cpu_seconds"] / row(ROOM_BEFORE)["cpu_seconds"]


def room_defaults_alone_seconds():
    ref = row(ALONE)
    return room_defaults_cpu_alone() * ref["seconds"] / ref["cpu_seconds"]


NUMBERS = {
    "room_defaults_probes": lambda: str(row(ROOM_DEFAULTS)["probes"]),
    "room_defaults_points": lambda: str(row(ROOM_DEFAULTS).get("points", row(ROOM_DEFAULTS)["renders"])),
    "room_defaults_samples": lambda: str(row(ROOM_DEFAULTS)["samples"]),
    "room_defaults_cpu_s": lambda: f"{room_defaults_cpu_alone():.0f}",
    "room_defaults_minutes": lambda: minutes(room_defaults_alone_seconds()),
    "room_defaults_error_mean": lambda: pct(row(ROOM_DEFAULTS)["error"]["mean"], 2),
    # The same room and render settings at 4 spp (placement_room_4spp_quad.json, noise in quadrature).
    "room_4spp_error_mean": lambda: pct(row("placement_room_4spp_quad")["error"]["mean"]),
    "room_4spp_minutes": lambda: minutes(row("placement_room_4spp_quad")["seconds"]),
    # Reduced quality (64×32 px, 16 spp, 16 bounces): Error Tolerance 0.05 with prediction
    # (placement_room_predict.json), 0.03 with the rates through noise (placement_room_pnoise.json,
    # the reduced table's default) and 0.05 without prediction (placement_room.json).
    # The guide's settings table is generated from addon/schnee_probes/settings.py
    # (scripts/gen_settings_table.py): its figures are not marked here.
    "room_reduced_005_points": lambda: str(row("placement_room_predict")["renders"]),
    "room_reduced_005_error_mean": lambda: pct(row("placement_room_predict")["error"]["mean"]),
    "room_reduced_points": lambda: str(row("placement_room_pnoise")["renders"]),
    "room_reduced_error_mean": lambda: pct(row("placement_room_pnoise")["error"]["mean"]),
    "room_reduced_nopredict_points": lambda: str(row("placement_room")["renders"]),
    "room_reduced_nopredict_error_mean": lambda: pct(row("placement_room")["error"]["mean"]),
}


def _defaults_cell(r, adaptive=False, alone_seconds=None):
    seconds = alone_seconds if alone_seconds is not None else wall(r)
    if adaptive:
        return f"{errors3(r['error'])}, {r['probes']} probes, {minutes(seconds)} min"
    return f"{errors3(r['error'])}, {r['probes']}, ≈ {minutes(seconds)} min"


def table_placement_defaults():
    """docs/user-guide.md "Placement: measured", at the add-on's render defaults: per scene the floor
    (a probe baked at the point), the Adaptive placement and uniform grids of the same settings. The
    bake's time on 2 cores: measured (Adaptive) or estimated by bench_placement from the renders
    (uniform grids, ≈)."""
    scenes = [
        ("bundled room", ROOM_DEFAULTS, "placement_room_defaults_uniform", room_defaults_alone_seconds()),
        ("courtyard", "placement_courtyard_estimate", "placement_courtyard_defaults", None),
        ("hall, sun **Mixed**", "placement_hall_mixed_defaults", "placement_hall_mixed_defaults_uniform", None),
    ]
    grids = ("0.5", "0.75", "1")
    lines = ["| scene | floor | Adaptive (default) | uniform 0.5 m grid | uniform 0.75 m grid | uniform 1 m grid |",
             "|---|---|---|---|---|---|"]
    for label, adaptive, uniform, alone in scenes:
        cells = [label, errors3(load(adaptive)["floor"]), _defaults_cell(row(adaptive), True, alone)]
        rows = {r["placement"]: r for r in load(uniform)["rows"]}
        cells += [_defaults_cell(rows[f"uniform grid {g} m"]) if f"uniform grid {g} m" in rows else "—"
                  for g in grids]
        lines.append("| " + " | ".join(cells) + " |")
    return "\n".join(lines) + "\n"


def errors2(err):
    """mean / median of the points, in %."""
    return f"{pct(err['mean'])} / {pct(err['median'])} %"


def table_placement_reduced():
    """docs/user-guide.md "Placement: measured", at reduced render quality (64×32 px, 16 spp, 16
    bounces): per scene the floor, the Adaptive placement (the shipped rules), uniform grids and the
    geometry octree, each cell from the bench_placement JSON named here (None: not measured, —)."""
    def grid(name, spacing):
        return row(name, f"uniform grid {spacing} m")
    scenes = [  # label, floor and Adaptive, uniform 0.5 m, uniform 1 m, geometry octree
        ("bundled room, 10 × 10 × 4 m", "placement_room_pnoise", grid("placement_room_uniform", "0.5"),
         grid("placement_room_uniform", "1"), row("placement_geometry_octree", "geometry octree (probes at the points baked)")),
        ("courtyard, 10 × 10 × 4 m volume", "placement_courtyard_pnoise", grid("placement_courtyard_uniform", "0.5"),
         grid("placement_courtyard_uniform", "1"), row("placement_courtyard", "geometry octree (probes at the points baked)")),
        ("hall, 24 × 16 × 8 m, sunbeams", "placement_hall_quad", grid("placement_hall_uniform05", "0.5"),
         grid("placement_hall", "1"), None),
        ("hall, Min Cell 1 m", "placement_hall_reloc", None, grid("placement_hall", "1"),
         row("placement_hall", "geometry octree (probes at the points baked)")),
        ("hall, its Sun lamp **Mixed** (probes + the engine's shadowed sun)", "placement_hall_mixed_pnoise",
         grid("placement_hall_mixed_indirect", "0.5"), grid("placement_hall_mixed_indirect", "1"), None),
    ]
    lines = ["| scene | floor | Adaptive (default) | uniform 0.5 m grid | uniform 1 m grid | geometry octree |",
             "|---|---|---|---|---|---|"]
    for label, adaptive, *others in scenes:
        a = row(adaptive)
        cells = [label, errors2(load(adaptive)["floor"]),
                 f"{errors2(a['error'])}, {a['probes']} probes, {a['renders']} renders"]
        for r in others:
            if r is None:
                cells.append("—")
                continue
            e = r["error"]
            worst = e["max"] > 20 * e["mean"]  # one probe far off dominates the mean: say so
            note = f" (one probe at the panel's edge: {pct(e['max'])} %)" if worst else ""
            cells.append(f"{errors2(e)}{note}, {r['probes']}")
        lines.append("| " + " | ".join(cells) + " |")
    return "\n".join(lines) + "\n"


TABLES = {"placement_defaults": table_placement_defaults, "placement_reduced": table_placement_reduced}


def render(text):
    """The document with every marked figure and table recomputed; unknown keys raise KeyError."""
    text = NUM.sub(lambda m: f"<!-- num:{m[1]} -->{NUMBERS[m[1]]()}<!-- /num -->", text)
    return TABLE.sub(lambda m: m[1] + TABLES[m[2]]() + m[4], text)


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--check", action="store_true", help="report differences, write nothing")
    args = ap.parse_args(argv)
    stale = []
    for path in DOCS:
        old = path.read_text(encoding="utf-8")
        new = render(old)
        if new != old:
            stale.append(path.relative_to(REPO))
            if not args.check:
                path.write_text(new, encoding="utf-8")
    verb = "differ from bench/results (run scripts/gen_numbers.py)" if args.check else "rewritten"
    for p in stale:
        print(f"gen_numbers: {p} {verb}")
    return 1 if args.check and stale else 0


if __name__ == "__main__":
    sys.exit(main())
