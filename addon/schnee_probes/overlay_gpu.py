"""The overlay's drawing with Blender's ``gpu`` module (docs/overlay.md): probe spheres shaded per
pixel with their own SH irradiance, the interpolation cells as lines.

All probes of a file sit in one RGBA32F texture (:data:`TEXELS` texels per probe: the 9 shading
coefficients, position + validity, the flat colour of the non-irradiance modes); one batch of
:data:`CHUNK` low-poly spheres (fewer triangles for more probes, :func:`sphere_subdivisions`), each vertex carrying its sphere's number, is drawn
``ceil(P / CHUNK)`` times with a probe offset (Blender 3.4's ``GPUBatch`` has no ``draw_instanced``,
so this one path serves 3.4, 4.3 and 5.2: about 100 draw calls for 100k probes). The fragment
shader evaluates DESIGN.md §3's L0-L2 basis at the pixel's normal converted to engine space
(x, z, −y) with the coefficients premultiplied by A_l / π and the probe's scale
(overlay_data.shading_coefficients), times ``2^exposure``.

Colour: the 3D viewport draws into an sRGB-encoding framebuffer (the value written is linear), an
RGBA8 GPUOffScreen does not encode: :func:`draw` takes ``encode_srgb`` and the shader applies the sRGB
transfer itself for offscreen pictures (tests, screenshots). Blender's view transform (Filmic, AgX)
is not applied to overlays in either case.
"""
from __future__ import annotations

import math
from typing import Dict

import numpy as np

import gpu
from gpu_extras.batch import batch_for_shader

from . import compat, overlay_data
from .overlay_data import ProbeSet

TEXELS = 12           # per probe: 0..8 shading SH (rgb), 9 position (xyz) + validity, 10 validity colour,
                      # 11 noise colour (a leaf marker: 9 its centre, 10 its refinement colour)
TEX_WIDTH = 4096      # texels per row of the probe texture (llvmpipe and every GPU allow 16384)
CHUNK = 1024          # spheres per batch (one draw call each)
# mode -> (shader mode: 0 irradiance, 1 flat colour, 2 white; the flat colour's texel)
MODES = {"IRRADIANCE": (0, 10), "VALIDITY": (1, 10), "NOISE": (1, 11), "REFINEMENT": (1, 10), "WHITE": (2, 10)}

_VERT = """
#ifndef TEXELS
#define TEXELS 12
#endif
vec4 probe_texel(int i)
{
  return texelFetch(probeData, ivec2(i % TEX_WIDTH, i / TEX_WIDTH), 0);
}
void main()
{
  int probe = probeOffset + int(localId + 0.5);
  probeIndex = probe;
  normalW = nrm;
  if (probe >= probeCount) {
    gl_Position = vec4(0.0, 0.0, -2.0, 1.0);  /* outside the clip volume: the chunk's unused spheres */
    flatColour = vec4(0.0);
    return;
  }
  vec4 p = probe_texel(probe * TEXELS + 9);
  flatColour = probe_texel(probe * TEXELS + colourTexel);
  gl_Position = viewProjectionMatrix * vec4(p.xyz + radius * nrm, 1.0);
}
"""

_FRAG = """
vec4 probe_texel(int i)
{
  return texelFetch(probeData, ivec2(i % TEX_WIDTH, i / TEX_WIDTH), 0);
}
float srgb_encode(float c)
{
  c = clamp(c, 0.0, 1.0);
  return c <= 0.0031308 ? 12.92 * c : 1.055 * pow(c, 1.0 / 2.4) - 0.055;
}
void main()
{
  vec3 colour;
  if (mode == 0) {
    vec3 b = normalize(normalW);
    vec3 d = vec3(b.x, b.z, -b.y);   /* Blender -> engine space (DESIGN.md §2) */
    float Y[9];
    Y[0] = 0.282094792;
    Y[1] = 0.488602512 * d.y;
    Y[2] = 0.488602512 * d.z;
    Y[3] = 0.488602512 * d.x;
    Y[4] = 1.092548431 * d.x * d.y;
    Y[5] = 1.092548431 * d.y * d.z;
    Y[6] = 0.315391565 * (3.0 * d.z * d.z - 1.0);
    Y[7] = 1.092548431 * d.x * d.z;
    Y[8] = 0.546274215 * (d.x * d.x - d.y * d.y);
    vec3 e = vec3(0.0);
    int base = probeIndex * TEXELS;
    for (int i = 0; i < 9; i++) {
      e += probe_texel(base + i).rgb * Y[i];
    }
    colour = max(e, vec3(0.0)) * exposure;
  }
  else if (mode == 1) {
    colour = flatColour.rgb;
  }
  else {
    colour = vec3(1.0);
  }
  if (encodeSrgb != 0) {
    colour = vec3(srgb_encode(colour.r), srgb_encode(colour.g), srgb_encode(colour.b));
  }
  fragColor = vec4(colour, 1.0);
}
"""

