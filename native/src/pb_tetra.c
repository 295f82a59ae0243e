/* Delaunay tetrahedra of probe positions (pb_tetra.h): qhull's tetrahedralisation, the neighbours,
 * the barycentric inverse matrices and the uniform grid of tetrahedron bounds that point location
 * (pb_interp.c) walks. */
#define _POSIX_C_SOURCE 200809L
#include "schnee/pb_tetra.h"

#include "pb_interp_internal.h"

#include <libqhull_r/qhull_ra.h>

#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

void pb_tetra_destroy(pb_tetra *t)
{
    if (!t) return;
    free(t->points);
    free(t->tets);
    free(t->nbr);
    free(t->inv);
    free(t->gstart);
    free(t->gtets);
    free(t);
}

uint32_t pb_tetra_count(const pb_tetra *t) { return t ? t->tet_count : 0; }
uint32_t pb_tetra_point_count(const pb_tetra *t) { return t ? t->point_count : 0; }
const uint32_t *pb_tetra_tets(const pb_tetra *t) { return t ? t->tets : NULL; }
const int32_t *pb_tetra_neighbours(const pb_tetra *t) { return t ? t->nbr : NULL; }

typedef struct face_ref {
    uint32_t v[3];
    uint32_t tet;
    uint32_t i;
} face_ref;

static int cmp_face(const void *pa, const void *pb)
{
    const face_ref *a = pa, *b = pb;
    for (int k = 0; k < 3; k++)
        if (a->v[k] != b->v[k]) return a->v[k] < b->v[k] ? -1 : 1;
    return a->tet < b->tet ? -1 : (a->tet > b->tet ? 1 : 0);
}

static void sort3(uint32_t v[3])
{
    uint32_t tmp;
    if (v[0] > v[1]) tmp = v[0], v[0] = v[1], v[1] = tmp;
    if (v[1] > v[2]) tmp = v[1], v[1] = v[2], v[2] = tmp;
    if (v[0] > v[1]) tmp = v[0], v[0] = v[1], v[1] = tmp;
}

