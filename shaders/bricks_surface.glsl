// Probe bricks per pixel with the anti-leak rules (docs/probe-bricks.md "Sampling rule" steps 1-6, "Back
// faces and visibility"; --probe-path bricks): a line-by-line mirror of pb_bricks_locate() and
// pb_bricks_sample_surface() of native/src/pb_bricks.c (the one C definition of the field; its header lists
// steps a-f in this order): where the cell's kept weights w' are separable the hardware's trilinear filter
// does cell_filtered() at their per-axis mean f' (its sub-texel weights are pb_bricks_sample_surface(...,
// subtexel_bits = 8)), elsewhere the 8 taps with the exact weights (brick_tap8 = cell_weighted).
// Static surfaces (not SV_DRAW_MOVABLE): back-face weights on the brick cell's 8 texels; every object: the
// visibility ramp of the brick cell's record when the cell is blocked (brick_vis, sv_bricks_vis.h). An
// unblocked cell of a movable object is the plain sample (step 4), as pb_bricks_sample_bits.
#ifndef SV_BRICKS_SURFACE_GLSL
#define SV_BRICKS_SURFACE_GLSL
#include "bricks.glsl"
#include "sh.glsl"

// Steps 1-3, pb_bricks_locate(): the lattice's margin of 0.01 min cells, u clamped into [0, E], the min
// cell q (max faces closed), its entry; not occupied: the face margin (masks x, y, xy, z, ...: the first
// occupied cell q - m whose lower faces u lies within 0.01 above, u clamped into it). Out: the entry e
// (x = brick | level << 27, w = the brick's row in brick_vis), the region's min corner r0 and the
// brick-local texel coordinate x in [0, 4]^3. False: no brick here.
bool brick_locate(sv_gpu_grid gr, vec3 p, out uvec4 e, out uvec3 r0, out vec3 x)
{
    r0 = uvec3(0u);
    x = vec3(0.0);
    float h = gr.origin_spacing.w;
    vec3 u = (p - gr.origin_spacing.xyz) / h;
    vec3 dims = vec3(gr.dims.xyz);
    e = uvec4(0xffffffffu, 0u, 0u, 0u);
    if (any(lessThan(u, vec3(-0.01))) || any(greaterThan(u, dims + 0.01))) return false;
    u = clamp(u, vec3(0.0), dims);
    uvec3 q = uvec3(min(floor(u), dims - 1.0));
    e = brick_entry(gr, q);
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
    uint L = e.x >> 27u;
    r0 = (q >> (L + 2u)) << (L + 2u);
    x = clamp((u - vec3(r0)) / float(1u << L), vec3(0.0), vec3(4.0));
    return true;
}

// One filtered tap of brick b at brick-local texel coordinate xt (cell_filtered / pb_bricks_filter: texel
// centres (origin_b + 0.5 + xt) / pool size, one LINEAR fetch per channel group, group g in its slab at
// z + g * slab), then E(n) = sum_i A_l(i) Y_i(n) N_i / D with AY = sh_lambert_basis. False when D <= 0.
bool brick_tap(sv_gpu_grid gr, uint b, vec3 xt, uint C, float AY[25], out vec3 e_out)
{
    e_out = vec3(0.0);
    uint px = gr.bricks.y & 0xffffu, py = gr.bricks.y >> 16u;
    uvec3 ob = 5u * uvec3(b % px, (b / px) % py, b / (px * py)) + uvec3(0u, 0u, gr.bricks.z);
    vec3 size = vec3(textureSize(brick_pool, 0));
    vec3 tc = (vec3(ob) + 0.5 + xt) / size;
    float slab = float(gr.bricks.w >> 8u) / size.z;
    vec4 t0 = textureLod(brick_pool, tc, 0.0); // N_0 (RGB), D
    if (!(t0.w > 0.0)) return false;
    vec3 s = AY[0] * t0.rgb;
    uint groups = (3u * C + 4u) / 4u; // ceil((3C + 1) / 4)
    SV_FOR_GROUPS(g, groups) {
        brick_group_add(g, textureLod(brick_pool, tc + vec3(0.0, 0.0, float(g) * slab), 0.0), C, AY, s);
    }
    e_out = s / t0.w;
    return true;
}

// The 8-tap form of brick b's cell k0 (cell_weighted: sum_k w[k] T_k over its 8 texels, exact weights; one
// texelFetch per corner with w[k] > 0 and group), then E(n) = sum_i A_l(i) Y_i(n) N_i / D. False when
// D <= 0.
bool brick_tap8(sv_gpu_grid gr, uint b, vec3 k0, float w[8], uint C, float AY[25], out vec3 e_out)
{
    e_out = vec3(0.0);
    uint px = gr.bricks.y & 0xffffu, py = gr.bricks.y >> 16u;
    ivec3 ob = ivec3(5u * uvec3(b % px, (b / px) % py, b / (px * py)) + uvec3(0u, 0u, gr.bricks.z)) + ivec3(k0);
    int slab = int(gr.bricks.w >> 8u);
    uint groups = (3u * C + 4u) / 4u; // ceil((3C + 1) / 4)
    vec3 s = vec3(0.0);
    float d = 0.0;
    for (uint k = 0u; k < 8u; ++k) {
        if (w[k] == 0.0) continue;
        ivec3 tk = ob + ivec3(int(k & 1u), int((k >> 1u) & 1u), int((k >> 2u) & 1u));
        vec4 t0 = texelFetch(brick_pool, tk, 0); // N_0 (RGB), D
        d += w[k] * t0.w;
        s += w[k] * AY[0] * t0.rgb;
        SV_FOR_GROUPS(g, groups) {
            brick_group_add(g, w[k] * texelFetch(brick_pool, tk + ivec3(0, 0, int(g) * slab), 0), C, AY, s);
        }
    }
    if (!(d > 0.0)) return false;
    e_out = s / d;
    return true;
}

