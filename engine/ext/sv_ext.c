/* VULKAN_SCHNEE_* extensions from the loader's raw extension JSON (see sv_ext.h). */
#include "sv_ext.h"

#include <cJSON.h>
#include <float.h>
#include <math.h>
#include <stdarg.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "sv_gpu.h"

const char *const sv_ext_names[SV_EXT_NAME_COUNT] = {"VULKAN_SCHNEE_engine_properties", "VULKAN_SCHNEE_materials",
                                                     "VULKAN_SCHNEE_light", "VULKAN_SCHNEE_node"};

typedef struct ectx_ {
    const sv_gltf *g;
    sv_gltf_error *err; /* NULL: a scratch context whose message goes to `scratch` */
    sv_gltf_result result;
    char scratch[512];
    sv_ext *out;
} ectx_;

#if defined(__GNUC__)
#define EXT_PRINTF(f, a) __attribute__((format(printf, f, a)))
#else
#define EXT_PRINTF(f, a)
#endif

static bool efail(ectx_ *c, sv_gltf_result code, const char *fmt, ...) EXT_PRINTF(3, 4);
static bool efail(ectx_ *c, sv_gltf_result code, const char *fmt, ...)
{
    if (c->result != SV_GLTF_SUCCESS) return false;
    c->result = code;
    char *dst = c->err ? c->err->message : c->scratch;
    size_t cap = c->err ? sizeof c->err->message : sizeof c->scratch;
    if (c->err) c->err->code = code;
    va_list ap;
    va_start(ap, fmt);
    vsnprintf(dst, cap, fmt, ap);
    va_end(ap);
    return false;
}

static void ewarn(ectx_ *c, const char *fmt, ...) EXT_PRINTF(2, 3);
static void ewarn(ectx_ *c, const char *fmt, ...)
{
    sv_ext *x = c->out;
    char buf[640];
    va_list ap;
    va_start(ap, fmt);
    vsnprintf(buf, sizeof buf, fmt, ap);
    va_end(ap);
    char **nw = realloc(x->warnings, (x->warning_count + 1) * sizeof *nw);
    if (!nw) return; /* warnings are best effort */
    x->warnings = nw;
    char *s = malloc(strlen(buf) + 1);
    if (!s) return;
    memcpy(s, buf, strlen(buf) + 1);
    x->warnings[x->warning_count++] = s;
}

static char *edup(ectx_ *c, const char *s)
{
    size_t n = strlen(s) + 1;
    char *d = malloc(n);
    if (!d) {
        efail(c, SV_GLTF_ERROR_OUT_OF_MEMORY, "out of memory");
        return NULL;
    }
    memcpy(d, s, n);
    return d;
}

static const char *type_of(const cJSON *j)
{
    if (cJSON_IsNumber(j)) return "a number";
    if (cJSON_IsString(j)) return "a string";
    if (cJSON_IsArray(j)) return "an array";
    if (cJSON_IsObject(j)) return "an object";
    if (cJSON_IsBool(j)) return "a boolean";
    if (cJSON_IsNull(j)) return "null";
    return "invalid";
}

static const cJSON *get(const cJSON *obj, const char *key) { return cJSON_GetObjectItemCaseSensitive(obj, key); }

/* `j` (named by path) must be an object. */
static bool expect_object(ectx_ *c, const cJSON *j, const char *path)
{
    if (cJSON_IsObject(j)) return true;
    return efail(c, SV_GLTF_ERROR_FORMAT, "%s: expected an object, got %s", path, type_of(j));
}

