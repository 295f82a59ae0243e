#version 450
// The deferred per-pixel probe pass (docs/engine.md "The per-pixel probe pass"): for every pixel whose
// visible fragment asked for per-pixel probes (mesh.frag built with SV_DEFERRED_PROBES), E from the
// grids at the fragment's own point and normal, then the terms E decides, added into the HDR target:
//   colour += k max(E, 0) + ratio(E) spec + (lit ? 0 : baked)
// mesh.frag's forward path computes the same E with the same functions (grid_irradiance, the object's
// own probe for tetrahedra, the fallback probe 0), once per fragment drawn; here once per pixel, in a
// compute dispatch (a GPU's compute units, not only its graphics part).
#extension GL_GOOGLE_include_directive : require
#define SV_SCENE_BINDINGS
#include "gpu_types.glsl"
#include "shading.glsl"

layout(local_size_x = SV_PROBE_PASS_GROUP, local_size_y = SV_PROBE_PASS_GROUP) in;

layout(set = SV_SET_PROBE_PASS, binding = 0, rgba32f) uniform image2D hdr_image;
layout(set = SV_SET_PROBE_PASS, binding = SV_GBUF_POINT, rgba32ui) uniform readonly uimage2D gbuf_point;
layout(set = SV_SET_PROBE_PASS, binding = SV_GBUF_NORMAL, rgba32f) uniform readonly image2D gbuf_normal;
layout(set = SV_SET_PROBE_PASS, binding = SV_GBUF_DIFFUSE, rgba32f) uniform readonly image2D gbuf_diffuse;
layout(set = SV_SET_PROBE_PASS, binding = SV_GBUF_BAKED, rgba32f) uniform readonly image2D gbuf_baked;

void main() {
    ivec2 xy = ivec2(gl_GlobalInvocationID.xy);
    if (any(greaterThanEqual(xy, imageSize(hdr_image)))) return;
    uvec4 point = imageLoad(gbuf_point, xy);
    uint meta = point.w;
    if ((meta & SV_GBUF_META_PIXEL) == 0u) return;
    vec3 p = uintBitsToFloat(point.xyz);
    vec4 nr = imageLoad(gbuf_normal, xy);
    vec3 n = nr.xyz;
    bool cube = (meta & SV_GBUF_META_CUBE) != 0u;
    vec3 e_probe;
    // As mesh.frag: the grids; outside them the object's own probe when it came from tetrahedra, else
    // the fallback probe 0.
    bool probe_lit = grid_irradiance(p, n, cube, (meta & SV_GBUF_META_MOVABLE) != 0u, e_probe);
    if (!probe_lit && (meta & SV_GBUF_META_TETRA) != 0u) {
        uint entry = meta >> SV_GBUF_META_ENTRY_SHIFT;
        probe_lit = entry != 0u;
        bool cube_obj = cube || (entry != 0u && (meta & SV_GBUF_META_CUBE_ONLY) != 0u);
        e_probe = probe_scaled_irradiance(entry, n, cube_obj);
    } else if (!probe_lit) {
        e_probe = probe_scaled_irradiance(0u, n, cube);
    }
    vec4 kd = imageLoad(gbuf_diffuse, xy);
    vec4 bs = imageLoad(gbuf_baked, xy);
    vec3 color = imageLoad(hdr_image, xy).rgb + kd.rgb * max(e_probe, vec3(0.0));
    vec3 spec = vec3(nr.w, kd.w, bs.w);
    if ((frame.flags & (SV_FRAME_SKY | SV_FRAME_NO_SPECULAR)) == SV_FRAME_SKY)
        color += spec * sky_specular_ratio(n, e_probe, cube);
    if (!probe_lit) color += bs.rgb;
    imageStore(hdr_image, xy, vec4(color, 1.0));
}
