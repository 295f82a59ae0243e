/* The dense probe grid's field (pb_grid_field.h, docs/grid-field.md): the weights of the per-pixel rule,
 * the sample, and the cell-centred texture form. shaders/shading.glsl grid_irradiance() and
 * shaders/bricks.glsl grid_tex_irradiance() mirror pb_grid_field_query() line by line. */
#include "schnee/pb_grid_field.h"

#include "schnee/pb_bricks.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>

struct pb_grid_field {
    pb_grid_field_info info;
    int32_t *cells;   /* X·Y·Z */
    uint32_t *masks;  /* X·Y·Z */
    double *coeffs;   /* probe_count × C × 3, scale folded in (s·c) */
    double *validity; /* probe_count, as given (the weight's factor) */
    double *texels;   /* X·Y·Z × channels */
};

static uint64_t cell_count(const uint32_t d[3]) { return (uint64_t)d[0] * d[1] * d[2]; }
static uint64_t flat(const uint32_t d[3], uint32_t x, uint32_t y, uint32_t z)
{
    return x + (uint64_t)d[0] * (y + (uint64_t)d[1] * z);
}
static int64_t clamp_i(int64_t v, int64_t lo, int64_t hi) { return v < lo ? lo : v > hi ? hi : v; }
static double smoothstep(double e0, double e1, double x)
{
    double t = (x - e0) / (e1 - e0);
    t = t < 0.0 ? 0.0 : t > 1.0 ? 1.0 : t;
    return t * t * (3.0 - 2.0 * t);
}

static pb_result check_desc(const pb_grid_field_desc *d, double axes[9], pb_error *err)
{
    if (!d || !d->cells || !d->coeffs)
        return pb_error_set(err, PB_ERROR_INVALID_ARGUMENT, "pb_grid_field_build: NULL desc, cells or coeffs");
    if (!d->dims[0] || !d->dims[1] || !d->dims[2])
        return pb_error_set(err, PB_ERROR_INVALID_ARGUMENT,
                            "pb_grid_field_build: grid dims %u x %u x %u has a zero axis", d->dims[0], d->dims[1],
                            d->dims[2]);
    if (cell_count(d->dims) > PB_GRID_FIELD_MAX_CELLS)
        return pb_error_set(err, PB_ERROR_TOO_LARGE, "pb_grid_field_build: %llu cells exceed the limit of 2^31",
                            (unsigned long long)cell_count(d->dims));
    if (!(isfinite(d->spacing) && d->spacing > 0.0))
        return pb_error_set(err, PB_ERROR_INVALID_ARGUMENT, "pb_grid_field_build: spacing %g is not a positive number",
                            d->spacing);
    if (!isfinite(d->origin[0]) || !isfinite(d->origin[1]) || !isfinite(d->origin[2]))
        return pb_error_set(err, PB_ERROR_NON_FINITE, "pb_grid_field_build: non-finite origin");
    if (d->coeff_count < 1 || d->coeff_count > PB_GRID_FIELD_MAX_COLOURS)
        return pb_error_set(err, PB_ERROR_INVALID_ARGUMENT, "pb_grid_field_build: coeff_count %u outside 1..25",
                            d->coeff_count);
    static const double id[9] = {1, 0, 0, 0, 1, 0, 0, 0, 1};
    memcpy(axes, d->axes ? d->axes : id, 9 * sizeof(double));
    for (int r = 0; r < 3; r++)
        for (int c = 0; c < 3; c++) {
            double dot =
                axes[3 * r] * axes[3 * c] + axes[3 * r + 1] * axes[3 * c + 1] + axes[3 * r + 2] * axes[3 * c + 2];
            if (!(fabs(dot - (r == c)) <= 1e-3))
                return pb_error_set(err, PB_ERROR_INVALID_ARGUMENT,
                                    "pb_grid_field_build: the grid axes are not orthonormal (row %d . row %d = %g)", r,
                                    c, dot);
        }
    uint64_t n = cell_count(d->dims);
    for (uint64_t i = 0; i < n; i++)
        if (d->cells[i] < -1 || (d->cells[i] >= 0 && (uint32_t)d->cells[i] >= d->probe_count))
            return pb_error_set(err, PB_ERROR_INVALID_ARGUMENT,
                                "pb_grid_field_build: cell %llu holds probe %d, outside [-1, %u)",
                                (unsigned long long)i, d->cells[i], d->probe_count);
    uint64_t nc = (uint64_t)d->probe_count * d->coeff_count * 3u;
    for (uint64_t i = 0; i < nc; i++)
        if (!isfinite(d->coeffs[i]))
            return pb_error_set(err, PB_ERROR_NON_FINITE, "pb_grid_field_build: coefficient %llu of probe %llu is %g",
                                (unsigned long long)(i / 3u % d->coeff_count),
                                (unsigned long long)(i / (3u * d->coeff_count)), d->coeffs[i]);
    for (uint32_t i = 0; i < d->probe_count; i++) {
        if (d->validity && !isfinite(d->validity[i]))
            return pb_error_set(err, PB_ERROR_NON_FINITE, "pb_grid_field_build: validity of probe %u is %g", i,
                                (double)d->validity[i]);
        if (d->scale && !isfinite(d->scale[i]))
            return pb_error_set(err, PB_ERROR_NON_FINITE, "pb_grid_field_build: scale of probe %u is %g", i,
                                (double)d->scale[i]);
    }
    return PB_SUCCESS;
}