_LINE_VERT = """
void main()
{
  colourV = col;
  gl_Position = viewProjectionMatrix * vec4(pos, 1.0);
}
"""

_LINE_FRAG = """
float srgb_encode(float c)
{
  c = clamp(c, 0.0, 1.0);
  return c <= 0.0031308 ? 12.92 * c : 1.055 * pow(c, 1.0 / 2.4) - 0.055;
}
void main()
{
  vec3 c = colourV;
  if (encodeSrgb != 0) {
    c = vec3(srgb_encode(c.r), srgb_encode(c.g), srgb_encode(c.b));
  }
  fragColor = vec4(c * lineAlpha, lineAlpha);
}
"""

_shaders: Dict[str, object] = {}
_sphere_batches: Dict[int, object] = {}
_resources: Dict[str, dict] = {}   # path -> {"key": (stamp, sidecar stamp), textures, line batches}


def sphere_shader():
    if "sphere" not in _shaders:
        _shaders["sphere"] = compat.gpu_shader(
            "schnee_probe_sphere", _VERT, _FRAG,
            attrs=(("VEC3", "nrm"), ("FLOAT", "localId")),
            varyings=(("smooth", "VEC3", "normalW"), ("flat", "INT", "probeIndex"), ("flat", "VEC4", "flatColour")),
            constants=(("MAT4", "viewProjectionMatrix"), ("INT", "probeOffset"), ("INT", "probeCount"),
                       ("FLOAT", "radius"), ("FLOAT", "exposure"), ("INT", "mode"), ("INT", "colourTexel"),
                       ("INT", "encodeSrgb")),
            samplers=(("FLOAT_2D", "probeData"),),
            defines={"TEXELS": TEXELS, "TEX_WIDTH": TEX_WIDTH})
    return _shaders["sphere"]


def line_shader():
    if "line" not in _shaders:
        _shaders["line"] = compat.gpu_shader(
            "schnee_probe_cells", _LINE_VERT, _LINE_FRAG,
            attrs=(("VEC3", "pos"), ("VEC3", "col")),
            varyings=(("smooth", "VEC3", "colourV"),),
            constants=(("MAT4", "viewProjectionMatrix"), ("FLOAT", "lineAlpha"), ("INT", "encodeSrgb")),
            samplers=(), defines={})
    return _shaders["line"]


def icosphere(subdivisions: int = 1):
    """Unit icosphere: (V, 3) float32 vertices (= normals) and (T, 3) int32 triangles."""
    t = (1.0 + math.sqrt(5.0)) / 2.0
    v = [(-1, t, 0), (1, t, 0), (-1, -t, 0), (1, -t, 0), (0, -1, t), (0, 1, t), (0, -1, -t), (0, 1, -t),
         (t, 0, -1), (t, 0, 1), (-t, 0, -1), (-t, 0, 1)]
    f = [(0, 11, 5), (0, 5, 1), (0, 1, 7), (0, 7, 10), (0, 10, 11), (1, 5, 9), (5, 11, 4), (11, 10, 2),
         (10, 7, 6), (7, 1, 8), (3, 9, 4), (3, 4, 2), (3, 2, 6), (3, 6, 8), (3, 8, 9), (4, 9, 5),
         (2, 4, 11), (6, 2, 10), (8, 6, 7), (9, 8, 1)]
    verts = [np.array(p, float) / np.linalg.norm(p) for p in v]
    for _ in range(subdivisions):
        mids, nf = {}, []

        def mid(a, b):
            key = (min(a, b), max(a, b))
            if key not in mids:
                m = verts[a] + verts[b]
                verts.append(m / np.linalg.norm(m))
                mids[key] = len(verts) - 1
            return mids[key]
        for a, b, c in f:
            ab, bc, ca = mid(a, b), mid(b, c), mid(c, a)
            nf += [(a, ab, ca), (b, bc, ab), (c, ca, bc), (ab, bc, ca)]
        f = nf
    return np.array(verts, np.float32), np.array(f, np.int32)


