/* Sky loading, GGX prefiltering and the BRDF lookup table (see sv_sky.h). */
#include "sv_sky.h"

#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

#include "schnee/pb_image.h"

#define SV_PI 3.14159265358979323846

static float radical_inverse(uint32_t b)
{
    b = (b << 16u) | (b >> 16u);
    b = ((b & 0x55555555u) << 1u) | ((b & 0xAAAAAAAAu) >> 1u);
    b = ((b & 0x33333333u) << 2u) | ((b & 0xCCCCCCCCu) >> 2u);
    b = ((b & 0x0F0F0F0Fu) << 4u) | ((b & 0xF0F0F0F0u) >> 4u);
    b = ((b & 0x00FF00FFu) << 8u) | ((b & 0xFF00FF00u) >> 8u);
    return (float)b * 2.3283064365386963e-10f;
}

/* GGX half vector for sample (u1, u2) in the frame of unit n (Karis 2013). */
static void ggx_half(float u1, float u2, float alpha, const float n[3], float h[3])
{
    float phi = 2.0f * (float)SV_PI * u2;
    float denom = 1.0f + (alpha * alpha - 1.0f) * u1;
    float cos_t = denom > 0.0f ? sqrtf((1.0f - u1) / denom) : 1.0f;
    float sin_t = sqrtf(fmaxf(0.0f, 1.0f - cos_t * cos_t));
    float hx = sin_t * cosf(phi), hy = sin_t * sinf(phi), hz = cos_t;
    float up[3] = {0, 0, 1};
    if (fabsf(n[2]) > 0.999f) up[0] = 1, up[2] = 0;
    float tx[3] = {up[1] * n[2] - up[2] * n[1], up[2] * n[0] - up[0] * n[2], up[0] * n[1] - up[1] * n[0]};
    float tl = sqrtf(tx[0] * tx[0] + tx[1] * tx[1] + tx[2] * tx[2]);
    for (int k = 0; k < 3; ++k) tx[k] /= tl;
    float ty[3] = {n[1] * tx[2] - n[2] * tx[1], n[2] * tx[0] - n[0] * tx[2], n[0] * tx[1] - n[1] * tx[0]};
    for (int k = 0; k < 3; ++k) h[k] = tx[k] * hx + ty[k] * hy + n[k] * hz;
}

static float g1_schlick(float x, float k) { return x / (x * (1.0f - k) + k); }

float *sv_brdf_lut(uint32_t size, uint32_t samples)
{
    float *lut = malloc((size_t)size * size * 2 * sizeof(float));
    float *hs = malloc((size_t)samples * 3 * sizeof(float)); /* the row's half vectors, n = +z */
    if (!lut || !hs) {
        free(lut);
        free(hs);
        return NULL;
    }
    const float n[3] = {0, 0, 1};
    for (uint32_t j = 0; j < size; ++j) {
        float rough = ((float)j + 0.5f) / (float)size;
        float alpha = rough * rough, k = alpha / 2.0f;
        for (uint32_t s = 0; s < samples; ++s)
            ggx_half((float)s / (float)samples, radical_inverse(s), alpha, n, hs + 3 * s);
        for (uint32_t i = 0; i < size; ++i) {
            float nv = ((float)i + 0.5f) / (float)size;
            float v[3] = {sqrtf(1.0f - nv * nv), 0.0f, nv};
            double a = 0.0, b = 0.0;
            for (uint32_t s = 0; s < samples; ++s) {
                const float *h = hs + 3 * s;
                float vh = v[0] * h[0] + v[1] * h[1] + v[2] * h[2];
                float nl = 2 * vh * h[2] - v[2], nh = h[2];
                if (nl <= 0.0f || vh <= 0.0f) continue;
                float g = g1_schlick(nl, k) * g1_schlick(nv, k);
                float gv = g * vh / (nh * nv);
                float x = 1.0f - vh, x2 = x * x;
                float fc = x2 * x2 * x;
                a += (1.0 - fc) * gv;
                b += fc * gv;
            }
            lut[((size_t)j * size + i) * 2 + 0] = (float)(a / samples);
            lut[((size_t)j * size + i) * 2 + 1] = (float)(b / samples);
        }
    }
    free(hs);
    return lut;
}

