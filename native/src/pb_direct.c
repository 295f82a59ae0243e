/* Direct light of lamps and sky projected onto SH by stratified quadrature (docs/direct-light.md). */
#include "schnee/pb_direct.h"

#include "schnee/pb_occluder.h"
#include "schnee/pb_sh.h"

#include <float.h>
#include <math.h>
#include <stdlib.h>
#include <string.h>

#define PB_PI 3.14159265358979323846

struct pb_direct_scene {
    pb_occluder *occluder; /* NULL when there is no geometry */
    double centre[3];      /* geometry is stored relative to this point (float precision far away) */
};

void pb_direct_scene_destroy(pb_direct_scene *s)
{
    if (!s) return;
    pb_occluder_destroy(s->occluder);
    free(s);
}

pb_result pb_direct_scene_create(const pb_mesh_desc *geometry, uint32_t count, pb_direct_scene **out, pb_error *err)
{
    if (!out) return pb_error_set(err, PB_ERROR_INVALID_ARGUMENT, "pb_direct_scene_create: out is NULL");
    *out = NULL;
    if (count && !geometry)
        return pb_error_set(err, PB_ERROR_INVALID_ARGUMENT, "pb_direct_scene_create: geometry is NULL");
    double lo[3] = {DBL_MAX, DBL_MAX, DBL_MAX}, hi[3] = {-DBL_MAX, -DBL_MAX, -DBL_MAX};
    uint64_t tris = 0;
    for (uint32_t i = 0; i < count; i++) {
        const pb_mesh_desc *m = &geometry[i];
        if (m->triangle_count == 0) continue;
        if (!m->positions || !m->indices || m->vertex_count == 0)
            return pb_error_set(err, PB_ERROR_INVALID_ARGUMENT, "occluder mesh %u ('%s') has triangles but no data", i,
                                m->name ? m->name : "");
        for (uint64_t t = 0; t < 3ull * m->triangle_count; t++)
            if (m->indices[t] >= m->vertex_count)
                return pb_error_set(err, PB_ERROR_INVALID_ARGUMENT,
                                    "occluder mesh %u ('%s'): triangle index %u out of range (%u vertices)", i,
                                    m->name ? m->name : "", m->indices[t], m->vertex_count);
        for (uint64_t v = 0; v < 3ull * m->vertex_count; v++) {
            const double x = m->positions[v];
            if (!isfinite(x))
                return pb_error_set(err, PB_ERROR_NON_FINITE, "occluder mesh %u ('%s'): non-finite vertex coordinate",
                                    i, m->name ? m->name : "");
            lo[v % 3] = fmin(lo[v % 3], x);
            hi[v % 3] = fmax(hi[v % 3], x);
        }
        tris += m->triangle_count;
    }
    pb_direct_scene *s = calloc(1, sizeof *s);
    if (!s) return pb_error_set(err, PB_ERROR_OUT_OF_MEMORY, "out of memory creating the occluder scene");
    pb_result r = PB_SUCCESS;
    if (tris > 0) {
        for (int a = 0; a < 3; a++) s->centre[a] = 0.5 * (lo[a] + hi[a]);
        /* One thread: the bake asks for one probe at a time. */
        r = pb_occluder_create_from_meshes(geometry, count, s->centre, 1, PB_OCCLUDER_BUILD_MEDIUM,
                                           "direct-light occluder", &s->occluder, err);
    }
    if (r) {
        pb_direct_scene_destroy(s);
        return r;
    }
    *out = s;
    return PB_SUCCESS;
}

/* ---------------------------------------------------------------------------------------------- */

typedef struct accum {
    uint32_t max_band, count;
    const pb_direct_scene *scene;
    double offset;
    double probe[3];
    double sum[PB_SH_MAX_COEFFS * 3];
} accum;

