/* GPU-side contract of schnee-view, ONE file read by both the C engine and the GLSL shaders (the
 * niagara way): enums, descriptor binding numbers, vertex locations and every struct a shader
 * reads. C includes it as "sv_gpu.h" (engine/src, engine/ext), GLSL through gpu_types.glsl.
 *
 * Structs are written with the SV_* field macros below, which expand to `float name[4]` in C and
 * `vec4 name` in GLSL, so a struct is declared once. Every member is a 16-byte (vec4) group, so
 * std430 (storage buffers, push constants) and std140 (the frame uniform) agree with the C layout;
 * the C side pins each size with a static assert.
 *
 * Adding a probe mode: a value below SV_PROBE_MODE_MATERIAL (and bump it and SV_PROBE_MODE_COUNT),
 * its name in sv_probe_mode_name(), the shading in shading.glsl/mesh.frag; the exporter's
 * PROBE_MODES list is compared with the names by tests/engine/ext/test_probe_modes.c. Probe
 * representations (SV_PROBE_REP_*) work the same way: sv_probe_representation_name(), the
 * exporter's PROBE_REPRESENTATIONS, tests/engine/ext/test_probe_representations.c.
 */
#ifndef SV_GPU_H
#define SV_GPU_H

#if defined(GL_core_profile) /* ------------------------------------------------- GLSL */
#define SV_STRUCT(name)      struct name
#define SV_END(name)         ;
#define SV_FLOAT(n)          float n
#define SV_UINT(n)           uint n
#define SV_INT(n)            int n
#define SV_VEC4(n)           vec4 n
#define SV_UVEC4(n)          uvec4 n
#define SV_MAT4(n)           mat4 n
#define SV_MAT4_ARRAY(n, k)  mat4 n[k]
#define SV_VEC4_ARRAY(n, k)  vec4 n[k]
#define SV_UINT_ARRAY(n, k)  uint n[k]
#define SV_UVEC2_ARRAY(n, k) uvec2 n[k]
#define SV_SIZE_CHECK(name, size)
#else /* --------------------------------------------------------------------------------- C */
#include <assert.h>
#include <stdint.h>
#include <stdio.h>
#include <string.h>
#define SV_STRUCT(name)           typedef struct name
#define SV_END(name)              name;
#define SV_FLOAT(n)               float n
#define SV_UINT(n)                uint32_t n
#define SV_INT(n)                 int32_t n
#define SV_VEC4(n)                float n[4]
#define SV_UVEC4(n)               uint32_t n[4]
#define SV_MAT4(n)                float n[16]
#define SV_MAT4_ARRAY(n, k)       float n[k][16]
#define SV_VEC4_ARRAY(n, k)       float n[k][4]
#define SV_UINT_ARRAY(n, k)       uint32_t n[k]
#define SV_UVEC2_ARRAY(n, k)      uint32_t n[k][2]
#define SV_SIZE_CHECK(name, size) static_assert(sizeof(name) == (size), #name " size is part of the GPU layout");
#endif

#define SV_SH_MAX_COEFFS 25 /* L <= 4, mirrors PB_SH_MAX_COEFFS */

/* ---------------------------------------------------------------- descriptor bindings */
/* Set 0 (the scene). */
#define SV_SET_SCENE           0
#define SV_BINDING_FRAME       0  /* UBO sv_gpu_frame */
#define SV_BINDING_MATERIALS   1  /* SSBO sv_gpu_material[] */
#define SV_BINDING_PROBES      2  /* SSBO sv_gpu_probe[] (float storage) */
#define SV_BINDING_LIGHTS      3  /* SSBO sv_gpu_light[] */
#define SV_BINDING_CUBES       4  /* SSBO sv_gpu_cube[] (ambient cubes, float storage) */
#define SV_BINDING_CELLS       5  /* SSBO sv_gpu_cell[] (probe view) */
#define SV_BINDING_GRIDS       6  /* SSBO sv_gpu_grid[] */
#define SV_BINDING_CELL_INDEX  7  /* SSBO int[]: cell -> probe, then visibility masks */
#define SV_BINDING_PROBES_HALF 8  /* SSBO sv_gpu_probe_half[] (half storage) */
#define SV_BINDING_SKY         9  /* sampler2D: equirect sky with prefiltered mips */
#define SV_BINDING_BRDF_LUT    10 /* sampler2D: split-sum BRDF LUT */
#define SV_BINDING_CUBES_HALF  11 /* SSBO sv_gpu_cube_half[] (ambient cubes, half storage) */
#define SV_BINDING_SHADOW      12 /* sampler2DArrayShadow: shadow maps, one layer per sun/spot, six per point */
#define SV_BINDING_BRICK_POOL  13 /* sampler3D: probe-brick pool, RGBA16F/32F, linear (--probe-path bricks) */
#define SV_BINDING_BRICK_INDEX 14 /* usampler3D: probe-brick indirection, RGBA32UI, nearest (texelFetch) */
#define SV_BINDING_BRICK_VIS   15 /* SSBO uint[]: brick tables, then visibility records (sv_bricks_vis.h) */
#define SV_SCENE_BINDING_COUNT 16 /* bindings in set 0 */
/* Set 1 (per material). */
#define SV_SET_MATERIAL           1
#define SV_BINDING_BASE_COLOR_TEX 0
#define SV_BINDING_EMISSIVE_TEX   1
/* Tone-mapping pass, set 0. */
#define SV_BINDING_HDR 0