/* Optional member of a kind (cJSON_Array, cJSON_Object, else string): absent → *out NULL. */
static bool get_typed(ectx_ *c, const cJSON *obj, const char *key, const char *path, int kind, const cJSON **out)
{
    const cJSON *j = get(obj, key);
    *out = NULL;
    if (!j) return true;
    bool ok = kind == cJSON_Array ? cJSON_IsArray(j) : kind == cJSON_Object ? cJSON_IsObject(j) : cJSON_IsString(j);
    if (!ok)
        return efail(c, SV_GLTF_ERROR_FORMAT, "%s.%s: expected %s, got %s", path, key,
                     kind == cJSON_Array    ? "an array"
                     : kind == cJSON_Object ? "an object"
                                            : "a string",
                     type_of(j));
    *out = j;
    return true;
}

static bool get_uint(ectx_ *c, const cJSON *obj, const char *key, const char *path, bool required, uint64_t def,
                     uint64_t lo, uint64_t hi, uint64_t *out)
{
    const cJSON *j = get(obj, key);
    *out = def;
    if (!j) return required ? efail(c, SV_GLTF_ERROR_FORMAT, "%s.%s: missing", path, key) : true;
    double v = cJSON_IsNumber(j) ? j->valuedouble : NAN;
    if (!cJSON_IsNumber(j) || !(v == floor(v)))
        return efail(c, SV_GLTF_ERROR_FORMAT, "%s.%s: expected an integer, got %s", path, key,
                     cJSON_IsNumber(j) ? "a fraction" : type_of(j));
    if (!(v >= (double)lo && v <= (double)hi))
        return efail(c, SV_GLTF_ERROR_FORMAT, "%s.%s: %.17g out of range [%llu, %llu]", path, key, v,
                     (unsigned long long)lo, (unsigned long long)hi);
    *out = (uint64_t)v;
    return true;
}

static bool get_float(ectx_ *c, const cJSON *obj, const char *key, const char *path, bool required, float def,
                      double lo, double hi, float *out)
{
    const cJSON *j = get(obj, key);
    *out = def;
    if (!j) return required ? efail(c, SV_GLTF_ERROR_FORMAT, "%s.%s: missing", path, key) : true;
    if (!cJSON_IsNumber(j) || !isfinite(j->valuedouble))
        return efail(c, SV_GLTF_ERROR_FORMAT, "%s.%s: expected a finite number, got %s", path, key,
                     cJSON_IsNumber(j) ? "a non-finite one" : type_of(j));
    double v = j->valuedouble;
    if (!(v >= lo && v <= hi))
        return efail(c, SV_GLTF_ERROR_FORMAT, "%s.%s: %.9g out of range [%g, %g]", path, key, v, lo, hi);
    *out = (float)v;
    return true;
}

/* JSON array `j` of exactly n finite numbers (float range); `where` names it. */
static bool floats_of(ectx_ *c, const cJSON *j, const char *where, uint32_t n, float *out)
{
    if (!cJSON_IsArray(j) || cJSON_GetArraySize(j) != (int)n)
        return efail(c, SV_GLTF_ERROR_FORMAT, "%s: expected an array of %u numbers", where, n);
    uint32_t i = 0;
    const cJSON *e;
    cJSON_ArrayForEach(e, j)
    {
        if (!cJSON_IsNumber(e) || !isfinite(e->valuedouble) || fabs(e->valuedouble) > FLT_MAX)
            return efail(c, SV_GLTF_ERROR_FORMAT, "%s[%u]: expected a finite number, got %s", where, i,
                         cJSON_IsNumber(e) ? "a non-finite one" : type_of(e));
        out[i++] = (float)e->valuedouble;
    }
    return true;
}

static bool get_floats(ectx_ *c, const cJSON *obj, const char *key, const char *path, uint32_t n, float *out)
{
    const cJSON *j = get(obj, key);
    if (!j) return true;
    char where[192];
    snprintf(where, sizeof where, "%s.%s", path, key);
    return floats_of(c, j, where, n, out);
}

