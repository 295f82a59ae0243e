// Surface shading shared by the scene and the probe-cell view (needs SV_SCENE_BINDINGS).
#ifndef SV_SHADING_GLSL
#define SV_SHADING_GLSL
#include "ambient_cube.glsl"
#include "bricks.glsl"
#include "bricks_surface.glsl"
#include "sh.glsl"

// Probe buffer access for either storage (SV_HALF_PROBES, a specialization constant).
uint probe_band(uint index) {
    float b = SV_HALF_PROBES ? unpackHalf2x16(probes_half[index].params[0]).x : probes[index].params.x;
    return min(uint(b + 0.5), 4u);
}
float probe_scale(uint index) {
    return SV_HALF_PROBES ? unpackHalf2x16(probes_half[index].params[0]).y : probes[index].params.y;
}
float probe_validity(uint index) {
    return SV_HALF_PROBES ? unpackHalf2x16(probes_half[index].params[1]).x : probes[index].params.w;
}
vec3 probe_coeff(uint index, uint i) {
    if (SV_HALF_PROBES) {
        uvec2 c = probes_half[index].sh[i];
        return vec3(unpackHalf2x16(c.x), unpackHalf2x16(c.y).x);
    }
    return probes[index].sh[i].xyz;
}

// sum_i AY[i] c_i over the first (band+1)^2 coefficients of probe `index`, read one by one from the
// probe buffer, for a basis from sh_lambert_basis() of sh.glsl: pb_sh_irradiance() of native/src/pb_sh.c
// on the probe's coefficients, without copying them into a local array.
vec3 probe_irradiance_basis(uint index, uint band, float AY[25]) {
    uint count = (band + 1u) * (band + 1u);
    vec3 e = vec3(0.0);
    for (uint i = 0u; i < 25u; ++i) {
        if (i >= count) break;
        e += AY[i] * probe_coeff(index, i);
    }
    return e;
}

// Irradiance E(n) of probe `index` (DESIGN.md §3), not clamped, only the bands the probe has.
vec3 probe_irradiance(uint index, vec3 n) {
    uint band = probe_band(index);
    float AY[25];
    sh_lambert_basis(band, n, AY);
    return probe_irradiance_basis(index, band, AY);
}

// Ambient-cube buffer access (docs/ambient-cube.md §5), either storage: the cube of probe `index`,
// fitted at load from the same probe's SH, with that probe's scale and validity.
float cube_scale(uint index) {
    return SV_HALF_PROBES ? unpackHalf2x16(cubes_half[index].params[0]).y : cubes[index].params.y;
}
float cube_validity(uint index) {
    return SV_HALF_PROBES ? unpackHalf2x16(cubes_half[index].params[1]).x : cubes[index].params.w;
}
// E_cube(n) of probe `index`, not clamped: ambient_cube_irradiance() of ambient_cube.glsl.
vec3 cube_irradiance(uint index, vec3 n) {
    vec3 c[6];
    for (uint f = 0u; f < 6u; ++f) {
        if (SV_HALF_PROBES) {
            uvec2 h = cubes_half[index].faces[f];
            c[f] = vec3(unpackHalf2x16(h.x), unpackHalf2x16(h.y).x);
        } else {
            c[f] = cubes[index].faces[f].xyz;
        }
    }
    return ambient_cube_irradiance(c, n);
}

// Irradiance of probe `index` including its own scale, in the representation `cube` selects.
vec3 probe_scaled_irradiance(uint index, vec3 n, bool cube) {
    return cube ? cube_scale(index) * cube_irradiance(index, n) : probe_scale(index) * probe_irradiance(index, n);
}

// ---- .shprobe version 3 corner octrees, per pixel (docs/engine.md "Version 3 grids") ----------------
// Morton order of two lattice points without computing their codes (Chan's most-significant-bit
// comparison): the axis whose coordinates differ in the highest bit decides, z before y before x
// at the same bit (Morton bit 3i + axis, z most significant: the file's leaf order).
bool less_msb(uint a, uint b) { return a < b && a < (a ^ b); }
bool morton_less(uvec3 a, uvec3 b) {
    uvec3 d = a ^ b;
    uint k = 2u;
    if (less_msb(d[k], d.y)) k = 1u;
    if (less_msb(d[k], d.x)) k = 0u;
    return a[k] < b[k];
}
uvec3 leaf_min(uint at) { return uvec3(uint(cell_probe[at]), uint(cell_probe[at + 1u]), uint(cell_probe[at + 2u])); }

