#version 450
// Brick view: a brick's region outline in its level's colour (linear, before tone mapping); levels past
// the palette take its last colour. tests/engine/test_engine_brick_view.py reads these values.
#extension GL_GOOGLE_include_directive : require
#define SV_SCENE_BINDINGS
#include "gpu_types.glsl"
#include "sv_gpu_brick_view.h"

const vec3 LEVEL_COLOURS[SV_BRICK_LEVEL_COLOURS] = vec3[](vec3(0.1, 0.8, 1.0),  // L0 cyan
                                                          vec3(0.3, 1.0, 0.2),  // L1 green
                                                          vec3(1.0, 0.55, 0.1), // L2 orange
                                                          vec3(1.0, 0.15, 0.5), // L3 pink
                                                          vec3(0.6, 0.35, 1.0), // L4 violet
                                                          vec3(1.0, 1.0, 1.0)); // L5 and up white

layout(location = 0) out vec4 out_color;

void main() { out_color = vec4(LEVEL_COLOURS[min(uint(draw.model[0].w), SV_BRICK_LEVEL_COLOURS - 1u)], 1.0); }
