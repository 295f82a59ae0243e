"""Nothing lost, nothing hung (issue 14, add-on and bake.py side), in real headless Blender 3.4:

- outputs that are not ours (the open .blend, another file, a FIFO, a folder) are refused before
  the bake starts, by bake.py (exit 3) and the operators, and left as they were;
- SIGINT and SIGTERM cancel a headless bake like Esc (exit 130 / 143, scene restored, temporary
  folder gone, the previous output byte for byte), and a killed bake's temporary folder is removed
  by the next bake;
- the probe count and an estimate are printed before the first render, and a bake above
  --probe-limit needs --allow-large;
- NaN/Inf emission is refused naming the material and the object; Inf in a rendered panorama
  names the probe and its position;
- with the Cycles add-on disabled both operators and bake.py refuse before placement, saying so.

Runtime: about a minute on 2 cores (tiny panoramas, 1 sample).
"""
import hashlib
import json
import os
import re
import signal
import stat
import subprocess
import threading
import time
from pathlib import Path

import numpy as np
import pytest

from conftest import ADDON_DIR, REPO, requires_native, run_blender
from schnee_probes import journal as journal_mod

SCRIPTS = Path(__file__).resolve().parent / "scripts"
BAKE_PY = REPO / "bake.py"
TINY = ["--panorama-resolution", "16", "--samples", "1"]
CELLS_2M = ["--min-cell-size", "2", "--max-cell-size", "2"]  # sky volume: 4 probes

pytestmark = requires_native


def scenes_made_by(script):
    """A module-scoped fixture: a temporary folder holding the .blend files that SCRIPTS/``script``
    writes into the folder it is given."""
    @pytest.fixture(scope="module")
    def scenes(tmp_path_factory):
        out = tmp_path_factory.mktemp(Path(script).stem)
        run_blender(SCRIPTS / script, out, timeout=120)
        return out
    return scenes


scenes = scenes_made_by("hazard_scenes.py")


def copy_blend(scenes, name, dest):
    dest.mkdir(parents=True, exist_ok=True)
    target = dest / name
    target.write_bytes((scenes / name).read_bytes())
    return target


def bake(blend, *args, env=None):
    # The geometry octree these tests were written for (Adaptive placement: test_refine_bake.py).
    return run_blender(BAKE_PY, "--placement", "OCTREE", *args, blend=blend, check=False, timeout=300, env=env)


def digest(path):
    return hashlib.sha256(Path(path).read_bytes()).hexdigest()


def last_error(proc):
    return proc.stderr.strip().splitlines()[-1] if proc.stderr.strip() else ""


# --------------------------------------------------------------------------- outputs not ours
def test_output_onto_the_open_blend_is_refused(scenes, tmp_path):
    # Issue 14: `--output //scene.blend` replaced the .blend with a 720-byte .shprobe (exit 0).
    blend = copy_blend(scenes, "sky.blend", tmp_path)
    before = digest(blend)
    proc = bake(blend, "--output", "//sky.blend", *CELLS_2M, *TINY)
    assert proc.returncode == 3, proc.stdout[-2000:] + proc.stderr[-2000:]
    assert ".shprobe" in last_error(proc) and "sky.blend" in last_error(proc)
    assert digest(blend) == before
    assert sorted(p.name for p in tmp_path.iterdir()) == ["sky.blend"]  # no sky.exr either
    # The same .blend reached through a .shprobe name (a symlink): refused as the open .blend.
    link = tmp_path / "out" / "probes.shprobe"
    link.parent.mkdir()
    link.symlink_to(blend)
    proc = bake(blend, "--output", link, *CELLS_2M, *TINY)
    assert proc.returncode == 3
    assert "open .blend" in last_error(proc), last_error(proc)
    assert digest(blend) == before and link.is_symlink()