/* 1 when the segment probe → probe + dir·dist (dist = INFINITY for a sun) is free of occluders. */
static bool visible(const accum *a, const double dir[3], double dist)
{
    if (!a->scene || !a->scene->occluder) return true;
    pb_occluder_ray ray;
    for (int k = 0; k < 3; k++) {
        ray.org[k] = (float)(a->probe[k] - a->scene->centre[k]);
        ray.dir[k] = (float)dir[k];
    }
    ray.tnear = (float)a->offset;
    ray.tfar = isfinite(dist) ? (float)(dist - a->offset) : INFINITY;
    if (!(ray.tfar > ray.tnear)) return true;
    return !pb_occluder_occluded(a->scene->occluder, &ray);
}

/* Adds weight_rgb · Y(dir) when the lamp point at `dist` along dir is visible. */
static void add_sample(accum *a, const double dir[3], double dist, const double w[3])
{
    if (!(w[0] > 0.0 || w[1] > 0.0 || w[2] > 0.0)) return;
    if (!visible(a, dir, dist)) return;
    double y[PB_SH_MAX_COEFFS];
    pb_sh_eval_basis(a->max_band, dir, y);
    for (uint32_t i = 0; i < a->count; i++)
        for (int c = 0; c < 3; c++) a->sum[i * 3 + c] += w[c] * y[i];
}

static double dot3(const double a[3], const double b[3]) { return a[0] * b[0] + a[1] * b[1] + a[2] * b[2]; }

static void cross3(const double a[3], const double b[3], double o[3])
{
    o[0] = a[1] * b[2] - a[2] * b[1];
    o[1] = a[2] * b[0] - a[0] * b[2];
    o[2] = a[0] * b[1] - a[1] * b[0];
}

static bool normalize3(double v[3])
{
    const double n = sqrt(dot3(v, v));
    if (!(n > 0.0) || !isfinite(n)) return false;
    for (int k = 0; k < 3; k++) v[k] /= n;
    return true;
}

/* Any orthonormal frame (u, v) perpendicular to the unit vector w. */
static void frame(const double w[3], double u[3], double v[3])
{
    const double h[3] = {fabs(w[0]) < 0.6 ? 1.0 : 0.0, fabs(w[0]) < 0.6 ? 0.0 : 1.0, 0.0};
    cross3(w, h, u);
    normalize3(u);
    cross3(w, u, v);
}

/* Rings × sectors for about `samples` cells, sectors even (so that a straight edge through the
 * centre splits the cells evenly). */
static void strat(uint32_t samples, uint32_t *rings, uint32_t *sectors)
{
    uint32_t r = (uint32_t)lround(sqrt(samples / 2.0));
    if (r < 1) r = 1;
    uint32_t s = (samples + r - 1) / r;
    s += s & 1u;
    if (s < 2) s = 2;
    *rings = r;
    *sectors = s;
}

/* Smoothstep of Cycles (3t² − 2t³ on [0, 1]). */
static double smoothstep01(double t)
{
    if (t <= 0.0) return 0.0;
    if (t >= 1.0) return 1.0;
    return t * t * (3.0 - 2.0 * t);
}

/* Spot attenuation for light leaving the lamp along `out_dir` (unit). */
static double spot_factor(const pb_light *l, const double out_dir[3])
{
    if (l->type != PB_LIGHT_SPOT) return 1.0;
    const double cos_half = cos(0.5 * l->spot_size);
    const double c = dot3(out_dir, l->direction);
    if (!(c > cos_half)) return 0.0;
    const double smooth = (1.0 - cos_half) * l->spot_blend;
    double f = smooth > 0.0 ? smoothstep01((c - cos_half) / smooth) : 1.0;
    if (l->spot_cosine) f *= c;
    return f;
}