/* The deferred per-pixel probe pass (docs/engine.md "The per-pixel probe pass"): mesh.frag built with
 * SV_DEFERRED_PROBES writes the HDR target (location 0) and four G-buffer targets; probe_pass.comp
 * reads them as storage images of set SV_SET_PROBE_PASS and adds the probe terms into the HDR target. */
#define SV_GBUF_POINT            1 /* RGBA32UI: the surface point's float bits, meta */
#define SV_GBUF_NORMAL           2 /* RGBA32F: n, the sky specular's r */
#define SV_GBUF_DIFFUSE          3 /* RGBA32F: albedo * sh_scale / pi, the sky specular's g */
#define SV_GBUF_BAKED            4 /* RGBA32F: the baked lights' direct light, the sky specular's b */
#define SV_GBUF_COUNT            4
#define SV_SET_PROBE_PASS        2   /* binding 0 the HDR target, 1 + i G-buffer target SV_GBUF_POINT + i */
#define SV_PROBE_PASS_GROUP      8   /* local size x = y */
#define SV_GBUF_META_PIXEL       1u  /* a per-pixel fragment: the probe pass shades it */
#define SV_GBUF_META_MOVABLE     2u  /* SV_DRAW_MOVABLE */
#define SV_GBUF_META_CUBE        4u  /* the ambient-cube representation */
#define SV_GBUF_META_TETRA       8u  /* SV_DRAW_TETRA: outside every grid, the object's own probe */
#define SV_GBUF_META_CUBE_ONLY   16u /* SV_DRAW_CUBE_ONLY */
#define SV_GBUF_META_ENTRY_SHIFT 8u  /* bits 8-31: the object's probe-buffer entry (0: none) */
/* Specialization constant ids. */
#define SV_CONSTANT_HALF_PROBES 0 /* bool: probes are read from the half storage */
/* Vertex inputs (one interleaved buffer: position, normal, uv). */
#define SV_LOCATION_POSITION 0
#define SV_LOCATION_NORMAL   1
#define SV_LOCATION_UV       2

/* ---------------------------------------------------------------- enums */
/* Debug views (sv_gpu_frame.debug_mode). */
#define SV_DEBUG_NONE           0u /* shaded */
#define SV_DEBUG_PROBE_COLOR    1u /* each object in a colour hashed from its probe index */
#define SV_DEBUG_PROBE_INDEX    2u /* R = probe index as a float (exact in EXR output), G = B = 0 */
#define SV_DEBUG_NORMALS        3u /* world normal * 0.5 + 0.5 */
#define SV_DEBUG_BRICK_LEVEL    4u /* --probe-path bricks: the level of the brick the pixel samples (brick_debug.glsl) */
#define SV_DEBUG_BRICK_VALIDITY 5u /* --probe-path bricks: the D (valid share) of the pixel's brick sample */

/* Probe lighting mode of a material (VULKAN_SCHNEE_materials.probeMode) or of the whole frame
 * (--probe-mode, sv_gpu_frame.probe_mode). Names: sv_probe_mode_name(). */