/* The raw JSON of extension `name` parsed (NULL when absent or on error, see c->result). */
static cJSON *parse_raw(ectx_ *c, const sv_gltf_extension *ext, uint32_t count, const char *name, const char *path)
{
    const char *text = sv_gltf_find_extension(ext, count, name);
    if (!text) return NULL;
    cJSON *j = cJSON_Parse(text);
    if (!j) efail(c, SV_GLTF_ERROR_OUT_OF_MEMORY, "%s.%s: cannot re-parse the extension JSON", path, name);
    return j;
}

/* ---------------------------------------------------------------- materials, lights */

static bool parse_material(ectx_ *c, uint32_t i, sv_ext_material *m)
{
    const sv_gltf_material *gm = &c->g->materials[i];
    m->sh_scale = SV_EXT_DEFAULT_SH_SCALE;
    m->ambient_term = SV_EXT_DEFAULT_AMBIENT_TERM;
    m->probe_mode = SV_PROBE_MODE_OBJECT;
    m->probe_representation = SV_PROBE_REP_SH;
    char path[96];
    snprintf(path, sizeof path, "materials[%u].extensions", i);
    cJSON *j = parse_raw(c, gm->extensions, gm->extension_count, "VULKAN_SCHNEE_materials", path);
    if (!j) return c->result == SV_GLTF_SUCCESS;
    snprintf(path, sizeof path, "materials[%u].extensions.VULKAN_SCHNEE_materials", i);
    const cJSON *mode = NULL, *rep = NULL;
    bool ok =
        expect_object(c, j, path) &&
        get_float(c, j, "shScale", path, false, SV_EXT_DEFAULT_SH_SCALE, -FLT_MAX, FLT_MAX, &m->sh_scale) &&
        get_float(c, j, "ambientTerm", path, false, SV_EXT_DEFAULT_AMBIENT_TERM, -FLT_MAX, FLT_MAX, &m->ambient_term) &&
        get_typed(c, j, "probeMode", path, cJSON_String, &mode) &&
        get_typed(c, j, "probeRepresentation", path, cJSON_String, &rep);
    if (ok && mode) {
        int pm = sv_probe_mode_from_name(mode->valuestring, 0);
        if (pm < 0) {
            char names[128];
            sv_probe_mode_list(names, sizeof names, 0);
            ok = efail(c, SV_GLTF_ERROR_FORMAT, "%s.probeMode: '%.40s' is not %s", path, mode->valuestring, names);
        } else {
            m->probe_mode = (uint32_t)pm;
        }
    }
    if (ok && rep) { /* docs/ambient-cube.md §4 "glTF" */
        int pr = sv_probe_representation_from_name(rep->valuestring, 0);
        if (pr < 0)
            ok = efail(c, SV_GLTF_ERROR_FORMAT, "%s.probeRepresentation: '%.40s' is not sh or ambientCube", path,
                       rep->valuestring);
        else
            m->probe_representation = (uint32_t)pr;
    }
    m->present = true;
    cJSON_Delete(j);
    return ok;
}

/* The message names the light, as a user knows it by name rather than by index. */
static bool parse_light(ectx_ *c, uint32_t i, sv_light_mode *mode_out, float *scale_out)
{
    const sv_gltf_light *l = &c->g->lights[i];
    *mode_out = SV_LIGHT_MODE_REALTIME;
    *scale_out = 1.0f;
    char path[160];
    snprintf(path, sizeof path, "KHR_lights_punctual.lights[%u] ('%.24s').extensions", i, l->name);
    cJSON *j = parse_raw(c, l->extensions, l->extension_count, "VULKAN_SCHNEE_light", path);
    if (!j) return c->result == SV_GLTF_SUCCESS;
    snprintf(path, sizeof path, "KHR_lights_punctual.lights[%u] ('%.24s').extensions.VULKAN_SCHNEE_light", i, l->name);
    const cJSON *mode = NULL;
    bool ok = expect_object(c, j, path) && get_typed(c, j, "mode", path, cJSON_String, &mode);
    if (ok && mode) {
        if (strcmp(mode->valuestring, "baked") == 0)
            *mode_out = SV_LIGHT_MODE_BAKED;
        else if (strcmp(mode->valuestring, "mixed") == 0)
            *mode_out = SV_LIGHT_MODE_MIXED;
        else if (strcmp(mode->valuestring, "realtime") != 0)
            ok = efail(c, SV_GLTF_ERROR_FORMAT, "%s.mode: '%.40s' is not baked, mixed or realtime", path,
                       mode->valuestring);
    }
    /* intensityScale: the light's intensity x this = the engine's radiometric units (docs/export.md). */
    ok = ok && get_float(c, j, "intensityScale", path, false, 1.0f, 1e-12, 1e12, scale_out);
    cJSON_Delete(j);
    return ok;
}

