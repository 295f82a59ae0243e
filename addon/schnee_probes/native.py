"""Python face of the native bake core (``_schnee_native``, a stable-ABI CPython module).

This file is the contract between the add-on and the C core. Arrays go in and out as numpy arrays
(flat buffers underneath, never per-element calls); long calls release the GIL; every core error is
raised as :class:`SchneeError` carrying the core's message verbatim and its code name.

All geometry and SH data are in engine space (Y-up, DESIGN.md §2) unless a docstring says otherwise.
SH coefficient arrays have shape ``(sh_count(max_band), 3)`` (coefficient-major, RGB), the
radiance projection ``L_i = ∫ L(ω) Y_i(ω) dω`` of DESIGN.md §3.

The sections below map 1:1 to the module's files (native/python/mod_*.c, one per area of the core):
one wrapper per C function. Each value is validated once. Here: arguments are converted to
C-contiguous arrays of the dtype the core wants (a dtype kind that cannot convert -> TypeError,
integers that would not fit -> ValueError), shapes the C cannot see in a flat buffer are checked
(ValueError), and names of choices ("clamp", "sinc4") become the C's numbers. The C module checks
the rest, once, naming the argument: buffer formats and item counts, max_band (0..4), sizes,
versions, callables and mesh tuples (native/python/mod_common.h). Images are read by images.py.
See docs/python-api.md.
"""
from __future__ import annotations

import os
from dataclasses import dataclass
from typing import Callable, Optional, Sequence, Tuple

import numpy as np

# The module exports only PyInit__schnee_native (hidden visibility + version script) and links only
# libc, libm and qhull (libqhull_r, which the package carries in lib/). Embree it opens itself at
# import (dlopen RTLD_LOCAL + dlsym, native/src/pb_embree_dyn.h), preferring an Embree 3 already in
# the process (Blender 3.x), else the one the add-on package carries in lib/ (with TBB), so its
# Embree calls cannot bind to the Embree 4 of Blender 4.x/5.x.
try:
    from . import _schnee_native as _native
    _NATIVE_IMPORT_ERROR: Optional[BaseException] = None
except ImportError as exc:  # not built yet: the pure-Python parts (dataclasses, errors) still work
    _native = None
    _NATIVE_IMPORT_ERROR = exc


def native_problem() -> Optional[str]:
    """None when the compiled module loaded, else what is wrong and what to do, in words for someone
    who installed the add-on package (shown by the panel and bake.py)."""
    if _native is not None:
        return None
    return _explain(_NATIVE_IMPORT_ERROR)


def _explain(exc: Optional[BaseException]) -> str:
    import platform
    text = str(exc) if exc is not None else "unknown reason"
    here = os.path.dirname(os.path.abspath(__file__))
    found = [f for f in os.listdir(here) if f.startswith("_schnee_native")] if os.path.isdir(here) else []
    if platform.system() != "Linux" or platform.machine() not in ("x86_64", "AMD64"):
        what = (f"this package's bake core is built for Linux x86-64, and this is "
                f"{platform.system()} {platform.machine()}")
    elif not found:
        what = "the package has no compiled bake core (_schnee_native.abi3.so)"
    elif "cannot open shared object file" in text:
        lib = text.split(":")[0].strip()
        what = (f"a library the bake core needs is missing: {lib} (the package ships Embree, TBB and "
                f"qhull in {os.path.join('schnee_probes', 'lib')}; the package seems incomplete)")
    elif "GLIBC" in text or "GLIBCXX" in text:
        what = f"this system's C/C++ runtime is older than the package was built for ({text})"
    else:
        what = f"the bake core did not load ({text})"
    return (f"Schnee Probes: {what}. Reinstall the add-on from the complete package "
            f"(schnee_probes-<version>.zip, or the extension package for Blender 4.2+) built for "
            f"Linux x86-64 with glibc 2.34 or newer, or build it from source (scripts/build.sh). "
            f"Loaded from: {here}")


class SchneeError(RuntimeError):
    """An error reported by the native core. ``code`` is the pb_result name, e.g. ``"open mesh"``."""

    def __init__(self, message: str, code: str = "unknown error"):
        super().__init__(message)
        self.code = code


if _native is not None:
    # The C module raises SchneeError(message) and sets .code = pb_result_string(code).
    _native._set_error_class(SchneeError)


def _lib():
    if _native is None:
        raise ImportError(_explain(_NATIVE_IMPORT_ERROR))
    return _native


# Blender world (Z-up) -> engine (Y-up): (x, y, z) -> (x, z, -y).
BLENDER_TO_ENGINE = np.array([[1.0, 0.0, 0.0], [0.0, 0.0, 1.0], [0.0, -1.0, 0.0]])


def sh_count(max_band: int) -> int:
    """Number of coefficients for bands 0..max_band: (max_band + 1)**2."""
    return (max_band + 1) ** 2


# ---- argument conversion ----------------------------------------------------------------------

_FLOAT_KINDS = "fiu"   # float targets accept float and integer input
_INT_KINDS = "iu"


def _array(x, name: str, dtype, kinds: str) -> np.ndarray:
    """``x`` as a C-contiguous array of ``dtype``; TypeError naming ``name`` for a wrong dtype kind."""
    arr = np.asarray(x)
    if arr.dtype.kind not in kinds:
        raise TypeError(f"{name} must be a numeric array convertible to {np.dtype(dtype).name}, "
                        f"got dtype {arr.dtype}")
    if arr.dtype.kind in _INT_KINDS and np.dtype(dtype).kind in _INT_KINDS and arr.size:
        info = np.iinfo(dtype)
        lo, hi = int(arr.min()), int(arr.max())
        if lo < info.min or hi > info.max:
            raise ValueError(f"{name} values must fit {np.dtype(dtype).name} "
                             f"[{info.min}, {info.max}], got range [{lo}, {hi}]")
    return np.ascontiguousarray(arr, dtype=dtype)


def _shape_error(name: str, want: str, arr: np.ndarray):
    return ValueError(f"{name} must have shape {want}, got {arr.shape}")


def _vectors(x, name: str, dtype=np.float64) -> Tuple[np.ndarray, bool]:
    """(N, 3) or (3,) -> (N, 3) array and whether the input was a single vector."""
    arr = _array(x, name, dtype, _FLOAT_KINDS)
    if arr.ndim == 1 and arr.shape[0] == 3:
        return arr.reshape(1, 3), True
    if arr.ndim != 2 or arr.shape[1] != 3:
        raise _shape_error(name, "(N, 3) or (3,)", arr)
    return arr, False


def _band_of(count: int, name: str) -> int:
    for band in range(5):
        if sh_count(band) == count:
            return band
    raise ValueError(f"{name} has {count} coefficients; expected (L+1)^2 for L in 0..4 "
                     "(1, 4, 9, 16 or 25)")


def _coeffs(x, name: str = "coeffs", dtype=np.float64) -> Tuple[np.ndarray, int]:
    arr = _array(x, name, dtype, _FLOAT_KINDS)
    if arr.ndim != 2 or arr.shape[1] != 3:
        raise _shape_error(name, "(sh_count, 3)", arr)
    return arr, _band_of(arr.shape[0], name)


def _rotation(rotation) -> Optional[np.ndarray]:
    if rotation is None:
        return None
    arr = _array(rotation, "rotation", np.float64, _FLOAT_KINDS)
    if arr.shape != (3, 3):
        raise _shape_error("rotation", "(3, 3)", arr)
    return arr


_NEGATIVE = {"error": 0, "clamp": 1, "allow": 2}
_WINDOWS = {"none": 0, "sinc4": 1, "laplacian": 2}


def _choice(value: str, table: dict, name: str) -> int:
    try:
        return table[value]
    except (KeyError, TypeError):
        raise ValueError(f"{name} must be one of {', '.join(map(repr, table))}; got {value!r}") from None


# ---- SH and ambient cubes (native/python/mod_sh.c) ------------------------------------------------

def sh_basis(dirs: np.ndarray, max_band: int) -> np.ndarray:
    """Basis values, shape (N, sh_count), at unit directions ``dirs`` (N, 3) in engine space.
    A single direction (3,) gives shape (sh_count,)."""
    d, single = _vectors(dirs, "dirs")
    raw = _lib().sh_basis(d, max_band)  # the C checks max_band (0..4)
    out = np.frombuffer(raw, dtype=np.float64).reshape(len(d), sh_count(int(max_band)))
    return out[0] if single else out


def min_panorama_size(max_band: int) -> Tuple[int, int]:
    """Smallest (width, height) panorama that can represent ``max_band``."""
    return tuple(_lib().min_panorama_size(max_band))