pb_result pb_grid_field_build(const pb_grid_field_desc *d, pb_grid_field **out, pb_error *err)
{
    if (!out) return pb_error_set(err, PB_ERROR_INVALID_ARGUMENT, "pb_grid_field_build: NULL out");
    *out = NULL;
    double axes[9];
    pb_result r = check_desc(d, axes, err);
    if (r != PB_SUCCESS) return r;
    uint32_t C = d->coeff_count, ch = 3u * C + 1u, groups = (ch + 3u) / 4u;
    uint64_t n = cell_count(d->dims), f32 = n * groups * 16u, cap = d->max_bytes ? d->max_bytes : (UINT64_C(1) << 30);
    if (f32 > cap)
        return pb_error_set(err, PB_ERROR_TOO_LARGE,
                            "pb_grid_field_build: the texture needs %.3g GiB in float32 (%llu cells x %u groups), past "
                            "the cap of %.3g GiB",
                            (double)f32 / 1073741824.0, (unsigned long long)n, groups, (double)cap / 1073741824.0);
    pb_grid_field *f = calloc(1, sizeof *f);
    size_t P = d->probe_count ? d->probe_count : 1;
    if (f) {
        f->cells = malloc((size_t)n * sizeof *f->cells);
        f->masks = malloc((size_t)n * sizeof *f->masks);
        f->coeffs = malloc(P * C * 3u * sizeof *f->coeffs);
        f->validity = malloc(P * sizeof *f->validity);
        f->texels = calloc((size_t)n * ch, sizeof *f->texels);
    }
    if (!f || !f->cells || !f->masks || !f->coeffs || !f->validity || !f->texels) {
        pb_grid_field_destroy(f);
        return pb_error_set(err, PB_ERROR_OUT_OF_MEMORY, "pb_grid_field_build: out of memory for %llu cells",
                            (unsigned long long)n);
    }
    pb_grid_field_info *in = &f->info;
    memcpy(in->dims, d->dims, sizeof in->dims);
    memcpy(in->origin, d->origin, sizeof in->origin);
    memcpy(in->axes, axes, sizeof in->axes);
    in->spacing = d->spacing;
    in->probe_count = d->probe_count;
    in->coeff_count = C;
    in->channels = ch;
    in->groups = groups;
    in->texture_bytes_f32 = f32;
    in->texture_bytes_f16 = f32 / 2u;
    memcpy(f->cells, d->cells, (size_t)n * sizeof *f->cells);
    for (uint64_t i = 0; i < n; i++) f->masks[i] = d->masks ? d->masks[i] : PB_GRID_FIELD_ALL_VISIBLE;
    for (uint32_t p = 0; p < d->probe_count; p++) {
        double s = d->scale ? d->scale[p] : 1.0;
        f->validity[p] = d->validity ? d->validity[p] : 1.0;
        for (uint32_t k = 0; k < 3u * C; k++) f->coeffs[(size_t)p * 3u * C + k] = s * d->coeffs[(size_t)p * 3u * C + k];
    }
    /* Texels: N_i = v s c_i, D = v, v = max(validity, 0) (0 for an empty cell); channel 3 = D. */
    for (uint64_t i = 0; i < n; i++) {
        int32_t pi = f->cells[i];
        double v = pi >= 0 && f->validity[pi] > 0.0 ? f->validity[pi] : 0.0, *t = f->texels + i * ch;
        if (v <= 0.0) continue;
        t[3] = v;
        for (uint32_t c = 0; c < C; c++)
            for (uint32_t k = 0; k < 3; k++) {
                uint32_t at = c == 0 ? k : 3u * c + 1u + k;
                t[at] = v * f->coeffs[((size_t)pi * C + c) * 3u + k];
            }
    }
    *out = f;
    return PB_SUCCESS;
}

