"""The bake's outputs: which files it may replace, and the all-or-none write of several files.

Part of the bake (bake_core.ProbeBake drives it). Every file a bake writes is an :class:`Output`
(its final path, what kind of file it replaces, and a function that writes its contents to a
temporary path); :func:`write_all` checks every final path again (:func:`check_replaceable`),
writes each to a temporary name beside it, then renames them into place one after another. The
placement plans (bake_plans.py) make the outputs of the probe files (:func:`dense_output`,
:func:`octree_output`) and the debug text; the driver adds the sky and the sun (bake_sky.py).
"""
from __future__ import annotations

import json
import os
import shutil
import stat
from dataclasses import dataclass
from typing import Callable, List, Optional

import bpy
import numpy as np

from . import bakeinfo, journal, native, scene_export
from .file_names import temporary
from .region import RECORD_MAGIC
from .safe_open import file_kind
from .settings import BakeError

# The world (sky) alone, captured by a volume bake next to the probe files; the glTF exporter
# copies it and lists it as VULKAN_SCHNEE_engine_properties.sky (docs/export.md).
SKY_FILE_NAME = "sky.exr"
# The sky's sun split off as a mixed light (Sky Sun "mixed", docs/export.md "The sky's sun"); the
# file starts with SUN_MAGIC (json.dumps of a dict whose first key is "format", indent 2), which
# check_replaceable looks for before replacing or removing it.
SUN_FILE_NAME = "sun.json"
SUN_FORMAT = "schnee-sky-sun"
SUN_MAGIC = b'{\n  "format": "schnee-sky-sun"'
DEBUG_TEXT_NAME = "debug_probe.txt"
# Where Bake SH at Cursor puts its single-probe file when probes.shprobe holds a full bake:
# a subfolder, so the glTF exporter (which scans sh_coeffs/*.shprobe) never exports it.
DEBUG_SUBDIR = "debug"
DEBUG_SHPROBE_NAME = "debug_probe.shprobe"
DEBUG_TEXT_FIRST_LINE = "# Schnee probes: Bake SH at Cursor"
# How an existing file is recognised as one of ours before the bake replaces it (by content).
SHPROBE_MAGIC = b"SPHR"             # 0x52485053 little-endian at offset 0 (DESIGN.md §4)
EXR_MAGIC = b"\x76\x2f\x31\x01"     # OpenEXR


def abspath(path: str) -> str:
    """Resolve ``//`` against the saved .blend; refuse it for an unsaved one."""
    if path.startswith("//") and not bpy.data.filepath:
        raise BakeError(
            "The .blend file is not saved, so '//' (the folder of the .blend) has no meaning: "
            f"save the file first or give an explicit output path instead of '{path}'")
    return os.path.abspath(bpy.path.abspath(path))


@dataclass
class Output:
    """One file of a bake: ``write(tmp)`` writes its contents to the temporary path ``tmp``;
    ``kind`` is :func:`check_replaceable`'s (what an existing file at ``path`` must be)."""
    path: str
    kind: str
    write: Callable[[str], None]


