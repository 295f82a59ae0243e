/* Loader: cameras, lights, nodes, the default scene. */
#include "sv_gltf_internal.h"
#include "sv_math.h"

#include <float.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

/* ---------------------------------------------------------------- cameras, lights */

bool svg_parse_cameras(ctx_ *c, const cJSON *root)
{
    const cJSON *arr, *j;
    uint32_t count;
    if (!svg_top_array(c, root, "cameras", &arr, &count)) return false;
    c->g->cameras = svg_xcalloc(c, count, sizeof *c->g->cameras);
    if (!c->g->cameras) return false;
    c->g->camera_count = count;
    uint32_t i = 0;
    cJSON_ArrayForEach(j, arr)
    {
        char path[48], sub[80];
        snprintf(path, sizeof path, "cameras[%u]", i);
        sv_gltf_camera *cam = &c->g->cameras[i];
        const cJSON *type, *persp, *ortho;
        if (!svg_get_string(c, j, "name", path, &cam->name) ||
            !svg_get_typed(c, j, "type", path, cJSON_String, &type) ||
            !svg_get_typed(c, j, "perspective", path, cJSON_Object, &persp) ||
            !svg_get_typed(c, j, "orthographic", path, cJSON_Object, &ortho))
            return false;
        bool is_persp = type && strcmp(type->valuestring, "perspective") == 0;
        bool is_ortho = type && strcmp(type->valuestring, "orthographic") == 0;
        if (!is_persp && !is_ortho) {
            if (!type)
                svg_fail(c, SV_GLTF_ERROR_FORMAT, "%s.type: missing", path);
            else
                svg_fail(c, SV_GLTF_ERROR_FORMAT, "%s.type: '%.40s' is not perspective or orthographic", path,
                         type->valuestring);
            return false;
        }
        if ((is_persp && !persp) || (is_ortho && !ortho)) {
            svg_fail(c, SV_GLTF_ERROR_FORMAT, "%s: type %s but no '%s' object", path, type->valuestring,
                     type->valuestring);
            return false;
        }
        snprintf(sub, sizeof sub, "%s.%s", path, type->valuestring);
        if (is_persp) {
            cam->type = SV_GLTF_CAMERA_PERSPECTIVE;
            if (!svg_get_float(c, persp, "yfov", sub, true, 0, 1e-6, 3.14159265, &cam->yfov) ||
                !svg_get_float(c, persp, "znear", sub, true, 0, 1e-30, FLT_MAX, &cam->znear) ||
                !svg_get_float(c, persp, "zfar", sub, false, 0, 0, FLT_MAX, &cam->zfar) ||
                !svg_get_float(c, persp, "aspectRatio", sub, false, 0, 1e-6, FLT_MAX, &cam->aspect_ratio))
                return false;
        } else {
            cam->type = SV_GLTF_CAMERA_ORTHOGRAPHIC;
            if (!svg_get_float(c, ortho, "xmag", sub, true, 0, -FLT_MAX, FLT_MAX, &cam->xmag) ||
                !svg_get_float(c, ortho, "ymag", sub, true, 0, -FLT_MAX, FLT_MAX, &cam->ymag) ||
                !svg_get_float(c, ortho, "znear", sub, true, 0, 0, FLT_MAX, &cam->znear) ||
                !svg_get_float(c, ortho, "zfar", sub, true, 0, 0, FLT_MAX, &cam->zfar))
                return false;
            if (cam->xmag == 0.0f || cam->ymag == 0.0f) {
                svg_fail(c, SV_GLTF_ERROR_FORMAT, "%s: xmag and ymag must not be zero", sub);
                return false;
            }
        }
        if (cam->zfar != 0.0f && !(cam->zfar > cam->znear)) {
            svg_fail(c, SV_GLTF_ERROR_FORMAT, "%s: zfar %g is not greater than znear %g", sub, cam->zfar, cam->znear);
            return false;
        }
        i++;
    }
    return true;
}

