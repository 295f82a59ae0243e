// The brick debug views (--debug brick-level | brick-validity, with --probe-path bricks; docs/engine.md
// "Probe view"): what the per-pixel path's lookup finds at a surface point. The first grid whose bricks
// hold the lookup point (the point moved by the normal bias, as brick_surface_irradiance; steps 1-3,
// brick_locate) gives the pixel's colour:
//   brick-level     brick_level_colour(L) of the brick, flat;
//   brick-validity  brick_validity_colour(D) of the plain filtered sample at x (step 4's D: the share of
//                   valid probes in the file's weights there), magenta where D <= 0;
// BRICK_NONE where no brick holds the point (dense grids, tetrahedra, outside every tree).
#ifndef SV_BRICK_DEBUG_GLSL
#define SV_BRICK_DEBUG_GLSL
#include "brick_view_colours.glsl"
#include "bricks_surface.glsl"

vec3 brick_debug_colour(vec3 p_surface, vec3 n, uint mode) {
    uint want = SV_GRID_OCTREE | SV_GRID_BRICKS;
    for (uint g = 0u; g < frame.grid_count; ++g) {
        sv_gpu_grid gr = grids[g];
        if ((frame.flags & SV_FRAME_BRICKS) == 0u || (gr.base.z & want) != want) continue;
        vec3 p = p_surface + n * (frame.normal_bias * gr.origin_spacing.w);
        uvec4 e;
        uvec3 r0;
        vec3 x;
        if (!brick_locate(gr, p, e, r0, x)) continue;
        if (mode == SV_DEBUG_BRICK_LEVEL) return brick_level_colour(e.x >> 27u);
        uint b = e.x & 0x7ffffffu, px = gr.bricks.y & 0xffffu, py = gr.bricks.y >> 16u;
        uvec3 ob = 5u * uvec3(b % px, (b / px) % py, b / (px * py)) + uvec3(0u, 0u, gr.bricks.z);
        float D = textureLod(brick_pool, (vec3(ob) + 0.5 + x) / vec3(textureSize(brick_pool, 0)), 0.0).w;
        return brick_validity_colour(D);
    }
    return BRICK_NONE;
}

#endif