void pb_grid_field_destroy(pb_grid_field *f)
{
    if (!f) return;
    free(f->cells);
    free(f->masks);
    free(f->coeffs);
    free(f->validity);
    free(f->texels);
    free(f);
}

void pb_grid_field_get_info(const pb_grid_field *f, pb_grid_field_info *out)
{
    if (f && out) *out = f->info;
}

/* u = R (p − origin) / h. */
static void grid_coords(const pb_grid_field_info *in, const double p[3], double u[3])
{
    double rel[3] = {p[0] - in->origin[0], p[1] - in->origin[1], p[2] - in->origin[2]};
    for (int a = 0; a < 3; a++)
        u[a] = (rel[0] * in->axes[3 * a] + rel[1] * in->axes[3 * a + 1] + rel[2] * in->axes[3 * a + 2]) / in->spacing;
}

static bool in_box(const pb_grid_field_info *in, const double u[3])
{
    for (int a = 0; a < 3; a++)
        if (!(u[a] >= -PB_GRID_FIELD_MARGIN && u[a] <= (double)in->dims[a] + PB_GRID_FIELD_MARGIN)) return false;
    return true;
}

pb_grid_field_status pb_grid_field_query(const pb_grid_field *f, const double p_surface[3], const double n_in[3],
                                         const pb_grid_field_opts *opts, pb_grid_field_weights *out)
{
    pb_grid_field_weights w;
    memset(&w, 0, sizeof w);
    if (out) *out = w;
    if (!f || !p_surface || !out) return PB_GRID_FIELD_OUTSIDE;
    const pb_grid_field_info *in = &f->info;
    const uint32_t *dims = in->dims;
    static const double zero[3] = {0, 0, 0};
    const double *n = n_in ? n_in : zero;
    pb_grid_field_opts o = opts ? *opts : (pb_grid_field_opts){0};
    double h = in->spacing;
    /* 1. (grid_irradiance: p, rel, u) the biased sample point in grid coordinates; the box with its margin. */
    double p[3];
    for (int a = 0; a < 3; a++) p[a] = p_surface[a] + n[a] * (o.normal_bias * h);
    grid_coords(in, p, w.u);
    for (int k = 0; k < 8; k++) w.probe[k] = -1;
    if (!in_box(in, w.u)) return *out = w, PB_GRID_FIELD_OUTSIDE;
    /* 2. (c, i0, f) */
    int64_t i0[3];
    double fr[3];
    for (int a = 0; a < 3; a++) {
        double c = w.u[a] - 0.5;
        i0[a] = (int64_t)floor(c);
        fr[a] = c - (double)i0[a];
    }
    /* 3. (rel_h, home, vis) the home cell, 0.01 cells along n from the sample point. */
    double ph[3], uh[3];
    for (int a = 0; a < 3; a++) ph[a] = p[a] + n[a] * (PB_GRID_FIELD_MARGIN * h);
    grid_coords(in, ph, uh);
    for (int a = 0; a < 3; a++) w.home[a] = (uint32_t)clamp_i((int64_t)floor(uh[a]), 0, (int64_t)dims[a] - 1);
    uint32_t vis = f->masks[flat(dims, w.home[0], w.home[1], w.home[2])];
    /* 4. (the loop over k) */
    double wsum = 0.0;
    for (int k = 0; k < 8; k++) {
        int o3[3] = {k & 1, (k >> 1) & 1, (k >> 2) & 1};
        int64_t ci[3], dd[3];
        for (int a = 0; a < 3; a++) {
            ci[a] = clamp_i(i0[a] + o3[a], 0, (int64_t)dims[a] - 1);
            w.cell[k][a] = (uint32_t)ci[a];
            dd[a] = ci[a] - (int64_t)w.home[a];
        }
        /* back-face factor: t = dot(centre(ci) − p_surface, n) / h (cell_centre of gpu_types.glsl) */
        double centre[3];
        for (int a = 0; a < 3; a++) centre[a] = in->origin[a];
        for (int r = 0; r < 3; r++)
            for (int a = 0; a < 3; a++) centre[a] += ((double)ci[r] + 0.5) * h * in->axes[3 * r + a];
        double t = ((centre[0] - p_surface[0]) * n[0] + (centre[1] - p_surface[1]) * n[1] +
                    (centre[2] - p_surface[2]) * n[2]) /
                   h;
        w.backface[k] = o.static_surface ? smoothstep(-PB_GRID_FIELD_BACK_RAMP, PB_GRID_FIELD_BACK_RAMP, t) : 1.0;
        int32_t idx = f->cells[flat(dims, (uint32_t)ci[0], (uint32_t)ci[1], (uint32_t)ci[2])];
        w.probe[k] = idx;
        if (idx < 0) continue;
        if (llabs(dd[0]) <= 1 && llabs(dd[1]) <= 1 && llabs(dd[2]) <= 1 &&
            !(vis & (UINT32_C(1) << (dd[0] + 1 + 3 * (dd[1] + 1) + 9 * (dd[2] + 1))))) {
            w.masked[k] = true;
            continue;
        }
        double wk = 1.0;
        for (int a = 0; a < 3; a++) wk *= o3[a] ? fr[a] : 1.0 - fr[a];
        wk *= w.backface[k] * f->validity[idx];
        if (wk <= 0.0) continue;
        w.raw[k] = wk;
        wsum += wk;
    }
    /* 5. renormalised; else the plain trilinear x validity weights of the 8 corners (no mask, no back face:
     *    the texture's own N / D at t = clamp(u - 1/2, 0, dims - 1)), renormalised by their sum D; else
     *    nothing. raw[] keeps the anti-leak weights. */
    if (wsum > PB_GRID_FIELD_MIN_WEIGHT) {
        for (int k = 0; k < 8; k++) w.weight[k] = w.raw[k] / wsum;
        w.status = PB_GRID_FIELD_WEIGHTS;
        return *out = w, w.status;
    }
    double d = 0.0;
    for (int k = 0; k < 8; k++) {
        double wk = 1.0;
        for (int a = 0; a < 3; a++) wk *= (k >> a) & 1 ? fr[a] : 1.0 - fr[a];
        wk *= w.probe[k] >= 0 ? f->validity[w.probe[k]] : 0.0;
        w.weight[k] = wk > 0.0 ? wk : 0.0;
        d += w.weight[k];
    }
    for (int k = 0; k < 8; k++) w.weight[k] = d > PB_GRID_FIELD_MIN_WEIGHT ? w.weight[k] / d : 0.0;
    w.status = d > PB_GRID_FIELD_MIN_WEIGHT ? PB_GRID_FIELD_FALLBACK : PB_GRID_FIELD_NONE;
    return *out = w, w.status;
}