/* Neighbours, inverse matrices and the acceleration grid, from points + tets. */
static pb_result tetra_index(pb_tetra *t, pb_error *err)
{
    uint32_t T = t->tet_count;
    t->nbr = malloc(((size_t)T * 4 + 1) * sizeof(int32_t));
    t->inv = malloc(((size_t)T * 12 + 1) * sizeof(double));
    face_ref *f = malloc(((size_t)T * 4 + 1) * sizeof *f);
    if (!t->nbr || !t->inv || !f) {
        free(f);
        return pb_error_set(err, PB_ERROR_OUT_OF_MEMORY, "out of memory for %u tetrahedra", T);
    }
    for (uint32_t i = 0; i < T; i++)
        for (uint32_t k = 0; k < 4; k++) {
            face_ref *r = f + 4u * i + k;
            for (uint32_t m = 0, n = 0; m < 4; m++)
                if (m != k) r->v[n++] = t->tets[4u * i + m];
            sort3(r->v);
            r->tet = i;
            r->i = k;
            t->nbr[4u * i + k] = -1;
        }
    qsort(f, (size_t)T * 4, sizeof *f, cmp_face);
    for (size_t j = 0; j + 1 < (size_t)T * 4; j++)
        if (memcmp(f[j].v, f[j + 1].v, sizeof f[j].v) == 0) {
            t->nbr[4u * f[j].tet + f[j].i] = (int32_t)f[j + 1].tet;
            t->nbr[4u * f[j + 1].tet + f[j + 1].i] = (int32_t)f[j].tet;
            j++;
        }
    free(f);

    double lo[3] = {INFINITY, INFINITY, INFINITY}, hi[3] = {-INFINITY, -INFINITY, -INFINITY};
    for (uint32_t i = 0; i < t->point_count; i++)
        for (int k = 0; k < 3; k++) {
            double v = t->points[3u * i + (uint32_t)k];
            lo[k] = v < lo[k] ? v : lo[k];
            hi[k] = v > hi[k] ? v : hi[k];
        }
    for (uint32_t i = 0; i < T; i++) {
        const double *v0 = t->points + 3u * t->tets[4u * i];
        double m[3][3], maxe = 0.0;
        for (int r = 0; r < 3; r++)
            for (int k = 0; k < 3; k++) {
                m[r][k] = t->points[3u * t->tets[4u * i + (uint32_t)r + 1] + (uint32_t)k] - v0[k];
                maxe = fmax(maxe, fabs(m[r][k]));
            }
        /* m rows are edges e_r; barycentrics λ_r = (M⁻ᵀ (p − v0))_r with M = [e0 e1 e2] as columns. */
        double det = m[0][0] * (m[1][1] * m[2][2] - m[1][2] * m[2][1]) -
                     m[0][1] * (m[1][0] * m[2][2] - m[1][2] * m[2][0]) +
                     m[0][2] * (m[1][0] * m[2][1] - m[1][1] * m[2][0]);
        double *o = t->inv + 12u * i;
        if (!(fabs(det) > 1e-12 * maxe * maxe * maxe)) {
            for (int k = 0; k < 12; k++) o[k] = NAN;
            continue;
        }
        /* Inverse of the matrix whose columns are e0, e1, e2 = transpose of m: inv(mᵀ) = inv(m)ᵀ. */
        double c[3][3];
        c[0][0] = m[1][1] * m[2][2] - m[1][2] * m[2][1];
        c[0][1] = m[1][2] * m[2][0] - m[1][0] * m[2][2];
        c[0][2] = m[1][0] * m[2][1] - m[1][1] * m[2][0];
        c[1][0] = m[0][2] * m[2][1] - m[0][1] * m[2][2];
        c[1][1] = m[0][0] * m[2][2] - m[0][2] * m[2][0];
        c[1][2] = m[0][1] * m[2][0] - m[0][0] * m[2][1];
        c[2][0] = m[0][1] * m[1][2] - m[0][2] * m[1][1];
        c[2][1] = m[0][2] * m[1][0] - m[0][0] * m[1][2];
        c[2][2] = m[0][0] * m[1][1] - m[0][1] * m[1][0];
        /* c is the cofactor matrix of m: inv(m) = cᵀ/det, so inv(mᵀ) = c/det; row r gives λ_{r+1}. */
        for (int r = 0; r < 3; r++)
            for (int k = 0; k < 3; k++) o[3 * r + k] = c[r][k] / det;
        for (int k = 0; k < 3; k++) o[9 + k] = v0[k];
    }

    /* Uniform grid, about 2 tetrahedra per cell, at most 128 cells per axis. */
    double ext = fmax(fmax(hi[0] - lo[0], hi[1] - lo[1]), hi[2] - lo[2]);
    double vol = fmax(hi[0] - lo[0], ext * 1e-3) * fmax(hi[1] - lo[1], ext * 1e-3) * fmax(hi[2] - lo[2], ext * 1e-3);
    double cell = cbrt(vol / fmax((double)T / 2.0, 1.0));
    if (!(cell > 0.0)) cell = 1.0;
    uint64_t cells = 1;
    for (int k = 0; k < 3; k++) {
        double d = ceil((hi[k] - lo[k]) / cell);
        if (d < 1) d = 1;
        if (d > 128) d = 128;
        t->gdims[k] = (uint32_t)d;
        cells *= t->gdims[k];
    }
    for (int k = 0; k < 3; k++) {
        /* One cell size for all axes would overflow 128 on flat sets: per-axis via the max. */
        double c = (hi[k] - lo[k]) / t->gdims[k];
        if (c > cell) cell = c;
    }
    memcpy(t->lo, lo, sizeof lo);
    t->cell = cell;
    t->gstart = calloc((size_t)cells + 1, sizeof(uint32_t));
    if (!t->gstart) return pb_error_set(err, PB_ERROR_OUT_OF_MEMORY, "out of memory for the tetrahedron grid");
    uint64_t total = 0;
    for (int pass = 0; pass < 2; pass++) {
        if (pass == 1) {
            uint32_t run = 0;
            for (uint64_t c = 0; c < cells; c++) {
                uint32_t k = t->gstart[c];
                t->gstart[c] = run;
                run += k;
            }
            t->gstart[cells] = run;
            total = run;
            t->gtets = malloc(((size_t)total + 1) * sizeof(uint32_t));
            if (!t->gtets) return pb_error_set(err, PB_ERROR_OUT_OF_MEMORY, "out of memory for the tetrahedron grid");
        }
        uint32_t *fill = NULL;
        if (pass == 1) {
            fill = malloc(((size_t)cells + 1) * sizeof(uint32_t));
            if (!fill) return pb_error_set(err, PB_ERROR_OUT_OF_MEMORY, "out of memory for the tetrahedron grid");
            memcpy(fill, t->gstart, (size_t)cells * sizeof(uint32_t));
        }
        for (uint32_t i = 0; i < T; i++) {
            if (isnan(t->inv[12u * i])) continue;
            uint32_t a[3], b[3];
            for (int k = 0; k < 3; k++) {
                double mn = INFINITY, mx = -INFINITY;
                for (int v = 0; v < 4; v++) {
                    double x = t->points[3u * t->tets[4u * i + (uint32_t)v] + (uint32_t)k];
                    mn = fmin(mn, x), mx = fmax(mx, x);
                }
                double ga = floor((mn - lo[k]) / cell - 1e-9), gb = floor((mx - lo[k]) / cell + 1e-9);
                a[k] = ga < 0 ? 0 : (ga >= t->gdims[k] ? t->gdims[k] - 1 : (uint32_t)ga);
                b[k] = gb < 0 ? 0 : (gb >= t->gdims[k] ? t->gdims[k] - 1 : (uint32_t)gb);
            }
            for (uint32_t z = a[2]; z <= b[2]; z++)
                for (uint32_t y = a[1]; y <= b[1]; y++)
                    for (uint32_t x = a[0]; x <= b[0]; x++) {
                        uint64_t c = x + (uint64_t)t->gdims[0] * (y + (uint64_t)t->gdims[1] * z);
                        if (pass == 0)
                            t->gstart[c]++;
                        else
                            t->gtets[fill[c]++] = i;
                    }
        }
        free(fill);
    }
    return PB_SUCCESS;
}