bool svg_parse_lights(ctx_ *c, const cJSON *root)
{
    const cJSON *ext, *khr = NULL, *arr = NULL, *j;
    if (!svg_get_typed(c, root, "extensions", "(root)", cJSON_Object, &ext)) return false;
    if (ext && !svg_get_typed(c, ext, "KHR_lights_punctual", "extensions", cJSON_Object, &khr)) return false;
    if (khr && !svg_get_typed(c, khr, "lights", "extensions.KHR_lights_punctual", cJSON_Array, &arr)) return false;
    if (!arr) return true;
    int count = cJSON_GetArraySize(arr);
    c->g->lights = svg_xcalloc(c, (uint64_t)count, sizeof *c->g->lights);
    if (!c->g->lights) return false;
    c->g->light_count = (uint32_t)count;
    uint32_t i = 0;
    cJSON_ArrayForEach(j, arr)
    {
        char path[80], sub[160];
        snprintf(path, sizeof path, "KHR_lights_punctual.lights[%u]", i);
        if (!cJSON_IsObject(j)) {
            svg_fail(c, SV_GLTF_ERROR_FORMAT, "%s: expected an object, got %s", path, svg_type_of(j));
            return false;
        }
        sv_gltf_light *l = &c->g->lights[i];
        const cJSON *type, *spot;
        l->color[0] = l->color[1] = l->color[2] = 1.0f;
        if (!svg_get_string(c, j, "name", path, &l->name) || !svg_get_typed(c, j, "type", path, cJSON_String, &type) ||
            !svg_get_floats(c, j, "color", path, 3, l->color, NULL) ||
            !svg_get_float(c, j, "intensity", path, false, 1.0f, 0.0, FLT_MAX, &l->intensity) ||
            !svg_get_float(c, j, "range", path, false, 0.0f, 1e-30, FLT_MAX, &l->range) ||
            !svg_get_typed(c, j, "spot", path, cJSON_Object, &spot))
            return false;
        if (!svg_get_extensions(c, j, path, NULL, &l->extensions, &l->extension_count)) return false;
        const char *t = type ? type->valuestring : "";
        if (strcmp(t, "directional") == 0)
            l->type = SV_GLTF_LIGHT_DIRECTIONAL;
        else if (strcmp(t, "point") == 0)
            l->type = SV_GLTF_LIGHT_POINT;
        else if (strcmp(t, "spot") == 0)
            l->type = SV_GLTF_LIGHT_SPOT;
        else {
            svg_fail(c, SV_GLTF_ERROR_FORMAT, "%s.type: '%.40s' is not directional, point or spot", path, t);
            return false;
        }
        l->inner_cone_angle = 0.0f;
        l->outer_cone_angle = (float)(SVG_PI / 4.0);
        if (l->type == SV_GLTF_LIGHT_SPOT) {
            if (!spot) {
                svg_fail(c, SV_GLTF_ERROR_FORMAT, "%s: type spot but no 'spot' object", path);
                return false;
            }
            snprintf(sub, sizeof sub, "%s.spot", path);
            if (!svg_get_float(c, spot, "innerConeAngle", sub, false, 0.0f, 0.0, SVG_PI / 2, &l->inner_cone_angle) ||
                !svg_get_float(c, spot, "outerConeAngle", sub, false, (float)(SVG_PI / 4.0), 0.0, SVG_PI / 2 + 1e-6,
                               &l->outer_cone_angle))
                return false;
            if (!(l->inner_cone_angle < l->outer_cone_angle)) {
                svg_fail(c, SV_GLTF_ERROR_FORMAT, "%s: innerConeAngle %g is not less than outerConeAngle %g", sub,
                         l->inner_cone_angle, l->outer_cone_angle);
                return false;
            }
        }
        i++;
    }
    return true;
}

/* ---------------------------------------------------------------- nodes and scene */

