/* Loader helpers: errors, warnings, the decoded-size budget, typed JSON getters, raw extensions. */
#include "sv_gltf_internal.h"

#include <float.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

/* ---------------------------------------------------------------- errors, warnings, memory */

sv_gltf_result svg_fail(ctx_ *c, sv_gltf_result code, const char *fmt, ...)
{
    if (c->result == SV_GLTF_SUCCESS) {
        c->result = code;
        if (c->err) {
            c->err->code = code;
            va_list ap;
            va_start(ap, fmt);
            vsnprintf(c->err->message, sizeof c->err->message, fmt, ap);
            va_end(ap);
        }
    }
    return code;
}

void svg_warn(ctx_ *c, const char *fmt, ...)
{
    sv_gltf *g = c->g;
    if (g->warning_count > SVG_MAX_WARNINGS) return;
    if (!g->warnings) {
        g->warnings = calloc(SVG_MAX_WARNINGS + 1, sizeof(char *));
        if (!g->warnings) return; /* warnings are best effort */
    }
    char buf[512];
    if (g->warning_count == SVG_MAX_WARNINGS) {
        snprintf(buf, sizeof buf, "more than %u warnings; the rest are not recorded", SVG_MAX_WARNINGS);
    } else {
        va_list ap;
        va_start(ap, fmt);
        vsnprintf(buf, sizeof buf, fmt, ap);
        va_end(ap);
    }
    size_t n = strlen(buf) + 1;
    char *s = malloc(n);
    if (!s) return;
    memcpy(s, buf, n);
    g->warnings[g->warning_count++] = s;
}

/* Charges `bytes` against the decoded-size budget. */
bool svg_take_budget(ctx_ *c, uint64_t bytes, const char *what)
{
    if (bytes > c->budget) {
        svg_fail(c, SV_GLTF_ERROR_TOO_LARGE, "%s: needs %llu bytes, over the max_decoded_bytes limit (%llu)", what,
                 (unsigned long long)bytes, (unsigned long long)c->desc.max_decoded_bytes);
        return false;
    }
    c->budget -= bytes;
    return true;
}

void *svg_xcalloc(ctx_ *c, uint64_t n, size_t size)
{
    if (n == 0) n = 1;
    if (n > SIZE_MAX / size) {
        svg_fail(c, SV_GLTF_ERROR_OUT_OF_MEMORY, "out of memory (%llu x %zu bytes)", (unsigned long long)n, size);
        return NULL;
    }
    void *p = calloc((size_t)n, size);
    if (!p) svg_fail(c, SV_GLTF_ERROR_OUT_OF_MEMORY, "out of memory (%llu x %zu bytes)", (unsigned long long)n, size);
    return p;
}

/* Decoded arrays: budget-checked calloc of n elements of `size`. */
void *svg_alloc_data(ctx_ *c, uint64_t n, size_t size, const char *what)
{
    if (n > UINT64_MAX / size || !svg_take_budget(c, n * size, what)) return NULL;
    return svg_xcalloc(c, n, size);
}

char *svg_xstrdup(ctx_ *c, const char *s)
{
    size_t n = strlen(s) + 1;
    char *d = svg_xcalloc(c, n, 1);
    if (d) memcpy(d, s, n);
    return d;
}

/* Hands ownership of a malloc'ed block to the handle. */
bool svg_own_blob(ctx_ *c, uint8_t *blob)
{
    struct sv_gltf_internal_ *in = c->g->internal_;
    if (in->blob_count == in->blob_capacity) {
        uint32_t cap = in->blob_capacity ? in->blob_capacity * 2 : 8;
        uint8_t **nb = realloc(in->blobs, cap * sizeof *nb);
        if (!nb) {
            free(blob);
            svg_fail(c, SV_GLTF_ERROR_OUT_OF_MEMORY, "out of memory");
            return false;
        }
        in->blobs = nb;
        in->blob_capacity = cap;
    }
    in->blobs[in->blob_count++] = blob;
    return true;
}

/* ---------------------------------------------------------------- JSON accessors */

const char *svg_type_of(const cJSON *j)
{
    if (cJSON_IsNumber(j)) return "a number";
    if (cJSON_IsString(j)) return "a string";
    if (cJSON_IsArray(j)) return "an array";
    if (cJSON_IsObject(j)) return "an object";
    if (cJSON_IsBool(j)) return "a boolean";
    if (cJSON_IsNull(j)) return "null";
    return "invalid";
}

const cJSON *svg_get(const cJSON *obj, const char *key) { return cJSON_GetObjectItemCaseSensitive(obj, key); }