// Leaf holding the unit lattice cell q, or -1: the leaves are in Morton order of their min corners and
// an aligned leaf covers a contiguous Morton range, so a binary search for the last leaf whose min
// corner is not after q finds the only candidate (at most 27 steps for the 2^26 leaves a file may
// hold); it holds q when q lies in its cube.
// A kd corner tree (.shprobe v4, SV_GRID_KDTREE; docs/aniso-refinement.md "Point location"): from the
// node of q's root cell (q >> R, x fastest), while the node splits along axis a, halve the box on a and
// go to the lower child when q_a < min_a + 2^l_a (the new level), else to the upper one. Each split
// lowers one of the three levels, so at most 3R steps (the loop's bound), one 4-byte fetch each; a split
// of a level-0 axis (never in a file the reader accepted) ends as no leaf.
int kd_locate(sv_gpu_grid gr, uvec3 q) {
    uint R = gr.tree.y;
    uvec3 lo = (q >> R) << R, lv = uvec3(R);
    uint node = (q.x >> R) + gr.tree.z * ((q.y >> R) + gr.tree.w * (q.z >> R));
    for (uint i = 0u; i <= 3u * R; ++i) {
        uint nd = uint(cell_probe[gr.tree.x + node]);
        uint ax = nd & 3u;
        if (ax == 0u) return (nd >> 2u) == 0x3fffffffu ? -1 : int(nd >> 2u);
        uint a = ax - 1u;
        if (lv[a] == 0u) return -1;
        lv[a] -= 1u;
        uint up = q[a] >= lo[a] + (1u << lv[a]) ? 1u : 0u;
        lo[a] += up << lv[a];
        node = (nd >> 2u) + up;
    }
    return -1;
}

int octree_locate(sv_gpu_grid gr, uvec3 q) {
    if ((gr.base.z & SV_GRID_KDTREE) != 0u) return kd_locate(gr, q);
    uint lo = 0u, hi = gr.base.w;
    while (lo < hi) {
        uint mid = (lo + hi) / 2u;
        if (morton_less(q, leaf_min(gr.dims.w + SV_LEAF_INTS * mid))) hi = mid; else lo = mid + 1u;
    }
    if (lo == 0u) return -1;
    uint at = gr.dims.w + SV_LEAF_INTS * (lo - 1u);
    uvec3 l = leaf_min(at);
    uint size = 1u << uint(cell_probe[at + 3u]);
    return all(greaterThanEqual(q, l)) && all(lessThan(q - l, uvec3(size))) ? int(lo - 1u) : -1;
}

// The leaf holding lattice point u in unit cell q; on a face between a leaf and a cell no leaf covers
// (within 0.01 units of the cell's lower face) the cells below are tried too, in the bit-mask order of
// locate_point_cell() in native/src/pb_interp.c, which this mirrors: a wall's surface on the volume's
// max face belongs to the leaf inside, not to nothing by its coordinates' rounding.
int octree_locate_point(sv_gpu_grid gr, vec3 u, uvec3 q) {
    int li = octree_locate(gr, q);
    for (uint m = 1u; li < 0 && m < 8u; ++m) {
        uvec3 r = q;
        bool ok = true;
        for (int k = 0; k < 3; ++k) {
            if (((m >> uint(k)) & 1u) == 0u) continue;
            if (!(q[k] > 0u && u[k] - float(q[k]) < 0.01)) ok = false;
            r[k] = q[k] - 1u;
        }
        if (ok) li = octree_locate(gr, r);
    }
    return li;
}