@pytest.mark.parametrize("kind", ["text", "fifo", "folder", "sky_not_exr"])
def test_existing_output_that_is_not_ours_is_refused(scenes, tmp_path, kind):
    blend = copy_blend(scenes, "sky.blend", tmp_path)
    out = tmp_path / "sh_coeffs" / "probes.shprobe"
    out.parent.mkdir()
    if kind == "text":
        out.write_text("precious notes\n")
    elif kind == "fifo":
        os.mkfifo(out)
    elif kind == "folder":
        out.mkdir()
    else:
        (out.parent / "sky.exr").write_text("not an image\n")
    t0 = time.monotonic()
    proc = bake(blend, *CELLS_2M, *TINY)
    assert proc.returncode == 3, proc.stdout[-2000:] + proc.stderr[-2000:]
    msg = last_error(proc)
    assert msg.startswith("bake.py: error: Refusing to replace"), msg
    assert {"text": "not a .shprobe", "fifo": "a FIFO", "folder": "a directory",
            "sky_not_exr": "not an OpenEXR"}[kind] in msg, msg
    assert "probe 1/" not in proc.stdout  # refused before any render
    assert time.monotonic() - t0 < 120  # a FIFO does not block the check
    if kind == "text":
        assert out.read_text() == "precious notes\n"
    elif kind == "fifo":
        assert stat.S_ISFIFO(os.lstat(out).st_mode)
    elif kind == "folder":
        assert out.is_dir()
    else:
        assert (out.parent / "sky.exr").read_text() == "not an image\n" and not out.exists()
    assert not list(tmp_path.glob("**/*.partial"))


def test_our_own_shprobe_is_replaced(scenes, tmp_path):
    # The check is by content: a previous bake's file is ours and gets replaced.
    blend = copy_blend(scenes, "sky.blend", tmp_path)
    assert bake(blend, *CELLS_2M, *TINY).returncode == 0
    out = tmp_path / "sh_coeffs" / "probes.shprobe"
    assert out.read_bytes()[:4] == b"SPHR"
    proc = bake(blend, *CELLS_2M, *TINY, "--seed", "5")
    assert proc.returncode == 0, proc.stderr[-2000:]


def test_operators_refuse_outputs_not_ours(scenes, tmp_path):
    proc = run_blender(SCRIPTS / "hazard_operator.py", tmp_path, blend=scenes / "sky.blend")
    r = json.loads([l for l in proc.stdout.splitlines() if l.startswith("RESULT ")][-1][7:])
    assert r["volumes_result"] == ["CANCELLED"] and r["foreign_unchanged"]
    assert r["volumes_message"].startswith("Refusing to replace") and "notes.shprobe" in r["volumes_message"]
    assert r["cursor_result"] == ["CANCELLED"]
    assert "debug_probe.txt" in r["cursor_message"], r["cursor_message"]
    assert r["cursor_files"] == ["debug_probe.txt"]
    # The estimate (same run, 4 x 4 x 2 m sky volume at 1 m cells = 32 probes): the model before
    # the first probe is 32 x 3.9 µs x 128 x 64 px x 16 spp + 1.6 s upload = 18.0 s; after 4 probes
    # of a sky-only scene (measured 0.15 µs per pixel-sample in the sweep, ~25x cheaper than the
    # room the model assumes) it is the measured mean of probes 2-4 times the 28 left.
    assert r["total"] == 32
    # 32 probes x (3.9 µs x 128 x 64 px x 16 spp + 0.03 s per render) + 1.6 s scene upload.
    assert r["estimated"] == pytest.approx(32 * (3.9e-6 * 128 * 64 * 16 + 0.03) + 1.6, rel=1e-9)
    assert r["model_before"] == pytest.approx(r["estimated"], rel=1e-9)
    measured = (r["spent_4"] - r["first_probe"]) / 3 * 28
    assert r["remaining_after_4"] == pytest.approx(measured, rel=1e-9)
    assert r["remaining_after_4"] < 0.5 * r["model_after_4"], r
    assert r["line"].startswith("Schnee bake: probe 4/32")


