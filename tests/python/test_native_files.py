"""Issue 14 through the Python module: write_shprobe never replaces what is not a .shprobe; the
readers (read_shprobe, read_shprobe_header, project_file) refuse special files at once without
reading or allocating much; messages never echo a foreign file's bytes; bad placement parameters
and non-finite data are named. Special files are made here in tmp_path (a device node only as root,
never a real /dev entry as a write target)."""
import json
import os
import socket
import stat
import subprocess
import sys
import textwrap

import numpy as np
import pytest

from conftest import ADDON_DIR
from schnee_probes import native
from test_native_placement import cube


def write_probe(path, value=0.5):
    return native.write_shprobe(str(path), np.full((1, 9, 3), value, np.float32), np.zeros(1, np.int32),
                                (1, 1, 1), (0, 0, 0), 1.0)


# ---- the writer -------------------------------------------------------------------------------

def test_write_new_and_over_own_file(tmp_path):
    p = tmp_path / "probes.shprobe"
    assert write_probe(p, 0.5) == 1
    assert write_probe(p, 2.5) == 1       # an existing .shprobe is replaced (atomically)
    np.testing.assert_array_equal(native.read_shprobe(str(p)).coeffs, np.full((1, 9, 3), 2.5, np.float32))


def test_write_refuses_foreign_regular_files(tmp_path):
    # The open .blend of the issue, an empty file, and a file with 3 bytes of the magic.
    for name, content in (("scene.blend", b"BLENDER-v304" + bytes(708)), ("empty.shprobe", b""),
                          ("short.shprobe", b"SPH")):
        p = tmp_path / name
        p.write_bytes(content)
        with pytest.raises(native.SchneeError) as exc:
            write_probe(p)
        assert exc.value.code == "invalid argument"
        assert str(exc.value) == (f"refusing to replace {p}: it exists and is not a .shprobe file (it does not "
                                  "start with the .shprobe magic); remove it or choose another output path")
        assert p.read_bytes() == content
    assert sorted(os.listdir(tmp_path)) == ["empty.shprobe", "scene.blend", "short.shprobe"]  # no temp left


def test_write_refuses_special_files(tmp_path):
    fifo = tmp_path / "fifo.shprobe"
    os.mkfifo(fifo)
    folder = tmp_path / "folder.shprobe"
    folder.mkdir()
    sock_path = tmp_path / "sock.shprobe"
    sock = socket.socket(socket.AF_UNIX)
    sock.bind(str(sock_path))
    cases = [(fifo, "FIFO (named pipe)", stat.S_ISFIFO), (folder, "directory", stat.S_ISDIR),
             (sock_path, "socket", stat.S_ISSOCK)]
    if os.geteuid() == 0:  # a character device like /dev/null (1, 3), made here, not the real one
        dev = tmp_path / "null"
        os.mknod(dev, 0o666 | stat.S_IFCHR, os.makedev(1, 3))
        cases.append((dev, "character device", stat.S_ISCHR))
    try:
        for path, kind, is_kind in cases:
            with pytest.raises(native.SchneeError) as exc:
                write_probe(path)
            assert exc.value.code == "invalid argument"
            assert f"refusing to write {path}: it exists and is a {kind}, not a .shprobe file" in str(exc.value)
            assert is_kind(os.lstat(path).st_mode)
    finally:
        sock.close()
    # A symbolic link, even to our own file: refused, the link and its target unchanged.
    own = tmp_path / "own.shprobe"
    write_probe(own, 1.0)
    link = tmp_path / "link.shprobe"
    link.symlink_to(own)
    with pytest.raises(native.SchneeError) as exc:
        write_probe(link, 3.0)
    assert exc.value.code == "invalid argument" and f"{link}: it is a symbolic link" in str(exc.value)
    assert link.is_symlink() and native.read_shprobe(str(own)).coeffs[0, 0, 0] == 1.0
    assert not [n for n in os.listdir(tmp_path) if ".tmp." in n]


# ---- the readers ------------------------------------------------------------------------------

# Run in a child so that a reader that blocks (the old code did, on a FIFO and /dev/zero) fails the
# test by timeout instead of hanging it; each call's time and peak-RSS growth are measured there.
READ_SCRIPT = textwrap.dedent("""
    import json, resource, sys, time
    sys.path.insert(0, sys.argv[1])
    from schnee_probes import native
    out = []
    for path in sys.argv[2:]:
        for name in ("read_shprobe", "read_shprobe_header", "project_file"):
            rss0 = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss
            t0 = time.perf_counter()
            try:
                getattr(native, name)(path)
                res = ("ok", "")
            except native.SchneeError as exc:
                res = (exc.code, str(exc))
            out.append(dict(path=path, fn=name, code=res[0], msg=res[1], s=time.perf_counter() - t0,
                            rss_kib=resource.getrusage(resource.RUSAGE_SELF).ru_maxrss - rss0))
    print(json.dumps(out))
""")