#define SV_PROBE_MODE_OFF      0u /* no baked probe: the fallback probe 0 (the sky's SH when there is a sky) */
#define SV_PROBE_MODE_OBJECT   1u /* one probe per object, at the centre of its bounds (default) */
#define SV_PROBE_MODE_PIXEL    2u /* per fragment: trilinear over the grid cells (DESIGN.md §7) */
#define SV_PROBE_MODE_MATERIAL 3u /* frame only: each material's own mode; always the last value */
#define SV_PROBE_MODE_COUNT    4u

/* Probe representation of a material (VULKAN_SCHNEE_materials.probeRepresentation) or of the
 * whole frame (--probe-representation, sv_gpu_frame.probe_representation), docs/ambient-cube.md §5.
 * Orthogonal to the probe mode (which says where the probe is sampled). Names:
 * sv_probe_representation_name(). */
#define SV_PROBE_REP_SH           0u /* L <= 4 SH irradiance (default) */
#define SV_PROBE_REP_AMBIENT_CUBE 1u /* the ambient cube fitted to the probe's SH at load */
#define SV_PROBE_REP_MATERIAL     2u /* frame only: each material's own; always the last value */
#define SV_PROBE_REP_COUNT        3u

#define SV_DRAW_MIRRORED 1u /* sv_gpu_draw.flags: det(model 3x3) < 0, front faces wind clockwise */
#define SV_DRAW_CUBE_ONLY                                                                                              \
    2u /* the object's probe comes from a grid that holds ambient cubes only (.shprobe v3,
                                representation 1): shaded with the cube whatever the material asks for */
#define SV_DRAW_TETRA                                                                                                  \
    4u /* the object's probe comes from a tetrahedra grid: per pixel falls back to the
                                object's own interpolated probe (no GPU point location for tetrahedra) */

#define SV_DRAW_MOVABLE                                                                                                \
    8u /* the object has moved (not in the static scene the probes were baked with): per pixel,
                              no back-face weights (every corner saw the light where the object now is) */

/* sv_gpu_draw.flags bits 4-5 and 6-7: the object's own probe mode (SV_PROBE_MODE_*) and
 * representation (SV_PROBE_REP_*) from its node's VULKAN_SCHNEE_node (docs/export.md "Node"), each
 * stored + 1; 0 = as its materials say. Between the frame's override and the material's. */
#define SV_DRAW_NODE_MODE_SHIFT 4u
#define SV_DRAW_NODE_REP_SHIFT  6u

/* Grid flags (sv_gpu_grid.base.z). */
#define SV_GRID_OCTREE    1u /* corner octree (.shprobe v3 structure 1): leaves in the cell buffer */
#define SV_GRID_CUBE_ONLY 2u /* the grid's file holds ambient cubes only (representation 1) */
#define SV_GRID_TETRA     4u /* tetrahedra: not sampled per pixel (objects use their per-object probe) */
#define SV_GRID_KDTREE                                                                                                 \
    8u /* with SV_GRID_OCTREE: a kd corner tree (.shprobe v4 structure 3): leaf int 3 holds the packed
          levels lx | ly << 8 | lz << 16, leaves are found by descending the file's split tree (tree) */
#define SV_GRID_BRICKS                                                                                                 \
    16u /* with SV_GRID_OCTREE: the grid's field is in the brick pool (--probe-path bricks; sv_gpu_grid.bricks) */
/* Ints per octree leaf in the cell buffer: x, y, z (lattice min corner), level (kd tree: the packed levels),
 * blocked (1 when its visibility field's table holds a surface, else 0: the field is then 1 everywhere),
 * 3 reserved (0), then the 8 corner nodes (corner bit 0 = +x, 1 = +y, 2 = +z; node = probe-buffer index
 * - base.x). */
#define SV_LEAF_INTS 16u
/* Ints per octree leaf of its visibility field (pb_cotree_pair_visibility, pb_interp.h): 64 bytes,
 * byte 8k + c (little-endian within each int) = corner k looking at corner c, round(255 t). */
#define SV_LEAF_VIS_INTS 16u
#define SV_VIS_RAMP      0.25 /* = PB_VIS_RAMP of pb_interp.h (tests/engine/test_engine_v3.py compares the two) */

/* Frame flags (sv_gpu_frame.flags). */
#define SV_FRAME_NO_DIRECT   1u  /* skip KHR_lights_punctual direct light */
#define SV_FRAME_SKY         2u  /* a sky is loaded: background + image-based specular */
#define SV_FRAME_NO_SPECULAR 4u  /* no specular: the sky's reflections and the lights' lobe (--no-specular) */
#define SV_FRAME_NO_RENORM   8u  /* do not scale sky specular by probe / sky irradiance */
#define SV_FRAME_BRICKS      16u /* --probe-path bricks: grids with SV_GRID_BRICKS are sampled from the bricks */