# ------------------------------------------------------------------------------- signals
class Running:
    """bake.py as a subprocess whose stdout is read as it comes (progress lines end in \\r)."""

    def __init__(self, blend, args, env, pre=None):
        cmd = ["blender", "-b", str(blend), "--factory-startup"]
        for script in ([] if pre is None else pre if isinstance(pre, (list, tuple)) else [pre]):
            cmd += ["-P", str(script)]
        cmd += ["-P", str(BAKE_PY), "--", "--placement", "OCTREE"] + [str(a) for a in args]
        full_env = {**os.environ, "PYTHONPATH": str(ADDON_DIR), "SCHNEE_REPO": str(REPO), **env}
        self.proc = subprocess.Popen(cmd, stdout=subprocess.PIPE, stderr=subprocess.PIPE, env=full_env)
        self.out, self.err = bytearray(), bytearray()
        self._threads = [threading.Thread(target=self._pump, args=(s, b), daemon=True)
                         for s, b in ((self.proc.stdout, self.out), (self.proc.stderr, self.err))]
        for t in self._threads:
            t.start()

    @staticmethod
    def _pump(stream, buf):
        while True:
            chunk = stream.read1(4096) if hasattr(stream, "read1") else stream.read(1)
            if not chunk:
                return
            buf.extend(chunk)

    def wait_for(self, text, timeout=240, after=None):
        """Until stdout holds ``text`` (after the first ``after``, when given)."""
        end = time.monotonic() + timeout
        while time.monotonic() < end:
            start = 0 if after is None else self.out.find(after.encode())
            if start >= 0 and text.encode() in self.out[start:]:
                return
            if self.proc.poll() is not None:
                break
            time.sleep(0.02)
        raise AssertionError(f"never saw {text!r}: {self.out[-2000:].decode(errors='replace')}"
                             f"{self.err[-2000:].decode(errors='replace')}")

    def finish(self, timeout=240):
        rc = self.proc.wait(timeout)
        for t in self._threads:
            t.join(10)
        return rc, self.out.decode(errors="replace"), self.err.decode(errors="replace")


def _previous_output(scenes, tmp_path):
    """The room baked once (the output a cancelled bake must leave intact), with TMPDIR in the test's
    folder: (blend, tmp, env, output folder, {name: digest} of the output)."""
    blend = copy_blend(scenes, "room.blend", tmp_path)
    tmp = tmp_path / "tmp"
    tmp.mkdir()
    env = {"TMPDIR": str(tmp)}
    assert bake(blend, *CELLS_2M, *TINY, env=env).returncode == 0  # the previous output
    out = tmp_path / "sh_coeffs"
    before = {p.name: digest(p) for p in out.iterdir()}
    assert set(before) == {"probes.shprobe", "sky.exr"}
    return blend, tmp, env, out, before


def _assert_cancelled_like_esc(stdout, stderr, sig, tmp, out, before):
    """A headless bake of 256 probes cancelled by ``sig``: the documented last line, no traceback,
    the scene state restored (bake_state_probe.py's RESULT), the temporary folder removed, the old
    output intact and the probes baked so far in the journal. Returns how many were kept."""
    last = stderr.strip().splitlines()[-1]
    journal = out / "probes.shprobe.journal"
    m = re.fullmatch(rf"bake\.py: error: cancelled by {signal.Signals(sig).name}; render settings restored, "
                     rf"existing files unchanged; (\d+) of 256 probes kept in {re.escape(str(journal))}; the same "
                     "bake run again resumes from them", last)
    assert m and 1 <= int(m.group(1)) < 256, last
    assert "Traceback" not in stderr
    assert "probe 256/256" not in stdout
    # (the progress line ends in neither \r nor \n: RESULT may follow it on the same line)
    results = re.findall(r"RESULT (\{.*\})", stdout)
    assert results, stdout[-1500:] + stderr[-3000:]
    result = json.loads(results[-1])
    assert result["diff"] == [] and result["engine"] == "BLENDER_EEVEE"  # scene state restored
    assert list(tmp.iterdir()) == []  # temporary folder removed
    # Old output intact, no .partial; the probes baked so far are in the journal (docs/farm.md).
    after = {p.name: digest(p) for p in out.iterdir()}
    assert after.pop(journal.name) and after == before
    assert len(journal_mod.read(str(journal)).values) == int(m.group(1))
    return int(m.group(1))