def write_all(outputs: List[Output], stale: Optional[str] = None, log=print) -> List[str]:
    """Write all ``outputs`` to temporary names, then rename them into place one after another;
    returns the final paths. ``stale``: a sun.json this bake did not write (Sky Sun "mixed" split
    no sun off), checked like the outputs and removed after them.

    The temporary names are unique per bake (``<name>.<pid>-<random>.partial`` beside the final
    file, shortened to 255 bytes by file_names.temporary), so two bakes writing to the same folder
    at once never share one. A failure while
    writing removes every temporary file and leaves all final files unchanged. The renames are
    not one atomic step: should a later rename fail (a full disk does not, a permission change
    between two renames could), the files already renamed are new and the rest keep their old
    contents; the error names the file. Every OS error is raised as :class:`BakeError`.
    """
    tag = f"{os.getpid()}-{os.urandom(4).hex()}"
    pending = []  # (tmp, final)

    def tmp_name(final):
        return temporary(final, tag)

    # Checked before the bake started; again now, as the folder may have changed meanwhile.
    for out in outputs:
        check_replaceable(out.path, out.kind)
    if stale is not None:
        check_replaceable(stale, "sun")
    current = None
    try:
        for out in outputs:
            current = out.path
            os.makedirs(os.path.dirname(out.path), exist_ok=True)
            tmp = tmp_name(out.path)
            out.write(tmp)
            pending.append((tmp, out.path))
    except native.SchneeError as exc:
        for tmp, _ in pending:
            remove_quietly(tmp)
        raise BakeError(f"Writing the probe file failed: {exc}") from exc
    except OSError as exc:
        for tmp, _ in pending:
            remove_quietly(tmp)
        if current is not None:
            remove_quietly(tmp_name(current))
        raise BakeError(f"Cannot write {current}: {exc}") from exc
    except BaseException:
        for tmp, _ in pending:
            remove_quietly(tmp)
        raise
    for i, (tmp, final) in enumerate(pending):
        try:
            os.replace(tmp, final)
        except OSError as exc:
            for t, _ in pending[i:]:
                remove_quietly(t)
            done = [f for _, f in pending[:i]]
            raise BakeError(f"Cannot write {final}: {exc}"
                            + (f" (already replaced: {', '.join(done)})" if done else "")) from exc
    if stale is not None and os.path.lexists(stale):
        # An earlier bake's sun (Sky Sun "mixed") that these probes hold or that the world no
        # longer has: the export would add it twice or add a sun that is not there.
        try:
            os.unlink(stale)
            log(f"Schnee: removed {stale}: this bake split no sun off the sky")
        except OSError as exc:
            raise BakeError(f"Cannot remove the earlier bake's {stale}: {exc}") from exc
    return [final for _, final in pending]


def dense_output(target, coeffs: np.ndarray, positions: np.ndarray, settings) -> Output:
    """A dense-grid .shprobe (version 1, or 2 above L = 2 with positions and validity):
    ``coeffs``/``positions`` are the target's probes."""
    s = settings

    def write(tmp):
        extra = {}
        if s.max_band > 2:
            # Version 2 anyway (DESIGN.md §4): carry what placement knows. L <= 2 stays v1.
            extra = dict(positions=positions.astype(np.float32), validity=target.validity)
        native.write_shprobe(tmp, coeffs.astype(np.float32), target.grid, target.grid_dims,
                             target.grid_origin, target.grid_spacing, default_sh_scale=s.default_sh_scale,
                             default_ambient=s.default_ambient, **extra)
    return Output(target.path, "shprobe", write)


def octree_output(target, coeffs: np.ndarray, validity: np.ndarray, settings, scratch: str, kept=None) -> Output:
    """Version 3 (the corner octree ``target.group.tree``), or with File Version 1 the same field
    resampled onto the dense grid of Min Cell Size (version 2 above L = 2) through the temporary
    file ``scratch``. ``kept`` (version 3; region.KeptTree.records): (rows, records, validity) that
    replace those rows as written, bit for bit."""
    s, group = settings, target.group

    def keep(records, valid):
        records, valid = np.array(records, dtype=np.float32), np.array(valid, dtype=np.float32)
        if kept is not None:
            records[kept[0]], valid[kept[0]] = kept[1], kept[2]
        return records, valid

    def write(tmp):
        kw = dict(default_sh_scale=s.default_sh_scale, default_ambient=s.default_ambient)
        if s.file_version == "V3":
            if s.probe_representation == "SH":
                c, v = keep(coeffs, validity)
                native.write_shprobe_v3(tmp, group.tree, c, validity=v, **kw)
            else:  # issue 16: the ambient cube fitted to each probe's SH
                cubes = native.ambient_cube_from_sh(coeffs)
                if s.probe_representation == "CUBE_HALF":
                    check_half_range(cubes, group.lattice_positions(group.tree.probe_lattice()), target.path)
                cubes, v = keep(cubes, validity)
                native.write_shprobe_v3(tmp, group.tree, cubes, representation="ambientCube",
                                        storage="float16" if s.probe_representation == "CUBE_HALF" else "float32",
                                        validity=v, **kw)
            return
        native.write_shprobe_v3(scratch, group.tree, coeffs.astype(np.float32), validity=validity, **kw)
        dense = native.resample_shprobe_dense(scratch)
        os.remove(scratch)
        native.write_shprobe(tmp, dense.coeffs, dense.grid, dense.grid_dims, dense.grid_origin,
                             dense.grid_spacing, version=1 if s.max_band <= 2 else 0, **kw)
    return Output(target.path, "shprobe", write)