// V(k, c) of the visibility field from its stored byte: pb_vis_pair_value() of pb_interp.h.
float pair_vis(uint at, uint k, uint c) {
    uint byte_index = 8u * k + c;
    uint q = (uint(cell_probe[at + byte_index / 4u]) >> (8u * (byte_index & 3u))) & 255u;
    return q >= 255u ? 1.0 : 1.0 - 127.5 / float(max(q, 1u));
}

// E(n) of a corner octree or kd corner tree at p: mirrors leaf_weights() of native/src/pb_interp.c line by
// line (leaf of the point, t = clamp((u - corner0) / s, 0, 1) with s = 2^l_a per axis, trilinear weights of the 8 corners, each
// times the ramp smoothstep(1/2, 1/2 + PB_VIS_RAMP, v_c) of the leaf's continuous visibility field
// v_c = sum_k w_k V(k, c) (pb_interp.h; tables traced at load through the static scene), zero weights
// skipped, probes of validity 0 dropped, renormalised). The hanging corners were resolved at load into
// the entries after the probes (value and validity mass, sv_probes.c resolve_hanging), so the 8
// fetches give exactly the CPU's expanded and merged weights. On top, for static objects only, the
// back-face weight smoothstep(-0.1, 0.1, dot((c - p) / s, n)) of each corner, s the leaf's per-axis size (a movable object was
// not in the bake, so every corner holds the light where it now is, and on a small convex object the
// weight would throw away the probes behind each surface point). When these leave no weight, the plain
// trilinear weights are used (the leaf's own field, as the CPU). False: no leaf holds p, or every
// corner is invalid (the caller tries the next grid).
bool octree_irradiance(sv_gpu_grid gr, vec3 p_surface, vec3 n, bool cube, bool movable, out vec3 e_out) {
    e_out = vec3(0.0);
    float h = gr.origin_spacing.w;
    vec3 p = p_surface + n * (frame.normal_bias * h);
    vec3 u = (p - gr.origin_spacing.xyz) / h; // lattice coordinates (octree axes are the identity)
    vec3 dims = vec3(gr.dims.xyz);
    // The CPU's point_cell() with the grids' margin of 1/100 min cell (surfaces on the lattice faces).
    if (any(lessThan(u, vec3(-0.01))) || any(greaterThan(u, dims + 0.01))) return false;
    u = clamp(u, vec3(0.0), dims);
    uvec3 q = uvec3(min(floor(u), dims - 1.0));
    int li = octree_locate_point(gr, u, q);
    if (li < 0) return false;
    uint lb = gr.dims.w + SV_LEAF_INTS * uint(li);
    vec3 l = vec3(float(cell_probe[lb]), float(cell_probe[lb + 1u]), float(cell_probe[lb + 2u]));
    // Per-axis sizes 2^l_a: a kd tree's leaf packs lx | ly << 8 | lz << 16, an octree's is one level.
    uint lw = uint(cell_probe[lb + 3u]);
    uvec3 lvl = (gr.base.z & SV_GRID_KDTREE) != 0u ? uvec3(lw & 255u, (lw >> 8u) & 255u, (lw >> 16u) & 255u) : uvec3(lw);
    vec3 s = vec3(uvec3(1u) << lvl);
    vec3 tt = clamp((u - l) / s, vec3(0.0), vec3(1.0));
    uint vb = gr.base.y + SV_LEAF_VIS_INTS * uint(li);
    // Corner c's trilinear weight (w8) and that times its back-face weight (wb, static objects), as
    // two vec4 each (corners 0-3, 4-7): registers, not a local array.
    vec2 fx = vec2(1.0 - tt.x, tt.x), fy = vec2(1.0 - tt.y, tt.y), fz = vec2(1.0 - tt.z, tt.z);
    vec4 xy = vec4(fx.x * fy.x, fx.y * fy.x, fx.x * fy.y, fx.y * fy.y);
    vec4 w8a = xy * fz.x, w8b = xy * fz.y;
    vec4 wba = w8a, wbb = w8b;
    if (!movable) {
        // dot((corner - p_surface) / (s h), n) per component = dot((l - u_surface) / s + o, n), u_surface in
        // lattice units, o the corner's bits: a box's back faces normalised per axis (a cube's dot / size)
        float d0 = dot((l - (p_surface - gr.origin_spacing.xyz) / h) / s, n);
        vec4 dxy = vec4(0.0, n.x, n.y, n.x + n.y);
        wba *= smoothstep(-0.1, 0.1, d0 + dxy);
        wbb *= smoothstep(-0.1, 0.1, d0 + n.z + dxy);
    }
    float wbsum = dot(wba, vec4(1.0)) + dot(wbb, vec4(1.0));
    uint band = 0u;
    float AY[25]; // A_l Y_i(n) (sh_lambert_basis)
    bool have_basis = false;
    bool blocked = cell_probe[lb + 4u] != 0; // else every V(k, c) = 1: v_c = 1, a ramp of exactly 1
    for (int pass = wbsum > 0.0 ? 0 : 1; pass < 2; ++pass) { // 0: visibility field and back faces; 1: plain
        vec3 e = vec3(0.0);
        float wsum = 0.0;
        for (uint c = 0u; c < 8u; ++c) {
            float w = c < 4u ? w8a[c] : w8b[c - 4u];
            if (w <= 0.0) continue;
            if (pass == 0) {
                // The field blended over the corners in front of the surface (a static surface's own
                // corners behind it would put its front probes' wall on the surface itself).
                w = c < 4u ? wba[c] : wbb[c - 4u];
                if (blocked) {
                    float v = 0.0;
                    for (uint k = 0u; k < 8u; ++k) {
                        float wk = k < 4u ? wba[k] : wbb[k - 4u];
                        if (wk > 0.0) v += wk * pair_vis(vb, k, c);
                    }
                    w *= smoothstep(0.5, 0.5 + SV_VIS_RAMP, v / wbsum);
                }
            }
            uint pi = gr.base.x + uint(cell_probe[lb + 8u + c]);
            w *= cube ? cube_validity(pi) : probe_validity(pi);
            if (w <= 0.0) continue;
            if (cube) {
                e += w * cube_scale(pi) * cube_irradiance(pi, n);
            } else {
                if (!have_basis) {
                    band = probe_band(pi);
                    sh_lambert_basis(band, n, AY);
                    have_basis = true;
                }
                e += w * probe_scale(pi) * probe_irradiance_basis(pi, band, AY);
            }
            wsum += w;
        }
        if (wsum > 0.0) {
            e_out = e / wsum;
            return true;
        }
    }
    return false;
}