/* Bilinear equirect fetch of level `l` of a pyramid (rgba rows), u wraps, v clamps. */
static void sample_level(const float *rgba, uint32_t w, uint32_t h, float u, float v, float out[3])
{
    float x = u * (float)w - 0.5f, y = v * (float)h - 0.5f;
    float fx = floorf(x), fy = floorf(y);
    float tx = x - fx, ty = y - fy;
    int x0 = (int)fx, y0 = (int)fy;
    out[0] = out[1] = out[2] = 0.0f;
    for (int dy = 0; dy < 2; ++dy)
        for (int dx = 0; dx < 2; ++dx) {
            int xi = ((x0 + dx) % (int)w + (int)w) % (int)w;
            int yi = y0 + dy < 0 ? 0 : y0 + dy >= (int)h ? (int)h - 1 : y0 + dy;
            float wgt = (dx ? tx : 1 - tx) * (dy ? ty : 1 - ty);
            const float *p = rgba + ((size_t)yi * w + (size_t)xi) * 4;
            for (int c = 0; c < 3; ++c) out[c] += wgt * p[c];
        }
}

static void dir_to_uv(const float d[3], float *u, float *v)
{
    float phi = atan2f(-d[2], d[0]);
    *u = ((float)SV_PI - phi) / (2.0f * (float)SV_PI);
    float y = d[1] < -1.0f ? -1.0f : d[1] > 1.0f ? 1.0f : d[1];
    *v = acosf(y) / (float)SV_PI;
}

static void uv_to_dir(float u, float v, float d[3])
{
    /* Inverse of dir_to_uv: Blender (sin t cos p, sin t sin p, cos t) -> engine (x, z, -y). */
    float phi = (float)SV_PI - 2.0f * (float)SV_PI * u, th = (float)SV_PI * v;
    d[0] = sinf(th) * cosf(phi);
    d[1] = cosf(th);
    d[2] = -sinf(th) * sinf(phi);
}

void sv_sky_sample(const sv_sky *sky, uint32_t level, const float dir[3], float out[3])
{
    float u, v;
    dir_to_uv(dir, &u, &v);
    sample_level(sky->rgba[level], sky->width[level], sky->height[level], u, v, out);
}

typedef struct pyramid {
    uint32_t count;
    uint32_t w[16], h[16];
    float *rgba[16];
} pyramid;

/* Box-filtered source pyramid for filtered importance sampling. */
static bool build_pyramid(const float *rgba, uint32_t w, uint32_t h, pyramid *p)
{
    memset(p, 0, sizeof(*p));
    p->w[0] = w, p->h[0] = h;
    p->rgba[0] = (float *)rgba; /* borrowed */
    p->count = 1;
    while (p->count < 16 && p->w[p->count - 1] > 1 && p->h[p->count - 1] > 1) {
        uint32_t l = p->count, pw = p->w[l - 1], ph = p->h[l - 1];
        uint32_t nw = pw / 2, nh = ph / 2;
        float *dst = malloc((size_t)nw * nh * 4 * sizeof(float));
        if (!dst) return false;
        for (uint32_t y = 0; y < nh; ++y)
            for (uint32_t x = 0; x < nw; ++x)
                for (int c = 0; c < 4; ++c) {
                    const float *s = p->rgba[l - 1];
                    dst[((size_t)y * nw + x) * 4 + c] = 0.25f * (s[((size_t)(2 * y) * pw + 2 * x) * 4 + c] +
                                                                 s[((size_t)(2 * y) * pw + 2 * x + 1) * 4 + c] +
                                                                 s[((size_t)(2 * y + 1) * pw + 2 * x) * 4 + c] +
                                                                 s[((size_t)(2 * y + 1) * pw + 2 * x + 1) * 4 + c]);
                }
        p->rgba[l] = dst, p->w[l] = nw, p->h[l] = nh;
        p->count++;
    }
    return true;
}