@pytest.mark.parametrize("sig,code", [(signal.SIGINT, 130), (signal.SIGTERM, 143)], ids=["SIGINT", "SIGTERM"])
def test_signal_cancels_headless_bake_like_esc(scenes, tmp_path, sig, code):
    blend, tmp, env, out, before = _previous_output(scenes, tmp_path)
    # 0.5 m cells: 256 probes, long enough to be interrupted after the first.
    run = Running(blend, ["--min-cell-size", "0.5", "--max-cell-size", "0.5", *TINY], env,
                  pre=SCRIPTS / "bake_state_probe.py")
    run.wait_for("probe 1/")
    assert list(tmp.glob("schnee_bake_*")), "the bake's temporary folder should exist while it runs"
    run.proc.send_signal(sig)
    rc, stdout, stderr = run.finish()
    assert rc == code, stdout[-2000:] + stderr[-2000:]
    _assert_cancelled_like_esc(stdout, stderr, sig, tmp, out, before)


# Where the second Ctrl+C lands: during the next probe's render (each render slowed to 3 s, so
# the cancel after the first one cannot be over yet), or while Blender exits after bake.py cleaned
# up (an atexit hook sleeping 3 s, after the first signal's cancel of a 0.3 s render; before the
# fix the default action was back by then: killed by SIGINT, exit -2).
SECOND_SIGINT = {"during_render": {"SCHNEE_TEST_RENDER_DELAY": "3"},
                 "during_exit": {"SCHNEE_TEST_RENDER_DELAY": "0.3", "SCHNEE_TEST_EXIT_DELAY": "3"}}


@pytest.mark.parametrize("when", sorted(SECOND_SIGINT))
def test_second_sigint_still_cancels_cleanly(scenes, tmp_path, when):
    # A user pressing Ctrl+C twice, 0.5 s apart: the second one must not cut the clean-up or the
    # exit short (no death by SIGINT, no KeyboardInterrupt traceback, no exit 2): still exit 130,
    # the scene restored, the temporary folder gone and the previous output byte for byte.
    blend, tmp, env, out, before = _previous_output(scenes, tmp_path)
    run = Running(blend, ["--min-cell-size", "0.5", "--max-cell-size", "0.5", *TINY], {**env, **SECOND_SIGINT[when]},
                  pre=[SCRIPTS / "slow_render.py", SCRIPTS / "bake_state_probe.py"])
    run.wait_for("probe 1/")
    assert list(tmp.glob("schnee_bake_*"))
    if when == "during_render":  # inside probe 2's 3 s post-render sleep, not between two probes
        run.wait_for("SLOW_RENDER start", after="probe 1/")
    run.proc.send_signal(signal.SIGINT)
    if when == "during_exit":
        run.wait_for("SLOW_EXIT start", timeout=30)  # bake.py is done; Blender is exiting
    else:
        time.sleep(0.5)
    assert run.proc.poll() is None, "the second SIGINT must reach a running bake: " + run.out[-600:].decode(errors="replace") + run.err[-1500:].decode(errors="replace")
    if when == "during_exit":
        assert not list(tmp.glob("schnee_bake_*"))  # cleaned up before the exit started
    run.proc.send_signal(signal.SIGINT)
    rc, stdout, stderr = run.finish()
    assert rc == 130, f"exit {rc}\n" + stdout[-2000:] + stderr[-3000:]
    if when == "during_exit":
        assert "SLOW_EXIT end" in stdout  # the exit ran to its end
    _assert_cancelled_like_esc(stdout, stderr, signal.SIGINT, tmp, out, before)
    assert stderr.count("SIGINT received: cancelling the bake") == 1  # said once, not per signal
    assert "KeyboardInterrupt" not in stderr