bool svg_parse_nodes(ctx_ *c, const cJSON *root)
{
    const cJSON *arr, *j;
    uint32_t count;
    sv_gltf *g = c->g;
    if (!svg_top_array(c, root, "nodes", &arr, &count)) return false;
    g->nodes = svg_xcalloc(c, count, sizeof *g->nodes);
    if (!g->nodes) return false;
    g->node_count = count;
    for (uint32_t i = 0; i < count; i++) g->nodes[i].parent = -1;
    uint32_t i = 0;
    cJSON_ArrayForEach(j, arr)
    {
        char path[48];
        snprintf(path, sizeof path, "nodes[%u]", i);
        sv_gltf_node *n = &g->nodes[i];
        const cJSON *children, *ext, *khr = NULL;
        bool has_t, has_r, has_s;
        const float zero3[3] = {0, 0, 0}, one3[3] = {1, 1, 1}, quat_id[4] = {0, 0, 0, 1};
        memcpy(n->translation, zero3, sizeof zero3);
        memcpy(n->scale, one3, sizeof one3);
        memcpy(n->rotation, quat_id, sizeof quat_id);
        if (!svg_get_string(c, j, "name", path, &n->name) ||
            !svg_get_index(c, j, "mesh", path, false, g->mesh_count, "meshes", &n->mesh) ||
            !svg_get_index(c, j, "camera", path, false, g->camera_count, "cameras", &n->camera) ||
            !svg_get_typed(c, j, "children", path, cJSON_Array, &children) ||
            !svg_get_floats(c, j, "matrix", path, 16, n->local, &n->has_matrix) ||
            !svg_get_floats(c, j, "translation", path, 3, n->translation, &has_t) ||
            !svg_get_floats(c, j, "rotation", path, 4, n->rotation, &has_r) ||
            !svg_get_floats(c, j, "scale", path, 3, n->scale, &has_s) ||
            !svg_get_typed(c, j, "extensions", path, cJSON_Object, &ext))
            return false;
        n->light = -1;
        if (ext) {
            char p[80];
            snprintf(p, sizeof p, "%s.extensions", path);
            if (!svg_get_typed(c, ext, "KHR_lights_punctual", p, cJSON_Object, &khr)) return false;
            snprintf(p, sizeof p, "%s.extensions.KHR_lights_punctual", path);
            if (khr && !svg_get_index(c, khr, "light", p, true, g->light_count, "lights", &n->light)) return false;
        }
        static const char *const consumed[] = {"KHR_lights_punctual", NULL};
        if (!svg_get_extensions(c, j, path, consumed, &n->extensions, &n->extension_count)) return false;
        if (n->has_matrix && (has_t || has_r || has_s)) {
            svg_fail(c, SV_GLTF_ERROR_FORMAT, "%s: has both matrix and translation/rotation/scale", path);
            return false;
        }
        if (!n->has_matrix) {
            double q2 = 0.0;
            for (int k = 0; k < 4; k++) q2 += (double)n->rotation[k] * n->rotation[k];
            if (!(q2 > 1e-12)) {
                svg_fail(c, SV_GLTF_ERROR_FORMAT, "%s.rotation: zero quaternion", path);
                return false;
            }
            for (int k = 0; k < 4; k++) n->rotation[k] = (float)(n->rotation[k] / sqrt(q2));
            sv_mat4_from_trs(n->translation, n->rotation, n->scale, n->local);
        }
        if (children) {
            int nc = cJSON_GetArraySize(children);
            n->children = svg_xcalloc(c, (uint64_t)nc, sizeof *n->children);
            if (!n->children) return false;
            const cJSON *e;
            cJSON_ArrayForEach(e, children)
            {
                double v = cJSON_IsNumber(e) ? e->valuedouble : -1.0;
                if (!(v >= 0.0 && v < (double)count && v == floor(v))) {
                    svg_fail(c, SV_GLTF_ERROR_FORMAT, "%s.children[%u]: not a node index (%u nodes)", path,
                             n->child_count, count);
                    return false;
                }
                uint32_t ch = (uint32_t)v;
                if (ch == i) {
                    svg_fail(c, SV_GLTF_ERROR_FORMAT, "%s.children: node %u is its own child (cycle)", path, ch);
                    return false;
                }
                if (g->nodes[ch].parent >= 0) {
                    svg_fail(c, SV_GLTF_ERROR_FORMAT, "%s.children: node %u already has parent %d (or is listed twice)",
                             path, ch, g->nodes[ch].parent);
                    return false;
                }
                g->nodes[ch].parent = (int32_t)i;
                n->children[n->child_count++] = ch;
            }
        }
        i++;
    }

    /* World matrices top-down from the roots. With one parent per node, a node not reached from a
     * root sits on (or under) a cycle. */
    uint32_t *stack = svg_xcalloc(c, count, sizeof *stack);
    bool *seen = svg_xcalloc(c, count, sizeof *seen);
    if (!stack || !seen) {
        free(stack);
        free(seen);
        return false;
    }
    uint32_t top = 0;
    for (uint32_t k = 0; k < count; k++)
        if (g->nodes[k].parent < 0) {
            memcpy(g->nodes[k].world, g->nodes[k].local, sizeof g->nodes[k].world);
            seen[k] = true;
            stack[top++] = k;
        }
    while (top) {
        const sv_gltf_node *n = &g->nodes[stack[--top]];
        for (uint32_t k = 0; k < n->child_count; k++) {
            sv_gltf_node *ch = &g->nodes[n->children[k]];
            sv_mat4_mul(n->world, ch->local, ch->world);
            seen[n->children[k]] = true;
            stack[top++] = n->children[k];
        }
    }
    bool ok = true;
    for (uint32_t k = 0; k < count && ok; k++)
        if (!seen[k]) {
            svg_fail(c, SV_GLTF_ERROR_FORMAT, "nodes[%u]: part of a cycle in the node hierarchy", k);
            ok = false;
        }
    free(stack);
    free(seen);
    return ok;
}

