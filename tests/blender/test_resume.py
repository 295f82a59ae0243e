"""A bake that survives a crash (issue 15; docs/farm.md), in real Blender + Cycles through bake.py:
killed with SIGKILL at a random probe, then run again, it renders only what was missing and writes
the same bytes as an uninterrupted bake with the same seed (and the same sky pixels); the same after a cancel (SIGINT); shards
baked separately and merged give the same bytes; a merge refuses shards of other settings and names
what changed; a journal of other settings is moved aside, not resumed. The expected bytes come from
an uninterrupted bake of the same scene (Cycles renders the same bits for the same seed). Runtime:
~2 min on 2 cores."""
import collections
import hashlib
import json
import random
import re
import signal
import time
import types

import numpy as np
import pytest

from conftest import requires_native
from schnee_probes import adaptive, journal, native
from test_bake_hazards import SCRIPTS, TINY, Running, bake, copy_blend, last_error, run_blender, scenes_made_by

pytestmark = requires_native

CELLS = ["--min-cell-size", "1", "--max-cell-size", "1"]  # 32 probes

# Adaptive placement at the coarsest sizes that still refine (one level: 2 m first layer, 1 m
# lattice): the same stages, shard waits and journal records as finer cells, a quarter of the renders.
ADAPTIVE = ["--placement", "ADAPTIVE", "--min-cell-size", "1", "--max-cell-size", "2"]


def _counted(blend, args, log, sig=None, at=None):
    """bake.py with every Cycles render counted into ``log`` (scripts/count_renders.py); with ``sig``,
    sent once the journal holds ``at`` records. (returncode, stdout)."""
    pre = [SCRIPTS / "count_renders.py"] + ([SCRIPTS / "slow_render.py"] if sig is not None else [])
    run = Running(blend, [*args, *TINY], {"SCHNEE_TEST_RENDER_LOG": str(log)}, pre=pre)
    if sig is not None:
        _signal_at(run, blend, sig, at)
    rc, out, err = run.finish()
    return rc, out + err[-2000:]


def _renders_per_key(log):
    """{(x, y, z, seed): renders} of a count_renders log: a key rendered twice is the same panorama
    twice (Cycles renders the same bits for the same position and seed)."""
    counts = collections.Counter()
    for line in log.read_text().splitlines():
        x, y, z, seed, _samples = line.split()
        counts[(x, y, z, seed)] += 1
    return counts


def _adaptive_reference(scenes, local):
    """An uninterrupted Adaptive bake in ``local``: its sha256, the points it rendered (probes and
    test points), its first layer's probe count and its renders per key (every one once)."""
    blend = copy_blend(scenes, "window_room.blend", local)
    rc, out = _counted(blend, ADAPTIVE, local / "renders.log")
    assert rc == 0, out[-3000:]
    first_layer = int(re.search(r"first layer \d+ cell\(s\) of 2 m with (\d+) probes", out).group(1))
    points = int(re.search(r"adaptive placement: \d+ pass\(es\), (\d+) points rendered", out).group(1))
    assert first_layer + 3 < points  # room to kill it in its second stage
    renders = _renders_per_key(local / "renders.log")
    assert max(renders.values()) == 1      # issue 29: each point and seed once
    return types.SimpleNamespace(shprobe=_sha(local / "sh_coeffs" / "probes.shprobe"), points=points,
                                 first_layer=first_layer, renders=renders,
                                 bakeinfo=_sidecar(local / "sh_coeffs" / "probes.shprobe.bakeinfo"))


scenes = scenes_made_by("resume_scene.py")


