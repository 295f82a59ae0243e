// Probe bricks per pixel (docs/probe-bricks.md "Sampling rule", --probe-path bricks): a line-by-line
// mirror of pb_bricks_locate() / pb_bricks_filter() / pb_bricks_sample() of native/src/pb_bricks.c, the
// one C definition of the field, with the hardware's trilinear filter doing pb_bricks_filter (its 8-bit
// sub-texel weights are pb_bricks_sample_bits(..., 8)). No search, no loop over leaves: one indirection
// fetch (two to eight more only within 0.01 min cell of an empty cell's lower faces) and one filtered
// fetch per channel group. The indirection helpers are here; steps 1-6 with step 5's anti-leak weights
// (back faces, visibility records) are in bricks_surface.glsl.
#ifndef SV_BRICKS_GLSL
#define SV_BRICKS_GLSL
#extension GL_EXT_control_flow_attributes : require // [[unroll]]
#include "sh.glsl"

// The most channel groups of a texel: ceil((3 * 25 + 1) / 4) = 19 (L4).
#define SV_BRICK_GROUPS_MAX 19u

// SV_FOR_GROUPS(g, groups) { ... }: a loop over the channel groups g = 1 .. groups - 1. The build of mesh.frag
// with SV_UNROLL_GROUPS (mesh.frag.unrolled.inc, which GPUs take: sv_pipelines.c) loops to the constant bound
// SV_BRICK_GROUPS_MAX and breaks at the grid's count, under [[unroll]]: the compiler unrolls it and every index
// into AY and the colour sum (brick_group_add) is a constant, so they stay in registers. Bounded by the grid's
// count, they are indexed at run time, which puts them in local memory on a GPU: 1.45-1.95x the per-pixel
// time on an NVIDIA H200. On lavapipe (a CPU device) the unrolled form costs 1.6-1.9x instead, so the
// plain loop is its build (bench/results/engine_gpu.md "Probe bricks (issue 30)").
#ifdef SV_UNROLL_GROUPS
#define SV_FOR_GROUPS(g, groups)                                                                                      \
    [[unroll]] for (uint g = 1u; g < SV_BRICK_GROUPS_MAX; ++g) if (g >= (groups)) break; else
#else
#define SV_FOR_GROUPS(g, groups) for (uint g = 1u; g < (groups); ++g)
#endif

// s += the SH channels of group g >= 1 of a texel t (channel 4g + j = N_i colour k, i = 1 + (4g + j - 4) / 3),
// weighted by AY (in an SV_FOR_GROUPS loop).
void brick_group_add(uint g, vec4 t, uint C, float AY[25], inout vec3 s)
{
    [[unroll]] for (uint j = 0u; j < 4u; ++j) {
        uint c = 4u * g + j - 4u, i = 1u + c / 3u;
        if (i < C) s[c % 3u] += AY[i] * t[j];
    }
}

// The indirection entry of the level-0 region holding min cell q of grid gr (grids along z).
uvec4 brick_entry(sv_gpu_grid gr, uvec3 q)
{
    return texelFetch(brick_index, ivec3(q >> 2u) + ivec3(0, 0, int(gr.bricks.x)), 0);
}

// Whether a leaf holds min cell q: its occupancy bit i + 4j + 16k in the entry's y (bits 0-31) and z.
bool brick_occupied(uvec4 e, uvec3 q)
{
    uvec3 l = q & 3u;
    uint bit = l.x + 4u * l.y + 16u * l.z;
    return ((bit < 32u ? e.y >> bit : e.z >> (bit - 32u)) & 1u) != 0u;
}

// pb_bricks_separable(): whether 8 nonnegative corner weights w are trilinear ones up to scale: with
// M_a(b) = sum of w_k over bit_a(k) = b, w_k (sum w)^2 = prod_a M_a(bit_a(k)) within PB_BRICKS_SEPARABLE_EPS
// = 1e-5 relative for every k (float32 rounds both sides to a few 2^-24 relative, also near f' = 0 or 1;
// a dropped corner must stay dropped); f1 = M(1) / sum w, the one tap's fraction.
bool brick_separable(float w[8], out vec3 f1)
{
    float sw = 0.0;
    vec3 m0 = vec3(0.0), m1 = vec3(0.0);
    for (uint k = 0u; k < 8u; ++k) {
        vec3 o = vec3(float(k & 1u), float((k >> 1u) & 1u), float((k >> 2u) & 1u));
        sw += w[k];
        m1 += w[k] * o;
        m0 += w[k] * (1.0 - o);
    }
    f1 = sw > 0.0 ? m1 / sw : vec3(0.0);
    if (!(sw > 0.0)) return false;
    for (uint k = 0u; k < 8u; ++k) {
        vec3 m = mix(m0, m1, vec3(float(k & 1u), float((k >> 1u) & 1u), float((k >> 2u) & 1u)));
        float lhs = w[k] * sw * sw, rhs = m.x * m.y * m.z;
        if (!(abs(lhs - rhs) <= 1e-5 * max(lhs, rhs))) return false;
    }
    return true;
}