def project_equirect(pixels: np.ndarray, max_band: int = 2, rotation: Optional[np.ndarray] = None,
                     negative: str = "error") -> np.ndarray:
    """Project an equirect panorama ``pixels`` (H, W, C>=3) float32, row 0 at the TOP (as Cycles
    writes files; note Blender's ``Image.pixels`` is bottom-up) onto SH. ``rotation`` (3, 3) maps the
    canonical Cycles panorama direction (Blender world space, camera rotated (90°, 0, −90°)) to the
    output space; None = BLENDER_TO_ENGINE. ``negative``: "error" | "clamp" | "allow" (NaN/Inf is
    always an error). Returns (sh_count, 3) float64. Runs with the GIL released."""
    pix = _array(pixels, "pixels", np.float32, _FLOAT_KINDS)
    if pix.ndim != 3 or pix.shape[2] < 3:
        raise _shape_error("pixels", "(H, W, C) with C >= 3", pix)
    h, w, c = pix.shape
    raw = _lib().project_equirect(pix, w, h, c, max_band, _rotation(rotation),
                                  _choice(negative, _NEGATIVE, "negative"))
    return np.frombuffer(raw, dtype=np.float64).reshape(-1, 3)


def project_file(path: str, max_band: int = 2, rotation: Optional[np.ndarray] = None,
                 negative: str = "error") -> np.ndarray:
    """Same as :func:`project_equirect` for an image file, read by :func:`images.read_image` (the
    bake's own EXR files by exr.py, other images through Blender, or oiiotool outside Blender).
    Errors are SchneeError: "I/O error" (missing/unreadable file), "malformed file"."""
    from . import images
    return project_pixels(images.read_image(path), max_band, rotation, negative, name=path)


def project_pixels(pixels: np.ndarray, max_band: int = 2, rotation: Optional[np.ndarray] = None,
                   negative: str = "error", name: str = "") -> np.ndarray:
    """:func:`project_file` of pixels already read (float32 (H, W, C), row 0 at the top, as
    :func:`images.read_image` gives them); ``name`` prefixes error messages."""
    rot = _rotation(rotation)
    policy = _choice(negative, _NEGATIVE, "negative")
    pixels = np.ascontiguousarray(pixels, dtype=np.float32)
    h, w, c = pixels.shape
    try:
        raw = _lib().project_equirect(pixels, w, h, c, max_band, rot, policy)
    except SchneeError as exc:
        raise SchneeError(f"{os.fspath(name)}: {exc}" if name else str(exc), exc.code) from None
    return np.frombuffer(raw, dtype=np.float64).reshape(-1, 3)


def read_image(path: str) -> np.ndarray:
    """Float32 pixels (H, W, C) of an image file, row 0 at the top: :func:`images.read_image`, the
    add-on's one image reader (kept here for callers of the earlier name)."""
    from . import images
    return images.read_image(path)


def irradiance(coeffs: np.ndarray, normals: np.ndarray) -> np.ndarray:
    """Irradiance E(n) (N, 3) of radiance coefficients (sh_count, 3) at unit normals (N, 3).
    A single normal (3,) gives shape (3,)."""
    c, band = _coeffs(coeffs)
    n, single = _vectors(normals, "normals")
    out = np.frombuffer(_lib().irradiance(c, band, n), dtype=np.float64).reshape(len(n), 3)
    return out[0] if single else out


def window(coeffs: np.ndarray, kind: str = "none", strength: float = 0.0) -> Tuple[np.ndarray, np.ndarray]:
    """Ringing window: kind "none" | "sinc4" | "laplacian"; strength 0 = automatic.
    Returns (windowed coefficients copy, minimum irradiance over the sphere (3,))."""
    c, band = _coeffs(coeffs)
    raw, min_e = _lib().window(c, band, _choice(kind, _WINDOWS, "kind"), float(strength))
    return np.frombuffer(raw, dtype=np.float64).reshape(c.shape), np.array(min_e, dtype=np.float64)


def ambient_cube_from_sh(coeffs: np.ndarray) -> np.ndarray:
    """Ambient cubes (P, 6, 3) (irradiance +X, −X, +Y, −Y, +Z, −Z; the shipped least-squares fit,
    docs/ambient-cube.md) of radiance SH ``coeffs`` (P, sh_count, 3)."""
    c = _array(coeffs, "coeffs", np.float64, _FLOAT_KINDS)
    if c.ndim != 3 or c.shape[2] != 3:
        raise _shape_error("coeffs", "(P, sh_count, 3)", c)
    band = _band_of(c.shape[1], "coeffs")
    raw = _lib().ambient_cube_from_sh(c.reshape(-1), band, 0)
    return np.frombuffer(raw, dtype=np.float64).reshape(-1, 6, 3)


# ---- placement (native/python/mod_placement.c) ----------------------------------------------------

@dataclass
class Placement:
    """Result of :func:`place_probes` (engine space)."""
    positions: np.ndarray       # (P, 3) float64 probe positions
    cell_sizes: np.ndarray      # (P,) float64 edge of the leaf cell of each probe
    backface_ratio: np.ndarray  # (P,) float32 solid-test back-face ratio
    grid: np.ndarray            # (X*Y*Z,) int32, flat x + y*X + z*X*Y, probe index or -1
    grid_dims: Tuple[int, int, int]
    grid_origin: Tuple[float, float, float]
    grid_spacing: float
    leaf_count: int
    pruned_count: int


Mesh = Tuple[str, np.ndarray, np.ndarray]  # (name, vertices (V, 3) float64, triangles (T, 3) uint32)


def _meshes(meshes: Sequence[Mesh], what: str) -> list:
    """Each (name, vertices, triangles) with its arrays converted and shapes checked; an item that
    is not such a triple is passed on for the C to refuse ("volumes[0] must be a (name, ...) tuple")."""
    out = []
    for i, mesh in enumerate(meshes):
        try:
            name, verts, tris = mesh
        except (TypeError, ValueError):
            out.append(mesh)
            continue
        v = _array(verts, f"{what}[{i}] vertices", np.float64, _FLOAT_KINDS)
        if v.ndim != 2 or v.shape[1] != 3:
            raise _shape_error(f"{what}[{i}] vertices", "(V, 3)", v)
        t = _array(tris, f"{what}[{i}] triangles", np.uint32, _INT_KINDS)
        if t.ndim != 2 or t.shape[1] != 3:
            raise _shape_error(f"{what}[{i}] triangles", "(T, 3)", t)
        out.append((None if name is None else str(name), v, t))
    return out


def place_probes(volumes: Sequence[Mesh], geometry: Sequence[Mesh], min_cell_size: float = 0.5,
                 max_cell_size: float = 16.0, threads: int = 0,
                 progress: Optional[Callable[[float, str], bool]] = None, *,
                 solid_ray_count: int = 0, solid_backface_ratio: float = 0.0,
                 max_grid_cells: int = 0) -> Placement:
    """Place probes in the union of closed ``volumes`` avoiding solid ``geometry`` (both engine
    space, metres). ``progress(fraction, stage)`` returning False cancels (SchneeError code
    "cancelled"); returning None continues; an exception raised in it cancels and propagates.
    Open volume meshes raise SchneeError code "open mesh" naming the mesh. Runs with the GIL
    released (the callback takes it back)."""
    d = _lib().place_probes(_meshes(volumes, "volumes"), _meshes(geometry, "geometry"),
                            float(min_cell_size), float(max_cell_size), int(threads), progress,
                            int(solid_ray_count), float(solid_backface_ratio), int(max_grid_cells))
    n = d["probe_count"]
    return Placement(
        positions=np.frombuffer(d["positions"], dtype=np.float64).reshape(n, 3),
        cell_sizes=np.frombuffer(d["cell_sizes"], dtype=np.float64),
        backface_ratio=np.frombuffer(d["backface_ratio"], dtype=np.float32),
        grid=np.frombuffer(d["grid"], dtype=np.int32),
        grid_dims=tuple(d["grid_dims"]), grid_origin=tuple(d["grid_origin"]),
        grid_spacing=d["grid_spacing"], leaf_count=d["leaf_count"], pruned_count=d["pruned_count"])


