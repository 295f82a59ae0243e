#version 450
// Probe view: the 12 edges of every occupied grid cell, and of every octree / kd tree leaf, as a line
// list (24 vertices per instance, no vertex buffer). The instance buffer is the cell list of
// probe_cells.vert; probe.y = grid, probe.z = the packed levels of a leaf (0 for a dense cell).
#extension GL_GOOGLE_include_directive : require
#define SV_SCENE_BINDINGS
#include "gpu_types.glsl"

const ivec2 EDGES[12] = ivec2[](ivec2(0, 1), ivec2(2, 3), ivec2(4, 5), ivec2(6, 7), ivec2(0, 2), ivec2(1, 3),
                                ivec2(4, 6), ivec2(5, 7), ivec2(0, 4), ivec2(1, 5), ivec2(2, 6), ivec2(3, 7));

void main() {
    sv_gpu_cell c = cells[gl_InstanceIndex];
    sv_gpu_grid g = grids[c.probe.y];
    int e = gl_VertexIndex / 2;
    int corner = (gl_VertexIndex & 1) == 0 ? EDGES[e].x : EDGES[e].y;
    // Edge lengths in grid spacings: 2^l per axis of the packed levels in probe.z (a dense cell's 0:
    // one spacing; an octree or kd tree leaf's box, sv_probe_pack.c leaf_outlines).
    uvec3 lv = uvec3(c.probe.z & 255u, (c.probe.z >> 8u) & 255u, (c.probe.z >> 16u) & 255u);
    vec3 s = (vec3(corner & 1, (corner >> 1) & 1, (corner >> 2) & 1) - 0.5) * vec3(uvec3(1u) << lv);
    // The brick view (draw.flags 1) draws the bricks' boxes instead of a bricked tree grid's leaves: the
    // line is put outside the clip volume.
    uint bricked = SV_GRID_OCTREE | SV_GRID_BRICKS;
    if (draw.flags == 1u && (g.base.z & bricked) == bricked) {
        gl_Position = vec4(2.0, 2.0, 2.0, 1.0);
        return;
    }
    float h = g.origin_spacing.w;
    vec3 p = c.center_radius.xyz + h * (s.x * g.axes[0].xyz + s.y * g.axes[1].xyz + s.z * g.axes[2].xyz);
    gl_Position = frame.view_proj * vec4(p, 1.0);
}