/* VULKAN_SCHNEE_light.mode on the GPU (sv_gpu_light.spot.z, as a float). */
#define SV_LIGHT_REALTIME 0u /* "realtime" or no extension: direct term always */
#define SV_LIGHT_BAKED    1u /* "baked": direct term only where the fallback probe 0 lights the surface */
#define SV_LIGHT_MIXED    2u /* "mixed": bounced light in the probes, direct term always (shadowed) */

/* Shadow maps (docs/engine.md "Shadows"): mixed and realtime lights get layers of one 2D-array depth
 * image, in light-instance order, while the layer budget lasts: a directional light one per cascade, a
 * spot light one layer, a point light (or a spot wider than SV_SPOT_SHADOW_MAX_ANGLE) six, one per cube
 * face. SV_MAX_SHADOW_LAYERS layers in all, shared by every kind of light; a sun gets the layers left
 * when fewer than its cascades are, a light that does not fit otherwise is unshadowed (one warning
 * naming it). */
#define SV_MAX_SHADOW_LAYERS 16
/* A directional light takes up to SV_MAX_SHADOW_CASCADES layers, one cascade each (--shadow-cascades,
 * default SV_SHADOW_DEFAULT_CASCADES): orthographic boxes around consecutive slices of the view's
 * depth range, near to far. The shader picks the first cascade whose box holds the point at least
 * SV_SHADOW_CASCADE_MARGIN texels inside its edge (room for the normal offset, <= 3.5 texels, and the
 * 3x3 PCF footprint, <= 2.5 texels); the last cascade takes what no earlier one holds. */
#define SV_MAX_SHADOW_CASCADES     4
#define SV_SHADOW_DEFAULT_CASCADES 4
#define SV_SHADOW_CASCADE_MARGIN   8.0f
#define SV_SPOT_SHADOW_MAX_ANGLE   1.0471976f /* 60 degrees: a wider outer cone is shadowed as a cube */
/* What a layer holds (sv_gpu_frame.shadow_params[k].w, as a float). */
#define SV_SHADOW_ORTHO 0u /* a directional light's cascade: orthographic box (the scene bounds when 1 cascade) */
#define SV_SHADOW_SPOT  1u /* a spot light: one perspective frustum around its cone */
#define SV_SHADOW_CUBE  2u /* one 90-degree face of a point light's cube: +X, -X, +Y, -Y, +Z, -Z from its first layer */

#define SV_TONEMAP_NONE        0u /* clamp only */
#define SV_TONEMAP_PBR_NEUTRAL 1u /* Khronos PBR Neutral (default) */
#define SV_TONEMAP_ACES        2u /* Narkowicz's ACES filmic fit */

/* ---------------------------------------------------------------- structs */
/* Per-frame uniform (std140, SV_BINDING_FRAME). */
SV_STRUCT(sv_gpu_frame)
{
    SV_MAT4(view_proj);     /* column-major, world -> Vulkan clip space (y down, z in [0,1]) */
    SV_MAT4(inv_view_proj); /* clip -> world (sky background directions) */
    SV_VEC4(camera_pos);    /* xyz world position, w = prefiltered sky mip count (0 = no sky) */
    SV_UINT(light_count);
    SV_UINT(debug_mode);           /* SV_DEBUG_* */
    SV_UINT(flags);                /* SV_FRAME_* */
    SV_UINT(probe_rebase);         /* subtracted from a nonzero draw.probe_index to give its probe-buffer
                                      entry: 0, or total - 1 when the buffer holds the fallback and the
                                      per-object slots only (docs/engine.md "Probe buffers") */
    SV_UINT(grid_count);           /* entries in the grid buffer (per-pixel mode) */
    SV_UINT(probe_mode);           /* SV_PROBE_MODE_*: override for every material, or _MATERIAL */
    SV_FLOAT(normal_bias);         /* per-pixel: sample point moved along n by this many grid spacings */
    SV_UINT(probe_representation); /* SV_PROBE_REP_*: override for every material, or _MATERIAL */
    /* Shadow map layer k (a light's layers start at its sv_gpu_light.spot.w): world -> light clip
     * space (x, y in [-1, 1] and z in [0, 1] after the divide by w). SV_SHADOW_ORTHO: an orthographic
     * box along the light, x, y around one cascade's slice of the view (the scene's world bounds with
     * one cascade), depth over the whole scene (w = 1); SV_SHADOW_SPOT / _CUBE: a perspective frustum
     * from the light's position (w = depth along the layer's axis). */
    SV_MAT4_ARRAY(shadow_view_proj, SV_MAX_SHADOW_LAYERS);
    /* x = world size of one shadow texel: ORTHO in metres (the larger of the two axes), SPOT / CUBE
     * per metre of depth along the layer's axis (2 tan(half fov) / resolution); y = ORTHO: 1 /
     * light-space depth range (metres), else 0; z = 1 / resolution (a texel in uv); w = SV_SHADOW_*. */
    SV_VEC4_ARRAY(shadow_params, SV_MAX_SHADOW_LAYERS);
}
SV_END(sv_gpu_frame)
SV_SIZE_CHECK(sv_gpu_frame, 1456)