/* One field of VULKAN_SCHNEE_node: absent → `fallback`; one of the first `count` names of the table
 * `name_of` (the glTF names, without the command line's "material") → its index; anything else →
 * `fallback` with a warning naming the node, the field and the accepted names. */
static uint32_t node_choice(ectx_ *c, const cJSON *j, const char *key, const char *path,
                            const char *(*name_of)(uint32_t), uint32_t count, uint32_t fallback)
{
    const cJSON *v = get(j, key);
    if (!v) return fallback;
    char names[128] = "";
    for (uint32_t k = 0; k < count; ++k) {
        if (cJSON_IsString(v) && strcmp(v->valuestring, name_of(k)) == 0) return k;
        size_t o = strlen(names);
        snprintf(names + o, sizeof names - o, "%s%s", k == 0 ? "" : k + 1 == count ? " or " : ", ", name_of(k));
    }
    if (cJSON_IsString(v))
        ewarn(c, "%s.%s: '%.40s' is not %s; the node follows its materials", path, key, v->valuestring, names);
    else
        ewarn(c, "%s.%s: expected a string (%s), got %s; the node follows its materials", path, key, names, type_of(v));
    return fallback;
}

/* nodes[i].extensions.VULKAN_SCHNEE_node: the object's own probe mode and representation. Unlike a
 * material's, a bad value is a warning: the node then follows its materials (docs/export.md "Node"). */
static bool parse_node(ectx_ *c, uint32_t i, sv_ext_node *n)
{
    const sv_gltf_node *gn = &c->g->nodes[i];
    n->probe_mode = SV_PROBE_MODE_MATERIAL;
    n->probe_representation = SV_PROBE_REP_MATERIAL;
    char path[160];
    snprintf(path, sizeof path, "nodes[%u] ('%.40s').extensions", i, gn->name ? gn->name : "");
    cJSON *j = parse_raw(c, gn->extensions, gn->extension_count, "VULKAN_SCHNEE_node", path);
    if (!j) return c->result == SV_GLTF_SUCCESS;
    snprintf(path, sizeof path, "nodes[%u] ('%.40s').extensions.VULKAN_SCHNEE_node", i, gn->name ? gn->name : "");
    if (!cJSON_IsObject(j)) {
        ewarn(c, "%s: expected an object, got %s; the node follows its materials", path, type_of(j));
    } else {
        n->probe_mode =
            node_choice(c, j, "probeMode", path, sv_probe_mode_name, SV_PROBE_MODE_MATERIAL, SV_PROBE_MODE_MATERIAL);
        n->probe_representation = node_choice(c, j, "probeRepresentation", path, sv_probe_representation_name,
                                              SV_PROBE_REP_MATERIAL, SV_PROBE_REP_MATERIAL);
    }
    cJSON_Delete(j);
    return true;
}

/* ---------------------------------------------------------------- probe grids, sky */

static const char *const grid_representations[] = {"sh", "ambientCube", NULL};
static const char *const grid_storages[] = {"float32", "float16", NULL};
static const char *const grid_structures[] = {"grid", "octree", "tetrahedra", "kdtree", NULL};
const char *sv_ext_grid_representation_name(uint32_t v) { return v < 2 ? grid_representations[v] : NULL; }
const char *sv_ext_grid_storage_name(uint32_t v) { return v < 2 ? grid_storages[v] : NULL; }
const char *sv_ext_grid_structure_name(uint32_t v) { return v < 4 ? grid_structures[v] : NULL; }

