/* glTF 2.0 loader: JSON (libcjson) + GLB container, validated and decoded to engine-ready arrays.
 *
 * Order of work: container (GLB or JSON) → asset/extensionsRequired → buffers → bufferViews →
 * accessors (all ranges validated up front) → samplers/images/textures/materials → meshes (decoded)
 * → cameras/lights → nodes (parents, cycles, world matrices) → default scene (instances, probe
 * grids). Every allocation hangs off the sv_gltf handle as soon as it is made, so one
 * sv_gltf_free() cleans up after success and after an error at any point.
 */
#include "sv_gltf_internal.h"

#include <cJSON.h>
#include <float.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#define GLB_MAGIC      0x46546C67u /* "glTF" */
#define GLB_CHUNK_JSON 0x4E4F534Au /* "JSON" */
#define GLB_CHUNK_BIN  0x004E4942u /* "BIN\0" */
#define MAX_WARNINGS   200u
#define SV_PI          3.14159265358979323846

enum { CT_BYTE = 5120, CT_UBYTE = 5121, CT_SHORT = 5122, CT_USHORT = 5123, CT_UINT = 5125, CT_FLOAT = 5126 };

typedef struct view_ {
    uint32_t buffer;
    uint64_t offset, length;
    uint32_t stride; /* 0 = tightly packed */
} view_;

typedef struct accessor_ {
    int32_t view; /* -1: all zeros (plus sparse) */
    uint64_t offset;
    uint32_t ct, comp_size, ncomp, count;
    const char *type_name;
    bool normalized, is_matrix;
    uint64_t elem_size, stride;
    bool sparse;
    uint32_t sp_count, sp_idx_ct, sp_idx_view, sp_val_view;
    uint64_t sp_idx_off, sp_val_off;
} accessor_;

typedef struct ctx_ {
    sv_gltf *g;
    sv_gltf_error *err;
    sv_gltf_result result;
    sv_gltf_desc desc;
    uint64_t budget; /* bytes still allowed by desc.max_decoded_bytes */
    const uint8_t *glb_bin;
    size_t glb_bin_size;
    bool is_glb;
    const uint8_t **buf_data;
    uint64_t *buf_size;
    uint32_t buf_count;
    view_ *views;
    uint32_t view_count;
    accessor_ *accs;
    uint32_t acc_count;
} ctx_;

/* ---------------------------------------------------------------- errors, warnings, memory */

static sv_gltf_result fail(ctx_ *c, sv_gltf_result code, const char *fmt, ...)
#if defined(__GNUC__)
    __attribute__((format(printf, 3, 4)))
#endif
    ;

static sv_gltf_result fail(ctx_ *c, sv_gltf_result code, const char *fmt, ...)
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

static void warn(ctx_ *c, const char *fmt, ...)
#if defined(__GNUC__)
    __attribute__((format(printf, 2, 3)))
#endif
    ;