pb_grid_field_status pb_grid_field_sample(const pb_grid_field *f, const double p[3], const double n[3],
                                          const pb_grid_field_opts *opts, double *coeffs_out)
{
    pb_grid_field_weights w;
    pb_grid_field_status s = pb_grid_field_query(f, p, n, opts, &w);
    if (!f || !coeffs_out) return s;
    uint32_t C3 = 3u * f->info.coeff_count;
    memset(coeffs_out, 0, C3 * sizeof *coeffs_out);
    for (int k = 0; k < 8; k++) {
        if (!(w.weight[k] > 0.0)) continue;
        const double *c = f->coeffs + (size_t)w.probe[k] * C3;
        for (uint32_t i = 0; i < C3; i++) coeffs_out[i] += w.weight[k] * c[i];
    }
    return s;
}

/* ---- texture form ----------------------------------------------------------------------------------- */

bool pb_grid_field_texel_coord(const pb_grid_field *f, const double p[3], double t[3])
{
    if (!f || !p || !t) return false;
    double u[3];
    grid_coords(&f->info, p, u);
    if (!in_box(&f->info, u)) return false;
    for (int a = 0; a < 3; a++) {
        double v = u[a] - 0.5, hi = (double)f->info.dims[a] - 1.0;
        t[a] = v < 0.0 ? 0.0 : v > hi ? hi : v;
    }
    return true;
}