/* An optional string field of an entry that must be one of `names` (NULL-terminated); absent = 0. */
static bool get_choice(ectx_ *c, const cJSON *j, const char *key, const char *gpath, const char *const *names,
                       uint32_t *out)
{
    const cJSON *v = NULL;
    *out = 0;
    if (!get_typed(c, j, key, gpath, cJSON_String, &v)) return false;
    if (!v) return true;
    char list[96] = "";
    for (uint32_t i = 0; names[i]; ++i) {
        if (strcmp(v->valuestring, names[i]) == 0) {
            *out = i;
            return true;
        }
        size_t o = strlen(list);
        snprintf(list + o, sizeof list - o, "%s%s", i ? (names[i + 1] ? ", " : " or ") : "", names[i]);
    }
    return efail(c, SV_GLTF_ERROR_FORMAT, "%s.%s: '%.40s' is not %s", gpath, key, v->valuestring, list);
}

/* One shProbeGrids entry, checked on a scratch context so that a bad entry becomes a warning. */
static bool check_probe_grid(ectx_ *c, const cJSON *j, const char *gpath, sv_ext_probe_grid *pg, const char **uri,
                             const char **name)
{
    const cJSON *u = NULL, *nm = NULL, *axes = NULL;
    uint64_t count = 0, band = 0;
    float dims[3] = {0, 0, 0};
    *uri = *name = NULL;
    if (!expect_object(c, j, gpath)) return false;
    if (!get_typed(c, j, "uri", gpath, cJSON_String, &u) || !get_typed(c, j, "name", gpath, cJSON_String, &nm) ||
        !get_uint(c, j, "probeCount", gpath, true, 0, 0, UINT32_MAX, &count) ||
        !get_uint(c, j, "maxBand", gpath, true, 0, 0, 4, &band) ||
        !get_floats(c, j, "gridOrigin", gpath, 3, pg->grid_origin) || !get_floats(c, j, "gridDims", gpath, 3, dims) ||
        !get_float(c, j, "gridSpacing", gpath, true, 0, 1e-30, FLT_MAX, &pg->grid_spacing) ||
        !get_typed(c, j, "gridAxes", gpath, cJSON_Array, &axes) ||
        !get_choice(c, j, "representation", gpath, grid_representations, &pg->representation) ||
        !get_choice(c, j, "storage", gpath, grid_storages, &pg->storage) ||
        !get_choice(c, j, "structure", gpath, grid_structures, &pg->structure))
        return false;
    const char *missing = !u ? "uri" : !get(j, "gridOrigin") ? "gridOrigin" : !get(j, "gridDims") ? "gridDims" : NULL;
    if (missing) return efail(c, SV_GLTF_ERROR_FORMAT, "%s.%s: missing", gpath, missing);
    for (int k = 0; k < 3; k++) {
        if (!(dims[k] >= 0.0f && dims[k] < 4294967296.0f && dims[k] == floorf(dims[k])))
            return efail(c, SV_GLTF_ERROR_FORMAT, "%s.gridDims[%d]: %g is not a non-negative integer", gpath, k,
                         dims[k]);
        pg->grid_dims[k] = (uint32_t)dims[k];
    }
    for (int r = 0; r < 3; r++)
        for (int k = 0; k < 3; k++) pg->grid_axes[r][k] = r == k ? 1.0f : 0.0f;
    if (axes) {
        if (cJSON_GetArraySize(axes) != 3)
            return efail(c, SV_GLTF_ERROR_FORMAT, "%s.gridAxes: expected 3 rows of 3 numbers", gpath);
        const cJSON *row;
        int r = 0;
        cJSON_ArrayForEach(row, axes)
        {
            char where[192];
            snprintf(where, sizeof where, "%s.gridAxes[%d]", gpath, r);
            if (!floats_of(c, row, where, 3, pg->grid_axes[r])) return false;
            r++;
        }
    }
    pg->probe_count = (uint32_t)count;
    pg->max_band = (uint32_t)band;
    *uri = u->valuestring;
    *name = nm ? nm->valuestring : "";
    return true;
}