static pb_result tetra_alloc(const double *positions, uint32_t count, pb_tetra **out, pb_error *err)
{
    if (!positions || !out) return pb_error_set(err, PB_ERROR_INVALID_ARGUMENT, "tetrahedra: NULL argument");
    *out = NULL;
    if (count < 4)
        return pb_error_set(err, PB_ERROR_INVALID_ARGUMENT, "%u probes cannot be tetrahedralised; at least 4 needed",
                            count);
    for (uint64_t i = 0; i < (uint64_t)count * 3; i++)
        if (!isfinite(positions[i]))
            return pb_error_set(err, PB_ERROR_NON_FINITE, "probe %llu position[%llu] is %g",
                                (unsigned long long)(i / 3), (unsigned long long)(i % 3), positions[i]);
    pb_tetra *t = calloc(1, sizeof *t);
    if (!t) return pb_error_set(err, PB_ERROR_OUT_OF_MEMORY, "out of memory");
    t->point_count = count;
    t->points = malloc((size_t)count * 3 * sizeof(double));
    if (!t->points) {
        free(t);
        return pb_error_set(err, PB_ERROR_OUT_OF_MEMORY, "out of memory for %u probes", count);
    }
    memcpy(t->points, positions, (size_t)count * 3 * sizeof(double));
    *out = t;
    return PB_SUCCESS;
}