/* Per-draw push constants (std430), one draw per mesh primitive of an object. */
SV_STRUCT(sv_gpu_draw)
{
    SV_MAT4(model);                  /* column-major object -> world */
    SV_VEC4_ARRAY(normal_matrix, 3); /* inverse-transpose of model's 3x3, three columns */
    SV_UINT(material_index);
    SV_UINT(probe_index); /* index into the probe buffer (0 = fallback) */
    SV_UINT(object_index);
    SV_UINT(flags); /* SV_DRAW_*, SV_DRAW_NODE_*_SHIFT fields */
}
SV_END(sv_gpu_draw)
SV_SIZE_CHECK(sv_gpu_draw, 128) /* the guaranteed push-constant range */

/* Per-draw push constants of the shadow pass (std430, shadow.vert): depth only. */
SV_STRUCT(sv_gpu_shadow_draw)
{
    SV_MAT4(light_mvp); /* column-major object -> light clip space (shadow_view_proj[layer] * model) */
}
SV_END(sv_gpu_shadow_draw)
SV_SIZE_CHECK(sv_gpu_shadow_draw, 64)

/* Material (std430, SV_BINDING_MATERIALS). */
SV_STRUCT(sv_gpu_material)
{
    SV_VEC4(base_color);    /* linear RGBA factor */
    SV_VEC4(emissive);      /* linear RGB emission (factor * strength), w unused */
    SV_FLOAT(sh_scale);     /* VULKAN_SCHNEE_materials.shScale, default 1.0 */
    SV_FLOAT(ambient_term); /* VULKAN_SCHNEE_materials.ambientTerm, default 0.1 */
    SV_FLOAT(metallic);
    SV_FLOAT(roughness);
    SV_INT(base_color_texture);    /* glTF texture index, -1 = none (set 1 holds it) */
    SV_INT(emissive_texture);      /* glTF texture index, -1 = none */
    SV_UINT(probe_mode);           /* SV_PROBE_MODE_OFF/OBJECT/PIXEL (VULKAN_SCHNEE_materials.probeMode) */
    SV_UINT(probe_representation); /* SV_PROBE_REP_SH/AMBIENT_CUBE (...probeRepresentation) */
}
SV_END(sv_gpu_material)
SV_SIZE_CHECK(sv_gpu_material, 64)

/* One SH probe, float storage (std430, SV_BINDING_PROBES). Index 0 is the fallback probe
 * (DESIGN.md §7). */
SV_STRUCT(sv_gpu_probe)
{
    SV_VEC4(params); /* x = max band (0..4), y = per-probe scale, z = 0 (the file's per-probe ambient
                        is not used: docs/shprobe-format.md), w = validity in [0, 1] */
    SV_VEC4_ARRAY(sh, SV_SH_MAX_COEFFS); /* radiance projection L_i, RGB in xyz; unused bands are 0 */
}
SV_END(sv_gpu_probe)
SV_SIZE_CHECK(sv_gpu_probe, 416)

/* The same probe in half storage (std430, SV_BINDING_PROBES_HALF; --probe-storage half): IEEE
 * half floats packed two per uint32 as GLSL's packHalf2x16 does (first value in the low bits). */
