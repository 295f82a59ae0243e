/* Private to engine/gltf: the load context and the helpers shared by the loader's source files
 * (not part of the API). One file per concern:
 *   sv_gltf.c            container (GLB/JSON), asset + extensionsRequired, load/free entry points
 *   sv_gltf_json.c       errors, warnings, the memory budget, typed JSON member getters, raw extensions
 *   sv_gltf_files.c      referenced files: URI resolution (folder-tree rule), non-blocking bounded reads
 *   sv_gltf_buffers.c    data: URIs, buffers, bufferViews, accessors (validated, decoded)
 *   sv_gltf_materials.c  samplers, images, textures, materials
 *   sv_gltf_meshes.c     meshes and primitives (attributes, indices, flat normals, bounds)
 *   sv_gltf_nodes.c      cameras, lights, nodes (hierarchy, world matrices), the default scene
 *   sv_gltf_util.c       percent-decoding, base64, data: URIs, paths, AABBs
 */
#ifndef SCHNEE_SV_GLTF_INTERNAL_H
#define SCHNEE_SV_GLTF_INTERNAL_H

#include "sv_gltf.h"

#include <cJSON.h>
#include <stdarg.h>

#if defined(__BYTE_ORDER__) && __BYTE_ORDER__ != __ORDER_LITTLE_ENDIAN__
#error "sv_gltf reads glTF buffers (little-endian) by memcpy; big-endian hosts are not supported"
#endif

#define SVG_MAX_WARNINGS 200u
#define SVG_PI           3.14159265358979323846

/* Blocks of memory the handle owns (buffers, decoded data URIs). */
struct sv_gltf_internal_ {
    uint8_t **blobs;
    uint32_t blob_count, blob_capacity;
    bool allow_outside_paths; /* desc.allow_outside_paths of the load */
};

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

#if defined(__GNUC__)
#define SVG_PRINTF(f, a) __attribute__((format(printf, f, a)))
#else
#define SVG_PRINTF(f, a)
#endif

/* ---- sv_gltf_json.c: errors, warnings, memory */
/* Records the first error (code + formatted message); returns code. */
sv_gltf_result svg_fail(ctx_ *c, sv_gltf_result code, const char *fmt, ...) SVG_PRINTF(3, 4);
/* Appends a warning to the handle (at most SVG_MAX_WARNINGS, then one "more than" line). */
void svg_warn(ctx_ *c, const char *fmt, ...) SVG_PRINTF(2, 3);
/* Charges `bytes` against the decoded-size budget (SV_GLTF_ERROR_TOO_LARGE when over). */
bool svg_take_budget(ctx_ *c, uint64_t bytes, const char *what);
void *svg_xcalloc(ctx_ *c, uint64_t n, size_t size);
/* Decoded arrays: budget-checked calloc of n elements of `size`. */
void *svg_alloc_data(ctx_ *c, uint64_t n, size_t size, const char *what);
char *svg_xstrdup(ctx_ *c, const char *s);
/* Hands ownership of a malloc'ed block to the handle (freed on failure). */
bool svg_own_blob(ctx_ *c, uint8_t *blob);

/* ---- sv_gltf_json.c: typed JSON members; each fails with "<path>.<key>: ..." */
const char *svg_type_of(const cJSON *j);
const cJSON *svg_get(const cJSON *obj, const char *key);
/* Optional member of a kind (cJSON_Array, cJSON_Object, else string): absent → *out NULL. */
bool svg_get_typed(ctx_ *c, const cJSON *obj, const char *key, const char *path, int kind, const cJSON **out);
/* Integer member in [lo, hi]; absent → def (or error when required). */
bool svg_get_uint(ctx_ *c, const cJSON *obj, const char *key, const char *path, bool required, uint64_t def,
                  uint64_t lo, uint64_t hi, uint64_t *out);
/* Index member referring to one of `count` `plural`; absent → -1 (or error when required). */
bool svg_get_index(ctx_ *c, const cJSON *obj, const char *key, const char *path, bool required, uint32_t count,
                   const char *plural, int32_t *out);
/* Finite number member in [lo, hi]; absent → def (or error when required). */
bool svg_get_float(ctx_ *c, const cJSON *obj, const char *key, const char *path, bool required, float def, double lo,
                   double hi, float *out);
/* JSON array `j` of exactly n finite numbers (float range) into out; `where` names it. */
bool svg_floats_of(ctx_ *c, const cJSON *j, const char *where, uint32_t n, float *out);
/* Array member of exactly n finite numbers; absent → out untouched. */
bool svg_get_floats(ctx_ *c, const cJSON *obj, const char *key, const char *path, uint32_t n, float *out,
                    bool *present);
