"""The bake journal: every finished probe, kept durably next to the output as the bake goes, so a
crash, a kill or a cancel loses at most the probe being rendered, and a shard of a farm bake is a
journal too (docs/farm.md, "Journal file", normative).

A journal is append-only: a fixed header, a JSON manifest (what the bake is: its fingerprint and
the parts it was computed from, so a mismatch can say what changed), then one fixed-size record
per probe (the probe's key — its engine-space position as three float64 — its coefficients as
float64, its measured relative noise as float64 (0 when not measured) and a CRC-32). Each record is written with one ``write`` on an ``O_APPEND`` descriptor and
``fdatasync``ed before the bake goes on, so at any instant the file is readable up to its last
complete record; a torn or corrupt tail is ignored by readers and cut off by the next writer.

No Blender here: the module is plain Python (tests run it without Blender) and the fingerprint's
parts are computed by the caller (``fingerprint.py`` in Blender).
"""
from __future__ import annotations

import hashlib
import json
import os
import struct
import zlib
from typing import Dict, Iterable, List, Optional, Tuple

import numpy as np

from .file_names import temporary
from .safe_open import RefusedFile, open_regular

MAGIC = b"SCHNJRNL"
VERSION = 1
HEADER = struct.Struct("<8sIIIIII32s")  # magic, version, coeff count, channels, shard k, shard n, manifest bytes, fingerprint
MAX_MANIFEST_BYTES = 1 << 16
MAX_RECORDS = 1 << 24  # the .shprobe probe limit (PB_SHPROBE_MAX_PROBES)
KEY = struct.Struct("<3dI")  # position (engine space), flags (the round: 0 = the first two, k >= 2 = round k)
CHANNELS = 3


class JournalError(RuntimeError):
    """A journal that cannot be used: not a journal, of another bake, unreadable. The message names
    the file and says what to do."""


def fingerprint_of(parts: Dict[str, str]) -> bytes:
    """SHA-256 over the manifest's parts (name → hex digest or value), in name order."""
    h = hashlib.sha256()
    for name in sorted(parts):
        h.update(name.encode() + b"\0" + str(parts[name]).encode() + b"\0")
    return h.digest()


def key_of(position, flags: int = 0) -> bytes:
    """The record key of a probe at ``position`` (engine space, metres): its float64 bits and
    ``flags`` (the Adaptive placement's round: 0 = the point's two first rounds, k >= 2 = its round k;
    docs/farm.md "Journal file")."""
    x, y, z = (float(c) for c in position)
    return KEY.pack(x, y, z, int(flags))


def record_size(coeff_count: int) -> int:
    return KEY.size + 8 * coeff_count * CHANNELS + 8 + 4


class Contents:
    """What a journal holds: ``manifest`` (dict), ``shard`` ((k, n) or None), ``values`` (key →
    (coeff_count, 3) float64 array), ``noise`` (key → float), ``torn_bytes`` (bytes after the last
    good record)."""

    def __init__(self, path, manifest, coeff_count, shard, values, noise, good_bytes, torn_bytes):
        self.path = path
        self.manifest = manifest
        self.coeff_count = coeff_count
        self.shard = shard
        self.values = values
        self.noise = noise
        self.good_bytes = good_bytes
        self.torn_bytes = torn_bytes

    @property
    def fingerprint(self) -> str:
        return self.manifest["fingerprint"]


def _describe_mismatch(found: dict, want: dict) -> str:
    a, b = found.get("parts", {}), want.get("parts", {})
    changed = sorted(k for k in set(a) | set(b) if a.get(k) != b.get(k))
    if not changed:
        return "its fingerprint differs"
    return "changed since it was written: " + ", ".join(changed)


