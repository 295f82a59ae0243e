#version 450
// Background: the sky's equirect radiance (mip 0, bilinear) along each pixel's view ray, drawn
// first into the HDR target without depth test or write, so geometry covers it.
#extension GL_GOOGLE_include_directive : require
#define SV_SCENE_BINDINGS
#include "gpu_types.glsl"
#include "shading.glsl"

layout(location = 0) in vec2 v_ndc;
layout(location = 0) out vec4 out_color;

void main() {
    // Two points on the pixel's ray (depths 0 and 0.5 are finite for every projection the viewer
    // builds, the infinite perspective included).
    vec4 a = frame.inv_view_proj * vec4(v_ndc, 0.0, 1.0);
    vec4 b = frame.inv_view_proj * vec4(v_ndc, 0.5, 1.0);
    vec3 d = normalize(b.xyz / b.w - a.xyz / a.w);
    out_color = vec4(textureLod(sky_tex, sky_uv(d), 0.0).rgb, 1.0);
}
