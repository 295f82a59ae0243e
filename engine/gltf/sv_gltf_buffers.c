/* Loader: data: URIs, buffers, bufferViews, accessors. */
#include "sv_gltf_internal.h"

#include <float.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

/* ---------------------------------------------------------------- data: URIs */

/* Decodes a base64 data: URI into an owned blob. */
bool svg_decode_data_uri(ctx_ *c, const char *uri, const char *what, const uint8_t **data, uint64_t *size,
                         char **mime_out)
{
    const char *mime, *payload;
    size_t mime_len;
    bool b64;
    if (!svg_parse_data_uri(uri, &mime, &mime_len, &payload, &b64)) {
        svg_fail(c, SV_GLTF_ERROR_FORMAT, "%s: malformed data: URI (no ',')", what);
        return false;
    }
    if (!b64) {
        svg_fail(c, SV_GLTF_ERROR_UNSUPPORTED, "%s: data: URI is not base64-encoded", what);
        return false;
    }
    size_t plen = strlen(payload);
    if (!svg_take_budget(c, plen / 4 * 3 + 3, what)) return false;
    uint8_t *bytes;
    size_t n;
    if (!svg_base64_decode(payload, plen, &bytes, &n)) {
        svg_fail(c, SV_GLTF_ERROR_FORMAT, "%s: invalid base64 in data: URI", what);
        return false;
    }
    if (!svg_own_blob(c, bytes)) return false;
    *data = bytes;
    *size = n;
    if (mime_out) {
        *mime_out = svg_xcalloc(c, mime_len + 1, 1);
        if (!*mime_out) return false;
        memcpy(*mime_out, mime, mime_len);
    }
    return true;
}

/* ---------------------------------------------------------------- buffers, views, accessors */

bool svg_parse_buffers(ctx_ *c, const cJSON *root)
{
    const cJSON *arr, *b;
    if (!svg_top_array(c, root, "buffers", &arr, &c->buf_count)) return false;
    c->buf_data = svg_xcalloc(c, c->buf_count, sizeof *c->buf_data);
    c->buf_size = svg_xcalloc(c, c->buf_count, sizeof *c->buf_size);
    if (!c->buf_data || !c->buf_size) return false;
    uint32_t i = 0;
    cJSON_ArrayForEach(b, arr)
    {
        char path[48];
        snprintf(path, sizeof path, "buffers[%u]", i);
        uint64_t len;
        const cJSON *uri;
        if (!svg_get_uint(c, b, "byteLength", path, true, 0, 1, (1ull << 53), &len) ||
            !svg_get_typed(c, b, "uri", path, cJSON_String, &uri))
            return false;
        if (!uri) {
            if (i != 0 || !c->is_glb || !c->glb_bin) {
                svg_fail(c, SV_GLTF_ERROR_FORMAT, "%s: no uri and no GLB binary chunk to refer to", path);
                return false;
            }
            if (c->glb_bin_size < len || c->glb_bin_size - len > 3) {
                svg_fail(c, SV_GLTF_ERROR_FORMAT, "%s: byteLength %llu does not match the GLB BIN chunk (%zu bytes)",
                         path, (unsigned long long)len, c->glb_bin_size);
                return false;
            }
            c->buf_data[i] = c->glb_bin;
        } else if (strncmp(uri->valuestring, "data:", 5) == 0) {
            uint64_t n;
            if (!svg_decode_data_uri(c, uri->valuestring, path, &c->buf_data[i], &n, NULL)) return false;
            if (n < len) {
                svg_fail(c, SV_GLTF_ERROR_FORMAT, "%s: data: URI holds %llu bytes, byteLength is %llu", path,
                         (unsigned long long)n, (unsigned long long)len);
                return false;
            }
        } else {
            bool literal;
            char *file = svg_resolve_uri(c, uri->valuestring, path, &literal);
            if (!file) return false;
            if (literal)
                svg_warn(c, "%s: URI '%.200s' has a '%%' that is not a %%XX escape; taken literally", path,
                         uri->valuestring);
            uint8_t *data;
            uint64_t n;
            bool ok = svg_read_file(c, file, len, path, &data, &n);
            free(file);
            if (!ok || !svg_own_blob(c, data)) return false;
            c->buf_data[i] = data;
        }
        c->buf_size[i] = len;
        i++;
    }
    return true;
}

