/* Loader: meshes and primitives. */
#include "sv_gltf_internal.h"

#include <float.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

/* ---------------------------------------------------------------- meshes */

/* Attribute accessor → freshly allocated float array of vertex_count * out_ncomp. */
static bool decode_attribute(ctx_ *c, const cJSON *attrs, const char *key, const char *ppath, uint32_t want_ncomp,
                             uint32_t alt_ncomp, uint32_t vertex_count, float **out)
{
    int32_t ai;
    char path[128];
    snprintf(path, sizeof path, "%s.attributes", ppath);
    *out = NULL;
    if (!svg_get_index(c, attrs, key, path, false, c->acc_count, "accessors", &ai)) return false;
    if (ai < 0) return true;
    const accessor_ *a = &c->accs[ai];
    snprintf(path, sizeof path, "%s.attributes.%s", ppath, key);
    if (a->is_matrix || (a->ncomp != want_ncomp && a->ncomp != alt_ncomp)) {
        svg_fail(c, SV_GLTF_ERROR_FORMAT, "%s: accessor %d has type %s, expected VEC%u", path, ai, a->type_name,
                 want_ncomp);
        return false;
    }
    if (a->count != vertex_count) {
        svg_fail(c, SV_GLTF_ERROR_FORMAT, "%s: accessor %d has count %u, POSITION has %u", path, ai, a->count,
                 vertex_count);
        return false;
    }
    *out = svg_alloc_data(c, (uint64_t)vertex_count * want_ncomp, sizeof(float), path);
    return *out && svg_decode_accessor(c, (uint32_t)ai, path, want_ncomp, 1.0f, *out, NULL);
}

/* Re-indexes a vertex array so that vertex i is the old vertex idx[i] (un-welding). */
static bool unweld(ctx_ *c, float **arr, uint32_t ncomp, const uint32_t *idx, uint32_t n, const char *what)
{
    if (!*arr) return true;
    float *na = svg_alloc_data(c, (uint64_t)n * ncomp, sizeof(float), what);
    if (!na) return false;
    for (uint32_t i = 0; i < n; i++)
        memcpy(na + (uint64_t)i * ncomp, *arr + (uint64_t)idx[i] * ncomp, ncomp * sizeof(float));
    free(*arr);
    *arr = na;
    return true;
}

static bool make_flat_normals(ctx_ *c, sv_gltf_primitive *p, const char *path)
{
    uint32_t n = p->index_count;
    if (!unweld(c, &p->positions, 3, p->indices, n, path) || !unweld(c, &p->tangents, 4, p->indices, n, path) ||
        !unweld(c, &p->texcoords0, 2, p->indices, n, path) || !unweld(c, &p->texcoords1, 2, p->indices, n, path) ||
        !unweld(c, &p->colors0, 4, p->indices, n, path))
        return false;
    p->vertex_count = n;
    for (uint32_t i = 0; i < n; i++) p->indices[i] = i;
    p->normals = svg_alloc_data(c, (uint64_t)n * 3, sizeof(float), path);
    if (!p->normals) return false;
    for (uint32_t t = 0; t + 2 < n; t += 3) {
        const float *a = p->positions + (uint64_t)t * 3, *b = a + 3, *d = a + 6;
        double e1[3] = {b[0] - a[0], b[1] - a[1], b[2] - a[2]};
        double e2[3] = {d[0] - a[0], d[1] - a[1], d[2] - a[2]};
        double nx = e1[1] * e2[2] - e1[2] * e2[1], ny = e1[2] * e2[0] - e1[0] * e2[2],
               nz = e1[0] * e2[1] - e1[1] * e2[0];
        double len = sqrt(nx * nx + ny * ny + nz * nz);
        float nn[3] = {0.0f, 1.0f, 0.0f}; /* degenerate triangle: any unit vector */
        if (len > 0.0 && isfinite(len)) {
            nn[0] = (float)(nx / len);
            nn[1] = (float)(ny / len);
            nn[2] = (float)(nz / len);
        }
        for (int k = 0; k < 3; k++) memcpy(p->normals + ((uint64_t)t + k) * 3, nn, sizeof nn);
    }
    p->normals_generated = true;
    return true;
}