def run_readers(paths):
    proc = subprocess.run([sys.executable, "-c", READ_SCRIPT, str(ADDON_DIR)] + [str(p) for p in paths],
                          capture_output=True, text=True, timeout=60)
    assert proc.returncode == 0, proc.stderr
    return json.loads(proc.stdout)


def test_readers_refuse_special_files_quickly(tmp_path):
    fifo = tmp_path / "fifo.shprobe"
    os.mkfifo(fifo)
    folder = tmp_path / "folder.exr"
    folder.mkdir()
    loop_a, loop_b = tmp_path / "loop_a.shprobe", tmp_path / "loop_b.shprobe"
    loop_a.symlink_to(loop_b)
    loop_b.symlink_to(loop_a)
    sparse = tmp_path / "sparse.exr"
    with open(sparse, "wb") as f:
        f.truncate(2 << 30)  # 2 GiB of zeros, sparse
    expected = {str(fifo): ("I/O error", "not a regular file (a FIFO (named pipe))"),
                "/dev/zero": ("I/O error", "not a regular file (a character device)"),
                str(folder): ("I/O error", "not a regular file (a directory)"),
                str(loop_a): ("I/O error", "(a symbolic link loop, or too many links in the path)"),
                str(sparse): ("malformed file", "")}
    results = run_readers(expected)
    assert len(results) == 15
    for r in results:
        code, needle = expected[r["path"]]
        assert r["code"] == code and r["msg"].startswith(r["path"] + ": ") and needle in r["msg"], r
        assert r["s"] < 2.0 and r["rss_kib"] < 64 * 1024, r   # nothing read or allocated past the header
    by_fn = {r["fn"]: r["msg"] for r in results if r["path"] == str(sparse)}
    assert "not a .shprobe file (bad magic" in by_fn["read_shprobe"]
    assert "not a .shprobe file (bad magic" in by_fn["read_shprobe_header"]
    assert "cannot read as exr" in by_fn["project_file"]


def test_sparse_shprobe_with_header_above_the_limits(tmp_path):
    # A valid v1 header claiming 2^25 probes, then 2 GiB of (sparse) zeros: refused after the header.
    p = tmp_path / "big.shprobe"
    header = b"SPHR" + (1).to_bytes(4, "little") + (1 << 25).to_bytes(4, "little")
    header += b"".join(v.to_bytes(4, "little") for v in (1, 1, 1)) + bytes(12)
    header += np.array([1.0, 1.0, 0.1], "<f4").tobytes()
    assert len(header) == 48
    with open(p, "wb") as f:
        f.write(header)
        f.truncate(2 << 30)
    results = run_readers([p])
    for r in results[:2]:
        assert r["code"] == "input too large", r
        assert r["msg"] == f"{p}: probe count 33554432 (offset 8) is above the limit of 16777216 probes"
        assert r["s"] < 2.0 and r["rss_kib"] < 64 * 1024, r


def test_foreign_file_bytes_are_not_echoed(tmp_path):
    p = tmp_path / "passwd"
    p.write_bytes(b"root:x:0:0:root:/root:/bin/bash\n")
    for fn in (native.read_shprobe, native.read_shprobe_header):
        with pytest.raises(native.SchneeError) as exc:
            fn(str(p))
        assert exc.value.code == "malformed file"
        assert str(exc.value) == f'{p}: not a .shprobe file (bad magic: it does not start with "SPHR" = 0x52485053)'
    with pytest.raises(native.SchneeError) as exc:
        native.project_file(str(p))
    assert "root" not in str(exc.value).replace(str(tmp_path), "") and "746F6F72" not in str(exc.value).upper()


# ---- non-finite data and image limits through project_file ------------------------------------

def write_pfm(path, pixels):
    """Portable float map (what OpenImageIO reads as 'pnm'): rows stored bottom first."""
    h, w, _ = pixels.shape
    with open(path, "wb") as f:
        f.write(f"PF\n{w} {h}\n-1.0\n".encode())
        f.write(np.ascontiguousarray(pixels[::-1], "<f4").tobytes())


def test_project_file_names_the_non_finite_pixel(tmp_path):
    pix = np.ones((16, 32, 3), np.float32)
    p = tmp_path / "pano.pfm"
    write_pfm(p, pix)
    np.testing.assert_allclose(native.project_file(str(p))[0], 2 * np.sqrt(np.pi), rtol=1e-6)  # L00 of 1
    neg_nan = np.array([0x7FC00000 | 0x80000000], np.uint32).view(np.float32)[0]  # sign bit set
    for value, text in ((np.nan, "nan"), (neg_nan, "nan"), (np.inf, "inf"), (-np.inf, "-inf")):
        bad = pix.copy()
        bad[5, 7, 1] = value
        write_pfm(p, bad)
        with pytest.raises(native.SchneeError) as exc:
            native.project_file(str(p), negative="allow")
        assert exc.value.code == "non-finite value"
        assert str(exc.value) == (f"{p}: SH projection: non-finite radiance {text} at pixel (x=7, y=5), "
                                  "channel 1 (G)")