// Per-pixel probe lighting (DESIGN.md §7, docs/engine.md "Per-pixel probes"): the first grid
// whose box holds p (moved by normal_bias grid spacings along n) is sampled trilinearly between
// the centres of the 8 neighbouring cells (indices clamped at the grid's faces). A neighbour gets
// weight  trilinear * validity * backface, where backface = smoothstep(-0.1, 0.1, dot(c - p, n) / spacing)
// is ~0 for a probe centre c behind the surface's tangent plane (the anti-leak measure for the static
// surfaces the bake saw; 1 for a movable object, SV_DRAW_MOVABLE, as in octree_irradiance); empty
// cells (-1) are skipped and the weights renormalised. A neighbour is also dropped when the cell
// holding p + 0.01 spacing * n (the "home" cell, on the lit side of the surface) cannot see it: its
// visibility mask (Embree segments between cell centres, computed at load) has the bit clear. When every weight is 0 (step 5)
// the plain trilinear x validity weights are used (no mask, no back face); when they are 0 too, the next grid is tried.
// Returns E(n) including each probe's own scale; false when no grid holds p. `cube`: the probes'
// ambient cubes instead of their SH, with the same weights, validity and visibility rules
// (docs/ambient-cube.md §5; the fit is linear, so this is the cube of the interpolated SH).
// The dense branch is pb_grid_field_query() of native/src/pb_grid_field.c step by step (docs/grid-field.md,
// the one definition; tests/python/test_native_grid_field.py checks the engine tests' numpy oracle against
// it): 1 p, rel, u and the box; 2 c, i0, f; 3 rel_h, home, vis; 4 the loop over k; 5 wsum > 1e-6, else pass 1's
// plain trilinear x validity weights. Under --probe-path bricks it reads the grid's texture (grid_tex_irradiance).
bool grid_irradiance(vec3 p_surface, vec3 n, bool cube_asked, bool movable, out vec3 e_out) {
    e_out = vec3(0.0);
    for (uint g = 0u; g < frame.grid_count; ++g) {
        sv_gpu_grid gr = grids[g];
        // A grid that holds cubes only shades with them whatever the material asks (docs/ambient-cube.md §5).
        bool cube = cube_asked || (gr.base.z & SV_GRID_CUBE_ONLY) != 0u;
        if ((gr.base.z & SV_GRID_TETRA) != 0u) continue; // tetrahedra: per object only
        if ((gr.base.z & SV_GRID_OCTREE) != 0u) {
            // --probe-path bricks (SH only): the bricks' field with step 5 (back faces on static surfaces,
            // the visibility records of blocked brick cells), bricks_surface.glsl.
            if (!cube && (frame.flags & SV_FRAME_BRICKS) != 0u && (gr.base.z & SV_GRID_BRICKS) != 0u) {
                if (brick_surface_irradiance(gr, p_surface, n, movable, e_out)) return true;
                continue;
            }
            if (octree_irradiance(gr, p_surface, n, cube, movable, e_out)) return true;
            continue;
        }
        float h = gr.origin_spacing.w;
        vec3 p = p_surface + n * (frame.normal_bias * h);
        vec3 rel = p - gr.origin_spacing.xyz;
        vec3 u = vec3(dot(rel, gr.axes[0].xyz), dot(rel, gr.axes[1].xyz), dot(rel, gr.axes[2].xyz)) / h;
        ivec3 dims = ivec3(gr.dims.xyz);
        // The box holds p with a margin of 1/100 cell: walls and floors modelled exactly on the
        // grid's faces would otherwise flicker between the grid and the fallback (float noise).
        if (any(lessThan(u, vec3(-0.01))) || any(greaterThan(u, vec3(dims) + 0.01))) continue;
        uint off = gr.dims.w;
        // --probe-path bricks (SH only): the grid's texture in the pool (bricks.glsl grid_tex_irradiance,
        // pb_grid_field's rule: one filtered fetch per group or 8 exact taps, step 5 from the texture too, so
        // no file probe is read); false: no value, the next grid.
        if (!cube && (frame.flags & SV_FRAME_BRICKS) != 0u && (gr.base.z & SV_GRID_BRICKS) != 0u) {
            if (grid_tex_irradiance(gr, p_surface, n, movable, e_out)) return true;
            continue;
        }
        vec3 c = u - 0.5;
        ivec3 i0 = ivec3(floor(c));
        vec3 f = c - vec3(i0);
        vec3 rel_h = rel + n * (0.01 * h);
        ivec3 home = clamp(ivec3(floor(vec3(dot(rel_h, gr.axes[0].xyz), dot(rel_h, gr.axes[1].xyz),
                                              dot(rel_h, gr.axes[2].xyz)) / h)), ivec3(0), dims - 1);
        uint vis = uint(cell_probe[gr.base.y + uint(home.x + home.y * dims.x + home.z * dims.x * dims.y)]);
        uint band = 0u;
        float AY[25];
        // Probes of one grid share the band: evaluate the basis once.
        bool have_basis = false;
        // Pass 0: the rule's anti-leak weights (mask, back faces, validity). Pass 1, step 5 (pass 0's sum
        // <= 1e-6): the plain trilinear x validity weights, no mask, no back face (pb_grid_field_query; the
        // texture's own N / D at the point); <= 1e-6 too: no value, the next grid.
        for (int pass = 0; pass < 2; ++pass) {
            vec3 e = vec3(0.0);
            float wsum = 0.0;
            for (int k = 0; k < 8; ++k) {
                ivec3 o = ivec3(k & 1, (k >> 1) & 1, (k >> 2) & 1);
                ivec3 ci = clamp(i0 + o, ivec3(0), dims - 1);
                int idx = cell_probe[off + uint(ci.x + ci.y * dims.x + ci.z * dims.x * dims.y)];
                if (idx < 0) continue;
                ivec3 d = ci - home; // in {-1, 0, 1}^3 but for float edge cases (then: no information)
                if (pass == 0 && all(lessThanEqual(abs(d), ivec3(1))) &&
                    (vis & (1u << uint(d.x + 1 + 3 * (d.y + 1) + 9 * (d.z + 1)))) == 0u)
                    continue;
                vec3 w3 = mix(1.0 - f, f, vec3(o));
                float w = w3.x * w3.y * w3.z;
                vec3 centre = cell_centre(gr, ci);
                float t = dot(centre - p_surface, n) / h;
                uint pi = gr.base.x + uint(idx);
                w *= (movable || pass == 1 ? 1.0 : smoothstep(-0.1, 0.1, t)) *
                     (cube ? cube_validity(pi) : probe_validity(pi));
                if (w <= 0.0) continue;
                if (cube) {
                    e += w * cube_scale(pi) * cube_irradiance(pi, n);
                } else {
                    if (!have_basis) {
                        band = probe_band(pi);
                        sh_lambert_basis(band, n, AY);
                        have_basis = true;
                    }
                    e += w * probe_scale(pi) * probe_irradiance_basis(pi, band, AY);
                }
                wsum += w;
            }
            if (wsum > 1e-6) {
                e_out = e / wsum;
                return true;
            }
        }
    }
    return false;
}