/* Optional object member of a given kind: absent → *out NULL, wrong kind → error. */
bool svg_get_typed(ctx_ *c, const cJSON *obj, const char *key, const char *path, int kind, const cJSON **out)
{
    const cJSON *j = svg_get(obj, key);
    *out = NULL;
    if (!j) return true;
    bool ok = kind == cJSON_Array ? cJSON_IsArray(j) : kind == cJSON_Object ? cJSON_IsObject(j) : cJSON_IsString(j);
    if (!ok) {
        svg_fail(c, SV_GLTF_ERROR_FORMAT, "%s.%s: expected %s, got %s", path, key,
                 kind == cJSON_Array    ? "an array"
                 : kind == cJSON_Object ? "an object"
                                        : "a string",
                 svg_type_of(j));
        return false;
    }
    *out = j;
    return true;
}

/* Integer member in [lo, hi]; absent → def (or error when required). */
bool svg_get_uint(ctx_ *c, const cJSON *obj, const char *key, const char *path, bool required, uint64_t def,
                  uint64_t lo, uint64_t hi, uint64_t *out)
{
    const cJSON *j = svg_get(obj, key);
    *out = def;
    if (!j) {
        if (required) svg_fail(c, SV_GLTF_ERROR_FORMAT, "%s.%s: missing", path, key);
        return !required;
    }
    double v = cJSON_IsNumber(j) ? j->valuedouble : NAN;
    if (!cJSON_IsNumber(j) || !(v == floor(v))) {
        svg_fail(c, SV_GLTF_ERROR_FORMAT, "%s.%s: expected an integer, got %s", path, key,
                 cJSON_IsNumber(j) ? "a fraction" : svg_type_of(j));
        return false;
    }
    if (!(v >= (double)lo && v <= (double)hi)) {
        svg_fail(c, SV_GLTF_ERROR_FORMAT, "%s.%s: %.17g out of range [%llu, %llu]", path, key, v,
                 (unsigned long long)lo, (unsigned long long)hi);
        return false;
    }
    *out = (uint64_t)v;
    return true;
}

/* Index member referring to one of `count` `plural`; absent → -1 (or error when required). */
bool svg_get_index(ctx_ *c, const cJSON *obj, const char *key, const char *path, bool required, uint32_t count,
                   const char *plural, int32_t *out)
{
    const cJSON *j = svg_get(obj, key);
    *out = -1;
    if (!j) {
        if (required) svg_fail(c, SV_GLTF_ERROR_FORMAT, "%s: %s missing", path, key);
        return !required;
    }
    double v = cJSON_IsNumber(j) ? j->valuedouble : NAN;
    if (!cJSON_IsNumber(j) || !(v == floor(v))) {
        svg_fail(c, SV_GLTF_ERROR_FORMAT, "%s: %s is not an integer index (%s)", path, key,
                 cJSON_IsNumber(j) ? "fraction" : svg_type_of(j));
        return false;
    }
    if (!(v >= 0.0 && v < (double)count)) {
        svg_fail(c, SV_GLTF_ERROR_FORMAT, "%s: %s %.17g out of range (%u %s)", path, key, v, count, plural);
        return false;
    }
    *out = (int32_t)v;
    return true;
}

/* Finite number member in [lo, hi]; absent → def (or error when required). */
bool svg_get_float(ctx_ *c, const cJSON *obj, const char *key, const char *path, bool required, float def, double lo,
                   double hi, float *out)
{
    const cJSON *j = svg_get(obj, key);
    *out = def;
    if (!j) {
        if (required) svg_fail(c, SV_GLTF_ERROR_FORMAT, "%s.%s: missing", path, key);
        return !required;
    }
    if (!cJSON_IsNumber(j) || !isfinite(j->valuedouble)) {
        svg_fail(c, SV_GLTF_ERROR_FORMAT, "%s.%s: expected a finite number, got %s", path, key,
                 cJSON_IsNumber(j) ? "a non-finite one" : svg_type_of(j));
        return false;
    }
    double v = j->valuedouble;
    if (!(v >= lo && v <= hi)) {
        svg_fail(c, SV_GLTF_ERROR_FORMAT, "%s.%s: %.9g out of range [%g, %g]", path, key, v, lo, hi);
        return false;
    }
    *out = (float)v;
    return true;
}

