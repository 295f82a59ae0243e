"""Bake cost per probe on the generated default room, split into scene sync, path tracing, EXR
write, EXR read and SH projection; plus error against a high-sample reference for the settings that
trade time for error (samples, bounces, pixel filter, panorama resolution).

    blender -b --factory-startup -P bench/bench_bake.py -- [--probes 8] [--ref-samples 512]
        [--error-probes 2] [--quick]

Writes a Markdown table to stdout (bench/results/bake.md holds the last run). Sync vs tracing: each
probe is rendered at 1 sample and at the tested count with persistent data on; the 1-sample render
is sync + one sample, so tracing = (t_N - t_1) * N / (N - 1) and sync = t_N - tracing.
"""
import argparse
import os
import sys
import tempfile
import time

import bpy
import numpy as np

HERE = os.path.dirname(os.path.abspath(__file__))
REPO = os.path.dirname(HERE)
sys.path.insert(0, os.path.join(REPO, "scenes"))
sys.path.insert(0, os.path.join(REPO, "addon"))
import make_default_scene  # noqa: E402
import schnee_probes  # noqa: E402
from schnee_probes import bake_core, native, scene_export  # noqa: E402

p = argparse.ArgumentParser()
p.add_argument("--probes", type=int, default=8, help="probes timed (spread over the placement)")
p.add_argument("--ref-samples", type=int, default=512)
p.add_argument("--error-probes", type=int, default=2)
p.add_argument("--quick", action="store_true", help="skip the error sweep")
a = p.parse_args(sys.argv[sys.argv.index("--") + 1:] if "--" in sys.argv else [])

tmp = tempfile.mkdtemp(prefix="schnee_bench_")
make_default_scene.build()
bpy.ops.wm.save_as_mainfile(filepath=os.path.join(tmp, "room.blend"))
schnee_probes.register()
scene, layer = bpy.context.scene, bpy.context.view_layer
out = []
say = out.append

# Placement at the defaults.
defaults = bake_core.BakeSettings(output_path=os.path.join(tmp, "sh_coeffs", "probes.shprobe"))
bake = bake_core.ProbeBake(scene, layer, defaults, log=lambda s: None)
t = time.perf_counter()
bake.prepare()
t_prepare = time.perf_counter() - t
positions = bake.positions.copy()
bake.cancel()
say(f"Default room (scenes/make_default_scene.py), default settings: {len(positions)} probes, "
    f"placement {bake.timings['placement']:.2f} s (prepare incl. geometry gathering {t_prepare:.2f} s).\n")
pick = positions[np.linspace(0, len(positions) - 1, a.probes).astype(int)]


def run(settings, probes, keep=None):
    """Render ``probes`` (engine positions) with ``settings``; per-probe stage times and coeffs."""
    b = bake_core.ProbeBake(scene, layer, settings, mode="CURSOR", cursor=(0, 0, 1), log=lambda s: None)
    b.prepare()
    b.positions = np.asarray(probes)
    b.coeffs = np.zeros((len(probes), native.sh_count(settings.max_band), 3))
    rows = []
    try:
        while b.done < b.total:
            before = dict(b.timings)
            if keep is not None:
                orig = native.project_file

                def grab(path, *x, **k):
                    im = bpy.data.images.load(path)
                    w, h = im.size
                    px = np.empty(w * h * 4, np.float32)
                    im.pixels.foreach_get(px)
                    bpy.data.images.remove(im)
                    img = px.reshape(h, w, 4)[::-1, :, :3].copy()
                    t2 = time.perf_counter()
                    native.project_equirect(img, settings.max_band, negative="clamp")
                    keep.append(time.perf_counter() - t2)
                    return orig(path, *x, **k)
                native.project_file = grab
            try:
                b.step()
            finally:
                if keep is not None:
                    native.project_file = orig
            rows.append({k: b.timings[k] - before[k] for k in ("render", "write_exr", "project")})
        return rows, b.coeffs.copy()
    finally:
        b.cancel()


# Timing split at the default settings.
s_def = bake_core.BakeSettings()
s_one = bake_core.BakeSettings(samples=1)
proj_only = []
rows_n, _ = run(s_def, pick, keep=proj_only)
rows_1, _ = run(s_one, pick)
rows_np, _ = run(bake_core.BakeSettings(persistent_data=False), pick[:3])
# Skip the first probe of each run: it pays the full scene upload once.
tn = np.array([r["render"] for r in rows_n[1:]])
t1 = np.array([r["render"] for r in rows_1[1:]])
n = s_def.samples
trace = (tn - t1) * n / (n - 1)
sync = tn - trace
wr = np.mean([r["write_exr"] for r in rows_n[1:]])
pf = np.mean([r["project"] for r in rows_n[1:]])
pe = np.mean(proj_only[1:])
say(f"Seconds per probe at the defaults ({s_def.panorama_resolution}x{s_def.panorama_resolution // 2}, "
    f"{s_def.samples} spp, {s_def.max_bounces} bounces, box 1 px), mean over {len(tn)} probes "
    f"(first probe excluded; it took {rows_n[0]['render']:.2f} s to render incl. the initial upload):\n")
say("| stage | s/probe |\n|---|---|")
say(f"| scene sync (persistent data on; noise-level when near 0) | {np.mean(sync):.3f} |")
say(f"| path tracing | {np.mean(trace):.3f} |")
say(f"| EXR write (Render Result -> 32-bit EXR) | {wr:.4f} |")
say(f"| EXR read + SH projection (native.project_file) | {pf:.4f} |")
say(f"| of which SH projection alone (native.project_equirect) | {pe:.5f} |")
say(f"| total | {np.mean(tn) + wr + pf:.3f} |")
say(f"| render with persistent data OFF (for comparison) | {np.mean([r['render'] for r in rows_np[1:]]):.3f} |\n")

if not a.quick:
    probes = pick[1: 1 + a.error_probes]
    ref_rows, ref = run(bake_core.BakeSettings(samples=a.ref_samples, max_bounces=32), probes)

    def err(c):
        return np.mean([float(np.sqrt(np.mean((native.irradiance(c[i], D) - native.irradiance(ref[i], D)) ** 2))
                              / np.sqrt(np.mean(native.irradiance(ref[i], D) ** 2))) for i in range(len(probes))])
    D = np.random.default_rng(1).normal(size=(2000, 3))
    D /= np.linalg.norm(D, axis=1, keepdims=True)
    say(f"Irradiance relative RMS error vs a reference ({a.ref_samples} spp, 32 bounces, 128x64), "
        f"mean over {len(probes)} probes of the room, and render seconds per probe:\n")
    say("| setting | error | s/probe |\n|---|---|---|")
    variants = [("defaults", {})]
    variants += [(f"samples {s}", {"samples": s}) for s in (16, 32, 128)]
    variants += [(f"bounces {b}", {"max_bounces": b}) for b in (2, 4, 8)]
    variants += [("Blackman-Harris 1.5 px", {"pixel_filter": "BLACKMAN_HARRIS", "filter_width": 1.5})]
    variants += [("resolution 64", {"panorama_resolution": 64})]
    for label, kw in variants:
        rows, c = run(bake_core.BakeSettings(**kw), probes)
        say(f"| {label} | {100 * err(c):.2f} % | {np.mean([r['render'] for r in rows]):.3f} |")
print("\n".join(out))
