#!/usr/bin/env python3
"""The sky's sun split (native.sky_sun_split) on Blender's eight bundled HDRIs: the table of
docs/direct-light.md "The sky's sun".

    /usr/bin/python3 bench/bench_sky_sun.py

Per HDRI (read by OpenImageIO, clamped at 0 as the bake reads a world): the verdict, the sun's
share of the luminance flux, its irradiance (W/m² at strength 1), elevation, angular diameter, how
far its region reached from the peak, the texels changed, and the energy check: the relative
irradiance RMS of (rest + the Sun lamp's projection) against the image's exact projection, and the
time of the split (one core, a loaded 2-core machine)."""
import math
import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent.parent / "addon"))
from schnee_probes import adaptive, native  # noqa: E402

FOLDER = Path("/usr/share/blender/datafiles/studiolights/world")


def main():
    print("| HDRI | verdict | share | irradiance RGB (W/m²) | elevation | angle | extent | texels | "
          "energy (irradiance RMS) | split |")
    print("|---|---|---|---|---|---|---|---|---|---|")
    for path in sorted(FOLDER.glob("*.exr")):
        world = np.ascontiguousarray(np.clip(native.read_image(str(path))[:, :, :3], 0.0, None), dtype=np.float32)
        t0 = time.perf_counter()
        split = native.sky_sun_split(world)
        dt = time.perf_counter() - t0
        s = split.sun
        if s is None:
            same = "unchanged" if np.array_equal(split.rest, world) else "CHANGED"
            print(f"| {path.stem} | {split.verdict} | – | – | – | – | – | 0 | {same} | {dt * 1e3:.1f} ms |")
            continue
        exact = native.sky_table(world, 1, 1, 2)[0, 0]
        total = native.sky_table(split.rest, 1, 1, 2)[0, 0] + native.direct_project([s.lamp()], np.zeros((1, 3)), 2)[0]
        err = float(adaptive.irradiance_error(total, exact))
        irr = ", ".join(f"{v:.3f}" for v in s.irradiance)
        print(f"| {path.stem} | found | {s.share * 100:.1f} % | {irr} | {math.degrees(math.asin(-s.direction[1])):.1f}° | "
              f"{math.degrees(s.angle):.2f}° | {math.degrees(s.extent):.2f}° | {s.texels} | {err:.1e} | {dt * 1e3:.1f} ms |")


if __name__ == "__main__":
    main()