bool svg_parse_views(ctx_ *c, const cJSON *root)
{
    const cJSON *arr, *v;
    if (!svg_top_array(c, root, "bufferViews", &arr, &c->view_count)) return false;
    c->views = svg_xcalloc(c, c->view_count, sizeof *c->views);
    if (!c->views) return false;
    uint32_t i = 0;
    cJSON_ArrayForEach(v, arr)
    {
        char path[48];
        snprintf(path, sizeof path, "bufferViews[%u]", i);
        view_ *w = &c->views[i];
        int32_t buffer;
        uint64_t stride;
        if (!svg_get_index(c, v, "buffer", path, true, c->buf_count, "buffers", &buffer) ||
            !svg_get_uint(c, v, "byteOffset", path, false, 0, 0, (1ull << 53), &w->offset) ||
            !svg_get_uint(c, v, "byteLength", path, true, 0, 1, (1ull << 53), &w->length) ||
            !svg_get_uint(c, v, "byteStride", path, false, 0, 4, 252, &stride))
            return false;
        if (stride % 4) {
            svg_fail(c, SV_GLTF_ERROR_FORMAT, "%s.byteStride: %llu is not a multiple of 4", path,
                     (unsigned long long)stride);
            return false;
        }
        w->buffer = (uint32_t)buffer;
        w->stride = (uint32_t)stride;
        uint64_t size = c->buf_size[buffer];
        if (w->offset > size || w->length > size - w->offset) {
            svg_fail(c, SV_GLTF_ERROR_FORMAT, "%s: byteOffset %llu + byteLength %llu exceeds buffer %d (%llu bytes)",
                     path, (unsigned long long)w->offset, (unsigned long long)w->length, buffer,
                     (unsigned long long)size);
            return false;
        }
        i++;
    }
    return true;
}

uint32_t svg_comp_size(uint32_t ct)
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
        svg_fail(c, SV_GLTF_ERROR_FORMAT, "%s: needs bytes [%llu, %llu) of bufferView %u, which has %llu bytes", path,
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
    if (!svg_get_uint(c, sp, "count", path, true, 0, 1, a->count, &count) ||
        !svg_get_typed(c, sp, "indices", path, cJSON_Object, &idx) ||
        !svg_get_typed(c, sp, "values", path, cJSON_Object, &val))
        return false;
    if (!idx || !val) {
        svg_fail(c, SV_GLTF_ERROR_FORMAT, "%s: %s missing", path, idx ? "values" : "indices");
        return false;
    }
    snprintf(ipath, sizeof ipath, "%s.indices", path);
    snprintf(vpath, sizeof vpath, "%s.values", path);
    int32_t iv, vv;
    if (!svg_get_index(c, idx, "bufferView", ipath, true, c->view_count, "bufferViews", &iv) ||
        !svg_get_uint(c, idx, "byteOffset", ipath, false, 0, 0, (1ull << 53), &a->sp_idx_off) ||
        !svg_get_uint(c, idx, "componentType", ipath, true, 0, 0, UINT32_MAX, &ct) ||
        !svg_get_index(c, val, "bufferView", vpath, true, c->view_count, "bufferViews", &vv) ||
        !svg_get_uint(c, val, "byteOffset", vpath, false, 0, 0, (1ull << 53), &a->sp_val_off))
        return false;
    if (ct != CT_UBYTE && ct != CT_USHORT && ct != CT_UINT) {
        svg_fail(c, SV_GLTF_ERROR_FORMAT, "%s.componentType: %llu is not 5121, 5123 or 5125", ipath,
                 (unsigned long long)ct);
        return false;
    }
    a->sparse = true;
    a->sp_count = (uint32_t)count;
    a->sp_idx_ct = (uint32_t)ct;
    a->sp_idx_view = (uint32_t)iv;
    a->sp_val_view = (uint32_t)vv;
    return check_in_view(c, ipath, a->sp_idx_view, a->sp_idx_off, count * svg_comp_size((uint32_t)ct)) &&
           check_in_view(c, vpath, a->sp_val_view, a->sp_val_off, count * a->elem_size);
}