// E(n) of a grid's bricks at a surface point: brick_surface_irradiance() in bricks_surface.glsl (steps 1-6
// with the anti-leak rules of step 5, mirroring pb_bricks_sample_surface()).

// ---- dense grids (docs/grid-field.md, --probe-path bricks): a line-by-line mirror of
// pb_grid_field_sample_surface_texture() of native/src/pb_grid_field.c (pb_grid_field_query's steps 1-5, step 5's
// fallback from the texture too: no file probe is read). The grid's cell-centred texture (pb_grid_field_texture_f16: N = v s c, D = v per cell) lies in
// the brick pool at (0, 0, gr.bricks.z) of each channel group's slab (gr.bricks.w = C | slab << 8).
// Corner k's weight is trilinear x keep_k (keep: 0 where the mask drops it, else its back-face weight, 1 for
// a movable object; validity is in N and D). Where these weights are separable (brick_separable, e.g. an
// axis-aligned floor or wall, or every keep_k = 1) one filtered fetch per channel group at t = clamp(i0 +
// f', 0, dims - 1) (pb_grid_field_sample_surface_texture) gives them exactly. Otherwise 8 texelFetch taps
// per group with the rule's weights exactly.

// Channel group g of cell ci of grid gr (texelFetch: exact, no filter).
vec4 grid_tex_fetch(sv_gpu_grid gr, ivec3 ci, uint g)
{
    return texelFetch(brick_pool, ci + ivec3(0, 0, int(gr.bricks.z + g * (gr.bricks.w >> 8u))), 0);
}

// E(n) = sum_i A_l(i) Y_i(n) N_i / D over the channel groups, N_0 and D from t0 (group 0); groups 1.. from
// `fetch_group` below (one of the two paths). Split in two to keep one loop for both paths.
float[25] grid_tex_basis(uint C, vec3 n)
{
    uint band = C >= 25u ? 4u : C >= 16u ? 3u : C >= 9u ? 2u : C >= 4u ? 1u : 0u;
    float AY[25];
    sh_lambert_basis(band, n, AY);
    return AY;
}

