""".shprobe through the Python API: bytes against DESIGN.md §4's table (built here with struct,
independently of the C writer), round trips v1/v2 for L = 0..4, errors with message + code,
argument validation and the C grid lookup."""
import struct

import numpy as np
import pytest

from schnee_probes import native


def _sample(n, band, seed=0):
    rng = np.random.default_rng(seed)
    coeffs = rng.normal(size=(n, native.sh_count(band), 3)).astype(np.float32)
    grid = np.array([i % n if i % 3 else -1 for i in range(12)], dtype=np.int32)  # dims 3 x 2 x 2
    return coeffs, grid


def _v1_bytes(coeffs9, scale, ambient, grid, dims, origin, spacing, dscale, dambient):
    """DESIGN.md §4 table: 48-byte header, 160 bytes per probe, int32 grid; little-endian."""
    out = struct.pack("<IIIIII", 0x52485053, 1, len(coeffs9), *dims)
    out += struct.pack("<ffffff", *origin, spacing, dscale, dambient)
    for c, s, a in zip(coeffs9, scale, ambient):
        for rgb in c:
            out += struct.pack("<ffff", *rgb, 0.0)
        out += struct.pack("<ff", s, a) + bytes(8)
    return out + struct.pack(f"<{len(grid)}i", *grid)


def test_v1_bytes_match_design_table(tmp_path):
    coeffs, grid = _sample(2, 2)
    scale = np.array([1.0, 0.5], np.float32)
    ambient = np.array([0.25, 0.125], np.float32)
    path = tmp_path / "a.shprobe"
    v = native.write_shprobe(str(path), coeffs, grid, (3, 2, 2), (-1.0, 0.5, 2.0), 0.5,
                             default_sh_scale=1.25, probe_scale=scale, probe_ambient=ambient)
    assert v == 1
    want = _v1_bytes(coeffs, scale, ambient, grid, (3, 2, 2), (-1.0, 0.5, 2.0), 0.5, 1.25, 0.1)
    got = path.read_bytes()
    assert got[:4] == b"SPHR"  # 0x52485053 little-endian
    assert len(got) == 48 + 2 * 160 + 12 * 4 == len(want)
    assert got == want


def test_python_built_v1_reads_back(tmp_path):
    """A file built only from the table (no C writer) reads back exactly through the C reader."""
    coeffs, grid = _sample(3, 2, seed=1)
    data = _v1_bytes(coeffs, [1, 2, 3], [0.1, 0.2, 0.3], grid, (3, 2, 2), (0, 0, 0), 0.25, 1.0, 0.1)
    (tmp_path / "b.shprobe").write_bytes(data)
    for f in (native.read_shprobe(str(tmp_path / "b.shprobe")), native.read_shprobe_bytes(data)):
        assert f.version == 1 and f.max_band == 2 and f.probe_count == 3 and f.positions is None
        np.testing.assert_array_equal(f.coeffs, coeffs)
        np.testing.assert_array_equal(f.probe_scale, [1, 2, 3])
        np.testing.assert_array_equal(f.probe_ambient, np.float32([0.1, 0.2, 0.3]))
        np.testing.assert_array_equal(f.grid, grid)
        np.testing.assert_array_equal(f.validity, [1, 1, 1])
        assert f.grid_dims == (3, 2, 2) and f.grid_spacing == 0.25
        assert f.grid_axes == ((1, 0, 0), (0, 1, 0), (0, 0, 1))