static void sample_pyramid(const pyramid *p, float lod, const float d[3], float out[3])
{
    float u, v;
    dir_to_uv(d, &u, &v);
    if (lod < 0) lod = 0;
    if (lod > (float)(p->count - 1)) lod = (float)(p->count - 1);
    uint32_t l0 = (uint32_t)lod, l1 = l0 + 1 < p->count ? l0 + 1 : l0;
    float t = lod - (float)l0, a[3], b[3];
    sample_level(p->rgba[l0], p->w[l0], p->h[l0], u, v, a);
    sample_level(p->rgba[l1], p->w[l1], p->h[l1], u, v, b);
    for (int c = 0; c < 3; ++c) out[c] = a[c] + t * (b[c] - a[c]);
}

/* Level `level` of the prefiltered chain: N = V = R, GGX lobe of roughness r. */
static void prefilter_level(const pyramid *src, float rough, uint32_t w, uint32_t h, float *dst)
{
    float alpha = rough * rough;
    uint32_t texels = w * h;
    uint32_t samples = texels ? 4000000u / texels : 64u;
    samples = samples < 32u ? 32u : samples > 256u ? 256u : samples;
    float omega_p = 4.0f * (float)SV_PI / ((float)src->w[0] * (float)src->h[0]);
    for (uint32_t y = 0; y < h; ++y)
        for (uint32_t x = 0; x < w; ++x) {
            float n[3];
            uv_to_dir(((float)x + 0.5f) / (float)w, ((float)y + 0.5f) / (float)h, n);
            double acc[3] = {0, 0, 0}, wsum = 0;
            for (uint32_t s = 0; s < samples; ++s) {
                float hv[3];
                ggx_half((float)s / (float)samples, radical_inverse(s), alpha, n, hv);
                float nh = n[0] * hv[0] + n[1] * hv[1] + n[2] * hv[2];
                float l[3] = {2 * nh * hv[0] - n[0], 2 * nh * hv[1] - n[1], 2 * nh * hv[2] - n[2]};
                float nl = n[0] * l[0] + n[1] * l[1] + n[2] * l[2];
                if (nl <= 0.0f) continue;
                float a2 = alpha * alpha, dd = nh * nh * (a2 - 1.0f) + 1.0f;
                float D = a2 / ((float)SV_PI * dd * dd);
                float pdf = D / 4.0f; /* D * NoH / (4 VoH) with N = V */
                float omega_s = 1.0f / ((float)samples * pdf + 1e-6f);
                float lod = 0.5f * log2f(omega_s / omega_p) + 1.0f;
                float c[3];
                sample_pyramid(src, lod, l, c);
                for (int k = 0; k < 3; ++k) acc[k] += c[k] * nl;
                wsum += nl;
            }
            float *o = dst + ((size_t)y * w + x) * 4;
            for (int k = 0; k < 3; ++k) o[k] = wsum > 0 ? (float)(acc[k] / wsum) : 0.0f;
            o[3] = 1.0f;
        }
}

