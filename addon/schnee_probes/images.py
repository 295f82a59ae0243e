"""The add-on's one image reader: every image the add-on reads as pixels goes through
:func:`read_image`, and the format decisions are made here, once.

- OpenEXR files (the bake's own panoramas, Cycles' ``save_render``: single-part scanline,
  uncompressed, RLE, ZIPS or ZIP) are decoded by :mod:`exr`, in Python, with no image library.
- Other EXR codecs (e.g. DWAB HDRIs) and Radiance HDR, PFM, PNG, JPEG or TIFF files are read through
  Blender's image API inside Blender, or through OpenImageIO's ``oiiotool`` outside it (benchmarks,
  tools), which rewrites them as an uncompressed EXR that :mod:`exr` reads. Outside Blender a plain
  RGB PFM (scale ±1, exact size) is read here in numpy, with the values oiiotool gives, and without its
  seconds of start-up; any other PFM still goes to oiiotool.
- Anything else is refused before any library sees it (a file must announce an image format).

Files are opened as the native readers open theirs (:mod:`safe_open`: no blocking, regular files
only, bounded size), and errors are :class:`native.SchneeError` with the codes the C readers use.
"""
from __future__ import annotations

import os
import re
import shutil
import subprocess
import tempfile

import numpy as np

from . import exr, safe_open
from .native import SchneeError

# Limits of image files read for projection: the native readers' (native/include/schnee/pb_image.h).
IMAGE_MAX_FILE_BYTES = 1 << 32
IMAGE_MAX_SIDE = 65536
IMAGE_MAX_CHANNELS = 64
IMAGE_MAX_VALUES = 1 << 29
# First bytes of the image formats read through Blender or oiiotool: Radiance HDR, PFM, PNG, JPEG, TIFF.
_IMAGE_SIGNATURES = (b"#?", b"PF", b"Pf", b"\x89PNG", b"\xff\xd8\xff", b"II*\0", b"MM\0*")


def read_image(path: str) -> np.ndarray:
    """Float32 pixels (H, W, C), row 0 at the top, of an image file: an EXR the add-on reads itself,
    else (inside Blender) any image Blender reads, else (outside) what oiiotool reads. The file is
    opened as the native readers open theirs: without blocking, regular files only, at most
    IMAGE_MAX_FILE_BYTES, the header checked before the pixels. SchneeError on failure; messages
    never quote the file's content."""
    path = os.fspath(path)
    try:
        f, size = safe_open.open_regular(path, "an image", IMAGE_MAX_FILE_BYTES)
    except safe_open.RefusedFile as exc:
        raise SchneeError(str(exc), exc.code) from None
    with f:
        head = f.read(4)
        if head.startswith(b"PF") and not _in_blender():
            f.seek(0)
            pixels = _read_pfm(f, size, path)
            if pixels is not None:
                return pixels
        if exr.has_magic(head):
            f.seek(0)
            try:
                return exr.read_file(f, size)
            except OSError as exc:
                raise SchneeError(f"{path}: cannot read: {exc.strerror or exc}", "I/O error") from None
            except exr.Malformed as exc:
                raise SchneeError(f"{path}: cannot read as exr: {exc}", "malformed file") from None
            except exr.Unsupported:
                pass  # e.g. DWAB-compressed HDRIs: Blender (or oiiotool) reads those
        elif path.lower().endswith(".exr"):
            raise SchneeError(f"{path}: cannot read as exr: not an OpenEXR file (bad magic number)", "malformed file")
        elif not head.startswith(_IMAGE_SIGNATURES):
            # Never hand an unknown file to a library that tries every reader on it (OpenImageIO
            # took minutes on a 2 GiB sparse file): only files that announce an image format.
            raise SchneeError(f"{path}: not an image (no EXR, HDR, PFM, PNG, JPEG or TIFF signature)",
                              "malformed file")
    return _read_with_blender(path)


def _check_image_size(path: str, w: int, h: int, c: int):
    if w > IMAGE_MAX_SIDE or h > IMAGE_MAX_SIDE or c > IMAGE_MAX_CHANNELS or w * h * c > IMAGE_MAX_VALUES:
        raise SchneeError(f"image '{path}' is too large: {w}x{h} with {c} channel(s); the limits are "
                          f"{IMAGE_MAX_SIDE} pixels per side, {IMAGE_MAX_CHANNELS} channels and {IMAGE_MAX_VALUES} "
                          "values (width x height x channels)", "input too large")


def _in_blender() -> bool:
    try:
        import bpy  # noqa: F401
    except ImportError:
        return False
    return True