def classify_placement(volumes: Sequence[Mesh], geometry: Sequence[Mesh], points: Optional[np.ndarray] = None,
                       boxes: Optional[np.ndarray] = None, *, min_cell_size: float = 0.0,
                       max_cell_size: float = 0.0, threads: int = 0, solid_ray_count: int = 0,
                       solid_backface_ratio: float = 0.0) -> Tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Inside/solid/box classification with :func:`place_probes`' rules (Embree), for the corner
    octree: (inside (N,) bool, backface_ratio (N,) float32, box_class (M,) uint8) for engine-space
    ``points`` (N, 3) and ``boxes`` (M, 4) = centre x, y, z and half edge. box_class: 0 outside the
    volumes, 1 inside, 2 crossed by a volume surface. A probe with backface_ratio > the solid ratio
    (default 0.25) is inside solid geometry: give it validity 0 (it is then left out of the
    interpolation) — see docs/placement.md."""
    p = None if points is None else _vectors(points, "points")[0]
    b = None
    if boxes is not None:
        b = _array(boxes, "boxes", np.float64, _FLOAT_KINDS)
        if b.ndim != 2 or b.shape[1] != 4:
            raise _shape_error("boxes", "(M, 4)", b)
    inside, ratio, cls = _lib().placement_classify(
        _meshes(volumes, "volumes"), _meshes(geometry, "geometry"), p, b, float(min_cell_size),
        float(max_cell_size), int(threads), int(solid_ray_count), float(solid_backface_ratio))
    return (np.frombuffer(inside, dtype=np.uint8).astype(bool), np.frombuffer(ratio, dtype=np.float32),
            np.frombuffer(cls, dtype=np.uint8))


# ---- .shprobe, versions 1 to 3 (native/python/mod_shprobe.c) --------------------------------------

_IDENTITY_AXES = ((1.0, 0.0, 0.0), (0.0, 1.0, 0.0), (0.0, 0.0, 1.0))


# Version 3 interpolation structures, indexed by the file's structure field (PB_SHPROBE_GRID, _OCTREE,
# _TETRA in native/include/schnee/pb_shprobe.h): the names of ShProbeFile.structure and of the glTF
# entry's "structure" (gltf_export.py takes this tuple). The C reader's and the engine's tables
# (native/src/pb_shprobe.c, engine/ext/sv_ext.c) are compared with it by
# tests/python/test_structure_names.py.
STRUCTURES = ("grid", "octree", "tetrahedra")
# Structure 3 (version 4 only, docs/shprobe-format.md "Version 4"): the kd corner tree of boxes with
# per-axis levels. Not a glTF entry's structure name yet (the exporter's list above is version 3's).
_FILE_STRUCTURES = STRUCTURES + ("kdtree",)


@dataclass
class ShProbeFile:
    """Contents of a ``.shprobe`` file (DESIGN.md §4, docs/shprobe-format.md)."""
    version: int
    max_band: int
    coeffs: np.ndarray          # (P, sh_count(max_band), 3) float32
    probe_scale: np.ndarray     # (P,) float32
    probe_ambient: np.ndarray   # (P,) float32
    positions: Optional[np.ndarray]  # (P, 3) float32 or None (version 1)
    grid: np.ndarray            # (X*Y*Z,) int32
    grid_dims: Tuple[int, int, int]
    grid_origin: Tuple[float, float, float]
    grid_spacing: float
    default_sh_scale: float
    default_ambient: float
    # Version 2 additions (version 1 reads back these defaults):
    validity: Optional[np.ndarray] = None   # (P,) float32 in [0, 1]; None = all 1
    grid_axes: Tuple[Tuple[float, float, float], ...] = _IDENTITY_AXES  # rows: grid X, Y, Z axes
    # Version 3 additions (docs/shprobe-format.md; versions 1/2 read back SH, float32, grid). For an
    # octree or tetrahedra ``grid`` is None; ``coeffs`` holds 6 faces per probe for an ambient cube.
    representation: str = "sh"        # "sh" or "ambientCube"
    storage: str = "float32"          # "float32" or "float16" (in the file; arrays are float32)
    structure: str = "grid"           # "grid", "octree", "tetrahedra" or (version 4) "kdtree"
    leaves: Optional[np.ndarray] = None           # (N, 4) uint32 x, y, z, level (octree); kdtree: the
    #                                               4th word packs the levels lx | ly << 8 | lz << 16
    leaf_corners: Optional[np.ndarray] = None     # (N, 8) int32 node indices (octree)
    hanging_sources: Optional[np.ndarray] = None  # (H, 4) uint32 (octree)
    hanging_weights: Optional[np.ndarray] = None  # (H, 4) float32 (octree)
    tets: Optional[np.ndarray] = None             # (N, 4) uint32 (tetrahedra)
    tet_neighbours: Optional[np.ndarray] = None   # (N, 4) int32, −1 = none (tetrahedra)
    # Version 4 additions (structure "kdtree"): root level R and the split tree (K,) uint32.
    root_level: int = 0
    split_nodes: Optional[np.ndarray] = None

    @property
    def probe_count(self) -> int:
        return int(self.coeffs.shape[0])

    def lookup(self, points: np.ndarray) -> np.ndarray:
        """Probe index (int32) of the grid cell holding each engine-space point, −1 outside/empty.
        Cells are half-open: the min faces belong to a cell, the grid's max faces do not."""
        return shprobe_lookup(self, points)


def _opt_rows(buf, dtype, cols: int) -> Optional[np.ndarray]:
    return None if buf is None else np.frombuffer(buf, dtype=dtype).reshape(-1, cols)


def _shprobe_from_dict(d: dict) -> ShProbeFile:
    n, band = d["probe_count"], d["max_band"]
    positions = d["positions"]
    cube = d.get("representation", 0) == 1
    return ShProbeFile(
        version=d["version"], max_band=band,
        coeffs=np.frombuffer(d["coeffs"], dtype=np.float32).reshape(n, 6 if cube else sh_count(band), 3),
        probe_scale=np.frombuffer(d["probe_scale"], dtype=np.float32),
        probe_ambient=np.frombuffer(d["probe_ambient"], dtype=np.float32),
        positions=None if positions is None else np.frombuffer(positions, dtype=np.float32).reshape(n, 3),
        grid=None if d["grid"] is None else np.frombuffer(d["grid"], dtype=np.int32),
        grid_dims=tuple(d["grid_dims"]), grid_origin=tuple(d["grid_origin"]),
        grid_spacing=d["grid_spacing"], default_sh_scale=d["default_sh_scale"],
        default_ambient=d["default_ambient"],
        validity=np.frombuffer(d["validity"], dtype=np.float32),
        grid_axes=tuple(tuple(r) for r in d["grid_axes"]),
        representation="ambientCube" if cube else "sh",
        storage="float16" if d.get("storage", 0) == 1 else "float32",
        structure=_FILE_STRUCTURES[d.get("structure", 0)],
        root_level=d.get("root_level", 0),
        split_nodes=None if d.get("split_nodes") is None else np.frombuffer(d["split_nodes"], dtype=np.uint32),
        leaves=_opt_rows(d.get("leaves"), np.uint32, 4),
        leaf_corners=_opt_rows(d.get("leaf_corners"), np.int32, 8),
        hanging_sources=_opt_rows(d.get("hanging_sources"), np.uint32, 4),
        hanging_weights=_opt_rows(d.get("hanging_weights"), np.float32, 4),
        tets=_opt_rows(d.get("tets"), np.uint32, 4),
        tet_neighbours=_opt_rows(d.get("tet_neighbours"), np.int32, 4))


def _per_probe(x, name: str, n: int) -> Optional[np.ndarray]:
    if x is None:
        return None
    arr = _array(x, name, np.float32, _FLOAT_KINDS)
    if arr.shape != (n,):
        raise _shape_error(name, f"({n},)", arr)
    return arr


def write_shprobe(path: str, coeffs: np.ndarray, grid: np.ndarray, grid_dims: Sequence[int],
                  grid_origin: Sequence[float], grid_spacing: float, *, default_sh_scale: float = 1.0,
                  default_ambient: float = 0.1, positions: Optional[np.ndarray] = None,
                  probe_scale: Optional[np.ndarray] = None, probe_ambient: Optional[np.ndarray] = None,
                  version: int = 0, validity: Optional[np.ndarray] = None,
                  grid_axes: Optional[np.ndarray] = None) -> int:
    """Write a ``.shprobe`` atomically (temp file + rename). ``coeffs`` (P, sh_count, 3);
    version 0 = smallest that holds the data (1 for max_band <= 2 without positions). Returns the
    version written. ``grid`` is flat (X*Y*Z,) or shaped (Z, Y, X) (so the flat index is
    x + y*X + z*X*Y). Version 2 extras: ``validity`` (P,) in [0, 1] and ``grid_axes`` (3, 3),
    rows = the grid's X, Y, Z axes in engine space (orthonormal); None = all 1 / identity."""
    c = _array(coeffs, "coeffs", np.float32, _FLOAT_KINDS)
    if c.ndim != 3 or c.shape[2] != 3:
        raise _shape_error("coeffs", "(P, sh_count, 3)", c)
    band = _band_of(c.shape[1], "coeffs")
    n = c.shape[0]
    dims = tuple(int(v) for v in grid_dims)     # the C checks 3 entries, each 0..2**32-1
    g = _array(grid, "grid", np.int32, _INT_KINDS)
    if g.ndim != 1 and g.shape != dims[::-1]:    # a flat grid's length is the C's to check
        raise _shape_error("grid", f"({int(np.prod(dims))},) or (Z, Y, X) = {dims[::-1]}", g)
    origin = tuple(float(v) for v in grid_origin)
    pos = None
    if positions is not None:
        pos = _array(positions, "positions", np.float32, _FLOAT_KINDS)
        if pos.shape != (n, 3):
            raise _shape_error("positions", f"({n}, 3)", pos)
    axes = None
    if grid_axes is not None:
        axes = _array(grid_axes, "grid_axes", np.float32, _FLOAT_KINDS)
        if axes.shape != (3, 3):
            raise _shape_error("grid_axes", "(3, 3)", axes)
    return _lib().shprobe_write(
        path, c, band, g, dims, origin, float(grid_spacing),
        default_sh_scale=float(default_sh_scale), default_ambient=float(default_ambient),
        positions=pos, probe_scale=_per_probe(probe_scale, "probe_scale", n),
        probe_ambient=_per_probe(probe_ambient, "probe_ambient", n),
        validity=_per_probe(validity, "validity", n), grid_axes=axes, version=int(version))