/* Width and height from an OpenEXR header (the first part's dataWindow, box2i) in buf[0, n). */
static bool exr_dims(const unsigned char *buf, size_t n, uint64_t *w, uint64_t *h)
{
    size_t p = 8; /* magic, version + flags */
    while (p < n && buf[p]) {
        const unsigned char *name = buf + p;
        const unsigned char *e = memchr(name, 0, n - p);
        if (!e) return false;
        size_t q = (size_t)(e - buf) + 1;
        const unsigned char *type = q < n ? memchr(buf + q, 0, n - q) : NULL;
        if (!type) return false;
        q = (size_t)(type - buf) + 1;
        if (n - q < 4) return false;
        uint32_t size =
            (uint32_t)buf[q] | (uint32_t)buf[q + 1] << 8 | (uint32_t)buf[q + 2] << 16 | (uint32_t)buf[q + 3] << 24;
        q += 4;
        if (size > n - q) return false;
        if (strcmp((const char *)name, "dataWindow") == 0 && size == 16) {
            int32_t v[4];
            for (int k = 0; k < 4; ++k)
                v[k] = (int32_t)((uint32_t)buf[q + 4 * k] | (uint32_t)buf[q + 4 * k + 1] << 8 |
                                 (uint32_t)buf[q + 4 * k + 2] << 16 | (uint32_t)buf[q + 4 * k + 3] << 24);
            if (v[2] < v[0] || v[3] < v[1]) return false;
            *w = (uint64_t)((int64_t)v[2] - v[0] + 1);
            *h = (uint64_t)((int64_t)v[3] - v[1] + 1);
            return true;
        }
        p = q + size;
    }
    return false;
}

bool sv_image_file_check(const char *path, const char *what, uint64_t max_pixels, char *msg, size_t cap)
{
    sv_gltf_error err = {0};
    uint64_t size = 0;
    int fd = sv_gltf_open_regular(path, what, SV_MAX_IMAGE_FILE_BYTES, &size, &err);
    if (fd < 0) {
        snprintf(msg, cap, "%s", err.message);
        return false;
    }
    static unsigned char h[1 << 16]; /* the header: signature, and the EXR attributes / PNG IHDR */
    ssize_t got = read(fd, h, sizeof h);
    close(fd);
    size_t n = got > 0 ? (size_t)got : 0;
    static const struct {
        const char *sig;
        size_t len;
    } sigs[] = {
        {"\x76\x2f\x31\x01", 4},  /* OpenEXR */
        {"\x89PNG\r\n\x1a\n", 8}, /* PNG */
        {"\xff\xd8\xff", 3},      /* JPEG */
        {"#?", 2},                /* Radiance HDR */
        {"II*\0", 4},             /* TIFF little-endian */
        {"MM\0*", 4},             /* TIFF big-endian */
        {"BM", 2},                /* BMP */
        {"GIF8", 4},              /* GIF */
        {"RIFF", 4},              /* WebP */
    };
    int kind = -1;
    for (size_t k = 0; k < sizeof sigs / sizeof sigs[0] && kind < 0; ++k)
        if (n >= sigs[k].len && memcmp(h, sigs[k].sig, sigs[k].len) == 0) kind = (int)k;
    /* PNM / PFM: 'P' then 1-7, F or f, then whitespace. */
    bool ok = kind >= 0 || (n >= 3 && h[0] == 'P' && h[1] && strchr("1234567Ff", h[1]) &&
                            (h[2] == '\n' || h[2] == ' ' || h[2] == '\r' || h[2] == '\t'));
    if (!ok) {
        snprintf(msg, cap,
                 "%s: '%s' (%llu bytes) does not start like an image file (EXR, PNG, JPEG, HDR, TIFF, PNM, BMP, GIF, "
                 "WebP); not read",
                 what, path, (unsigned long long)size);
        return false;
    }
    uint64_t w = 0, hh = 0;
    if (kind == 0 && !exr_dims(h, n, &w, &hh)) {
        snprintf(msg, cap, "%s: '%s': malformed OpenEXR header (no valid dataWindow in the first %zu bytes)", what,
                 path, n);
        return false;
    }
    if (kind == 1 && n >= 24 && memcmp(h + 12, "IHDR", 4) == 0) {
        w = (uint64_t)h[16] << 24 | (uint64_t)h[17] << 16 | (uint64_t)h[18] << 8 | h[19];
        hh = (uint64_t)h[20] << 24 | (uint64_t)h[21] << 16 | (uint64_t)h[22] << 8 | h[23];
    }
    if (max_pixels && (w > max_pixels || hh > max_pixels || w * hh > max_pixels)) {
        snprintf(msg, cap, "%s: '%s' is %llu x %llu pixels, over the limit of %llu pixels; not read", what, path,
                 (unsigned long long)w, (unsigned long long)hh, (unsigned long long)max_pixels);
        return false;
    }
    return true;
}