static bool check_sky(ectx_ *c, const cJSON *j, const char *path, sv_ext_sky *sky, const char **uri)
{
    const cJSON *u = NULL, *sh = NULL, *e;
    uint64_t band = 2;
    *uri = NULL;
    if (!expect_object(c, j, path)) return false;
    if (!get_typed(c, j, "uri", path, cJSON_String, &u) || !get_typed(c, j, "sh", path, cJSON_Array, &sh) ||
        !get_uint(c, j, "maxBand", path, false, 2, 0, 4, &band))
        return false;
    if (!u || !sh) return efail(c, SV_GLTF_ERROR_FORMAT, "%s.%s: missing", path, !u ? "uri" : "sh");
    uint32_t n = (uint32_t)((band + 1) * (band + 1));
    if (cJSON_GetArraySize(sh) != (int)n)
        return efail(c, SV_GLTF_ERROR_FORMAT, "%s.sh: expected %u RGB triples for maxBand %u, got %d", path, n,
                     (unsigned)band, cJSON_GetArraySize(sh));
    uint32_t i = 0;
    cJSON_ArrayForEach(e, sh)
    {
        char where[192];
        snprintf(where, sizeof where, "%s.sh[%u]", path, i);
        if (!floats_of(c, e, where, 3, sky->sh[i])) return false;
        i++;
    }
    sky->max_band = (uint32_t)band;
    *uri = u->valuestring;
    return true;
}

/* Resolves a grid's or the sky's uri; no base directory → NULL with a warning. */
static bool resolve(ectx_ *c, const char *uri, const char *what, char **path)
{
    *path = NULL;
    if (!c->g->base_dir) {
        ewarn(c, "%s: URI '%.200s' left unresolved (no base directory)", what, uri);
        return true;
    }
    sv_gltf_error e = {0};
    bool literal = false;
    if (sv_gltf_resolve_uri(c->g, uri, what, path, &literal, &e) != SV_GLTF_SUCCESS)
        return efail(c, e.code, "%s", e.message);
    if (literal) ewarn(c, "%s: URI '%.200s' has a '%%' that is not a %%XX escape; taken literally", what, uri);
    return true;
}

static bool parse_sky(ectx_ *c, const cJSON *props, const char *path)
{
    const cJSON *j = get(props, "sky");
    if (!j) return true;
    char spath[160];
    snprintf(spath, sizeof spath, "%s.sky", path);
    ectx_ scratch = {.g = c->g, .out = c->out};
    sv_ext_sky sky = {0};
    const char *uri;
    if (!check_sky(&scratch, j, spath, &sky, &uri)) {
        ewarn(c, "%s (sky skipped)", scratch.scratch);
        return true;
    }
    sv_ext_sky *dst = &c->out->sky;
    *dst = sky;
    dst->present = true;
    return (dst->uri = edup(c, uri)) != NULL && resolve(c, uri, spath, &dst->path);
}