bool svg_parse_accessors(ctx_ *c, const cJSON *root)
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
    if (!svg_top_array(c, root, "accessors", &arr, &c->acc_count)) return false;
    c->accs = svg_xcalloc(c, c->acc_count, sizeof *c->accs);
    if (!c->accs) return false;
    uint32_t i = 0;
    cJSON_ArrayForEach(j, arr)
    {
        char path[48];
        snprintf(path, sizeof path, "accessors[%u]", i);
        accessor_ *a = &c->accs[i];
        uint64_t ct, count;
        const cJSON *type, *sp;
        if (!svg_get_index(c, j, "bufferView", path, false, c->view_count, "bufferViews", &a->view) ||
            !svg_get_uint(c, j, "byteOffset", path, false, 0, 0, (1ull << 53), &a->offset) ||
            !svg_get_uint(c, j, "componentType", path, true, 0, 0, UINT32_MAX, &ct) ||
            !svg_get_uint(c, j, "count", path, true, 0, 1, UINT32_MAX, &count) ||
            !svg_get_bool(c, j, "normalized", path, false, &a->normalized) ||
            !svg_get_typed(c, j, "type", path, cJSON_String, &type) ||
            !svg_get_typed(c, j, "sparse", path, cJSON_Object, &sp))
            return false;
        a->ct = (uint32_t)ct;
        a->count = (uint32_t)count;
        a->comp_size = svg_comp_size(a->ct);
        if (!a->comp_size) {
            svg_fail(c, SV_GLTF_ERROR_FORMAT, "%s.componentType: %llu is not a glTF component type", path,
                     (unsigned long long)ct);
            return false;
        }
        if (a->normalized && (a->ct == CT_FLOAT || a->ct == CT_UINT)) {
            svg_fail(c, SV_GLTF_ERROR_FORMAT, "%s: normalized is not allowed with componentType %u", path, a->ct);
            return false;
        }
        if (!type) {
            svg_fail(c, SV_GLTF_ERROR_FORMAT, "%s.type: missing", path);
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
            svg_fail(c, SV_GLTF_ERROR_FORMAT, "%s.type: '%.40s' is not SCALAR, VEC2..4 or MAT2..4", path,
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
                svg_fail(c, SV_GLTF_ERROR_FORMAT, "%s: byteOffset without bufferView", path);
                return false;
            }
        } else {
            const view_ *v = &c->views[a->view];
            if (a->offset % a->comp_size) {
                svg_fail(c, SV_GLTF_ERROR_FORMAT, "%s: byteOffset %llu is not a multiple of the component size %u",
                         path, (unsigned long long)a->offset, a->comp_size);
                return false;
            }
            a->stride = v->stride ? v->stride : a->elem_size;
            if (a->stride < a->elem_size) {
                svg_fail(c, SV_GLTF_ERROR_FORMAT,
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

const uint8_t *svg_view_ptr(const ctx_ *c, uint32_t view, uint64_t offset)
{
    const view_ *v = &c->views[view];
    return c->buf_data[v->buffer] + v->offset + offset;
}

/* Decodes accessor `ai` into out (count * out_ncomp floats, or uint32 when outu). Source components
 * beyond out_ncomp never exist (callers check the type); missing ones are filled with `fill`. */
bool svg_decode_accessor(ctx_ *c, uint32_t ai, const char *path, uint32_t out_ncomp, float fill, float *outf,
                         uint32_t *outu)
{
    const accessor_ *a = &c->accs[ai];
    uint32_t n = a->ncomp;
    for (uint32_t i = 0; i < a->count; i++) {
        for (uint32_t k = 0; k < out_ncomp; k++) {
            double v = k < n ? 0.0 : fill;
            if (k < n && a->view >= 0)
                v = read_comp(svg_view_ptr(c, (uint32_t)a->view,
                                           a->offset + (uint64_t)i * a->stride + (uint64_t)k * a->comp_size),
                              a->ct, a->normalized);
            if (outu)
                outu[(uint64_t)i * out_ncomp + k] = (uint32_t)v;
            else
                outf[(uint64_t)i * out_ncomp + k] = (float)v;
        }
    }
    if (a->sparse) {
        const uint8_t *ip = svg_view_ptr(c, a->sp_idx_view, a->sp_idx_off);
        const uint8_t *vp = svg_view_ptr(c, a->sp_val_view, a->sp_val_off);
        uint32_t isz = svg_comp_size(a->sp_idx_ct);
        uint64_t prev = 0;
        for (uint32_t s = 0; s < a->sp_count; s++) {
            uint64_t idx = (uint64_t)read_comp(ip + (uint64_t)s * isz, a->sp_idx_ct, false);
            if (idx >= a->count || (s > 0 && idx <= prev)) {
                svg_fail(c, SV_GLTF_ERROR_FORMAT, "%s: accessors[%u].sparse.indices[%u] = %llu is %s", path, ai, s,
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
                svg_fail(c, SV_GLTF_ERROR_FORMAT, "%s: accessor %u element %llu is not finite", path, ai,
                         (unsigned long long)(i / out_ncomp));
                return false;
            }
    }
    return true;
}