// Equirect texture coordinate of an engine-space direction (DESIGN.md §3's panorama mapping:
// Blender d = (e.x, -e.z, e.y), u = (pi - atan2(d.y, d.x)) / 2pi, v = acos(d.z) / pi).
vec2 sky_uv(vec3 e) {
    float phi = atan(-e.z, e.x);
    return vec2((SH_PI - phi) / (2.0 * SH_PI), acos(clamp(e.y, -1.0, 1.0)) / SH_PI);
}

float luminance(vec3 c) { return dot(c, vec3(0.2126, 0.7152, 0.0722)); }

// Split-sum image-based specular from the sky (prefiltered mips + BRDF LUT), scaled by
// clamp(lum(E_probe(n)) / lum(E_sky(n)), 0, 1) so surfaces the probes see darker than the open sky
// (interiors) do not reflect it at full strength. e_probe: the irradiance the diffuse term used;
// cube: it came from the ambient cubes, so the sky's E is the fallback probe's cube too (ratio 1
// outside the grids in either representation).
// The split-sum term before the ratio (the deferred probe pass applies the ratio after E is known).
vec3 sky_specular_unscaled(vec3 p, vec3 n, vec3 albedo, float metallic, float roughness) {
    vec3 v = normalize(frame.camera_pos.xyz - p);
    float nv = clamp(dot(n, v), 1e-4, 1.0);
    vec3 r = reflect(-v, n);
    float mips = frame.camera_pos.w;
    float rough = clamp(roughness, 0.0, 1.0);
    vec3 pre = textureLod(sky_tex, sky_uv(r), rough * max(mips - 1.0, 0.0)).rgb;
    vec2 ab = textureLod(brdf_lut, vec2(nv, rough), 0.0).rg;
    vec3 f0 = mix(vec3(0.04), albedo, metallic);
    return pre * (f0 * ab.x + ab.y);
}

