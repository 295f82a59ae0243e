/* Interpolation between probes at their real positions (pb_interp.h; docs/placement.md,
 * "Interpolation"; boxes: docs/aniso-refinement.md): point location in the corner octree (the split
 * tree's descent, locate_cell in pb_interp_internal.h) and in the tetrahedra, and the weights over
 * the probes, with the visibility field, validity and a visibility judge. The structures are built in
 * pb_cotree.c and pb_tetra.c. shaders/shading.glsl mirrors locate_point_cell() and leaf_weights().
 */
#define _POSIX_C_SOURCE 200809L
#include "schnee/pb_interp.h"

#include "pb_interp_internal.h"

#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

/* Lattice coordinates u of a point and the unit cell holding it (max faces closed). */
static bool point_cell(const pb_cotree *t, const double point[3], double u[3], uint32_t q[3])
{
    for (int k = 0; k < 3; k++) {
        u[k] = (point[k] - t->origin[k]) / t->h;
        if (!(u[k] >= 0.0) || !(u[k] <= (double)t->dims[k])) return false;
        double f = floor(u[k]);
        q[k] = f >= (double)t->dims[k] ? t->dims[k] - 1 : (uint32_t)f;
    }
    return true;
}

/* The leaf holding lattice point u in unit cell q. A point on a face between a leaf and a lattice
 * cell no leaf covers (the sparse tree's outer faces, e.g. a wall's surface on a volume's max face)
 * belongs to the leaf: within PB_COTREE_FACE_EPS units of a cell's lower face the cells below are
 * tried too (x first, then y, then z and their combinations, in the order of the bit mask), so such a
 * surface does not flicker between the leaf and nothing with its coordinates' rounding. Mirrored by
 * octree_locate_point() in shaders/shading.glsl. */
#define PB_COTREE_FACE_EPS 0.01
static int32_t locate_point_cell(const pb_cotree *t, const double u[3], const uint32_t q[3])
{
    int32_t li = locate_cell(t, q);
    for (uint32_t m = 1; li < 0 && m < 8; m++) {
        uint32_t r[3];
        bool ok = true;
        for (int k = 0; k < 3; k++) {
            bool down = (m >> k) & 1u;
            if (down && !(q[k] > 0 && u[k] - (double)q[k] < PB_COTREE_FACE_EPS)) ok = false;
            r[k] = down ? q[k] - 1 : q[k];
        }
        if (ok) li = locate_cell(t, r);
    }
    return li;
}

int32_t pb_cotree_locate(const pb_cotree *t, const double point[3])
{
    if (!t || !point) return -1;
    double u[3];
    uint32_t q[3];
    if (!point_cell(t, point, u, q)) return -1;
    return locate_point_cell(t, u, q);
}

/* Drops invisible / invalid probes and zero weights, renormalises. */
static void finish_weights(pb_interp_weights *w, const double point[3], const pb_interp_options *opt)
{
    uint32_t n = 0;
    double sum = 0.0;
    for (uint32_t i = 0; i < w->count; i++) {
        uint32_t p = w->probe[i];
        double wi = w->weight[i];
        if (!(wi > 0.0)) continue;
        if (opt && opt->validity && !(opt->validity[p] > 0.0f)) continue;
        if (opt && opt->visible && !opt->visible(opt->visible_user, p, point)) continue;
        w->probe[n] = p;
        w->weight[n] = wi;
        sum += wi;
        n++;
    }
    if (!(sum > 0.0)) n = 0;
    for (uint32_t i = 0; i < n; i++) w->weight[i] /= sum;
    w->count = n;
}

static void leaf_weights(const pb_cotree *t, int32_t li, const double u[3], const double point[3],
                         const pb_interp_options *opt, pb_interp_weights *out);

pb_result pb_interp_query_cotree(const pb_cotree *t, const double point[3], const pb_interp_options *opt,
                                 pb_interp_weights *out)
{
    if (!t || !point || !out) return pb_error_set(NULL, PB_ERROR_INVALID_ARGUMENT, "NULL argument");
    out->count = 0;
    if (!t->finalized) return PB_ERROR_INVALID_ARGUMENT;
    double u[3];
    uint32_t q[3];
    if (!point_cell(t, point, u, q)) return PB_SUCCESS;
    int32_t li = locate_point_cell(t, u, q);
    if (li < 0) return PB_SUCCESS;
    leaf_weights(t, li, u, point, opt, out);
    return PB_SUCCESS;
}

pb_result pb_interp_query_cotree_leaf(const pb_cotree *t, uint32_t leaf, const double point[3],
                                      const pb_interp_options *opt, pb_interp_weights *out)
{
    if (!t || !point || !out) return PB_ERROR_INVALID_ARGUMENT;
    out->count = 0;
    if (!t->finalized || leaf >= t->leaf_count) return PB_ERROR_INVALID_ARGUMENT;
    double u[3];
    for (int k = 0; k < 3; k++) u[k] = (point[k] - t->origin[k]) / t->h;
    leaf_weights(t, (int32_t)leaf, u, point, opt, out);
    return PB_SUCCESS;
}

/* smoothstep(1/2, 1/2 + PB_VIS_RAMP, v): GLSL's smoothstep, as shading.glsl's octree_irradiance. */
static double vis_ramp(double v)
{
    double x = (v - 0.5) / PB_VIS_RAMP;
    x = x < 0.0 ? 0.0 : (x > 1.0 ? 1.0 : x);
    return x * x * (3.0 - 2.0 * x);
}

