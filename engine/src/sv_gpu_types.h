/* GPU-side data layout of schnee-view, mirrored one-to-one by shaders/gpu_types.glsl.
 *
 * Every struct here is read by a shader through std430 (storage buffers, push constants) or
 * std140 (the frame uniform); all members are 16-byte vec4-aligned groups so both layouts agree
 * with the C layout. The static asserts pin the sizes the GLSL side assumes: change both files
 * together.
 */
#ifndef SV_GPU_TYPES_H
#define SV_GPU_TYPES_H

#include <assert.h>
#include <stdint.h>

#define SV_SH_MAX_COEFFS 25 /* L <= 4, mirrors PB_SH_MAX_COEFFS */

/* Debug views (sv_gpu_frame.debug_mode). */
enum {
    SV_DEBUG_NONE = 0,        /* shaded */
    SV_DEBUG_PROBE_COLOR = 1, /* each object in a colour hashed from its probe index */
    SV_DEBUG_PROBE_INDEX = 2, /* R = probe index as a float (exact in EXR output), G = B = 0 */
    SV_DEBUG_NORMALS = 3,     /* world normal * 0.5 + 0.5 */
};

/* Probe lighting mode of a material (VULKAN_SCHNEE_materials.probeMode) or of the whole frame
 * (--probe-mode, sv_gpu_frame.probe_mode). */
enum {
    SV_PROBE_MODE_OFF = 0,      /* no baked probe: the fallback probe 0 (the sky's SH when there is a sky) */
    SV_PROBE_MODE_OBJECT = 1,   /* one probe per object, at the centre of its bounds (default) */
    SV_PROBE_MODE_PIXEL = 2,    /* per fragment: trilinear over the grid cells (DESIGN.md §7) */
    SV_PROBE_MODE_MATERIAL = 3, /* frame only: each material's own mode */
};

/* Frame flags (sv_gpu_frame.flags). */
enum {
    SV_FRAME_NO_DIRECT = 1u << 0,   /* skip KHR_lights_punctual direct light */
    SV_FRAME_SKY = 1u << 1,         /* a sky is loaded: background + image-based specular */
    SV_FRAME_NO_SPECULAR = 1u << 2, /* skip the sky's specular reflections (--no-specular) */
    SV_FRAME_NO_RENORM = 1u << 3,   /* do not scale sky specular by probe / sky irradiance */
};

/* Per-frame uniform (std140, set 0 binding 0). */
typedef struct sv_gpu_frame {
    float view_proj[16];     /* column-major, world -> Vulkan clip space (y down, z in [0,1]) */
    float inv_view_proj[16]; /* clip -> world (sky background directions) */
    float camera_pos[4];     /* xyz world position, w = prefiltered sky mip count (0 = no sky) */
    uint32_t light_count;
    uint32_t debug_mode;  /* SV_DEBUG_* */
    uint32_t flags;       /* SV_FRAME_* */
    uint32_t probe_count; /* entries in the probe buffer, fallback included */
    uint32_t grid_count;  /* entries in the grid buffer (per-pixel mode) */
    uint32_t probe_mode;  /* SV_PROBE_MODE_*: override for every material, or _MATERIAL */
    float normal_bias;    /* per-pixel: sample point moved along n by this many grid spacings */
    float pad_;
} sv_gpu_frame;
static_assert(sizeof(sv_gpu_frame) == 176, "sv_gpu_frame must match gpu_types.glsl");

#define SV_DRAW_MIRRORED 1u

/* Per-draw push constants (std430), one draw per mesh primitive of an object. */
typedef struct sv_gpu_draw {
    float model[16];         /* column-major object -> world */
    float normal_matrix[12]; /* inverse-transpose of model's 3x3, as three vec4 columns */
    uint32_t material_index;
    uint32_t probe_index; /* index into the probe buffer (0 = fallback) */
    uint32_t object_index;
    uint32_t flags; /* SV_DRAW_MIRRORED: det(model 3x3) < 0, clockwise front faces (glTF) */
} sv_gpu_draw;
static_assert(sizeof(sv_gpu_draw) == 128, "sv_gpu_draw must fit the guaranteed 128-byte push range");

