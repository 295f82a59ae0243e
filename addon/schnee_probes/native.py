"""Python face of the native bake core (``_schnee_native``, a stable-ABI CPython module).

This file is the contract between the add-on and the C core. Arrays go in and out as numpy arrays
(flat buffers underneath, never per-element calls); long calls release the GIL; every core error is
raised as :class:`SchneeError` carrying the core's message verbatim and its code name.

All geometry and SH data are in engine space (Y-up, DESIGN.md §2) unless a docstring says otherwise.
SH coefficient arrays have shape ``(sh_count(max_band), 3)`` (coefficient-major, RGB), the
radiance projection ``L_i = ∫ L(ω) Y_i(ω) dω`` of DESIGN.md §3.

STATUS: placeholder signatures; the implementation lands with the extension module.
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import Callable, Optional, Sequence, Tuple

import numpy as np


class SchneeError(RuntimeError):
    """An error reported by the native core. ``code`` is the pb_result name, e.g. ``"open mesh"``."""

    def __init__(self, message: str, code: str = "unknown error"):
        super().__init__(message)
        self.code = code


# Blender world (Z-up) -> engine (Y-up): (x, y, z) -> (x, z, -y).
BLENDER_TO_ENGINE = np.array([[1.0, 0.0, 0.0], [0.0, 0.0, 1.0], [0.0, -1.0, 0.0]])


def sh_count(max_band: int) -> int:
    """Number of coefficients for bands 0..max_band: (max_band + 1)**2."""
    return (max_band + 1) ** 2


def sh_basis(dirs: np.ndarray, max_band: int) -> np.ndarray:
    """Basis values, shape (N, sh_count), at unit directions ``dirs`` (N, 3) in engine space."""
    raise NotImplementedError


def min_panorama_size(max_band: int) -> Tuple[int, int]:
    """Smallest (width, height) panorama that can represent ``max_band``."""
    raise NotImplementedError


def project_equirect(pixels: np.ndarray, max_band: int = 2, rotation: Optional[np.ndarray] = None,
                     negative: str = "error") -> np.ndarray:
    """Project an equirect panorama ``pixels`` (H, W, C>=3) float32, row 0 at the TOP (as Cycles
    writes files; note Blender's ``Image.pixels`` is bottom-up) onto SH. ``rotation`` (3, 3) maps the
    canonical Cycles panorama direction (Blender world space, camera rotated (90°, 0, −90°)) to the
    output space; None = BLENDER_TO_ENGINE. ``negative``: "error" | "clamp" | "allow" (NaN/Inf is
    always an error). Returns (sh_count, 3) float64."""
    raise NotImplementedError


def project_file(path: str, max_band: int = 2, rotation: Optional[np.ndarray] = None,
                 negative: str = "error") -> np.ndarray:
    """Same as :func:`project_equirect` for an image file read through OpenImageIO (EXR, HDR, ...)."""
    raise NotImplementedError


def irradiance(coeffs: np.ndarray, normals: np.ndarray) -> np.ndarray:
    """Irradiance E(n) (N, 3) of radiance coefficients (sh_count, 3) at unit normals (N, 3)."""
    raise NotImplementedError


def window(coeffs: np.ndarray, kind: str = "none", strength: float = 0.0) -> Tuple[np.ndarray, np.ndarray]:
    """Ringing window: kind "none" | "sinc4" | "laplacian"; strength 0 = automatic.
    Returns (windowed coefficients copy, minimum irradiance over the sphere (3,))."""
    raise NotImplementedError


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


def place_probes(volumes: Sequence[Mesh], geometry: Sequence[Mesh], min_cell_size: float = 0.5,
                 max_cell_size: float = 16.0, threads: int = 0,
                 progress: Optional[Callable[[float, str], bool]] = None, *,
                 solid_ray_count: int = 0, solid_backface_ratio: float = 0.0,
                 max_grid_cells: int = 0) -> Placement:
    """Place probes in the union of closed ``volumes`` avoiding solid ``geometry`` (both engine
    space, metres). ``progress(fraction, stage)`` returning False cancels (SchneeError code
    "cancelled"). Open volume meshes raise SchneeError code "open mesh" naming the mesh."""
    raise NotImplementedError


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

    @property
    def probe_count(self) -> int:
        return int(self.coeffs.shape[0])


def write_shprobe(path: str, coeffs: np.ndarray, grid: np.ndarray, grid_dims: Sequence[int],
                  grid_origin: Sequence[float], grid_spacing: float, *, default_sh_scale: float = 1.0,
                  default_ambient: float = 0.1, positions: Optional[np.ndarray] = None,
                  probe_scale: Optional[np.ndarray] = None, probe_ambient: Optional[np.ndarray] = None,
                  version: int = 0) -> int:
    """Write a ``.shprobe`` atomically (temp file + rename). ``coeffs`` (P, sh_count, 3);
    version 0 = smallest that holds the data (1 for max_band <= 2 without positions). Returns the
    version written."""
    raise NotImplementedError


def read_shprobe(path: str) -> ShProbeFile:
    """Read and validate a ``.shprobe`` (any version); SchneeError on malformed input."""
    raise NotImplementedError


def read_shprobe_header(path: str) -> dict:
    """Header fields only (version, probe_count, max_band, grid_dims, grid_origin, grid_spacing,
    default_sh_scale, default_ambient), validated against the file size."""
    raise NotImplementedError