@pytest.fixture(scope="module")
def reference(scenes, tmp_path_factory):
    """The uninterrupted bake: (probe count, sha256 of probes.shprobe, of sky.exr)."""
    d = tmp_path_factory.mktemp("reference")
    blend = copy_blend(scenes, "window_room.blend", d)
    proc = bake(blend, *CELLS, *TINY)
    assert proc.returncode == 0, proc.stdout[-2000:] + proc.stderr[-2000:]
    out = d / "sh_coeffs"
    assert not (out / "probes.shprobe.journal").exists()  # spent once the output is written
    count = int(re.search(r"bake\.py: (\d+) probes in", proc.stdout).group(1))
    return count, _sha(out / "probes.shprobe"), _pixels(out / "sky.exr")


def _sha(path):
    return hashlib.sha256(path.read_bytes()).hexdigest()


def _sidecar(path):
    """The bake-info sidecar's arrays (docs/bakeinfo.md; its zip members carry the write's time, so
    the bytes differ run to run): noise, leaves, decisions and the .shprobe's hash."""
    h = hashlib.sha256()
    with np.load(str(path), allow_pickle=False) as z:
        for name in sorted(z.files):
            a = z[name]
            h.update(f"{name} {a.dtype} {a.shape}".encode() + a.tobytes())
    return h.hexdigest()


def _pixels(path):
    """The sky's pixels (its EXR header holds the render's date, so the bytes differ run to run)."""
    return hashlib.sha256(native.read_image(str(path)).tobytes()).hexdigest()


def _panel_labels(blend):
    proc = run_blender(SCRIPTS / "journal_panel.py", blend=blend, timeout=120)
    return json.loads([l for l in proc.stdout.splitlines() if l.startswith("RESULT ")][-1][7:])["labels"]


def _interrupt(blend, sig, at, args=()):
    """Start the bake (each render slowed by 0.2 s), send ``sig`` once the journal holds ``at``
    probes."""
    run = Running(blend, [*CELLS, *TINY, *args], {}, pre=SCRIPTS / "slow_render.py")
    _signal_at(run, blend, sig, at)
    return run.finish()


def _signal_at(run, blend, sig, at):
    """Send ``sig`` to the running bake once its journal holds ``at`` records (or it has ended, or
    240 s passed)."""
    path = str(blend.parent / "sh_coeffs" / "probes.shprobe.journal")
    end = time.monotonic() + 240
    while time.monotonic() < end and run.proc.poll() is None:
        info = journal.summary(path)
        if info and info["records"] >= at:
            break
        time.sleep(0.01)
    run.proc.send_signal(sig)


@pytest.mark.parametrize("sig", [signal.SIGKILL, signal.SIGINT], ids=["kill-9", "cancel"])
def test_interrupted_then_resumed_equals_uninterrupted(scenes, tmp_path, reference, sig):
    count, shprobe, sky = reference
    blend = copy_blend(scenes, "window_room.blend", tmp_path)
    at = random.Random(str(sig)).randrange(2, count - 2)
    rc, stdout, stderr = _interrupt(blend, sig, at)
    assert rc == (-9 if sig == signal.SIGKILL else 130), stderr[-2000:]
    out = tmp_path / "sh_coeffs"
    kept = len(journal.read(str(out / "probes.shprobe.journal")).values)
    assert at <= kept < count  # everything up to the probe it was rendering when interrupted
    assert not (out / "probes.shprobe").exists()
    # The panel says a resumable bake exists (and says nothing once it is spent, below).
    assert _panel_labels(blend) == [f"Resumable bake: {kept} probe(s) kept", "probes.shprobe.journal"]
    proc = bake(blend, *CELLS, *TINY)
    assert proc.returncode == 0, proc.stdout[-2000:] + proc.stderr[-2000:]
    assert _panel_labels(blend) == []
    assert f"resuming from {out / 'probes.shprobe.journal'}: {kept} of {count} probes already baked, " \
           f"{count - kept} to render" in proc.stdout
    assert f"probe {count}/{count}" in proc.stdout
    assert _sha(out / "probes.shprobe") == shprobe and _pixels(out / "sky.exr") == sky
    assert not (out / "probes.shprobe.journal").exists()