static void project_sun(accum *a, const pb_light *l, uint32_t samples)
{
    double d[3] = {-l->direction[0], -l->direction[1], -l->direction[2]}; /* towards the sun */
    if (!normalize3(d)) return;
    const double half = 0.5 * l->radius;
    if (!(half > 1e-9)) {
        add_sample(a, d, INFINITY, l->color);
        return;
    }
    /* Cycles samples the sun uniformly on a disc of radius tan(half) at unit distance; every cell of
     * an equal-area polar stratification of that disc carries S / cells (docs/direct-light.md). */
    const double t = tan(fmin(half, 0.5 * PB_PI - 1e-6));
    double u[3], v[3];
    frame(d, u, v);
    uint32_t nr, ns;
    strat(samples, &nr, &ns);
    const double cells = (double)nr * ns;
    const double w[3] = {l->color[0] / cells, l->color[1] / cells, l->color[2] / cells};
    for (uint32_t i = 0; i < nr; i++) {
        const double rr = t * sqrt((i + 0.5) / nr);
        for (uint32_t j = 0; j < ns; j++) {
            const double ph = 2.0 * PB_PI * (j + 0.5) / ns;
            double dir[3];
            for (int k = 0; k < 3; k++) dir[k] = d[k] + rr * (cos(ph) * u[k] + sin(ph) * v[k]);
            normalize3(dir);
            add_sample(a, dir, INFINITY, w);
        }
    }
}

static void project_point(accum *a, const pb_light *l, uint32_t samples)
{
    double d[3] = {l->position[0] - a->probe[0], l->position[1] - a->probe[1], l->position[2] - a->probe[2]};
    const double dist = sqrt(dot3(d, d));
    if (!(dist > 0.0) || !normalize3(d)) return;
    const double r = l->radius;
    const double out_dir[3] = {-d[0], -d[1], -d[2]};
    if (!(r > 0.0)) {
        /* Delta lamp: intensity P / (4π) W/sr, irradiance-like weight I / d². */
        const double f = spot_factor(l, out_dir) / (4.0 * PB_PI * dist * dist);
        const double w[3] = {l->color[0] * f, l->color[1] * f, l->color[2] * f};
        add_sample(a, d, dist, w);
        return;
    }
    /* Uniform radiance P / (4π² r²) over a cone: half-angle atan(r/d) (disc facing the probe, Cycles
     * ≤ 3.6) or asin(r/d) (sphere, Cycles ≥ 4.0). 1 − cos β computed without cancellation. */
    double one_minus_cos;
    if (l->legacy_point) {
        /* not hypot(): glibc 2.35 versioned it anew, and the package promises glibc 2.34 */
        const double h = sqrt(dist * dist + r * r);
        one_minus_cos = r * r / (h * (h + dist));
    } else {
        if (!(r < dist)) return; /* probe inside the sphere lamp: nothing (documented) */
        const double c = sqrt((dist - r) * (dist + r));
        one_minus_cos = r * r / (dist * (dist + c));
    }
    const double rad = 1.0 / (4.0 * PB_PI * PB_PI * r * r);
    double u[3], v[3];
    frame(d, u, v);
    uint32_t nr, ns;
    strat(samples, &nr, &ns);
    const double dw = 2.0 * PB_PI * one_minus_cos / ((double)nr * ns);
    for (uint32_t i = 0; i < nr; i++) {
        const double omc = one_minus_cos * (i + 0.5) / nr; /* 1 − cos θ at the ring's centre */
        const double ct = 1.0 - omc, st = sqrt(fmax(0.0, omc * (2.0 - omc)));
        for (uint32_t j = 0; j < ns; j++) {
            const double ph = 2.0 * PB_PI * (j + 0.5) / ns;
            double dir[3];
            for (int k = 0; k < 3; k++) dir[k] = ct * d[k] + st * (cos(ph) * u[k] + sin(ph) * v[k]);
            /* Distance to the lamp surface along dir (for the shadow ray): the disc plane or the sphere. */
            double t;
            if (l->legacy_point)
                t = dist / ct;
            else {
                const double b = dist * ct, disc = r * r - dist * dist * (1.0 - ct * ct);
                t = b - sqrt(fmax(0.0, disc));
            }
            const double od[3] = {-dir[0], -dir[1], -dir[2]};
            const double f = rad * dw * spot_factor(l, od);
            const double w[3] = {l->color[0] * f, l->color[1] * f, l->color[2] * f};
            add_sample(a, dir, t, w);
        }
    }
}

