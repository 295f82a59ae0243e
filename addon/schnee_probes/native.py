"""Python face of the native bake core (``_schnee_native``, a stable-ABI CPython module).

This file is the contract between the add-on and the C core. Arrays go in and out as numpy arrays
(flat buffers underneath, never per-element calls); long calls release the GIL; every core error is
raised as :class:`SchneeError` carrying the core's message verbatim and its code name.

All geometry and SH data are in engine space (Y-up, DESIGN.md §2) unless a docstring says otherwise.
SH coefficient arrays have shape ``(sh_count(max_band), 3)`` (coefficient-major, RGB), the
radiance projection ``L_i = ∫ L(ω) Y_i(ω) dω`` of DESIGN.md §3.

Inputs are validated here (shape -> ValueError, dtype kind -> TypeError, both naming the
argument) and converted to C-contiguous arrays of the dtype the core wants; the C module
re-checks every buffer's format and length. See docs/python-api.md.
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import Callable, Optional, Sequence, Tuple

import numpy as np

try:
    from . import _schnee_native as _native
    _NATIVE_IMPORT_ERROR: Optional[BaseException] = None
except ImportError as exc:  # not built yet: the pure-Python parts (dataclasses, errors) still work
    _native = None
    _NATIVE_IMPORT_ERROR = exc


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
        raise ImportError("the native module _schnee_native is not built (run scripts/build.sh): "
                          f"{_NATIVE_IMPORT_ERROR}")
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


def _check_band(max_band: int) -> int:
    if isinstance(max_band, bool) or not isinstance(max_band, (int, np.integer)):
        raise TypeError(f"max_band must be an int, got {type(max_band).__name__}")
    if not 0 <= int(max_band) <= 4:
        raise ValueError(f"max_band {max_band} is out of range 0..4")
    return int(max_band)


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


# ---- SH -----------------------------------------------------------------------------------------

def sh_basis(dirs: np.ndarray, max_band: int) -> np.ndarray:
    """Basis values, shape (N, sh_count), at unit directions ``dirs`` (N, 3) in engine space.
    A single direction (3,) gives shape (sh_count,)."""
    band = _check_band(max_band)
    d, single = _vectors(dirs, "dirs")
    out = np.frombuffer(_lib().sh_basis(d, band), dtype=np.float64).reshape(len(d), sh_count(band))
    return out[0] if single else out


def min_panorama_size(max_band: int) -> Tuple[int, int]:
    """Smallest (width, height) panorama that can represent ``max_band``."""
    return tuple(_lib().min_panorama_size(_check_band(max_band)))


def project_equirect(pixels: np.ndarray, max_band: int = 2, rotation: Optional[np.ndarray] = None,
                     negative: str = "error") -> np.ndarray:
    """Project an equirect panorama ``pixels`` (H, W, C>=3) float32, row 0 at the TOP (as Cycles
    writes files; note Blender's ``Image.pixels`` is bottom-up) onto SH. ``rotation`` (3, 3) maps the
    canonical Cycles panorama direction (Blender world space, camera rotated (90°, 0, −90°)) to the
    output space; None = BLENDER_TO_ENGINE. ``negative``: "error" | "clamp" | "allow" (NaN/Inf is
    always an error). Returns (sh_count, 3) float64. Runs with the GIL released."""
    band = _check_band(max_band)
    pix = _array(pixels, "pixels", np.float32, _FLOAT_KINDS)
    if pix.ndim != 3 or pix.shape[2] < 3:
        raise _shape_error("pixels", "(H, W, C) with C >= 3", pix)
    h, w, c = pix.shape
    raw = _lib().project_equirect(pix, w, h, c, band, _rotation(rotation),
                                  _choice(negative, _NEGATIVE, "negative"))
    return np.frombuffer(raw, dtype=np.float64).reshape(sh_count(band), 3)


def project_file(path: str, max_band: int = 2, rotation: Optional[np.ndarray] = None,
                 negative: str = "error") -> np.ndarray:
    """Same as :func:`project_equirect` for an image file read through OpenImageIO (EXR, HDR, ...)."""
    band = _check_band(max_band)
    raw = _lib().project_file(path, band, _rotation(rotation), _choice(negative, _NEGATIVE, "negative"))
    return np.frombuffer(raw, dtype=np.float64).reshape(sh_count(band), 3)


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


# ---- placement ----------------------------------------------------------------------------------

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
    out = []
    for i, mesh in enumerate(meshes):
        try:
            name, verts, tris = mesh
        except (TypeError, ValueError):
            raise TypeError(f"{what}[{i}] must be a (name, vertices, triangles) tuple") from None
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
    if progress is not None and not callable(progress):
        raise TypeError("progress must be callable(fraction, stage) or None")
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


# ---- .shprobe -----------------------------------------------------------------------------------

_IDENTITY_AXES = ((1.0, 0.0, 0.0), (0.0, 1.0, 0.0), (0.0, 0.0, 1.0))


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

    @property
    def probe_count(self) -> int:
        return int(self.coeffs.shape[0])

    def lookup(self, points: np.ndarray) -> np.ndarray:
        """Probe index (int32) of the grid cell holding each engine-space point, −1 outside/empty.
        Cells are half-open: the min faces belong to a cell, the grid's max faces do not."""
        return shprobe_lookup(self, points)


def _shprobe_from_dict(d: dict) -> ShProbeFile:
    n, band = d["probe_count"], d["max_band"]
    positions = d["positions"]
    return ShProbeFile(
        version=d["version"], max_band=band,
        coeffs=np.frombuffer(d["coeffs"], dtype=np.float32).reshape(n, sh_count(band), 3),
        probe_scale=np.frombuffer(d["probe_scale"], dtype=np.float32),
        probe_ambient=np.frombuffer(d["probe_ambient"], dtype=np.float32),
        positions=None if positions is None else np.frombuffer(positions, dtype=np.float32).reshape(n, 3),
        grid=np.frombuffer(d["grid"], dtype=np.int32),
        grid_dims=tuple(d["grid_dims"]), grid_origin=tuple(d["grid_origin"]),
        grid_spacing=d["grid_spacing"], default_sh_scale=d["default_sh_scale"],
        default_ambient=d["default_ambient"],
        validity=np.frombuffer(d["validity"], dtype=np.float32),
        grid_axes=tuple(tuple(r) for r in d["grid_axes"]))


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
    dims = tuple(int(v) for v in grid_dims)
    if len(dims) != 3 or min(dims) < 0:
        raise ValueError(f"grid_dims must be 3 non-negative ints (X, Y, Z), got {tuple(grid_dims)}")
    g = _array(grid, "grid", np.int32, _INT_KINDS)
    x, y, z = dims
    if g.shape not in ((x * y * z,), (z, y, x)):
        raise _shape_error("grid", f"({x * y * z},) or (Z, Y, X) = ({z}, {y}, {x})", g)
    origin = tuple(float(v) for v in grid_origin)
    if len(origin) != 3:
        raise ValueError(f"grid_origin must be 3 floats, got {tuple(grid_origin)}")
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
    if int(version) not in (0, 1, 2):
        raise ValueError(f"version must be 0 (auto), 1 or 2, got {version}")
    return _lib().shprobe_write(
        path, c, band, g, dims, origin, float(grid_spacing),
        default_sh_scale=float(default_sh_scale), default_ambient=float(default_ambient),
        positions=pos, probe_scale=_per_probe(probe_scale, "probe_scale", n),
        probe_ambient=_per_probe(probe_ambient, "probe_ambient", n),
        validity=_per_probe(validity, "validity", n), grid_axes=axes, version=int(version))


def read_shprobe(path: str) -> ShProbeFile:
    """Read and validate a ``.shprobe`` (any version); SchneeError on malformed input."""
    return _shprobe_from_dict(_lib().shprobe_read(path))


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


# ---- direct light (issue 11, docs/direct-light.md) ---------------------------------------------

LIGHT_TYPES = {"SUN": 0, "POINT": 1, "SPOT": 2, "AREA_RECT": 3, "AREA_ELLIPSE": 4}
LIGHT_RECORD = 20  # float64 per lamp: type, position[3], direction[3], axis_u[3], rgb[3], radius,
#                    size_u, size_v, spot_size, spot_blend, legacy_point, 0


@dataclass
class Lamp:
    """One lamp for :func:`direct_project`, engine space, Blender/Cycles units.

    ``kind``: SUN, POINT, SPOT, AREA_RECT (square/rectangle) or AREA_ELLIPSE (disk/ellipse).
    ``color``: colour × strength (sun W/m², others W). ``direction``: where the lamp emits (its
    local −Z; for a sun the direction its light travels). ``radius``: point/spot radius (m), sun
    angular diameter ``angle`` (rad). ``legacy_point``: Cycles ≤ 3.6 point/spot conventions."""
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

    def record(self) -> list:
        return ([float(_choice(self.kind, LIGHT_TYPES, "kind"))] + [float(x) for x in self.position]
                + [float(x) for x in self.direction] + [float(x) for x in self.axis_u]
                + [float(x) for x in self.color]
                + [float(self.radius), float(self.size_u), float(self.size_v), float(self.spot_size),
                   float(self.spot_blend), 1.0 if self.legacy_point else 0.0, 0.0])


def direct_project(lamps: Sequence[Lamp], probes: np.ndarray, max_band: int = 2, samples: int = 0,
                   geometry: Optional[Sequence[Mesh]] = None, ray_offset: float = 0.0) -> np.ndarray:
    """Radiance projection of the lamps' direct light at each probe (engine space), shadowed by
    ``geometry`` (opaque triangles; None = nothing occludes). ``samples``: quadrature cells and
    shadow rays per lamp (0 = 256). Returns (P, sh_count, 3) float64. GIL released."""
    band = _check_band(max_band)
    p, _ = _vectors(probes, "probes")
    rec = np.ascontiguousarray(np.array([lamp.record() for lamp in lamps], dtype=np.float64).reshape(-1))
    geo = None if geometry is None else _meshes(geometry, "geometry")
    out = _lib().direct_project(rec, p, band, int(samples), geo, float(ray_offset))
    return np.frombuffer(out, dtype=np.float64).reshape(len(p), sh_count(band), 3)


def sky_table(world: np.ndarray, pano_width: int, pano_height: int, max_band: int = 2,
              rotation: Optional[np.ndarray] = None) -> np.ndarray:
    """Per panorama cell (canonical mapping, row 0 at the top) the exact projection of the world
    texels whose centres fall into it: ``world`` (H, W, C>=3) float32 equirect, same mapping, any
    resolution. Returns (pano_height, pano_width, sh_count, 3) float64; the sum over all cells is
    the world's projection (project_equirect)."""
    band = _check_band(max_band)
    arr = _array(world, "world", np.float32, _FLOAT_KINDS)
    if arr.ndim != 3 or arr.shape[2] < 3:
        raise _shape_error("world", "(H, W, C>=3)", arr)
    rot = _rotation(rotation)
    out = _lib().sky_table(arr, arr.shape[1], arr.shape[0], arr.shape[2], int(pano_width), int(pano_height),
                           band, rot)
    return np.frombuffer(out, dtype=np.float64).reshape(int(pano_height), int(pano_width), sh_count(band), 3)
