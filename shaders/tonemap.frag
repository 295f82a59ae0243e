#version 450
// Exposure, tone mapping (Khronos PBR Neutral by default, or Narkowicz's ACES fit, or clamp) and
// sRGB output. The HDR target has the same size as the output, so pixels map one to one.
#extension GL_GOOGLE_include_directive : require
#include "gpu_types.glsl"

layout(set = 0, binding = SV_BINDING_HDR) uniform sampler2D hdr;
layout(push_constant, std430) uniform TonemapBlock { sv_gpu_tonemap pc; };
layout(location = 0) out vec4 out_color;

// Khronos PBR Neutral tone mapper (KhronosGroup/ToneMapping, reference GLSL).
vec3 pbr_neutral(vec3 color) {
    const float start_compression = 0.8 - 0.04;
    const float desaturation = 0.15;
    float x = min(color.r, min(color.g, color.b));
    float offset = x < 0.08 ? x - 6.25 * x * x : 0.04;
    color -= offset;
    float peak = max(color.r, max(color.g, color.b));
    if (peak < start_compression) return color;
    const float d = 1.0 - start_compression;
    float new_peak = 1.0 - d * d / (peak + d - start_compression);
    color *= new_peak / peak;
    float g = 1.0 - 1.0 / (desaturation * (peak - new_peak) + 1.0);
    return mix(color, vec3(new_peak), g);
}

// Krzysztof Narkowicz's fit of the ACES filmic curve.
vec3 aces_fitted(vec3 x) {
    return clamp((x * (2.51 * x + 0.03)) / (x * (2.43 * x + 0.59) + 0.14), 0.0, 1.0);
}

vec3 srgb_encode(vec3 c) {
    return mix(12.92 * c, 1.055 * pow(c, vec3(1.0 / 2.4)) - 0.055, step(vec3(0.0031308), c));
}

void main() {
    vec3 c = max(texelFetch(hdr, ivec2(gl_FragCoord.xy), 0).rgb * pc.exposure, vec3(0.0));
    if (pc.op == SV_TONEMAP_PBR_NEUTRAL) c = pbr_neutral(c);
    else if (pc.op == SV_TONEMAP_ACES) c = aces_fitted(c);
    c = clamp(c, 0.0, 1.0);
    if (pc.encode_srgb != 0u) c = srgb_encode(c);
    out_color = vec4(c, 1.0);
}