/* Appends the mesh, camera and light instances of the subtree at root_node (depth-first pre-order,
 * children in file order) with their world matrices, grows the scene bounds by each mesh instance's
 * box and marks every node visited in_scene. False only when out of memory. */
static bool add_instances(ctx_ *c, uint32_t root_node)
{
    sv_gltf *g = c->g;
    uint32_t *stack = svg_xcalloc(c, g->node_count, sizeof *stack);
    if (!stack) return false;
    uint32_t top = 0;
    stack[top++] = root_node;
    while (top) {
        uint32_t ni = stack[--top];
        sv_gltf_node *n = &g->nodes[ni];
        n->in_scene = true;
        if (n->mesh >= 0) {
            sv_gltf_mesh_instance *mi = &g->mesh_instances[g->mesh_instance_count++];
            const sv_gltf_mesh *m = &g->meshes[n->mesh];
            mi->node = ni;
            mi->mesh = (uint32_t)n->mesh;
            memcpy(mi->world, n->world, sizeof mi->world);
            if (m->aabb_min[0] <= m->aabb_max[0]) {
                svg_aabb_transform(n->world, m->aabb_min, m->aabb_max, mi->aabb_min, mi->aabb_max);
                for (int k = 0; k < 3; k++) {
                    g->scene_aabb_min[k] = fminf(g->scene_aabb_min[k], mi->aabb_min[k]);
                    g->scene_aabb_max[k] = fmaxf(g->scene_aabb_max[k], mi->aabb_max[k]);
                }
            } else {
                memcpy(mi->aabb_min, m->aabb_min, sizeof mi->aabb_min);
                memcpy(mi->aabb_max, m->aabb_max, sizeof mi->aabb_max);
            }
        }
        if (n->camera >= 0) {
            sv_gltf_camera_instance *ci = &g->camera_instances[g->camera_instance_count++];
            ci->node = ni;
            ci->camera = (uint32_t)n->camera;
            memcpy(ci->world, n->world, sizeof ci->world);
        }
        if (n->light >= 0) {
            sv_gltf_light_instance *li = &g->light_instances[g->light_instance_count++];
            li->node = ni;
            li->light = (uint32_t)n->light;
            memcpy(li->world, n->world, sizeof li->world);
            memcpy(li->position, n->world + 12, sizeof li->position);
            double d[3] = {-n->world[8], -n->world[9], -n->world[10]};
            double len = sqrt(d[0] * d[0] + d[1] * d[1] + d[2] * d[2]);
            for (int k = 0; k < 3; k++) li->direction[k] = len > 0.0 ? (float)(d[k] / len) : (k == 2 ? -1.0f : 0.0f);
        }
        /* Push children reversed so they pop in file order (depth-first pre-order). */
        for (uint32_t k = n->child_count; k-- > 0;) stack[top++] = n->children[k];
    }
    free(stack);
    return true;
}