/* JSON array `j` of exactly n finite numbers (float range) into out; `where` names it. */
bool svg_floats_of(ctx_ *c, const cJSON *j, const char *where, uint32_t n, float *out)
{
    if (!cJSON_IsArray(j) || cJSON_GetArraySize(j) != (int)n) {
        svg_fail(c, SV_GLTF_ERROR_FORMAT, "%s: expected an array of %u numbers", where, n);
        return false;
    }
    uint32_t i = 0;
    const cJSON *e;
    cJSON_ArrayForEach(e, j)
    {
        if (!cJSON_IsNumber(e) || !isfinite(e->valuedouble) || fabs(e->valuedouble) > FLT_MAX) {
            svg_fail(c, SV_GLTF_ERROR_FORMAT, "%s[%u]: expected a finite number, got %s", where, i,
                     cJSON_IsNumber(e) ? "a non-finite one" : svg_type_of(e));
            return false;
        }
        out[i++] = (float)e->valuedouble;
    }
    return true;
}

/* Array member of exactly n finite numbers; absent → out untouched (defaults already there). */
bool svg_get_floats(ctx_ *c, const cJSON *obj, const char *key, const char *path, uint32_t n, float *out, bool *present)
{
    const cJSON *j = svg_get(obj, key);
    if (present) *present = j != NULL;
    if (!j) return true;
    char where[192];
    snprintf(where, sizeof where, "%s.%s", path, key);
    return svg_floats_of(c, j, where, n, out);
}

bool svg_get_bool(ctx_ *c, const cJSON *obj, const char *key, const char *path, bool def, bool *out)
{
    const cJSON *j = svg_get(obj, key);
    *out = def;
    if (!j) return true;
    if (!cJSON_IsBool(j)) {
        svg_fail(c, SV_GLTF_ERROR_FORMAT, "%s.%s: expected a boolean, got %s", path, key, svg_type_of(j));
        return false;
    }
    *out = cJSON_IsTrue(j);
    return true;
}

/* Optional string member duplicated into the handle ("" when absent). */
bool svg_get_string(ctx_ *c, const cJSON *obj, const char *key, const char *path, char **out)
{
    const cJSON *j;
    *out = NULL;
    if (!svg_get_typed(c, obj, key, path, cJSON_String, &j)) return false;
    *out = svg_xstrdup(c, j ? j->valuestring : "");
    return *out != NULL;
}

/* Top-level array (absent → NULL with count 0). */
bool svg_top_array(ctx_ *c, const cJSON *root, const char *key, const cJSON **arr, uint32_t *count)
{
    *count = 0;
    if (!svg_get_typed(c, root, key, "(root)", cJSON_Array, arr)) return false;
    if (*arr) {
        int n = cJSON_GetArraySize(*arr);
        *count = n > 0 ? (uint32_t)n : 0;
        const cJSON *e;
        uint32_t i = 0;
        cJSON_ArrayForEach(e, *arr)
        {
            if (!cJSON_IsObject(e)) {
                svg_fail(c, SV_GLTF_ERROR_FORMAT, "%s[%u]: expected an object, got %s", key, i, svg_type_of(e));
                return false;
            }
            i++;
        }
    }
    return true;
}

bool svg_get_extensions(ctx_ *c, const cJSON *obj, const char *path, const char *const *consumed,
                        sv_gltf_extension **out, uint32_t *count)
{
    const cJSON *ext, *e;
    *out = NULL;
    *count = 0;
    if (!svg_get_typed(c, obj, "extensions", path, cJSON_Object, &ext)) return false;
    if (!ext) return true;
    uint32_t n = 0;
    cJSON_ArrayForEach(e, ext) n++;
    if (!n) return true;
    *out = svg_xcalloc(c, n, sizeof **out);
    if (!*out) return false;
    cJSON_ArrayForEach(e, ext)
    {
        bool skip = false;
        for (const char *const *k = consumed; k && *k && !skip; k++) skip = strcmp(e->string, *k) == 0;
        if (skip) continue;
        sv_gltf_extension *x = &(*out)[*count];
        char *text = cJSON_PrintUnformatted(e);
        if (!text) {
            svg_fail(c, SV_GLTF_ERROR_OUT_OF_MEMORY, "out of memory");
            return false;
        }
        size_t len = strlen(text);
        x->name = svg_xstrdup(c, e->string);
        x->json = x->name && svg_take_budget(c, len + 1, path) ? svg_xcalloc(c, len + 1, 1) : NULL;
        if (x->json) memcpy(x->json, text, len + 1);
        cJSON_free(text);
        (*count)++; /* counted before the check so that sv_gltf_free releases a half-filled entry */
        if (!x->name || !x->json) return false;
    }
    return true;
}

void svg_free_extensions(sv_gltf_extension *ext, uint32_t count)
{
    for (uint32_t i = 0; ext && i < count; i++) {
        free(ext[i].name);
        free(ext[i].json);
    }
    free(ext);
}
