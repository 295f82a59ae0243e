#version 450
// Brick view, texels (shaders/sv_gpu_brick_view.h): the 125 texels of one brick as instances of the probe
// view's unit UV sphere, texel t = i + 5j + 25k = gl_InstanceIndex at lattice point r + 2^L (i, j, k),
// radius SV_BRICK_TEXEL_RADIUS * 2^L min cells. Out: the sphere (centre, radius) for the fragment's exact
// normal, and the texel's pool coordinate in channel group 0 (the brick's texel
// origin 5 (b mod px, (b / px) mod py, b / (px py)) + (0, 0, bricks.z) as in bricks_surface.glsl's
// brick_tap, + (i, j, k)).
#extension GL_GOOGLE_include_directive : require
#define SV_SCENE_BINDINGS
#include "gpu_types.glsl"
#include "sv_gpu_brick_view.h"

layout(location = SV_LOCATION_POSITION) in vec3 in_position;

layout(location = 1) flat out vec4 v_sphere;
layout(location = 2) flat out ivec3 v_texel;

void main() {
    sv_gpu_grid g = grids[draw.material_index];
    uint t = uint(gl_InstanceIndex);
    uvec3 ijk = uvec3(t % 5u, (t / 5u) % 5u, t / 25u);
    float s = exp2(draw.model[0].w);
    vec3 u = draw.model[0].xyz + s * vec3(ijk);
    float h = g.origin_spacing.w;
    vec3 c = g.origin_spacing.xyz + h * (u.x * g.axes[0].xyz + u.y * g.axes[1].xyz + u.z * g.axes[2].xyz);
    float radius = float(SV_BRICK_TEXEL_RADIUS) * s * h;
    uint b = draw.probe_index, px = g.bricks.y & 0xffffu, py = g.bricks.y >> 16u;
    uvec3 ob = 5u * uvec3(b % px, (b / px) % py, b / (px * py)) + uvec3(0u, 0u, g.bricks.z);
    v_sphere = vec4(c, radius);
    v_texel = ivec3(ob + ijk);
    gl_Position = frame.view_proj * vec4(c + in_position * radius, 1.0);
}