/* acc += scale × the trilinear filter of the texels at texel coordinate t (in [0, dims − 1]), fractions
 * rounded to 2^−bits when 0 < bits <= 24 (pb_grid_field_sample_texture). */
static void texture_tap(const pb_grid_field *f, const double t[3], uint32_t bits, double scale, double *acc)
{
    const uint32_t *dims = f->info.dims;
    uint32_t i0[3], i1[3], ch = f->info.channels;
    double fr[3];
    for (int a = 0; a < 3; a++) {
        double fl = floor(t[a]);
        i0[a] = (uint32_t)fl;
        i1[a] = i0[a] + 1u < dims[a] ? i0[a] + 1u : i0[a];
        fr[a] = t[a] - fl;
        if (bits > 0 && bits <= 24) fr[a] = nearbyint(ldexp(fr[a], (int)bits)) / ldexp(1.0, (int)bits);
    }
    for (int k = 0; k < 8; k++) {
        uint32_t x = k & 1 ? i1[0] : i0[0], y = k & 2 ? i1[1] : i0[1], z = k & 4 ? i1[2] : i0[2];
        double wk = (k & 1 ? fr[0] : 1.0 - fr[0]) * (k & 2 ? fr[1] : 1.0 - fr[1]) * (k & 4 ? fr[2] : 1.0 - fr[2]);
        const double *tx = f->texels + flat(dims, x, y, z) * ch;
        for (uint32_t c = 0; c < ch; c++) acc[c] += scale * wk * tx[c];
    }
}

/* coeffs_out[c] = N_c / D of the channels acc (0 without a value). */
static void texture_ratio(const pb_grid_field *f, const double *acc, bool has, double *coeffs_out)
{
    for (uint32_t c = 0; coeffs_out && c < f->info.coeff_count; c++)
        for (uint32_t k = 0; k < 3; k++) coeffs_out[3 * c + k] = has ? acc[c == 0 ? k : 3 * c + 1 + k] / acc[3] : 0.0;
}

bool pb_grid_field_sample_texture(const pb_grid_field *f, const double p[3], uint32_t bits, double *channels_out,
                                  double *coeffs_out, double *d_out)
{
    double t[3];
    uint32_t ch = f ? f->info.channels : 0;
    double acc[3u * PB_GRID_FIELD_MAX_COLOURS + 1u] = {0};
    bool inside = pb_grid_field_texel_coord(f, p, t);
    if (inside) texture_tap(f, t, bits, 1.0, acc);
    bool has = inside && acc[3] > PB_GRID_FIELD_MIN_WEIGHT;
    if (channels_out) memcpy(channels_out, acc, ch * sizeof *acc);
    if (d_out) *d_out = acc[3];
    if (f) texture_ratio(f, acc, has, coeffs_out);
    return has;
}

/* acc += Σ_k w[k] · texel(ci[k]) over the corners with a weight (the exact taps). */
static void exact_taps(const pb_grid_field *f, int64_t ci[8][3], const double w[8], double *acc)
{
    const uint32_t *dims = f->info.dims;
    const uint32_t channels = f->info.channels;
    for (int k = 0; k < 8; k++) {
        if (!(w[k] > 0.0)) continue;
        const double *tx =
            f->texels + flat(dims, (uint32_t)ci[k][0], (uint32_t)ci[k][1], (uint32_t)ci[k][2]) * channels;
        for (uint32_t c = 0; c < channels; c++) acc[c] += w[k] * tx[c];
    }
}