SV_STRUCT(sv_gpu_probe_half)
{
    SV_UINT_ARRAY(params, 2);             /* (max band, scale), (validity, 0) */
    SV_UVEC2_ARRAY(sh, SV_SH_MAX_COEFFS); /* (R, G), (B, 0) of L_i */
}
SV_END(sv_gpu_probe_half)
SV_SIZE_CHECK(sv_gpu_probe_half, 208)

/* One probe as an ambient cube, float storage (std430, SV_BINDING_CUBES; docs/ambient-cube.md §4,
 * §5): same indexing as the SH probes (0 = fallback), filled at load from each probe's SH by
 * pb_ambient_cube_from_sh (least squares) when a material or --probe-representation asks for it. */
SV_STRUCT(sv_gpu_cube)
{
    SV_VEC4(params);         /* x = band the cube was fitted from, y = per-probe scale, z = 0, w = validity */
    SV_VEC4_ARRAY(faces, 6); /* irradiance C_j, RGB in xyz, faces +X, -X, +Y, -Y, +Z, -Z (engine space) */
}
SV_END(sv_gpu_cube)
SV_SIZE_CHECK(sv_gpu_cube, 112)

/* The same cube in half storage (std430, SV_BINDING_CUBES_HALF; --probe-storage half), packed as
 * GLSL's packHalf2x16 (first value in the low bits). */
SV_STRUCT(sv_gpu_cube_half)
{
    SV_UINT_ARRAY(params, 2); /* (band, scale), (validity, 0) */
    SV_UVEC2_ARRAY(faces, 6); /* (R, G), (B, 0) of C_j */
}
SV_END(sv_gpu_cube_half)
SV_SIZE_CHECK(sv_gpu_cube_half, 56)

/* One probe grid for per-pixel sampling (std430, SV_BINDING_GRIDS), in glTF order. Cell (x, y, z)
 * has its centre at sv_cell_centre() (C, sv_probes.h) / cell_centre() (GLSL, gpu_types.glsl). */
SV_STRUCT(sv_gpu_grid)
{
    SV_VEC4(origin_spacing); /* xyz = min corner of cell (0,0,0), w = spacing (metres) */
    SV_VEC4_ARRAY(axes, 3);  /* rows: the grid's unit X, Y, Z axes in world space */
    SV_UVEC4(dims);          /* xyz = cell counts (octree: lattice extent in min cells), w = offset of
                                cell (0,0,0) (octree: of leaf 0, SV_LEAF_INTS each) in the cell buffer */
    SV_UVEC4(base);          /* x = probe-buffer index of the grid's probe 0 (octree: node 0; hanging
                                nodes follow the probes), y = offset of its visibility masks in the cell
                                buffer (octree: SV_LEAF_VIS_INTS per leaf), z = SV_GRID_* flags,
                                w = octree leaf count */
    SV_UVEC4(tree);          /* kd tree (SV_GRID_KDTREE): x = offset of split-tree node 0 in the cell buffer
                                (the file's nodes as stored), y = root level R, z, w = root cells along
                                x and y (ceil(dims / 2^R)); 0 otherwise */
    SV_UVEC4(bricks);        /* SV_GRID_BRICKS (docs/probe-bricks.md, docs/engine.md "Probe bricks"): x = z offset
                                of the grid's entries in the indirection texture, y = its pool's bricks along
                                x | along y << 16 (brick b at 5 (b mod px, (b / px) mod py, b / (px py))), z = z
                                offset of its bricks in each channel group's slab of the pool, w = SH coefficients
                                C | the slab's depth in texels << 8 (group g at z + g * slab); 0 otherwise */
}
SV_END(sv_gpu_grid)
SV_SIZE_CHECK(sv_gpu_grid, 128)
/* Cell buffer (SV_BINDING_CELL_INDEX): int32 per cell, x + y*X + z*X*Y from dims.w on, the grid's
 * own probe index or -1 (the .shprobe occupancy grid as stored), then the visibility masks. */