pb_result pb_tetra_create(const double *positions, uint32_t count, pb_tetra **out, pb_error *err)
{
    pb_tetra *t;
    pb_result r = tetra_alloc(positions, count, &t, err);
    if (r != PB_SUCCESS) return r;
    char *errbuf = NULL;
    size_t errlen = 0;
    FILE *errfile = open_memstream(&errbuf, &errlen);
    qhT qh_qh;
    qhT *qh = &qh_qh;
    qh_zero(qh, errfile);
    char flags[] = "qhull d Qbb Qc Qz Q12 Qt";
    int exitcode = qh_new_qhull(qh, 3, (int)count, t->points, False, flags, NULL, errfile);
    if (exitcode == 0) {
        facetT *facet;
        vertexT *vertex, **vertexp;
        uint32_t T = 0;
        FORALLfacets
        {
            if (!facet->upperdelaunay) T++;
        }
        t->tets = malloc(((size_t)T + 1) * 4 * sizeof(uint32_t));
        if (!t->tets) {
            r = pb_error_set(err, PB_ERROR_OUT_OF_MEMORY, "out of memory for %u tetrahedra", T);
        } else {
            uint32_t i = 0;
            FORALLfacets
            {
                if (facet->upperdelaunay) continue;
                uint32_t k = 0;
                FOREACHvertex_(facet->vertices)
                {
                    if (k < 4) t->tets[4u * i + k] = (uint32_t)qh_pointid(qh, vertex->point);
                    k++;
                }
                if (k == 4) i++; /* Qt makes every facet a simplex; anything else is skipped */
            }
            t->tet_count = i;
        }
    }
    qh_freeqhull(qh, !qh_ALL);
    int curlong, totlong;
    qh_memfreeshort(qh, &curlong, &totlong);
    if (errfile) fclose(errfile);
    if (exitcode != 0) {
        /* qhull's own text (its first line) says why: coplanar input, too few points, ... */
        char first[200] = "";
        if (errbuf) {
            size_t n = strcspn(errbuf, "\n");
            if (n >= sizeof first) n = sizeof first - 1;
            memcpy(first, errbuf, n);
            first[n] = 0;
        }
        r = pb_error_set(err, PB_ERROR_INVALID_ARGUMENT,
                         "the %u probe positions cannot be tetrahedralised (qhull error %d: %s); are they coplanar?",
                         count, exitcode, first);
    }
    free(errbuf);
    if (r == PB_SUCCESS && t->tet_count == 0)
        r = pb_error_set(err, PB_ERROR_INVALID_ARGUMENT, "the %u probe positions give no tetrahedron", count);
    if (r == PB_SUCCESS) r = tetra_index(t, err);
    if (r != PB_SUCCESS) {
        pb_tetra_destroy(t);
        return r;
    }
    *out = t;
    return PB_SUCCESS;
}

pb_result pb_tetra_create_from(const double *positions, uint32_t count, const uint32_t *tets, uint32_t tet_count,
                               pb_tetra **out, pb_error *err)
{
    if (!tets && tet_count) return pb_error_set(err, PB_ERROR_INVALID_ARGUMENT, "tetrahedra: NULL tets");
    pb_tetra *t;
    pb_result r = tetra_alloc(positions, count, &t, err);
    if (r != PB_SUCCESS) return r;
    t->tets = malloc(((size_t)tet_count + 1) * 4 * sizeof(uint32_t));
    if (!t->tets) {
        pb_tetra_destroy(t);
        return pb_error_set(err, PB_ERROR_OUT_OF_MEMORY, "out of memory for %u tetrahedra", tet_count);
    }
    for (uint64_t i = 0; i < (uint64_t)tet_count * 4; i++)
        if (tets[i] >= count) {
            pb_tetra_destroy(t);
            return pb_error_set(err, PB_ERROR_INVALID_ARGUMENT, "tetrahedron %llu vertex %llu is %u, not below %u",
                                (unsigned long long)(i / 4), (unsigned long long)(i % 4), tets[i], count);
        }
    if (tet_count) memcpy(t->tets, tets, (size_t)tet_count * 4 * sizeof(uint32_t));
    t->tet_count = tet_count;
    r = tetra_index(t, err);
    if (r != PB_SUCCESS) {
        pb_tetra_destroy(t);
        return r;
    }
    *out = t;
    return PB_SUCCESS;
}