def text_output(path: str, kind: str, text: str, sync: bool = False) -> Output:
    """A text file (debug_probe.txt, sun.json); ``sync``: flushed to the disk before the rename."""
    def write(tmp):
        with open(tmp, "w", encoding="utf-8") as fh:
            fh.write(text)
            if sync:
                fh.flush()
                os.fsync(fh.fileno())
    return Output(path, kind, write)


def sun_output(path: str, record: dict) -> Output:
    """sun.json: ``record`` (direct_light.sun_record) after its format line (SUN_MAGIC)."""
    return text_output(path, "sun", json.dumps(dict(format=SUN_FORMAT, **record), indent=2) + "\n", sync=True)


def copy_output(path: str, kind: str, source: str) -> Output:
    """A file made in the temporary folder (the sky's EXR), copied into place."""
    return Output(path, kind, lambda tmp: shutil.copyfile(source, tmp))


# Largest finite binary16 value: what Probe Representation "Ambient cube (half)" can store.
HALF_MAX = 65504.0
# Ambient-cube face k (engine axes +X, -X, +Y, -Y, +Z, -Z; native.ambient_cube_from_sh) named by
# the Blender axis it faces (engine (x, y, z) = Blender (x, z, -y)).
_CUBE_FACES_BLENDER = ("+X", "-X", "+Z", "-Z", "-Y", "+Y")


def check_half_range(cubes, positions, path):
    """Raise :class:`BakeError` unless every ambient-cube colour of ``cubes`` (P, 6, 3) fits
    binary16 (|value| <= 65504): the native writer would refuse the file naming only a record
    (issue 14: an emission of 1e30). The message names the first probe beyond the range, its
    position in Blender coordinates (``positions`` (P, 3) are engine space) and what to do."""
    cubes = np.asarray(cubes, dtype=np.float64)
    over = np.abs(cubes) > HALF_MAX
    if not over.any():
        return
    p, face, channel = (int(v) for v in np.argwhere(over)[0])
    where = tuple(float(c) for c in scene_export.engine_to_blender(np.asarray(positions)[p]))
    raise BakeError(
        f"Probe Representation 'Ambient cube (half)' cannot store {os.path.basename(path)}: probe {p + 1} of "
        f"{len(cubes)} at Blender ({where[0]:.3f}, {where[1]:.3f}, {where[2]:.3f}) has the irradiance "
        f"{cubes[p, face, channel]:.4g} ({'RGB'[channel]}, face {_CUBE_FACES_BLENDER[face]}), beyond half "
        f"floats' largest value {HALF_MAX:g} ({int(over.any(axis=(1, 2)).sum())} probe(s) in all); choose "
        f"Probe Representation 'Ambient cube (float)' (--probe-representation CUBE_FLOAT), or lower the "
        f"emission that lights it; existing files are unchanged")


