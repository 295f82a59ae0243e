/* The sun of a sky image split off as a directional light (pb_sky_sun.h says what and why). */
#include "schnee/pb_sky_sun.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>

#define PB_PI 3.14159265358979323846

/* Rec. 709 luminance: the weights every part of the bake uses to compare colours by brightness. */
static double luminance(const float *p) { return 0.2126 * p[0] + 0.7152 * p[1] + 0.0722 * p[2]; }

enum { MARK_NONE = 0, MARK_REGION = 1, MARK_GROWN = 2, MARK_RING = 3 };

typedef struct index_list {
    uint32_t *v;
    size_t count, cap;
} index_list;

static bool push(index_list *l, uint32_t i)
{
    if (l->count == l->cap) {
        size_t cap = l->cap ? 2 * l->cap : 256;
        uint32_t *v = realloc(l->v, cap * sizeof *v);
        if (!v) return false;
        l->v = v;
        l->cap = cap;
    }
    l->v[l->count++] = i;
    return true;
}

typedef struct image_ {
    const float *px;
    uint32_t w, h, c;
} image_;

static void texel_dir(const image_ *im, uint32_t idx, double d[3])
{
    const uint32_t row = idx / im->w, col = idx % im->w;
    const double theta = PB_PI * (row + 0.5) / im->h, phi = PB_PI - 2.0 * PB_PI * (col + 0.5) / im->w;
    d[0] = sin(theta) * cos(phi);
    d[1] = sin(theta) * sin(phi);
    d[2] = cos(theta);
}

/* Exact solid angle of a texel of `row` (all texels of a row are equal). */
static double texel_omega(const image_ *im, uint32_t row)
{
    return (2.0 * PB_PI / im->w) * (cos(PB_PI * row / im->h) - cos(PB_PI * (row + 1.0) / im->h));
}

/* The 8 neighbours of a texel: φ wraps; a step past a pole lands in the same row, half a turn on
 * (the texel on the other side of the pole). Duplicates are harmless (the marks dedupe). */
static uint32_t neighbours(const image_ *im, uint32_t idx, uint32_t out[8])
{
    const long w = im->w, h = im->h, row = (long)(idx / im->w), col = (long)(idx % im->w);
    uint32_t n = 0;
    for (long dr = -1; dr <= 1; dr++)
        for (long dc = -1; dc <= 1; dc++) {
            if (dr == 0 && dc == 0) continue;
            long r = row + dr, c = col + dc;
            if (r < 0) {
                r = 0;
                c += w / 2;
            } else if (r >= h) {
                r = h - 1;
                c += w / 2;
            }
            c = ((c % w) + w) % w;
            const uint32_t j = (uint32_t)(r * w + c);
            if (j != idx) out[n++] = j;
        }
    return n;
}

static int cmp_double(const void *a, const void *b)
{
    const double x = *(const double *)a, y = *(const double *)b;
    return (x > y) - (x < y);
}

const char *pb_sky_sun_verdict_string(pb_sky_sun_verdict verdict)
{
    switch (verdict) {
    case PB_SKY_SUN_FOUND: return "found";
    case PB_SKY_SUN_BLACK: return "black";
    case PB_SKY_SUN_WIDE: return "wide";
    case PB_SKY_SUN_FAINT: return "faint";
    default: return "unknown verdict";
    }
}