/* A KHR_lights_punctual light in world space (std430, SV_BINDING_LIGHTS). */
SV_STRUCT(sv_gpu_light)
{
    SV_VEC4(position_range); /* xyz world position, w = range (0 = infinite) */
    SV_VEC4(direction_type); /* xyz unit direction the light points to, w = type (0 dir, 1 point, 2 spot) */
    SV_VEC4(color);          /* rgb = colour * intensity (lux for directional, candela otherwise),
                                w = a shadowed directional light's cascade count (its layers from spot.w) */
    SV_VEC4(spot);           /* x = angle scale, y = angle offset (KHR_lights_punctual spot formula),
                                z = SV_LIGHT_* mode (VULKAN_SCHNEE_light.mode: 0 realtime, 1 baked, 2 mixed),
                                w = first shadow map layer (mixed/realtime lights), -1 = unshadowed */
}
SV_END(sv_gpu_light)
SV_SIZE_CHECK(sv_gpu_light, 64)

/* Probe-view instance (std430, SV_BINDING_CELLS): centre + radius, probe.x = probe-buffer index,
 * probe.y = grid index, probe.z = an outline's packed levels lx | ly << 8 | lz << 16 (its edges are 2^l_a
 * grid spacings: 0 for a dense cell, the box of an octree or kd tree leaf). */
SV_STRUCT(sv_gpu_cell)
{
    SV_VEC4(center_radius);
    SV_UVEC4(probe);
}
SV_END(sv_gpu_cell)
SV_SIZE_CHECK(sv_gpu_cell, 32)

/* Tone-mapping pass push constants. */
SV_STRUCT(sv_gpu_tonemap)
{
    SV_FLOAT(exposure);   /* linear multiplier applied before the operator */
    SV_UINT(op);          /* SV_TONEMAP_* */
    SV_UINT(encode_srgb); /* 1 = shader applies the sRGB transfer (target is UNORM), 0 = hardware does */
    SV_UINT(pad_);
}
SV_END(sv_gpu_tonemap)
SV_SIZE_CHECK(sv_gpu_tonemap, 16)

#if !defined(GL_core_profile)
/* The one table of probe-mode names (index = SV_PROBE_MODE_* value): the glTF's
 * VULKAN_SCHNEE_materials.probeMode values are the names below SV_PROBE_MODE_MATERIAL; the command
 * line's --probe-mode takes all of them. NULL past the end. */
static inline const char *sv_probe_mode_name(uint32_t mode)
{
    static const char *const names[SV_PROBE_MODE_COUNT] = {"off", "object", "pixel", "material"};
    return mode < SV_PROBE_MODE_COUNT ? names[mode] : NULL;
}

/* SV_PROBE_MODE_* for a name, or -1. `with_material`: accept "material" (the command line). */
static inline int sv_probe_mode_from_name(const char *name, int with_material)
{
    uint32_t n = with_material ? SV_PROBE_MODE_COUNT : SV_PROBE_MODE_MATERIAL;
    for (uint32_t m = 0; m < n; ++m)
        if (strcmp(name, sv_probe_mode_name(m)) == 0) return (int)m;
    return -1;
}

/* The one table of probe-representation names (index = SV_PROBE_REP_* value): the glTF's
 * VULKAN_SCHNEE_materials.probeRepresentation values are the names below SV_PROBE_REP_MATERIAL; the
 * command line's --probe-representation takes all of them. NULL past the end. */
static inline const char *sv_probe_representation_name(uint32_t rep)
{
    static const char *const names[SV_PROBE_REP_COUNT] = {"sh", "ambientCube", "material"};
    return rep < SV_PROBE_REP_COUNT ? names[rep] : NULL;
}

/* SV_PROBE_REP_* for a name, or -1. `with_material`: accept "material" (the command line). */
static inline int sv_probe_representation_from_name(const char *name, int with_material)
{
    uint32_t n = with_material ? SV_PROBE_REP_COUNT : SV_PROBE_REP_MATERIAL;
    for (uint32_t m = 0; m < n; ++m)
        if (strcmp(name, sv_probe_representation_name(m)) == 0) return (int)m;
    return -1;
}

/* "off, object or pixel" style list of the names, for messages. */
static inline void sv_probe_mode_list(char *out, size_t cap, int with_material)
{
    uint32_t n = with_material ? SV_PROBE_MODE_COUNT : SV_PROBE_MODE_MATERIAL;
    size_t o = 0;
    if (cap) out[0] = '\0';
    for (uint32_t m = 0; m < n && o + 1 < cap; ++m) {
        const char *sep = m == 0 ? "" : m + 1 == n ? " or " : ", ";
        int w = snprintf(out + o, cap - o, "%s%s", sep, sv_probe_mode_name(m));
        if (w < 0) break;
        o += (size_t)w;
    }
}
#endif

#endif
