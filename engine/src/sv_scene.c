/* Scene state on top of the glTF loader (see sv_scene.h). */
#include "sv_scene.h"

#include <float.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "sv_gpu.h"
#include "sv_math.h"

static void object_bounds(const sv_gltf_mesh *mesh, const float world[16], float mn[3], float mx[3])
{
    for (int k = 0; k < 3; ++k) {
        mn[k] = FLT_MAX;
        mx[k] = -FLT_MAX;
    }
    if (mesh->aabb_min[0] > mesh->aabb_max[0]) return; /* empty mesh */
    for (int c = 0; c < 8; ++c) {
        float p[3] = {(c & 1) ? mesh->aabb_max[0] : mesh->aabb_min[0], (c & 2) ? mesh->aabb_max[1] : mesh->aabb_min[1],
                      (c & 4) ? mesh->aabb_max[2] : mesh->aabb_min[2]};
        float w[3];
        sv_mat4_point(world, p, w);
        for (int k = 0; k < 3; ++k) {
            if (w[k] < mn[k]) mn[k] = w[k];
            if (w[k] > mx[k]) mx[k] = w[k];
        }
    }
}

static void update_scene_bounds(sv_scene *s)
{
    for (int k = 0; k < 3; ++k) {
        s->aabb_min[k] = FLT_MAX;
        s->aabb_max[k] = -FLT_MAX;
    }
    for (uint32_t i = 0; i < s->object_count; ++i)
        for (int k = 0; k < 3; ++k) {
            if (s->objects[i].aabb_min[k] < s->aabb_min[k]) s->aabb_min[k] = s->objects[i].aabb_min[k];
            if (s->objects[i].aabb_max[k] > s->aabb_max[k]) s->aabb_max[k] = s->objects[i].aabb_max[k];
        }
}

bool sv_scene_load(const char *path, bool allow_outside_paths, sv_scene *out)
{
    memset(out, 0, sizeof(*out));
    sv_gltf_desc desc = {.app_extensions = sv_ext_names,
                         .app_extension_count = SV_EXT_NAME_COUNT,
                         .allow_outside_paths = allow_outside_paths};
    sv_gltf_error err = {0};
    if (sv_gltf_load_file(path, &desc, &out->gltf, &err) != SV_GLTF_SUCCESS) {
        fprintf(stderr, "schnee-view: error: cannot load %s: %s (%s)\n", path, err.message,
                sv_gltf_result_string(err.code));
        return false;
    }
    sv_gltf *g = out->gltf;
    for (uint32_t i = 0; i < g->warning_count; ++i)
        fprintf(stderr, "schnee-view: warning: %s: %s\n", path, g->warnings[i]);
    if (sv_ext_parse(g, &out->ext, &err) != SV_GLTF_SUCCESS) {
        fprintf(stderr, "schnee-view: error: cannot load %s: %s (%s)\n", path, err.message,
                sv_gltf_result_string(err.code));
        sv_gltf_free(out->gltf);
        out->gltf = NULL;
        return false;
    }
    for (uint32_t i = 0; i < out->ext.warning_count; ++i)
        fprintf(stderr, "schnee-view: warning: %s: %s\n", path, out->ext.warnings[i]);
    size_t nodes = g->node_count ? g->node_count : 1;
    out->node_local = calloc(nodes * 16, sizeof(float));
    out->node_world = calloc(nodes * 16, sizeof(float));
    out->objects = calloc(g->mesh_instance_count ? g->mesh_instance_count : 1, sizeof(sv_object));
    if (!out->node_local || !out->node_world || !out->objects) {
        fprintf(stderr, "schnee-view: error: out of memory loading %s\n", path);
        sv_scene_destroy(out);
        return false;
    }
    for (uint32_t i = 0; i < g->node_count; ++i) {
        memcpy(out->node_local + 16 * i, g->nodes[i].local, 16 * sizeof(float));
        memcpy(out->node_world + 16 * i, g->nodes[i].world, 16 * sizeof(float));
    }
    out->object_count = g->mesh_instance_count;
    for (uint32_t i = 0; i < g->mesh_instance_count; ++i) {
        const sv_gltf_mesh_instance *mi = &g->mesh_instances[i];
        sv_object *o = &out->objects[i];
        o->node = mi->node;
        o->mesh = mi->mesh;
        o->name = g->nodes[mi->node].name;
        memcpy(o->world, mi->world, sizeof(o->world));
        object_bounds(&g->meshes[mi->mesh], o->world, o->aabb_min, o->aabb_max);
        o->needs_probe = true;
        o->probe_mode = out->ext.nodes[mi->node].probe_mode;
        o->probe_representation = out->ext.nodes[mi->node].probe_representation;
    }
    update_scene_bounds(out);
    return true;
}

