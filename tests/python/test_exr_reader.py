"""The add-on's own EXR reader (addon/schnee_probes/exr.py), which replaces OpenImageIO inside
Blender for the bake's panoramas: every codec it claims against OpenImageIO's reading of the same
file (oiiotool --dumpdata, independent code), refusals for what it does not handle, and malformed
input. Runtime: ~3 s."""
import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from conftest import REPO
from schnee_probes import exr, native

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "engine" / "scripts"))
import viewer  # noqa: E402  (oiiotool-based reference reader)

STUDIO = "/usr/share/blender/datafiles/studiolights/world/interior.exr"


def _write(tmp_path, codec, dtype="float", alpha=False, name=None):
    out = tmp_path / (name or f"{codec}-{dtype}-{int(alpha)}.exr")
    cmd = ["oiiotool", STUDIO, "--cut", "40x20+500+250"]
    if alpha:
        cmd += ["--ch", "R,G,B,A=0.25"]
    cmd += ["-d", dtype, "--compression", codec, "-o", str(out)]
    subprocess.run(cmd, check=True)
    return out


@pytest.mark.parametrize("codec", ["none", "rle", "zips", "zip"])
@pytest.mark.parametrize("dtype", ["float", "half"])
def test_codecs_match_openimageio(tmp_path, codec, dtype):
    path = _write(tmp_path, codec, dtype, alpha=(dtype == "half"))
    ours = exr.read(str(path))
    ref = viewer.read_image(path)  # 9 printed decimals
    assert ours.dtype == np.float32 and ours.shape == ref.shape == (20, 40, 4 if dtype == "half" else 3)
    np.testing.assert_allclose(ours, ref, rtol=1e-7, atol=1e-9)
    assert np.ptp(ours[..., 0]) > 0.01  # a real image, not a constant


def test_project_file_equals_projection_of_pixels(tmp_path):
    path = _write(tmp_path, "zip")
    pixels = viewer.read_image(path).astype(np.float32)
    np.testing.assert_array_equal(native.project_file(str(path), 1, negative="allow"),
                                  native.project_equirect(pixels, 1, negative="allow"))


@pytest.mark.parametrize("codec", ["piz", "dwab", "b44"])
def test_other_codecs_are_unsupported_not_misread(tmp_path, codec):
    path = _write(tmp_path, codec)
    with pytest.raises(exr.Unsupported):
        exr.read(str(path))
    # Outside Blender, native.project_file falls back to oiiotool (development machines, benchmarks):
    # the same projection as OpenImageIO's pixels.
    pixels = viewer.read_image(path).astype(np.float32)
    np.testing.assert_allclose(native.project_file(str(path), 1, negative="allow"),
                               native.project_equirect(pixels, 1, negative="allow"), rtol=0, atol=1e-6)
    # Without oiiotool: a clear I/O error, not garbage.
    code = ("import schnee_probes.native as n\n"
            "try:\n    n.project_file(%r, 1)\nexcept n.SchneeError as e:\n    print(e.code, '|', e)\n" % str(path))
    env = dict(os.environ, PATH="/nonexistent", PYTHONPATH=str(REPO / "addon"))
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, env=env, check=True).stdout
    assert out.startswith("I/O error |") and "outside Blender" in out and "oiiotool" in out, out


def test_malformed_files(tmp_path):
    data = _write(tmp_path, "zip").read_bytes()
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


def test_reads_no_more_than_the_header_allows(tmp_path):
    # A real 40x20 EXR padded to 2 GiB (sparse): its header allows at most a few kB, so the reader
    # refuses it after reading the header, without reading or allocating the rest (issue 14).
    import resource
    import time
    path = _write(tmp_path, "none")
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