@pytest.mark.parametrize("band", [0, 1, 2, 3, 4])
@pytest.mark.parametrize("extras", ["none", "positions", "v2"])
def test_round_trip(tmp_path, band, extras):
    coeffs, grid = _sample(4, band, seed=band)
    kw = {}
    if extras == "positions":
        kw["positions"] = np.arange(12, dtype=np.float32).reshape(4, 3) - 5.5
    if extras == "v2":
        kw.update(version=2, validity=np.float32([1, 0.5, 0, 0.25]),
                  grid_axes=np.array([[0, 0, 1], [1, 0, 0], [0, 1, 0]], np.float32))
    path = tmp_path / "rt.shprobe"
    v = native.write_shprobe(path, coeffs, grid.reshape(2, 2, 3), (3, 2, 2), (1, 2, 3), 0.5, **kw)
    want_v = 1 if band <= 2 and extras == "none" else 2
    assert v == want_v
    f = native.read_shprobe(path)
    assert f.version == want_v
    if want_v == 1:  # v1 always holds 9 coefficients: lower bands are zero-padded
        assert f.max_band == 2
        np.testing.assert_array_equal(f.coeffs[:, :coeffs.shape[1]], coeffs)
        np.testing.assert_array_equal(f.coeffs[:, coeffs.shape[1]:], 0)
    else:
        assert f.max_band == band
        np.testing.assert_array_equal(f.coeffs, coeffs)
    np.testing.assert_array_equal(f.grid, grid)
    if extras == "positions":
        np.testing.assert_array_equal(f.positions, kw["positions"])
    else:
        assert f.positions is None
    if extras == "v2":
        np.testing.assert_array_equal(f.validity, kw["validity"])
        assert f.grid_axes == ((0, 0, 1), (1, 0, 0), (0, 1, 0))
    h = native.read_shprobe_header(path)
    assert (h["version"], h["probe_count"], h["max_band"]) == (want_v, 4, f.max_band)
    assert h["grid_dims"] == (3, 2, 2) and h["grid_origin"] == (1, 2, 3) and h["grid_spacing"] == 0.5


def test_errors_carry_message_and_code(tmp_path):
    coeffs, grid = _sample(2, 2)
    good = tmp_path / "g.shprobe"
    native.write_shprobe(good, coeffs, grid, (3, 2, 2), (0, 0, 0), 0.5)
    data = bytearray(good.read_bytes())
    cases = [
        (b"XXXX" + data[4:], "malformed file", "bad magic"),
        (data[:4] + struct.pack("<I", 9) + data[8:], "malformed file", "unknown version 9 at offset 4"),
        (data[:-1], "malformed file", "truncated"),
        (data + b"\0", "malformed file", "trailing data"),
        (data[:36] + struct.pack("<f", 0.0) + data[40:], "malformed file", "grid spacing is 0 (offset 36)"),
        (data[:48] + struct.pack("<f", float("nan")) + data[52:], "non-finite value",
         "probe 0 coefficient 0 red is nan (offset 48)"),
        (data[:368] + struct.pack("<i", 2) + data[372:], "malformed file", "grid cell (0, 0, 0) holds 2"),
    ]
    for blob, code, needle in cases:
        with pytest.raises(native.SchneeError) as exc:
            native.read_shprobe_bytes(bytes(blob))
        assert exc.value.code == code
        assert needle in str(exc.value)
        bad = tmp_path / "bad.shprobe"
        bad.write_bytes(bytes(blob))
        with pytest.raises(native.SchneeError) as exc:
            native.read_shprobe(bad)
        assert exc.value.code == code and str(bad) in str(exc.value) and needle in str(exc.value)
    with pytest.raises(native.SchneeError) as exc:
        native.read_shprobe_header(tmp_path / "missing.shprobe")
    assert exc.value.code == "I/O error" and "cannot open" in str(exc.value)
    # The writer refuses what the reader would refuse, and what v1 cannot hold.
    with pytest.raises(native.SchneeError) as exc:
        native.write_shprobe(tmp_path / "w.shprobe", coeffs, grid, (3, 2, 2), (0, 0, 0), -1.0)
    assert exc.value.code == "invalid argument" and "grid spacing is -1" in str(exc.value)
    c16 = np.zeros((2, 16, 3), np.float32)
    with pytest.raises(native.SchneeError) as exc:
        native.write_shprobe(tmp_path / "w.shprobe", c16, grid, (3, 2, 2), (0, 0, 0), 1.0, version=1)
    assert "version 1 cannot hold max band > 2" in str(exc.value)
    assert not (tmp_path / "w.shprobe").exists()
    # A failed write leaves the previous file untouched (atomic temp + rename).
    before = good.read_bytes()
    bad_coeffs = coeffs.copy()
    bad_coeffs[1, 3, 2] = np.inf
    with pytest.raises(native.SchneeError) as exc:
        native.write_shprobe(good, bad_coeffs, grid, (3, 2, 2), (0, 0, 0), 0.5)
    assert exc.value.code == "non-finite value" and "probe 1 coefficient 3 blue is inf" in str(exc.value)
    with pytest.raises(native.SchneeError) as exc:
        native.write_shprobe(tmp_path / "nodir" / "x.shprobe", coeffs, grid, (3, 2, 2), (0, 0, 0), 0.5)
    assert exc.value.code == "I/O error"
    assert good.read_bytes() == before
    assert not [p for p in tmp_path.iterdir() if ".tmp." in p.name]