def read(path: str, expect_manifest: Optional[dict] = None) -> Contents:
    """Read a journal without blocking (regular files only, bounded by its header). Raises
    :class:`JournalError`. With ``expect_manifest``, a journal of another bake is an error that
    names the parts that changed."""
    try:
        f, size = open_regular(path, "a bake journal", HEADER.size + MAX_MANIFEST_BYTES
                               + MAX_RECORDS * record_size(81))
    except RefusedFile as exc:
        raise JournalError(str(exc)) from None
    with f:
        head = f.read(HEADER.size)
        if len(head) < HEADER.size or head[:8] != MAGIC:
            raise JournalError(f"{path}: not a Schnee bake journal")
        magic, version, count, channels, k, n, mlen, digest = HEADER.unpack(head)
        if version != VERSION:
            raise JournalError(f"{path}: journal version {version}; this add-on reads version {VERSION}")
        if channels != CHANNELS or not 1 <= count <= 81 or mlen > MAX_MANIFEST_BYTES or (n and k >= n):
            raise JournalError(f"{path}: malformed journal header")
        raw = f.read(mlen)
        try:
            manifest = json.loads(raw.decode("utf-8"))
        except (UnicodeDecodeError, ValueError):
            raise JournalError(f"{path}: malformed journal manifest") from None
        if not isinstance(manifest, dict) or manifest.get("fingerprint") != digest.hex():
            raise JournalError(f"{path}: the journal's manifest does not match its header")
        if expect_manifest is not None and expect_manifest["fingerprint"] != manifest["fingerprint"]:
            raise JournalError(f"{path} belongs to another bake ({_describe_mismatch(manifest, expect_manifest)}); "
                               "delete it to bake from scratch")
        rs = record_size(count)
        if size > HEADER.size + mlen + (MAX_RECORDS + 1) * rs:
            raise JournalError(f"{path}: {size} bytes is more than {MAX_RECORDS} probes can fill")
        body = f.read()
    values: Dict[bytes, np.ndarray] = {}
    noise: Dict[bytes, float] = {}
    good = 0
    for off in range(0, len(body) - rs + 1, rs):
        rec = body[off:off + rs]
        if zlib.crc32(rec[:-4]) != struct.unpack("<I", rec[-4:])[0]:
            break
        key = rec[:KEY.size]
        if key not in values:
            values[key] = np.frombuffer(rec[KEY.size:-12], dtype="<f8").reshape(count, CHANNELS).copy()
            noise[key] = struct.unpack("<d", rec[-12:-4])[0]
        good = off + rs
    start = HEADER.size + mlen
    return Contents(path, manifest, count, (k, n) if n else None, values, noise, start + good, len(body) - good)