def test_shards_merge_to_the_same_bytes(scenes, tmp_path, reference):
    count, shprobe, sky = reference
    blend = copy_blend(scenes, "window_room.blend", tmp_path)
    out = tmp_path / "sh_coeffs"
    for k in range(3):
        proc = bake(blend, *CELLS, *TINY, "--shard", f"{k}/3")
        assert proc.returncode == 0, proc.stdout[-2000:] + proc.stderr[-2000:]
        assert f"wrote {out / f'probes.shprobe.shard-{k}-of-3.journal'}" in proc.stdout
        assert len(journal.read(str(out / f"probes.shprobe.shard-{k}-of-3.journal")).values) == \
            len(range(k, count, 3))
    assert not (out / "probes.shprobe").exists()  # shards write no output
    proc = bake(blend, *CELLS, *TINY, "--merge-shards", "3")
    assert proc.returncode == 0, proc.stdout[-2000:] + proc.stderr[-2000:]
    assert f"{count} of {count} probes already baked, 0 to render" in proc.stdout
    assert _sha(out / "probes.shprobe") == shprobe and _pixels(out / "sky.exr") == sky


def test_merge_refuses_missing_and_foreign_shards(scenes, tmp_path):
    blend = copy_blend(scenes, "window_room.blend", tmp_path)
    out = tmp_path / "sh_coeffs"
    # Shard 1 baked with other samples: another bake.
    assert bake(blend, *CELLS, "--panorama-resolution", "16", "--samples", "2", "--shard", "1/2").returncode == 0
    proc = bake(blend, *CELLS, *TINY, "--merge-shards", "2")
    assert proc.returncode == 3
    assert "1 of 2 shard journal(s) missing (probes.shprobe.shard-0-of-2.journal)" in last_error(proc)
    # A shard reads the other shards' journals (their points feed its refinement): refused early.
    proc = bake(blend, *CELLS, *TINY, "--shard", "0/2")
    assert proc.returncode == 3
    msg = last_error(proc)
    assert "probes.shprobe.shard-1-of-2.journal belongs to another bake (changed since it was written: " \
           "settings)" in msg, msg
    # Shard 0 alone is fine (moved aside from the foreign one); the merge names what changed.
    (out / "probes.shprobe.shard-1-of-2.journal").rename(tmp_path / "foreign")
    assert bake(blend, *CELLS, *TINY, "--shard", "0/2").returncode == 0
    (tmp_path / "foreign").rename(out / "probes.shprobe.shard-1-of-2.journal")
    proc = bake(blend, *CELLS, *TINY, "--merge-shards", "2")
    assert proc.returncode == 3
    msg = last_error(proc)
    assert "probes.shprobe.shard-1-of-2.journal belongs to another bake (changed since it was written: " \
           "settings)" in msg, msg
    assert not (out / "probes.shprobe").exists()


def test_journal_of_other_settings_is_moved_aside(scenes, tmp_path, reference):
    count, shprobe, _ = reference
    blend = copy_blend(scenes, "window_room.blend", tmp_path)
    out = tmp_path / "sh_coeffs"
    rc, _, _ = _interrupt(blend, signal.SIGKILL, 3)
    old = (out / "probes.shprobe.journal").read_bytes()
    # Another panorama size: not resumed (its probes would be wrong), kept as .previous, baked from
    # scratch.
    proc = bake(blend, *CELLS, "--panorama-resolution", "32", "--samples", "1")
    assert proc.returncode == 0, proc.stdout[-2000:] + proc.stderr[-2000:]
    assert "belongs to another bake (changed since it was written: settings)" in proc.stdout
    assert "resuming" not in proc.stdout
    assert (out / "probes.shprobe.journal.previous").read_bytes() == old
    assert _sha(out / "probes.shprobe") != shprobe


