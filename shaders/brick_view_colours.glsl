// The brick view's colours (linear, before tone mapping), shared by the brick view (probe_bricks_*.frag)
// and the brick debug views (brick_debug.glsl); tests/engine/test_engine_brick_view.py reads these values.
#ifndef SV_BRICK_VIEW_COLOURS_GLSL
#define SV_BRICK_VIEW_COLOURS_GLSL
#include "sv_gpu_brick_view.h"

// A brick of level L: LEVEL_COLOURS[min(L, 5)].
const vec3 BRICK_LEVEL_COLOURS[SV_BRICK_LEVEL_COLOURS] = vec3[](vec3(0.1, 0.8, 1.0),  // L0 cyan
                                                                vec3(0.3, 1.0, 0.2),  // L1 green
                                                                vec3(1.0, 0.55, 0.1), // L2 orange
                                                                vec3(1.0, 0.15, 0.5), // L3 pink
                                                                vec3(0.6, 0.35, 1.0), // L4 violet
                                                                vec3(1.0, 1.0, 1.0)); // L5 and up white
const vec3 BRICK_NO_PROBE = vec3(1.0, 0.0, 1.0);     // D <= 0: no valid probe
const vec3 BRICK_PARTIAL_TINT = vec3(1.0, 0.3, 0.3); // texels: E / pi times mix(tint, 1, D)
const vec3 BRICK_INVALID = vec3(1.0, 0.1, 0.0);      // validity: mix(INVALID, VALID, D)
const vec3 BRICK_VALID = vec3(0.1, 1.0, 0.1);
const vec3 BRICK_NONE = vec3(0.2, 0.2, 0.2); // brick debug views: no brick at the pixel

vec3 brick_level_colour(uint level) { return BRICK_LEVEL_COLOURS[min(level, SV_BRICK_LEVEL_COLOURS - 1u)]; }
vec3 brick_validity_colour(float D) {
    return D > 0.0 ? mix(BRICK_INVALID, BRICK_VALID, clamp(D, 0.0, 1.0)) : BRICK_NO_PROBE;
}

#endif
