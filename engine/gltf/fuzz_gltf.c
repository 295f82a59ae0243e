/* libFuzzer entry over the from-memory glTF loader (JSON and GLB; detected by the GLB magic).
 * Built and run by tests/fuzz/run_gltf_fuzz.sh. No base directory: external URIs are refused, so
 * the fuzzer never touches the file system. Decoded data is capped at 64 MiB so that a small input
 * claiming a huge accessor count hits the loader's budget error, not the fuzzer's RSS limit. A file
 * that loads also goes through the engine's VULKAN_SCHNEE_* parser (engine/ext/sv_ext.c). */
#include "sv_ext.h"
#include "sv_gltf.h"

#include <stddef.h>
#include <stdint.h>

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size);

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size)
{
    sv_gltf_desc desc = {
        .max_decoded_bytes = 64u << 20, .app_extensions = sv_ext_names, .app_extension_count = SV_EXT_NAME_COUNT};
    sv_gltf *g = NULL;
    sv_gltf_error err = {0};
    if (sv_gltf_load_memory(data, size, &desc, &g, &err) != SV_GLTF_SUCCESS) return 0;
    /* Touch every decoded array and reference so ASan sees any inconsistency between the counts
     * the loader reports and what it allocated. */
    volatile float sink = 0.0f;
    volatile uint32_t isink = 0;
    for (uint32_t m = 0; m < g->mesh_count; m++)
        for (uint32_t p = 0; p < g->meshes[m].primitive_count; p++) {
            const sv_gltf_primitive *pr = &g->meshes[m].primitives[p];
            for (uint32_t i = 0; i < pr->index_count; i++) {
                uint32_t v = pr->indices[i];
                if (v >= pr->vertex_count) __builtin_trap();
                sink += pr->positions[v * 3u] + (pr->normals ? pr->normals[v * 3u] : 0.0f) +
                        (pr->texcoords0 ? pr->texcoords0[v * 2u] : 0.0f) +
                        (pr->tangents ? pr->tangents[v * 4u + 3u] : 0.0f) +
                        (pr->colors0 ? pr->colors0[v * 4u + 3u] : 0.0f) +
                        (pr->texcoords1 ? pr->texcoords1[v * 2u + 1u] : 0.0f);
            }
            if (pr->material >= (int32_t)g->material_count) __builtin_trap();
        }
    for (uint32_t i = 0; i < g->mesh_instance_count; i++) isink += g->meshes[g->mesh_instances[i].mesh].primitive_count;
    for (uint32_t i = 0; i < g->image_count; i++)
        if (g->images[i].data && g->images[i].size) isink += g->images[i].data[g->images[i].size - 1];
    for (uint32_t i = 0; i < g->node_count; i++) isink += g->nodes[i].child_count + (uint32_t)g->nodes[i].name[0];
    for (uint32_t i = 0; i < g->warning_count; i++) isink += (uint32_t)g->warnings[i][0];
    (void)sv_gltf_find_camera(g, "Camera");
    sv_ext ext;
    if (sv_ext_parse(g, &ext, &err) == SV_GLTF_SUCCESS) {
        if (ext.material_count != g->material_count || ext.light_count != g->light_count) __builtin_trap();
        for (uint32_t i = 0; i < ext.probe_grid_count; i++) isink += (uint32_t)ext.probe_grids[i].uri[0];
        isink += ext.sky.present ? (uint32_t)ext.sky.uri[0] : 0u;
        sv_ext_free(&ext);
    }
    (void)sink;
    (void)isink;
    sv_gltf_free(g);
    return 0;
}
