"""The glTF export hook and special files in sh_coeffs/ (issue 14: nothing hung, nothing read that
should not be), in real headless Blender: a .shprobe or sky.exr that is a FIFO, a device, a symbolic
link loop, or that is swapped for one (or for another file) between the hook's validation and its
copy, is skipped with a warning naming it; the export finishes, nothing blocks, and only the good
file is in the glTF and copied. Before the fix the copy opened the swapped FIFO with a blocking
open() and the export hung (here: the 120 s timeout), and a FIFO present from the start was
skipped without a word. Runtime: ~3 s.
"""
import json
import os
import stat
import time
from pathlib import Path

import numpy as np
import pytest

from conftest import requires_native, run_blender
from test_export import ENGINE_EXT, load_gltf_json

SCRIPTS = Path(__file__).resolve().parent / "scripts"
pytestmark = requires_native

GOOD = ("a_good", "b_fifo_later", "c_device_later", "d_other_later")


def _write_good(native, path):
    coeffs = np.full((1, 9, 3), 0.5, dtype=np.float32)
    native.write_shprobe(str(path), coeffs, np.zeros(1, dtype=np.int32), (1, 1, 1), (0.0, 0.0, 0.0), 1.0)


def test_special_and_swapped_files_are_skipped_with_a_warning(tmp_path):
    from schnee_probes import native
    sh = tmp_path / "scene" / "sh_coeffs"
    sh.mkdir(parents=True)
    for name in GOOD:
        _write_good(native, sh / f"{name}.shprobe")
    good_bytes = (sh / "a_good.shprobe").read_bytes()
    os.mkfifo(sh / "e_fifo.shprobe")
    (sh / "f_device.shprobe").symlink_to("/dev/zero")
    (sh / "g_loop.shprobe").symlink_to(sh / "g_loop.shprobe")
    os.mkfifo(sh / "sky.exr")

    t0 = time.monotonic()
    proc = run_blender(SCRIPTS / "export_special_files.py", tmp_path, timeout=120)
    assert time.monotonic() - t0 < 120
    result = json.loads([l for l in proc.stdout.splitlines() if l.startswith("RESULT ")][-1][7:])
    assert result["swapped"] == ["b_fifo_later.shprobe", "c_device_later.shprobe", "d_other_later.shprobe"]

    # One warning per file, naming it and saying why (nothing else is warned about).
    p = lambda name: str(sh / name)  # noqa: E731
    expected = {
        f"skipped {p('b_fifo_later.shprobe')}: not a regular file (a FIFO (named pipe)); only regular files are "
        "read as a file to export",
        f"skipped {p('c_device_later.shprobe')}: not a regular file (a character device); only regular files are "
        "read as a file to export",
        f"skipped {p('d_other_later.shprobe')}: the file changed after it was checked; not copied",
        f"skipped {p('e_fifo.shprobe')}: not a regular file (a FIFO (named pipe))",
        f"skipped {p('f_device.shprobe')}: not a regular file (a character device)",
        f"skipped {p('g_loop.shprobe')}: cannot read it: Too many levels of symbolic links",
        f"skipped the sky {p('sky.exr')}: not a regular file (a FIFO (named pipe))",
    }
    warnings = [w.removeprefix("Schnee glTF export: ") for w in result["warnings"]]
    assert sorted(warnings) == sorted(expected), warnings
    for w in expected:  # and the user sees them (the exporter's console / report)
        assert w in proc.stdout + proc.stderr, w

    # Only the good file is in the glTF and copied, byte for byte, with no temporary file left.
    doc = load_gltf_json(tmp_path / "out" / "scene.gltf")
    scene = doc["scenes"][doc.get("scene", 0)]
    entries = scene["extensions"][ENGINE_EXT]["shProbeGrids"]
    assert [(e["name"], e["uri"], e["probeCount"]) for e in entries] == [("a_good", "sh_coeffs/a_good.shprobe", 1)]
    assert "sky" not in scene["extensions"][ENGINE_EXT]
    copied = tmp_path / "out" / "sh_coeffs"
    assert sorted(os.listdir(copied)) == ["a_good.shprobe"]
    assert (copied / "a_good.shprobe").read_bytes() == good_bytes
    # The special files are as they were (never opened for writing, never replaced).
    assert stat.S_ISFIFO(os.lstat(sh / "e_fifo.shprobe").st_mode) and stat.S_ISFIFO(os.lstat(sh / "sky.exr").st_mode)
    assert stat.S_ISFIFO(os.lstat(sh / "b_fifo_later.shprobe").st_mode)
    assert os.readlink(sh / "f_device.shprobe") == "/dev/zero"
