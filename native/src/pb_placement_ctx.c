/* Probe placement: the context of one call (pb_placement_internal.h): settings and validation,
 * progress and cancelling, the parallel for, the occluders of the volumes and of the scene geometry
 * and the queries on them. */
#include "pb_placement_internal.h"

#include "schnee/pb_shprobe.h"

#include "pb_file.h"

#include <float.h>
#include <math.h>
#include <pthread.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>
#include <unistd.h>

/* ---------------------------------------------------------------------------------------------- */
/* Small helpers                                                                                   */

static double now_seconds(void)
{
    struct timespec ts;
    clock_gettime(CLOCK_MONOTONIC, &ts);
    return (double)ts.tv_sec + 1e-9 * (double)ts.tv_nsec;
}

static const char *mesh_name(const pb_mesh_desc *m) { return (m->name && m->name[0]) ? m->name : "(unnamed)"; }

/* Reports progress from the calling thread; returns false (and raises the cancel flag) when the
 * callback asks to cancel. `force` reports regardless of the 50 ms throttle. */
bool pb_oct_report(oct_ctx *c, double fraction, const char *stage, bool force)
{
    if (atomic_load(&c->cancel)) return false;
    if (!c->desc->progress) return true;
    double t = now_seconds();
    if (!force && t - c->last_report < 0.05) return true;
    c->last_report = t;
    if (!c->desc->progress(c->desc->progress_user, fraction, stage)) {
        atomic_store(&c->cancel, true);
        return false;
    }
    return true;
}

pb_result pb_oct_cancelled(oct_ctx *c, const char *stage)
{
    return pb_error_set(c->err, PB_ERROR_CANCELLED, "probe placement cancelled during %s", stage);
}

/* The first Embree error any occluder of the call met, as a pb_error. */
pb_result pb_oct_occluder_check(oct_ctx *c, const char *what)
{
    pb_result r = pb_occluder_error(c->vol, c->err, what);
    if (!r) r = pb_occluder_error(c->geo, c->err, what);
    if (!r) r = pb_point_index_error(c->probe_index, c->err, what);
    return r;
}

/* ---------------------------------------------------------------------------------------------- */
/* Parallel for: the calling thread and up to threads−1 workers take chunks of [0, count) from an
 * atomic counter; only the calling thread reports progress (so a Python callback runs on the
 * thread that called pb_placement_build).                                                          */

typedef void (*range_fn)(oct_ctx *c, void *user, uint64_t begin, uint64_t end);

typedef struct par_job {
    oct_ctx *c;
    range_fn fn;
    void *user;
    uint64_t count, chunk;
    atomic_uint_fast64_t next, done;
} par_job;

static void par_run_chunks(par_job *j, bool main_thread, double p0, double p1, const char *stage)
{
    for (;;) {
        if (atomic_load(&j->c->cancel)) return;
        uint64_t b = atomic_fetch_add(&j->next, j->chunk);
        if (b >= j->count) return;
        uint64_t e = b + j->chunk < j->count ? b + j->chunk : j->count;
        j->fn(j->c, j->user, b, e);
        uint64_t done = atomic_fetch_add(&j->done, e - b) + (e - b);
        if (main_thread) pb_oct_report(j->c, p0 + (p1 - p0) * (double)done / (double)j->count, stage, false);
    }
}

static void *par_worker(void *arg)
{
    par_run_chunks((par_job *)arg, false, 0, 0, NULL);
    return NULL;
}