def read_shprobe(path: str) -> ShProbeFile:
    """Read and validate a ``.shprobe`` (any version); SchneeError on malformed input."""
    return _shprobe_from_dict(_lib().shprobe_read(path))


class ShprobeRead:
    """:func:`read_shprobe` on a native thread that runs no Python (the overlay's background read:
    in Blender 3.4 a Python worker thread crashes the UI, docs/overlay.md). :meth:`poll` is None
    while the file is read, then the :class:`ShProbeFile` (or the SchneeError) on every call."""

    def __init__(self, path: str):
        self._job = _lib().shprobe_read_start(path)

    def poll(self) -> Optional[ShProbeFile]:
        d = _lib().shprobe_read_poll(self._job)
        return None if d is None else _shprobe_from_dict(d)


def read_shprobe_bytes(data: bytes) -> ShProbeFile:
    """Like :func:`read_shprobe` for the bytes of a file (any buffer)."""
    return _shprobe_from_dict(_lib().shprobe_read_memory(data))


def read_shprobe_header(path: str) -> dict:
    """Header fields only (version, probe_count, max_band, grid_dims, grid_origin, grid_spacing,
    default_sh_scale, default_ambient, grid_axes), validated against the file size."""
    return _lib().shprobe_read_header(path)


def shprobe_lookup(probes: ShProbeFile, points: np.ndarray) -> np.ndarray:
    """Probe index per engine-space point (N, 3) -> (N,) int32 (−1 outside or empty), through the
    same C lookup the engine uses; a single point (3,) gives a 0-d array."""
    p, single = _vectors(points, "points", np.float32)
    axes = np.ascontiguousarray(probes.grid_axes, dtype=np.float32)
    raw = _lib().shprobe_lookup(np.ascontiguousarray(probes.grid, dtype=np.int32),
                                tuple(probes.grid_dims), tuple(probes.grid_origin),
                                float(probes.grid_spacing), probes.probe_count, p, grid_axes=axes)
    out = np.frombuffer(raw, dtype=np.int32)
    return out.reshape(()) if single else out


_REPRESENTATIONS = {"sh": 0, "ambientCube": 1}
_STORAGES = {"float32": 0, "float16": 1}


def write_shprobe_v3(path: str, structure: _Interpolation, coeffs: np.ndarray, *, representation: str = "sh",
                     storage: str = "float32", probe_scale=None, probe_ambient=None, validity=None,
                     default_sh_scale: float = 1.0, default_ambient: float = 0.1) -> int:
    """Write a version 3 ``.shprobe`` of a finalized :class:`CornerOctree` or a :class:`Tetrahedra`
    (positions from the structure); a tree with a box that is not a cube is written as version 4 (the
    kd corner tree, docs/shprobe-format.md "Version 4"). ``coeffs`` (P, sh_count, 3) for SH, (P, 6, 3) for an ambient
    cube (its header's max band is then 2, informational). Returns the probe count."""
    rep = _choice(representation, _REPRESENTATIONS, "representation")
    sto = _choice(storage, _STORAGES, "storage")
    c = _array(coeffs, "coeffs", np.float32, _FLOAT_KINDS)
    if c.ndim != 3 or c.shape[2] != 3:
        raise _shape_error("coeffs", "(P, colours, 3)", c)
    if rep == 1 and c.shape[1] != 6:
        raise _shape_error("coeffs", "(P, 6, 3) for an ambient cube", c)
    band = 2 if rep == 1 else _band_of(c.shape[1], "coeffs")
    n = c.shape[0]
    return _lib().shprobe_write_v3(path, structure._handle, c.reshape(-1), rep, band, sto,
                                   probe_scale=_per_probe(probe_scale, "probe_scale", n),
                                   probe_ambient=_per_probe(probe_ambient, "probe_ambient", n),
                                   validity=_per_probe(validity, "validity", n),
                                   default_sh_scale=float(default_sh_scale),
                                   default_ambient=float(default_ambient))


def resample_shprobe_dense(path: str, spacing: float = 0.0) -> ShProbeFile:
    """A version 3 or 4 SH file's field resampled onto a dense grid (each covered cell = one probe with
    the value interpolated at its centre); write it with :func:`write_shprobe` (version 1 for L <= 2).
    ``spacing`` 0 = the octree's min cell (required for tetrahedra)."""
    return _shprobe_from_dict(_lib().shprobe_resample_dense(path, float(spacing)))


# ---- interpolation on probe positions, error-driven refinement (issue 12, native/python/mod_interp.c)
#
# docs/placement.md ("Interpolation", "Error-driven refinement") and docs/shprobe-format.md
# ("Version 3"). A bake drives the refinement pass by pass (bench/bench_interp.py does it on
# synthetic fields):
#
#     tree = CornerOctree.uniform(origin, min_cell, root_level, root_dims)  # Max Cell Size leaves
#     tree.drop(outside); tree.finalize()                                    # leaves outside volumes
#     values = bake(tree.positions())                                        # (P, C, 3) radiance SH
#     while True:
#         tests = tree.refine_tests()                    # centre + face centres (lattice points)
#         test_values = bake(tests.positions)            # rows with tests.probe >= 0 are not read
#         split, err, thr = tree.refine_decide(tests, values, test_values, probe_noise=..., ...)
#         if not split.any(): break
#         tree.split(split); tree.finalize()             # test points become probes
#         values = old values by lattice point (tree.probe_lattice()); bake the new edge midpoints
#     write_shprobe_v3(path, tree, values, ...)


@dataclass
class RefineTests:
    """Test points of a corner octree's leaves (see :meth:`CornerOctree.refine_tests`)."""
    lattice: np.ndarray     # (T, 3) uint32 lattice coordinates (units of the min cell)
    positions: np.ndarray   # (T, 3) float64 engine space
    probe: np.ndarray       # (T,) int32: probe already at the point (no bake needed) or −1
    leaf_tests: np.ndarray  # (L, 7) int32: centre, −x, +x, −y, +y, −z, +z test indices; −1 = none


class _Interpolation:
    _handle = None

    def query(self, points: np.ndarray, validity: Optional[np.ndarray] = None,
              pair_visibility: Optional[np.ndarray] = None) -> Tuple[np.ndarray, np.ndarray]:
        """Weights of the probes at engine-space points (N, 3): (probes (N, K) int32, weights (N, K)
        float64); unused slots are −1 / 0, weights >= 0 sum to 1 (a row of −1 = outside).
        ``validity`` (P,): probes with validity <= 0 are dropped and the rest renormalised.
        ``pair_visibility`` (corner octrees): (leaf_count, 8, 8) uint8, [leaf, k, c] = round(255 t)
        with t the fraction of the segment from corner c towards corner k before its first surface
        (255 = clear): the continuous visibility field of pb_interp.h / docs/placement.md."""
        p, _ = _vectors(points, "points")
        val = None if validity is None else _array(validity, "validity", np.float32, _FLOAT_KINDS)
        # uint8 as it is (no conversion of other dtypes: the C refuses them, naming the format)
        pv = None if pair_visibility is None else np.ascontiguousarray(pair_visibility).reshape(-1)
        pr, wt, k = _lib().interp_query(self._handle, p, val, pv)
        return (np.frombuffer(pr, dtype=np.int32).reshape(-1, k),
                np.frombuffer(wt, dtype=np.float64).reshape(-1, k))

    def interpolate(self, points: np.ndarray, values: np.ndarray,
                    validity: Optional[np.ndarray] = None,
                    pair_visibility: Optional[np.ndarray] = None) -> np.ndarray:
        """Per-probe values (P, ...) interpolated at the points -> (N, ...); NaN outside."""
        probes, weights = self.query(points, validity, pair_visibility)
        v = np.asarray(values, dtype=np.float64)
        out = np.einsum("nk,nk...->n...", weights, v[np.maximum(probes, 0)])
        out[probes[:, 0] < 0] = np.nan
        return out