/* Decodes one primitive. Returns false on error; *skip set when it is left out with a warning. */
static bool parse_primitive(ctx_ *c, const cJSON *j, const char *path, sv_gltf_primitive *p, bool *skip)
{
    static const char *mode_names[] = {"POINTS",    "LINES",          "LINE_LOOP",   "LINE_STRIP",
                                       "TRIANGLES", "TRIANGLE_STRIP", "TRIANGLE_FAN"};
    const cJSON *attrs;
    uint64_t mode;
    int32_t pos_ai, idx_ai;
    *skip = false;
    if (!svg_get_typed(c, j, "attributes", path, cJSON_Object, &attrs) ||
        !svg_get_uint(c, j, "mode", path, false, 4, 0, 6, &mode) ||
        !svg_get_index(c, j, "material", path, false, c->g->material_count, "materials", &p->material) ||
        !svg_get_index(c, j, "indices", path, false, c->acc_count, "accessors", &idx_ai))
        return false;
    if (!attrs) {
        svg_fail(c, SV_GLTF_ERROR_FORMAT, "%s.attributes: missing", path);
        return false;
    }
    char apath[128];
    snprintf(apath, sizeof apath, "%s.attributes", path);
    if (!svg_get_index(c, attrs, "POSITION", apath, false, c->acc_count, "accessors", &pos_ai)) return false;
    if (mode < 4) {
        if (c->desc.non_triangles_are_errors) {
            svg_fail(c, SV_GLTF_ERROR_UNSUPPORTED, "%s: mode %s is not supported (triangles only)", path,
                     mode_names[mode]);
            return false;
        }
        svg_warn(c, "%s: mode %s skipped (triangles only)", path, mode_names[mode]);
        *skip = true;
        return true;
    }
    if (pos_ai < 0) {
        svg_warn(c, "%s: no POSITION attribute, skipped", path);
        *skip = true;
        return true;
    }
    uint32_t vc = c->accs[pos_ai].count;
    p->vertex_count = vc;
    if (!decode_attribute(c, attrs, "POSITION", path, 3, 3, vc, &p->positions) ||
        !decode_attribute(c, attrs, "NORMAL", path, 3, 3, vc, &p->normals) ||
        !decode_attribute(c, attrs, "TANGENT", path, 4, 4, vc, &p->tangents) ||
        !decode_attribute(c, attrs, "TEXCOORD_0", path, 2, 2, vc, &p->texcoords0) ||
        !decode_attribute(c, attrs, "TEXCOORD_1", path, 2, 2, vc, &p->texcoords1) ||
        !decode_attribute(c, attrs, "COLOR_0", path, 4, 3, vc, &p->colors0))
        return false;

    /* Source indices (or 0..n-1), then strips/fans to lists. */
    uint32_t *src;
    uint32_t n;
    char ipath[128];
    snprintf(ipath, sizeof ipath, "%s.indices", path);
    if (idx_ai >= 0) {
        const accessor_ *a = &c->accs[idx_ai];
        if (a->ncomp != 1 || a->is_matrix || a->normalized ||
            (a->ct != CT_UBYTE && a->ct != CT_USHORT && a->ct != CT_UINT)) {
            svg_fail(c, SV_GLTF_ERROR_FORMAT,
                     "%s: accessor %d must be a SCALAR of unsigned byte/short/int, not normalized", ipath, idx_ai);
            return false;
        }
        n = a->count;
        src = svg_alloc_data(c, n, sizeof(uint32_t), ipath);
        if (!src || !svg_decode_accessor(c, (uint32_t)idx_ai, ipath, 1, 0.0f, NULL, src)) {
            free(src);
            return false;
        }
        for (uint32_t i = 0; i < n; i++)
            if (src[i] >= vc) {
                svg_fail(c, SV_GLTF_ERROR_FORMAT, "%s: index %u at position %u is out of range (%u vertices)", ipath,
                         src[i], i, vc);
                free(src);
                return false;
            }
    } else {
        n = vc;
        src = svg_alloc_data(c, n, sizeof(uint32_t), ipath);
        if (!src) return false;
        for (uint32_t i = 0; i < n; i++) src[i] = i;
    }
    if (mode == 4) {
        if (n % 3) {
            free(src);
            svg_fail(c, SV_GLTF_ERROR_FORMAT, "%s: %u indices is not a multiple of 3 for TRIANGLES", path, n);
            return false;
        }
        p->indices = src;
        p->index_count = n;
    } else {
        uint64_t tris = n >= 3 ? n - 2 : 0;
        p->indices = svg_alloc_data(c, tris * 3, sizeof(uint32_t), ipath);
        if (!p->indices) {
            free(src);
            return false;
        }
        for (uint64_t t = 0; t < tris; t++) {
            uint32_t *o = p->indices + t * 3;
            if (mode == 5) { /* glTF 2.0 §3.7.2.1: {v_i, v_{i+(1+i%2)}, v_{i+(2-i%2)}} */
                o[0] = src[t];
                o[1] = src[t + 1 + t % 2];
                o[2] = src[t + 2 - t % 2];
            } else { /* fan: {v_{i+1}, v_{i+2}, v_0} */
                o[0] = src[t + 1];
                o[1] = src[t + 2];
                o[2] = src[0];
            }
        }
        p->index_count = (uint32_t)(tris * 3);
        free(src);
    }
    if (!p->normals && !c->desc.keep_shared_normals && !make_flat_normals(c, p, path)) return false;

    for (int k = 0; k < 3; k++) {
        p->aabb_min[k] = FLT_MAX;
        p->aabb_max[k] = -FLT_MAX;
    }
    for (uint64_t v = 0; v < p->vertex_count; v++)
        for (int k = 0; k < 3; k++) {
            float x = p->positions[v * 3 + k];
            if (x < p->aabb_min[k]) p->aabb_min[k] = x;
            if (x > p->aabb_max[k]) p->aabb_max[k] = x;
        }
    return true;
}