# An RGB PFM header: "PF", width, height, then the scale, whose sign is the byte order (negative:
# little-endian), and one whitespace byte before the rows (stored bottom row first). Grey PFM ("Pf")
# is left to oiiotool (whose one-channel EXR exr.py refuses, as before).
_PFM_HEADER = re.compile(rb"PF\s+(\d{1,9})\s+(\d{1,9})\s+([-+]?(?:\d+\.?\d*|\.\d+)(?:[eE][-+]?\d+)?)\s")


def _read_pfm(f, size: int, path: str):
    """Pixels of a plain RGB PFM file (scale +1 or -1, no trailing bytes), as oiiotool reads it (the test
    compares the two bit for bit); None for any other PFM, which oiiotool then reads or refuses.
    A header that claims more than the limits is refused before the rows are read."""
    m = _PFM_HEADER.match(f.read(64))
    if m is None:
        return None
    c = 3
    w, h, scale = int(m.group(1)), int(m.group(2)), float(m.group(3))
    _check_image_size(path, w, h, c)
    nbytes = w * h * c * 4
    if w == 0 or h == 0 or abs(scale) != 1.0 or size != m.end() + nbytes:
        return None
    f.seek(m.end())
    try:
        data = f.read(nbytes)
    except OSError as exc:
        raise SchneeError(f"{path}: cannot read: {exc.strerror or exc}", "I/O error") from None
    if len(data) != nbytes:
        return None
    rows = np.frombuffer(data, "<f4" if scale < 0 else ">f4").reshape(h, w, c)
    return np.ascontiguousarray(rows[::-1], np.float32)  # row 0 at the top, native byte order


def _read_with_oiiotool(path: str) -> np.ndarray:
    """Outside Blender (benchmarks, tools on a development machine): OpenImageIO's command-line tool,
    when installed, rewrites the image as an uncompressed float EXR, which exr.py reads exactly."""
    tool = shutil.which("oiiotool")
    if tool is None:
        raise SchneeError(f"{path}: outside Blender only uncompressed/RLE/ZIP scanline EXR files are read "
                          "(or any image when OpenImageIO's oiiotool is installed)", "I/O error")
    if not os.path.isfile(path):
        raise SchneeError(f"cannot read {path}: no such file", "I/O error")
    # The header first (oiiotool --info reads no pixels), so a file that claims gigabytes is refused
    # before anything is decoded.
    info = subprocess.run([tool, "--info", path], capture_output=True, text=True)
    m = re.search(r"(\d+)\s+x\s+(\d+)(?:\s+x\s+\d+)?,\s+(\d+) channel", info.stdout)
    if info.returncode != 0 or m is None:
        raise SchneeError(f"cannot read {path}: OpenImageIO does not recognise it as an image", "I/O error")
    _check_image_size(path, int(m.group(1)), int(m.group(2)), int(m.group(3)))
    with tempfile.TemporaryDirectory(prefix="schnee-img-") as tmp:
        out = os.path.join(tmp, "image.exr")
        proc = subprocess.run([tool, path, "-d", "float", "--compression", "none", "-o", out],
                              capture_output=True, text=True)
        if proc.returncode != 0 or not os.path.isfile(out):
            raise SchneeError(f"cannot read {path}: {proc.stderr.strip() or 'oiiotool failed'}", "I/O error")
        try:
            return exr.read(out)
        except (exr.Malformed, exr.Unsupported) as exc:
            raise SchneeError(f"cannot read {path}: {exc}", "I/O error") from None


def _read_with_blender(path: str) -> np.ndarray:
    try:
        import bpy
    except ImportError:
        return _read_with_oiiotool(path)
    if not os.path.isfile(path):
        raise SchneeError(f"cannot read {path}: no such file", "I/O error")
    try:
        image = bpy.data.images.load(path, check_existing=False)
    except RuntimeError as exc:
        raise SchneeError(f"cannot read {path}: {exc}", "I/O error") from None
    try:
        w, h = image.size
        c = image.channels
        _check_image_size(path, w, h, c)
        if w <= 0 or h <= 0 or c < 3:
            raise SchneeError(f"cannot read {path}: Blender loaded {w} x {h} x {c}", "I/O error")
        buf = np.empty(w * h * c, np.float32)
        image.pixels.foreach_get(buf)
    finally:
        bpy.data.images.remove(image)
    # Blender's Image.pixels is bottom-up; the projection wants row 0 at the top.
    return np.ascontiguousarray(buf.reshape(h, w, c)[::-1])
