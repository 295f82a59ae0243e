// Surface shading shared by the scene and the probe-cell view (needs SV_SCENE_BINDINGS).
#ifndef SV_SHADING_GLSL
#define SV_SHADING_GLSL
#include "sh.glsl"

// Irradiance E(n) of probe `index` (DESIGN.md §3), not clamped: sh_irradiance() of sh.glsl,
// reading the coefficients straight from the buffer and only the bands the probe has.
vec3 probe_irradiance(uint index, vec3 n) {
    uint band = min(uint(probes[index].params.x), 4u);
    float Y[25];
    sh_eval_basis(band, n, Y);
    vec3 e = vec3(0.0);
    for (uint l = 0u; l <= band; ++l) {
        float a = sh_lambert_band(l);
        for (uint i = l * l; i < (l + 1u) * (l + 1u); ++i) e += a * Y[i] * probes[index].sh[i].xyz;
    }
    return e;
}

// A distinct, stable colour per probe index (index 0, the fallback, is mid grey).
vec3 probe_color(uint index) {
    if (index == 0u) return vec3(0.5);
    uint h = index * 2654435761u;
    h ^= h >> 15;
    h *= 2246822519u;
    h ^= h >> 13;
    return vec3(float(h & 255u), float((h >> 8) & 255u), float((h >> 16) & 255u)) / 255.0 * 0.8 + 0.2;
}

// Direct light of the KHR_lights_punctual lights: Lambert diffuse plus a normalised Blinn-Phong
// lobe (exponent from roughness, Schlick-free F0 = mix(0.04, albedo, metallic)).
vec3 direct_light(vec3 p, vec3 n, vec3 albedo, float metallic, float roughness) {
    vec3 v = normalize(frame.camera_pos.xyz - p);
    vec3 f0 = mix(vec3(0.04), albedo, metallic);
    float r = clamp(roughness, 0.05, 1.0);
    float s = max(2.0 / (r * r * r * r) - 2.0, 1.0);
    vec3 sum = vec3(0.0);
    for (uint i = 0u; i < frame.light_count; ++i) {
        sv_gpu_light light = lights[i];
        uint type = uint(light.direction_type.w);
        vec3 l;
        float atten = 1.0;
        if (type == 0u) {
            l = -light.direction_type.xyz;
        } else {
            vec3 d = light.position_range.xyz - p;
            float dist2 = max(dot(d, d), 1e-8);
            l = d * inversesqrt(dist2);
            atten = 1.0 / dist2;
            float range = light.position_range.w;
            if (range > 0.0) {
                float q = dist2 / (range * range);
                atten *= clamp(1.0 - q * q, 0.0, 1.0);
            }
            if (type == 2u) {
                float cd = dot(light.direction_type.xyz, -l);
                float a = clamp(cd * light.spot.x + light.spot.y, 0.0, 1.0);
                atten *= a * a;
            }
        }
        float nl = max(dot(n, l), 0.0);
        if (nl <= 0.0) continue;
        vec3 h = normalize(l + v);
        float spec = (s + 8.0) / (8.0 * SH_PI) * pow(max(dot(n, h), 0.0), s);
        vec3 radiance = light.color.rgb * atten;
        sum += ((1.0 - metallic) * albedo / SH_PI + f0 * spec) * radiance * nl;
    }
    return sum;
}

#endif