bool pb_grid_field_sample_surface_texture(const pb_grid_field *f, const double p_surface[3], const double n_in[3],
                                          const pb_grid_field_opts *opts, uint32_t bits, double *coeffs_out,
                                          double *d_out, uint32_t *taps_out)
{
    double acc[3u * PB_GRID_FIELD_MAX_COLOURS + 1u] = {0};
    if (taps_out) *taps_out = 0;
    if (d_out) *d_out = 0.0;
    if (f) texture_ratio(f, acc, false, coeffs_out);
    if (!f || !p_surface) return false;
    const pb_grid_field_info *in = &f->info;
    const uint32_t *dims = in->dims;
    static const double zero[3] = {0, 0, 0};
    const double *n = n_in ? n_in : zero;
    pb_grid_field_opts o = opts ? *opts : (pb_grid_field_opts){0};
    double h = in->spacing;
    /* 1.–3. as pb_grid_field_query: u of the biased point, the box, c, i0, f, the home cell's mask. */
    double p[3], u[3], ph[3], uh[3], fr[3];
    int64_t i0[3];
    uint32_t home[3];
    for (int a = 0; a < 3; a++) p[a] = p_surface[a] + n[a] * (o.normal_bias * h);
    grid_coords(in, p, u);
    if (!in_box(in, u)) return false;
    for (int a = 0; a < 3; a++) {
        double c = u[a] - 0.5;
        i0[a] = (int64_t)floor(c);
        fr[a] = c - (double)i0[a];
    }
    for (int a = 0; a < 3; a++) ph[a] = p[a] + n[a] * (PB_GRID_FIELD_MARGIN * h);
    grid_coords(in, ph, uh);
    for (int a = 0; a < 3; a++) home[a] = (uint32_t)clamp_i((int64_t)floor(uh[a]), 0, (int64_t)dims[a] - 1);
    uint32_t vis = f->masks[flat(dims, home[0], home[1], home[2])];
    /* 4. Each corner's weight besides validity (which is in N and D): trilinear × keep_k, keep_k = 0 where
     *    the mask drops the corner, else its back-face weight (1 for a movable object). */
    double w[8], tri8[8];
    int64_t ci[8][3];
    for (int k = 0; k < 8; k++) {
        int o3[3] = {k & 1, (k >> 1) & 1, (k >> 2) & 1};
        int64_t dd[3];
        double centre[3], tri = 1.0;
        for (int a = 0; a < 3; a++) {
            ci[k][a] = clamp_i(i0[a] + o3[a], 0, (int64_t)dims[a] - 1);
            dd[a] = ci[k][a] - (int64_t)home[a];
            tri *= o3[a] ? fr[a] : 1.0 - fr[a];
        }
        bool masked = llabs(dd[0]) <= 1 && llabs(dd[1]) <= 1 && llabs(dd[2]) <= 1 &&
                      !(vis & (UINT32_C(1) << (dd[0] + 1 + 3 * (dd[1] + 1) + 9 * (dd[2] + 1))));
        for (int a = 0; a < 3; a++) centre[a] = in->origin[a];
        for (int r = 0; r < 3; r++)
            for (int a = 0; a < 3; a++) centre[a] += ((double)ci[k][r] + 0.5) * h * in->axes[3 * r + a];
        double t = ((centre[0] - p_surface[0]) * n[0] + (centre[1] - p_surface[1]) * n[1] +
                    (centre[2] - p_surface[2]) * n[2]) /
                   h;
        double b = o.static_surface ? smoothstep(-PB_GRID_FIELD_BACK_RAMP, PB_GRID_FIELD_BACK_RAMP, t) : 1.0;
        w[k] = tri * (masked ? 0.0 : b);
        tri8[k] = tri;
    }
    /* 5. Separable weights (pb_bricks_separable): one filtered tap at t = clamp(i0 + f', 0, dims − 1) (a
     *    clamped axis has both corners in one cell), exactly Σ (w_k / sw) (N, D)_k; kept where its D >=
     *    PB_GRID_FIELD_FILTER_MIN_D. Else the 8 texels with w exactly. Σ w v <= 1e-6: the rule's fallback,
     *    the 8 texels with the plain trilinear weights (exact taps: its D may be tiny). */
    double f1[3], sw = 0.0;
    for (int k = 0; k < 8; k++) sw += w[k];
    uint32_t taps = 8;
    if (pb_bricks_separable(w, f1)) {
        double t[3];
        for (int a = 0; a < 3; a++) {
            double v = (double)i0[a] + f1[a], hi = (double)dims[a] - 1.0;
            t[a] = v < 0.0 ? 0.0 : v > hi ? hi : v;
        }
        texture_tap(f, t, bits, sw, acc);
        if (acc[3] >= PB_GRID_FIELD_FILTER_MIN_D * sw)
            taps = 1;
        else
            memset(acc, 0, sizeof acc);
    }
    if (taps == 8) exact_taps(f, ci, w, acc);
    bool has = acc[3] > PB_GRID_FIELD_MIN_WEIGHT;
    if (!has) {
        taps = 8;
        memset(acc, 0, sizeof acc);
        exact_taps(f, ci, tri8, acc);
        has = acc[3] > PB_GRID_FIELD_MIN_WEIGHT;
    }
    if (taps_out) *taps_out = taps;
    if (d_out) *d_out = acc[3];
    texture_ratio(f, acc, has, coeffs_out);
    return has;
}