def test_killed_bake_leaves_a_folder_the_next_bake_removes(scenes, tmp_path):
    blend = copy_blend(scenes, "room.blend", tmp_path)
    tmp = tmp_path / "tmp"
    tmp.mkdir()
    env = {"TMPDIR": str(tmp)}
    alive = tmp / f"schnee_bake_{os.getpid()}_keepme"  # a running process's folder: kept
    alive.mkdir()
    other = tmp / "schnee_bake_oldstyle"  # no process id in the name: not ours to judge
    other.mkdir()
    run = Running(blend, ["--min-cell-size", "0.5", "--max-cell-size", "0.5", *TINY], env)
    run.wait_for("probe 1/")
    pid = run.proc.pid
    run.proc.kill()  # SIGKILL: no clean-up possible
    run.finish()
    left = [p.name for p in tmp.glob(f"schnee_bake_{pid}_*")]
    assert len(left) == 1, list(tmp.iterdir())
    proc = bake(blend, *CELLS_2M, *TINY, env=env)
    assert proc.returncode == 0, proc.stderr[-2000:]
    assert f"removed 1 temporary folder(s) left by killed bakes: {left[0]}" in proc.stdout
    assert sorted(p.name for p in tmp.glob("schnee_bake_*")) == sorted([alive.name, other.name])


# ------------------------------------------------------------------ estimate and limit
def test_probe_count_and_estimate_before_the_first_render(scenes, tmp_path):
    blend = copy_blend(scenes, "sky.blend", tmp_path)
    proc = bake(blend, *CELLS_2M, *TINY)
    assert proc.returncode == 0, proc.stderr[-2000:]
    lines = proc.stdout.replace("\r", "\n").splitlines()
    first_render = next(i for i, l in enumerate(lines) if "probe 1/4" in l)
    bound = next(i for i, l in enumerate(lines) if l.startswith("Schnee: placing probes (at most 4 "))
    est = next(i for i, l in enumerate(lines) if l.startswith("Schnee: 4 probe(s) to bake, estimated "))
    assert bound < est < first_render
    # 4 x 3.9 µs x 16 x 8 px x 1 spp + 1.6 s upload + the sky at 0.15 µs x 512 x 256 = 1.62 s.
    assert lines[est].startswith("Schnee: 4 probe(s) to bake, estimated 2 s"), lines[est]


def test_panel_estimate_matches_the_headless_line(scenes, tmp_path):
    # properties.draw_estimate (the panel and the bake dialog) and bake.py on the same scene and
    # settings: 4 x 4 x 2 m volume at 2 m cells, 256 x 128 px, 16 spp, sky 512 x 256. The model:
    # 4 x 3.9 µs x 256 x 128 x 16 + 1.6 s + 0.15 µs x 512 x 256 x 16 = 8.18 + 1.6 + 0.31 = 10.1 s.
    settings = {"placement": "OCTREE", "min_cell_size": 2.0, "max_cell_size": 2.0, "panorama_resolution": 256,
                "samples": 16, "sky_resolution": 512, "capture_sky": True}
    proc = run_blender(SCRIPTS / "draw_estimate.py", json.dumps(settings), blend=scenes / "sky.blend", timeout=120)
    cases = json.loads([l for l in proc.stdout.splitlines() if l.startswith("RESULT ")][-1][7:])["cases"]
    seconds = 4 * 3.9e-6 * 256 * 128 * 16 + 1.6 + 0.15e-6 * 512 * 256 * 16
    assert f"{seconds:.0f} s" == "10 s"
    assert cases["as_set"] == [["Up to 4 probes, at most ~10 s", "TIME"]]
    assert cases["limit_3"] == [["Up to 4 probes, at most ~10 s", "TIME"],
                                ["May exceed Confirm Above (3): the bake will ask", "ERROR"]]
    assert cases["no_volumes"] == [["Probes: no usable probe volumes or settings", "INFO"]]
    # The headless path, same scene and settings: the bound before placement, then (the exact
    # count equals the bound here) the same estimate in the limit's refusal, before any render.
    blend = copy_blend(scenes, "sky.blend", tmp_path)
    proc = bake(blend, "--min-cell-size", "2", "--max-cell-size", "2", "--panorama-resolution", "256",
                "--samples", "16", "--sky-resolution", "512", "--probe-limit", "3")
    assert proc.returncode == 3, proc.stdout[-2000:] + proc.stderr[-2000:]
    bound = re.search(r"Schnee: placing probes \(at most (\d+) ", proc.stdout)
    assert bound and int(bound.group(1)) == 4, proc.stdout[-2000:]
    refusal = re.search(r"(\d+) probes \(estimated ([^)]+)\) is more than the limit of 3", last_error(proc))
    assert refusal, last_error(proc)
    assert cases["as_set"][0][0] == f"Up to {bound.group(1)} probes, at most ~{refusal.group(2)}"
    assert "probe 1/" not in proc.stdout