void svg_free_primitive(sv_gltf_primitive *p)
{
    free(p->positions);
    free(p->normals);
    free(p->tangents);
    free(p->texcoords0);
    free(p->texcoords1);
    free(p->colors0);
    free(p->indices);
    memset(p, 0, sizeof *p);
}

bool svg_parse_meshes(ctx_ *c, const cJSON *root)
{
    const cJSON *arr, *j;
    uint32_t count;
    if (!svg_top_array(c, root, "meshes", &arr, &count)) return false;
    c->g->meshes = svg_xcalloc(c, count, sizeof *c->g->meshes);
    if (!c->g->meshes) return false;
    c->g->mesh_count = count;
    uint32_t i = 0;
    cJSON_ArrayForEach(j, arr)
    {
        char path[48];
        snprintf(path, sizeof path, "meshes[%u]", i);
        sv_gltf_mesh *m = &c->g->meshes[i];
        for (int k = 0; k < 3; k++) {
            m->aabb_min[k] = FLT_MAX;
            m->aabb_max[k] = -FLT_MAX;
        }
        const cJSON *prims, *pj;
        if (!svg_get_string(c, j, "name", path, &m->name) ||
            !svg_get_typed(c, j, "primitives", path, cJSON_Array, &prims))
            return false;
        int np = prims ? cJSON_GetArraySize(prims) : 0;
        if (np <= 0) {
            svg_fail(c, SV_GLTF_ERROR_FORMAT, "%s.primitives: missing or empty", path);
            return false;
        }
        m->primitives = svg_xcalloc(c, (uint64_t)np, sizeof *m->primitives);
        if (!m->primitives) return false;
        uint32_t pi = 0;
        cJSON_ArrayForEach(pj, prims)
        {
            char ppath[80];
            snprintf(ppath, sizeof ppath, "%s.primitives[%u]", path, pi++);
            if (!cJSON_IsObject(pj)) {
                svg_fail(c, SV_GLTF_ERROR_FORMAT, "%s: expected an object, got %s", ppath, svg_type_of(pj));
                return false;
            }
            sv_gltf_primitive *p = &m->primitives[m->primitive_count];
            bool skip;
            /* Count it before decoding so sv_gltf_free releases a half-decoded primitive. */
            m->primitive_count++;
            if (!parse_primitive(c, pj, ppath, p, &skip)) return false;
            if (skip) {
                svg_free_primitive(p);
                m->primitive_count--;
                continue;
            }
            for (int k = 0; k < 3; k++) {
                m->aabb_min[k] = fminf(m->aabb_min[k], p->aabb_min[k]);
                m->aabb_max[k] = fmaxf(m->aabb_max[k], p->aabb_max[k]);
            }
        }
        i++;
    }
    return true;
}
