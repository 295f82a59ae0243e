#version 450
// Scene shading: DESIGN.md §3 movable diffuse from the object's probe, punctual lights, emission.
// Output is linear scene-referred radiance (the HDR target, tone mapped in tonemap.frag).
#extension GL_GOOGLE_include_directive : require
#define SV_SCENE_BINDINGS
#include "gpu_types.glsl"
#include "shading.glsl"
#include "brick_debug.glsl"

layout(location = 0) in vec3 v_world;
layout(location = 1) in vec3 v_normal;
layout(location = 2) in vec2 v_uv;

layout(location = 0) out vec4 out_color;
// Builds without the per-pixel grid lookup (docs/engine.md "The per-pixel probe pass"): SV_DEFERRED_PROBES, the
// scene pass of a frame with the probe pass; SV_LEAN_SCENE, the scene pass of a frame where no fragment asks
// for per-pixel probes (a per-pixel mode there takes the object's probe: the renderer never draws one).
#if defined(SV_DEFERRED_PROBES) || defined(SV_LEAN_SCENE)
#define SV_SCENE_NO_GRIDS
#endif
#ifdef SV_DEFERRED_PROBES
// The deferred probe pass (docs/engine.md "The per-pixel probe pass"): a per-pixel fragment writes its
// colour without the terms E decides and what probe_pass.comp needs to add them; any other fragment its
// whole colour and meta 0.
layout(location = SV_GBUF_POINT) out uvec4 out_point;     // p bits, meta (SV_GBUF_META_*)
layout(location = SV_GBUF_NORMAL) out vec4 out_normal;    // n, sky specular r
layout(location = SV_GBUF_DIFFUSE) out vec4 out_diffuse;  // albedo sh_scale / pi, sky specular g
layout(location = SV_GBUF_BAKED) out vec4 out_baked;      // baked lights' direct light, sky specular b
#endif