// false: no value (sum w v and step 5's sum tri v <= 1e-6, PB_GRID_FIELD_MIN_WEIGHT): the next grid.
bool grid_tex_irradiance(sv_gpu_grid gr, vec3 p_surface, vec3 n, bool movable, out vec3 e_out)
{
    e_out = vec3(0.0);
    // 1. (pb_grid_field_query step 1) biased point, grid coordinates u = R (p - origin) / h.
    float h = gr.origin_spacing.w;
    vec3 p = p_surface + n * (frame.normal_bias * h);
    vec3 rel = p - gr.origin_spacing.xyz;
    vec3 u = vec3(dot(rel, gr.axes[0].xyz), dot(rel, gr.axes[1].xyz), dot(rel, gr.axes[2].xyz)) / h;
    ivec3 dims = ivec3(gr.dims.xyz);
    if (any(lessThan(u, vec3(-0.01))) || any(greaterThan(u, vec3(dims) + 0.01))) return false;
    // 2. (c, i0, f)
    vec3 c = u - 0.5;
    ivec3 i0 = ivec3(floor(c));
    vec3 f = c - vec3(i0);
    // 3. (home, vis) the home cell 0.01 cells along n, its 27-bit neighbour mask from the cell buffer.
    vec3 rel_h = rel + n * (0.01 * h);
    ivec3 home = clamp(
        ivec3(floor(vec3(dot(rel_h, gr.axes[0].xyz), dot(rel_h, gr.axes[1].xyz), dot(rel_h, gr.axes[2].xyz)) / h)),
        ivec3(0), dims - 1);
    uint vis = uint(cell_probe[gr.base.y + uint(home.x + home.y * dims.x + home.z * dims.x * dims.y)]);
    // 4. (the loop over k) each corner's weight besides validity: trilinear x keep_k, keep_k = 0 when the
    //    mask drops it, else its back-face weight (1 for a movable object). Empty cells have N = D = 0.
    float w[8], tri[8];
    for (int k = 0; k < 8; ++k) {
        ivec3 o = ivec3(k & 1, (k >> 1) & 1, (k >> 2) & 1);
        ivec3 ci = clamp(i0 + o, ivec3(0), dims - 1);
        ivec3 d = ci - home;
        bool masked =
            all(lessThanEqual(abs(d), ivec3(1))) && (vis & (1u << uint(d.x + 1 + 3 * (d.y + 1) + 9 * (d.z + 1)))) == 0u;
        float b = movable ? 1.0 : smoothstep(-0.1, 0.1, dot(cell_centre(gr, ci) - p_surface, n) / h);
        vec3 w3 = mix(1.0 - f, f, vec3(o));
        tri[k] = w3.x * w3.y * w3.z;
        w[k] = tri[k] * (masked ? 0.0 : b);
    }
    uint C = gr.bricks.w & 255u;
    uint groups = (3u * C + 4u) / 4u; // ceil((3C + 1) / 4)
    float AY[25] = grid_tex_basis(C, n);
    vec3 s;
    float D;
    // 5. Separable weights: one filtered tap at f' (scaled by sw, the weights' sum), kept where its D >= 1/64
    //    (PB_GRID_FIELD_FILTER_MIN_D), else the 8 taps: where the only valid corners have tiny trilinear weights, lavapipe's
    //    filtered N and D lose the ratio N_k / D_k (measured 0.3 % at D = 8.7e-5, 2e-4 at 1.3e-3;
    //    test_engine_grid_field.py), which the exact taps keep.
    vec3 f1;
    float sw = 0.0;
    for (int k = 0; k < 8; ++k) sw += w[k];
    bool one = brick_separable(w, f1);
    vec3 size = vec3(textureSize(brick_pool, 0));
    vec3 tc = (clamp(vec3(i0) + f1, vec3(0.0), vec3(dims - 1)) + 0.5 + vec3(0.0, 0.0, float(gr.bricks.z))) / size;
    vec4 t0 = one ? textureLod(brick_pool, tc, 0.0) : vec4(0.0); // N_0 (RGB), D
    if (one && t0.w < 1.0 / 64.0) one = false;
    bool done = false;
    if (one) {
        // pb_grid_field_sample_surface_texture's texture_tap: texel centres (t + 1/2 + (0, 0, z offset)) /
        // pool size (tc above); the hardware's trilinear filter (its sub-texel weights).
        float slab = float(gr.bricks.w >> 8u) / size.z;
        D = t0.w;              // N / D of the tap = sum w (N, D) / sum w (N, D): sw cancels
        done = sw * D > 1e-6;  // else sum w v <= 1e-6: step 5 below
        s = AY[0] * t0.rgb;
        if (done) {
            SV_FOR_GROUPS(g, groups) {
                brick_group_add(g, textureLod(brick_pool, tc + vec3(0.0, 0.0, float(g) * slab), 0.0), C, AY, s);
            }
        }
    }
    // Pass 0: the rule's weights exactly, 8 taps: sum_k w_k (N, D)_k = (sum w v s c, sum w v) (not after the
    // one tap: its sum w D is the taps'). Pass 1, step 5 (sum w v <= 1e-6): the plain trilinear weights, the
    // texture's own N / D at the point, exact taps (its D may be tiny); D <= 1e-6 too: no value (next grid).
    for (int pass = one ? 1 : 0; pass < 2 && !done; ++pass) {
        if (pass == 1)
            for (int k = 0; k < 8; ++k) w[k] = tri[k];
        vec4 a0 = vec4(0.0);
        for (int k = 0; k < 8; ++k) {
            if (w[k] <= 0.0) continue;
            a0 +=
                w[k] * grid_tex_fetch(gr, clamp(i0 + ivec3(k & 1, (k >> 1) & 1, (k >> 2) & 1), ivec3(0), dims - 1), 0u);
        }
        D = a0.w;
        done = D > 1e-6;
        if (!done) continue;
        s = AY[0] * a0.rgb;
        SV_FOR_GROUPS(g, groups) {
            vec4 tg = vec4(0.0);
            for (int k = 0; k < 8; ++k) {
                if (w[k] <= 0.0) continue;
                tg += w[k] *
                      grid_tex_fetch(gr, clamp(i0 + ivec3(k & 1, (k >> 1) & 1, (k >> 2) & 1), ivec3(0), dims - 1), g);
            }
            brick_group_add(g, tg, C, AY, s);
        }
    }
    if (!done) return false;
    e_out = s / D; // 5. renormalised: sum w v s E / sum w v (step 5: sum tri v s E / sum tri v)
    return true;
}

#endif
