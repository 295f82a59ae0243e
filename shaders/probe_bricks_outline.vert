#version 450
// Brick view (shaders/sv_gpu_brick_view.h): the 12 edges of one brick's region [r, r + 4 * 2^L) (lattice
// coordinates of its grid) as a line list, 24 vertices, no vertex buffer; the brick comes in the push
// constants (model[0] = r, L; material_index = grid).
#extension GL_GOOGLE_include_directive : require
#define SV_SCENE_BINDINGS
#include "gpu_types.glsl"
#include "sv_gpu_brick_view.h"

const ivec2 EDGES[12] = ivec2[](ivec2(0, 1), ivec2(2, 3), ivec2(4, 5), ivec2(6, 7), ivec2(0, 2), ivec2(1, 3),
                                ivec2(4, 6), ivec2(5, 7), ivec2(0, 4), ivec2(1, 5), ivec2(2, 6), ivec2(3, 7));

void main() {
    sv_gpu_grid g = grids[draw.material_index];
    int e = gl_VertexIndex / 2;
    int corner = (gl_VertexIndex & 1) == 0 ? EDGES[e].x : EDGES[e].y;
    float edge = 4.0 * exp2(draw.model[0].w); // B - 1 = 4 cells of 2^L min cells
    vec3 u = draw.model[0].xyz + edge * vec3(corner & 1, (corner >> 1) & 1, (corner >> 2) & 1);
    float h = g.origin_spacing.w;
    vec3 p = g.origin_spacing.xyz + h * (u.x * g.axes[0].xyz + u.y * g.axes[1].xyz + u.z * g.axes[2].xyz);
    gl_Position = frame.view_proj * vec4(p, 1.0);
}