const double *pb_grid_field_texels(const pb_grid_field *f) { return f ? f->texels : NULL; }

/* binary16 of a finite |v| <= 65504, round to nearest even (as pb_bricks.c's pool). */
static uint16_t double_to_half(double v)
{
    uint16_t sign = signbit(v) ? 0x8000u : 0u;
    double a = fabs(v);
    if (a < 6.103515625e-05) return (uint16_t)(sign | (uint16_t)nearbyint(a * 16777216.0)); /* subnormal */
    int e;
    (void)frexp(a, &e);
    uint32_t q = (uint32_t)nearbyint(ldexp(a, 11 - e));
    return (uint16_t)(sign | (((uint32_t)(e + 14) << 10) + q - 1024u));
}

static pb_result texture_fill(const pb_grid_field *f, void *out, uint64_t capacity, bool half, const char *fn,
                              pb_error *err)
{
    if (!f) return pb_error_set(err, PB_ERROR_INVALID_ARGUMENT, "%s: NULL field", fn);
    const pb_grid_field_info *in = &f->info;
    uint64_t n = cell_count(in->dims), need = n * in->groups * 4u;
    if (!out || capacity < need)
        return pb_error_set(err, PB_ERROR_INVALID_ARGUMENT, "%s: capacity %llu below the texture's %llu values", fn,
                            (unsigned long long)capacity, (unsigned long long)need);
    if (half)
        for (uint64_t i = 0; i < n * in->channels; i++)
            if (fabs(f->texels[i]) > 65504.0)
                return pb_error_set(err, PB_ERROR_TOO_LARGE,
                                    "%s: texel value %g (channel %llu) exceeds binary16's 65504: upload float32", fn,
                                    f->texels[i], (unsigned long long)(i % in->channels));
    for (uint64_t i = 0; i < n; i++)
        for (uint32_t g = 0; g < in->groups; g++)
            for (uint32_t c = 0; c < 4; c++) {
                uint32_t chn = 4u * g + c;
                double v = chn < in->channels ? f->texels[i * in->channels + chn] : 0.0;
                uint64_t at = (g * n + i) * 4u + c;
                if (half)
                    ((uint16_t *)out)[at] = double_to_half(v);
                else
                    ((float *)out)[at] = (float)v;
            }
    return PB_SUCCESS;
}

pb_result pb_grid_field_texture_f32(const pb_grid_field *f, float *out, uint64_t capacity, pb_error *err)
{
    return texture_fill(f, out, capacity, false, "pb_grid_field_texture_f32", err);
}

pb_result pb_grid_field_texture_f16(const pb_grid_field *f, uint16_t *out, uint64_t capacity, pb_error *err)
{
    return texture_fill(f, out, capacity, true, "pb_grid_field_texture_f16", err);
}