bool svg_parse_scene(ctx_ *c, const cJSON *root)
{
    sv_gltf *g = c->g;
    const cJSON *arr, *j, *scene = NULL;
    uint32_t count;
    int32_t si;
    for (int k = 0; k < 3; k++) {
        g->scene_aabb_min[k] = FLT_MAX;
        g->scene_aabb_max[k] = -FLT_MAX;
    }
    g->scene = -1;
    if (!svg_top_array(c, root, "scenes", &arr, &count) ||
        !svg_get_index(c, root, "scene", "(root)", false, count, "scenes", &si))
        return false;
    if (count == 0) return true;
    g->scene = si >= 0 ? si : 0;
    uint32_t k = 0;
    cJSON_ArrayForEach(j, arr) if (k++ == (uint32_t)g->scene) scene = j;
    char spath[32];
    snprintf(spath, sizeof spath, "scenes[%d]", g->scene);
    const cJSON *nodes;
    if (!svg_get_string(c, scene, "name", spath, &g->scene_name) ||
        !svg_get_typed(c, scene, "nodes", spath, cJSON_Array, &nodes))
        return false;
    /* Every node appears at most once, so node_count bounds each instance list. */
    g->mesh_instances = svg_xcalloc(c, g->node_count, sizeof *g->mesh_instances);
    g->camera_instances = svg_xcalloc(c, g->node_count, sizeof *g->camera_instances);
    g->light_instances = svg_xcalloc(c, g->node_count, sizeof *g->light_instances);
    bool *listed = svg_xcalloc(c, g->node_count, sizeof *listed);
    if (!g->mesh_instances || !g->camera_instances || !g->light_instances || !listed) {
        free(listed);
        return false;
    }
    const cJSON *e;
    uint32_t r = 0;
    bool ok = true;
    if (nodes) cJSON_ArrayForEach(e, nodes)
        {
            double v = cJSON_IsNumber(e) ? e->valuedouble : -1.0;
            if (!(v >= 0.0 && v < (double)g->node_count && v == floor(v))) {
                svg_fail(c, SV_GLTF_ERROR_FORMAT, "%s.nodes[%u]: not a node index (%u nodes)", spath, r, g->node_count);
                ok = false;
                break;
            }
            uint32_t ni = (uint32_t)v;
            if (g->nodes[ni].parent >= 0 || listed[ni]) {
                svg_fail(c, SV_GLTF_ERROR_FORMAT, "%s.nodes[%u]: node %u %s", spath, r, ni,
                         listed[ni] ? "is listed twice" : "is not a root node (it has a parent)");
                ok = false;
                break;
            }
            listed[ni] = true;
            if (!add_instances(c, ni)) {
                ok = false;
                break;
            }
            r++;
        }
    free(listed);
    return ok && svg_get_extensions(c, scene, spath, NULL, &g->scene_extensions, &g->scene_extension_count);
}
