// GLSL side of the GPU contract: the structs, enums and binding numbers come from sv_gpu.h (shared
// with the C engine); this file only declares the descriptor blocks with them.
#ifndef SV_GPU_TYPES_GLSL
#define SV_GPU_TYPES_GLSL

#include "sv_gpu.h"

#ifdef SV_SCENE_BINDINGS
// Probe storage chosen at pipeline creation (--probe-storage): false = float, true = half.
layout(constant_id = SV_CONSTANT_HALF_PROBES) const bool SV_HALF_PROBES = false;

layout(std140, set = SV_SET_SCENE, binding = SV_BINDING_FRAME) uniform FrameBlock { sv_gpu_frame frame; };
layout(std430, set = SV_SET_SCENE, binding = SV_BINDING_MATERIALS) readonly buffer MaterialBlock {
    sv_gpu_material materials[];
};
layout(std430, set = SV_SET_SCENE, binding = SV_BINDING_PROBES) readonly buffer ProbeBlock { sv_gpu_probe probes[]; };
layout(std430, set = SV_SET_SCENE, binding = SV_BINDING_LIGHTS) readonly buffer LightBlock { sv_gpu_light lights[]; };
layout(std430, set = SV_SET_SCENE, binding = SV_BINDING_CELLS) readonly buffer CellBlock { sv_gpu_cell cells[]; };
layout(std430, set = SV_SET_SCENE, binding = SV_BINDING_GRIDS) readonly buffer GridBlock { sv_gpu_grid grids[]; };
// Cell -> probe indices of every grid, then one neighbour-visibility mask per cell (grids[g].base.y).
layout(std430, set = SV_SET_SCENE, binding = SV_BINDING_CELL_INDEX) readonly buffer CellIndexBlock { int cell_probe[]; };
layout(std430, set = SV_SET_SCENE, binding = SV_BINDING_PROBES_HALF) readonly buffer ProbeHalfBlock {
    sv_gpu_probe_half probes_half[];
};
// Ambient cubes of the same probes (docs/ambient-cube.md §5), float or half like the SH; one zero
// entry when no material and no --probe-representation asked for cubes.
layout(std430, set = SV_SET_SCENE, binding = SV_BINDING_CUBES) readonly buffer CubeBlock { sv_gpu_cube cubes[]; };
layout(std430, set = SV_SET_SCENE, binding = SV_BINDING_CUBES_HALF) readonly buffer CubeHalfBlock {
    sv_gpu_cube_half cubes_half[];
};
// Sky: equirect radiance, mip k = GGX prefiltered at roughness k / (mips - 1); BRDF LUT (NoV, roughness).
layout(set = SV_SET_SCENE, binding = SV_BINDING_SKY) uniform sampler2D sky_tex;
layout(set = SV_SET_SCENE, binding = SV_BINDING_BRDF_LUT) uniform sampler2D brdf_lut;
// Shadow maps (docs/engine.md "Shadows"): depth from the light, one layer per cascade of a shadowed
// directional light, one per spot light, six per point light (cube faces), sampled with a LESS_OR_EQUAL comparison (1 = lit); a
// 1x1 layer when no light is shadowed.
layout(set = SV_SET_SCENE, binding = SV_BINDING_SHADOW) uniform sampler2DArrayShadow shadow_tex;
// Probe bricks (docs/probe-bricks.md, --probe-path bricks): the pool of N/D texels (linear filter, clamp
// to edge; one slab of z per channel group) and the RGBA32UI indirection (read with texelFetch). 1x1x1
// stand-ins when the bricks are off.
layout(set = SV_SET_SCENE, binding = SV_BINDING_BRICK_POOL) uniform sampler3D brick_pool;
layout(set = SV_SET_SCENE, binding = SV_BINDING_BRICK_INDEX) uniform usampler3D brick_index;
// Step 5 (engine/src/sv_bricks_vis.h): 4 uint per brick (x = uint offset of its first visibility record
// here, y / z = blocked-cell bits; row = the indirection entry's w), then 16 uint per 64-B record.
layout(std430, set = SV_SET_SCENE, binding = SV_BINDING_BRICK_VIS) readonly buffer BrickVisBlock { uint brick_vis[]; };
// Set 1: the draw's material textures (a 1x1 white texel when the material has none).
layout(set = SV_SET_MATERIAL, binding = SV_BINDING_BASE_COLOR_TEX) uniform sampler2D base_color_tex;
layout(set = SV_SET_MATERIAL, binding = SV_BINDING_EMISSIVE_TEX) uniform sampler2D emissive_tex;

layout(push_constant, std430) uniform DrawBlock { sv_gpu_draw draw; };

// World-space centre of cell c of grid g: origin + sum_i (c_i + 0.5) * spacing * axis_i. The C twin
// is sv_cell_centre() in engine/src/sv_probes.h.
vec3 cell_centre(sv_gpu_grid g, ivec3 c) {
    vec3 l = (vec3(c) + 0.5) * g.origin_spacing.w;
    return g.origin_spacing.xyz + l.x * g.axes[0].xyz + l.y * g.axes[1].xyz + l.z * g.axes[2].xyz;
}
#endif

#endif
