/* Test-time generators for glTF inputs: byte buffers, base64 data URIs, GLB containers and files in
 * a temporary folder. Everything a test loads is built here at run time (no binaries in git). */
#ifndef SCHNEE_GLTF_TESTGEN_H
#define SCHNEE_GLTF_TESTGEN_H

#include "sv_gltf.h"

#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

/* Growable byte buffer. */
typedef struct tg_bin {
    uint8_t *data;
    size_t size, cap;
} tg_bin;

static inline void tg_put(tg_bin *b, const void *p, size_t n)
{
    if (b->size + n > b->cap) {
        b->cap = (b->size + n) * 2 + 64;
        b->data = realloc(b->data, b->cap);
        if (!b->data) abort();
    }
    memcpy(b->data + b->size, p, n);
    b->size += n;
}
static inline void tg_f32(tg_bin *b, float v) { tg_put(b, &v, 4); }
static inline void tg_u16(tg_bin *b, uint16_t v) { tg_put(b, &v, 2); }
static inline void tg_u32(tg_bin *b, uint32_t v) { tg_put(b, &v, 4); }
static inline void tg_u8(tg_bin *b, uint8_t v) { tg_put(b, &v, 1); }
static inline void tg_pad4(tg_bin *b, uint8_t fill)
{
    while (b->size % 4) tg_u8(b, fill);
}

/* malloc'ed "data:application/octet-stream;base64,..." of the bytes. */
static inline char *tg_data_uri(const uint8_t *p, size_t n)
{
    static const char *alpha = "ABCDEFGHIJKLMNOPQRSTUVWXYZabcdefghijklmnopqrstuvwxyz0123456789+/";
    const char *prefix = "data:application/octet-stream;base64,";
    size_t pl = strlen(prefix);
    char *out = malloc(pl + (n + 2) / 3 * 4 + 1);
    if (!out) abort();
    memcpy(out, prefix, pl);
    char *o = out + pl;
    for (size_t i = 0; i < n; i += 3) {
        uint32_t v = (uint32_t)p[i] << 16 | (i + 1 < n ? (uint32_t)p[i + 1] << 8 : 0) | (i + 2 < n ? p[i + 2] : 0);
        *o++ = alpha[v >> 18 & 63];
        *o++ = alpha[v >> 12 & 63];
        *o++ = i + 1 < n ? alpha[v >> 6 & 63] : '=';
        *o++ = i + 2 < n ? alpha[v & 63] : '=';
    }
    *o = '\0';
    return out;
}

/* Copy of tmpl with ' turned into " (JSON written readably in C) and every @KEY@ token replaced by
 * its value from the NULL-terminated key/value list. malloc'ed. */
static inline char *tg_json(const char *tmpl, const char *const *kv)
{
    size_t cap = strlen(tmpl) + 1;
    for (size_t k = 0; kv && kv[k]; k += 2) cap += strlen(kv[k + 1]) * 8; /* generous */
    char *out = malloc(cap), *o = out;
    if (!out) abort();
    for (const char *p = tmpl; *p;) {
        bool replaced = false;
        for (size_t k = 0; kv && kv[k] && *p == '@'; k += 2) {
            size_t kl = strlen(kv[k]);
            if (strncmp(p + 1, kv[k], kl) == 0 && p[1 + kl] == '@') {
                size_t vl = strlen(kv[k + 1]);
                memcpy(o, kv[k + 1], vl);
                o += vl;
                p += kl + 2;
                replaced = true;
                break;
            }
        }
        if (!replaced) *o++ = *p == '\'' ? '"' : *p, p++;
    }
    *o = '\0';
    return out;
}

/* GLB container: 12-byte header, JSON chunk padded with spaces, optional BIN chunk padded with 0. */
static inline tg_bin tg_glb(const char *json, const tg_bin *bin)
{
    tg_bin g = {0};
    size_t jl = strlen(json), jpad = (4 - jl % 4) % 4;
    size_t bl = bin ? bin->size : 0, bpad = (4 - bl % 4) % 4;
    uint32_t total = (uint32_t)(12 + 8 + jl + jpad + (bin ? 8 + bl + bpad : 0));
    tg_u32(&g, 0x46546C67u);
    tg_u32(&g, 2);
    tg_u32(&g, total);
    tg_u32(&g, (uint32_t)(jl + jpad));
    tg_u32(&g, 0x4E4F534Au);
    tg_put(&g, json, jl);
    for (size_t i = 0; i < jpad; i++) tg_u8(&g, ' ');
    if (bin) {
        tg_u32(&g, (uint32_t)(bl + bpad));
        tg_u32(&g, 0x004E4942u);
        if (bl) tg_put(&g, bin->data, bl);
        for (size_t i = 0; i < bpad; i++) tg_u8(&g, 0);
    }
    return g;
}

/* A fresh temporary folder (malloc'ed path). */
static inline char *tg_tmpdir(void)
{
    char tmpl[] = "/tmp/sv_gltf_test_XXXXXX";
    char *d = mkdtemp(tmpl);
    if (!d) abort();
    char *out = malloc(strlen(d) + 1);
    if (!out) abort();
    strcpy(out, d);
    return out;
}

/* Writes bytes to dir/name; returns the malloc'ed full path. */
static inline char *tg_write(const char *dir, const char *name, const void *p, size_t n)
{
    char *path = malloc(strlen(dir) + strlen(name) + 2);
    if (!path) abort();
    sprintf(path, "%s/%s", dir, name);
    FILE *f = fopen(path, "wb");
    if (!f) abort();
    if (n && fwrite(p, 1, n, f) != n) abort();
    fclose(f);
    return path;
}

static inline void tg_remove(const char *dir, const char *name)
{
    char path[512];
    snprintf(path, sizeof path, "%s/%s", dir, name);
    remove(path);
}

#endif