def sphere_subdivisions(probe_count: int) -> int:
    """Icosphere subdivisions by probe count: 2 (320 triangles) up to 4096 probes, 1 (80) up to
    32768, 0 (20, the icosahedron) above; per-pixel shading hides the facets' outline only."""
    return 2 if probe_count <= 4096 else 1 if probe_count <= 32768 else 0


def _spheres(subdivisions: int):
    """One batch of CHUNK unit spheres (icospheres), each vertex carrying its sphere's number."""
    if subdivisions not in _sphere_batches:
        v, f = icosphere(subdivisions)
        nv = len(v)
        nrm = np.tile(v, (CHUNK, 1))
        local = np.repeat(np.arange(CHUNK, dtype=np.float32), nv)
        idx = (f[None, :, :] + (np.arange(CHUNK, dtype=np.int32) * nv)[:, None, None]).reshape(-1, 3)
        _sphere_batches[subdivisions] = batch_for_shader(sphere_shader(), 'TRIS', {"nrm": nrm, "localId": local},
                                                         indices=idx)
    return _sphere_batches[subdivisions]


def validity_colours(validity: np.ndarray) -> np.ndarray:
    """Validity 0 red, 0.5 yellow, 1 green (linear RGB), (P, 3)."""
    return overlay_data.traffic_light(1.0 - np.asarray(validity, np.float64))


def level_colours(levels: np.ndarray) -> np.ndarray:
    """(N, 3) cell line colours by level: 0 (Min Cell Size) white, along a ramp through orange to
    deep blue at levels >= 6."""
    t = np.clip(np.asarray(levels, np.float64) / 6.0, 0.0, 1.0)[:, None]
    white, orange, blue = np.array([1.0, 1.0, 1.0]), np.array([1.0, 0.55, 0.1]), np.array([0.15, 0.3, 1.0])
    c = white + (orange - white) * np.clip(t * 2.0, 0.0, 1.0)
    return (c + (blue - c) * np.clip(t * 2.0 - 1.0, 0.0, 1.0)).astype(np.float32)