bool svg_get_bool(ctx_ *c, const cJSON *obj, const char *key, const char *path, bool def, bool *out);
/* Optional string member duplicated into the handle ("" when absent). */
bool svg_get_string(ctx_ *c, const cJSON *obj, const char *key, const char *path, char **out);
/* Top-level array of objects (absent → NULL with count 0). */
bool svg_top_array(ctx_ *c, const cJSON *root, const char *key, const cJSON **arr, uint32_t *count);
/* The object's "extensions" (must be an object when present): every member whose name is not in
 * `consumed` (NULL-terminated; the loader parses those itself) as name + raw JSON text. */
bool svg_get_extensions(ctx_ *c, const cJSON *obj, const char *path, const char *const *consumed,
                        sv_gltf_extension **out, uint32_t *count);
void svg_free_extensions(sv_gltf_extension *ext, uint32_t count);

/* ---- sv_gltf_files.c */
/* Reads `want` bytes (want > 0; the file must have at least that many) or, want == 0, the glTF
 * file itself bounded by its header (GLB length; JSON under SV_GLTF_MAX_JSON_BYTES). Opened with
 * sv_gltf_open_regular. *out is malloc'ed. */
bool svg_read_file(ctx_ *c, const char *path, uint64_t want, const char *what, uint8_t **out, uint64_t *out_size);
/* Resolves a relative URI against the base dir (see sv_gltf_resolve_uri); *literal_percent tells
 * that a '%' without two hex digits was kept literally (the caller warns). */
char *svg_resolve_uri(ctx_ *c, const char *uri, const char *what, bool *literal_percent);

/* ---- sv_gltf_buffers.c */
/* Decodes a base64 data: URI into an owned blob. */
bool svg_decode_data_uri(ctx_ *c, const char *uri, const char *what, const uint8_t **data, uint64_t *size,
                         char **mime_out);
bool svg_parse_buffers(ctx_ *c, const cJSON *root);
bool svg_parse_views(ctx_ *c, const cJSON *root);
bool svg_parse_accessors(ctx_ *c, const cJSON *root);
uint32_t svg_comp_size(uint32_t ct);
const uint8_t *svg_view_ptr(const ctx_ *c, uint32_t view, uint64_t offset);
/* Decodes accessor `ai` into out (count * out_ncomp floats, or uint32 when outu); missing
 * components are filled with `fill`. */
bool svg_decode_accessor(ctx_ *c, uint32_t ai, const char *path, uint32_t out_ncomp, float fill, float *outf,
                         uint32_t *outu);

/* ---- sv_gltf_materials.c, sv_gltf_meshes.c, sv_gltf_nodes.c */
bool svg_parse_samplers(ctx_ *c, const cJSON *root);
bool svg_parse_images(ctx_ *c, const cJSON *root);
bool svg_parse_textures(ctx_ *c, const cJSON *root);
bool svg_parse_materials(ctx_ *c, const cJSON *root);
bool svg_parse_meshes(ctx_ *c, const cJSON *root);
void svg_free_primitive(sv_gltf_primitive *p);
bool svg_parse_cameras(ctx_ *c, const cJSON *root);
bool svg_parse_lights(ctx_ *c, const cJSON *root);
bool svg_parse_nodes(ctx_ *c, const cJSON *root);
bool svg_parse_scene(ctx_ *c, const cJSON *root);

/* ---- sv_gltf_util.c */
/* Percent-decodes a URI reference into a new string. A '%' not followed by two hex digits is kept
 * as it is (*literal_percent set: Blender's exporter writes file names unencoded); NULL on %00 or
 * out of memory. */
char *svg_percent_decode(const char *uri, bool *literal_percent);

/* Decodes standard base64 (with or without '=' padding, no whitespace). Returns false on a bad
 * character or length; *out is malloc'ed (at least 1 byte) and must be freed by the caller. */
bool svg_base64_decode(const char *text, size_t len, uint8_t **out, size_t *out_size);

/* Splits a "data:[mediatype][;base64],payload" URI: mime (may be empty) and payload pointers into
 * uri. Returns false when uri is not a data URI; *is_base64 tells the encoding. */
bool svg_parse_data_uri(const char *uri, const char **mime, size_t *mime_len, const char **payload, bool *is_base64);

/* True when uri starts with a scheme ("http:", "file:", ...) other than data:. */
bool svg_uri_has_scheme(const char *uri, char *scheme_out, size_t scheme_cap);

/* Joins dir and a relative path ("dir/rel"; rel as is when absolute or dir is empty). malloc'ed. */
char *svg_path_join(const char *dir, const char *rel);

/* Folder part of a path ("." when there is none). malloc'ed. */
char *svg_path_dirname(const char *path);

/* World AABB of a local box under m (Arvo's method: exact bounds of the 8 transformed corners). */
void svg_aabb_transform(const float m[16], const float lmin[3], const float lmax[3], float wmin[3], float wmax[3]);

#endif