void main() {
    vec3 n = normalize(v_normal);
    // The pipeline's front face is CCW; glTF makes a node whose world matrix has a negative
    // determinant (a mirror) wind clockwise, so for those the rasteriser's "front" is the back.
    bool front = gl_FrontFacing != ((draw.flags & SV_DRAW_MIRRORED) != 0u);
    if (!front) n = -n; // planes and open meshes are lit from the side we see
    if (frame.debug_mode == SV_DEBUG_PROBE_INDEX) {
        out_color = vec4(float(draw.probe_index), 0.0, 0.0, 1.0);
        return;
    }
    if (frame.debug_mode == SV_DEBUG_PROBE_COLOR) {
        out_color = vec4(probe_color(draw.probe_index) * (0.6 + 0.4 * abs(n.y)), 1.0);
        return;
    }
    if (frame.debug_mode == SV_DEBUG_BRICK_LEVEL || frame.debug_mode == SV_DEBUG_BRICK_VALIDITY) {
        out_color = vec4(brick_debug_colour(v_world, n, frame.debug_mode), 1.0);
        return;
    }
    if (frame.debug_mode == SV_DEBUG_NORMALS) {
        out_color = vec4(n * 0.5 + 0.5, 1.0);
        return;
    }

    sv_gpu_material m = materials[draw.material_index];
    vec4 base = m.base_color;
    if (m.base_color_texture >= 0) base *= texture(base_color_tex, v_uv);
    vec3 albedo = base.rgb;

    // diffuse = albedo * (shScale * max(E(n), 0) / pi + ambientTerm); the probe's own scale
    // multiplies the material's shScale (1.0 in a fresh bake). E comes from the object's probe,
    // from the grids per pixel, or from the fallback probe 0 (mode off), by the object's own
    // probeMode (its node's VULKAN_SCHNEE_node, in draw.flags + 1) or else the material's, unless
    // --probe-mode overrides both.
    uint node_mode = (draw.flags >> SV_DRAW_NODE_MODE_SHIFT) & 3u;
    uint own_mode = node_mode != 0u ? node_mode - 1u : m.probe_mode;
    uint mode = frame.probe_mode == SV_PROBE_MODE_MATERIAL ? own_mode : frame.probe_mode;
    // How E is evaluated (docs/ambient-cube.md §5): the probe's SH, or its ambient cube, by the
    // object's or else the material's probeRepresentation unless --probe-representation overrides it.
    uint node_rep = (draw.flags >> SV_DRAW_NODE_REP_SHIFT) & 3u;
    uint own_rep = node_rep != 0u ? node_rep - 1u : m.probe_representation;
    uint rep = frame.probe_representation == SV_PROBE_REP_MATERIAL ? own_rep : frame.probe_representation;
    bool cube = rep == SV_PROBE_REP_AMBIENT_CUBE;
#ifdef SV_DEFERRED_PROBES
    out_point = uvec4(0u);
    if (mode == SV_PROBE_MODE_PIXEL) {
        // The same terms as below, apart: colour = rest + k max(E, 0) + ratio(E) spec + (lit ? 0 : baked).
        uint index = draw.probe_index;
        uint entry = index == 0u ? 0u : index - frame.probe_rebase;
        vec3 k = albedo * m.sh_scale / SH_PI;
        vec3 spec = vec3(0.0), baked = vec3(0.0), rest = albedo * m.ambient_term;
        if ((frame.flags & (SV_FRAME_SKY | SV_FRAME_NO_SPECULAR)) == SV_FRAME_SKY)
            spec = sky_specular_unscaled(v_world, n, albedo, m.metallic, m.roughness);
        if ((frame.flags & SV_FRAME_NO_DIRECT) == 0u) {
            rest += direct_light_of(v_world, n, albedo, m.metallic, m.roughness, true, false);
            baked = direct_light_of(v_world, n, albedo, m.metallic, m.roughness, false, true);
        }
        vec3 emissive = m.emissive.rgb;
        if (m.emissive_texture >= 0) emissive *= texture(emissive_tex, v_uv).rgb;
        out_color = vec4(rest + emissive, 1.0);
        uint meta = SV_GBUF_META_PIXEL | (cube ? SV_GBUF_META_CUBE : 0u) |
                    ((draw.flags & SV_DRAW_MOVABLE) != 0u ? SV_GBUF_META_MOVABLE : 0u) |
                    ((draw.flags & SV_DRAW_TETRA) != 0u ? SV_GBUF_META_TETRA : 0u) |
                    ((draw.flags & SV_DRAW_CUBE_ONLY) != 0u ? SV_GBUF_META_CUBE_ONLY : 0u) |
                    (entry << SV_GBUF_META_ENTRY_SHIFT);
        out_point = uvec4(floatBitsToUint(v_world), meta);
        out_normal = vec4(n, spec.r);
        out_diffuse = vec4(k, spec.g);
        out_baked = vec4(baked, spec.b);
        return;
    }
#endif
    vec3 e_probe;
    bool probe_lit; // E came from a baked probe rather than the fallback probe 0 (for baked lights)
    // Per pixel, a fragment no octree or dense grid holds takes the object's own probe when that was
    // interpolated from tetrahedra (no GPU point location for them), else the fallback probe 0.
#ifndef SV_SCENE_NO_GRIDS
    if (mode == SV_PROBE_MODE_PIXEL)
        probe_lit = grid_irradiance(v_world, n, cube, (draw.flags & SV_DRAW_MOVABLE) != 0u, e_probe);
    if (mode != SV_PROBE_MODE_PIXEL || (!probe_lit && (draw.flags & SV_DRAW_TETRA) != 0u)) {
#else
    if (true) { // the non-pixel modes (a per-pixel fragment returned above)
#endif
        uint index = mode == SV_PROBE_MODE_OFF ? 0u : draw.probe_index;
        probe_lit = index != 0u;
        // A probe from a grid that holds cubes only is shaded with its cube (docs/ambient-cube.md §5).
        bool cube_obj = cube || (index != 0u && (draw.flags & SV_DRAW_CUBE_ONLY) != 0u);
        // The slots sit after the file's probes, or right after the fallback when the file's probes are
        // not uploaded (frame.probe_rebase, docs/engine.md "Probe buffers"); draw.probe_index stays the
        // object's probe as --print-assignments and the probe-index view give it.
        e_probe = probe_scaled_irradiance(index == 0u ? 0u : index - frame.probe_rebase, n, cube_obj);
    } else if (!probe_lit) {
        e_probe = probe_scaled_irradiance(0u, n, cube);
    }
    vec3 color = albedo * (m.sh_scale * max(e_probe, vec3(0.0)) / SH_PI + m.ambient_term);

    if ((frame.flags & (SV_FRAME_SKY | SV_FRAME_NO_SPECULAR)) == SV_FRAME_SKY)
        color += sky_specular(v_world, n, albedo, m.metallic, m.roughness, e_probe, cube);

    if ((frame.flags & SV_FRAME_NO_DIRECT) == 0u)
        color += direct_light(v_world, n, albedo, m.metallic, m.roughness, probe_lit);

    vec3 emissive = m.emissive.rgb;
    if (m.emissive_texture >= 0) emissive *= texture(emissive_tex, v_uv).rgb;
    color += emissive;
    out_color = vec4(color, 1.0);
}