static void warn(ctx_ *c, const char *fmt, ...)
{
    sv_gltf *g = c->g;
    if (g->warning_count > MAX_WARNINGS) return;
    if (!g->warnings) {
        g->warnings = calloc(MAX_WARNINGS + 1, sizeof(char *));
        if (!g->warnings) return; /* warnings are best effort */
    }
    char buf[512];
    if (g->warning_count == MAX_WARNINGS) {
        snprintf(buf, sizeof buf, "more than %u warnings; the rest are not recorded", MAX_WARNINGS);
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
static bool take_budget(ctx_ *c, uint64_t bytes, const char *what)
{
    if (bytes > c->budget) {
        fail(c, SV_GLTF_ERROR_TOO_LARGE, "%s: needs %llu bytes, over the max_decoded_bytes limit (%llu)", what,
             (unsigned long long)bytes, (unsigned long long)c->desc.max_decoded_bytes);
        return false;
    }
    c->budget -= bytes;
    return true;
}

static void *xcalloc(ctx_ *c, uint64_t n, size_t size)
{
    if (n == 0) n = 1;
    if (n > SIZE_MAX / size) {
        fail(c, SV_GLTF_ERROR_OUT_OF_MEMORY, "out of memory (%llu x %zu bytes)", (unsigned long long)n, size);
        return NULL;
    }
    void *p = calloc((size_t)n, size);
    if (!p) fail(c, SV_GLTF_ERROR_OUT_OF_MEMORY, "out of memory (%llu x %zu bytes)", (unsigned long long)n, size);
    return p;
}

/* Decoded arrays: budget-checked calloc of n elements of `size`. */
static void *alloc_data(ctx_ *c, uint64_t n, size_t size, const char *what)
{
    if (n > UINT64_MAX / size || !take_budget(c, n * size, what)) return NULL;
    return xcalloc(c, n, size);
}

static char *xstrdup(ctx_ *c, const char *s)
{
    size_t n = strlen(s) + 1;
    char *d = xcalloc(c, n, 1);
    if (d) memcpy(d, s, n);
    return d;
}

/* Hands ownership of a malloc'ed block to the handle. */
static bool own_blob(ctx_ *c, uint8_t *blob)
{
    struct sv_gltf_internal_ *in = c->g->internal_;
    if (in->blob_count == in->blob_capacity) {
        uint32_t cap = in->blob_capacity ? in->blob_capacity * 2 : 8;
        uint8_t **nb = realloc(in->blobs, cap * sizeof *nb);
        if (!nb) {
            free(blob);
            fail(c, SV_GLTF_ERROR_OUT_OF_MEMORY, "out of memory");
            return false;
        }
        in->blobs = nb;
        in->blob_capacity = cap;
    }
    in->blobs[in->blob_count++] = blob;
    return true;
}

/* ---------------------------------------------------------------- JSON accessors */

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

/* Optional object member of a given kind: absent → *out NULL, wrong kind → error. */
static bool get_typed(ctx_ *c, const cJSON *obj, const char *key, const char *path, int kind, const cJSON **out)
{
    const cJSON *j = get(obj, key);
    *out = NULL;
    if (!j) return true;
    bool ok = kind == cJSON_Array ? cJSON_IsArray(j) : kind == cJSON_Object ? cJSON_IsObject(j) : cJSON_IsString(j);
    if (!ok) {
        fail(c, SV_GLTF_ERROR_FORMAT, "%s.%s: expected %s, got %s", path, key,
             kind == cJSON_Array    ? "an array"
             : kind == cJSON_Object ? "an object"
                                    : "a string",
             type_of(j));
        return false;
    }
    *out = j;
    return true;
}

/* Integer member in [lo, hi]; absent → def (or error when required). */
static bool get_uint(ctx_ *c, const cJSON *obj, const char *key, const char *path, bool required, uint64_t def,
                     uint64_t lo, uint64_t hi, uint64_t *out)
{
    const cJSON *j = get(obj, key);
    *out = def;
    if (!j) {
        if (required) fail(c, SV_GLTF_ERROR_FORMAT, "%s.%s: missing", path, key);
        return !required;
    }
    double v = cJSON_IsNumber(j) ? j->valuedouble : NAN;
    if (!cJSON_IsNumber(j) || !(v == floor(v))) {
        fail(c, SV_GLTF_ERROR_FORMAT, "%s.%s: expected an integer, got %s", path, key,
             cJSON_IsNumber(j) ? "a fraction" : type_of(j));
        return false;
    }
    if (!(v >= (double)lo && v <= (double)hi)) {
        fail(c, SV_GLTF_ERROR_FORMAT, "%s.%s: %.17g out of range [%llu, %llu]", path, key, v, (unsigned long long)lo,
             (unsigned long long)hi);
        return false;
    }
    *out = (uint64_t)v;
    return true;
}

/* Index member referring to one of `count` `plural`; absent → -1 (or error when required). */
static bool get_index(ctx_ *c, const cJSON *obj, const char *key, const char *path, bool required, uint32_t count,
                      const char *plural, int32_t *out)
{
    const cJSON *j = get(obj, key);
    *out = -1;
    if (!j) {
        if (required) fail(c, SV_GLTF_ERROR_FORMAT, "%s: %s missing", path, key);
        return !required;
    }
    double v = cJSON_IsNumber(j) ? j->valuedouble : NAN;
    if (!cJSON_IsNumber(j) || !(v == floor(v))) {
        fail(c, SV_GLTF_ERROR_FORMAT, "%s: %s is not an integer index (%s)", path, key,
             cJSON_IsNumber(j) ? "fraction" : type_of(j));
        return false;
    }
    if (!(v >= 0.0 && v < (double)count)) {
        fail(c, SV_GLTF_ERROR_FORMAT, "%s: %s %.17g out of range (%u %s)", path, key, v, count, plural);
        return false;
    }
    *out = (int32_t)v;
    return true;
}

/* Finite number member in [lo, hi]; absent → def (or error when required). */
static bool get_float(ctx_ *c, const cJSON *obj, const char *key, const char *path, bool required, float def, double lo,
                      double hi, float *out)
{
    const cJSON *j = get(obj, key);
    *out = def;
    if (!j) {
        if (required) fail(c, SV_GLTF_ERROR_FORMAT, "%s.%s: missing", path, key);
        return !required;
    }
    if (!cJSON_IsNumber(j) || !isfinite(j->valuedouble)) {
        fail(c, SV_GLTF_ERROR_FORMAT, "%s.%s: expected a finite number, got %s", path, key,
             cJSON_IsNumber(j) ? "a non-finite one" : type_of(j));
        return false;
    }
    double v = j->valuedouble;
    if (!(v >= lo && v <= hi)) {
        fail(c, SV_GLTF_ERROR_FORMAT, "%s.%s: %.9g out of range [%g, %g]", path, key, v, lo, hi);
        return false;
    }
    *out = (float)v;
    return true;
}

/* JSON array `j` of exactly n finite numbers (float range) into out; `where` names it. */
static bool floats_of(ctx_ *c, const cJSON *j, const char *where, uint32_t n, float *out)
{
    if (!cJSON_IsArray(j) || cJSON_GetArraySize(j) != (int)n) {
        fail(c, SV_GLTF_ERROR_FORMAT, "%s: expected an array of %u numbers", where, n);
        return false;
    }
    uint32_t i = 0;
    const cJSON *e;
    cJSON_ArrayForEach(e, j)
    {
        if (!cJSON_IsNumber(e) || !isfinite(e->valuedouble) || fabs(e->valuedouble) > FLT_MAX) {
            fail(c, SV_GLTF_ERROR_FORMAT, "%s[%u]: expected a finite number, got %s", where, i,
                 cJSON_IsNumber(e) ? "a non-finite one" : type_of(e));
            return false;
        }
        out[i++] = (float)e->valuedouble;
    }
    return true;
}

/* Array member of exactly n finite numbers; absent → out untouched (defaults already there). */
static bool get_floats(ctx_ *c, const cJSON *obj, const char *key, const char *path, uint32_t n, float *out,
                       bool *present)
{
    const cJSON *j = get(obj, key);
    if (present) *present = j != NULL;
    if (!j) return true;
    char where[192];
    snprintf(where, sizeof where, "%s.%s", path, key);
    return floats_of(c, j, where, n, out);
}

static bool get_bool(ctx_ *c, const cJSON *obj, const char *key, const char *path, bool def, bool *out)
{
    const cJSON *j = get(obj, key);
    *out = def;
    if (!j) return true;
    if (!cJSON_IsBool(j)) {
        fail(c, SV_GLTF_ERROR_FORMAT, "%s.%s: expected a boolean, got %s", path, key, type_of(j));
        return false;
    }
    *out = cJSON_IsTrue(j);
    return true;
}

/* Optional string member duplicated into the handle ("" when absent). */
static bool get_string(ctx_ *c, const cJSON *obj, const char *key, const char *path, char **out)
{
    const cJSON *j;
    *out = NULL;
    if (!get_typed(c, obj, key, path, cJSON_String, &j)) return false;
    *out = xstrdup(c, j ? j->valuestring : "");
    return *out != NULL;
}

/* Top-level array (absent → NULL with count 0). */
static bool top_array(ctx_ *c, const cJSON *root, const char *key, const cJSON **arr, uint32_t *count)
{
    *count = 0;
    if (!get_typed(c, root, key, "(root)", cJSON_Array, arr)) return false;
    if (*arr) {
        int n = cJSON_GetArraySize(*arr);
        *count = n > 0 ? (uint32_t)n : 0;
        const cJSON *e;
        uint32_t i = 0;
        cJSON_ArrayForEach(e, *arr)
        {
            if (!cJSON_IsObject(e)) {
                fail(c, SV_GLTF_ERROR_FORMAT, "%s[%u]: expected an object, got %s", key, i, type_of(e));
                return false;
            }
            i++;
        }
    }
    return true;
}

/* ---------------------------------------------------------------- URIs and files */

/* Reads up to `want` bytes (or the whole file when want == 0) of path; fails with a message about
 * `what`. *out is malloc'ed. */
static bool read_file(ctx_ *c, const char *path, uint64_t want, const char *what, uint8_t **out, uint64_t *out_size)
{
    *out = NULL;
    FILE *f = fopen(path, "rb");
    if (!f) {
        fail(c, SV_GLTF_ERROR_IO, "%s: cannot open '%s'", what, path);
        return false;
    }
    long end = -1;
    if (fseek(f, 0, SEEK_END) == 0) end = ftell(f);
    if (end < 0 || fseek(f, 0, SEEK_SET) != 0) {
        fclose(f);
        fail(c, SV_GLTF_ERROR_IO, "%s: cannot read '%s' (not a regular file?)", what, path);
        return false;
    }
    uint64_t size = (uint64_t)end;
    if (want && size < want) {
        fclose(f);
        fail(c, SV_GLTF_ERROR_FORMAT, "%s: file '%s' has %llu bytes, byteLength is %llu", what, path,
             (unsigned long long)size, (unsigned long long)want);
        return false;
    }
    if (want) size = want;
    if (!take_budget(c, size, what)) {
        fclose(f);
        return false;
    }
    uint8_t *buf = xcalloc(c, size, 1);
    if (!buf) {
        fclose(f);
        return false;
    }
    if (size && fread(buf, 1, (size_t)size, f) != size) {
        fclose(f);
        free(buf);
        fail(c, SV_GLTF_ERROR_IO, "%s: cannot read '%s'", what, path);
        return false;
    }
    fclose(f);
    *out = buf;
    *out_size = size;
    return true;
}

/* Resolves a relative URI to a path under the base dir (percent-decoded). Refuses schemes and
 * external files without a base dir. */
static char *resolve_uri(ctx_ *c, const char *uri, const char *what)
{
    char scheme[16];
    if (svg_uri_has_scheme(uri, scheme, sizeof scheme)) {
        fail(c, SV_GLTF_ERROR_UNSUPPORTED, "%s: URI scheme '%s:' is not supported (only relative paths and data:)",
             what, scheme);
        return NULL;
    }
    if (!c->g->base_dir) {
        fail(c, SV_GLTF_ERROR_UNSUPPORTED, "%s: external URI '%.200s' but no base directory was given", what, uri);
        return NULL;
    }
    char *decoded = svg_percent_decode(uri);
    if (!decoded) {
        fail(c, SV_GLTF_ERROR_FORMAT, "%s: malformed percent-encoding in URI '%.200s'", what, uri);
        return NULL;
    }
    if (!decoded[0]) {
        free(decoded);
        fail(c, SV_GLTF_ERROR_FORMAT, "%s: empty URI", what);
        return NULL;
    }
    char *path = svg_path_join(c->g->base_dir, decoded);
    free(decoded);
    if (!path) fail(c, SV_GLTF_ERROR_OUT_OF_MEMORY, "out of memory");
    return path;
}

/* Decodes a base64 data: URI into an owned blob. */
static bool decode_data_uri(ctx_ *c, const char *uri, const char *what, const uint8_t **data, uint64_t *size,
                            char **mime_out)
{
    const char *mime, *payload;
    size_t mime_len;
    bool b64;
    if (!svg_parse_data_uri(uri, &mime, &mime_len, &payload, &b64)) {
        fail(c, SV_GLTF_ERROR_FORMAT, "%s: malformed data: URI (no ',')", what);
        return false;
    }
    if (!b64) {
        fail(c, SV_GLTF_ERROR_UNSUPPORTED, "%s: data: URI is not base64-encoded", what);
        return false;
    }
    size_t plen = strlen(payload);
    if (!take_budget(c, plen / 4 * 3 + 3, what)) return false;
    uint8_t *bytes;
    size_t n;
    if (!svg_base64_decode(payload, plen, &bytes, &n)) {
        fail(c, SV_GLTF_ERROR_FORMAT, "%s: invalid base64 in data: URI", what);
        return false;
    }
    if (!own_blob(c, bytes)) return false;
    *data = bytes;
    *size = n;
    if (mime_out) {
        *mime_out = xcalloc(c, mime_len + 1, 1);
        if (!*mime_out) return false;
        memcpy(*mime_out, mime, mime_len);
    }
    return true;
}

/* ---------------------------------------------------------------- buffers, views, accessors */

static bool parse_buffers(ctx_ *c, const cJSON *root)
{
    const cJSON *arr, *b;
    if (!top_array(c, root, "buffers", &arr, &c->buf_count)) return false;
    c->buf_data = xcalloc(c, c->buf_count, sizeof *c->buf_data);
    c->buf_size = xcalloc(c, c->buf_count, sizeof *c->buf_size);
    if (!c->buf_data || !c->buf_size) return false;
    uint32_t i = 0;
    cJSON_ArrayForEach(b, arr)
    {
        char path[48];
        snprintf(path, sizeof path, "buffers[%u]", i);
        uint64_t len;
        const cJSON *uri;
        if (!get_uint(c, b, "byteLength", path, true, 0, 1, (1ull << 53), &len) ||
            !get_typed(c, b, "uri", path, cJSON_String, &uri))
            return false;
        if (!uri) {
            if (i != 0 || !c->is_glb || !c->glb_bin) {
                fail(c, SV_GLTF_ERROR_FORMAT, "%s: no uri and no GLB binary chunk to refer to", path);
                return false;
            }
            if (c->glb_bin_size < len || c->glb_bin_size - len > 3) {
                fail(c, SV_GLTF_ERROR_FORMAT, "%s: byteLength %llu does not match the GLB BIN chunk (%zu bytes)", path,
                     (unsigned long long)len, c->glb_bin_size);
                return false;
            }
            c->buf_data[i] = c->glb_bin;
        } else if (strncmp(uri->valuestring, "data:", 5) == 0) {
            uint64_t n;
            if (!decode_data_uri(c, uri->valuestring, path, &c->buf_data[i], &n, NULL)) return false;
            if (n < len) {
                fail(c, SV_GLTF_ERROR_FORMAT, "%s: data: URI holds %llu bytes, byteLength is %llu", path,
                     (unsigned long long)n, (unsigned long long)len);
                return false;
            }
        } else {
            char *file = resolve_uri(c, uri->valuestring, path);
            if (!file) return false;
            uint8_t *data;
            uint64_t n;
            bool ok = read_file(c, file, len, path, &data, &n);
            free(file);
            if (!ok || !own_blob(c, data)) return false;
            c->buf_data[i] = data;
        }
        c->buf_size[i] = len;
        i++;
    }
    return true;
}

static bool parse_views(ctx_ *c, const cJSON *root)
{
    const cJSON *arr, *v;
    if (!top_array(c, root, "bufferViews", &arr, &c->view_count)) return false;
    c->views = xcalloc(c, c->view_count, sizeof *c->views);
    if (!c->views) return false;
    uint32_t i = 0;
    cJSON_ArrayForEach(v, arr)
    {
        char path[48];
        snprintf(path, sizeof path, "bufferViews[%u]", i);
        view_ *w = &c->views[i];
        int32_t buffer;
        uint64_t stride;
        if (!get_index(c, v, "buffer", path, true, c->buf_count, "buffers", &buffer) ||
            !get_uint(c, v, "byteOffset", path, false, 0, 0, (1ull << 53), &w->offset) ||
            !get_uint(c, v, "byteLength", path, true, 0, 1, (1ull << 53), &w->length) ||
            !get_uint(c, v, "byteStride", path, false, 0, 4, 252, &stride))
            return false;
        if (stride % 4) {
            fail(c, SV_GLTF_ERROR_FORMAT, "%s.byteStride: %llu is not a multiple of 4", path,
                 (unsigned long long)stride);
            return false;
        }
        w->buffer = (uint32_t)buffer;
        w->stride = (uint32_t)stride;
        uint64_t size = c->buf_size[buffer];
        if (w->offset > size || w->length > size - w->offset) {
            fail(c, SV_GLTF_ERROR_FORMAT, "%s: byteOffset %llu + byteLength %llu exceeds buffer %d (%llu bytes)", path,
                 (unsigned long long)w->offset, (unsigned long long)w->length, buffer, (unsigned long long)size);
            return false;
        }
        i++;
    }
    return true;
}

static uint32_t comp_size(uint32_t ct)
{
    switch (ct) {
    case CT_BYTE:
    case CT_UBYTE: return 1;
    case CT_SHORT:
    case CT_USHORT: return 2;
    case CT_UINT:
    case CT_FLOAT: return 4;
    default: return 0;
    }
}

/* Checks that [offset, offset + size) lies in bufferView `view`. */
static bool check_in_view(ctx_ *c, const char *path, uint32_t view, uint64_t offset, uint64_t size)
{
    uint64_t len = c->views[view].length;
    if (offset > len || size > len - offset) {
        fail(c, SV_GLTF_ERROR_FORMAT, "%s: needs bytes [%llu, %llu) of bufferView %u, which has %llu bytes", path,
             (unsigned long long)offset, (unsigned long long)(offset + size), view, (unsigned long long)len);
        return false;
    }
    return true;
}

static bool parse_sparse(ctx_ *c, accessor_ *a, const cJSON *sp, const char *apath)
{
    char path[64], ipath[80], vpath[80];
    snprintf(path, sizeof path, "%s.sparse", apath);
    uint64_t count, ct;
    const cJSON *idx, *val;
    if (!get_uint(c, sp, "count", path, true, 0, 1, a->count, &count) ||
        !get_typed(c, sp, "indices", path, cJSON_Object, &idx) || !get_typed(c, sp, "values", path, cJSON_Object, &val))
        return false;
    if (!idx || !val) {
        fail(c, SV_GLTF_ERROR_FORMAT, "%s: %s missing", path, idx ? "values" : "indices");
        return false;
    }
    snprintf(ipath, sizeof ipath, "%s.indices", path);
    snprintf(vpath, sizeof vpath, "%s.values", path);
    int32_t iv, vv;
    if (!get_index(c, idx, "bufferView", ipath, true, c->view_count, "bufferViews", &iv) ||
        !get_uint(c, idx, "byteOffset", ipath, false, 0, 0, (1ull << 53), &a->sp_idx_off) ||
        !get_uint(c, idx, "componentType", ipath, true, 0, 0, UINT32_MAX, &ct) ||
        !get_index(c, val, "bufferView", vpath, true, c->view_count, "bufferViews", &vv) ||
        !get_uint(c, val, "byteOffset", vpath, false, 0, 0, (1ull << 53), &a->sp_val_off))
        return false;
    if (ct != CT_UBYTE && ct != CT_USHORT && ct != CT_UINT) {
        fail(c, SV_GLTF_ERROR_FORMAT, "%s.componentType: %llu is not 5121, 5123 or 5125", ipath,
             (unsigned long long)ct);
        return false;
    }
    a->sparse = true;
    a->sp_count = (uint32_t)count;
    a->sp_idx_ct = (uint32_t)ct;
    a->sp_idx_view = (uint32_t)iv;
    a->sp_val_view = (uint32_t)vv;
    return check_in_view(c, ipath, a->sp_idx_view, a->sp_idx_off, count * comp_size((uint32_t)ct)) &&
           check_in_view(c, vpath, a->sp_val_view, a->sp_val_off, count * a->elem_size);
}

static bool parse_accessors(ctx_ *c, const cJSON *root)
{
    static const struct {
        const char *name;
        uint32_t ncomp;
        bool matrix;
    } types[] = {
        {"SCALAR", 1, false}, {"VEC2", 2, false}, {"VEC3", 3, false}, {"VEC4", 4, false},
        {"MAT2", 4, true},    {"MAT3", 9, true},  {"MAT4", 16, true},
    };
    const cJSON *arr, *j;
    if (!top_array(c, root, "accessors", &arr, &c->acc_count)) return false;
    c->accs = xcalloc(c, c->acc_count, sizeof *c->accs);
    if (!c->accs) return false;
    uint32_t i = 0;
    cJSON_ArrayForEach(j, arr)
    {
        char path[48];
        snprintf(path, sizeof path, "accessors[%u]", i);
        accessor_ *a = &c->accs[i];
        uint64_t ct, count;
        const cJSON *type, *sp;
        if (!get_index(c, j, "bufferView", path, false, c->view_count, "bufferViews", &a->view) ||
            !get_uint(c, j, "byteOffset", path, false, 0, 0, (1ull << 53), &a->offset) ||
            !get_uint(c, j, "componentType", path, true, 0, 0, UINT32_MAX, &ct) ||
            !get_uint(c, j, "count", path, true, 0, 1, UINT32_MAX, &count) ||
            !get_bool(c, j, "normalized", path, false, &a->normalized) ||
            !get_typed(c, j, "type", path, cJSON_String, &type) || !get_typed(c, j, "sparse", path, cJSON_Object, &sp))
            return false;
        a->ct = (uint32_t)ct;
        a->count = (uint32_t)count;
        a->comp_size = comp_size(a->ct);
        if (!a->comp_size) {
            fail(c, SV_GLTF_ERROR_FORMAT, "%s.componentType: %llu is not a glTF component type", path,
                 (unsigned long long)ct);
            return false;
        }
        if (a->normalized && (a->ct == CT_FLOAT || a->ct == CT_UINT)) {
            fail(c, SV_GLTF_ERROR_FORMAT, "%s: normalized is not allowed with componentType %u", path, a->ct);
            return false;
        }
        if (!type) {
            fail(c, SV_GLTF_ERROR_FORMAT, "%s.type: missing", path);
            return false;
        }
        bool found = false;
        for (size_t t = 0; t < sizeof types / sizeof types[0]; t++)
            if (strcmp(type->valuestring, types[t].name) == 0) {
                a->ncomp = types[t].ncomp;
                a->is_matrix = types[t].matrix;
                a->type_name = types[t].name;
                found = true;
            }
        if (!found) {
            fail(c, SV_GLTF_ERROR_FORMAT, "%s.type: '%.40s' is not SCALAR, VEC2..4 or MAT2..4", path,
                 type->valuestring);
            return false;
        }
        /* Matrix columns are padded to 4-byte boundaries (glTF 2.0 §3.6.2.4). */
        uint64_t cols = a->is_matrix ? (a->ncomp == 4 ? 2 : a->ncomp == 9 ? 3 : 4) : 1;
        uint64_t col_bytes = (uint64_t)(a->ncomp / cols) * a->comp_size;
        a->elem_size = cols * ((col_bytes + 3) / 4 * 4);
        if (!a->is_matrix) a->elem_size = (uint64_t)a->ncomp * a->comp_size;
        if (a->view < 0) {
            if (a->offset) {
                fail(c, SV_GLTF_ERROR_FORMAT, "%s: byteOffset without bufferView", path);
                return false;
            }
        } else {
            const view_ *v = &c->views[a->view];
            if (a->offset % a->comp_size) {
                fail(c, SV_GLTF_ERROR_FORMAT, "%s: byteOffset %llu is not a multiple of the component size %u", path,
                     (unsigned long long)a->offset, a->comp_size);
                return false;
            }
            a->stride = v->stride ? v->stride : a->elem_size;
            if (a->stride < a->elem_size) {
                fail(c, SV_GLTF_ERROR_FORMAT,
                     "%s: bufferView %d byteStride %u is smaller than the element (%llu bytes)", path, a->view,
                     v->stride, (unsigned long long)a->elem_size);
                return false;
            }
            /* count <= 2^32 and stride <= 252: no overflow in 64 bits. */
            if (!check_in_view(c, path, (uint32_t)a->view, a->offset,
                               (uint64_t)(a->count - 1) * a->stride + a->elem_size))
                return false;
        }
        if (sp && !parse_sparse(c, a, sp, path)) return false;
        i++;
    }
    return true;
}

static double read_comp(const uint8_t *p, uint32_t ct, bool norm)
{
    switch (ct) {
    case CT_BYTE: {
        int8_t v;
        memcpy(&v, p, 1);
        return norm ? fmax(v / 127.0, -1.0) : v;
    }
    case CT_UBYTE: return norm ? p[0] / 255.0 : p[0];
    case CT_SHORT: {
        int16_t v;
        memcpy(&v, p, 2);
        return norm ? fmax(v / 32767.0, -1.0) : v;
    }
    case CT_USHORT: {
        uint16_t v;
        memcpy(&v, p, 2);
        return norm ? v / 65535.0 : v;
    }
    case CT_UINT: {
        uint32_t v;
        memcpy(&v, p, 4);
        return v;
    }
    default: {
        float v;
        memcpy(&v, p, 4);
        return v;
    }
    }
}

static const uint8_t *view_ptr(const ctx_ *c, uint32_t view, uint64_t offset)
{
    const view_ *v = &c->views[view];
    return c->buf_data[v->buffer] + v->offset + offset;
}

/* Decodes accessor `ai` into out (count * out_ncomp floats, or uint32 when outu). Source components
 * beyond out_ncomp never exist (callers check the type); missing ones are filled with `fill`. */
static bool decode_accessor(ctx_ *c, uint32_t ai, const char *path, uint32_t out_ncomp, float fill, float *outf,
                            uint32_t *outu)
{
    const accessor_ *a = &c->accs[ai];
    uint32_t n = a->ncomp;
    for (uint32_t i = 0; i < a->count; i++) {
        for (uint32_t k = 0; k < out_ncomp; k++) {
            double v = k < n ? 0.0 : fill;
            if (k < n && a->view >= 0)
                v = read_comp(
                    view_ptr(c, (uint32_t)a->view, a->offset + (uint64_t)i * a->stride + (uint64_t)k * a->comp_size),
                    a->ct, a->normalized);
            if (outu)
                outu[(uint64_t)i * out_ncomp + k] = (uint32_t)v;
            else
                outf[(uint64_t)i * out_ncomp + k] = (float)v;
        }
    }
    if (a->sparse) {
        const uint8_t *ip = view_ptr(c, a->sp_idx_view, a->sp_idx_off);
        const uint8_t *vp = view_ptr(c, a->sp_val_view, a->sp_val_off);
        uint32_t isz = comp_size(a->sp_idx_ct);
        uint64_t prev = 0;
        for (uint32_t s = 0; s < a->sp_count; s++) {
            uint64_t idx = (uint64_t)read_comp(ip + (uint64_t)s * isz, a->sp_idx_ct, false);
            if (idx >= a->count || (s > 0 && idx <= prev)) {
                fail(c, SV_GLTF_ERROR_FORMAT, "%s: accessors[%u].sparse.indices[%u] = %llu is %s", path, ai, s,
                     (unsigned long long)idx, idx >= a->count ? "out of range" : "not increasing");
                return false;
            }
            prev = idx;
            for (uint32_t k = 0; k < n && k < out_ncomp; k++) {
                double v =
                    read_comp(vp + (uint64_t)s * a->elem_size + (uint64_t)k * a->comp_size, a->ct, a->normalized);
                if (outu)
                    outu[idx * out_ncomp + k] = (uint32_t)v;
                else
                    outf[idx * out_ncomp + k] = (float)v;
            }
        }
    }
    if (outf && a->ct == CT_FLOAT) {
        for (uint64_t i = 0; i < (uint64_t)a->count * out_ncomp; i++)
            if (!isfinite(outf[i])) {
                fail(c, SV_GLTF_ERROR_FORMAT, "%s: accessor %u element %llu is not finite", path, ai,
                     (unsigned long long)(i / out_ncomp));
                return false;
            }
    }
    return true;
}

/* ---------------------------------------------------------------- images, textures, materials */

static bool parse_samplers(ctx_ *c, const cJSON *root)
{
    const cJSON *arr, *j;
    uint32_t count;
    if (!top_array(c, root, "samplers", &arr, &count)) return false;
    c->g->samplers = xcalloc(c, count, sizeof *c->g->samplers);
    if (!c->g->samplers) return false;
    c->g->sampler_count = count;
    uint32_t i = 0;
    cJSON_ArrayForEach(j, arr)
    {
        char path[48];
        snprintf(path, sizeof path, "samplers[%u]", i);
        sv_gltf_sampler *s = &c->g->samplers[i];
        uint64_t v[4];
        if (!get_uint(c, j, "magFilter", path, false, 0, 0, UINT32_MAX, &v[0]) ||
            !get_uint(c, j, "minFilter", path, false, 0, 0, UINT32_MAX, &v[1]) ||
            !get_uint(c, j, "wrapS", path, false, 10497, 0, UINT32_MAX, &v[2]) ||
            !get_uint(c, j, "wrapT", path, false, 10497, 0, UINT32_MAX, &v[3]))
            return false;
        if (v[0] && v[0] != 9728 && v[0] != 9729) {
            fail(c, SV_GLTF_ERROR_FORMAT, "%s.magFilter: %llu is not 9728 or 9729", path, (unsigned long long)v[0]);
            return false;
        }
        if (v[1] && v[1] != 9728 && v[1] != 9729 && !(v[1] >= 9984 && v[1] <= 9987)) {
            fail(c, SV_GLTF_ERROR_FORMAT, "%s.minFilter: %llu is not a glTF filter", path, (unsigned long long)v[1]);
            return false;
        }
        for (int w = 2; w < 4; w++)
            if (v[w] != 33071 && v[w] != 33648 && v[w] != 10497) {
                fail(c, SV_GLTF_ERROR_FORMAT, "%s.%s: %llu is not 33071, 33648 or 10497", path,
                     w == 2 ? "wrapS" : "wrapT", (unsigned long long)v[w]);
                return false;
            }
        s->mag_filter = (uint32_t)v[0];
        s->min_filter = (uint32_t)v[1];
        s->wrap_s = (uint32_t)v[2];
        s->wrap_t = (uint32_t)v[3];
        i++;
    }
    return true;
}

static bool parse_images(ctx_ *c, const cJSON *root)
{
    const cJSON *arr, *j;
    uint32_t count;
    if (!top_array(c, root, "images", &arr, &count)) return false;
    c->g->images = xcalloc(c, count, sizeof *c->g->images);
    if (!c->g->images) return false;
    c->g->image_count = count;
    uint32_t i = 0;
    cJSON_ArrayForEach(j, arr)
    {
        char path[48];
        snprintf(path, sizeof path, "images[%u]", i);
        sv_gltf_image *im = &c->g->images[i];
        const cJSON *uri;
        int32_t view;
        if (!get_string(c, j, "name", path, &im->name) || !get_string(c, j, "mimeType", path, &im->mime_type) ||
            !get_typed(c, j, "uri", path, cJSON_String, &uri) ||
            !get_index(c, j, "bufferView", path, false, c->view_count, "bufferViews", &view))
            return false;
        if ((uri != NULL) == (view >= 0)) {
            fail(c, SV_GLTF_ERROR_FORMAT, "%s: needs exactly one of uri and bufferView", path);
            return false;
        }
        if (view >= 0) {
            im->data = view_ptr(c, (uint32_t)view, 0);
            im->size = (size_t)c->views[view].length;
        } else if (strncmp(uri->valuestring, "data:", 5) == 0) {
            uint64_t n;
            char *mime = NULL;
            if (!decode_data_uri(c, uri->valuestring, path, &im->data, &n, &mime)) {
                free(mime);
                return false;
            }
            im->size = (size_t)n;
            if (!im->mime_type[0] && mime) {
                free(im->mime_type);
                im->mime_type = mime;
            } else {
                free(mime);
            }
        } else {
            if (!c->g->base_dir) {
                warn(c, "%s: external URI '%.200s' left unresolved (no base directory)", path, uri->valuestring);
            } else if (!(im->path = resolve_uri(c, uri->valuestring, path))) {
                return false;
            }
        }
        i++;
    }
    return true;
}

static bool parse_textures(ctx_ *c, const cJSON *root)
{
    const cJSON *arr, *j;
    uint32_t count;
    if (!top_array(c, root, "textures", &arr, &count)) return false;
    c->g->textures = xcalloc(c, count, sizeof *c->g->textures);
    if (!c->g->textures) return false;
    c->g->texture_count = count;
    uint32_t i = 0;
    cJSON_ArrayForEach(j, arr)
    {
        char path[48];
        snprintf(path, sizeof path, "textures[%u]", i);
        sv_gltf_texture *t = &c->g->textures[i];
        if (!get_string(c, j, "name", path, &t->name) ||
            !get_index(c, j, "source", path, false, c->g->image_count, "images", &t->image) ||
            !get_index(c, j, "sampler", path, false, c->g->sampler_count, "samplers", &t->sampler))
            return false;
        if (t->image < 0) warn(c, "%s: no source image (extension sources are not supported)", path);
        i++;
    }
    return true;
}

static bool parse_texref(ctx_ *c, const cJSON *obj, const char *key, const char *path, const char *scale_key,
                         sv_gltf_texture_ref *ref)
{
    const cJSON *j;
    ref->texture = -1;
    ref->texcoord = 0;
    ref->scale = 1.0f;
    if (!get_typed(c, obj, key, path, cJSON_Object, &j)) return false;
    if (!j) return true;
    char p[96];
    snprintf(p, sizeof p, "%s.%s", path, key);
    uint64_t tc;
    if (!get_index(c, j, "index", p, true, c->g->texture_count, "textures", &ref->texture) ||
        !get_uint(c, j, "texCoord", p, false, 0, 0, 255, &tc) ||
        (scale_key && !get_float(c, j, scale_key, p, false, 1.0f, -FLT_MAX, FLT_MAX, &ref->scale)))
        return false;
    ref->texcoord = (uint32_t)tc;
    if (tc > 1) warn(c, "%s: TEXCOORD_%u is not decoded (only 0 and 1)", p, ref->texcoord);
    return true;
}

static bool parse_materials(ctx_ *c, const cJSON *root)
{
    const cJSON *arr, *j;
    uint32_t count;
    if (!top_array(c, root, "materials", &arr, &count)) return false;
    c->g->materials = xcalloc(c, count, sizeof *c->g->materials);
    if (!c->g->materials) return false;
    c->g->material_count = count;
    uint32_t i = 0;
    cJSON_ArrayForEach(j, arr)
    {
        char path[48], pbr_path[80], ext_path[80];
        snprintf(path, sizeof path, "materials[%u]", i);
        snprintf(pbr_path, sizeof pbr_path, "%s.pbrMetallicRoughness", path);
        snprintf(ext_path, sizeof ext_path, "%s.extensions", path);
        sv_gltf_material *m = &c->g->materials[i];
        const float white[4] = {1, 1, 1, 1};
        memcpy(m->base_color_factor, white, sizeof white);
        const cJSON *pbr, *ext, *alpha, *schnee = NULL, *strength = NULL;
        if (!get_string(c, j, "name", path, &m->name) ||
            !get_typed(c, j, "pbrMetallicRoughness", path, cJSON_Object, &pbr) ||
            !get_typed(c, j, "extensions", path, cJSON_Object, &ext) ||
            !get_typed(c, j, "alphaMode", path, cJSON_String, &alpha) ||
            !get_float(c, j, "alphaCutoff", path, false, 0.5f, 0.0, FLT_MAX, &m->alpha_cutoff) ||
            !get_bool(c, j, "doubleSided", path, false, &m->double_sided) ||
            !get_floats(c, j, "emissiveFactor", path, 3, m->emissive_factor, NULL) ||
            !parse_texref(c, j, "normalTexture", path, "scale", &m->normal_texture) ||
            !parse_texref(c, j, "occlusionTexture", path, "strength", &m->occlusion_texture) ||
            !parse_texref(c, j, "emissiveTexture", path, NULL, &m->emissive_texture))
            return false;
        m->metallic_factor = m->roughness_factor = 1.0f;
        m->base_color_texture.texture = m->metallic_roughness_texture.texture = -1;
        m->base_color_texture.scale = m->metallic_roughness_texture.scale = 1.0f;
        if (pbr && (!get_floats(c, pbr, "baseColorFactor", pbr_path, 4, m->base_color_factor, NULL) ||
                    !get_float(c, pbr, "metallicFactor", pbr_path, false, 1.0f, 0.0, 1.0, &m->metallic_factor) ||
                    !get_float(c, pbr, "roughnessFactor", pbr_path, false, 1.0f, 0.0, 1.0, &m->roughness_factor) ||
                    !parse_texref(c, pbr, "baseColorTexture", pbr_path, NULL, &m->base_color_texture) ||
                    !parse_texref(c, pbr, "metallicRoughnessTexture", pbr_path, NULL, &m->metallic_roughness_texture)))
            return false;
        m->alpha_mode = SV_GLTF_ALPHA_OPAQUE;
        if (alpha) {
            if (strcmp(alpha->valuestring, "MASK") == 0)
                m->alpha_mode = SV_GLTF_ALPHA_MASK;
            else if (strcmp(alpha->valuestring, "BLEND") == 0)
                m->alpha_mode = SV_GLTF_ALPHA_BLEND;
            else if (strcmp(alpha->valuestring, "OPAQUE") != 0) {
                fail(c, SV_GLTF_ERROR_FORMAT, "%s.alphaMode: '%.40s' is not OPAQUE, MASK or BLEND", path,
                     alpha->valuestring);
                return false;
            }
        }
        m->emissive_strength = 1.0f;
        m->sh_scale = 1.0f;
        m->ambient_term = 0.1f;
        m->probe_mode = SV_GLTF_PROBE_MODE_OBJECT;
        if (ext && (!get_typed(c, ext, "VULKAN_SCHNEE_materials", ext_path, cJSON_Object, &schnee) ||
                    !get_typed(c, ext, "KHR_materials_emissive_strength", ext_path, cJSON_Object, &strength)))
            return false;
        if (strength) {
            char p[112];
            snprintf(p, sizeof p, "%s.KHR_materials_emissive_strength", ext_path);
            if (!get_float(c, strength, "emissiveStrength", p, false, 1.0f, 0.0, FLT_MAX, &m->emissive_strength))
                return false;
        }
        if (schnee) {
            char p[112];
            snprintf(p, sizeof p, "%s.VULKAN_SCHNEE_materials", ext_path);
            m->has_schnee = true;
            const cJSON *mode = NULL;
            if (!get_float(c, schnee, "shScale", p, false, 1.0f, -FLT_MAX, FLT_MAX, &m->sh_scale) ||
                !get_float(c, schnee, "ambientTerm", p, false, 0.1f, -FLT_MAX, FLT_MAX, &m->ambient_term) ||
                !get_typed(c, schnee, "probeMode", p, cJSON_String, &mode))
                return false;
            if (mode) {
                if (strcmp(mode->valuestring, "off") == 0)
                    m->probe_mode = SV_GLTF_PROBE_MODE_OFF;
                else if (strcmp(mode->valuestring, "pixel") == 0)
                    m->probe_mode = SV_GLTF_PROBE_MODE_PIXEL;
                else if (strcmp(mode->valuestring, "object") != 0) {
                    fail(c, SV_GLTF_ERROR_FORMAT, "%s.probeMode: '%.40s' is not off, object or pixel", p,
                         mode->valuestring);
                    return false;
                }
            }
        }
        i++;
    }
    return true;
}

/* ---------------------------------------------------------------- meshes */

/* Attribute accessor → freshly allocated float array of vertex_count * out_ncomp. */
static bool decode_attribute(ctx_ *c, const cJSON *attrs, const char *key, const char *ppath, uint32_t want_ncomp,
                             uint32_t alt_ncomp, uint32_t vertex_count, float **out)
{
    int32_t ai;
    char path[128];
    snprintf(path, sizeof path, "%s.attributes", ppath);
    *out = NULL;
    if (!get_index(c, attrs, key, path, false, c->acc_count, "accessors", &ai)) return false;
    if (ai < 0) return true;
    const accessor_ *a = &c->accs[ai];
    snprintf(path, sizeof path, "%s.attributes.%s", ppath, key);
    if (a->is_matrix || (a->ncomp != want_ncomp && a->ncomp != alt_ncomp)) {
        fail(c, SV_GLTF_ERROR_FORMAT, "%s: accessor %d has type %s, expected VEC%u", path, ai, a->type_name,
             want_ncomp);
        return false;
    }
    if (a->count != vertex_count) {
        fail(c, SV_GLTF_ERROR_FORMAT, "%s: accessor %d has count %u, POSITION has %u", path, ai, a->count,
             vertex_count);
        return false;
    }
    *out = alloc_data(c, (uint64_t)vertex_count * want_ncomp, sizeof(float), path);
    return *out && decode_accessor(c, (uint32_t)ai, path, want_ncomp, 1.0f, *out, NULL);
}

/* Re-indexes a vertex array so that vertex i is the old vertex idx[i] (un-welding). */
static bool unweld(ctx_ *c, float **arr, uint32_t ncomp, const uint32_t *idx, uint32_t n, const char *what)
{
    if (!*arr) return true;
    float *na = alloc_data(c, (uint64_t)n * ncomp, sizeof(float), what);
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
    p->normals = alloc_data(c, (uint64_t)n * 3, sizeof(float), path);
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
    if (!get_typed(c, j, "attributes", path, cJSON_Object, &attrs) ||
        !get_uint(c, j, "mode", path, false, 4, 0, 6, &mode) ||
        !get_index(c, j, "material", path, false, c->g->material_count, "materials", &p->material) ||
        !get_index(c, j, "indices", path, false, c->acc_count, "accessors", &idx_ai))
        return false;
    if (!attrs) {
        fail(c, SV_GLTF_ERROR_FORMAT, "%s.attributes: missing", path);
        return false;
    }
    char apath[128];
    snprintf(apath, sizeof apath, "%s.attributes", path);
    if (!get_index(c, attrs, "POSITION", apath, false, c->acc_count, "accessors", &pos_ai)) return false;
    if (mode < 4) {
        if (c->desc.non_triangles_are_errors) {
            fail(c, SV_GLTF_ERROR_UNSUPPORTED, "%s: mode %s is not supported (triangles only)", path, mode_names[mode]);
            return false;
        }
        warn(c, "%s: mode %s skipped (triangles only)", path, mode_names[mode]);
        *skip = true;
        return true;
    }
    if (pos_ai < 0) {
        warn(c, "%s: no POSITION attribute, skipped", path);
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
            fail(c, SV_GLTF_ERROR_FORMAT, "%s: accessor %d must be a SCALAR of unsigned byte/short/int, not normalized",
                 ipath, idx_ai);
            return false;
        }
        n = a->count;
        src = alloc_data(c, n, sizeof(uint32_t), ipath);
        if (!src || !decode_accessor(c, (uint32_t)idx_ai, ipath, 1, 0.0f, NULL, src)) {
            free(src);
            return false;
        }
        for (uint32_t i = 0; i < n; i++)
            if (src[i] >= vc) {
                fail(c, SV_GLTF_ERROR_FORMAT, "%s: index %u at position %u is out of range (%u vertices)", ipath,
                     src[i], i, vc);
                free(src);
                return false;
            }
    } else {
        n = vc;
        src = alloc_data(c, n, sizeof(uint32_t), ipath);
        if (!src) return false;
        for (uint32_t i = 0; i < n; i++) src[i] = i;
    }
    if (mode == 4) {
        if (n % 3) {
            free(src);
            fail(c, SV_GLTF_ERROR_FORMAT, "%s: %u indices is not a multiple of 3 for TRIANGLES", path, n);
            return false;
        }
        p->indices = src;
        p->index_count = n;
    } else {
        uint64_t tris = n >= 3 ? n - 2 : 0;
        p->indices = alloc_data(c, tris * 3, sizeof(uint32_t), ipath);
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

static void free_primitive(sv_gltf_primitive *p)
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

static bool parse_meshes(ctx_ *c, const cJSON *root)
{
    const cJSON *arr, *j;
    uint32_t count;
    if (!top_array(c, root, "meshes", &arr, &count)) return false;
    c->g->meshes = xcalloc(c, count, sizeof *c->g->meshes);
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
        if (!get_string(c, j, "name", path, &m->name) || !get_typed(c, j, "primitives", path, cJSON_Array, &prims))
            return false;
        int np = prims ? cJSON_GetArraySize(prims) : 0;
        if (np <= 0) {
            fail(c, SV_GLTF_ERROR_FORMAT, "%s.primitives: missing or empty", path);
            return false;
        }
        m->primitives = xcalloc(c, (uint64_t)np, sizeof *m->primitives);
        if (!m->primitives) return false;
        uint32_t pi = 0;
        cJSON_ArrayForEach(pj, prims)
        {
            char ppath[80];
            snprintf(ppath, sizeof ppath, "%s.primitives[%u]", path, pi++);
            if (!cJSON_IsObject(pj)) {
                fail(c, SV_GLTF_ERROR_FORMAT, "%s: expected an object, got %s", ppath, type_of(pj));
                return false;
            }
            sv_gltf_primitive *p = &m->primitives[m->primitive_count];
            bool skip;
            /* Count it before decoding so sv_gltf_free releases a half-decoded primitive. */
            m->primitive_count++;
            if (!parse_primitive(c, pj, ppath, p, &skip)) return false;
            if (skip) {
                free_primitive(p);
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

/* ---------------------------------------------------------------- cameras, lights */

static bool parse_cameras(ctx_ *c, const cJSON *root)
{
    const cJSON *arr, *j;
    uint32_t count;
    if (!top_array(c, root, "cameras", &arr, &count)) return false;
    c->g->cameras = xcalloc(c, count, sizeof *c->g->cameras);
    if (!c->g->cameras) return false;
    c->g->camera_count = count;
    uint32_t i = 0;
    cJSON_ArrayForEach(j, arr)
    {
        char path[48], sub[80];
        snprintf(path, sizeof path, "cameras[%u]", i);
        sv_gltf_camera *cam = &c->g->cameras[i];
        const cJSON *type, *persp, *ortho;
        if (!get_string(c, j, "name", path, &cam->name) || !get_typed(c, j, "type", path, cJSON_String, &type) ||
            !get_typed(c, j, "perspective", path, cJSON_Object, &persp) ||
            !get_typed(c, j, "orthographic", path, cJSON_Object, &ortho))
            return false;
        bool is_persp = type && strcmp(type->valuestring, "perspective") == 0;
        bool is_ortho = type && strcmp(type->valuestring, "orthographic") == 0;
        if (!is_persp && !is_ortho) {
            if (!type)
                fail(c, SV_GLTF_ERROR_FORMAT, "%s.type: missing", path);
            else
                fail(c, SV_GLTF_ERROR_FORMAT, "%s.type: '%.40s' is not perspective or orthographic", path,
                     type->valuestring);
            return false;
        }
        if ((is_persp && !persp) || (is_ortho && !ortho)) {
            fail(c, SV_GLTF_ERROR_FORMAT, "%s: type %s but no '%s' object", path, type->valuestring, type->valuestring);
            return false;
        }
        snprintf(sub, sizeof sub, "%s.%s", path, type->valuestring);
        if (is_persp) {
            cam->type = SV_GLTF_CAMERA_PERSPECTIVE;
            if (!get_float(c, persp, "yfov", sub, true, 0, 1e-6, 3.14159265, &cam->yfov) ||
                !get_float(c, persp, "znear", sub, true, 0, 1e-30, FLT_MAX, &cam->znear) ||
                !get_float(c, persp, "zfar", sub, false, 0, 0, FLT_MAX, &cam->zfar) ||
                !get_float(c, persp, "aspectRatio", sub, false, 0, 1e-6, FLT_MAX, &cam->aspect_ratio))
                return false;
        } else {
            cam->type = SV_GLTF_CAMERA_ORTHOGRAPHIC;
            if (!get_float(c, ortho, "xmag", sub, true, 0, -FLT_MAX, FLT_MAX, &cam->xmag) ||
                !get_float(c, ortho, "ymag", sub, true, 0, -FLT_MAX, FLT_MAX, &cam->ymag) ||
                !get_float(c, ortho, "znear", sub, true, 0, 0, FLT_MAX, &cam->znear) ||
                !get_float(c, ortho, "zfar", sub, true, 0, 0, FLT_MAX, &cam->zfar))
                return false;
            if (cam->xmag == 0.0f || cam->ymag == 0.0f) {
                fail(c, SV_GLTF_ERROR_FORMAT, "%s: xmag and ymag must not be zero", sub);
                return false;
            }
        }
        if (cam->zfar != 0.0f && !(cam->zfar > cam->znear)) {
            fail(c, SV_GLTF_ERROR_FORMAT, "%s: zfar %g is not greater than znear %g", sub, cam->zfar, cam->znear);
            return false;
        }
        i++;
    }
    return true;
}

static bool parse_lights(ctx_ *c, const cJSON *root)
{
    const cJSON *ext, *khr = NULL, *arr = NULL, *j;
    if (!get_typed(c, root, "extensions", "(root)", cJSON_Object, &ext)) return false;
    if (ext && !get_typed(c, ext, "KHR_lights_punctual", "extensions", cJSON_Object, &khr)) return false;
    if (khr && !get_typed(c, khr, "lights", "extensions.KHR_lights_punctual", cJSON_Array, &arr)) return false;
    if (!arr) return true;
    int count = cJSON_GetArraySize(arr);
    c->g->lights = xcalloc(c, (uint64_t)count, sizeof *c->g->lights);
    if (!c->g->lights) return false;
    c->g->light_count = (uint32_t)count;
    uint32_t i = 0;
    cJSON_ArrayForEach(j, arr)
    {
        char path[80], sub[160];
        snprintf(path, sizeof path, "KHR_lights_punctual.lights[%u]", i);
        if (!cJSON_IsObject(j)) {
            fail(c, SV_GLTF_ERROR_FORMAT, "%s: expected an object, got %s", path, type_of(j));
            return false;
        }
        sv_gltf_light *l = &c->g->lights[i];
        const cJSON *type, *spot, *lext, *schnee = NULL, *mode = NULL;
        l->color[0] = l->color[1] = l->color[2] = 1.0f;
        if (!get_string(c, j, "name", path, &l->name) || !get_typed(c, j, "type", path, cJSON_String, &type) ||
            !get_floats(c, j, "color", path, 3, l->color, NULL) ||
            !get_float(c, j, "intensity", path, false, 1.0f, 0.0, FLT_MAX, &l->intensity) ||
            !get_float(c, j, "range", path, false, 0.0f, 1e-30, FLT_MAX, &l->range) ||
            !get_typed(c, j, "spot", path, cJSON_Object, &spot) ||
            !get_typed(c, j, "extensions", path, cJSON_Object, &lext))
            return false;
        /* VULKAN_SCHNEE_light.mode (docs/export.md): absent = realtime, since a glTF from another
         * tool has no baked probes that hold the light. The message names the light, as a user
         * knows it by name rather than by index. */
        l->mode = SV_GLTF_LIGHT_MODE_REALTIME;
        snprintf(sub, sizeof sub, "%s ('%.24s').extensions", path, l->name);
        if (lext && !get_typed(c, lext, "VULKAN_SCHNEE_light", sub, cJSON_Object, &schnee)) return false;
        snprintf(sub, sizeof sub, "%s ('%.24s').extensions.VULKAN_SCHNEE_light", path, l->name);
        if (schnee && !get_typed(c, schnee, "mode", sub, cJSON_String, &mode)) return false;
        if (mode) {
            if (strcmp(mode->valuestring, "baked") == 0)
                l->mode = SV_GLTF_LIGHT_MODE_BAKED;
            else if (strcmp(mode->valuestring, "realtime") != 0) {
                fail(c, SV_GLTF_ERROR_FORMAT, "%s.mode: '%.40s' is not baked or realtime", sub, mode->valuestring);
                return false;
            }
        }
        const char *t = type ? type->valuestring : "";
        if (strcmp(t, "directional") == 0)
            l->type = SV_GLTF_LIGHT_DIRECTIONAL;
        else if (strcmp(t, "point") == 0)
            l->type = SV_GLTF_LIGHT_POINT;
        else if (strcmp(t, "spot") == 0)
            l->type = SV_GLTF_LIGHT_SPOT;
        else {
            fail(c, SV_GLTF_ERROR_FORMAT, "%s.type: '%.40s' is not directional, point or spot", path, t);
            return false;
        }
        l->inner_cone_angle = 0.0f;
        l->outer_cone_angle = (float)(SV_PI / 4.0);
        if (l->type == SV_GLTF_LIGHT_SPOT) {
            if (!spot) {
                fail(c, SV_GLTF_ERROR_FORMAT, "%s: type spot but no 'spot' object", path);
                return false;
            }
            snprintf(sub, sizeof sub, "%s.spot", path);
            if (!get_float(c, spot, "innerConeAngle", sub, false, 0.0f, 0.0, SV_PI / 2, &l->inner_cone_angle) ||
                !get_float(c, spot, "outerConeAngle", sub, false, (float)(SV_PI / 4.0), 0.0, SV_PI / 2 + 1e-6,
                           &l->outer_cone_angle))
                return false;
            if (!(l->inner_cone_angle < l->outer_cone_angle)) {
                fail(c, SV_GLTF_ERROR_FORMAT, "%s: innerConeAngle %g is not less than outerConeAngle %g", sub,
                     l->inner_cone_angle, l->outer_cone_angle);
                return false;
            }
        }
        i++;
    }
    return true;
}

/* ---------------------------------------------------------------- nodes and scene */

static bool parse_nodes(ctx_ *c, const cJSON *root)
{
    const cJSON *arr, *j;
    uint32_t count;
    sv_gltf *g = c->g;
    if (!top_array(c, root, "nodes", &arr, &count)) return false;
    g->nodes = xcalloc(c, count, sizeof *g->nodes);
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
        if (!get_string(c, j, "name", path, &n->name) ||
            !get_index(c, j, "mesh", path, false, g->mesh_count, "meshes", &n->mesh) ||
            !get_index(c, j, "camera", path, false, g->camera_count, "cameras", &n->camera) ||
            !get_typed(c, j, "children", path, cJSON_Array, &children) ||
            !get_floats(c, j, "matrix", path, 16, n->local, &n->has_matrix) ||
            !get_floats(c, j, "translation", path, 3, n->translation, &has_t) ||
            !get_floats(c, j, "rotation", path, 4, n->rotation, &has_r) ||
            !get_floats(c, j, "scale", path, 3, n->scale, &has_s) ||
            !get_typed(c, j, "extensions", path, cJSON_Object, &ext))
            return false;
        n->light = -1;
        if (ext) {
            char p[80];
            snprintf(p, sizeof p, "%s.extensions", path);
            if (!get_typed(c, ext, "KHR_lights_punctual", p, cJSON_Object, &khr)) return false;
            snprintf(p, sizeof p, "%s.extensions.KHR_lights_punctual", path);
            if (khr && !get_index(c, khr, "light", p, true, g->light_count, "lights", &n->light)) return false;
        }
        if (n->has_matrix && (has_t || has_r || has_s)) {
            fail(c, SV_GLTF_ERROR_FORMAT, "%s: has both matrix and translation/rotation/scale", path);
            return false;
        }
        if (!n->has_matrix) {
            double q2 = 0.0;
            for (int k = 0; k < 4; k++) q2 += (double)n->rotation[k] * n->rotation[k];
            if (!(q2 > 1e-12)) {
                fail(c, SV_GLTF_ERROR_FORMAT, "%s.rotation: zero quaternion", path);
                return false;
            }
            for (int k = 0; k < 4; k++) n->rotation[k] = (float)(n->rotation[k] / sqrt(q2));
            svg_mat4_from_trs(n->local, n->translation, n->rotation, n->scale);
        }
        if (children) {
            int nc = cJSON_GetArraySize(children);
            n->children = xcalloc(c, (uint64_t)nc, sizeof *n->children);
            if (!n->children) return false;
            const cJSON *e;
            cJSON_ArrayForEach(e, children)
            {
                double v = cJSON_IsNumber(e) ? e->valuedouble : -1.0;
                if (!(v >= 0.0 && v < (double)count && v == floor(v))) {
                    fail(c, SV_GLTF_ERROR_FORMAT, "%s.children[%u]: not a node index (%u nodes)", path, n->child_count,
                         count);
                    return false;
                }
                uint32_t ch = (uint32_t)v;
                if (ch == i) {
                    fail(c, SV_GLTF_ERROR_FORMAT, "%s.children: node %u is its own child (cycle)", path, ch);
                    return false;
                }
                if (g->nodes[ch].parent >= 0) {
                    fail(c, SV_GLTF_ERROR_FORMAT, "%s.children: node %u already has parent %d (or is listed twice)",
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
    uint32_t *stack = xcalloc(c, count, sizeof *stack);
    bool *seen = xcalloc(c, count, sizeof *seen);
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
            svg_mat4_mul(ch->world, n->world, ch->local);
            seen[n->children[k]] = true;
            stack[top++] = n->children[k];
        }
    }
    bool ok = true;
    for (uint32_t k = 0; k < count && ok; k++)
        if (!seen[k]) {
            fail(c, SV_GLTF_ERROR_FORMAT, "nodes[%u]: part of a cycle in the node hierarchy", k);
            ok = false;
        }
    free(stack);
    free(seen);
    return ok;
}

/* One shProbeGrids entry, checked on a scratch context so that a bad entry becomes a warning.
 * Fills pg's scalars; *uri and *name point into the JSON. */
static bool check_probe_grid(ctx_ *c, const cJSON *j, const char *gpath, sv_gltf_probe_grid *pg, const char **uri,
                             const char **name)
{
    const cJSON *u = NULL, *nm = NULL, *axes = NULL;
    uint64_t count = 0, band = 0;
    float dims[3] = {0, 0, 0};
    *uri = *name = NULL;
    if (!cJSON_IsObject(j)) {
        fail(c, SV_GLTF_ERROR_FORMAT, "%s: expected an object, got %s", gpath, type_of(j));
        return false;
    }
    if (!get_typed(c, j, "uri", gpath, cJSON_String, &u) || !get_typed(c, j, "name", gpath, cJSON_String, &nm) ||
        !get_uint(c, j, "probeCount", gpath, true, 0, 0, UINT32_MAX, &count) ||
        !get_uint(c, j, "maxBand", gpath, true, 0, 0, 4, &band) ||
        !get_floats(c, j, "gridOrigin", gpath, 3, pg->grid_origin, NULL) ||
        !get_floats(c, j, "gridDims", gpath, 3, dims, NULL) ||
        !get_float(c, j, "gridSpacing", gpath, true, 0, 1e-30, FLT_MAX, &pg->grid_spacing) ||
        !get_typed(c, j, "gridAxes", gpath, cJSON_Array, &axes))
        return false;
    const char *missing = !u ? "uri" : !get(j, "gridOrigin") ? "gridOrigin" : !get(j, "gridDims") ? "gridDims" : NULL;
    if (missing) {
        fail(c, SV_GLTF_ERROR_FORMAT, "%s.%s: missing", gpath, missing);
        return false;
    }
    for (int k = 0; k < 3; k++) {
        if (!(dims[k] >= 0.0f && dims[k] < 4294967296.0f && dims[k] == floorf(dims[k]))) {
            fail(c, SV_GLTF_ERROR_FORMAT, "%s.gridDims[%d]: %g is not a non-negative integer", gpath, k, dims[k]);
            return false;
        }
        pg->grid_dims[k] = (uint32_t)dims[k];
    }
    for (int r = 0; r < 3; r++)
        for (int k = 0; k < 3; k++) pg->grid_axes[r][k] = r == k ? 1.0f : 0.0f;
    if (axes) {
        if (cJSON_GetArraySize(axes) != 3) {
            fail(c, SV_GLTF_ERROR_FORMAT, "%s.gridAxes: expected 3 rows of 3 numbers", gpath);
            return false;
        }
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

/* The optional "sky" member, checked on a scratch context like a grid entry. */
static bool check_sky(ctx_ *c, const cJSON *j, const char *path, sv_gltf_sky *sky, const char **uri)
{
    const cJSON *u = NULL, *sh = NULL, *e;
    uint64_t band = 2;
    *uri = NULL;
    if (!cJSON_IsObject(j)) {
        fail(c, SV_GLTF_ERROR_FORMAT, "%s: expected an object, got %s", path, type_of(j));
        return false;
    }
    if (!get_typed(c, j, "uri", path, cJSON_String, &u) || !get_typed(c, j, "sh", path, cJSON_Array, &sh) ||
        !get_uint(c, j, "maxBand", path, false, 2, 0, 4, &band))
        return false;
    if (!u || !sh) {
        fail(c, SV_GLTF_ERROR_FORMAT, "%s.%s: missing", path, !u ? "uri" : "sh");
        return false;
    }
    uint32_t n = (uint32_t)((band + 1) * (band + 1));
    if (cJSON_GetArraySize(sh) != (int)n) {
        fail(c, SV_GLTF_ERROR_FORMAT, "%s.sh: expected %u RGB triples for maxBand %u, got %d", path, n, (unsigned)band,
             cJSON_GetArraySize(sh));
        return false;
    }
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

static bool parse_sky(ctx_ *c, const cJSON *props, const char *path)
{
    const cJSON *j = get(props, "sky");
    if (!j) return true;
    char spath[160];
    snprintf(spath, sizeof spath, "%s.sky", path);
    sv_gltf_error e = {0};
    ctx_ scratch = *c;
    scratch.err = &e;
    scratch.result = SV_GLTF_SUCCESS;
    sv_gltf_sky sky = {0};
    const char *uri;
    if (!check_sky(&scratch, j, spath, &sky, &uri)) {
        warn(c, "%s (sky skipped)", e.message);
        return true;
    }
    c->g->sky = sky;
    c->g->sky.present = true;
    if (!(c->g->sky.uri = xstrdup(c, uri))) return false;
    if (!c->g->base_dir)
        warn(c, "%s: URI '%.200s' left unresolved (no base directory)", spath, uri);
    else if (!(c->g->sky.path = resolve_uri(c, uri, spath)))
        return false;
    return true;
}

static bool parse_probe_grids(ctx_ *c, const cJSON *scene, const char *spath)
{
    const cJSON *ext, *props = NULL, *grids = NULL, *j;
    char path[112];
    snprintf(path, sizeof path, "%s.extensions", spath);
    if (!get_typed(c, scene, "extensions", spath, cJSON_Object, &ext)) return false;
    if (ext && !get_typed(c, ext, "VULKAN_SCHNEE_engine_properties", path, cJSON_Object, &props)) return false;
    snprintf(path, sizeof path, "%s.extensions.VULKAN_SCHNEE_engine_properties", spath);
    if (props && !get_typed(c, props, "shProbeGrids", path, cJSON_Array, &grids)) return false;
    if (props && !parse_sky(c, props, path)) return false;
    if (!grids) return true;
    c->g->probe_grids = xcalloc(c, (uint64_t)cJSON_GetArraySize(grids), sizeof *c->g->probe_grids);
    if (!c->g->probe_grids) return false;
    uint32_t i = 0;
    cJSON_ArrayForEach(j, grids)
    {
        char gpath[160];
        snprintf(gpath, sizeof gpath, "%s.shProbeGrids[%u]", path, i++);
        /* A bad entry is skipped with a warning (the engine then falls back to probe 0 there);
         * the rest of the scene still loads. */
        sv_gltf_error e = {0};
        ctx_ scratch = *c;
        scratch.err = &e;
        scratch.result = SV_GLTF_SUCCESS;
        sv_gltf_probe_grid pg = {0};
        const char *uri, *name;
        if (!check_probe_grid(&scratch, j, gpath, &pg, &uri, &name)) {
            warn(c, "%s (shProbeGrids entry skipped)", e.message);
            continue;
        }
        sv_gltf_probe_grid *dst = &c->g->probe_grids[c->g->probe_grid_count++];
        *dst = pg;
        if (!(dst->name = xstrdup(c, name)) || !(dst->uri = xstrdup(c, uri))) return false;
        if (!c->g->base_dir)
            warn(c, "%s: URI '%.200s' left unresolved (no base directory)", gpath, uri);
        else if (!(dst->path = resolve_uri(c, uri, gpath)))
            return false;
    }
    return true;
}

static bool add_instances(ctx_ *c, uint32_t root_node)
{
    sv_gltf *g = c->g;
    uint32_t *stack = xcalloc(c, g->node_count, sizeof *stack);
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

static bool parse_scene(ctx_ *c, const cJSON *root)
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
    if (!top_array(c, root, "scenes", &arr, &count) ||
        !get_index(c, root, "scene", "(root)", false, count, "scenes", &si))
        return false;
    if (count == 0) return true;
    g->scene = si >= 0 ? si : 0;
    uint32_t k = 0;
    cJSON_ArrayForEach(j, arr) if (k++ == (uint32_t)g->scene) scene = j;
    char spath[32];
    snprintf(spath, sizeof spath, "scenes[%d]", g->scene);
    const cJSON *nodes;
    if (!get_string(c, scene, "name", spath, &g->scene_name) ||
        !get_typed(c, scene, "nodes", spath, cJSON_Array, &nodes))
        return false;
    /* Every node appears at most once, so node_count bounds each instance list. */
    g->mesh_instances = xcalloc(c, g->node_count, sizeof *g->mesh_instances);
    g->camera_instances = xcalloc(c, g->node_count, sizeof *g->camera_instances);
    g->light_instances = xcalloc(c, g->node_count, sizeof *g->light_instances);
    bool *listed = xcalloc(c, g->node_count, sizeof *listed);
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
                fail(c, SV_GLTF_ERROR_FORMAT, "%s.nodes[%u]: not a node index (%u nodes)", spath, r, g->node_count);
                ok = false;
                break;
            }
            uint32_t ni = (uint32_t)v;
            if (g->nodes[ni].parent >= 0 || listed[ni]) {
                fail(c, SV_GLTF_ERROR_FORMAT, "%s.nodes[%u]: node %u %s", spath, r, ni,
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
    return ok && parse_probe_grids(c, scene, spath);
}

/* ---------------------------------------------------------------- top level */

static bool check_asset(ctx_ *c, const cJSON *root)
{
    const cJSON *asset, *version, *req;
    if (!get_typed(c, root, "asset", "(root)", cJSON_Object, &asset)) return false;
    if (!asset) {
        fail(c, SV_GLTF_ERROR_FORMAT, "asset: missing (not a glTF file?)");
        return false;
    }
    if (!get_typed(c, asset, "version", "asset", cJSON_String, &version)) return false;
    if (!version) {
        fail(c, SV_GLTF_ERROR_FORMAT, "asset.version: missing");
        return false;
    }
    if (strncmp(version->valuestring, "2.", 2) != 0) {
        fail(c, SV_GLTF_ERROR_UNSUPPORTED, "asset.version: '%.20s' is not glTF 2.x", version->valuestring);
        return false;
    }
    if (!get_typed(c, root, "extensionsRequired", "(root)", cJSON_Array, &req)) return false;
    static const char *supported[] = {"KHR_lights_punctual",     "KHR_materials_emissive_strength",
                                      "KHR_mesh_quantization",   "VULKAN_SCHNEE_engine_properties",
                                      "VULKAN_SCHNEE_materials", "VULKAN_SCHNEE_light"};
    const cJSON *e;
    uint32_t i = 0;
    if (req) cJSON_ArrayForEach(e, req)
        {
            if (!cJSON_IsString(e)) {
                fail(c, SV_GLTF_ERROR_FORMAT, "extensionsRequired[%u]: expected a string", i);
                return false;
            }
            bool ok = false;
            for (size_t k = 0; k < sizeof supported / sizeof supported[0]; k++)
                ok |= strcmp(e->valuestring, supported[k]) == 0;
            if (!ok) {
                fail(c, SV_GLTF_ERROR_UNSUPPORTED, "extensionsRequired: '%.60s' is not supported", e->valuestring);
                return false;
            }
            i++;
        }
    return true;
}

static uint32_t rd32(const uint8_t *p)
{
    return (uint32_t)p[0] | (uint32_t)p[1] << 8 | (uint32_t)p[2] << 16 | (uint32_t)p[3] << 24;
}

/* Splits a GLB into its JSON and BIN chunks (pointers into data). */
static bool parse_glb(ctx_ *c, const uint8_t *data, size_t size, const char **json, size_t *json_size)
{
    if (size < 20) {
        fail(c, SV_GLTF_ERROR_FORMAT, "GLB: %zu bytes is too short for a header and a chunk", size);
        return false;
    }
    uint32_t version = rd32(data + 4), length = rd32(data + 8);
    if (version != 2) {
        fail(c, SV_GLTF_ERROR_UNSUPPORTED, "GLB: container version %u is not 2", version);
        return false;
    }
    if (length > size || length < 20) {
        fail(c, SV_GLTF_ERROR_FORMAT, "GLB: header length %u but the data has %zu bytes (truncated?)", length, size);
        return false;
    }
    size_t pos = 12;
    uint32_t index = 0;
    *json = NULL;
    while (pos < length) {
        if (length - pos < 8) {
            fail(c, SV_GLTF_ERROR_FORMAT, "GLB: chunk %u header truncated at byte %zu", index, pos);
            return false;
        }
        uint32_t clen = rd32(data + pos), ctype = rd32(data + pos + 4);
        pos += 8;
        if (clen > length - pos) {
            fail(c, SV_GLTF_ERROR_FORMAT, "GLB: chunk %u length %u exceeds the file (%zu bytes left)", index, clen,
                 (size_t)length - pos);
            return false;
        }
        if (index == 0) {
            if (ctype != GLB_CHUNK_JSON) {
                fail(c, SV_GLTF_ERROR_FORMAT, "GLB: first chunk is not JSON (type 0x%08x)", ctype);
                return false;
            }
            *json = (const char *)data + pos;
            *json_size = clen;
        } else if (index == 1 && ctype == GLB_CHUNK_BIN) {
            c->glb_bin = data + pos;
            c->glb_bin_size = clen;
        } /* other chunks are ignored, as the spec asks */
        pos += clen;
        index++;
    }
    return true;
}

static bool load_document(ctx_ *c, const uint8_t *data, size_t size)
{
    const char *json = (const char *)data;
    size_t json_size = size;
    if (size >= 4 && rd32(data) == GLB_MAGIC) {
        c->is_glb = true;
        if (!parse_glb(c, data, size, &json, &json_size)) return false;
    }
    /* cJSON gets a NUL-terminated copy: its length-bounded parser then cannot read past the chunk
     * even on a parser bug (libcjson is not built with sanitizers). */
    if (!take_budget(c, (uint64_t)json_size + 1, "glTF JSON")) return false;
    char *text = xcalloc(c, (uint64_t)json_size + 1, 1);
    if (!text) return false;
    memcpy(text, json, json_size);
    json = text;
    const char *end = NULL;
    cJSON *root = cJSON_ParseWithLengthOpts(json, json_size, &end, false);
    if (!root) {
        size_t at = end && end >= json ? (size_t)(end - json) : 0;
        fail(c, SV_GLTF_ERROR_JSON, "%s: invalid JSON near byte %zu", c->is_glb ? "GLB JSON chunk" : "glTF", at);
        free(text);
        return false;
    }
    for (const char *p = end; p && p < json + json_size; p++)
        if (*p != ' ' && *p != '\t' && *p != '\n' && *p != '\r' && *p != '\0') {
            cJSON_Delete(root);
            fail(c, SV_GLTF_ERROR_JSON, "glTF: trailing data after the JSON value at byte %zu", (size_t)(p - json));
            free(text);
            return false;
        }
    bool ok = true;
    if (!cJSON_IsObject(root)) {
        fail(c, SV_GLTF_ERROR_FORMAT, "glTF: the JSON root is not an object");
        ok = false;
    }
    ok = ok && check_asset(c, root) && parse_buffers(c, root) && parse_views(c, root) && parse_accessors(c, root) &&
         parse_samplers(c, root) && parse_images(c, root) && parse_textures(c, root) && parse_materials(c, root) &&
         parse_meshes(c, root) && parse_cameras(c, root) && parse_lights(c, root) && parse_nodes(c, root) &&
         parse_scene(c, root);
    cJSON_Delete(root);
    free(text);
    return ok;
}

static sv_gltf_result load(const uint8_t *data, size_t size, uint8_t *owned, const char *base_dir,
                           const sv_gltf_desc *desc, sv_gltf **out, sv_gltf_error *err, uint64_t already)
{
    ctx_ c = {0};
    c.err = err;
    if (desc) c.desc = *desc;
    if (!c.desc.max_decoded_bytes) c.desc.max_decoded_bytes = 4ull << 30;
    c.budget = c.desc.max_decoded_bytes > already ? c.desc.max_decoded_bytes - already : 0;
    c.g = calloc(1, sizeof *c.g);
    struct sv_gltf_internal_ *in = calloc(1, sizeof *in);
    if (!c.g || !in) {
        free(c.g);
        free(in);
        free(owned);
        return fail(&c, SV_GLTF_ERROR_OUT_OF_MEMORY, "out of memory");
    }
    c.g->internal_ = in;
    /* The input stays alive with the handle: GLB BIN chunks and images point into it. */
    if (owned && !own_blob(&c, owned)) {
        sv_gltf_free(c.g);
        return c.result;
    }
    if (base_dir && !(c.g->base_dir = xstrdup(&c, base_dir))) {
        sv_gltf_free(c.g);
        return c.result;
    }
    bool ok = load_document(&c, data, size);
    free(c.buf_data);
    free(c.buf_size);
    free(c.views);
    free(c.accs);
    if (!ok) {
        if (c.result == SV_GLTF_SUCCESS) fail(&c, SV_GLTF_ERROR_OUT_OF_MEMORY, "out of memory");
        sv_gltf_free(c.g);
        return c.result;
    }
    *out = c.g;
    return SV_GLTF_SUCCESS;
}

sv_gltf_result sv_gltf_load_memory(const void *data, size_t size, const sv_gltf_desc *desc, sv_gltf **out,
                                   sv_gltf_error *err)
{
    ctx_ c = {0};
    c.err = err;
    if (!out || (!data && size)) return fail(&c, SV_GLTF_ERROR_INVALID_ARGUMENT, "sv_gltf_load_memory: NULL argument");
    *out = NULL;
    /* GLB chunks and embedded images point into the data, so the handle keeps its own copy. */
    uint8_t *copy = malloc(size ? size : 1);
    if (!copy) return fail(&c, SV_GLTF_ERROR_OUT_OF_MEMORY, "out of memory (%zu bytes)", size);
    if (size) memcpy(copy, data, size);
    return load(copy, size, copy, desc ? desc->base_dir : NULL, desc, out, err, size);
}

sv_gltf_result sv_gltf_load_file(const char *path, const sv_gltf_desc *desc, sv_gltf **out, sv_gltf_error *err)
{
    ctx_ c = {0};
    c.err = err;
    if (!out || !path) return fail(&c, SV_GLTF_ERROR_INVALID_ARGUMENT, "sv_gltf_load_file: NULL argument");
    *out = NULL;
    c.desc.max_decoded_bytes = desc && desc->max_decoded_bytes ? desc->max_decoded_bytes : 4ull << 30;
    c.budget = c.desc.max_decoded_bytes;
    sv_gltf tmp = {0};
    c.g = &tmp;
    uint8_t *data;
    uint64_t size;
    if (!read_file(&c, path, 0, path, &data, &size)) return c.result;
    char *dir = svg_path_dirname(path);
    if (!dir) {
        free(data);
        return fail(&c, SV_GLTF_ERROR_OUT_OF_MEMORY, "out of memory");
    }
    sv_gltf_result r = load(data, (size_t)size, data, dir, desc, out, err, size);
    free(dir);
    return r;
}

void sv_gltf_free(sv_gltf *g)
{
    if (!g) return;
    for (uint32_t i = 0; g->meshes && i < g->mesh_count; i++) {
        for (uint32_t p = 0; p < g->meshes[i].primitive_count; p++) free_primitive(&g->meshes[i].primitives[p]);
        free(g->meshes[i].primitives);
        free(g->meshes[i].name);
    }
    free(g->meshes);
    for (uint32_t i = 0; g->materials && i < g->material_count; i++) free(g->materials[i].name);
    free(g->materials);
    for (uint32_t i = 0; g->textures && i < g->texture_count; i++) free(g->textures[i].name);
    free(g->textures);
    for (uint32_t i = 0; g->images && i < g->image_count; i++) {
        free(g->images[i].name);
        free(g->images[i].path);
        free(g->images[i].mime_type);
    }
    free(g->images);
    free(g->samplers);
    for (uint32_t i = 0; g->nodes && i < g->node_count; i++) {
        free(g->nodes[i].name);
        free(g->nodes[i].children);
    }
    free(g->nodes);
    for (uint32_t i = 0; g->cameras && i < g->camera_count; i++) free(g->cameras[i].name);
    free(g->cameras);
    for (uint32_t i = 0; g->lights && i < g->light_count; i++) free(g->lights[i].name);
    free(g->lights);
    free(g->mesh_instances);
    free(g->camera_instances);
    free(g->light_instances);
    for (uint32_t i = 0; g->probe_grids && i < g->probe_grid_count; i++) {
        free(g->probe_grids[i].name);
        free(g->probe_grids[i].uri);
        free(g->probe_grids[i].path);
    }
    free(g->probe_grids);
    free(g->sky.uri);
    free(g->sky.path);
    for (uint32_t i = 0; g->warnings && i < g->warning_count; i++) free(g->warnings[i]);
    free(g->warnings);
    free(g->scene_name);
    free(g->base_dir);
    if (g->internal_) {
        for (uint32_t i = 0; i < g->internal_->blob_count; i++) free(g->internal_->blobs[i]);
        free(g->internal_->blobs);
        free(g->internal_);
    }
    free(g);
}

const char *sv_gltf_result_string(sv_gltf_result r)
{
    switch (r) {
    case SV_GLTF_SUCCESS: return "success";
    case SV_GLTF_ERROR_INVALID_ARGUMENT: return "invalid argument";
    case SV_GLTF_ERROR_IO: return "I/O error";
    case SV_GLTF_ERROR_JSON: return "invalid JSON";
    case SV_GLTF_ERROR_FORMAT: return "malformed glTF";
    case SV_GLTF_ERROR_UNSUPPORTED: return "unsupported glTF feature";
    case SV_GLTF_ERROR_TOO_LARGE: return "too large";
    case SV_GLTF_ERROR_OUT_OF_MEMORY: return "out of memory";
    default: return "unknown result";
    }
}

int32_t sv_gltf_find_camera(const sv_gltf *g, const char *name)
{
    if (!g || !name) return -1;
    for (uint32_t i = 0; i < g->camera_instance_count; i++) {
        const sv_gltf_camera_instance *ci = &g->camera_instances[i];
        if (strcmp(g->nodes[ci->node].name, name) == 0 || strcmp(g->cameras[ci->camera].name, name) == 0)
            return (int32_t)i;
    }
    return -1;
}