// clamp(lum(E_probe(n)) / lum(E_sky(n)), 0, 1), 1 under SV_FRAME_NO_RENORM.
float sky_specular_ratio(vec3 n, vec3 e_probe, bool cube) {
    if ((frame.flags & SV_FRAME_NO_RENORM) != 0u) return 1.0;
    float sky = luminance(max(cube ? cube_irradiance(0u, n) : probe_irradiance(0u, n), vec3(0.0)));
    return sky > 1e-6 ? clamp(luminance(max(e_probe, vec3(0.0))) / sky, 0.0, 1.0) : 1.0;
}

vec3 sky_specular(vec3 p, vec3 n, vec3 albedo, float metallic, float roughness, vec3 e_probe, bool cube) {
    return sky_specular_unscaled(p, n, albedo, metallic, roughness) * sky_specular_ratio(n, e_probe, cube);
}

// A distinct, stable colour per probe index (index 0, the fallback, is mid grey).
vec3 probe_color(uint index) {
    if (index == 0u) return vec3(0.5);
    uint h = index * 2654435761u;
    h ^= h >> 15;
    h *= 2246822519u;
    h ^= h >> 13;
    return vec3(float(h & 255u), float((h >> 8) & 255u), float((h >> 16) & 255u)) / 255.0 * 0.8 + 0.2;
}

