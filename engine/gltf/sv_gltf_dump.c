/* sv-gltf-dump: loads a .gltf/.glb with the engine's loader and prints a JSON summary of what the
 * renderer would get (counts, bounds, instances, materials, cameras, lights, probe grids, warnings),
 * with the VULKAN_SCHNEE_* extensions parsed by the engine's own module (engine/ext).
 * Exit status 0 on success, 1 with "error: <message>" on stderr when the loader refuses the file.
 * Used by tests (e.g. the Blender-exported .glb test) and for inspecting files by hand. */
#include "sv_ext.h"
#include "sv_gltf.h"

#include <stdio.h>
#include <string.h>

static void print_str(const char *s)
{
    putchar('"');
    for (; *s; s++) {
        unsigned char ch = (unsigned char)*s;
        if (ch == '"' || ch == '\\')
            printf("\\%c", ch);
        else if (ch < 0x20)
            printf("\\u%04x", ch);
        else
            putchar(ch);
    }
    putchar('"');
}

static void print_vec(const float *v, int n)
{
    putchar('[');
    for (int i = 0; i < n; i++) printf("%s%.9g", i ? ", " : "", v[i]);
    putchar(']');
}

int main(int argc, char **argv)
{
    if (argc != 2 || argv[1][0] == '-') {
        fprintf(stderr, "usage: sv-gltf-dump FILE.gltf|FILE.glb\n");
        return 2;
    }
    sv_gltf_desc desc = {.app_extensions = sv_ext_names, .app_extension_count = SV_EXT_NAME_COUNT};
    sv_gltf *g = NULL;
    sv_gltf_error err = {0};
    sv_ext ext;
    if (sv_gltf_load_file(argv[1], &desc, &g, &err) != SV_GLTF_SUCCESS) {
        fprintf(stderr, "error: %s: %s (%s)\n", argv[1], err.message, sv_gltf_result_string(err.code));
        return 1;
    }
    if (sv_ext_parse(g, &ext, &err) != SV_GLTF_SUCCESS) {
        fprintf(stderr, "error: %s: %s (%s)\n", argv[1], err.message, sv_gltf_result_string(err.code));
        sv_gltf_free(g);
        return 1;
    }
    printf("{\n  \"scene\": %d,\n  \"counts\": {\"meshes\": %u, \"materials\": %u, \"textures\": %u, \"images\": %u, "
           "\"samplers\": %u, \"nodes\": %u, \"cameras\": %u, \"lights\": %u},\n",
           g->scene, g->mesh_count, g->material_count, g->texture_count, g->image_count, g->sampler_count,
           g->node_count, g->camera_count, g->light_count);
    printf("  \"meshes\": [");
    for (uint32_t m = 0; m < g->mesh_count; m++) {
        const sv_gltf_mesh *mesh = &g->meshes[m];
        printf("%s\n    {\"name\": ", m ? "," : "");
        print_str(mesh->name);
        printf(", \"aabb_min\": ");
        print_vec(mesh->aabb_min, 3);
        printf(", \"aabb_max\": ");
        print_vec(mesh->aabb_max, 3);
        printf(", \"primitives\": [");
        for (uint32_t p = 0; p < mesh->primitive_count; p++) {
            const sv_gltf_primitive *pr = &mesh->primitives[p];
            printf("%s{\"vertices\": %u, \"indices\": %u, \"material\": %d, \"normals\": %s, "
                   "\"normals_generated\": %s, \"texcoords0\": %s, \"tangents\": %s, \"colors0\": %s}",
                   p ? ", " : "", pr->vertex_count, pr->index_count, pr->material, pr->normals ? "true" : "false",
                   pr->normals_generated ? "true" : "false", pr->texcoords0 ? "true" : "false",
                   pr->tangents ? "true" : "false", pr->colors0 ? "true" : "false");
        }
        printf("]}");
    }
    printf("\n  ],\n  \"mesh_instances\": [");
    for (uint32_t i = 0; i < g->mesh_instance_count; i++) {
        const sv_gltf_mesh_instance *mi = &g->mesh_instances[i];
        printf("%s\n    {\"node\": %u, \"node_name\": ", i ? "," : "", mi->node);
        print_str(g->nodes[mi->node].name);
        printf(", \"mesh\": %u, \"world\": ", mi->mesh);
        print_vec(mi->world, 16);
        printf(", \"aabb_min\": ");
        print_vec(mi->aabb_min, 3);
        printf(", \"aabb_max\": ");
        print_vec(mi->aabb_max, 3);
        printf("}");
    }
    printf("\n  ],\n  \"scene_aabb_min\": ");
    print_vec(g->scene_aabb_min, 3);
    printf(",\n  \"scene_aabb_max\": ");
    print_vec(g->scene_aabb_max, 3);
    printf(",\n  \"materials\": [");
    for (uint32_t i = 0; i < g->material_count; i++) {
        const sv_gltf_material *m = &g->materials[i];
        printf("%s\n    {\"name\": ", i ? "," : "");
        print_str(m->name);
        printf(", \"base_color_factor\": ");
        print_vec(m->base_color_factor, 4);
        printf(", \"base_color_texture\": %d, \"metallic\": %.9g, \"roughness\": %.9g, \"emissive\": ",
               m->base_color_texture.texture, m->metallic_factor, m->roughness_factor);
        print_vec(m->emissive_factor, 3);
        printf(", \"alpha_mode\": %d, \"double_sided\": %s, \"has_schnee\": %s, \"sh_scale\": %.9g, "
               "\"ambient_term\": %.9g}",
               (int)m->alpha_mode, m->double_sided ? "true" : "false", ext.materials[i].present ? "true" : "false",
               ext.materials[i].sh_scale, ext.materials[i].ambient_term);
    }
    printf("\n  ],\n  \"cameras\": [");
    for (uint32_t i = 0; i < g->camera_instance_count; i++) {
        const sv_gltf_camera_instance *ci = &g->camera_instances[i];
        const sv_gltf_camera *c = &g->cameras[ci->camera];
        printf("%s\n    {\"node_name\": ", i ? "," : "");
        print_str(g->nodes[ci->node].name);
        printf(", \"type\": %d, \"yfov\": %.9g, \"znear\": %.9g, \"zfar\": %.9g, \"world\": ", (int)c->type, c->yfov,
               c->znear, c->zfar);
        print_vec(ci->world, 16);
        printf("}");
    }
    printf("\n  ],\n  \"lights\": [");
    for (uint32_t i = 0; i < g->light_instance_count; i++) {
        const sv_gltf_light_instance *li = &g->light_instances[i];
        const sv_gltf_light *l = &g->lights[li->light];
        printf("%s\n    {\"name\": ", i ? "," : "");
        print_str(l->name);
        printf(", \"type\": %d, \"intensity\": %.9g, \"color\": ", (int)l->type, l->intensity);
        print_vec(l->color, 3);
        printf(", \"position\": ");
        print_vec(li->position, 3);
        printf(", \"direction\": ");
        print_vec(li->direction, 3);
        printf("}");
    }
    printf("\n  ],\n  \"probe_grids\": [");
    for (uint32_t i = 0; i < ext.probe_grid_count; i++) {
        const sv_ext_probe_grid *pg = &ext.probe_grids[i];
        printf("%s\n    {\"name\": ", i ? "," : "");
        print_str(pg->name);
        printf(", \"path\": ");
        print_str(pg->path ? pg->path : "");
        printf(", \"probe_count\": %u, \"max_band\": %u, \"grid_dims\": [%u, %u, %u]}", pg->probe_count, pg->max_band,
               pg->grid_dims[0], pg->grid_dims[1], pg->grid_dims[2]);
    }
    printf("\n  ],\n  \"warnings\": [");
    for (uint32_t i = 0; i < g->warning_count + ext.warning_count; i++) {
        printf("%s\n    ", i ? "," : "");
        print_str(i < g->warning_count ? g->warnings[i] : ext.warnings[i - g->warning_count]);
    }
    printf("\n  ]\n}\n");
    sv_ext_free(&ext);
    sv_gltf_free(g);
    return 0;
}