def test_fingerprint_names_what_changed(scenes):
    """Each edit changes exactly the part that holds it; editor-only changes, where the files go and
    how they store the values (SH / ambient cube, float / half) change nothing (so they never block
    a resume)."""
    proc = run_blender(SCRIPTS / "fingerprint_parts.py", blend=scenes / "window_room.blend", timeout=120)
    changed = json.loads([l for l in proc.stdout.splitlines() if l.startswith("RESULT ")][-1][7:])["changed"]
    assert changed == {
        "nothing": [], "node moved in the editor": [], "material colour": ["materials"], "wall moved": ["geometry"],
        "world strength": ["world"], "bounces": ["render"], "lamp added": ["lights"], "lamp mode": ["lights"],
        "samples setting": ["settings"], "output path only": [], "probe representation only": [],
        "dilate setting": [], "window setting": [], "window strength": [],
    }


def test_adaptive_shards_pass_by_pass(scenes, tmp_path):
    """Adaptive placement refines pass by pass, so a shard bakes its share of one stage and stops
    until the other shards' points of that stage exist (what the farm's chained arrays do): shards
    run in turn, then the merge writes the same bytes as a local bake."""
    adaptive_reference = _adaptive_reference(scenes, tmp_path / "local")
    farm = tmp_path / "farm"
    blend = copy_blend(scenes, "window_room.blend", farm)
    waits = 0
    log = farm / "renders.log"
    for _ in range(adaptive.stage_bound(1, 2)):  # one round per stage, as the farm chains its arrays
        for k in range(2):
            rc, out = _counted(blend, [*ADAPTIVE, "--shard", f"{k}/2"], log)
            assert rc == 0, out[-3000:]
            waits += "its share of this pass is baked" in out
    assert waits >= 2  # the shards did wait for each other at a stage boundary
    rc, out = _counted(blend, [*ADAPTIVE, "--merge-shards", "2"], log)
    assert rc == 0, out[-3000:]
    assert _sha(farm / "sh_coeffs" / "probes.shprobe") == adaptive_reference.shprobe
    assert _sidecar(farm / "sh_coeffs" / "probes.shprobe.bakeinfo") == adaptive_reference.bakeinfo
    # Issue 29: every render of the shards once, and the same renders as the local bake (the merge
    # renders nothing but the sky).
    renders = _renders_per_key(log)
    assert max(renders.values()) == 1
    assert set(renders) == set(adaptive_reference.renders)


def test_adaptive_killed_then_resumed_equals_uninterrupted(scenes, tmp_path):
    """The default placement: killed in its second stage (test points), resumed, same bytes."""
    ref = _adaptive_reference(scenes, tmp_path / "local")
    blend = copy_blend(scenes, "window_room.blend", tmp_path / "killed")
    log = tmp_path / "killed" / "renders.log"
    rc, _ = _counted(blend, ADAPTIVE, log, signal.SIGKILL, ref.first_layer + 3)
    assert rc == -9
    out = tmp_path / "killed" / "sh_coeffs"
    path = str(out / "probes.shprobe.journal")
    kept = len(journal.read(path).values)
    assert journal.summary(path)["records"] == kept      # issue 29: no key twice in the journal
    assert ref.first_layer + 3 <= kept < ref.points  # past the first layer, short of the whole bake
    rc, stdout = _counted(blend, ADAPTIVE, log)
    assert rc == 0, stdout[-3000:]
    assert f"{ref.first_layer} of {ref.first_layer} probes already baked, 0 to render in the first pass ({kept} points" \
        in stdout, stdout[-3000:]
    assert _sha(out / "probes.shprobe") == ref.shprobe
    assert _sidecar(out / "probes.shprobe.bakeinfo") == ref.bakeinfo   # noise and decisions too
    # Issue 29: the killed bake and its resume render every key of the uninterrupted bake, each once,
    # but for the point the kill cut short (its renders without a record: at most its two first rounds).
    renders = _renders_per_key(log)
    assert set(renders) == set(ref.renders)
    twice = [k for k, n in renders.items() if n > 1]
    assert len(twice) <= 2 and len({k[:3] for k in twice}) <= 1 and max(renders.values()) <= 2