class CornerOctree(_Interpolation):
    """Probes at the corners of octree leaves, trilinear inside each leaf, hanging corners taken from
    the larger neighbour's face/edge (C0 everywhere). Lattice units = the min cell size. Leaves may be
    boxes with per-axis levels (docs/aniso-refinement.md): :meth:`from_boxes`, :meth:`split_axes`."""

    def __init__(self, handle):
        self._handle = handle

    @classmethod
    def uniform(cls, origin: Sequence[float], min_cell: float, root_level: int,
                root_dims: Sequence[int]) -> "CornerOctree":
        """root_dims leaves of 2**root_level min cells per axis, min corner at ``origin``."""
        return cls(_lib().cotree_create(tuple(float(v) for v in origin), float(min_cell), int(root_level),
                                        tuple(int(v) for v in root_dims)))

    @classmethod
    def from_leaves(cls, origin: Sequence[float], min_cell: float, dims: Sequence[int],
                    leaves: np.ndarray) -> "CornerOctree":
        """A tree from (N, 4) leaves (x, y, z lattice min corner, level); finalize it."""
        lv = _array(leaves, "leaves", np.uint32, _INT_KINDS).reshape(-1)
        return cls(_lib().cotree_from_leaves(tuple(float(v) for v in origin), float(min_cell),
                                             tuple(int(v) for v in dims), lv))

    @classmethod
    def from_boxes(cls, origin: Sequence[float], min_cell: float, root_level: int, dims: Sequence[int],
                   leaves: np.ndarray) -> "CornerOctree":
        """A tree from (N, 4) boxes: x, y, z lattice min corner, levels packed as
        :func:`pack_levels` (lx | ly << 8 | lz << 16), each <= root_level (Max Cell Size = 2**root_level
        min cells). Aligned per axis, inside ``dims``, no overlap; finalize it (the nesting rule may
        split leaves: :attr:`forced_splits`)."""
        lv = _array(leaves, "leaves", np.uint32, _INT_KINDS).reshape(-1)
        return cls(_lib().cotree_from_boxes(tuple(float(v) for v in origin), float(min_cell), int(root_level),
                                            tuple(int(v) for v in dims), lv))

    def _flags(self, flags, name: str) -> np.ndarray:
        f = np.ascontiguousarray(np.asarray(flags).astype(bool), dtype=np.uint8)
        if f.shape != (self.leaf_count,):
            raise _shape_error(name, f"({self.leaf_count},)", f)
        return f

    def split(self, flags) -> int:
        """Split the flagged leaves (level > 0) into 8; returns how many. Finalize afterwards."""
        return _lib().cotree_split(self._handle, self._flags(flags, "flags"))

    def split_axes(self, masks) -> int:
        """Halve every leaf along the axes of its mask (L,) (bit 0 = x, 1 = y, 2 = z; axes at level 0
        ignored): 2**|axes| children. Returns the leaves split. Finalize afterwards."""
        m = np.asarray(masks)
        if m.shape != (self.leaf_count,):
            raise _shape_error("masks", f"({self.leaf_count},)", m)
        if m.dtype.kind not in "iub" or (m.size and (int(m.min()) < 0 or int(m.max()) > 7)):
            raise ValueError("masks must be integers 0..7 (bit 0 = x, 1 = y, 2 = z)")
        return _lib().cotree_split_axes(self._handle, np.ascontiguousarray(m, dtype=np.uint8))

    def drop(self, flags) -> None:
        """Remove the flagged leaves (e.g. outside the volumes). Finalize afterwards."""
        _lib().cotree_drop(self._handle, self._flags(flags, "flags"))

    def finalize(self) -> None:
        """Number the probes (corner nodes that do not hang) and build the hanging rules."""
        _lib().cotree_finalize(self._handle)

    def info(self) -> dict:
        """origin, min_cell, dims, root_level, forced_splits, leaves (L, 4) (x, y, z, largest level),
        levels (L, 3) (lx, ly, lz); after finalize also probe_count, probe_lattice (P, 3), positions
        (P, 3), leaf_corners (L, 8), hanging_count, hanging_sources/weights (H, 4)."""
        d = _lib().cotree_info(self._handle)
        out = dict(d)
        out["leaves"] = np.frombuffer(d["leaves"], dtype=np.uint32).reshape(-1, 4)
        out["levels"] = np.frombuffer(d["levels"], dtype=np.uint32).reshape(-1, 3)
        if d["finalized"]:
            out["probe_lattice"] = np.frombuffer(d["probe_lattice"], dtype=np.uint32).reshape(-1, 3)
            out["positions"] = np.frombuffer(d["positions"], dtype=np.float64).reshape(-1, 3)
            out["leaf_corners"] = np.frombuffer(d["leaf_corners"], dtype=np.int32).reshape(-1, 8)
            out["hanging_sources"] = np.frombuffer(d["hanging_sources"], dtype=np.uint32).reshape(-1, 4)
            out["hanging_weights"] = np.frombuffer(d["hanging_weights"], dtype=np.float32).reshape(-1, 4)
        return out

    @property
    def leaf_count(self) -> int:
        return int(len(_lib().cotree_info(self._handle)["leaves"]) // 16)

    @property
    def probe_count(self) -> int:
        return int(_lib().cotree_info(self._handle)["probe_count"])

    @property
    def forced_splits(self) -> int:
        """Leaves the last finalize split to keep the nesting rule (0 for trees of cubes)."""
        return int(_lib().cotree_info(self._handle)["forced_splits"])

    def split_tree(self) -> np.ndarray:
        """The canonical split tree (K,) uint32 (pb_cotree.h, docs/aniso-refinement.md "Point
        location"): nodes 0..G-1 the root cells (x fastest); bits 0-1: 0 leaf, 1/2/3 split along x/y/z;
        bits 2-31: leaf index (2**30 - 1 = empty) or the lower child (upper = lower + 1)."""
        return np.frombuffer(_lib().cotree_split_tree(self._handle), dtype=np.uint32)

    def locate(self, points: np.ndarray) -> np.ndarray:
        """The leaf holding each engine-space point (N, 3) -> (N,) int32, -1 = none."""
        p, _ = _vectors(points, "points")
        return np.frombuffer(_lib().cotree_locate(self._handle, p), dtype=np.int32)

    def positions(self) -> np.ndarray:
        """(P, 3) float64 probe positions (after finalize)."""
        return self.info()["positions"]

    def probe_lattice(self) -> np.ndarray:
        """(P, 3) uint32 lattice points of the probes (after finalize): keys to carry values over."""
        return self.info()["probe_lattice"]

    def refine_tests(self, active=None) -> RefineTests:
        """Test points (centre, face centres) of every leaf above Min Cell Size, or of the ``active``
        ones (L,) bool."""
        a = None if active is None else self._flags(active, "active")
        d = _lib().refine_tests(self._handle, a)
        return RefineTests(lattice=np.frombuffer(d["lattice"], dtype=np.uint32).reshape(-1, 3),
                           positions=np.frombuffer(d["positions"], dtype=np.float64).reshape(-1, 3),
                           probe=np.frombuffer(d["probe"], dtype=np.int32),
                           leaf_tests=np.frombuffer(d["leaf_tests"], dtype=np.int32).reshape(-1, 7))

    def refine_decide(self, tests: RefineTests, probe_coeffs: np.ndarray, test_coeffs: np.ndarray, *,
                      probe_noise=None, test_noise=None, probe_validity=None, test_valid=None,
                      tolerance: float = 0.0,
                      noise_k: float = 0.0) -> Tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Which leaves split: (split (L,) bool, error (L,), threshold (L,)). ``probe_coeffs``
        (P, C, 3) and ``test_coeffs`` (T, C, 3) radiance SH (rows of tests that are probes are not
        read); noise: relative RMS irradiance noise per probe / test; tolerance 0 = 0.05, noise_k 0 = 2."""
        pc = _array(probe_coeffs, "probe_coeffs", np.float64, _FLOAT_KINDS)
        tc = _array(test_coeffs, "test_coeffs", np.float64, _FLOAT_KINDS)
        if pc.ndim != 3 or pc.shape[2] != 3:
            raise _shape_error("probe_coeffs", "(P, sh_count, 3)", pc)
        band = _band_of(pc.shape[1], "probe_coeffs")
        n_tests = tests.positions.shape[0]
        if tc.shape != (n_tests, pc.shape[1], 3):
            raise _shape_error("test_coeffs", f"({n_tests}, {pc.shape[1]}, 3)", tc)

        def opt(x, name):
            return None if x is None else _array(x, name, np.float32, _FLOAT_KINDS)

        tv = None if test_valid is None else np.ascontiguousarray(np.asarray(test_valid).astype(bool),
                                                                   dtype=np.uint8)
        split, err, thr = _lib().refine_decide(
            self._handle, np.ascontiguousarray(tests.leaf_tests, dtype=np.int32),
            np.ascontiguousarray(tests.positions, dtype=np.float64),
            np.ascontiguousarray(tests.probe, dtype=np.int32), band, pc, tc,
            probe_noise=opt(probe_noise, "probe_noise"), test_noise=opt(test_noise, "test_noise"),
            probe_validity=opt(probe_validity, "probe_validity"), test_valid=tv,
            tolerance=float(tolerance), noise_k=float(noise_k))
        return (np.frombuffer(split, dtype=np.uint8).astype(bool), np.frombuffer(err, dtype=np.float64),
                np.frombuffer(thr, dtype=np.float64))


def refine_error(a: np.ndarray, ref: np.ndarray) -> np.ndarray:
    """The refinement's metric (pb_refine_irradiance_error) of radiance SH ``a`` against ``ref``, both
    (..., sh_count, 3) of one shape: an array of shape (...) (0-d for one point). metric.py's
    irradiance_error is the add-on's entry point."""
    av = _array(a, "a", np.float64, _FLOAT_KINDS)
    rv = _array(ref, "ref", np.float64, _FLOAT_KINDS)
    if av.ndim < 2 or av.shape[-1] != 3:
        raise _shape_error("a", "(..., sh_count, 3)", av)
    if rv.shape != av.shape:
        raise _shape_error("ref", str(av.shape), rv)
    raw = _lib().refine_error(av, rv, _band_of(av.shape[-2], "a"))
    return np.frombuffer(raw, dtype=np.float64).reshape(av.shape[:-2])


def refine_norm(c: np.ndarray) -> np.ndarray:
    """‖A·c‖ of radiance SH ``c`` (..., sh_count, 3), summed as the metric sums (shape (...); a
    float64 scalar for one point)."""
    cv = _array(c, "c", np.float64, _FLOAT_KINDS)
    if cv.ndim < 2 or cv.shape[-1] != 3:
        raise _shape_error("c", "(..., sh_count, 3)", cv)
    raw = _lib().refine_norm(cv, _band_of(cv.shape[-2], "c"))
    return np.frombuffer(raw, dtype=np.float64).reshape(cv.shape[:-2])[()]


class Tetrahedra(_Interpolation):
    """Delaunay tetrahedralisation of probe positions (qhull), barycentric inside each tetrahedron."""

    def __init__(self, handle):
        self._handle = handle

    @classmethod
    def create(cls, positions: np.ndarray) -> "Tetrahedra":
        p, _ = _vectors(positions, "positions")
        return cls(_lib().tetra_create(p))

    def info(self) -> dict:
        """tets (N, 4) uint32 probe indices, neighbours (N, 4) int32 (opposite vertex i, −1 = hull)."""
        d = _lib().tetra_info(self._handle)
        return {"tets": np.frombuffer(d["tets"], dtype=np.uint32).reshape(-1, 4),
                "neighbours": np.frombuffer(d["neighbours"], dtype=np.int32).reshape(-1, 4)}


def pack_levels(levels: np.ndarray) -> np.ndarray:
    """Per-axis levels (..., 3) -> the packed word lx | ly << 8 | lz << 16 (PB_LEVELS_PACK), uint32."""
    lv = np.asarray(levels).astype(np.uint32)
    return lv[..., 0] | lv[..., 1] << np.uint32(8) | lv[..., 2] << np.uint32(16)


def interpolation_from_file(path: str) -> _Interpolation:
    """The interpolation structure of a version 3 file, with the file's own probe numbering."""
    h = _lib().interp_from_file(path)
    return CornerOctree(h) if "cotree" in repr(h) else Tetrahedra(h)


# ---- direct light (issue 11, docs/direct-light.md; native/python/mod_direct.c) --------------------

LIGHT_TYPES = {"SUN": 0, "POINT": 1, "SPOT": 2, "AREA_RECT": 3, "AREA_ELLIPSE": 4}
LIGHT_RECORD = 20  # float64 per lamp: type, position[3], direction[3], axis_u[3], rgb[3], radius,
#                    size_u, size_v, spot_size, spot_blend, legacy_point, spot_cosine


@dataclass
class Lamp:
    """One lamp for :func:`direct_project`, engine space, Blender/Cycles units.

    ``kind``: SUN, POINT, SPOT, AREA_RECT (square/rectangle) or AREA_ELLIPSE (disk/ellipse).
    ``color``: colour × strength (sun W/m², others W). ``direction``: where the lamp emits (its
    local −Z; for a sun the direction its light travels). ``radius``: point/spot radius (m), sun
    angular diameter ``angle`` (rad). ``legacy_point``: point/spot drawn as a disc facing the
    viewer (Cycles ≤ 3.6; 4.0+ with Soft Falloff on), else a sphere. ``spot_cosine``: the spot cone
    also × cos γ (Cycles ≤ 3.6)."""
    kind: str
    color: Tuple[float, float, float]
    position: Tuple[float, float, float] = (0.0, 0.0, 0.0)
    direction: Tuple[float, float, float] = (0.0, -1.0, 0.0)
    axis_u: Tuple[float, float, float] = (1.0, 0.0, 0.0)
    radius: float = 0.0
    size_u: float = 0.0
    size_v: float = 0.0
    spot_size: float = 0.0
    spot_blend: float = 0.0
    legacy_point: bool = True
    spot_cosine: bool = True

    def record(self) -> list:
        return ([float(_choice(self.kind, LIGHT_TYPES, "kind"))] + [float(x) for x in self.position]
                + [float(x) for x in self.direction] + [float(x) for x in self.axis_u]
                + [float(x) for x in self.color]
                + [float(self.radius), float(self.size_u), float(self.size_v), float(self.spot_size),
                   float(self.spot_blend), 1.0 if self.legacy_point else 0.0,
                   1.0 if self.spot_cosine else 0.0])


def direct_project(lamps: Sequence[Lamp], probes: np.ndarray, max_band: int = 2, samples: int = 0,
                   geometry: Optional[Sequence[Mesh]] = None, ray_offset: float = 0.0) -> np.ndarray:
    """Radiance projection of the lamps' direct light at each probe (engine space), shadowed by
    ``geometry`` (opaque triangles; None = nothing occludes). ``samples``: quadrature cells and
    shadow rays per lamp (0 = 256). Returns (P, sh_count, 3) float64. GIL released."""
    p, _ = _vectors(probes, "probes")
    rec = np.ascontiguousarray(np.array([lamp.record() for lamp in lamps], dtype=np.float64).reshape(-1))
    geo = None if geometry is None else _meshes(geometry, "geometry")
    out = _lib().direct_project(rec, p, max_band, int(samples), geo, float(ray_offset))
    return np.frombuffer(out, dtype=np.float64).reshape(len(p), sh_count(int(max_band)), 3)


def sky_table(world: np.ndarray, pano_width: int, pano_height: int, max_band: int = 2,
              rotation: Optional[np.ndarray] = None) -> np.ndarray:
    """Per panorama cell (canonical mapping, row 0 at the top) the exact projection of the world
    texels whose centres fall into it: ``world`` (H, W, C>=3) float32 equirect, same mapping, any
    resolution. Returns (pano_height, pano_width, sh_count, 3) float64; the sum over all cells is
    the world's projection (project_equirect)."""
    arr = _array(world, "world", np.float32, _FLOAT_KINDS)
    if arr.ndim != 3 or arr.shape[2] < 3:
        raise _shape_error("world", "(H, W, C>=3)", arr)
    rot = _rotation(rotation)
    out = _lib().sky_table(arr, arr.shape[1], arr.shape[0], arr.shape[2], int(pano_width), int(pano_height),
                           max_band, rot)
    return np.frombuffer(out, dtype=np.float64).reshape(int(pano_height), int(pano_width), sh_count(int(max_band)), 3)


# ---- the sky's sun (issue 27, docs/direct-light.md "The sky's sun"; native/python/mod_direct.c) ---

@dataclass
class SkySun:
    """The sun split off a sky image (native/include/schnee/pb_sky_sun.h). ``direction``: unit,
    engine space, the way its light travels; ``irradiance``: RGB W/m² at normal incidence (the
    image's radiance units × sr); ``angle``: angular diameter (rad); ``share``: its part of the
    image's luminance flux; ``background``: the sky level its texels keep; ``extent``: how far (rad)
    its bright region reached from the peak texel ``peak`` (column, row); ``texels``: texels changed."""
    direction: Tuple[float, float, float]
    irradiance: Tuple[float, float, float]
    angle: float
    share: float
    background: Tuple[float, float, float]
    extent: float
    peak: Tuple[int, int]
    texels: int

    def lamp(self) -> Lamp:
        """The Cycles Sun lamp carrying the same light (what the engine and the bake's direct
        light model it as: strength = irradiance, angle = angular diameter)."""
        return Lamp("SUN", tuple(self.irradiance), direction=tuple(self.direction), radius=float(self.angle))


@dataclass
class SkySplit:
    """:func:`sky_sun_split`'s answer: ``sun`` (None when the image has none), ``rest`` (the image
    without it, (H, W, C) float32, the image itself when there is no sun) and ``verdict``
    ("found", "black", "wide": no compact bright region, "faint": below the least share)."""
    sun: Optional[SkySun]
    rest: np.ndarray
    verdict: str


def sky_sun_split(world: np.ndarray, peak_fraction: float = 0.0, max_radius: float = 0.0,
                  min_share: float = 0.0) -> SkySplit:
    """Split an equirect world image (H, W, C>=3) linear radiance, rows top-down, the texel
    directions of :func:`sky_table`, into its sun and the rest: sun + rest = the image exactly
    (docs/direct-light.md "The sky's sun": the criteria and their defaults, 0 = default:
    ``peak_fraction`` 0.01, ``max_radius`` 5° in rad, ``min_share`` 0.01). Texels must be finite and
    >= 0 (SchneeError otherwise). GIL released."""
    arr = _array(world, "world", np.float32, _FLOAT_KINDS)
    if arr.ndim != 3 or arr.shape[2] < 3:
        raise _shape_error("world", "(H, W, C>=3)", arr)
    info, rest = _lib().sky_sun_split(arr, arr.shape[1], arr.shape[0], arr.shape[2], float(peak_fraction),
                                      float(max_radius), float(min_share))
    rest = np.frombuffer(rest, dtype=np.float32).reshape(arr.shape)
    sun = None
    if info["found"]:
        sun = SkySun(direction=tuple(info["direction"]), irradiance=tuple(info["irradiance"]),
                     angle=float(info["angle"]), share=float(info["share"]),
                     background=tuple(info["background"]), extent=float(info["extent"]),
                     peak=tuple(int(v) for v in info["peak"]), texels=int(info["texels"]))
    return SkySplit(sun=sun, rest=rest, verdict=str(info["verdict"]))


# ---- probe bricks (issue 30, docs/probe-bricks.md; native/python/mod_bricks.c) ----------------------
#
#     bricks = Bricks.build(tree, coeffs, validity, scale)   # tree: a finalized CornerOctree
#     coeffs, has_value = bricks.sample(points)              # the field the engine is to shade with


def _triangles(triangles):
    if triangles is None:
        return None
    t = np.ascontiguousarray(triangles, dtype=np.float64)
    if t.size % 9 or t.ndim < 2 or not np.isfinite(t).all():
        raise ValueError(f"triangles must be finite (T, 3, 3), got shape {t.shape}")
    return t.reshape(-1)


class Bricks:
    """A corner octree's / kd corner tree's field resampled into bricks of 5^3 texels with an
    indirection grid (native/include/schnee/pb_bricks.h): texels N = sum W m s c and D = sum W m from
    the core's interpolation weights, sampled with exact trilinear weights as N / D. The C definition
    the engine's GLSL is to mirror; independent of the tree once built."""

    def __init__(self, handle):
        self._handle = handle
        self._raw = _lib().bricks_info(handle)  # immutable once built: sizes and array copies, read once

    STATIC = 1  # PB_BRICKS_STATIC: a static surface of the bake (back-face weights)
    EIGHT_TAP = 2  # PB_BRICKS_8TAP: 8 texel fetches with exact weights (else one filtered tap)

    @classmethod
    def build(cls, tree: CornerOctree, coeffs: np.ndarray, validity: Optional[np.ndarray] = None,
              scale: Optional[np.ndarray] = None, max_bytes: int = 0,
              planes: Optional[np.ndarray] = None, triangles: Optional[np.ndarray] = None) -> "Bricks":
        """``coeffs`` (P, sh_count, 3) radiance SH per probe of the finalized ``tree`` (float64 in the
        C), ``validity`` (P,) (<= 0: the probe is dropped, as the file's rule), ``scale`` (P,) (the
        file's probe_scale, inside N). ``max_bytes``: the build's memory cap, 0 = 1 GiB (SchneeError
        past it). ``planes`` (K, 4) (nx, ny, nz, d: the plane n.p = d, engine space): the static scene
        as infinite planes, for the build with visibility (leaf tables, visibility texels, brick table
        and records, docs/probe-bricks.md "Back faces and visibility"); None = without. ``triangles``
        (T, 3, 3) (engine space, both sides, hits within [1e-4, 1 - 1e-4] of a segment as the engine's
        tracer): the static scene as triangles, alone or with ``planes``."""
        if not isinstance(tree, CornerOctree):
            raise TypeError(f"tree must be a CornerOctree, got {type(tree).__name__}")
        P = tree.probe_count
        c = _array(coeffs, "coeffs", np.float64, _FLOAT_KINDS)
        if c.ndim != 3 or c.shape[0] != P or c.shape[2] != 3:
            raise _shape_error("coeffs", f"({P}, sh_count, 3)", c)
        _band_of(c.shape[1], "coeffs")
        pl = None
        if planes is not None:
            pl = np.ascontiguousarray(planes, dtype=np.float64)
            if pl.ndim != 2 or pl.shape[1] != 4 or not np.isfinite(pl).all():
                raise ValueError(f"planes must be finite (K, 4) (nx, ny, nz, d), got shape {pl.shape}")
            pl = pl.reshape(-1)
        return cls(_lib().bricks_build(tree._handle, c.reshape(-1), c.shape[1], _per_probe(validity, "validity", P),
                                       _per_probe(scale, "scale", P), int(max_bytes), pl, _triangles(triangles)))

    @staticmethod
    def leaf_tables(tree: CornerOctree, planes: Optional[np.ndarray] = None,
                    triangles: Optional[np.ndarray] = None) -> np.ndarray:
        """The leaves' pair-visibility tables (pb_cotree_pair_visibility) through the test scene of
        ``build`` (planes and / or triangles): (leaf_count, 8, 8) uint8, for ``tree.query``'s
        ``pair_visibility`` (today's rule of the storage-buffer path)."""
        if not isinstance(tree, CornerOctree):
            raise TypeError(f"tree must be a CornerOctree, got {type(tree).__name__}")
        pl = None if planes is None else np.ascontiguousarray(planes, dtype=np.float64).reshape(-1)
        out = _lib().bricks_leaf_tables(tree._handle, pl, _triangles(triangles))
        return np.frombuffer(out, dtype=np.uint8).reshape(-1, 8, 8)

    def info(self) -> dict:
        """Sizes (pb_bricks_info): dims, root_level, coeff_count, channels (3C + 1), groups (RGBA
        textures), brick_count, level_counts {level: bricks}, pool_bricks, pool_texels,
        indirection_dims, texel_count, the bytes (indirection, pool_bytes_f16 / _f32,
        bytes_per_texel_f16, bytes_per_probe_f16 given ``probe_count``), blocked_leaves, traced_cells,
        vis_record_count, table_bytes, vis_record_bytes; arrays regions (n, 4) (region min x, y, z,
        level), indirection (ind_z, ind_y, ind_x, 4) uint32, texels (n, 5, 5, 5, channels) float64
        indexed [brick, k (z), j (y), i (x)], table (n, 4) uint32 (first record, blocked-cell bits 0-31,
        32-63, 0), vis_records (records, 8, 8) uint8 [record, k, c]."""
        d = dict(self._raw)
        d["level_counts"] = {L: int(n) for L, n in enumerate(d["level_counts"]) if n}
        n, ch = d["brick_count"], d["channels"]
        d["regions"] = np.frombuffer(d["regions"], dtype=np.uint32).reshape(n, 4)
        d["indirection"] = np.frombuffer(d["indirection"], dtype=np.uint32).reshape(
            tuple(reversed(d["indirection_dims"])) + (4,))
        d["texels"] = np.frombuffer(d["texels"], dtype=np.float64).reshape(n, 5, 5, 5, ch)
        d["table"] = np.frombuffer(d["table"], dtype=np.uint32).reshape(n, 4)
        d["vis_records"] = np.frombuffer(d["vis_records"], dtype=np.uint8).reshape(-1, 8, 8)
        d["bytes_per_texel_f16"] = 8 * d["groups"]
        return d

    def bytes_per_probe(self, probe_count: int, half: bool = True) -> float:
        """GPU bytes per probe of the file: the pool's used texels (8 B per RGBA16F texel and group, 16
        for RGBA32F), the indirection, and 16 B per brick for the brick table (visibility records not
        counted), over ``probe_count``."""
        d = self._raw
        texel = d["groups"] * (8 if half else 16)
        return (d["texel_count"] * texel + d["indirection_bytes"] + 16 * d["brick_count"]) / probe_count

    def sample(self, points: np.ndarray, subtexel_bits: int = 0) -> Tuple[np.ndarray, np.ndarray]:
        """The field at engine-space points (N, 3): (coeffs (N, C, 3) = N / D, NaN without a value;
        has_value (N,) bool). Within 0.01 min cells outside the lattice's box a point takes the face's
        value (the sampling rule's margin), where the CPU query has none. ``subtexel_bits`` > 0: the
        filter's fractions rounded to 2**-bits (8 on desktop GPUs); 0 = exact."""
        c, _, has, _, _ = self.sample_raw(points, subtexel_bits)
        c = c.copy()
        c[~has] = np.nan
        return c, has

    def sample_raw(self, points: np.ndarray, subtexel_bits: int = 0):
        """(coeffs (N, C, 3) (0 without a value), D (N,), has_value (N,) bool, brick (N,) int32 (-1 none),
        x (N, 3) brick-local texel coordinates in [0, 4]) at engine-space points (N, 3)."""
        p, _ = _vectors(points, "points")
        co, d, has, br, x = _lib().bricks_sample(self._handle, p, int(subtexel_bits))
        C = self._raw["coeff_count"]
        return (np.frombuffer(co, dtype=np.float64).reshape(-1, C, 3), np.frombuffer(d, dtype=np.float64),
                np.frombuffer(has, dtype=np.uint8).astype(bool), np.frombuffer(br, dtype=np.int32),
                np.frombuffer(x, dtype=np.float64).reshape(-1, 3))

    def sample_surface(self, points: np.ndarray, normals: Optional[np.ndarray] = None,
                       surface: Optional[np.ndarray] = None, static: bool = False, eight_tap: bool = False,
                       subtexel_bits: int = 0) -> Tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Step 5 of the sampling rule (pb_bricks_sample_surface) at engine-space ``points`` (N, 3) (the
        lookup point): (coeffs (N, C, 3) = N / D, NaN without a value; D (N,); has_value (N,) bool).
        ``static``: back-face weights against ``normals`` (N, 3) at ``surface`` (N, 3; None = points);
        the visibility record of a blocked brick cell applies on every object. ``eight_tap``: 8 texel
        fetches with the weights exact, else one filtered tap at the weights' per-axis mean with the
        fractions rounded to 2**-subtexel_bits (0 = exact). SchneeError names a refused point (non-finite
        or zero normal)."""
        p, _ = _vectors(points, "points")
        n = len(p)
        nv = None if normals is None else _vectors(normals, "normals")[0]
        sv = None if surface is None else _vectors(surface, "surface")[0]
        for name, v in (("normals", nv), ("surface", sv)):
            if v is not None and v.size != 3 * n:
                raise ValueError(f"{name} must be ({n}, 3) like points, got {v.size // 3} rows")
        flags = (self.STATIC if static else 0) | (self.EIGHT_TAP if eight_tap else 0)
        co, d, has = _lib().bricks_sample_surface(self._handle, p, sv, nv, flags, int(subtexel_bits))
        C = self._raw["coeff_count"]
        c = np.frombuffer(co, dtype=np.float64).reshape(-1, C, 3).copy()
        has = np.frombuffer(has, dtype=np.uint8).astype(bool)
        c[~has] = np.nan
        return c, np.frombuffer(d, dtype=np.float64), has

    def pool(self, half: bool = True) -> np.ndarray:
        """The channel textures (groups, pz, py, px, 4): float16 (SchneeError when a value exceeds
        65504: upload float32) or float32."""
        d = self._raw
        px, py, pz = d["pool_texels"]
        raw = _lib().bricks_pool(self._handle, bool(half))
        return np.frombuffer(raw, dtype=np.float16 if half else np.float32).reshape(d["groups"], pz, py, px, 4)


# ---- dense grid field (pb_grid_field.h, docs/grid-field.md) ----------------------------------------

GRID_FIELD_STATUS = ("outside", "none", "weights", "fallback")


class GridField:
    """The dense probe grid's field (native/include/schnee/pb_grid_field.h): the one definition of
    shading.glsl's grid_irradiance (trilinear between cell centres with clamped indices, validity,
    optional back faces and home-cell neighbour masks, empty cells, renormalisation, home-cell
    fallback, the 0.01-cell margin, rotated axes) and its cell-centred texture form (N = v s c, D = v)."""

    def __init__(self, handle):
        self._handle = handle
        self._raw = _lib().grid_field_info(handle)

    @classmethod
    def build(cls, cells: np.ndarray, origin, spacing: float, coeffs: np.ndarray, axes=None,
              validity: Optional[np.ndarray] = None, scale: Optional[np.ndarray] = None,
              masks: Optional[np.ndarray] = None, max_bytes: int = 0) -> "GridField":
        """``cells`` int (Z, Y, X) of probe indices or -1 (the .shprobe grid, x fastest in memory);
        ``coeffs`` (P, C, 3) colours per probe (SH coefficients, or 6 ambient-cube faces); ``axes``
        (3, 3) rows = the grid's unit axes (None = identity); ``validity`` / ``scale`` (P,);
        ``masks`` uint32 (Z, Y, X) 27-bit neighbour masks (None = all visible)."""
        g = _array(cells, "cells", np.int32, "iu")
        if g.ndim != 3:
            raise _shape_error("cells", "(Z, Y, X)", g)
        c = _array(coeffs, "coeffs", np.float64, _FLOAT_KINDS)
        if c.ndim != 3 or c.shape[2] != 3:
            raise _shape_error("coeffs", "(P, C, 3)", c)
        P = c.shape[0]
        ax = None if axes is None else _array(axes, "axes", np.float64, _FLOAT_KINDS)
        if ax is not None and ax.shape != (3, 3):
            raise _shape_error("axes", "(3, 3)", ax)
        m = None if masks is None else _array(masks, "masks", np.uint32, "iu")
        if m is not None and m.shape != g.shape:
            raise _shape_error("masks", str(g.shape), m)
        Z, Y, X = g.shape
        o = tuple(float(v) for v in origin)
        return cls(_lib().grid_field_build((X, Y, Z), o, float(spacing), None if ax is None else ax.reshape(-1),
                                           g.reshape(-1), c.reshape(-1), c.shape[1],
                                           _per_probe(validity, "validity", P), _per_probe(scale, "scale", P),
                                           None if m is None else m.reshape(-1), int(max_bytes)))

    def info(self) -> dict:
        """dims (X, Y, Z), origin, spacing, probe_count, coeff_count, channels (3C + 1), groups, the
        texture bytes, and texels (Z, Y, X, channels) float64."""
        d = dict(self._raw)
        X, Y, Z = d["dims"]
        d["texels"] = np.frombuffer(d["texels"], dtype=np.float64).reshape(Z, Y, X, d["channels"])
        return d

    def query(self, points: np.ndarray, normals: Optional[np.ndarray] = None, static_surface: bool = False,
              normal_bias: float = 0.0) -> dict:
        """The rule at surface points (N, 3) with unit normals (N, 3) (None: no normal): status (N,)
        (GRID_FIELD_STATUS index), probe (N, 8) (-1 empty or unused), weight (N, 8) (sum 1 with a value),
        coeffs (N, C, 3) = sum w s c (0 without a value), home (N, 3)."""
        p, _ = _vectors(points, "points")
        n = None if normals is None else _vectors(normals, "normals")[0]
        if n is not None and n.shape != p.shape:
            raise _shape_error("normals", str(p.shape), n)
        st, pr, wt, co, hm = _lib().grid_field_query(self._handle, p, n, bool(static_surface), float(normal_bias))
        C = self._raw["coeff_count"]
        return {"status": np.frombuffer(st, dtype=np.uint8), "probe": np.frombuffer(pr, dtype=np.int32).reshape(-1, 8),
                "weight": np.frombuffer(wt, dtype=np.float64).reshape(-1, 8),
                "coeffs": np.frombuffer(co, dtype=np.float64).reshape(-1, C, 3),
                "home": np.frombuffer(hm, dtype=np.uint32).reshape(-1, 3)}

    def sample_texture(self, points: np.ndarray, subtexel_bits: int = 0):
        """The texture form at points (N, 3): (coeffs (N, C, 3) = N / D (0 without a value), D (N,),
        has_value (N,) bool (in the box and D > 1e-6), t (N, 3) texel coordinates in [0, dims - 1]).
        ``subtexel_bits`` > 0: fractions rounded to 2**-bits (the filter's weights)."""
        p, _ = _vectors(points, "points")
        co, d, has, t = _lib().grid_field_sample_texture(self._handle, p, int(subtexel_bits))
        C = self._raw["coeff_count"]
        return (np.frombuffer(co, dtype=np.float64).reshape(-1, C, 3), np.frombuffer(d, dtype=np.float64),
                np.frombuffer(has, dtype=np.uint8).astype(bool), np.frombuffer(t, dtype=np.float64).reshape(-1, 3))

    def sample_surface_texture(self, points: np.ndarray, normals: Optional[np.ndarray] = None,
                               static_surface: bool = False, normal_bias: float = 0.0, subtexel_bits: int = 0):
        """The rule in the texture form as the engine samples it (pb_grid_field_sample_surface_texture) at
        surface points (N, 3) with unit normals (N, 3) (None: no normal): (coeffs (N, C, 3) = N / D (0
        without a value), D (N,) = sum w D (step 5's D where it was taken), has_value (N,) bool (the rule has a
        value: its weights or step 5's plain trilinear fallback), taps (N,) uint8: 1 where the kept weights are
        separable (one filtered tap), 8 elsewhere (step 5 included), 0 outside)."""
        p, _ = _vectors(points, "points")
        n = None if normals is None else _vectors(normals, "normals")[0]
        if n is not None and n.shape != p.shape:
            raise _shape_error("normals", str(p.shape), n)
        co, d, has, tp = _lib().grid_field_sample_surface_texture(self._handle, p, n, bool(static_surface),
                                                                  float(normal_bias), int(subtexel_bits))
        C = self._raw["coeff_count"]
        return (np.frombuffer(co, dtype=np.float64).reshape(-1, C, 3), np.frombuffer(d, dtype=np.float64),
                np.frombuffer(has, dtype=np.uint8).astype(bool), np.frombuffer(tp, dtype=np.uint8))

    def texture(self, half: bool = True) -> np.ndarray:
        """The channel textures (groups, Z, Y, X, 4): float16 (SchneeError past 65504) or float32."""
        d = self._raw
        X, Y, Z = d["dims"]
        raw = _lib().grid_field_texture(self._handle, bool(half))
        return np.frombuffer(raw, dtype=np.float16 if half else np.float32).reshape(d["groups"], Z, Y, X, 4)
