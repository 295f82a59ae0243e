// Probe bricks per pixel (docs/probe-bricks.md "Sampling rule", --probe-path bricks): a line-by-line
// mirror of pb_bricks_locate() / pb_bricks_filter() / pb_bricks_sample() of native/src/pb_bricks.c, the
// one C definition of the field, with the hardware's trilinear filter doing pb_bricks_filter (its 8-bit
// sub-texel weights are pb_bricks_sample_bits(..., 8)). No search, no loop over leaves: one indirection
// fetch (two to eight more only within 0.01 min cell of an empty cell's lower faces) and one filtered
// fetch per channel group. This session: the movable-object rule (step 4, the plain sample: no back-face
// weight, no visibility record); steps 5's anti-leak weights are not carried yet (docs/engine.md).
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

// E(n) of grid gr's bricks at p (moved by normal_bias min cells along n as octree_irradiance does), not
// clamped; false where the bricks give no value (outside, no leaf, or D <= 0: the caller tries the
// next grid, then probe 0).
bool brick_irradiance(sv_gpu_grid gr, vec3 p_surface, vec3 n, out vec3 e_out) {
    e_out = vec3(0.0);
    // 1. Lattice coordinates, the lattice's margin of 0.01 min cells, clamped into [0, E].
    float h = gr.origin_spacing.w;
    vec3 p = p_surface + n * (frame.normal_bias * h);
    vec3 u = (p - gr.origin_spacing.xyz) / h;
    vec3 dims = vec3(gr.dims.xyz);
    if (any(lessThan(u, vec3(-0.01))) || any(greaterThan(u, dims + 0.01))) return false;
    u = clamp(u, vec3(0.0), dims);
    // 2. The min cell (max faces closed), its entry; not occupied: the face margin (masks x, y, xy, z,
    //    ...: the first occupied cell q - m whose lower faces u lies within 0.01 above, u clamped into it).
    uvec3 q = uvec3(min(floor(u), dims - 1.0));
    uvec4 e = brick_entry(gr, q);
    bool found = brick_occupied(e, q);
    for (uint m = 1u; !found && m < 8u; ++m) {
        uvec3 r = q;
        bool ok = true;
        for (int a = 0; a < 3; ++a) {
            if (((m >> uint(a)) & 1u) == 0u) continue;
            if (!(q[a] > 0u && u[a] - float(q[a]) < 0.01)) ok = false;
            r[a] = q[a] - 1u;
        }
        if (!ok) continue;
        uvec4 er = brick_entry(gr, r);
        if (!brick_occupied(er, r)) continue;
        q = r;
        u = clamp(u, vec3(q), vec3(q) + 1.0);
        e = er;
        found = true;
    }
    if (!found || e.x == 0xffffffffu) return false;
    // 3. The brick and the brick-local texel coordinate x in [0, 4]^3.
    uint b = e.x & 0x7ffffffu, L = e.x >> 27u;
    uvec3 r0 = (q >> (L + 2u)) << (L + 2u);
    vec3 x = clamp((u - vec3(r0)) / float(1u << L), vec3(0.0), vec3(4.0));
    // 4. Plain sample: texel centres (origin_b + 0.5 + x) / pool size, one LINEAR fetch per channel group
    //    (group g in its slab, z + g * slab); D <= 0: no value. E(n) = sum_i A_l(i) Y_i(n) N_i / D.
    uint px = gr.bricks.y & 0xffffu, py = gr.bricks.y >> 16u;
    uvec3 ob = 5u * uvec3(b % px, (b / px) % py, b / (px * py)) + uvec3(0u, 0u, gr.bricks.z);
    vec3 size = vec3(textureSize(brick_pool, 0));
    vec3 tc = (vec3(ob) + 0.5 + x) / size;
    float slab = float(gr.bricks.w >> 8u) / size.z;
    vec4 t0 = textureLod(brick_pool, tc, 0.0); // N_0 (RGB), D
    if (!(t0.w > 0.0)) return false;
    uint C = gr.bricks.w & 255u;
    uint band = C >= 25u ? 4u : C >= 16u ? 3u : C >= 9u ? 2u : C >= 4u ? 1u : 0u;
    float AY[25];
    sh_lambert_basis(band, n, AY);
    vec3 s = AY[0] * t0.rgb;
    uint groups = (3u * C + 4u) / 4u; // ceil((3C + 1) / 4)
    for (uint g = 1u; g < groups; ++g) {
        vec4 t = textureLod(brick_pool, tc + vec3(0.0, 0.0, float(g) * slab), 0.0);
        for (uint j = 0u; j < 4u; ++j) { // channel 4g + j = N_i colour k, i = 1 + (4g + j - 4) / 3
            uint c = 4u * g + j - 4u, i = 1u + c / 3u;
            if (i < C) s[c % 3u] += AY[i] * t[j];
        }
    }
    e_out = s / t0.w;
    return true;
}

#endif
