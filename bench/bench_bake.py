"""Bake cost per probe on the generated default room, split into scene sync, path tracing, EXR
write, EXR read and SH projection; plus error against a high-sample reference for the settings that
trade time for error (samples, bounces, pixel filter, panorama resolution).

    blender -b --factory-startup -P bench/bench_bake.py -- [--probes 5] [--repeats 3]
        [--ref-samples 512] [--error-probes 2] [--quick]

Writes Markdown tables to stdout (bench/results/bake.md holds the last run). Sync vs tracing: each
probe is rendered at 1 sample and at the default count with persistent data on; the 1-sample render
is sync + one sample, so tracing = (t_N - t_1) * N / (N - 1) and sync = t_N - tracing (medians over
probes). Persistent data OFF is run in the same rounds, interleaved with ON, --repeats times; its
per-probe sync is estimated as t_OFF - tracing. EXR read = native.project_file (OpenImageIO read +
projection) - native.project_equirect on the same pixels (projection alone).
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
p.add_argument("--probes", type=int, default=5, help="probes per timed run (spread over the placement; "
               "the first is the setup probe)")
p.add_argument("--repeats", type=int, default=3, help="interleaved rounds of persistent data on/off")
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


def run(settings, probes, split=None):
    """Render ``probes`` (engine positions) with ``settings``; per-probe stage times and coeffs.
    With ``split`` (a list), native.project_file is timed alone and the same EXR is then loaded
    (untimed, through bpy) and projected again with native.project_equirect, so that EXR read =
    project_file - project_equirect; one (t_file, t_project) pair per probe is appended."""
    b = bake_core.ProbeBake(scene, layer, settings, mode="CURSOR", cursor=(0, 0, 1), log=lambda s: None)
    b.prepare()
    b.bake_positions(probes)
    rows = []
    orig = native.project_file

    def timed(path, *x, **k):
        t = time.perf_counter()
        res = orig(path, *x, **k)
        t_file = time.perf_counter() - t
        im = bpy.data.images.load(path)
        w, h = im.size
        px = np.empty(w * h * 4, np.float32)
        im.pixels.foreach_get(px)
        bpy.data.images.remove(im)
        img = px.reshape(h, w, 4)[::-1, :, :3].copy()
        t = time.perf_counter()
        native.project_equirect(img, settings.max_band, negative="clamp")
        split.append((t_file, time.perf_counter() - t))
        return res
    try:
        while b.done < b.total:
            before = dict(b.timings)
            if split is not None:
                native.project_file = timed
            try:
                b.step()
            finally:
                native.project_file = orig
            rows.append({k: b.timings[k] - before[k] for k in ("render", "write_exr", "project")})
        return rows, b.coeffs.copy()
    finally:
        b.cancel()


# Timing split at the default settings, persistent data on and off interleaved a.repeats times.
# Per run: the first probe pays the scene upload (setup); the others are summarised by their median.
s_def = bake_core.BakeSettings()
s_one = bake_core.BakeSettings(samples=1)
s_off = bake_core.BakeSettings(persistent_data=False)
n = s_def.samples
load0 = os.getloadavg()
runs = []
for rep in range(a.repeats):
    split = []
    on, _ = run(s_def, pick, split=split)
    one, _ = run(s_one, pick)
    off, _ = run(s_off, pick)
    med = lambda rows, k="render": float(np.median([r[k] for r in rows[1:]]))  # noqa: E731
    trace = (med(on) - med(one)) * n / (n - 1)
    runs.append({
        "on_first": on[0]["render"], "off_first": off[0]["render"],
        "on": med(on), "off": med(off), "one": med(one), "trace": trace,
        "sync_on": med(on) - trace, "sync_off": med(off) - trace,
        "write": med(on, "write_exr"),
        "read": float(np.median([f - p for f, p in split[1:]])),
        "proj": float(np.median([p for f, p in split[1:]])),
    })
load1 = os.getloadavg()
settings_txt = (f"{s_def.panorama_resolution}x{s_def.panorama_resolution // 2}, {s_def.samples} spp, "
                f"{s_def.max_bounces} bounces, box {s_def.filter_width:g} px")
say(f"Seconds per probe at the current defaults ({settings_txt}); {a.repeats} rounds, each "
    f"round = persistent data ON at {n} spp, ON at 1 spp, OFF at {n} spp, {len(pick)} probes per run; "
    f"per run the median over probes 2..{len(pick)}, the first probe (scene upload) listed apart. "
    f"Load average (1 min) {load0[0]:.1f} before, {load1[0]:.1f} after.\n")
say("| round | first probe ON (setup) | first probe OFF | scene sync ON | path tracing | EXR write "
    "| EXR read | SH projection | render ON | render OFF | sync OFF (= OFF - tracing) |")
say("|---|---|---|---|---|---|---|---|---|---|---|")
for i, r in enumerate(runs, 1):
    say(f"| {i} | {r['on_first']:.2f} | {r['off_first']:.2f} | {r['sync_on']:.3f} | {r['trace']:.3f} "
        f"| {r['write']:.4f} | {r['read']:.4f} | {r['proj']:.5f} | {r['on']:.3f} | {r['off']:.3f} "
        f"| {r['sync_off']:.3f} |")
m = {k: float(np.median([r[k] for r in runs])) for k in runs[0]}
say(f"| **median** | **{m['on_first']:.2f}** | **{m['off_first']:.2f}** | **{m['sync_on']:.3f}** "
    f"| **{m['trace']:.3f}** | **{m['write']:.4f}** | **{m['read']:.4f}** | **{m['proj']:.5f}** "
    f"| **{m['on']:.3f}** | **{m['off']:.3f}** | **{m['sync_off']:.3f}** |\n")
diffs = [r["off"] - r["on"] for r in runs]
say("Persistent data OFF minus ON, per round: " + ", ".join(f"{d:+.3f}" for d in diffs)
    + f" s/probe (OFF slower in {sum(d > 0 for d in diffs)} of {len(diffs)} rounds; "
    f"median {np.median(diffs):+.3f} s).\n")

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
