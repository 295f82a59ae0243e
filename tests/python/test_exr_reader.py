"""The add-on's own EXR reader (addon/schnee_probes/exr.py), which replaces OpenImageIO inside
Blender for the bake's panoramas: every codec it claims against OpenImageIO's reading of the same
file (oiiotool --dumpdata, independent code), refusals for what it does not handle, and malformed
input. Runtime: ~3 s."""
import os
import shutil
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from conftest import REPO
from schnee_probes import exr, native

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "engine" / "scripts"))
import viewer  # noqa: E402  (read_image_oiio: the oiiotool-based reference reader)

STUDIO = "/usr/share/blender/datafiles/studiolights/world/interior.exr"


FLOAT_CODECS = ["none", "rle", "zips", "zip", "piz", "dwab", "b44"]  # the last three exr.py refuses
HALF_CODECS = ["none", "rle", "zips", "zip"]


@pytest.fixture(scope="module")
def written(tmp_path_factory):
    """{(codec, dtype): path} of a 40x20 cut of interior.exr written by OpenImageIO with each codec,
    float RGB and half RGBA (alpha 0.25): one oiiotool run writes all eleven files (an oiiotool start
    takes 1-3 s here, one per file before). Tests that change a file change a copy."""
    tmp = tmp_path_factory.mktemp("exr")
    cmd = ["oiiotool", STUDIO, "--cut", "40x20+500+250", "-d", "float"]
    paths = {}
    for codec in FLOAT_CODECS:
        paths[codec, "float"] = tmp / f"{codec}-float-0.exr"
        cmd += ["--compression", codec, "-o", str(paths[codec, "float"])]
    cmd += ["--ch", "R,G,B,A=0.25", "-d", "half"]
    for codec in HALF_CODECS:
        paths[codec, "half"] = tmp / f"{codec}-half-1.exr"
        cmd += ["--compression", codec, "-o", str(paths[codec, "half"])]
    subprocess.run(cmd, check=True)
    # Each file carries its own codec (the header's compression attribute; OpenEXR's enum numbers).
    code = {"none": 0, "rle": 1, "zips": 2, "zip": 3, "piz": 4, "b44": 6, "dwab": 9}
    for (codec, _), path in paths.items():
        head = path.read_bytes()[:4096]
        at = head.index(b"compression\0compression\0") + 24
        assert head[at:at + 5] == bytes([1, 0, 0, 0, code[codec]]), (path, head[at:at + 5])
    return paths


def _copy(written, tmp_path, codec, dtype="float"):
    out = tmp_path / written[codec, dtype].name
    shutil.copyfile(written[codec, dtype], out)
    return out


@pytest.mark.parametrize("codec", HALF_CODECS)
@pytest.mark.parametrize("dtype", ["float", "half"])
def test_codecs_match_openimageio(written, codec, dtype):
    path = written[codec, dtype]
    ours = exr.read(str(path))
    ref = viewer.read_image_oiio(path)  # 9 printed decimals
    assert ours.dtype == np.float32 and ours.shape == ref.shape == (20, 40, 4 if dtype == "half" else 3)
    np.testing.assert_allclose(ours, ref, rtol=1e-7, atol=1e-9)
    assert np.ptp(ours[..., 0]) > 0.01  # a real image, not a constant


def test_project_file_equals_projection_of_pixels(written):
    path = written["zip", "float"]
    pixels = viewer.read_image_oiio(path).astype(np.float32)
    np.testing.assert_array_equal(native.project_file(str(path), 1, negative="allow"),
                                  native.project_equirect(pixels, 1, negative="allow"))


@pytest.mark.parametrize("codec", ["piz", "dwab", "b44"])
def test_other_codecs_are_unsupported_not_misread(written, codec):
    path = written[codec, "float"]
    with pytest.raises(exr.Unsupported):
        exr.read(str(path))
    # Outside Blender, native.project_file falls back to oiiotool (development machines, benchmarks):
    # the same projection as OpenImageIO's pixels.
    pixels = viewer.read_image_oiio(path).astype(np.float32)
    np.testing.assert_allclose(native.project_file(str(path), 1, negative="allow"),
                               native.project_equirect(pixels, 1, negative="allow"), rtol=0, atol=1e-6)


def test_other_codecs_without_oiiotool_are_an_io_error(written):
    # Without oiiotool: a clear I/O error, not garbage (one interpreter tries the three files).
    paths = [str(written[codec, "float"]) for codec in ("piz", "dwab", "b44")]
    code = ("import schnee_probes.native as n\n"
            "for p in %r:\n"
            "    try:\n        n.project_file(p, 1)\n        print('read |', p)\n"
            "    except n.SchneeError as e:\n        print(e.code, '|', e)\n" % paths)
    env = dict(os.environ, PATH="/nonexistent", PYTHONPATH=str(REPO / "addon"))
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, env=env, check=True).stdout
    lines = out.splitlines()
    assert len(lines) == 3, out
    for line, path in zip(lines, paths):
        assert line.startswith("I/O error |") and path in line and "outside Blender" in line and "oiiotool" in line, out


def test_malformed_files(tmp_path, written):
    data = written["zip", "float"].read_bytes()
    bad = tmp_path / "bad.exr"
    for cut in (8, 60, len(data) // 2, len(data) - 3):
        bad.write_bytes(data[:cut])
        with pytest.raises(exr.Malformed):
            exr.read(str(bad))
        with pytest.raises(native.SchneeError) as err:
            native.project_file(str(bad), 1)
        assert err.value.code == "malformed file"
    # A corrupted zlib stream (flip bytes in the last block's payload).
    broken = bytearray(data)
    for i in range(len(data) - 40, len(data) - 20):
        broken[i] ^= 0x5A
    bad.write_bytes(bytes(broken))
    with pytest.raises(exr.Malformed):
        exr.read(str(bad))
    bad.write_bytes(b"P6\n1 1\n255\n\0\0\0")
    assert not exr.has_magic(bad.read_bytes()[:4])


def test_reads_no_more_than_the_header_allows(tmp_path, written):
    # A real 40x20 EXR padded to 2 GiB (sparse): its header allows at most a few kB, so the reader
    # refuses it after reading the header, without reading or allocating the rest (issue 14).
    import resource
    import time
    path = _copy(written, tmp_path, "none")
    size = path.stat().st_size
    with open(path, "r+b") as f:
        f.truncate(2 << 30)
    rss0, t0 = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss, time.perf_counter()
    with pytest.raises(exr.Malformed, match=r"the file has 2147483648 bytes, more than its header allows"):
        exr.read(str(path))
    assert time.perf_counter() - t0 < 2.0
    assert resource.getrusage(resource.RUSAGE_SELF).ru_maxrss - rss0 < 64 * 1024  # KiB: nothing near 2 GiB
    assert size < 40 * 20 * 3 * 4 + 4096  # the uncompressed original is what its header says


def test_special_files_are_refused_without_blocking(tmp_path):
    fifo = tmp_path / "pano.exr"
    os.mkfifo(fifo)
    with pytest.raises(OSError, match=r"not a regular file \(a FIFO \(named pipe\)\)"):
        exr.read(str(fifo))   # the old reader blocked here forever
    with pytest.raises(native.SchneeError) as err:
        native.project_file("/dev/zero", 1)
    assert err.value.code == "I/O error" and "not a regular file (a character device)" in str(err.value)