static void project_area(accum *a, const pb_light *l, uint32_t samples)
{
    double n[3] = {l->direction[0], l->direction[1], l->direction[2]};
    double u[3] = {l->axis_u[0], l->axis_u[1], l->axis_u[2]};
    if (!normalize3(n) || !normalize3(u)) return;
    double v[3];
    cross3(n, u, v);
    if (!normalize3(v)) return;
    cross3(v, n, u); /* re-orthogonalise */
    const double su = l->size_u, sv = l->size_v;
    if (!(su > 0.0) || !(sv > 0.0)) return;
    const double rel[3] = {a->probe[0] - l->position[0], a->probe[1] - l->position[1], a->probe[2] - l->position[2]};
    const double h = dot3(rel, n); /* height of the probe over the lamp plane, front side > 0 */
    if (!(h > 0.0)) return;
    const bool ellipse = l->type == PB_LIGHT_AREA_ELLIPSE;
    const double area = ellipse ? 0.25 * PB_PI * su * sv : su * sv;
    const double rad = 1.0 / (4.0 * area);
    /* Cells: one shadow ray each; inside every cell a k × k midpoint sub-grid for the radiance when
     * the probe is close (k grows with lamp size / height) so the quadrature stays accurate. */
    uint32_t nu, nv;
    if (ellipse) {
        strat(samples, &nu, &nv);
    } else {
        nu = (uint32_t)lround(sqrt(samples * su / sv));
        if (nu < 1) nu = 1;
        nv = (samples + nu - 1) / nu;
        if (nv < 1) nv = 1;
    }
    const double cell_extent =
        ellipse ? 0.5 * fmax(su, sv) * fmax(sqrt(1.0 / nu), 2.0 * PB_PI / nv) : fmax(su / nu, sv / nv);
    const double kf = ceil(16.0 * cell_extent / h);
    const uint32_t k = kf < 1.0 ? 1u : kf > 32.0 ? 32u : (uint32_t)kf;
    const double cell_area = area / ((double)nu * nv);
    for (uint32_t i = 0; i < nu; i++) {
        for (uint32_t j = 0; j < nv; j++) {
            /* Cell centre (shadow ray target) and the radiance quadrature of the cell. */
            double centre_dir[3], centre_dist = 0.0;
            double sum_w = 0.0, y_acc[PB_SH_MAX_COEFFS] = {0};
            for (uint32_t si = 0; si <= k; si++) {
                for (uint32_t sj = 0; sj < (si == k ? 1u : k); sj++) {
                    double s, t; /* local coordinates (m) along u and v */
                    const bool is_centre = si == k;
                    const double fi = is_centre ? 0.5 : (si + 0.5) / k, fj = is_centre ? 0.5 : (sj + 0.5) / k;
                    if (ellipse) {
                        const double rr = sqrt((i + fi) / nu), ph = 2.0 * PB_PI * (j + fj) / nv;
                        s = 0.5 * su * rr * cos(ph);
                        t = 0.5 * sv * rr * sin(ph);
                    } else {
                        s = su * ((i + fi) / nu - 0.5);
                        t = sv * ((j + fj) / nv - 0.5);
                    }
                    double dir[3];
                    for (int c = 0; c < 3; c++) dir[c] = l->position[c] + s * u[c] + t * v[c] - a->probe[c];
                    const double dd = sqrt(dot3(dir, dir));
                    if (!(dd > 0.0)) continue;
                    for (int c = 0; c < 3; c++) dir[c] /= dd;
                    if (is_centre) {
                        memcpy(centre_dir, dir, sizeof centre_dir);
                        centre_dist = dd;
                        continue;
                    }
                    /* dω = dA cos θ_l / d², cos θ_l = h / d. */
                    const double w = (cell_area / (k * k)) * (h / dd) / (dd * dd);
                    double y[PB_SH_MAX_COEFFS];
                    pb_sh_eval_basis(a->max_band, dir, y);
                    for (uint32_t q = 0; q < a->count; q++) y_acc[q] += w * y[q];
                    sum_w += w;
                }
            }
            if (!(sum_w > 0.0) || !(centre_dist > 0.0)) continue;
            if (!visible(a, centre_dir, centre_dist)) continue;
            for (uint32_t q = 0; q < a->count; q++)
                for (int c = 0; c < 3; c++) a->sum[q * 3 + c] += l->color[c] * rad * y_acc[q];
        }
    }
}

