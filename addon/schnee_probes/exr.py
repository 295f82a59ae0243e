"""A small OpenEXR reader for the panoramas the bake writes, so the native module needs no image
library inside Blender.

Reads single-part scanline EXR files with HALF, FLOAT or UINT channels, uncompressed (NONE), RLE,
ZIPS or ZIP (zlib, from the standard library): Cycles' ``save_render`` output whatever the codec
setting of those. Anything else (tiled, multi-part, deep, PIZ/DWA/..., subsampled channels) raises
:class:`Unsupported`; images.read_image (the add-on's one image reader, which uses this module)
then reads the file through Blender or oiiotool.

Every size is checked against the file before use; a malformed file raises :class:`Malformed`.
"""
from __future__ import annotations

import struct
import zlib

import numpy as np

MAGIC = 20000630
_NONE, _RLE, _ZIPS, _ZIP = 0, 1, 2, 3
_LINES_PER_BLOCK = {_NONE: 1, _RLE: 1, _ZIPS: 1, _ZIP: 16}
_DTYPES = {0: np.dtype("<u4"), 1: np.dtype("<f2"), 2: np.dtype("<f4")}
_MAX_PIXELS = 1 << 28  # 16384 x 16384: far past any panorama; guards allocations from a bad header
_MAX_HEADER_BYTES = 1 << 20  # a header (attributes) past 1 MiB is refused as malformed


class Unsupported(ValueError):
    """A valid file this reader does not handle (another codec, tiles, parts, ...)."""


class Malformed(ValueError):
    """The file is not a well-formed EXR (truncated, inconsistent sizes, ...)."""


def has_magic(head: bytes) -> bool:
    """True when ``head`` (the first bytes of a file) starts with OpenEXR's magic number."""
    return len(head) >= 4 and struct.unpack_from("<i", head)[0] == MAGIC


def _cstring(data: bytes, pos: int, limit: int = 256):
    end = data.find(b"\0", pos, min(len(data), pos + limit))
    if end < 0:
        raise Malformed("unterminated name in the header")
    return data[pos:end].decode("latin-1"), end + 1


def _header(data: bytes):
    if len(data) < 8 or struct.unpack_from("<i", data, 0)[0] != MAGIC:
        raise Malformed("not an OpenEXR file (bad magic number)")
    version = struct.unpack_from("<I", data, 4)[0]
    if version & 0xFF != 2:
        raise Unsupported(f"OpenEXR version {version & 0xFF}")
    if version & (0x200 | 0x800 | 0x1000):
        raise Unsupported("tiled, deep or multi-part OpenEXR")
    pos, attrs = 8, {}
    while True:
        if pos >= len(data):
            raise Malformed("truncated header")
        if data[pos] == 0:
            pos += 1
            break
        name, pos = _cstring(data, pos)
        kind, pos = _cstring(data, pos)
        if pos + 4 > len(data):
            raise Malformed("truncated header")
        size = struct.unpack_from("<i", data, pos)[0]
        pos += 4
        if size < 0 or pos + size > len(data):
            raise Malformed(f"attribute {name!r} runs past the end of the file")
        attrs[name] = (kind, data[pos:pos + size])
        pos += size
    return attrs, pos


def _channels(raw: bytes):
    out, pos = [], 0
    while pos < len(raw) and raw[pos] != 0:
        name, pos = _cstring(raw, pos)
        if pos + 16 > len(raw):
            raise Malformed("truncated channel list")
        ptype, _linear, xs, ys = struct.unpack_from("<iB3xii", raw, pos)
        pos += 16
        if ptype not in _DTYPES:
            raise Malformed(f"channel {name!r} has unknown pixel type {ptype}")
        if (xs, ys) != (1, 1):
            raise Unsupported(f"subsampled channel {name!r}")
        out.append((name, _DTYPES[ptype]))
    if not out:
        raise Malformed("no channels")
    return out


def _unzip(packed: bytes, size: int) -> bytes:
    try:
        raw = zlib.decompress(packed)
    except zlib.error as exc:
        raise Malformed(f"bad zlib data ({exc})") from None
    return _reorder(raw, size)


def _reorder(raw: bytes, size: int) -> bytes:
    """Undo OpenEXR's byte predictor and its split into even/odd halves (ZIP and RLE codecs)."""
    if len(raw) != size:
        raise Malformed(f"block decompresses to {len(raw)} bytes, expected {size}")
    t = np.frombuffer(raw, np.uint8).astype(np.int64)
    t[1:] -= 128
    t = (np.cumsum(t) & 0xFF).astype(np.uint8)
    out = np.empty(size, np.uint8)
    half = (size + 1) // 2
    out[0::2] = t[:half]
    out[1::2] = t[half:]
    return out.tobytes()


