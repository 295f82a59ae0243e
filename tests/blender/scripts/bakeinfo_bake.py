"""A real Adaptive bake writes its bake-info sidecar (docs/bakeinfo.md; tests/blender/test_bakeinfo.py).

Usage: blender -b SHADOW.blend --factory-startup -P bakeinfo_bake.py -- OUT_DIR

Bakes refine_scenes.py's shadow scene (the settings of refine_bake.py), copies the journal when the
last point is rendered (the bake removes it once the files are written), and emits one RESULT line:
the sidecar's arrays, each probe's noise rebuilt from the journal's records (the first record's σ,
then every more round added as a resumed bake adds it: adaptive.add_round), the file's leaves, the
bake's pass log.
"""
import os
import shutil
import sys

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import addon_common  # noqa: E402
from addon_common import emit  # noqa: E402

import bpy  # noqa: E402
import numpy as np  # noqa: E402

import schnee_probes  # noqa: E402
from schnee_probes import adaptive, bake_core, bakeinfo, journal, native  # noqa: E402

OUT = addon_common.args()[0]
schnee_probes.register()


def journal_noise(contents, position, first):
    """A point's relative noise from its journal records (flags 0: the two first rounds' mean and σ;
    flags k >= 2: round k's value, its samples in the noise field), combined as PointCache does."""
    key0 = journal.key_of(position, 0)
    mean = contents.values[key0]
    n = 2.0 * first
    m2 = (contents.noise[key0] * float(adaptive.irradiance_norm(mean))) ** 2 * n
    noise, rounds = contents.noise[key0], 2
    while journal.key_of(position, rounds) in contents.values:   # round k's record has flags k
        key = journal.key_of(position, rounds)
        mean, n, m2 = adaptive.add_round(mean, n, m2, contents.values[key], contents.noise[key])
        rounds += 1
        noise = adaptive.round_noise(mean, n, m2, rounds)
    return noise, rounds


def main():
    out = os.path.join(OUT, "probes.shprobe")
    s = bake_core.BakeSettings(placement="ADAPTIVE", min_cell_size=0.5, max_cell_size=2.0, panorama_resolution=64,
                               samples=16, capture_sky=False, error_tolerance=0.05, output_path=out)
    b = bake_core.ProbeBake(bpy.context.scene, bpy.context.view_layer, s)
    kept = os.path.join(OUT, "kept.journal")

    def progress(bake):
        if bake.plan.finished and bake.done >= bake.total:
            shutil.copyfile(bake.journal_path, kept)
    result = b.run(progress=progress)
    group, cache = b.plan.groups[0], b.plan.cache
    contents = journal.read(kept)
    first = adaptive.round_samples(s.samples, b.plan.policy)[0]
    rebuilt = [journal_noise(contents, cache.positions[i], first) for i in group.probe_index]
    f = native.read_shprobe(out)
    side = bakeinfo.path_for(out)
    with np.load(side, allow_pickle=False) as z:
        arrays = {k: z[k].tolist() for k in z.files}
    info = bakeinfo.read(side, out, f.probe_count, f.leaves)
    emit(files=result.files, arrays=arrays, journal_noise=[r[0] for r in rebuilt], journal_rounds=[r[1] for r in rebuilt],
         file_leaves=np.asarray(f.leaves).tolist(), probe_count=f.probe_count, sha256=bakeinfo.sha256_file(out),
         passes=[dict(pass_index=p.pass_index, leaves=p.leaves, split=p.split, direct_split=p.direct_split,
                      predicted=p.predicted) for p in result.passes],
         read_error=info.error, read_missing=info.missing)


main()