void sv_scene_destroy(sv_scene *scene)
{
    sv_ext_free(&scene->ext);
    sv_gltf_free(scene->gltf);
    free(scene->node_local);
    free(scene->node_world);
    free(scene->objects);
    memset(scene, 0, sizeof(*scene));
}

void sv_object_probe_mode(const sv_object *o, const sv_ext_material *m, uint32_t mode_override, uint32_t rep_override,
                          uint32_t *mode, uint32_t *rep)
{
    *mode = mode_override < SV_PROBE_MODE_MATERIAL   ? mode_override
            : o->probe_mode < SV_PROBE_MODE_MATERIAL ? o->probe_mode
            : m                                      ? m->probe_mode
                                                     : SV_PROBE_MODE_OBJECT;
    *rep = rep_override < SV_PROBE_REP_MATERIAL              ? rep_override
           : o->probe_representation < SV_PROBE_REP_MATERIAL ? o->probe_representation
           : m                                               ? m->probe_representation
                                                             : SV_PROBE_REP_SH;
}

bool sv_scene_nodes_want_cubes(const sv_scene *scene)
{
    for (uint32_t i = 0; i < scene->object_count; ++i)
        if (scene->objects[i].probe_representation == SV_PROBE_REP_AMBIENT_CUBE) return true;
    return false;
}

int32_t sv_scene_find_node(const sv_scene *scene, const char *name)
{
    for (uint32_t i = 0; i < scene->gltf->node_count; ++i)
        if (strcmp(scene->gltf->nodes[i].name, name) == 0) return (int32_t)i;
    return -1;
}

/* Recomputes node `n`'s world matrix from its parent's and recurses into the children. The loader
 * validated the hierarchy as a forest, so the recursion terminates. */
static void update_world(sv_scene *s, uint32_t n)
{
    const sv_gltf_node *node = &s->gltf->nodes[n];
    if (node->parent >= 0)
        sv_mat4_mul(s->node_world + 16 * (uint32_t)node->parent, s->node_local + 16 * n, s->node_world + 16 * n);
    else
        memcpy(s->node_world + 16 * n, s->node_local + 16 * n, 16 * sizeof(float));
    for (uint32_t c = 0; c < node->child_count; ++c) update_world(s, node->children[c]);
}

void sv_scene_set_translation(sv_scene *scene, uint32_t node, const float translation[3])
{
    const sv_gltf_node *gn = &scene->gltf->nodes[node];
    float *local = scene->node_local + 16 * node;
    if (gn->has_matrix) {
        local[12] = translation[0];
        local[13] = translation[1];
        local[14] = translation[2];
    } else {
        sv_mat4_from_trs(translation, gn->rotation, gn->scale, local);
    }
    update_world(scene, node);
    for (uint32_t i = 0; i < scene->object_count; ++i) {
        sv_object *o = &scene->objects[i];
        const float *w = scene->node_world + 16 * o->node;
        if (memcmp(w, o->world, sizeof(o->world)) == 0) continue;
        memcpy(o->world, w, sizeof(o->world));
        object_bounds(&scene->gltf->meshes[o->mesh], o->world, o->aabb_min, o->aabb_max);
        o->needs_probe = true;
        o->movable = true; /* left the static set for good (docs/engine.md "Static scene") */
    }
    update_scene_bounds(scene);
}