static pb_result check_light(const pb_light *l, uint32_t index, pb_error *err)
{
    if ((unsigned)l->type >= PB_LIGHT_TYPE_COUNT_)
        return pb_error_set(err, PB_ERROR_INVALID_ARGUMENT, "lamp %u: unknown type %d", index, (int)l->type);
    const double *vals[] = {l->position, l->direction, l->axis_u, l->color};
    for (int g = 0; g < 4; g++)
        for (int k = 0; k < 3; k++)
            if (!isfinite(vals[g][k]))
                return pb_error_set(err, PB_ERROR_NON_FINITE, "lamp %u: non-finite position, direction or colour",
                                    index);
    const double s[5] = {l->radius, l->size_u, l->size_v, l->spot_size, l->spot_blend};
    for (int k = 0; k < 5; k++)
        if (!isfinite(s[k]) || s[k] < 0.0)
            return pb_error_set(err, PB_ERROR_INVALID_ARGUMENT,
                                "lamp %u: radius, sizes, spot size and blend must be finite and >= 0", index);
    for (int c = 0; c < 3; c++)
        if (l->color[c] < 0.0)
            return pb_error_set(err, PB_ERROR_NEGATIVE, "lamp %u: negative colour x strength", index);
    return PB_SUCCESS;
}

pb_result pb_direct_project(const pb_direct_desc *desc, const pb_light *lights, uint32_t count, const double probe[3],
                            double *out, pb_error *err)
{
    if (!desc || !probe || !out || (count && !lights))
        return pb_error_set(err, PB_ERROR_INVALID_ARGUMENT, "pb_direct_project: NULL argument");
    if (desc->max_band > PB_SH_MAX_BAND)
        return pb_error_set(err, PB_ERROR_INVALID_ARGUMENT, "max_band %u is out of range 0..%d", desc->max_band,
                            PB_SH_MAX_BAND);
    if (desc->samples > (1u << 20))
        return pb_error_set(err, PB_ERROR_INVALID_ARGUMENT, "samples %u per lamp is above the limit %u", desc->samples,
                            1u << 20);
    if (!isfinite(desc->ray_offset) || desc->ray_offset < 0.0)
        return pb_error_set(err, PB_ERROR_INVALID_ARGUMENT, "ray_offset must be finite and >= 0");
    for (int k = 0; k < 3; k++)
        if (!isfinite(probe[k])) return pb_error_set(err, PB_ERROR_NON_FINITE, "probe position is not finite");
    for (uint32_t i = 0; i < count; i++) {
        pb_result r = check_light(&lights[i], i, err);
        if (r) return r;
    }
    accum a;
    memset(&a, 0, sizeof a);
    a.max_band = desc->max_band;
    a.count = pb_sh_count(desc->max_band);
    a.scene = desc->scene;
    a.offset = desc->ray_offset > 0.0 ? desc->ray_offset : 1e-4;
    memcpy(a.probe, probe, sizeof a.probe);
    const uint32_t samples = desc->samples ? desc->samples : 256u;
    for (uint32_t i = 0; i < count; i++) {
        const pb_light *l = &lights[i];
        switch (l->type) {
        case PB_LIGHT_SUN: project_sun(&a, l, samples); break;
        case PB_LIGHT_POINT:
        case PB_LIGHT_SPOT: project_point(&a, l, samples); break;
        case PB_LIGHT_AREA_RECT:
        case PB_LIGHT_AREA_ELLIPSE: project_area(&a, l, samples); break;
        default: break;
        }
    }
    for (uint32_t i = 0; i < a.count * 3; i++) {
        if (!isfinite(a.sum[i]))
            return pb_error_set(err, PB_ERROR_NON_FINITE, "the direct light of the lamps overflowed (coefficient %u)",
                                i / 3);
    }
    for (uint32_t i = 0; i < a.count * 3; i++) out[i] += a.sum[i];
    return PB_SUCCESS;
}

/* ---------------------------------------------------------------------------------------------- */
/* Sky                                                                                              */

