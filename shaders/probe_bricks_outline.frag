#version 450
// Brick view: a brick's region outline in its level's colour (brick_view_colours.glsl).
#extension GL_GOOGLE_include_directive : require
#define SV_SCENE_BINDINGS
#include "gpu_types.glsl"
#include "brick_view_colours.glsl"

layout(location = 0) out vec4 out_color;

void main() { out_color = vec4(brick_level_colour(uint(draw.model[0].w)), 1.0); }