/* Returns false when cancelled. */
bool pb_oct_parallel_for(oct_ctx *c, uint64_t count, uint64_t chunk, range_fn fn, void *user, double p0, double p1,
                         const char *stage)
{
    if (!pb_oct_report(c, p0, stage, true)) return false;
    if (count == 0) return true;
    par_job j;
    j.c = c;
    j.fn = fn;
    j.user = user;
    j.count = count;
    j.chunk = chunk ? chunk : 1;
    atomic_init(&j.next, 0);
    atomic_init(&j.done, 0);
    uint64_t chunks = (count + j.chunk - 1) / j.chunk;
    uint32_t nthreads = c->threads;
    if ((uint64_t)nthreads > chunks) nthreads = (uint32_t)chunks;
    pthread_t tids[PB_MAX_THREADS];
    uint32_t started = 0;
    for (uint32_t t = 1; t < nthreads; t++) {
        if (pthread_create(&tids[started], NULL, par_worker, &j) != 0) break; /* run with fewer */
        started++;
    }
    par_run_chunks(&j, true, p0, p1, stage);
    for (uint32_t t = 0; t < started; t++) pthread_join(tids[t], NULL);
    if (atomic_load(&c->cancel)) return false;
    return pb_oct_report(c, p1, stage, true);
}

/* ---------------------------------------------------------------------------------------------- */
/* Queries                                                                                          */

bool pb_oct_box_touches_geometry(const oct_ctx *c, const double centre[3], double h)
{
    return pb_occluder_box_overlaps(c->geo, centre, h + c->eps, c->eps);
}

bool pb_oct_box_straddles_volumes(const oct_ctx *c, const double centre[3], double h)
{
    return pb_occluder_box_overlaps(c->vol, centre, h - c->eps, c->eps);
}

/* Inside test: for each of three fixed directions, a ray from the point collects every volume
 * triangle it crosses (an Embree filter passed with the call rejects each hit so traversal continues); the point
 * is inside the union for that direction when some volume is crossed an odd number of times. The
 * answer is the majority of the three directions, so a ray that grazes an edge or vertex (and may
 * count a crossing twice or not at all) is outvoted. */
#define INSIDE_MAX_HITS 512

/* The crossings of one ray (pb_occluder_crossings): mesh and triangle of each. */
typedef struct inside_ray {
    uint32_t count;
    uint32_t mesh[INSIDE_MAX_HITS];
    uint32_t prim[INSIDE_MAX_HITS];
} inside_ray;

static const double inside_dirs[3][3] = {
    {0.26726124191242440, 0.53452248382484879, 0.80178372573727319},  /* (1,2,3)/√14 */
    {-0.71066905451870360, 0.24313941206692493, 0.66003068395598600}, /* arbitrary, off-axis */
    {0.13168938050081670, -0.82305862813010440, 0.55217424537227870},
};

/* Returns 1 inside, 0 outside, −1 unknown (too many crossings recorded). */
static int inside_one_dir(const oct_ctx *c, const double p[3], const double d[3], inside_ray *r)
{
    if (!pb_occluder_crossings(c->vol, p, d, INSIDE_MAX_HITS, r->mesh, r->prim, &r->count)) return -1;
    /* Some volume crossed an odd number of times? */
    for (uint32_t k = 0; k < r->count; k++) {
        uint32_t g = r->mesh[k], n = 0;
        bool seen_before = false;
        for (uint32_t i = 0; i < r->count; i++) {
            if (r->mesh[i] == g) {
                if (i < k) {
                    seen_before = true;
                    break;
                }
                n++;
            }
        }
        if (!seen_before && (n & 1u)) return 1;
    }
    return 0;
}

bool pb_oct_point_inside(const oct_ctx *c, const double p[3])
{
    inside_ray rc; /* ~4 KiB, fine on any thread's stack */
    inside_ray *r = &rc;
    int votes_in = 0, votes = 0;
    for (int k = 0; k < 3; k++) {
        int v = inside_one_dir(c, p, inside_dirs[k], r);
        if (v >= 0) {
            votes++;
            votes_in += v;
        }
        /* Two agreeing directions already decide the majority. */
        if (votes_in >= 2 || votes - votes_in >= 2) break;
    }
    return votes_in * 2 > votes;
}

/* ---------------------------------------------------------------------------------------------- */
/* Stage 1: validation                                                                              */

