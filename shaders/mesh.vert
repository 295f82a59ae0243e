#version 450
// Scene geometry: object -> world with the per-draw push constants, world -> clip with the frame.
#extension GL_GOOGLE_include_directive : require
#define SV_SCENE_BINDINGS
#include "gpu_types.glsl"

layout(location = SV_LOCATION_POSITION) in vec3 in_position;
layout(location = SV_LOCATION_NORMAL) in vec3 in_normal;
layout(location = SV_LOCATION_UV) in vec2 in_uv;

layout(location = 0) out vec3 v_world;
layout(location = 1) out vec3 v_normal;
layout(location = 2) out vec2 v_uv;

void main() {
    vec4 world = draw.model * vec4(in_position, 1.0);
    mat3 nm = mat3(draw.normal_matrix[0].xyz, draw.normal_matrix[1].xyz, draw.normal_matrix[2].xyz);
    v_world = world.xyz;
    v_normal = nm * in_normal;
    v_uv = in_uv;
    gl_Position = frame.view_proj * world;
}
