/* URI, base64, path and matrix helpers of the glTF loader. */
#include "sv_gltf_internal.h"

#include <ctype.h>
#include <math.h>
#include <stdlib.h>
#include <string.h>

static int hex_value(int ch)
{
    if (ch >= '0' && ch <= '9') return ch - '0';
    if (ch >= 'a' && ch <= 'f') return ch - 'a' + 10;
    if (ch >= 'A' && ch <= 'F') return ch - 'A' + 10;
    return -1;
}

char *svg_percent_decode(const char *uri, bool *literal_percent)
{
    *literal_percent = false;
    size_t n = strlen(uri);
    char *out = malloc(n + 1);
    if (!out) return NULL;
    size_t o = 0;
    for (size_t i = 0; i < n; i++) {
        if (uri[i] != '%') {
            out[o++] = uri[i];
            continue;
        }
        int hi = i + 1 < n ? hex_value((unsigned char)uri[i + 1]) : -1;
        int lo = i + 2 < n ? hex_value((unsigned char)uri[i + 2]) : -1;
        if (hi < 0 || lo < 0) { /* not an escape: the '%' itself (Blender writes names unencoded) */
            *literal_percent = true;
            out[o++] = '%';
            continue;
        }
        if (hi == 0 && lo == 0) {
            free(out);
            return NULL;
        }
        out[o++] = (char)(hi * 16 + lo);
        i += 2;
    }
    out[o] = '\0';
    return out;
}

static int b64_value(int ch)
{
    if (ch >= 'A' && ch <= 'Z') return ch - 'A';
    if (ch >= 'a' && ch <= 'z') return ch - 'a' + 26;
    if (ch >= '0' && ch <= '9') return ch - '0' + 52;
    if (ch == '+') return 62;
    if (ch == '/') return 63;
    return -1;
}

bool svg_base64_decode(const char *text, size_t len, uint8_t **out, size_t *out_size)
{
    *out = NULL;
    *out_size = 0;
    /* Up to two '=' of padding at the end. */
    size_t pad = 0;
    while (len > 0 && pad < 2 && text[len - 1] == '=') {
        len--;
        pad++;
    }
    if (len % 4 == 1) return false;
    if (pad && (len + pad) % 4 != 0) return false;
    size_t size = len / 4 * 3 + (len % 4 ? len % 4 - 1 : 0);
    uint8_t *buf = malloc(size ? size : 1);
    if (!buf) return false;
    uint32_t acc = 0;
    int bits = 0;
    size_t o = 0;
    for (size_t i = 0; i < len; i++) {
        int v = b64_value((unsigned char)text[i]);
        if (v < 0) {
            free(buf);
            return false;
        }
        acc = (acc << 6) | (uint32_t)v;
        bits += 6;
        if (bits >= 8) {
            bits -= 8;
            buf[o++] = (uint8_t)(acc >> bits);
            acc &= (1u << bits) - 1u;
        }
    }
    *out = buf;
    *out_size = o;
    return true;
}

bool svg_parse_data_uri(const char *uri, const char **mime, size_t *mime_len, const char **payload, bool *is_base64)
{
    if (strncmp(uri, "data:", 5) != 0) return false;
    const char *comma = strchr(uri + 5, ',');
    if (!comma) return false;
    const char *params = uri + 5;
    const char *semi = memchr(params, ';', (size_t)(comma - params));
    *mime = params;
    *mime_len = (size_t)((semi ? semi : comma) - params);
    *is_base64 = comma - params >= 7 && strncmp(comma - 7, ";base64", 7) == 0;
    *payload = comma + 1;
    return true;
}

bool svg_uri_has_scheme(const char *uri, char *scheme_out, size_t scheme_cap)
{
    /* RFC 3986: scheme = ALPHA *( ALPHA / DIGIT / "+" / "-" / "." ) ":" */
    if (!isalpha((unsigned char)uri[0])) return false;
    size_t i = 1;
    while (isalnum((unsigned char)uri[i]) || uri[i] == '+' || uri[i] == '-' || uri[i] == '.') i++;
    if (uri[i] != ':') return false;
    if (scheme_cap) {
        size_t n = i < scheme_cap - 1 ? i : scheme_cap - 1;
        memcpy(scheme_out, uri, n);
        scheme_out[n] = '\0';
    }
    return true;
}

char *svg_path_join(const char *dir, const char *rel)
{
    size_t dn = (dir && rel[0] != '/') ? strlen(dir) : 0;
    size_t rn = strlen(rel);
    char *out = malloc(dn + 1 + rn + 1);
    if (!out) return NULL;
    size_t o = 0;
    if (dn) {
        memcpy(out, dir, dn);
        o = dn;
        if (out[o - 1] != '/') out[o++] = '/';
    }
    memcpy(out + o, rel, rn + 1);
    return out;
}

char *svg_path_dirname(const char *path)
{
    const char *slash = strrchr(path, '/');
    if (!slash) {
        char *dot = malloc(2);
        if (dot) memcpy(dot, ".", 2);
        return dot;
    }
    size_t n = slash == path ? 1 : (size_t)(slash - path);
    char *out = malloc(n + 1);
    if (!out) return NULL;
    memcpy(out, path, n);
    out[n] = '\0';
    return out;
}

void svg_aabb_transform(const float m[16], const float lmin[3], const float lmax[3], float wmin[3], float wmax[3])
{
    for (int r = 0; r < 3; r++) {
        double lo = m[12 + r], hi = m[12 + r];
        for (int c = 0; c < 3; c++) {
            double a = (double)m[c * 4 + r] * lmin[c], b = (double)m[c * 4 + r] * lmax[c];
            lo += fmin(a, b);
            hi += fmax(a, b);
        }
        wmin[r] = (float)lo;
        wmax[r] = (float)hi;
    }
}