pb_result pb_direct_sky_table(const float *world, uint32_t world_width, uint32_t world_height, uint32_t channels,
                              uint32_t pano_width, uint32_t pano_height, uint32_t max_band, const double *rotation,
                              double *table, pb_error *err)
{
    static const double blender_to_engine[9] = {1, 0, 0, 0, 0, 1, 0, -1, 0};
    if (!world || !table) return pb_error_set(err, PB_ERROR_INVALID_ARGUMENT, "pb_direct_sky_table: NULL argument");
    if (max_band > PB_SH_MAX_BAND)
        return pb_error_set(err, PB_ERROR_INVALID_ARGUMENT, "max_band %u is out of range 0..%d", max_band,
                            PB_SH_MAX_BAND);
    if (channels < 3) return pb_error_set(err, PB_ERROR_INVALID_ARGUMENT, "the world needs >= 3 channels");
    if (world_width == 0 || world_height == 0 || pano_width == 0 || pano_height == 0)
        return pb_error_set(err, PB_ERROR_INVALID_ARGUMENT, "empty world or panorama");
    const double *r = rotation ? rotation : blender_to_engine;
    const uint32_t n = pb_sh_count(max_band);
    memset(table, 0, sizeof(double) * (size_t)pano_width * pano_height * n * 3);
    const double dphi = 2.0 * PB_PI / world_width;
    for (uint32_t row = 0; row < world_height; row++) {
        const double t0 = PB_PI * row / world_height, t1 = PB_PI * (row + 1) / world_height;
        const double theta = PB_PI * (row + 0.5) / world_height;
        const double dw = dphi * (cos(t0) - cos(t1));
        const uint32_t prow = (uint32_t)(((2ull * row + 1) * pano_height) / (2ull * world_height));
        for (uint32_t col = 0; col < world_width; col++) {
            const float *p = world + ((size_t)row * world_width + col) * channels;
            const double rgb[3] = {p[0], p[1], p[2]};
            for (int c = 0; c < 3; c++)
                if (!isfinite(rgb[c]) || rgb[c] < 0.0)
                    return pb_error_set(err, isfinite(rgb[c]) ? PB_ERROR_NEGATIVE : PB_ERROR_NON_FINITE,
                                        "world pixel (%u, %u) is negative or not finite", col, row);
            if (rgb[0] == 0.0 && rgb[1] == 0.0 && rgb[2] == 0.0) continue;
            const double phi = PB_PI - dphi * (col + 0.5);
            const double d[3] = {sin(theta) * cos(phi), sin(theta) * sin(phi), cos(theta)};
            double e[3];
            for (int k = 0; k < 3; k++) e[k] = r[3 * k] * d[0] + r[3 * k + 1] * d[1] + r[3 * k + 2] * d[2];
            double y[PB_SH_MAX_COEFFS];
            pb_sh_eval_basis(max_band, e, y);
            const uint32_t pcol = (uint32_t)(((2ull * col + 1) * pano_width) / (2ull * world_width));
            double *cell = table + ((size_t)prow * pano_width + pcol) * n * 3;
            for (uint32_t i = 0; i < n; i++)
                for (int c = 0; c < 3; c++) cell[i * 3 + c] += rgb[c] * dw * y[i];
        }
    }
    return PB_SUCCESS;
}

void pb_direct_add_sky(const double *table, uint32_t pano_width, uint32_t pano_height, uint32_t max_band,
                       const float *vis, size_t vis_stride, double *out)
{
    const uint32_t n = pb_sh_count(max_band > PB_SH_MAX_BAND ? PB_SH_MAX_BAND : max_band);
    const size_t cells = (size_t)pano_width * pano_height;
    if (vis_stride == 0) vis_stride = 1;
    double sum[PB_SH_MAX_COEFFS * 3] = {0};
    for (size_t k = 0; k < cells; k++) {
        double v = vis[k * vis_stride];
        if (!(v > 0.0)) continue; /* also drops NaN */
        if (v > 1.0) v = 1.0;
        const double *cell = table + k * n * 3;
        for (uint32_t i = 0; i < n * 3; i++) sum[i] += v * cell[i];
    }
    for (uint32_t i = 0; i < n * 3; i++) out[i] += sum[i];
}
