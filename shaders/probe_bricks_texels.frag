#version 450
// Brick view, texels: one brick texel's N / D read exactly (texelFetch of every channel group, the pool's
// binary16 or float32 values) and shown as
//   SV_BRICK_VIEW_TEXELS    E(n) / pi = max(sum_i A_l(i) Y_i(n) N_i / D, 0) / pi, n the exact sphere normal
//                           where the pixel's ray meets the sphere (not the tessellation's), times
//                           mix(BRICK_PARTIAL_TINT, 1, D) where 0 < D < 1 (some probe with weight invalid);
//   SV_BRICK_VIEW_VALIDITY  flat brick_validity_colour(D);
// and BRICK_NO_PROBE in both where D <= 0 (no valid probe, or the texel outside every leaf); the colours
// in brick_view_colours.glsl.
#extension GL_GOOGLE_include_directive : require
#define SV_SCENE_BINDINGS
#include "gpu_types.glsl"
#include "sh.glsl"
#include "brick_view_colours.glsl"

layout(location = 1) flat in vec4 v_sphere;
layout(location = 2) flat in ivec3 v_texel;
layout(location = 0) out vec4 out_color;

vec3 unproject(vec3 ndc) {
    vec4 q = frame.inv_view_proj * vec4(ndc, 1.0);
    return q.xyz / q.w;
}

// The unit normal of the sphere (centre c, radius r) where the ray through this pixel's centre first
// meets it. The pixel is gl_FragCoord over the target's size (push constants), not the interpolated
// surface point (the rasteriser's snapped vertices move it by up to 1/512 pixel: a normal error of 1e-3
// on a sphere two pixels wide). The ray is taken at the centre's own depth and measured from the centre
// unprojected through the same matrix, so that fp32's errors of the inverse mostly cancel: the near
// plane alone (0.05 m from the eye) gave a direction off by 1e-5 rad, 2e-3 of a small sphere's normal.
vec3 sphere_normal(vec3 c, float r) {
    vec2 ndc = 2.0 * gl_FragCoord.xy / draw.normal_matrix[0].xy - 1.0;
    vec4 cc = frame.view_proj * vec4(c, 1.0);
    vec3 p1 = unproject(vec3(ndc, cc.z / cc.w)); // the pixel's ray at the centre's depth
    vec3 d = normalize(p1 - unproject(vec3(ndc, 0.0)));
    vec3 oc = p1 - unproject(cc.xyz / cc.w);
    float b = dot(oc, d);
    float t = -b - sqrt(max(b * b - (dot(oc, oc) - r * r), 0.0));
    return normalize(oc + t * d);
}

void main() {
    sv_gpu_grid g = grids[draw.material_index];
    vec4 t0 = texelFetch(brick_pool, v_texel, 0); // N_0 (RGB), D
    float D = t0.w;
    if (!(D > 0.0)) {
        out_color = vec4(BRICK_NO_PROBE, 1.0);
        return;
    }
    if (draw.object_index == SV_BRICK_VIEW_VALIDITY) {
        out_color = vec4(brick_validity_colour(D), 1.0);
        return;
    }
    vec3 n = sphere_normal(v_sphere.xyz, v_sphere.w);
    uint C = g.bricks.w & 255u, slab = g.bricks.w >> 8u;
    uint band = C >= 25u ? 4u : C >= 16u ? 3u : C >= 9u ? 2u : C >= 4u ? 1u : 0u;
    float AY[25];
    sh_lambert_basis(band, n, AY);
    vec3 s = AY[0] * t0.rgb;
    uint groups = (3u * C + 4u) / 4u; // ceil((3C + 1) / 4)
    for (uint k = 1u; k < groups; ++k) {
        vec4 t = texelFetch(brick_pool, v_texel + ivec3(0, 0, int(k * slab)), 0);
        for (uint j = 0u; j < 4u; ++j) { // channel 4k + j = N_i colour c, i = 1 + (4k + j - 4) / 3
            uint ch = 4u * k + j - 4u, i = 1u + ch / 3u;
            if (i < C) s[ch % 3u] += AY[i] * t[j];
        }
    }
    vec3 e = max(s / D, vec3(0.0)) / SH_PI;
    out_color = vec4(e * mix(BRICK_PARTIAL_TINT, vec3(1.0), clamp(D, 0.0, 1.0)), 1.0);
}