// Cube face (SV_SHADOW_CUBE layer offset 0..5 = +X, -X, +Y, -Y, +Z, -Z) whose frustum holds the
// direction d from a point light: the major axis of d.
int shadow_cube_face(vec3 d) {
    vec3 a = abs(d);
    if (a.x >= a.y && a.x >= a.z) return d.x >= 0.0 ? 0 : 1;
    if (a.y >= a.z) return d.y >= 0.0 ? 2 : 3;
    return d.z >= 0.0 ? 4 : 5;
}

// Visibility in [0, 1] of a shadowed light from p through its shadow map layers (docs/engine.md
// "Shadows"); l = unit direction towards the light. The point is moved along n by
// T * (0.5 + 3 sin(phi)) where T is the world size of a shadow texel at p (orthographic: constant;
// perspective: depth of p along the layer's axis * 2 tan(half fov) / resolution) and phi the angle
// between n and the layer's axis (orthographic: the light direction, so phi = theta). Over the filter
// footprint (at most 2 sqrt(2) texels from the sample: the 3x3 grid of 1-texel steps plus the
// hardware's 2x2 bilinear compare) a plane's stored depth changes by at most 2 sqrt(2) T sin(phi)
// / cos(theta) relative to the sample's own, which the offset's T (0.5 + 3 sin(phi)) / cos(theta)
// exceeds: no acne. Then a 3x3 PCF of bilinear LESS_OR_EQUAL comparisons (1 = lit). Outside the map
// (or behind a spot light): lit. A point light's face is picked from the moved point, whose
// direction lies inside that face's 90 degrees; the faces are a few texels wider, for the filter.
// A sun's cascades (color.w layers from its first): the first whose box holds p at least
// SV_SHADOW_CASCADE_MARGIN of its texels inside the edge in light x, y (the normal offset and the
// filter footprint then stay in that map), else the last. Its texel size sets the offset and the PCF.
float shadow_visibility(sv_gpu_light light, vec3 p, vec3 n, vec3 l) {
    int layer = int(light.spot.w + 0.5);
    vec4 prm = frame.shadow_params[layer];
    uint kind = uint(prm.w + 0.5);
    if (kind == SV_SHADOW_ORTHO) {
        int last = layer + max(int(light.color.w + 0.5), 1) - 1;
        for (; layer < last; ++layer) {
            vec2 c = (frame.shadow_view_proj[layer] * vec4(p, 1.0)).xy;
            if (max(abs(c.x), abs(c.y)) <= 1.0 - 2.0 * SV_SHADOW_CASCADE_MARGIN * frame.shadow_params[layer].z) break;
        }
        prm = frame.shadow_params[layer];
    }
    vec3 axis = l;
    float texel = prm.x;
    vec3 d = p - light.position_range.xyz;
    if (kind != SV_SHADOW_ORTHO) {
        if (kind == SV_SHADOW_SPOT) {
            axis = light.direction_type.xyz;
        } else {
            int f = shadow_cube_face(d);
            axis = vec3(0.0);
            axis[f / 2] = (f & 1) == 0 ? 1.0 : -1.0;
        }
        texel *= max(dot(axis, d), 0.0);
    }
    float cos_a = dot(n, axis);
    float sin_a = sqrt(max(1.0 - cos_a * cos_a, 0.0));
    vec3 q = p + n * (texel * (0.5 + 3.0 * sin_a));
    if (kind == SV_SHADOW_CUBE) layer += shadow_cube_face(q - light.position_range.xyz);
    vec4 c = frame.shadow_view_proj[layer] * vec4(q, 1.0);
    if (c.w <= 0.0) return 1.0;
    vec2 uv = c.xy / c.w * 0.5 + 0.5;
    float z = clamp(c.z / c.w, 0.0, 1.0);
    float sum = 0.0;
    for (int j = -1; j <= 1; ++j)
        for (int i = -1; i <= 1; ++i) sum += texture(shadow_tex, vec4(uv + vec2(i, j) * prm.z, float(layer), z));
    return sum / 9.0;
}

