/* Private to engine/gltf: helpers shared by the loader's source files (not part of the API). */
#ifndef SCHNEE_SV_GLTF_INTERNAL_H
#define SCHNEE_SV_GLTF_INTERNAL_H

#include "sv_gltf.h"

#include <stdarg.h>

#if defined(__BYTE_ORDER__) && __BYTE_ORDER__ != __ORDER_LITTLE_ENDIAN__
#error "sv_gltf reads glTF buffers (little-endian) by memcpy; big-endian hosts are not supported"
#endif

/* Blocks of memory the handle owns (buffers, decoded data URIs). */
struct sv_gltf_internal_ {
    uint8_t **blobs;
    uint32_t blob_count, blob_capacity;
};

/* Percent-decodes a URI reference into a new string; NULL on a malformed escape or %00. */
char *svg_percent_decode(const char *uri);

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

/* 4x4 column-major helpers. */
void svg_mat4_identity(float m[16]);
void svg_mat4_mul(float out[16], const float a[16], const float b[16]); /* out = a * b */
void svg_mat4_from_trs(float m[16], const float t[3], const float r[4], const float s[3]);
/* World AABB of a local box under m (Arvo's method: exact bounds of the 8 transformed corners). */
void svg_aabb_transform(const float m[16], const float lmin[3], const float lmax[3], float wmin[3], float wmax[3]);

#endif