/* The corner weights w8 of leaf li expanded over the probes (hanging corners through their rules),
 * then validity / visibility dropped and renormalised (finish_weights). */
static void expand_weights(const pb_cotree *t, int32_t li, const double w8[8], const double point[3],
                           const pb_interp_options *opt, pb_interp_weights *out)
{
    out->count = 0;
    for (uint32_t c = 0; c < 8; c++) {
        if (w8[c] <= 0.0) continue;
        uint32_t node = (uint32_t)t->corners[8u * (uint32_t)li + c];
        if (node < t->probe_count) {
            (void)merge_add(out->probe, out->weight, &out->count, PB_INTERP_MAX_WEIGHTS, node, w8[c]);
        } else {
            uint32_t hI = node - t->probe_count;
            for (uint32_t e = t->exp_start[hI]; e < t->exp_start[hI + 1]; e++)
                (void)merge_add(out->probe, out->weight, &out->count, PB_INTERP_MAX_WEIGHTS, t->exp_probe[e],
                                w8[c] * t->exp_w[e]);
        }
    }
    finish_weights(out, point, opt);
}

static void leaf_weights(const pb_cotree *t, int32_t li, const double u[3], const double point[3],
                         const pb_interp_options *opt, pb_interp_weights *out)
{
    /* Trilinear in t = (u − min) / s with the per-axis size s = 2^l_a (docs/aniso-refinement.md). */
    const uint32_t *l = t->leaves + 4u * (uint32_t)li, *lv = t->levels + 3u * (uint32_t)li;
    double tt[3], w8[8];
    for (int k = 0; k < 3; k++) {
        tt[k] = (u[k] - l[k]) / (double)(1u << lv[k]);
        tt[k] = tt[k] < 0.0 ? 0.0 : (tt[k] > 1.0 ? 1.0 : tt[k]);
    }
    trilinear8(tt, w8);
    if (opt && opt->pair_visibility) {
        /* The visibility field (pb_interp.h): each corner's weight times the ramp of its blended
         * visibility; when that leaves nothing, the plain weights below. */
        const uint8_t *pv = opt->pair_visibility + 64u * (uint32_t)li;
        double wv[8];
        for (uint32_t c = 0; c < 8; c++) {
            double v = 0.0;
            for (uint32_t k = 0; k < 8; k++) v += w8[k] * pb_vis_pair_value(pv[8u * k + c]);
            wv[c] = w8[c] > 0.0 ? w8[c] * vis_ramp(v) : 0.0;
        }
        expand_weights(t, li, wv, point, opt, out);
        if (out->count) return;
    }
    expand_weights(t, li, w8, point, opt, out);
}

static void tet_bary(const pb_tetra *t, uint32_t i, const double p[3], double l[4])
{
    const double *o = t->inv + 12u * i;
    double d[3] = {p[0] - o[9], p[1] - o[10], p[2] - o[11]};
    l[1] = o[0] * d[0] + o[1] * d[1] + o[2] * d[2];
    l[2] = o[3] * d[0] + o[4] * d[1] + o[5] * d[2];
    l[3] = o[6] * d[0] + o[7] * d[1] + o[8] * d[2];
    l[0] = 1.0 - l[1] - l[2] - l[3];
}

/* Best tetrahedron for p (largest smallest barycentric, accepted ≥ −1e-9) and its barycentrics. */
static int32_t tetra_find(const pb_tetra *t, const double p[3], double best_l[4])
{
    if (!t || !p || !t->gstart) return -1;
    uint32_t g[3];
    for (int k = 0; k < 3; k++) {
        double u = (p[k] - t->lo[k]) / t->cell;
        if (!(u >= -1e-9) || !(u <= (double)t->gdims[k] + 1e-9)) return -1;
        double f = floor(u);
        g[k] = f < 0 ? 0 : (f >= t->gdims[k] ? t->gdims[k] - 1 : (uint32_t)f);
    }
    uint64_t c = g[0] + (uint64_t)t->gdims[0] * (g[1] + (uint64_t)t->gdims[1] * g[2]);
    int32_t best = -1;
    double best_min = -1e-9;
    for (uint32_t j = t->gstart[c]; j < t->gstart[c + 1]; j++) {
        uint32_t i = t->gtets[j];
        double l[4];
        tet_bary(t, i, p, l);
        double mn = fmin(fmin(l[0], l[1]), fmin(l[2], l[3]));
        if (mn >= best_min) {
            best_min = mn;
            best = (int32_t)i;
            memcpy(best_l, l, sizeof l);
            if (mn >= 0.0) break; /* inside: any containing tetrahedron gives the same field */
        }
    }
    return best;
}

int32_t pb_tetra_locate(const pb_tetra *t, const double point[3])
{
    double l[4];
    return tetra_find(t, point, l);
}

pb_result pb_interp_query_tetra(const pb_tetra *t, const double point[3], const pb_interp_options *opt,
                                pb_interp_weights *out)
{
    if (!t || !point || !out) return PB_ERROR_INVALID_ARGUMENT;
    out->count = 0;
    double l[4];
    int32_t i = tetra_find(t, point, l);
    if (i < 0) return PB_SUCCESS;
    for (uint32_t k = 0; k < 4; k++) {
        double w = l[k] < 0.0 ? 0.0 : l[k];
        (void)merge_add(out->probe, out->weight, &out->count, PB_INTERP_MAX_WEIGHTS, t->tets[4u * (uint32_t)i + k], w);
    }
    finish_weights(out, point, opt);
    return PB_SUCCESS;
}
