// Probe bricks per pixel (docs/probe-bricks.md "Sampling rule", --probe-path bricks): a line-by-line
// mirror of pb_bricks_locate() / pb_bricks_filter() / pb_bricks_sample() of native/src/pb_bricks.c, the
// one C definition of the field, with the hardware's trilinear filter doing pb_bricks_filter (its 8-bit
// sub-texel weights are pb_bricks_sample_bits(..., 8)). No search, no loop over leaves: one indirection
// fetch (two to eight more only within 0.01 min cell of an empty cell's lower faces) and one filtered
// fetch per channel group. The indirection helpers are here; steps 1-6 with step 5's anti-leak weights
// (back faces, visibility records) are in bricks_surface.glsl.
#ifndef SV_BRICKS_GLSL
#define SV_BRICKS_GLSL
#include "sh.glsl"

// The indirection entry of the level-0 region holding min cell q of grid gr (grids along z).
uvec4 brick_entry(sv_gpu_grid gr, uvec3 q) {
    return texelFetch(brick_index, ivec3(q >> 2u) + ivec3(0, 0, int(gr.bricks.x)), 0);
}

// Whether a leaf holds min cell q: its occupancy bit i + 4j + 16k in the entry's y (bits 0-31) and z.
bool brick_occupied(uvec4 e, uvec3 q) {
    uvec3 l = q & 3u;
    uint bit = l.x + 4u * l.y + 16u * l.z;
    return ((bit < 32u ? e.y >> bit : e.z >> (bit - 32u)) & 1u) != 0u;
}

// E(n) of a grid's bricks at a surface point: brick_surface_irradiance() in bricks_surface.glsl (steps 1-6
// with the anti-leak rules of step 5, mirroring pb_bricks_sample_surface()).

#endif
