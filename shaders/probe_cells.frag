#version 450
// Probe-cell view: a white diffuse sphere lit by its probe alone (E(n)/pi), so each probe's
// lighting can be read off directly; cells of the fallback draw grey.
#extension GL_GOOGLE_include_directive : require
#define SV_SCENE_BINDINGS
#include "gpu_types.glsl"
#include "shading.glsl"

layout(location = 0) in vec3 v_normal;
layout(location = 1) flat in uint v_probe;
layout(location = 0) out vec4 out_color;

void main() {
    vec3 n = normalize(v_normal);
    vec3 e = max(probe_irradiance(v_probe, n), vec3(0.0));
    out_color = vec4(e / SH_PI, 1.0);
}