def test_argument_validation(tmp_path):
    coeffs, grid = _sample(2, 2)
    p = tmp_path / "v.shprobe"
    with pytest.raises(ValueError, match=r"coeffs must have shape \(P, sh_count, 3\), got \(2, 27\)"):
        native.write_shprobe(p, coeffs.reshape(2, 27), grid, (3, 2, 2), (0, 0, 0), 1)
    with pytest.raises(ValueError, match="coeffs has 10 coefficients"):
        native.write_shprobe(p, np.zeros((2, 10, 3)), grid, (3, 2, 2), (0, 0, 0), 1)
    with pytest.raises(TypeError, match="grid must be a numeric array convertible to int32, got dtype float64"):
        native.write_shprobe(p, coeffs, grid.astype(np.float64), (3, 2, 2), (0, 0, 0), 1)
    with pytest.raises(ValueError, match=r"grid must have shape \(12,\) or \(Z, Y, X\) = \(2, 2, 3\)"):
        native.write_shprobe(p, coeffs, grid.reshape(3, 2, 2), (3, 2, 2), (0, 0, 0), 1)
    with pytest.raises(ValueError, match="grid values must fit int32"):
        native.write_shprobe(p, coeffs, grid.astype(np.int64) + 2**31, (3, 2, 2), (0, 0, 0), 1)
    with pytest.raises(ValueError, match=r"positions must have shape \(2, 3\)"):
        native.write_shprobe(p, coeffs, grid, (3, 2, 2), (0, 0, 0), 1, positions=np.zeros((3, 3)))
    with pytest.raises(ValueError, match=r"probe_scale must have shape \(2,\)"):
        native.write_shprobe(p, coeffs, grid, (3, 2, 2), (0, 0, 0), 1, probe_scale=[1.0])
    with pytest.raises(TypeError, match="coeffs must be a numeric array"):
        native.write_shprobe(p, np.zeros((2, 9, 3), dtype=complex), grid, (3, 2, 2), (0, 0, 0), 1)
    # The C module checks buffers on its own (format and length), for callers that bypass native.py.
    raw = native._lib()
    with pytest.raises(TypeError, match="grid must hold int32 items, got buffer format"):
        raw.shprobe_write(str(p), coeffs, 2, grid.astype(np.float32), (3, 2, 2), (0, 0, 0), 1.0)
    with pytest.raises(ValueError, match="grid has 11 items, expected 12"):
        raw.shprobe_write(str(p), coeffs, 2, grid[:11], (3, 2, 2), (0, 0, 0), 1.0)
    with pytest.raises(TypeError, match="C-contiguous"):
        raw.shprobe_write(str(p), coeffs[:, ::2], 2, grid, (3, 2, 2), (0, 0, 0), 1.0)
    with pytest.raises(ValueError, match="grid_dims entry 4294967296 is out of range"):
        raw.shprobe_write(str(p), coeffs, 2, grid, (2**32, 1, 1), (0, 0, 0), 1.0)
    with pytest.raises(ValueError, match="grid_dims 2147483648 x 2147483648 x 2147483648 is too large"):
        raw.shprobe_write(str(p), coeffs, 2, grid, (2**31,) * 3, (0, 0, 0), 1.0)
    assert not p.exists()


def test_lookup_boundaries(tmp_path):
    coeffs, _ = _sample(2, 2)
    grid = np.arange(12, dtype=np.int32) % 2
    grid[7] = -1
    path = tmp_path / "l.shprobe"
    native.write_shprobe(path, coeffs, grid, (3, 2, 2), (-1.0, 0.5, 2.0), 0.5)
    f = native.read_shprobe(path)
    # Cell (x, y, z) spans [-1 + 0.5x, ...) etc.; min faces belong to the cell, max faces of the grid do not.
    pts = [(-1.0, 0.5, 2.0), (-0.5, 0.5, 2.0), (0.4999, 1.4999, 2.9999), (0.5, 1.0, 2.5),
           (-1.0001, 0.7, 2.2), (-0.25, 0.75, 2.75), (np.nan, 1.0, 2.2)]
    want = [0, 1, 1, -1, -1, -1, -1]   # flat indices 0, 1, 11, outside, outside, 7 (empty), NaN
    np.testing.assert_array_equal(f.lookup(pts), want)
    assert int(f.lookup((0.25, 0.75, 2.75))) == 0    # cell (2, 0, 1) = flat 8 -> 8 % 2