static int cmp_u64(const void *a, const void *b)
{
    uint64_t x = *(const uint64_t *)a, y = *(const uint64_t *)b;
    return x < y ? -1 : x > y;
}

static pb_result check_mesh(oct_ctx *c, const pb_mesh_desc *m, const char *kind, uint32_t index)
{
    if (m->triangle_count > 0 && (!m->indices || !m->positions))
        return pb_error_set(c->err, PB_ERROR_INVALID_ARGUMENT, "%s '%s' (#%u) has %u triangles but no %s array", kind,
                            mesh_name(m), index, m->triangle_count, m->indices ? "position" : "index");
    if (m->vertex_count > 0 && !m->positions)
        return pb_error_set(c->err, PB_ERROR_INVALID_ARGUMENT, "%s '%s' (#%u) has %u vertices but no position array",
                            kind, mesh_name(m), index, m->vertex_count);
    for (size_t i = 0; i < 3 * (size_t)m->triangle_count; i++) {
        if (m->indices[i] >= m->vertex_count)
            return pb_error_set(c->err, PB_ERROR_INVALID_ARGUMENT,
                                "%s '%s' (#%u): triangle %zu uses vertex index %u, but the mesh has "
                                "only %u vertices",
                                kind, mesh_name(m), index, i / 3, m->indices[i], m->vertex_count);
    }
    for (size_t i = 0; i < 3 * (size_t)m->vertex_count; i++) {
        if (!isfinite(m->positions[i])) {
            /* Every coordinate of the vertex, NaN and Inf spelled as such (never "-nan"). */
            const double *v = m->positions + 3 * (i / 3);
            char b[3][32];
            return pb_error_set(c->err, PB_ERROR_NON_FINITE,
                                "%s '%s' (#%u): vertex %zu = (%s, %s, %s) has a non-finite %c coordinate (%s)", kind,
                                mesh_name(m), index, i / 3, pb_format_double_(v[0], b[0], sizeof b[0]),
                                pb_format_double_(v[1], b[1], sizeof b[1]), pb_format_double_(v[2], b[2], sizeof b[2]),
                                "xyz"[i % 3], isnan(m->positions[i]) ? "NaN" : "infinite");
        }
        if (fabs(m->positions[i]) > 1e15)
            return pb_error_set(c->err, PB_ERROR_INVALID_ARGUMENT,
                                "%s '%s' (#%u): vertex %zu coordinate %g is out of range (|x| > 1e15 m)", kind,
                                mesh_name(m), index, i / 3, m->positions[i]);
    }
    return PB_SUCCESS;
}

/* Edge-manifold check of a volume: every directed edge (u, v) of a non-degenerate triangle must
 * occur exactly once and its reverse (v, u) exactly once. Triangles that repeat an index have no
 * area and are skipped (their two real edges cancel each other anyway). */
