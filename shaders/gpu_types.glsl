// GPU-side data layout of schnee-view; mirrors engine/src/sv_gpu_types.h (sizes asserted there).
#ifndef SV_GPU_TYPES_GLSL
#define SV_GPU_TYPES_GLSL

#define SV_SH_MAX_COEFFS 25

#define SV_DEBUG_NONE 0u
#define SV_DEBUG_PROBE_COLOR 1u
#define SV_DEBUG_PROBE_INDEX 2u
#define SV_DEBUG_NORMALS 3u

#define SV_PROBE_MODE_OFF 0u
#define SV_PROBE_MODE_OBJECT 1u
#define SV_PROBE_MODE_PIXEL 2u
#define SV_PROBE_MODE_MATERIAL 3u

#define SV_DRAW_MIRRORED 1u

#define SV_FRAME_NO_DIRECT 1u
#define SV_FRAME_SKY 2u
#define SV_FRAME_NO_SPECULAR 4u
#define SV_FRAME_NO_RENORM 8u

#define SV_TONEMAP_NONE 0u
#define SV_TONEMAP_PBR_NEUTRAL 1u
#define SV_TONEMAP_ACES 2u

struct sv_gpu_material {
    vec4 base_color;
    vec4 emissive;
    float sh_scale;
    float ambient_term;
    float metallic;
    float roughness;
    int base_color_texture;
    int emissive_texture;
    uint probe_mode;
    uint pad1;
};

struct sv_gpu_probe {
    vec4 params; // x = max band, y = per-probe scale, z = per-probe ambient, w = validity
    vec4 sh[SV_SH_MAX_COEFFS];
};

struct sv_gpu_probe_half {
    uint params[2];               // packHalf2x16(band, scale), packHalf2x16(validity, ambient)
    uvec2 sh[SV_SH_MAX_COEFFS];   // packHalf2x16(R, G), packHalf2x16(B, 0)
};

struct sv_gpu_grid {
    vec4 origin_spacing;
    vec4 axes[3];
    uvec4 dims;   // w = offset into the cell buffer
    uvec4 base;   // x = probe-buffer index of the grid's probe 0, y = offset of its visibility masks in cell_probe
};

struct sv_gpu_light {
    vec4 position_range;
    vec4 direction_type;
    vec4 color;
    vec4 spot; // x = angle scale, y = angle offset, z = 1 baked / 0 realtime (VULKAN_SCHNEE_light.mode)
};

#ifdef SV_SCENE_BINDINGS
// Probe storage chosen at pipeline creation (--probe-storage): false = float (binding 2),
// true = half (binding 8).
layout(constant_id = 0) const bool SV_HALF_PROBES = false;

layout(std140, set = 0, binding = 0) uniform FrameBlock {
    mat4 view_proj;
    mat4 inv_view_proj;
    vec4 camera_pos; // w = prefiltered sky mip count (0 = no sky)
    uint light_count;
    uint debug_mode;
    uint flags;
    uint probe_count;
    uint grid_count;
    uint probe_mode;
    float normal_bias;
    float pad;
} frame;

layout(std430, set = 0, binding = 1) readonly buffer MaterialBlock { sv_gpu_material materials[]; };
layout(std430, set = 0, binding = 2) readonly buffer ProbeBlock { sv_gpu_probe probes[]; };
layout(std430, set = 0, binding = 3) readonly buffer LightBlock { sv_gpu_light lights[]; };
layout(std430, set = 0, binding = 6) readonly buffer GridBlock { sv_gpu_grid grids[]; };
// Cell -> probe indices of every grid, then one neighbour-visibility mask per cell (grids[g].base.y).
layout(std430, set = 0, binding = 7) readonly buffer CellIndexBlock { int cell_probe[]; };
layout(std430, set = 0, binding = 8) readonly buffer ProbeHalfBlock { sv_gpu_probe_half probes_half[]; };
// Sky: equirect radiance, mip k = GGX prefiltered at roughness k / (mips - 1); BRDF LUT (NoV, roughness).
layout(set = 0, binding = 9) uniform sampler2D sky_tex;
layout(set = 0, binding = 10) uniform sampler2D brdf_lut;
// Set 1: the draw's material textures (a 1x1 white texel when the material has none).
layout(set = 1, binding = 0) uniform sampler2D base_color_tex;
layout(set = 1, binding = 1) uniform sampler2D emissive_tex;

layout(push_constant, std430) uniform DrawBlock {
    mat4 model;
    vec4 normal_col0;
    vec4 normal_col1;
    vec4 normal_col2;
    uint material_index;
    uint probe_index;
    uint object_index;
    uint flags; // SV_DRAW_MIRRORED: det(model 3x3) < 0, front faces wind clockwise (glTF)
} draw;
#endif

#endif
