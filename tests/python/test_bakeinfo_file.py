"""The bake-info sidecar's reader and writer (addon/schnee_probes/bakeinfo.py, docs/bakeinfo.md)
without Blender: a v3 file written by the native writer and its sidecar read back; every rule of
"Readers" (missing, not an archive, another format or version, another .shprobe's hash, another
probe count or leaves, a pickled array, over the size cap) gives a message naming the sidecar and
"ignored", never an exception; a sidecar name over 255 bytes is not written. Runtime < 1 s."""
import os
from collections import namedtuple

import numpy as np
import pytest

from schnee_probes import bakeinfo, native

# bake_outputs.Output's fields (that module needs bpy)
Output = namedtuple("Output", "path kind write")


def _tree_file(path, split_first=True):
    tree = native.CornerOctree.uniform((0.0, 0.0, 0.0), 0.5, 2, (2, 1, 1))
    tree.finalize()
    if split_first:
        tree.split(np.array([1, 0], np.uint8))
        tree.finalize()
    p = int(tree.info()["probe_count"])
    c = np.zeros((p, 9, 3), np.float32)
    c[:, 0] = 1.0
    native.write_shprobe_v3(str(path), tree, c)
    f = native.read_shprobe(str(path))
    return f


def _arrays(f, **over):
    n = len(f.leaves)
    a = dict(placement=np.array("ADAPTIVE"), tolerance=np.float64(0.03), noise_k=np.float64(2.0),
             min_cell_size=np.float64(0.5), samples=np.int64(8),
             noise=np.linspace(0, 0.05, f.probe_count).astype(np.float32), leaves=np.asarray(f.leaves, np.uint32),
             leaf_error=np.full(n, 0.01, np.float32), leaf_threshold=np.full(n, 0.04, np.float32),
             leaf_parent_ratio=np.full(n, 2.0, np.float32), leaf_reason=np.full(n, bakeinfo.PASSED, np.uint8))
    a.update(over)
    return a


@pytest.fixture
def baked(tmp_path):
    path = tmp_path / "room.shprobe"
    f = _tree_file(path)
    bakeinfo.write(bakeinfo.path_for(str(path)), str(path), _arrays(f))
    return path, f


def _read(path, f, leaves="file"):
    return bakeinfo.read(bakeinfo.path_for(str(path)), str(path), f.probe_count,
                         f.leaves if leaves == "file" else leaves)


def test_written_sidecar_reads_back(baked):
    path, f = baked
    info = _read(path, f)
    assert info.error is None and not info.missing
    assert info.tolerance == 0.03 and np.array_equal(info.noise, _arrays(f)["noise"])
    assert np.allclose(info.leaf_ratio, 0.25) and (info.leaf_reason == bakeinfo.PASSED).all()
    with np.load(bakeinfo.path_for(str(path)), allow_pickle=False) as z:
        assert str(z["shprobe_sha256"]) == bakeinfo.sha256_file(str(path))
        assert open(bakeinfo.path_for(str(path)), "rb").read(4) == bakeinfo.MAGIC


def test_missing_sidecar_is_not_an_error(tmp_path):
    path = tmp_path / "old.shprobe"
    f = _tree_file(path)
    info = _read(path, f)
    assert info.missing and info.error is None and info.noise is None


def _message(baked, change):
    path, f = baked
    side = bakeinfo.path_for(str(path))
    change(path, f, side)
    info = _read(path, f)
    assert info.noise is None or info.error is not None
    assert info.error.startswith("room.shprobe.bakeinfo: ") and info.error.endswith("; ignored")
    return info.error


def test_sidecar_of_another_bake_is_ignored(baked):
    def rewrite_shprobe(path, f, side):   # a new bake of the .shprobe without a new sidecar
        _tree_file(path, split_first=False)
    path, f = baked
    rewrite_shprobe(path, f, None)
    g = native.read_shprobe(str(path))
    info = _read(path, g)
    assert info.error == ("room.shprobe.bakeinfo: written for another bake of the .shprobe (its SHA-256 "
                          "differs); ignored")


@pytest.mark.parametrize("case, words", [
    ("not_archive", "not a bake-info file (not a .npz archive)"),
    ("truncated", ""),
    ("format", "not a Schnee bake-info file"),
    ("version", "version 2; this add-on reads version 1"),
    ("count", "probes, the .shprobe has"),
    ("leaves", "its leaves differ from the .shprobe's"),
    ("pickled", "allow_pickle"),
    ("tolerance", "Error Tolerance nan"),
])
def test_malformed_or_mismatched_sidecar_is_a_message(baked, case, words):
    def change(path, f, side):
        a = _arrays(f)
        if case == "not_archive":
            open(side, "wb").write(b"hello")
            return
        if case == "truncated":
            data = open(side, "rb").read()
            open(side, "wb").write(data[:len(data) // 2])
            return
        if case in ("format", "version"):
            with np.load(side) as z:
                d = dict(z)
            d.update(format=np.array("something-else")) if case == "format" else d.update(version=np.int32(2))
            with open(side, "wb") as fh:
                np.savez(fh, **d)
            return
        if case == "count":
            a["noise"] = a["noise"][:-1]
            with open(side, "wb") as fh:
                np.savez(fh, format=np.array(bakeinfo.FORMAT), version=np.int32(1),
                         shprobe_sha256=np.array(bakeinfo.sha256_file(str(path))),
                         probe_count=np.int64(f.probe_count - 1), **a)
            return
        if case == "leaves":
            a["leaves"] = a["leaves"].copy()
            a["leaves"][0, 0] += 1
        if case == "pickled":
            a["noise"] = np.array([object()] * f.probe_count, dtype=object)
        if case == "tolerance":
            a["tolerance"] = np.float64(np.nan)
        bakeinfo.write(side, str(path), a)
    msg = _message(baked, change)
    assert words in msg, msg


def test_over_the_size_cap_is_refused_before_reading(baked):
    path, f = baked
    with open(bakeinfo.path_for(str(path)), "r+b") as fh:
        fh.truncate(bakeinfo.MAX_BYTES + 1)     # sparse: no disk space used
    msg = _read(path, f).error
    assert msg.startswith("room.shprobe.bakeinfo: ") and "more than the 256 MiB a sidecar may have" in msg


def test_a_fifo_sidecar_is_refused_without_waiting(baked):
    # A named pipe where the sidecar should be: opened non-blocking and refused (safe_open), so the
    # overlay's timer never waits on a writer that does not come.
    path, f = baked
    side = bakeinfo.path_for(str(path))
    os.remove(side)
    os.mkfifo(side)
    msg = _read(path, f).error
    assert msg.startswith("room.shprobe.bakeinfo: ") and "not a regular file (a FIFO (named pipe))" in msg, msg


def test_no_sidecar_for_a_name_over_255_bytes(tmp_path):
    logs = []
    long_path = str(tmp_path / ("p" * (255 - len(".shprobe")) + ".shprobe"))   # a legal 255-byte name
    out = Output(long_path, "shprobe", lambda tmp: None)
    got = bakeinfo.with_sidecar(out, {}, Output, log=logs.append)
    assert got == [out] and "no bake-info sidecar" in logs[0]
    short = Output(str(tmp_path / "a.shprobe"), "shprobe", lambda tmp: None)
    pair = bakeinfo.with_sidecar(short, {}, Output, log=logs.append)
    assert [o.path for o in pair] == [short.path, short.path + ".bakeinfo"] and [o.kind for o in pair] == \
        ["shprobe", "bakeinfo"]