def test_bake_above_the_limit_needs_allow_large(scenes, tmp_path):
    blend = copy_blend(scenes, "sky.blend", tmp_path)
    proc = bake(blend, *CELLS_2M, *TINY, "--probe-limit", "3")
    assert proc.returncode == 3, proc.stdout[-2000:] + proc.stderr[-2000:]
    msg = last_error(proc)
    assert "4 probes (estimated 2 s) is more than the limit of 3" in msg and "--allow-large" in msg, msg
    assert "probe 1/" not in proc.stdout and not (tmp_path / "sh_coeffs").exists()
    proc = bake(blend, *CELLS_2M, *TINY, "--probe-limit", "3", "--allow-large")
    assert proc.returncode == 0, proc.stderr[-2000:]
    assert "probe 4/4" in proc.stdout


# ------------------------------------------------------------------ values we cannot represent
@pytest.mark.parametrize("blend_name,words", [
    ("emission_inf.blend", ["material 'Hot'", "node 'Emission' input 'Strength' is Inf", "object 'HotBox'"]),
    ("emission_nan.blend", ["material 'NaNGlow'", "input 'Emission' is NaN", "object 'GlowBox'"]),
], ids=["inf_strength", "nan_colour"])
def test_non_finite_emission_is_refused_naming_it(scenes, tmp_path, blend_name, words):
    # Cycles drops such light silently; the old bake exited 0 without it.
    blend = copy_blend(scenes, blend_name, tmp_path)
    proc = bake(blend, *CELLS_2M, *TINY)
    assert proc.returncode == 3, proc.stdout[-2000:] + proc.stderr[-2000:]
    msg = last_error(proc)
    for w in words:
        assert w in msg, msg
    assert not (tmp_path / "sh_coeffs").exists()


@pytest.mark.parametrize("blend_name,words", [
    ("image_missing.blend", ["image 'brick.png'", "material 'Bricks'", "object 'Brick'",
                             os.path.join("textures", "brick.png")]),
    ("world_missing.blend", ["image 'lost_sky.exr'", "world 'Lost'", os.path.join("hdri", "lost_sky.exr")]),
], ids=["material", "world"])
def test_a_missing_image_file_is_refused_naming_it(scenes, tmp_path, blend_name, words):
    # Cycles renders a missing texture magenta; the bake used to hold that colour without a word.
    # (Every other scene here renders Blender's own courtyard.exr: a found image passes.)
    blend = copy_blend(scenes, blend_name, tmp_path)
    proc = bake(blend, *CELLS_2M, *TINY)
    assert proc.returncode == 3, proc.stdout[-2000:] + proc.stderr[-2000:]
    msg = last_error(proc)
    for w in words + ["magenta", "Find Missing Files"]:
        assert w in msg, msg
    assert str(tmp_path) in msg                      # the absolute path the render looked for
    assert not (tmp_path / "sh_coeffs").exists()