def summary(path: str) -> Optional[dict]:
    """{'records': count, 'shard': (k, n) or None} from the header and the file size, without
    reading or checking the records (for the panel, drawn often); None when there is no readable
    journal at ``path``."""
    try:
        f, size = open_regular(path, "a bake journal", 1 << 62)
    except RefusedFile:
        return None
    with f:
        head = f.read(HEADER.size)
    if len(head) < HEADER.size or head[:8] != MAGIC:
        return None
    _, version, count, channels, k, n, mlen, _ = HEADER.unpack(head)
    if version != VERSION or channels != CHANNELS or not 1 <= count <= 81:
        return None
    return {"records": max(0, size - HEADER.size - mlen) // record_size(count), "shard": (k, n) if n else None}


class Writer:
    """Appends records to a journal; creates it (atomically, header and manifest) when absent, and
    cuts off a torn tail left by a crash. One writer per file (shards write one file each)."""

    def __init__(self, path: str, manifest: dict, coeff_count: int, shard: Optional[Tuple[int, int]] = None):
        self.path = path
        self.coeff_count = coeff_count
        self.rs = record_size(coeff_count)
        self.values: Dict[bytes, np.ndarray] = {}
        self.noise: Dict[bytes, float] = {}
        self.torn_bytes = 0
        if os.path.lexists(path):
            old = read(path, expect_manifest=manifest)
            if old.coeff_count != coeff_count or old.shard != (tuple(shard) if shard else None):
                raise JournalError(f"{path}: written for another band or shard; delete it to bake from scratch")
            self.values, self.noise = old.values, old.noise
            self.torn_bytes = old.torn_bytes
            fd = os.open(path, os.O_WRONLY | os.O_CLOEXEC | os.O_NOFOLLOW)
            try:
                if old.torn_bytes:
                    os.ftruncate(fd, old.good_bytes)
                    os.fsync(fd)
            finally:
                os.close(fd)
        self._manifest, self._shard = manifest, shard
        self._fd = -1
        if os.path.lexists(path):  # else created by the first append: no empty journals
            self._fd = os.open(path, os.O_WRONLY | os.O_APPEND | os.O_CLOEXEC | os.O_NOFOLLOW)

    def append(self, key: bytes, coeffs: np.ndarray, noise: float = 0.0) -> None:
        """Write one probe durably (returns after the data is on disk); ``noise`` is its measured
        relative Monte-Carlo noise, if any."""
        if self._fd < 0:
            _create(self.path, self._manifest, self.coeff_count, self._shard)
            self._fd = os.open(self.path, os.O_WRONLY | os.O_APPEND | os.O_CLOEXEC | os.O_NOFOLLOW)
        c, rec = _record(key, coeffs, noise, self.coeff_count)
        n = os.write(self._fd, rec)
        if n != len(rec):  # a short write (disk full): cut it off so the file stays well formed
            size = os.fstat(self._fd).st_size
            os.ftruncate(self._fd, size - n)
            raise OSError(28, f"{self.path}: short write (disk full?)")
        os.fdatasync(self._fd)
        if key not in self.values:
            self.values[key], self.noise[key] = c.copy(), float(noise)

    def close(self) -> None:
        if self._fd >= 0:
            os.close(self._fd)
            self._fd = -1

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        self.close()


def _record(key: bytes, coeffs, noise: float, coeff_count: int):
    """(the coefficients as float64, the record's bytes with its CRC)."""
    c = np.ascontiguousarray(coeffs, dtype="<f8").reshape(coeff_count, CHANNELS)
    body = key + c.tobytes() + struct.pack("<d", float(noise))
    return c, body + struct.pack("<I", zlib.crc32(body))


def _head(path: str, manifest: dict, coeff_count: int, shard) -> bytes:
    raw = json.dumps(manifest, sort_keys=True).encode()
    if len(raw) > MAX_MANIFEST_BYTES:
        raise JournalError(f"{path}: the manifest is {len(raw)} bytes, above {MAX_MANIFEST_BYTES}")
    k, n = shard if shard else (0, 0)
    return HEADER.pack(MAGIC, VERSION, coeff_count, CHANNELS, k, n, len(raw),
                       bytes.fromhex(manifest["fingerprint"])) + raw


def write_whole(path: str, manifest: dict, coeff_count: int, values: Dict[bytes, np.ndarray],
                noise: Dict[bytes, float]) -> None:
    """A complete journal of ``values`` in one write (keys in sorted order), to ``path`` (the
    caller's temporary name: bake_outputs.write_all renames it): region.py's kept points."""
    recs = b"".join(_record(k, values[k], noise.get(k, 0.0), coeff_count)[1] for k in sorted(values))
    with open(path, "wb") as fh:
        fh.write(_head(path, manifest, coeff_count, None) + recs)
        fh.flush()
        os.fsync(fh.fileno())


def _create(path: str, manifest: dict, coeff_count: int, shard) -> None:
    head = _head(path, manifest, coeff_count, shard)
    folder = os.path.dirname(os.path.abspath(path))
    os.makedirs(folder, exist_ok=True)
    # Hidden, beside the journal, at most 255 bytes even for the longest legal output name.
    tmp = temporary(os.path.join(folder, "." + os.path.basename(path)))
    fd = os.open(tmp, os.O_WRONLY | os.O_CREAT | os.O_EXCL | os.O_CLOEXEC, 0o644)
    try:
        os.write(fd, head)
        os.fsync(fd)
    finally:
        os.close(fd)
    try:
        # link() + unlink() instead of rename(): never replaces a journal another process created
        # in the meantime (two shards given the same file by mistake): the second one fails.
        os.link(tmp, path)
    except FileExistsError:
        raise JournalError(f"{path}: created by another process at the same time; each shard needs its own "
                           "journal") from None
    finally:
        os.unlink(tmp)
    dfd = os.open(folder, os.O_RDONLY | os.O_DIRECTORY)
    try:
        os.fsync(dfd)
    finally:
        os.close(dfd)


def make_manifest(parts: Dict[str, str], **info) -> dict:
    """The manifest of a bake: its parts (name → digest), their fingerprint, and free information
    (add-on version, scene name) that does not enter the fingerprint."""
    return {"fingerprint": fingerprint_of(parts).hex(), "parts": dict(parts), "info": info}


def merge(paths: Iterable[str], manifest: dict) -> Tuple[Dict[bytes, np.ndarray], Dict[bytes, float], List[Contents]]:
    """The union of several journals of the same bake (shards): every one must have ``manifest``'s
    fingerprint, and a probe present in two must have the same bits in both (else the renders are
    not deterministic and the merge would depend on order: an error)."""
    out: Dict[bytes, np.ndarray] = {}
    noise: Dict[bytes, float] = {}
    contents = []
    for p in paths:
        c = read(p, expect_manifest=manifest)
        contents.append(c)
        for key, v in c.values.items():
            old = out.get(key)
            if old is None:
                out[key], noise[key] = v, c.noise[key]
            elif old.tobytes() != v.tobytes() or noise[key] != c.noise[key]:
                x, y, z, _ = KEY.unpack(key)
                raise JournalError(f"{p}: probe at ({x:.4f}, {y:.4f}, {z:.4f}) differs from the same probe in "
                                   "another shard; the shards were not baked with the same renderer")
    return out, noise, contents