// V(k, c) of a visibility record at uint offset rec of brick_vis: pb_vis_pair_value() (as pair_vis()).
float brick_pair_vis(uint rec, uint k, uint c)
{
    uint byte_index = 8u * k + c;
    uint q = (brick_vis[rec + byte_index / 4u] >> (8u * (byte_index & 3u))) & 255u;
    return q >= 255u ? 1.0 : 1.0 - 127.5 / float(max(q, 1u));
}

// E(n) of grid gr's bricks at the surface point p_surface with normal n (pb_bricks_sample_surface with
// PB_BRICKS_STATIC unless movable), not clamped; false where the bricks give no value (outside,
// no leaf, or D <= 0 in the last sample: the caller tries the next grid, then probe 0).
bool brick_surface_irradiance(sv_gpu_grid gr, vec3 p_surface, vec3 n, bool movable, out vec3 e_out)
{
    e_out = vec3(0.0);
    // 1-3. Locate p_lookup (the point moved by the normal bias): brick, L, region min r, x.
    float h = gr.origin_spacing.w;
    vec3 p = p_surface + n * (frame.normal_bias * h);
    uvec4 e;
    uvec3 r0;
    vec3 x;
    if (!brick_locate(gr, p, e, r0, x)) return false;
    uint b = e.x & 0x7ffffffu, L = e.x >> 27u;
    uint C = gr.bricks.w & 255u;
    uint band = C >= 25u ? 4u : C >= 16u ? 3u : C >= 9u ? 2u : C >= 4u ? 1u : 0u;
    float AY[25];
    sh_lambert_basis(band, n, AY);
    bool is_static = !movable;
    // a. The brick cell k0 = min(floor(x), 3), f = x - k0 (cell_of), its index and its blocked bit in
    //    the brick's table row (y: cells 0-31, z: 32-63).
    vec3 xc = clamp(x, vec3(0.0), vec3(4.0));
    vec3 k0 = min(floor(xc), vec3(3.0));
    vec3 f = xc - k0;
    uint cell = uint(k0.x) + 4u * uint(k0.y) + 16u * uint(k0.z);
    uint row = 4u * e.w;
    uvec3 t = uvec3(brick_vis[row], brick_vis[row + 1u], brick_vis[row + 2u]);
    uint word = cell < 32u ? t.y : t.z, below = word & ((1u << (cell % 32u)) - 1u);
    bool blocked = ((word >> (cell % 32u)) & 1u) != 0u;
    if (is_static || blocked) {
        // b. Trilinear weights (trilinear8: corner k = bits x, y, z of k); c. back faces (static only)
        //    against u_s, the surface point's lattice coordinates before the normal bias.
        float w[8], wb[8], wv[8];
        float s = float(1u << L), wbsum = 0.0, sw = 0.0;
        vec3 us = (p_surface - gr.origin_spacing.xyz) / h;
        for (uint k = 0u; k < 8u; ++k) {
            vec3 o = vec3(float(k & 1u), float((k >> 1u) & 1u), float((k >> 2u) & 1u));
            vec3 w3 = mix(1.0 - f, f, o);
            w[k] = w3.x * w3.y * w3.z;
            wb[k] = w[k];
            if (is_static) {
                float dd = dot((vec3(r0) + s * (k0 + o) - us) / s, n);
                wb[k] *= smoothstep(-0.1, 0.1, dd);
            }
            wbsum += wb[k];
        }
        // d. The visibility ramp of the cell's record: record index = the row's first + the blocked
        //    cells below this one; v_c blended over the back-face weights.
        if (blocked) {
            uint rec = t.x + 16u * (uint(bitCount(below)) + (cell >= 32u ? uint(bitCount(t.y)) : 0u));
            for (uint c = 0u; c < 8u; ++c) {
                float v = 0.0;
                for (uint k = 0u; k < 8u; ++k) v += wb[k] * brick_pair_vis(rec, k, c);
                v = wbsum > 0.0 ? v / wbsum : 0.0;
                wv[c] = wb[c] * smoothstep(0.5, 0.5 + SV_VIS_RAMP, v);
            }
        } else {
            wv = wb;
        }
        for (uint k = 0u; k < 8u; ++k) sw += wv[k];
        // e. sw > 0: f'_a = sum_k w'_k bit_a(k) / sw; separable w' (brick_separable = pb_bricks_separable:
        //    w'_k / sw = prod_a (bit_a(k) ? f'_a : 1 - f'_a) within 1e-5 relative for all k, e.g. an axis-aligned
        //    surface, or no corner dropped): one filtered tap at k0 + f', exactly the weights w' / sw on N
        //    and D alike; else the 8 taps with w' (brick_tap8 = cell_weighted). D > 0: N / D.
        if (sw > 0.0) {
            vec3 f1;
            if (brick_separable(wv, f1)) {
                if (brick_tap(gr, b, k0 + f1, C, AY, e_out)) return true;
            } else if (brick_tap8(gr, b, k0, wv, C, AY, e_out)) {
                return true;
            }
        }
    }
    // f. Else the plain sample at x (the shader's second pass); D <= 0: no value.
    return brick_tap(gr, b, x, C, AY, e_out);
}

#endif