def test_inf_in_a_panorama_names_the_probe_and_its_position(scenes, tmp_path):
    # Emission 1e38 is finite (not refused up front), but 4 samples of it sum past float32's
    # range: the panorama holds Inf, which the native projection refuses. The bake says which
    # probe, where, and what to look for; no output is written, only the journal of the probes
    # before it (docs/farm.md).
    blend = copy_blend(scenes, "emission_huge.blend", tmp_path)
    proc = bake(blend, *CELLS_2M, "--panorama-resolution", "16", "--samples", "4")
    assert proc.returncode == 3, proc.stdout[-2000:] + proc.stderr[-2000:]
    msg = last_error(proc)
    m = re.match(r"bake.py: error: Projecting the panorama of probe (\d+) at Blender "
                 r"\((-?1\.000, ){2}1\.000\) failed: .*non-finite radiance inf at pixel", msg)
    assert m, msg
    assert "the render holds NaN or Inf, which the probes cannot represent" in msg
    out = tmp_path / "sh_coeffs"
    kept = int(m.group(1)) - 1  # the probes rendered before the failing one
    if kept:
        assert [p.name for p in out.iterdir()] == ["probes.shprobe.journal"]
        assert len(journal_mod.read(str(out / "probes.shprobe.journal")).values) == kept
        assert msg.endswith(f"; {kept} of 4 probes kept in {out / 'probes.shprobe.journal'}; the same bake run "
                            "again resumes from them"), msg
    else:
        assert not out.exists()


# ------------------------------------------------------------------ Cycles add-on disabled
CYCLES_DISABLED = "the Cycles add-on is disabled: enable it in Preferences > Add-ons"


def test_bake_without_cycles_is_refused_before_anything(scenes, tmp_path):
    """With the Cycles add-on disabled the scene has no ``cycles`` settings and 'CYCLES' is no render
    engine: before, the bake placed the probes and then died in apply_bake_settings (TypeError /
    AttributeError). Now both operators and bake.py refuse at once, saying what to do, and leave
    the scene and the output folder as they were."""
    proc = run_blender(SCRIPTS / "hazard_no_cycles.py", tmp_path, blend=scenes / "sky.blend", timeout=120)
    r = json.loads([l for l in proc.stdout.splitlines() if l.startswith("RESULT ")][-1][7:])
    assert r["cycles_enabled"] == [False, False] and r["scene_has_cycles"] is False
    for op in ("volumes", "cursor"):
        assert r[f"{op}_result"] == ["CANCELLED"]
        assert CYCLES_DISABLED in r[f"{op}_message"], r[f"{op}_message"]
    assert r["files"] == []
    assert r["state_after"] == r["state_before"]
    assert "Traceback" not in proc.stdout + proc.stderr

    # bake.py, Cycles disabled by a --python-expr before it: exit 3 with the same words, no output.
    blend = copy_blend(scenes, "sky.blend", tmp_path / "cli")
    before = digest(blend)
    cmd = ["blender", "-b", str(blend), "--factory-startup", "--python-exit-code", "1", "--python-expr",
           "import addon_utils; addon_utils.disable('cycles', default_set=True)",
           "-P", str(BAKE_PY), "--", *CELLS_2M, *TINY]
    proc = subprocess.run(cmd, capture_output=True, text=True, timeout=120,
                          env={**os.environ, "PYTHONPATH": str(ADDON_DIR), "SCHNEE_REPO": str(REPO)})
    assert proc.returncode == 3, proc.stdout[-2000:] + proc.stderr[-2000:]
    assert last_error(proc).startswith("bake.py: error: ") and CYCLES_DISABLED in last_error(proc), last_error(proc)
    assert "placing probes" not in proc.stdout  # refused before placement
    assert sorted(p.name for p in blend.parent.iterdir()) == ["sky.blend"] and digest(blend) == before