static pb_result check_closed(oct_ctx *c, const pb_mesh_desc *m, uint32_t index)
{
    size_t n = 0;
    uint64_t *edges = malloc(sizeof(uint64_t) * 3 * ((size_t)m->triangle_count + 1));
    if (!edges) return pb_error_set(c->err, PB_ERROR_OUT_OF_MEMORY, "out of memory checking volume '%s'", mesh_name(m));
    for (size_t t = 0; t < m->triangle_count; t++) {
        const uint32_t *i = &m->indices[3 * t];
        if (i[0] == i[1] || i[1] == i[2] || i[2] == i[0]) continue;
        for (int k = 0; k < 3; k++) edges[n++] = ((uint64_t)i[k] << 32) | i[(k + 1) % 3];
    }
    if (n == 0) {
        free(edges);
        return pb_error_set(c->err, PB_ERROR_OPEN_MESH,
                            "probe volume '%s' (#%u) has no non-degenerate triangles; volumes must "
                            "be closed meshes",
                            mesh_name(m), index);
    }
    qsort(edges, n, sizeof *edges, cmp_u64);
    size_t bad = 0;
    uint64_t example = 0;
    for (size_t k = 0; k < n; k++) {
        bool ok = !(k > 0 && edges[k] == edges[k - 1]) && !(k + 1 < n && edges[k] == edges[k + 1]);
        if (ok) {
            uint64_t rev = (edges[k] << 32) | (edges[k] >> 32);
            const uint64_t *r = bsearch(&rev, edges, n, sizeof *edges, cmp_u64);
            ok = r && !(r > edges && r[-1] == rev) && !(r + 1 < edges + n && r[1] == rev);
        }
        if (!ok) {
            if (bad == 0) example = edges[k];
            bad++;
        }
    }
    free(edges);
    if (bad)
        return pb_error_set(c->err, PB_ERROR_OPEN_MESH,
                            "probe volume '%s' (#%u) is not a closed mesh: %zu edge%s not shared by "
                            "exactly two triangles with opposite orientation (e.g. the edge from "
                            "vertex %u to vertex %u); close the holes and make the normals consistent",
                            mesh_name(m), index, bad, bad == 1 ? " is" : "s are", (uint32_t)(example >> 32),
                            (uint32_t)example);
    return PB_SUCCESS;
}

/* A cell count for messages: exact below 10^9, else 4 significant digits (a 1e-300 m cell size
 * must not print a 300-digit number). */
static const char *count_text(double v, char *buf, size_t n)
{
    snprintf(buf, n, v < 1e9 ? "%.0f" : "%.4g", v);
    return buf;
}

/* The frame (centre of the volumes' bounding box) and the occupancy grid, within max_grid_cells. */
static pb_result setup_grid(oct_ctx *c)
{
    const pb_placement_desc *d = c->desc;
    /* Bounding box of the volumes' referenced vertices. */
    for (int a = 0; a < 3; a++) {
        c->bbmin[a] = INFINITY;
        c->centre[a] = -INFINITY; /* holds the max until the end of the loop */
    }
    for (uint32_t i = 0; i < d->volume_count; i++) {
        const pb_mesh_desc *m = &d->volumes[i];
        for (size_t t = 0; t < 3 * (size_t)m->triangle_count; t++) {
            const double *p = &m->positions[3 * (size_t)m->indices[t]];
            for (int a = 0; a < 3; a++) {
                c->bbmin[a] = fmin(c->bbmin[a], p[a]);
                c->centre[a] = fmax(c->centre[a], p[a]);
            }
        }
    }
    uint64_t total = 1;
    bool overflow = false;
    double want[3];
    for (int a = 0; a < 3; a++) {
        double extent = c->centre[a] - c->bbmin[a];
        c->centre[a] = c->bbmin[a] + 0.5 * extent;
        c->origin_rel[a] = c->bbmin[a] - c->centre[a];
        /* ceil with a tolerance of 1e-6 cell so that 10 m / 0.5 m stays 20 cells after rounding */
        want[a] = ceil(extent / c->min_cell - 1e-6);
        if (want[a] < 1) want[a] = 1;
        if (!(want[a] <= (double)PB_MAX_AXIS_CELLS)) {
            overflow = true;
            c->dims[a] = 0;
        } else {
            c->dims[a] = (uint32_t)want[a];
            if (!overflow && total > UINT64_MAX / c->dims[a])
                overflow = true;
            else if (!overflow)
                total *= c->dims[a];
        }
    }
    c->eps = PB_BOX_EPS * c->min_cell;
    if (overflow || total > c->max_cells || total > SIZE_MAX / sizeof(int32_t)) {
        double cells = want[0] * want[1] * want[2]; /* may be inf for absurd sizes: printed as such */
        /* min·cbrt(X·Y·Z / limit), factor by factor so that it does not overflow. */
        double suggest =
            c->min_cell * cbrt(want[0]) * cbrt(want[1]) * cbrt(want[2]) / cbrt((double)c->max_cells) * 1.01;
        char dx[32], dy[32], dz[32], total_text[48], mib_text[48];
        if (isfinite(cells)) {
            snprintf(total_text, sizeof total_text, "%.4g", cells);
            snprintf(mib_text, sizeof mib_text, "%.4g", cells * 4.0 / 1048576.0);
        } else {
            snprintf(total_text, sizeof total_text, "more than 1e308");
            snprintf(mib_text, sizeof mib_text, "more than 1e302");
        }
        return pb_error_set(c->err, PB_ERROR_TOO_LARGE,
                            "the occupancy grid would have %s x %s x %s = %s cells "
                            "(%s MiB) at Min Cell Size %g m, above the limit of %llu cells "
                            "(%.4g MiB); use a larger Min Cell Size (about %.3g m or more) or "
                            "smaller probe volumes",
                            count_text(want[0], dx, sizeof dx), count_text(want[1], dy, sizeof dy),
                            count_text(want[2], dz, sizeof dz), total_text, mib_text, c->min_cell,
                            (unsigned long long)c->max_cells, (double)c->max_cells * 4.0 / 1048576.0, suggest);
    }
    return PB_SUCCESS;
}