def texture_data(positions: np.ndarray, colours, shading=None, validity=None) -> np.ndarray:
    """The texels (rows of TEX_WIDTH, RGBA float32, zero-padded) of spheres at ``positions`` (N, 3):
    ``colours`` the flat colours (N, 3) of texels 10, 11, ...; ``shading`` (N, 9, 3) texels 0..8."""
    n = len(positions)
    tex = np.zeros((n, TEXELS, 4), np.float32)
    if shading is not None:
        tex[:, :9, :3] = shading
    tex[:, 9, :3] = positions
    if validity is not None:
        tex[:, 9, 3] = validity
    for k, c in enumerate(colours):
        tex[:, 10 + k, :3] = c
        tex[:, 10 + k, 3] = 1.0
    flat = tex.reshape(-1, 4)
    rows = max(1, -(-len(flat) // TEX_WIDTH))
    out = np.zeros((rows * TEX_WIDTH, 4), np.float32)
    out[:len(flat)] = flat
    return out.reshape(rows, TEX_WIDTH, 4)


def probe_texture_data(ps: ProbeSet) -> np.ndarray:
    """The probe texture's texels: shading, position + validity, the validity and noise colours
    (grey where the file has no noise, overlay_data.noise_colours)."""
    noise = (overlay_data.noise_colours(ps.info.noise, ps.info.tolerance) if ps.has_noise
             else np.tile(overlay_data.GREY.astype(np.float32), (ps.probe_count, 1)))
    return texture_data(ps.positions, (validity_colours(ps.validity), noise), ps.shading, ps.validity)


def leaf_colours(ps: ProbeSet) -> np.ndarray:
    """(L, 3) the Refinement mode's colour per leaf of ``ps`` (its sidecar's decisions)."""
    i = ps.info
    return overlay_data.refinement_colours(i.leaf_reason, i.leaf_ratio, i.leaf_parent_ratio)


def _texture(data: np.ndarray):
    buf = gpu.types.Buffer('FLOAT', data.size, data.reshape(-1))
    return gpu.types.GPUTexture((TEX_WIDTH, data.shape[0]), format='RGBA32F', data=buf)


def _resources_for(ps: ProbeSet) -> dict:
    key = (ps.stamp, None if ps.info is None else ps.info.stamp)
    hit = _resources.get(ps.path)
    if hit is not None and hit["key"] == key:
        return hit
    hit = {"key": key, "probes": _texture(probe_texture_data(ps)), "lines": None, "markers": None,
           "refined_lines": None}
    if len(ps.cell_lines):
        hit["lines"] = batch_for_shader(line_shader(), 'LINES', {"pos": ps.cell_lines,
                                                                 "col": level_colours(ps.cell_levels)})
    if ps.has_refinement and len(ps.leaf_centres):
        colours = leaf_colours(ps)
        hit["markers"] = _texture(texture_data(ps.leaf_centres, (colours,)))
        if len(ps.cell_lines) and ps.structure in ("octree", "kdtree"):
            per_vertex = np.repeat(colours[:len(ps.cell_lines) // 24], 24, axis=0)
            hit["refined_lines"] = batch_for_shader(line_shader(), 'LINES', {"pos": ps.cell_lines, "col": per_vertex})
    _resources[ps.path] = hit
    return hit


def free_resources() -> None:
    _resources.clear()


def _draw_spheres(tex, count: int, view_projection, mode: str, radius: float, exposure: float, encode_srgb: bool):
    sh = sphere_shader()
    batch = _spheres(sphere_subdivisions(count))
    shader_mode, texel = MODES[mode]
    sh.bind()
    sh.uniform_float("viewProjectionMatrix", view_projection)
    sh.uniform_int("probeCount", count)
    sh.uniform_float("radius", float(radius))
    sh.uniform_float("exposure", float(2.0 ** exposure))
    sh.uniform_int("mode", shader_mode)
    sh.uniform_int("colourTexel", texel)
    sh.uniform_int("encodeSrgb", 1 if encode_srgb else 0)
    sh.uniform_sampler("probeData", tex)
    for offset in range(0, count, CHUNK):
        sh.uniform_int("probeOffset", offset)
        batch.draw(sh)


def draw(ps: ProbeSet, view_projection, *, radius: float = 0.1, exposure: float = 0.0,
         mode: str = "IRRADIANCE", show_probes: bool = True, show_cells: bool = True,
         cell_alpha: float = 0.6, encode_srgb: bool = False) -> None:
    """Draw ``ps`` into the bound framebuffer with the matrix ``view_projection`` (mathutils 4x4,
    Blender world -> clip). Depth test on; the caller restores state it cares about. Mode
    REFINEMENT draws a sphere per leaf at its centre and the leaves' lines in the colour of their
    decision (overlay_data.refinement_colours) where the file has a sidecar with them, else white
    probes and the cells by level."""
    if ps.error or ps.probe_count == 0:
        return
    res = _resources_for(ps)
    tex, count, lines = res["probes"], ps.probe_count, res["lines"]
    if mode == "REFINEMENT":
        if res["markers"] is not None:
            tex, count = res["markers"], len(ps.leaf_centres)
            lines = res["refined_lines"] or lines
        else:
            mode = "WHITE"
    gpu.state.depth_test_set('LESS_EQUAL')
    gpu.state.depth_mask_set(True)
    if show_probes:
        _draw_spheres(tex, count, view_projection, mode, radius, exposure, encode_srgb)
    if show_cells and lines is not None:
        ls = line_shader()
        ls.bind()
        ls.uniform_float("viewProjectionMatrix", view_projection)
        ls.uniform_float("lineAlpha", float(cell_alpha))
        ls.uniform_int("encodeSrgb", 1 if encode_srgb else 0)
        gpu.state.blend_set('ALPHA_PREMULT')
        gpu.state.depth_mask_set(False)
        lines.draw(ls)
        gpu.state.blend_set('NONE')
    gpu.state.depth_mask_set(False)
    gpu.state.depth_test_set('NONE')


def draw_offscreen(probe_sets, view_matrix, projection_matrix, width: int, height: int,
                   background=(0.05, 0.05, 0.05), **kw) -> np.ndarray:
    """Draw into a new RGBA8 GPUOffScreen (sRGB-encoded by the shader) and return its pixels,
    (height, width, 4) uint8, row 0 at the bottom (OpenGL's order). For tests and screenshots."""
    off = gpu.types.GPUOffScreen(width, height)
    try:
        with off.bind():
            fb = gpu.state.active_framebuffer_get()
            fb.clear(color=(*background, 1.0), depth=1.0)
            vp = projection_matrix @ view_matrix
            for ps in probe_sets:
                draw(ps, vp, encode_srgb=True, **kw)
            pixels = compat.gpu_read_framebuffer(fb, width, height)
    finally:
        off.free()
    return pixels


def srgb_decode(code: np.ndarray) -> np.ndarray:
    """8-bit sRGB codes -> linear values (the inverse of the shader's encode)."""
    c = np.asarray(code, np.float64) / 255.0
    return np.where(c <= 0.04045, c / 12.92, ((c + 0.055) / 1.055) ** 2.4)
