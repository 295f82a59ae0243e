// GPU-side data layout of schnee-view; mirrors engine/src/sv_gpu_types.h (sizes asserted there).
#ifndef SV_GPU_TYPES_GLSL
#define SV_GPU_TYPES_GLSL

#define SV_SH_MAX_COEFFS 25

#define SV_DEBUG_NONE 0u
#define SV_DEBUG_PROBE_COLOR 1u
#define SV_DEBUG_PROBE_INDEX 2u
#define SV_DEBUG_NORMALS 3u

#define SV_FRAME_NO_DIRECT 1u

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
    uint pad0;
    uint pad1;
};

struct sv_gpu_probe {
    vec4 params; // x = max band, y = per-probe scale, z = per-probe ambient
    vec4 sh[SV_SH_MAX_COEFFS];
};

struct sv_gpu_light {
    vec4 position_range;
    vec4 direction_type;
    vec4 color;
    vec4 spot;
};

#ifdef SV_SCENE_BINDINGS
layout(std140, set = 0, binding = 0) uniform FrameBlock {
    mat4 view_proj;
    vec4 camera_pos;
    uint light_count;
    uint debug_mode;
    uint flags;
    uint probe_count;
} frame;

layout(std430, set = 0, binding = 1) readonly buffer MaterialBlock { sv_gpu_material materials[]; };
layout(std430, set = 0, binding = 2) readonly buffer ProbeBlock { sv_gpu_probe probes[]; };
layout(std430, set = 0, binding = 3) readonly buffer LightBlock { sv_gpu_light lights[]; };
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
    uint pad;
} draw;
#endif

#endif