pb_result pb_oct_setup(oct_ctx *c)
{
    const pb_placement_desc *d = c->desc;
    if (!d->volumes || d->volume_count == 0)
        return pb_error_set(c->err, PB_ERROR_INVALID_ARGUMENT,
                            "probe placement needs at least one probe volume (volume_count = %u)", d->volume_count);
    if (d->geometry_count > 0 && !d->geometry)
        return pb_error_set(c->err, PB_ERROR_INVALID_ARGUMENT, "geometry_count is %u but geometry is NULL",
                            d->geometry_count);

    c->min_cell = d->min_cell_size == 0 ? PB_DEFAULT_MIN_CELL : d->min_cell_size;
    double max_cell = d->max_cell_size == 0 ? PB_DEFAULT_MAX_CELL : d->max_cell_size;
    if (!(c->min_cell > 0) || !isfinite(c->min_cell))
        return pb_error_set(c->err, PB_ERROR_INVALID_ARGUMENT,
                            "min_cell_size must be a positive finite length in metres (got %g)", d->min_cell_size);
    if (!(max_cell > 0) || !isfinite(max_cell))
        return pb_error_set(c->err, PB_ERROR_INVALID_ARGUMENT,
                            "max_cell_size must be a positive finite length in metres (got %g)", d->max_cell_size);
    if (max_cell < c->min_cell)
        return pb_error_set(c->err, PB_ERROR_INVALID_ARGUMENT,
                            "max_cell_size (%g m) is smaller than min_cell_size (%g m)", max_cell, c->min_cell);
    c->solid_rays = d->solid_ray_count == 0 ? PB_SOLID_DEFAULT_RAYS : d->solid_ray_count;
    if (c->solid_rays > PB_SOLID_MAX_RAYS)
        return pb_error_set(c->err, PB_ERROR_INVALID_ARGUMENT, "solid_ray_count %u is above the maximum of %u",
                            c->solid_rays, PB_SOLID_MAX_RAYS);
    c->solid_ratio = d->solid_backface_ratio == 0 ? PB_SOLID_DEFAULT_BACKFACE_RATIO : d->solid_backface_ratio;
    if (!(c->solid_ratio > 0 && c->solid_ratio <= 1))
        return pb_error_set(c->err, PB_ERROR_INVALID_ARGUMENT,
                            "solid_backface_ratio must be in (0, 1] (got %g; 1 disables pruning)",
                            d->solid_backface_ratio);
    c->max_cells = d->max_grid_cells == 0 ? PB_DEFAULT_MAX_GRID_CELLS : d->max_grid_cells;
    if (c->max_cells > PB_SHPROBE_MAX_GRID_CELLS)
        return pb_error_set(c->err, PB_ERROR_INVALID_ARGUMENT,
                            "max_grid_cells %llu is above the hard limit of %llu cells (%.4g GiB), the largest grid a "
                            ".shprobe file holds",
                            (unsigned long long)d->max_grid_cells, (unsigned long long)PB_SHPROBE_MAX_GRID_CELLS,
                            (double)PB_SHPROBE_MAX_GRID_CELLS * 4.0 / 1073741824.0);
    uint32_t threads = d->thread_count;
    if (threads == 0) {
        long n = sysconf(_SC_NPROCESSORS_ONLN);
        threads = n > 0 ? (uint32_t)n : 1;
    }
    c->threads = threads > PB_MAX_THREADS ? PB_MAX_THREADS : threads;

    /* Root cell: max_cell_size rounded down to min·2^k (1e-9 relative slack so that 16/0.5 = 2^5
     * is not lost to rounding). */
    uint32_t k = 0;
    while (k < PB_MAX_LEVELS && c->min_cell * (double)(UINT64_C(1) << (k + 1)) <= max_cell * (1 + 1e-9)) k++;
    c->root_lg = k;

    for (uint32_t i = 0; i < d->volume_count; i++) {
        pb_result r = check_mesh(c, &d->volumes[i], "probe volume", i);
        if (r) return r;
    }
    for (uint32_t i = 0; i < d->geometry_count; i++) {
        pb_result r = check_mesh(c, &d->geometry[i], "scene mesh", i);
        if (r) return r;
    }
    for (uint32_t i = 0; i < d->volume_count; i++) {
        pb_result r = check_closed(c, &d->volumes[i], i);
        if (r) return r;
        if (!pb_oct_report(c, 0.05 * (i + 1) / d->volume_count, "checking meshes", false))
            return pb_oct_cancelled(c, "checking meshes");
    }
    return setup_grid(c);
}

