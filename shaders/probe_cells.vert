#version 450
// Probe-cell view: one small sphere per occupied grid cell, instanced; the instance buffer holds
// the cell centre, the sphere radius and the probe index the cell maps to.
#extension GL_GOOGLE_include_directive : require
#define SV_SCENE_BINDINGS
#include "gpu_types.glsl"

layout(location = SV_LOCATION_POSITION) in vec3 in_position;
layout(location = SV_LOCATION_NORMAL) in vec3 in_normal;

layout(location = 0) out vec3 v_normal;
layout(location = 1) flat out uint v_probe;

void main() {
    sv_gpu_cell c = cells[gl_InstanceIndex];
    v_normal = in_normal;
    v_probe = c.probe.x;
    gl_Position = frame.view_proj * vec4(c.center_radius.xyz + in_position * c.center_radius.w, 1.0);
}