/* Material (std430, set 0 binding 1). */
typedef struct sv_gpu_material {
    float base_color[4]; /* linear RGBA factor */
    float emissive[4];   /* linear RGB emission (factor * strength), w unused */
    float sh_scale;      /* VULKAN_SCHNEE_materials.shScale, default 1.0 */
    float ambient_term;  /* VULKAN_SCHNEE_materials.ambientTerm, default 0.1 */
    float metallic;
    float roughness;
    int32_t base_color_texture; /* glTF texture index, -1 = none (set 1 binding 0 holds it) */
    int32_t emissive_texture;   /* glTF texture index, -1 = none (set 1 binding 1 holds it) */
    uint32_t probe_mode;        /* SV_PROBE_MODE_OFF/OBJECT/PIXEL (VULKAN_SCHNEE_materials.probeMode) */
    uint32_t pad_;
} sv_gpu_material;
static_assert(sizeof(sv_gpu_material) == 64, "sv_gpu_material must match gpu_types.glsl");

/* One SH probe, float storage (std430, set 0 binding 2). Index 0 is the fallback probe
 * (DESIGN.md §7). */
typedef struct sv_gpu_probe {
    float params[4];               /* x = max band (0..4), y = per-probe scale, z = per-probe ambient,
                                           w = validity in [0, 1] (.shprobe v2; 1 for v1) */
    float sh[SV_SH_MAX_COEFFS][4]; /* radiance projection L_i, RGB in xyz; unused bands are 0 */
} sv_gpu_probe;
static_assert(sizeof(sv_gpu_probe) == 416, "sv_gpu_probe must match gpu_types.glsl");

/* The same probe in half storage (std430, set 0 binding 8; --probe-storage half): IEEE half
 * floats packed two per uint32 as GLSL's packHalf2x16 does (first value in the low 16 bits). */
typedef struct sv_gpu_probe_half {
    uint32_t params[2];               /* (max band, scale), (validity, ambient) */
    uint32_t sh[SV_SH_MAX_COEFFS][2]; /* (R, G), (B, 0) of L_i */
} sv_gpu_probe_half;
static_assert(sizeof(sv_gpu_probe_half) == 208, "sv_gpu_probe_half must match gpu_types.glsl");

/* One probe grid for per-pixel sampling (std430, set 0 binding 6), in glTF order. */
typedef struct sv_gpu_grid {
    float origin_spacing[4]; /* xyz = min corner of cell (0,0,0), w = spacing (metres) */
    float axes[3][4];        /* rows: the grid's unit X, Y, Z axes in world space */
    uint32_t dims[4];        /* xyz = cell counts, w = offset of cell (0,0,0) in the cell buffer */
    uint32_t base[4];        /* x = probe-buffer index of the grid's probe 0 */
} sv_gpu_grid;
static_assert(sizeof(sv_gpu_grid) == 96, "sv_gpu_grid must match gpu_types.glsl");
/* Cell buffer (set 0 binding 7): int32 per cell, x + y*X + z*X*Y from dims.w on, the grid's own
 * probe index or -1 (the .shprobe occupancy grid as stored). */

/* A KHR_lights_punctual light in world space (std430, set 0 binding 3). */
typedef struct sv_gpu_light {
    float position_range[4]; /* xyz world position, w = range (0 = infinite) */
    float direction_type[4]; /* xyz unit direction the light points to, w = type (0 dir, 1 point, 2 spot) */
    float color[4];          /* rgb = colour * intensity (lux for directional, candela otherwise) */
    float spot[4];           /* x = angle scale, y = angle offset (KHR_lights_punctual spot formula),
                                 z = 1 for a baked light (VULKAN_SCHNEE_light.mode; no direct term where
                                 a baked probe lights the surface), 0 realtime */
} sv_gpu_light;
static_assert(sizeof(sv_gpu_light) == 64, "sv_gpu_light must match gpu_types.glsl");

/* Tone-mapping pass push constants. */
typedef struct sv_gpu_tonemap {
    float exposure;       /* linear multiplier applied before the operator */
    uint32_t op;          /* SV_TONEMAP_* */
    uint32_t encode_srgb; /* 1 = shader applies the sRGB transfer (target is UNORM), 0 = hardware does */
    uint32_t pad_;
} sv_gpu_tonemap;
static_assert(sizeof(sv_gpu_tonemap) == 16, "sv_gpu_tonemap must match gpu_types.glsl");

enum {
    SV_TONEMAP_NONE = 0,        /* clamp only */
    SV_TONEMAP_PBR_NEUTRAL = 1, /* Khronos PBR Neutral (default) */
    SV_TONEMAP_ACES = 2,        /* Narkowicz's ACES filmic fit */
};

#endif