static bool parse_engine_properties(ectx_ *c)
{
    char spath[32], path[112];
    snprintf(spath, sizeof spath, "scenes[%d].extensions", c->g->scene);
    cJSON *props =
        parse_raw(c, c->g->scene_extensions, c->g->scene_extension_count, "VULKAN_SCHNEE_engine_properties", spath);
    if (!props) return c->result == SV_GLTF_SUCCESS;
    snprintf(path, sizeof path, "%s.VULKAN_SCHNEE_engine_properties", spath);
    const cJSON *grids = NULL, *j;
    bool ok = expect_object(c, props, path) && get_typed(c, props, "shProbeGrids", path, cJSON_Array, &grids) &&
              parse_sky(c, props, path);
    if (ok && grids) {
        sv_ext *x = c->out;
        x->probe_grids = calloc((size_t)cJSON_GetArraySize(grids) + 1, sizeof *x->probe_grids);
        if (!x->probe_grids) ok = efail(c, SV_GLTF_ERROR_OUT_OF_MEMORY, "out of memory");
        uint32_t i = 0;
        if (ok) cJSON_ArrayForEach(j, grids)
            {
                char gpath[160];
                snprintf(gpath, sizeof gpath, "%s.shProbeGrids[%u]", path, i++);
                ectx_ scratch = {.g = c->g, .out = c->out};
                sv_ext_probe_grid pg = {0};
                const char *uri, *name;
                if (!check_probe_grid(&scratch, j, gpath, &pg, &uri, &name)) {
                    ewarn(c, "%s (shProbeGrids entry skipped)", scratch.scratch);
                    continue;
                }
                sv_ext_probe_grid *dst = &x->probe_grids[x->probe_grid_count++];
                *dst = pg;
                if (!(dst->name = edup(c, name)) || !(dst->uri = edup(c, uri)) || !resolve(c, uri, gpath, &dst->path)) {
                    ok = false;
                    break;
                }
            }
    }
    cJSON_Delete(props);
    return ok;
}

sv_gltf_result sv_ext_parse(const sv_gltf *g, sv_ext *out, sv_gltf_error *err)
{
    sv_gltf_error local = {0};
    ectx_ c = {.g = g, .err = err ? err : &local, .out = out};
    if (!g || !out) {
        efail(&c, SV_GLTF_ERROR_INVALID_ARGUMENT, "sv_ext_parse: NULL argument");
        return c.result;
    }
    memset(out, 0, sizeof *out);
    out->materials = calloc(g->material_count + 1, sizeof *out->materials);
    out->light_modes = calloc(g->light_count + 1, sizeof *out->light_modes);
    out->light_scales = calloc(g->light_count + 1, sizeof *out->light_scales);
    out->nodes = calloc(g->node_count + 1, sizeof *out->nodes);
    bool ok = out->materials && out->light_modes && out->light_scales && out->nodes;
    if (!ok) efail(&c, SV_GLTF_ERROR_OUT_OF_MEMORY, "out of memory");
    for (uint32_t i = 0; ok && i < g->material_count; i++, out->material_count++)
        ok = parse_material(&c, i, &out->materials[i]);
    for (uint32_t i = 0; ok && i < g->light_count; i++, out->light_count++)
        ok = parse_light(&c, i, &out->light_modes[i], &out->light_scales[i]);
    for (uint32_t i = 0; ok && i < g->node_count; i++, out->node_count++) ok = parse_node(&c, i, &out->nodes[i]);
    ok = ok && parse_engine_properties(&c);
    if (!ok) {
        sv_ext_free(out);
        return c.result != SV_GLTF_SUCCESS ? c.result : SV_GLTF_ERROR_OUT_OF_MEMORY;
    }
    return SV_GLTF_SUCCESS;
}

void sv_ext_free(sv_ext *x)
{
    if (!x) return;
    free(x->materials);
    free(x->light_modes);
    free(x->light_scales);
    free(x->nodes);
    for (uint32_t i = 0; x->probe_grids && i < x->probe_grid_count; i++) {
        free(x->probe_grids[i].name);
        free(x->probe_grids[i].uri);
        free(x->probe_grids[i].path);
    }
    free(x->probe_grids);
    free(x->sky.uri);
    free(x->sky.path);
    for (uint32_t i = 0; i < x->warning_count; i++) free(x->warnings[i]);
    free(x->warnings);
    memset(x, 0, sizeof *x);
}