pb_result pb_sky_sun_split(const pb_sky_sun_desc *desc, const float *image, uint32_t width, uint32_t height,
                           uint32_t channels, float *rest, pb_sky_sun *out, pb_error *err)
{
    if (!desc || !image || !out) return pb_error_set(err, PB_ERROR_INVALID_ARGUMENT, "pb_sky_sun_split: NULL argument");
    memset(out, 0, sizeof *out);
    out->verdict = PB_SKY_SUN_BLACK;
    if (width == 0 || height == 0)
        return pb_error_set(err, PB_ERROR_INVALID_ARGUMENT, "the sky image is empty (%ux%u)", width, height);
    if (channels < 3)
        return pb_error_set(err, PB_ERROR_INVALID_ARGUMENT, "the sky image has %u channels; RGB (3) or more are needed",
                            channels);
    size_t texels = 0, values = 0;
    if (__builtin_mul_overflow((size_t)width, (size_t)height, &texels) ||
        __builtin_mul_overflow(texels, (size_t)channels, &values) || texels > UINT32_MAX)
        return pb_error_set(err, PB_ERROR_TOO_LARGE, "the sky image %ux%ux%u is too large", width, height, channels);
    const double fraction = desc->peak_fraction == 0.0 ? 0.01 : desc->peak_fraction;
    const double radius = desc->max_radius == 0.0 ? 5.0 * PB_PI / 180.0 : desc->max_radius;
    const double min_share = desc->min_share == 0.0 ? 0.01 : desc->min_share;
    if (!(fraction > 0.0 && fraction < 1.0))
        return pb_error_set(err, PB_ERROR_INVALID_ARGUMENT, "peak_fraction %g is not in (0, 1)", desc->peak_fraction);
    if (!(radius > 0.0 && radius <= 0.5 * PB_PI))
        return pb_error_set(err, PB_ERROR_INVALID_ARGUMENT, "max_radius %g rad is not in (0, pi/2]", desc->max_radius);
    if (!(min_share > 0.0 && min_share < 1.0))
        return pb_error_set(err, PB_ERROR_INVALID_ARGUMENT, "min_share %g is not in (0, 1)", desc->min_share);

    const image_ im = {image, width, height, channels};
    /* Pass 1: every texel valid, the image's luminance flux and the brightest texel. */
    double total = 0.0, peak = -1.0;
    uint32_t peak_idx = 0;
    for (uint32_t row = 0; row < height; row++) {
        const double dw = texel_omega(&im, row);
        double row_sum = 0.0;
        for (uint32_t col = 0; col < width; col++) {
            const uint32_t idx = row * width + col;
            const float *p = image + (size_t)idx * channels;
            for (int k = 0; k < 3; k++)
                if (!isfinite(p[k]) || p[k] < 0.0f)
                    return pb_error_set(err, isfinite(p[k]) ? PB_ERROR_NEGATIVE : PB_ERROR_NON_FINITE,
                                        "sky texel (%u, %u) channel %d is %s (%g)", col, row, k,
                                        isfinite(p[k]) ? "negative" : "not finite", (double)p[k]);
            const double y = luminance(p);
            row_sum += y;
            if (y > peak) {
                peak = y;
                peak_idx = idx;
            }
        }
        total += row_sum * dw;
    }
    if (rest && rest != image) memcpy(rest, image, values * sizeof(float));
    out->peak_col = peak_idx % width;
    out->peak_row = peak_idx / width;
    if (!(peak > 0.0) || !(total > 0.0)) return PB_SUCCESS; /* black: nothing to split */

    unsigned char *mark = calloc(texels, 1);
    index_list sun = {0}, ring = {0};
    double *ring_values = NULL;
    pb_result r = PB_SUCCESS;
    if (!mark || !push(&sun, peak_idx)) goto oom;
    mark[peak_idx] = MARK_REGION;

    /* The region: breadth-first from the peak over texels >= fraction × peak; `sun` is the queue. */
    double to_peak[3], d[3];
    texel_dir(&im, peak_idx, to_peak);
    const double cos_radius = cos(radius), threshold = fraction * peak;
    double min_cos = 1.0;
    uint32_t nb[8];
    out->verdict = PB_SKY_SUN_WIDE;
    for (size_t head = 0; head < sun.count; head++) {
        const uint32_t n = neighbours(&im, sun.v[head], nb);
        for (uint32_t k = 0; k < n; k++) {
            const uint32_t j = nb[k];
            if (mark[j] != MARK_NONE || luminance(image + (size_t)j * channels) < threshold) continue;
            texel_dir(&im, j, d);
            const double c = d[0] * to_peak[0] + d[1] * to_peak[1] + d[2] * to_peak[2];
            if (c < cos_radius) {
                out->extent = radius;
                goto done; /* a soft sky, a window, a lamp shade: no sun */
            }
            if (c < min_cos) min_cos = c;
            mark[j] = MARK_REGION;
            if (!push(&sun, j)) goto oom;
        }
    }
    out->extent = acos(min_cos > 1.0 ? 1.0 : min_cos);
    /* Grown by one texel (the disc's partly covered edge texels fall below the threshold), then the
     * ring just outside it: the surrounding sky. */
    const size_t region_count = sun.count;
    for (size_t i = 0; i < region_count; i++) {
        const uint32_t n = neighbours(&im, sun.v[i], nb);
        for (uint32_t k = 0; k < n; k++)
            if (mark[nb[k]] == MARK_NONE) {
                mark[nb[k]] = MARK_GROWN;
                if (!push(&sun, nb[k])) goto oom;
            }
    }
    for (size_t i = 0; i < sun.count; i++) {
        const uint32_t n = neighbours(&im, sun.v[i], nb);
        for (uint32_t k = 0; k < n; k++)
            if (mark[nb[k]] == MARK_NONE) {
                mark[nb[k]] = MARK_RING;
                if (!push(&ring, nb[k])) goto oom;
            }
    }
    if (ring.count == 0) goto done; /* the sun would be the whole (tiny) image: no sky around it */
    ring_values = malloc(ring.count * sizeof *ring_values);
    if (!ring_values) goto oom;
    float level[3];
    for (int c = 0; c < 3; c++) {
        for (size_t i = 0; i < ring.count; i++) ring_values[i] = image[(size_t)ring.v[i] * channels + c];
        qsort(ring_values, ring.count, sizeof *ring_values, cmp_double);
        const size_t m = ring.count / 2;
        out->background[c] = ring.count % 2 ? ring_values[m] : 0.5 * (ring_values[m - 1] + ring_values[m]);
        level[c] = (float)out->background[c];
    }

    /* The excess over the surrounding level, texel by texel, as the rest will hold it (float). */
    double irr[3] = {0, 0, 0}, flux = 0.0, dir[3] = {0, 0, 0}, peak_excess = 0.0;
    for (size_t i = 0; i < sun.count; i++) {
        const uint32_t idx = sun.v[i];
        const float *p = image + (size_t)idx * channels;
        const double dw = texel_omega(&im, idx / width);
        double ex[3];
        for (int c = 0; c < 3; c++) {
            const float kept = p[c] < level[c] ? p[c] : level[c];
            ex[c] = (double)p[c] - (double)kept;
            irr[c] += ex[c] * dw;
        }
        const double y = 0.2126 * ex[0] + 0.7152 * ex[1] + 0.0722 * ex[2];
        if (idx == peak_idx) peak_excess = y;
        texel_dir(&im, idx, d);
        for (int c = 0; c < 3; c++) dir[c] += y * dw * d[c];
        flux += y * dw;
    }
    const double norm = sqrt(dir[0] * dir[0] + dir[1] * dir[1] + dir[2] * dir[2]);
    out->verdict = PB_SKY_SUN_FAINT;
    if (!(flux > 0.0) || !(peak_excess > 0.0) || !(norm > 0.0) || flux < min_share * total) goto done;

    out->found = true;
    out->verdict = PB_SKY_SUN_FOUND;
    out->share = flux / total;
    out->texels = (uint32_t)sun.count;
    for (int c = 0; c < 3; c++) out->irradiance[c] = irr[c];
    /* Blender (x, y, z) -> engine (x, z, -y); the light travels away from the sun. */
    out->direction[0] = -dir[0] / norm;
    out->direction[1] = -dir[2] / norm;
    out->direction[2] = dir[1] / norm;
    double omega = flux / peak_excess, cos_half = 1.0 - omega / (2.0 * PB_PI);
    if (cos_half < -1.0) cos_half = -1.0;
    out->angle = 2.0 * acos(cos_half);
    if (rest)
        for (size_t i = 0; i < sun.count; i++) {
            float *p = rest + (size_t)sun.v[i] * channels;
            for (int c = 0; c < 3; c++)
                if (p[c] > level[c]) p[c] = level[c];
        }
    goto done;
oom:
    r = pb_error_set(err, PB_ERROR_OUT_OF_MEMORY, "out of memory splitting the sky's sun");
    memset(out, 0, sizeof *out);
done:
    free(ring_values);
    free(ring.v);
    free(sun.v);
    free(mark);
    return r;
}
