#version 450
// Shadow pass (docs/engine.md "Shadows"): depth only, object -> light clip space in one matrix.
#extension GL_GOOGLE_include_directive : require
#include "sv_gpu.h"

layout(location = SV_LOCATION_POSITION) in vec3 in_position;

layout(push_constant, std430) uniform ShadowDrawBlock { sv_gpu_shadow_draw draw; };

void main() { gl_Position = draw.light_mvp * vec4(in_position, 1.0); }