def test_pfm_read_in_numpy_as_oiiotool_reads_it(tmp_path):
    """Outside Blender images.py reads a plain PFM itself; the reference is OpenImageIO, which read
    every PFM before (oiiotool converts both files in one run, as images.py invoked it: float,
    uncompressed EXR, read back by exr.py). Both byte orders; bits compared, with NaN payloads, -0, denormals, ±inf."""
    import shutil
    from schnee_probes import exr, images
    oiiotool = shutil.which("oiiotool")
    assert oiiotool, "OpenImageIO's oiiotool is the reference here"
    rng = np.random.default_rng(7)
    rgb = rng.standard_normal((5, 7, 3)).astype(np.float32) * 1e3
    rgb[0, 0] = (np.inf, -np.inf, -0.0)
    rgb[1, 2] = (np.float32(1e-42), np.nan, np.array([0xFFC01234], np.uint32).view(np.float32)[0])
    files = {"le.pfm": (b"PF\n7 5\n-1.0\n", rgb, "<f4"), "be.pfm": (b"PF 7 5 1\n", rgb, ">f4")}
    cmd = [oiiotool]
    for name, (header, pix, order) in files.items():
        (tmp_path / name).write_bytes(header + np.ascontiguousarray(pix[::-1], order).tobytes())
        cmd += [str(tmp_path / name), "-d", "float", "--compression", "none", "-o", str(tmp_path / (name + ".exr"))]
    subprocess.run(cmd, check=True, capture_output=True)
    for name, (header, pix, order) in files.items():
        ours = images.read_image(str(tmp_path / name))
        ref = exr.read(str(tmp_path / (name + ".exr")))
        assert ours.dtype == np.float32 and ours.shape == ref.shape == pix.shape, name
        np.testing.assert_array_equal(ours.view(np.uint32), ref.view(np.uint32), err_msg=name)
        np.testing.assert_array_equal(ours.view(np.uint32), pix.view(np.uint32), err_msg=name)


def test_project_file_image_limits(tmp_path):
    p = tmp_path / "huge.pfm"
    p.write_bytes(b"PF\n65536 8193\n-1.0\n")  # 6 GiB of floats claimed by a 19-byte file
    with pytest.raises(native.SchneeError) as exc:
        native.project_file(str(p))
    assert exc.value.code == "input too large"
    assert "65536x8193 with 3 channel(s); the limits are 65536 pixels per side, 64 channels and " \
           "536870912 values" in str(exc.value)


# ---- placement parameters ---------------------------------------------------------------------

@pytest.mark.parametrize("kw, text", [
    (dict(min_cell_size=0), "min_cell_size must be a positive finite length in metres, got 0"),
    (dict(min_cell_size=-0.5), "min_cell_size must be a positive finite length in metres, got -0.5"),
    (dict(min_cell_size=float("nan")), "min_cell_size must be a positive finite length in metres, got nan"),
    (dict(min_cell_size=float("inf")), "min_cell_size must be a positive finite length in metres, got inf"),
    (dict(max_cell_size=0), "max_cell_size must be a positive finite length in metres, got 0"),
    (dict(max_cell_size=float("-inf")), "max_cell_size must be a positive finite length in metres, got -inf"),
    (dict(max_grid_cells=-1), "max_grid_cells must be 0 (the default limit) or a positive cell count, got -1"),
])
def test_placement_parameters_refused(kw, text):
    v, t = cube()
    with pytest.raises(ValueError) as exc:
        native.place_probes([("cube", v, t)], [], **kw)
    assert text in str(exc.value)


def test_placement_limits_and_messages():
    v, t = cube()
    with pytest.raises(native.SchneeError) as exc:
        native.place_probes([("cube", v, t)], [], max_grid_cells=(1 << 28) + 1)
    assert exc.value.code == "invalid argument" and "above the hard limit of 268435456 cells" in str(exc.value)
    assert native.place_probes([("cube", v, t)], [], 1.0, 2.0, max_grid_cells=1 << 28).grid_dims == (2, 2, 2)
    with pytest.raises(native.SchneeError) as exc:
        native.place_probes([("cube", v, t)], [], min_cell_size=1e-300)
    msg = str(exc.value)
    assert exc.value.code == "input too large" and len(msg) < 400, msg
    assert "2e+300 x 2e+300 x 2e+300 = more than 1e308 cells" in msg and "at Min Cell Size 1e-300 m" in msg
    for value, shown, what in ((np.inf, "inf", "infinite"), (-np.nan, "nan", "NaN")):
        bad = v.copy()
        bad[3, 1] = value
        with pytest.raises(native.SchneeError) as exc:
            native.place_probes([("cube", bad, t)], [])
        assert exc.value.code == "non-finite value"
        x, _, z = (f"{c:g}" for c in v[3])
        assert str(exc.value) == (f"probe volume 'cube' (#0): vertex 3 = ({x}, {shown}, {z}) has a non-finite "
                                  f"y coordinate ({what})")