/* ---------------------------------------------------------------------------------------------- */
/* Stage 2: occluders                                                                              */

/* An occluder of `count` meshes, positions relative to the volumes' centre. */
static pb_result build_occluder(oct_ctx *c, const pb_mesh_desc *meshes, uint32_t count, uint32_t flags,
                                const char *what, pb_occluder **out)
{
    return pb_occluder_create_from_meshes(meshes, count, c->centre, c->threads, flags, what, out, c->err);
}

/* The volumes' occluder (robust, with the crossings of the inside test) and the geometry's (when
 * there is any). */
pb_result pb_oct_build_scenes(oct_ctx *c)
{
    if (!pb_oct_report(c, 0.05, "building BVH", true)) return pb_oct_cancelled(c, "building BVH");
    pb_result r = build_occluder(c, c->desc->volumes, c->desc->volume_count,
                                 PB_OCCLUDER_FILTERABLE | PB_OCCLUDER_ROBUST, "probe volume", &c->vol);
    if (r) return r;
    bool any_geometry = false;
    for (uint32_t i = 0; i < c->desc->geometry_count; i++) any_geometry |= c->desc->geometry[i].triangle_count > 0;
    if (any_geometry) {
        r = build_occluder(c, c->desc->geometry, c->desc->geometry_count, 0, "scene geometry", &c->geo);
        if (r) return r;
    }
    if (!pb_oct_report(c, 0.10, "building BVH", true)) return pb_oct_cancelled(c, "building BVH");
    return PB_SUCCESS;
}

/* The context of one pb_placement_build / pb_placement_classify call: set up before, and every
 * Embree object, table and lock it gained released after (fields never made stay NULL / false). */
void pb_oct_ctx_init(oct_ctx *c, const pb_placement_desc *desc, pb_error *err)
{
    c->desc = desc;
    c->err = err;
    atomic_init(&c->cancel, false);
    c->last_report = -1e300;
}

void pb_oct_ctx_free(oct_ctx *c)
{
    pb_point_index_destroy(c->probe_index);
    pb_occluder_destroy(c->geo);
    pb_occluder_destroy(c->vol);
    free(c->ray_dirs);
    free(c);
}