bool sv_sky_load(const sv_ext *ext, sv_sky *out)
{
    memset(out, 0, sizeof(*out));
    if (!ext->sky.present) return true;
    if (!ext->sky.path) {
        fprintf(stderr, "schnee-view: error: sky '%s' has no resolvable path\n", ext->sky.uri);
        return false;
    }
    char msg[640];
    if (!sv_image_file_check(ext->sky.path, "sky", SV_SKY_MAX_PIXELS, msg, sizeof msg)) {
        fprintf(stderr, "schnee-view: error: %s\n", msg);
        return false;
    }
    pb_image img = {0};
    pb_error err = {0};
    if (pb_image_read(ext->sky.path, &img, &err) != PB_SUCCESS) {
        fprintf(stderr, "schnee-view: error: sky: cannot read %s: %s\n", ext->sky.path, err.message);
        return false;
    }
    if (img.width < 4 || img.height < 2) {
        fprintf(stderr, "schnee-view: error: sky %s: %ux%u is too small (at least 4x2)\n", ext->sky.path, img.width,
                img.height);
        pb_image_free(&img);
        return false;
    }
    uint32_t w = img.width, h = img.height;
    float *base = malloc((size_t)w * h * 4 * sizeof(float));
    if (!base) {
        pb_image_free(&img);
        return false;
    }
    size_t clamped = 0;
    for (size_t i = 0; i < (size_t)w * h; ++i) {
        for (uint32_t c = 0; c < 3; ++c) {
            float v = img.pixels[i * img.channels + (img.channels >= 3 ? c : 0)];
            base[i * 4 + c] = isfinite(v) && v > 0.0f ? v : 0.0f; /* the bake clamps negatives too */
            if (base[i * 4 + c] > SV_SKY_MAX_RADIANCE) {          /* the prefilter's sums must stay finite */
                base[i * 4 + c] = SV_SKY_MAX_RADIANCE;
                clamped++;
            }
        }
        base[i * 4 + 3] = 1.0f;
    }
    if (clamped)
        fprintf(stderr, "schnee-view: warning: sky %s: %zu value(s) above %g clamped to it\n", ext->sky.path, clamped,
                (double)SV_SKY_MAX_RADIANCE);
    pb_image_free(&img);
    out->present = true;
    out->max_band = ext->sky.max_band;
    memcpy(out->sh, ext->sky.sh, sizeof(out->sh));
    out->rgba[0] = base;
    out->width[0] = w, out->height[0] = h;
    uint32_t mips = 1;
    while (mips < SV_SKY_MAX_MIPS && (h >> mips) >= 2) mips++;
    out->mip_count = mips;
    pyramid src;
    bool ok = build_pyramid(base, w, h, &src);
    for (uint32_t l = 1; ok && l < mips; ++l) {
        out->width[l] = w >> l, out->height[l] = h >> l;
        out->rgba[l] = malloc((size_t)out->width[l] * out->height[l] * 4 * sizeof(float));
        if (!out->rgba[l])
            ok = false;
        else
            prefilter_level(&src, (float)l / (float)(mips - 1), out->width[l], out->height[l], out->rgba[l]);
    }
    for (uint32_t l = 1; l < src.count; ++l) free(src.rgba[l]);
    if (!ok) {
        fprintf(stderr, "schnee-view: error: out of memory prefiltering the sky\n");
        sv_sky_destroy(out);
    }
    return ok;
}

void sv_sky_destroy(sv_sky *sky)
{
    for (uint32_t l = 0; l < SV_SKY_MAX_MIPS; ++l) free(sky->rgba[l]);
    memset(sky, 0, sizeof(*sky));
}