def test_half_storage_overflow_names_the_probe_and_says_choose_float(scenes, tmp_path):
    # Issue 14: an emission of 1e30 baked with half storage. The native writer refused the file
    # naming only a record ("probe 3 face 0 R is 1e+30 (offset …)"): the bake must say which probe
    # (where, in Blender coordinates) and what to do, and write nothing.
    from schnee_probes import native, scene_export
    blend = copy_blend(scenes, "emission_1e30.blend", tmp_path)
    adaptive = ["--placement", "ADAPTIVE", "--file-version", "V3", *CELLS_2M, *TINY]
    proc = bake(blend, *adaptive, "--probe-representation", "CUBE_FLOAT")
    assert proc.returncode == 0, proc.stdout[-2000:] + proc.stderr[-2000:]
    out = tmp_path / "sh_coeffs" / "probes.shprobe"
    previous = native.read_shprobe(str(out))
    assert previous.representation == "ambientCube" and previous.storage == "float32"
    assert np.abs(previous.coeffs).max() > 1e20  # the 1e30 light is there, beyond half floats
    before = {p.name: digest(p) for p in out.parent.iterdir()}

    proc = bake(blend, *adaptive, "--probe-representation", "CUBE_HALF")
    assert proc.returncode == 3, proc.stdout[-2000:] + proc.stderr[-2000:]
    msg = last_error(proc)
    m = re.match(r"bake\.py: error: Probe Representation 'Ambient cube \(half\)' cannot store probes\.shprobe: "
                 r"probe (\d+) of (\d+) at Blender \((-?[\d.]+), (-?[\d.]+), (-?[\d.]+)\) has the irradiance "
                 r"(\S+) \(([RGB]), face ([+-][XYZ])\), beyond half floats' largest value 65504 \((\d+) probe\(s\) "
                 r"in all\); choose Probe Representation 'Ambient cube \(float\)' \(--probe-representation "
                 r"CUBE_FLOAT\), or lower the emission that lights it; existing files are unchanged", msg)
    assert m, msg
    k, n = int(m.group(1)) - 1, int(m.group(2))
    assert n == previous.probe_count
    # The probe named is the file's probe k: its position (engine space in the file) in Blender
    # coordinates, and the first colour beyond the range in the same bake's float file.
    where = scene_export.engine_to_blender(previous.positions[k])
    np.testing.assert_allclose([float(m.group(i)) for i in (3, 4, 5)], where, atol=1e-3)
    over = np.abs(previous.coeffs) > 65504
    assert over[k].any() and not over[:k].any()
    face, channel = (int(v) for v in np.argwhere(over[k])[0])
    assert m.group(7) == "RGB"[channel] and m.group(8) == ("+X", "-X", "+Z", "-Z", "-Y", "+Y")[face]
    assert float(m.group(6)) == pytest.approx(float(previous.coeffs[k, face, channel]), rel=1e-2)
    assert int(m.group(9)) == int(over.any(axis=(1, 2)).sum())
    # Nothing replaced, nothing partial; the probes are kept for a run with float storage.
    after = {p.name: digest(p) for p in out.parent.iterdir()}
    assert after.pop("probes.shprobe.journal") and after == before
    assert not list(tmp_path.glob("**/*.partial"))
    assert msg.endswith(f"; {n} baked point(s) kept in {out}.journal; the same bake run again resumes from them"), msg
    # Following the advice costs no render: the representation is not in the journal's fingerprint.
    proc = bake(blend, *adaptive, "--probe-representation", "CUBE_FLOAT")
    assert proc.returncode == 0, proc.stdout[-2000:] + proc.stderr[-2000:]
    assert re.search(rf"Schnee: resuming from \S+: {n} of {n} probes already baked, 0 to render", proc.stdout), \
        proc.stdout[-3000:]
    again = native.read_shprobe(str(out))
    np.testing.assert_array_equal(again.coeffs, previous.coeffs)