// Direct light of the KHR_lights_punctual lights: Lambert diffuse plus a normalised Blinn-Phong
// lobe (exponent from roughness, Schlick-free F0 = mix(0.04, albedo, metallic)); without the lobe
// under --no-specular (SV_FRAME_NO_SPECULAR: diffuse only, as the sky's reflections are left out; the
// benchmarks compare Cycles' diffuse spheres with it).
// probe_lit: the surface's probe term came from a baked probe (not the fallback probe 0). The bake
// rendered a baked light (VULKAN_SCHNEE_light.mode "baked") into those probes, direct and bounced,
// so adding its direct term there would count it twice: it is skipped. Where the fallback lights
// the surface (probe mode off, or outside every grid) no probe holds the light and it is added.
// Realtime and mixed lights (spot.z 0 and 2) always add it; one with shadow map layers (spot.w >= 0)
// is multiplied by shadow_visibility().
// skip_baked / only_baked: the lights summed (the deferred probe pass sums the baked ones apart, to add
// them where no baked probe lit the pixel).
vec3 direct_light_of(vec3 p, vec3 n, vec3 albedo, float metallic, float roughness, bool skip_baked, bool only_baked) {
    vec3 v = normalize(frame.camera_pos.xyz - p);
    vec3 f0 = mix(vec3(0.04), albedo, metallic);
    float r = clamp(roughness, 0.05, 1.0);
    float s = max(2.0 / (r * r * r * r) - 2.0, 1.0);
    vec3 sum = vec3(0.0);
    float specular = (frame.flags & SV_FRAME_NO_SPECULAR) != 0u ? 0.0 : 1.0;
    for (uint i = 0u; i < frame.light_count; ++i) {
        sv_gpu_light light = lights[i];
        bool baked = abs(light.spot.z - float(SV_LIGHT_BAKED)) < 0.5;
        if ((skip_baked && baked) || (only_baked && !baked)) continue;
        uint type = uint(light.direction_type.w);
        vec3 l;
        float atten = 1.0;
        if (type == 0u) {
            l = -light.direction_type.xyz;
        } else {
            vec3 d = light.position_range.xyz - p;
            float dist2 = max(dot(d, d), 1e-8);
            l = d * inversesqrt(dist2);
            atten = 1.0 / dist2;
            float range = light.position_range.w;
            if (range > 0.0) {
                float q = dist2 / (range * range);
                atten *= clamp(1.0 - q * q, 0.0, 1.0);
            }
            if (type == 2u) {
                float cd = dot(light.direction_type.xyz, -l);
                float a = clamp(cd * light.spot.x + light.spot.y, 0.0, 1.0);
                atten *= a * a;
            }
        }
        float nl = max(dot(n, l), 0.0);
        if (nl <= 0.0) continue;
        vec3 h = normalize(l + v);
        float spec = (s + 8.0) / (8.0 * SH_PI) * pow(max(dot(n, h), 0.0), s);
        if (light.spot.w > -0.5 && atten > 0.0) atten *= shadow_visibility(light, p, n, l);
        vec3 radiance = light.color.rgb * atten;
        sum += ((1.0 - metallic) * albedo / SH_PI + specular * f0 * spec) * radiance * nl;
    }
    return sum;
}

vec3 direct_light(vec3 p, vec3 n, vec3 albedo, float metallic, float roughness, bool probe_lit) {
    return direct_light_of(p, n, albedo, metallic, roughness, probe_lit, false);
}

#endif