def _unrle(packed: bytes, size: int) -> bytes:
    out, pos = bytearray(), 0
    while pos < len(packed):
        count = struct.unpack_from("<b", packed, pos)[0]
        pos += 1
        if count < 0:
            out += packed[pos:pos - count]
            pos -= count
        else:
            if pos >= len(packed):
                raise Malformed("truncated RLE run")
            out += packed[pos:pos + 1] * (count + 1)
            pos += 1
        if len(out) > size:
            raise Malformed("RLE block larger than its lines")
    return _reorder(bytes(out), size)


def read(path: str, max_bytes: int = 1 << 32) -> np.ndarray:
    """Pixels of the EXR at ``path`` as float32 (H, W, C), row 0 at the top, channels R, G, B and A
    when present (other channels dropped). The file is opened as the native readers open theirs
    (safe_open: no blocking, regular files only, at most ``max_bytes``). Raises OSError (RefusedFile
    for special or oversized files), :class:`Unsupported`, :class:`Malformed`."""
    from .safe_open import open_regular
    f, size = open_regular(path, "an OpenEXR image", max_bytes)
    with f:
        return read_file(f, size)


def read_file(f, size: int) -> np.ndarray:
    """Like :func:`read` for an open binary file of ``size`` bytes, positioned at its start. Reads
    the header first and then at most the bytes that header allows (never a whole huge file)."""
    data = f.read(min(size, _MAX_HEADER_BYTES))
    attrs, pos = _header(data)
    try:
        channels = _channels(attrs["channels"][1])
        compression = attrs["compression"][1][0]
        xmin, ymin, xmax, ymax = struct.unpack("<4i", attrs["dataWindow"][1][:16])
    except (KeyError, IndexError, struct.error):
        raise Malformed("header lacks channels, compression or dataWindow") from None
    if compression not in _LINES_PER_BLOCK:
        raise Unsupported(f"OpenEXR compression {compression}")
    width, height = xmax - xmin + 1, ymax - ymin + 1
    if width <= 0 or height <= 0 or width * height > _MAX_PIXELS:
        raise Malformed(f"bad data window {width} x {height}")
    lines = _LINES_PER_BLOCK[compression]
    blocks = (height + lines - 1) // lines
    line_bytes = sum(dt.itemsize for _, dt in channels) * width
    # OpenEXR stores a block raw when its codec would not make it smaller, so the header bounds the
    # file: header + offset table + per block (y, size) + the raw lines.
    most = pos + 8 * blocks + 8 * blocks + line_bytes * height
    if size > most:
        raise Malformed(f"the file has {size} bytes, more than its header allows ({most})")
    if size > len(data):
        data += f.read(size - len(data))
    if len(data) != size:
        raise Malformed("the file changed size while it was read")
    names = [n for n, _ in channels]
    wanted = [c for c in ("R", "G", "B", "A") if c in names]
    if wanted[:3] != ["R", "G", "B"]:
        raise Unsupported(f"channels {names} (R, G, B needed)")

    if pos + 8 * blocks > len(data):
        raise Malformed("truncated offset table")
    offsets = struct.unpack_from(f"<{blocks}Q", data, pos)
    planes = {n: np.empty((height, width), np.float32) for n in wanted}
    seen = np.zeros(height, bool)
    for offset in offsets:
        if offset + 8 > len(data):
            raise Malformed("block offset past the end of the file")
        y, size = struct.unpack_from("<ii", data, offset)
        first = y - ymin
        if first < 0 or first >= height or first % lines or size < 0 or offset + 8 + size > len(data):
            raise Malformed(f"bad block at line {y}")
        count = min(lines, height - first)
        expected = line_bytes * count
        packed = data[offset + 8:offset + 8 + size]
        if size == expected:
            raw = packed  # stored as is (also when a codec would not have made it smaller)
        elif compression in (_ZIPS, _ZIP):
            raw = _unzip(packed, expected)
        elif compression == _RLE:
            raw = _unrle(packed, expected)
        else:
            raise Malformed(f"block at line {y} has {size} bytes, expected {expected}")
        seen[first:first + count] = True
        at = 0
        for row in range(first, first + count):
            for name, dt in channels:
                n = dt.itemsize * width
                if name in planes:
                    planes[name][row] = np.frombuffer(raw, dt, width, at)
                at += n
    if not seen.all():
        raise Malformed(f"{int((~seen).sum())} lines have no block")
    return np.ascontiguousarray(np.stack([planes[n] for n in wanted], axis=-1))