# ------------------------------------------------------------------ what we may replace
def check_replaceable(path, kind):
    """Raise :class:`BakeError` unless ``path`` is absent or a file the bake wrote: ``kind``
    "shprobe" (magic SPHR), "exr" (the sky), "sun" (sun.json), "record" (region.py's bake record) or
    "text" (debug_probe.txt). Never the open .blend,
    never something that is not a regular file. Opens nothing that could block (no FIFO)."""
    blend = bpy.data.filepath
    try:
        st = os.stat(path)
    except FileNotFoundError:
        return
    except OSError as exc:
        raise BakeError(f"Cannot write {path}: {exc.strerror}") from exc
    if blend:
        try:
            if os.path.samefile(path, blend):
                raise BakeError(f"Refusing to write {path}: it is the open .blend file; choose an "
                                "output ending in .shprobe")
        except OSError:
            pass
    if not stat.S_ISREG(st.st_mode):
        raise BakeError(f"Refusing to replace {path}: it exists and is a {file_kind(st.st_mode)}; "
                        "the bake only replaces files it wrote")
    want = {"shprobe": SHPROBE_MAGIC, "exr": EXR_MAGIC, "text": DEBUG_TEXT_FIRST_LINE.encode(),
            "journal": journal.MAGIC, "sun": SUN_MAGIC, "record": RECORD_MAGIC, "bakeinfo": bakeinfo.MAGIC}[kind]
    try:
        fd = os.open(path, os.O_RDONLY | getattr(os, "O_NONBLOCK", 0) | getattr(os, "O_NOCTTY", 0))
        try:
            if not stat.S_ISREG(os.fstat(fd).st_mode):  # swapped since the stat above
                raise BakeError(f"Refusing to replace {path}: it is not a regular file")
            head = os.read(fd, len(want))
        finally:
            os.close(fd)
    except OSError as exc:
        raise BakeError(f"Cannot check {path} before replacing it: {exc.strerror}") from exc
    if head != want:
        what = {"shprobe": "a .shprobe file (no Schnee probe header)", "exr": "an OpenEXR image",
                "journal": "a Schnee bake journal", "sun": "a sun.json written by a bake",
                "record": "a bake record written by a bake",
                "bakeinfo": "a bake-info sidecar (a .npz archive)",
                "text": "a debug_probe.txt written by Bake SH at Cursor"}[kind]
        raise BakeError(f"Refusing to replace {path}: it exists and is not {what}; move it away or "
                        "choose another output")


def remove_quietly(path):
    try:
        os.remove(path)
    except OSError:
        pass


def is_single_probe_file(path) -> bool:
    try:
        h = native.read_shprobe_header(path)
    except (native.SchneeError, OSError):
        return False  # unreadable: not a bake we would destroy knowingly, but not ours either
    return h["probe_count"] == 1 and tuple(h["grid_dims"]) == (1, 1, 1)


_AXES = (("+X", (1, 0, 0)), ("-X", (-1, 0, 0)), ("+Y", (0, 1, 0)), ("-Y", (0, -1, 0)),
         ("+Z", (0, 0, 1)), ("-Z", (0, 0, -1)))


def debug_text(cursor_blender, pos_engine, coeffs, settings) -> str:
    """The readable ``debug_probe.txt``: position, coefficients and irradiance along the axes."""
    lines = ["# Schnee probes: Bake SH at Cursor",
             f"# blender position (Z-up): {cursor_blender[0]:.6f} {cursor_blender[1]:.6f} {cursor_blender[2]:.6f}",
             f"# engine position (Y-up):  {pos_engine[0]:.6f} {pos_engine[1]:.6f} {pos_engine[2]:.6f}",
             f"# max band {settings.max_band}, panorama {settings.panorama_resolution}x"
             f"{settings.panorama_resolution // 2}, {settings.samples} samples, {settings.max_bounces} bounces",
             "# radiance SH coefficients L_i = integral L(w) Y_i(w) dw, engine space (DESIGN.md §3)",
             "# i  l  m          R            G            B"]
    i = 0
    for band in range(settings.max_band + 1):
        for m in range(-band, band + 1):
            r, g, b = coeffs[i]
            lines.append(f"{i:3d} {band:2d} {m:2d} {r:12.6f} {g:12.6f} {b:12.6f}")
            i += 1
    normals = np.array([a[1] for a in _AXES], dtype=np.float64)
    irr = native.irradiance(np.asarray(coeffs, dtype=np.float64), normals)
    lines.append("# irradiance E(n) (W/m^2 in Cycles units) for normals along the engine axes "
                 "(engine +Y = Blender +Z, engine -Z = Blender +Y)")
    lines.append("# axis        R            G            B")
    for (label, _), (r, g, b) in zip(_AXES, irr):
        lines.append(f"{label:>6} {r:12.6f} {g:12.6f} {b:12.6f}")
    return "\n".join(lines) + "\n"
