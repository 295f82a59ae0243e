/* Probe placement: sparse adaptive octree over the union of closed probe volumes (DESIGN.md §6,
 * docs/placement.md).
 *
 * Stages (each reported through the progress callback, each cancellable):
 *   1. "checking meshes"  validate inputs, edge-manifold check of every volume, grid size/limits.
 *   2. "building BVH"     one Embree device (threads = thread_count), three scenes: volumes,
 *                         scene geometry, later the probe points.
 *   3. "octree"           level by level from root cells of max_cell_size (rounded down to
 *                         min·2^k) aligned to the occupancy grid; a cell subdivides while its box
 *                         touches a scene triangle (exact SAT, candidates from an Embree point query
 *                         with the box's bounding sphere) or straddles the volume surface with its
 *                         centre outside the volumes; cells entirely outside are dropped.
 *   4. "solid test"       fixed spherical-Fibonacci rays from each leaf centre inside the volumes;
 *                         more than solid_backface_ratio back-face hits → pruned.
 *   5. "occupancy grid"   every grid cell whose centre is inside the volumes gets its leaf's probe.
 *   6. "nearest probe"    grid cells whose leaf has no valid probe get the nearest valid probe
 *                         (Embree point query over the probe points).
 *
 * Precision: every input position is used relative to the centre of the volumes' bounding box,
 * computed in double; Embree sees floats of those relative positions (exact enough for candidate
 * search and rays), while the box-triangle tests and all outputs use doubles.
 *
 * Determinism: the result does not depend on the thread count or on Embree's traversal order:
 * per-item results go to per-item slots, probes are numbered in Morton order of their leaf cells,
 * and the nearest-probe search breaks distance ties by the smaller probe index.
 */
#include "schnee/pb_octree.h"

#include "schnee/pb_occluder.h"
#include "schnee/pb_shprobe.h"

#include "pb_file.h"

#include <float.h>
#include <math.h>
#include <pthread.h>
#include <stdatomic.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>
#include <unistd.h>

/* Defaults of pb_placement_desc (a zero field selects them; documented in docs/placement.md). */
#define PB_DEFAULT_MIN_CELL 0.5
#define PB_DEFAULT_MAX_CELL 16.0
/* 64 rays: a probe inside a closed solid sees ~100 % back faces, one in the open 0 %; 64
 * directions resolve the ratio in steps of 1.6 % and cost ~64 ray casts, negligible next to the
 * panorama render of the same probe. */
#define PB_DEFAULT_SOLID_RAYS 64u
/* 0.25: single-sided planes facing away and small open meshes can show a probe some back faces
 * while it is in free space; a probe inside a closed solid sees (nearly) only back faces. A quarter
 * of the hitting rays tolerates such stray back faces yet prunes anything enclosed by geometry. */
#define PB_DEFAULT_BACKFACE_RATIO 0.25
/* 2^26 cells = 256 MiB of int32 grid (and of .shprobe file): a 100 m × 100 m × 25 m level at the
 * default 0.5 m cell size needs 2·10^6 cells; 2^26 is ~32× that. */
#define PB_DEFAULT_MAX_GRID_CELLS (UINT64_C(1) << 26)
#define PB_MAX_SOLID_RAYS         65536u
#define PB_MAX_THREADS            256u
/* Octree depth is bounded so that every integer coordinate (grid units) fits in uint32. */
#define PB_MAX_LEVELS     30u
#define PB_MAX_AXIS_CELLS (UINT32_C(1) << 30)

/* Geometric tolerance, in units of min_cell_size: boxes are padded by it for the scene-geometry
 * test (a triangle touching a cell face counts as overlapping, also after rounding) and shrunk by
 * it for the volume-surface test (a volume face on a cell face does not make the cell straddle). */
#define PB_BOX_EPS 1e-6

/* Cell flags. */
#define CELL_FULL      1u /* box entirely inside the volumes (no volume triangle crosses it) */
#define CELL_CENTRE_IN 2u /* centre inside the volumes (known) */
#define CELL_PRUNED    4u /* centre inside solid geometry */

/* Classification results of one octree cell. */
enum { CLS_DROP = 0, CLS_LEAF = 1, CLS_SPLIT = 2 };

/* Grid marker while filling: inside the volumes, probe still to be chosen (nearest). */
#define GRID_NEAREST (-2)

typedef struct oct_cell {
    uint32_t x, y, z; /* min corner, grid units */
    uint8_t lg;       /* edge = 2^lg grid units */
    uint8_t flags;
} oct_cell;

typedef struct oct_ctx {
    const pb_placement_desc *desc;
    pb_error *err;

    /* Settings after defaults. */
    double min_cell, solid_ratio;
    uint32_t solid_rays, threads;
    uint64_t max_cells;

    /* Frame and grid. */
    double centre[3];     /* absolute centre of the volumes' bounding box */
    double bbmin[3];      /* absolute min corner = grid origin */
    double origin_rel[3]; /* grid origin relative to centre */
    uint32_t dims[3];
    uint32_t root_lg; /* root cell edge = 2^root_lg grid units */
    double eps;       /* PB_BOX_EPS · min_cell, metres */

    /* Occluders (pb_occluder.h): the volumes, the scene geometry (NULL without triangles) and,
     * for the last stage, the probe points. */
    pb_occluder *vol, *geo;
    pb_point_index *probe_index;

    float (*ray_dirs)[3];

    /* Progress. */
    atomic_bool cancel;
    double last_report; /* monotonic seconds */
} oct_ctx;

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
static bool report(oct_ctx *c, double fraction, const char *stage, bool force)
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

static pb_result cancelled(oct_ctx *c, const char *stage)
{
    return pb_error_set(c->err, PB_ERROR_CANCELLED, "probe placement cancelled during %s", stage);
}

/* The first Embree error any occluder of the call met, as a pb_error. */
static pb_result embree_check(oct_ctx *c, const char *what)
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
        if (main_thread) report(j->c, p0 + (p1 - p0) * (double)done / (double)j->count, stage, false);
    }
}

static void *par_worker(void *arg)
{
    par_run_chunks((par_job *)arg, false, 0, 0, NULL);
    return NULL;
}

/* Returns false when cancelled. */
static bool parallel_for(oct_ctx *c, uint64_t count, uint64_t chunk, range_fn fn, void *user, double p0, double p1,
                         const char *stage)
{
    if (!report(c, p0, stage, true)) return false;
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
    return report(c, p1, stage, true);
}

/* ---------------------------------------------------------------------------------------------- */
/* Queries                                                                                          */

static bool box_touches_geometry(const oct_ctx *c, const double centre[3], double h)
{
    return pb_occluder_box_overlaps(c->geo, centre, h + c->eps, c->eps);
}

static bool box_straddles_volumes(const oct_ctx *c, const double centre[3], double h)
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

static bool point_inside(const oct_ctx *c, const double p[3])
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

/* Relative coordinates of a cell: centre and half edge. */
static inline void cell_geometry(const oct_ctx *c, uint64_t x, uint64_t y, uint64_t z, uint32_t lg, double centre[3],
                                 double *h)
{
    double edge = c->min_cell * (double)(UINT64_C(1) << lg);
    *h = 0.5 * edge;
    centre[0] = c->origin_rel[0] + (double)x * c->min_cell + *h;
    centre[1] = c->origin_rel[1] + (double)y * c->min_cell + *h;
    centre[2] = c->origin_rel[2] + (double)z * c->min_cell + *h;
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

static pb_result setup(oct_ctx *c)
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
    c->solid_rays = d->solid_ray_count == 0 ? PB_DEFAULT_SOLID_RAYS : d->solid_ray_count;
    if (c->solid_rays > PB_MAX_SOLID_RAYS)
        return pb_error_set(c->err, PB_ERROR_INVALID_ARGUMENT, "solid_ray_count %u is above the maximum of %u",
                            c->solid_rays, PB_MAX_SOLID_RAYS);
    c->solid_ratio = d->solid_backface_ratio == 0 ? PB_DEFAULT_BACKFACE_RATIO : d->solid_backface_ratio;
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
        if (!report(c, 0.05 * (i + 1) / d->volume_count, "checking meshes", false))
            return cancelled(c, "checking meshes");
    }

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

/* ---------------------------------------------------------------------------------------------- */
/* Stage 2: occluders                                                                              */

/* An occluder of `count` meshes, positions relative to the volumes' centre. */
static pb_result build_occluder(oct_ctx *c, const pb_mesh_desc *meshes, uint32_t count, uint32_t flags,
                                const char *what, pb_occluder **out)
{
    pb_occluder_mesh *om = calloc((size_t)count + 1, sizeof *om);
    if (!om) return pb_error_set(c->err, PB_ERROR_OUT_OF_MEMORY, "out of memory creating a scene");
    for (uint32_t i = 0; i < count; i++) {
        om[i].positions = meshes[i].positions;
        om[i].indices = meshes[i].indices;
        om[i].vertex_count = meshes[i].vertex_count;
        om[i].triangle_count = meshes[i].triangle_count;
    }
    pb_occluder_desc d = {0};
    d.meshes = om;
    d.mesh_count = count;
    memcpy(d.origin, c->centre, sizeof d.origin);
    d.thread_count = c->threads;
    d.flags = flags;
    d.what = what;
    pb_result r = pb_occluder_create(&d, out, c->err);
    free(om);
    return r;
}

/* ---------------------------------------------------------------------------------------------- */
/* Stage 3: octree                                                                                  */

typedef struct classify_job {
    const oct_cell *cells;
    uint8_t *result; /* CLS_* */
    uint8_t *flags;  /* flags for the leaf or the children */
} classify_job;

static void classify_range(oct_ctx *c, void *user, uint64_t begin, uint64_t end)
{
    classify_job *j = (classify_job *)user;
    for (uint64_t i = begin; i < end; i++) {
        const oct_cell *cell = &j->cells[i];
        double ctr[3], h;
        cell_geometry(c, cell->x, cell->y, cell->z, cell->lg, ctr, &h);
        uint8_t flags = cell->flags & CELL_FULL;
        if (!flags) {
            if (!box_straddles_volumes(c, ctr, h)) {
                if (!point_inside(c, ctr)) {
                    j->result[i] = CLS_DROP;
                    continue;
                }
                flags = CELL_FULL | CELL_CENTRE_IN;
            }
        } else {
            flags |= CELL_CENTRE_IN;
        }
        if (cell->lg > 0 && box_touches_geometry(c, ctr, h)) {
            j->result[i] = CLS_SPLIT;
            j->flags[i] = flags & CELL_FULL;
            continue;
        }
        if (!(flags & CELL_FULL)) {
            /* Straddles the volume surface: a centre outside would leave the inside part without a
             * probe, so such a cell subdivides. */
            if (point_inside(c, ctr)) {
                flags |= CELL_CENTRE_IN;
            } else if (cell->lg > 0) {
                j->result[i] = CLS_SPLIT;
                j->flags[i] = 0;
                continue;
            }
        }
        j->result[i] = CLS_LEAF;
        j->flags[i] = flags;
    }
}

/* Morton order of integer points (Chan's most-significant-differing-bit comparison); z is the most
 * significant axis, x the least. Sorting the leaves' min corners this way numbers the probes in
 * depth-first octree order. */
static inline bool less_msb(uint32_t a, uint32_t b) { return a < b && a < (a ^ b); }

static int cmp_cell_morton(const void *pa, const void *pb)
{
    const oct_cell *a = (const oct_cell *)pa, *b = (const oct_cell *)pb;
    uint32_t ka[3] = {a->x, a->y, a->z}, kb[3] = {b->x, b->y, b->z};
    int ms = 0;
    for (int d = 1; d < 3; d++) {
        if (!less_msb(ka[d] ^ kb[d], ka[ms] ^ kb[ms])) ms = d;
    }
    return ka[ms] < kb[ms] ? -1 : ka[ms] > kb[ms];
}

typedef struct cell_vec {
    oct_cell *v;
    size_t n, cap;
} cell_vec;

static bool cell_vec_reserve(cell_vec *a, size_t n)
{
    if (n <= a->cap) return true;
    size_t cap = a->cap ? a->cap : 1024;
    while (cap < n) {
        if (cap > SIZE_MAX / 2 / sizeof(oct_cell)) return false;
        cap *= 2;
    }
    oct_cell *v = realloc(a->v, cap * sizeof *v);
    if (!v) return false;
    a->v = v;
    a->cap = cap;
    return true;
}

static pb_result build_octree(oct_ctx *c, cell_vec *leaves)
{
    cell_vec cur = {0}, next = {0};
    uint8_t *res = NULL, *flg = NULL;
    pb_result r = PB_SUCCESS;
    uint32_t root_units = UINT32_C(1) << c->root_lg;
    uint64_t roots[3];
    for (int a = 0; a < 3; a++) roots[a] = (c->dims[a] + (uint64_t)root_units - 1) / root_units;
    /* Root count ≤ grid cells ≤ max_grid_cells (checked), so this fits. */
    size_t nroot = (size_t)(roots[0] * roots[1] * roots[2]);
    if (!cell_vec_reserve(&cur, nroot)) {
        r = pb_error_set(c->err, PB_ERROR_OUT_OF_MEMORY, "out of memory for %zu octree root cells", nroot);
        goto done;
    }
    for (uint64_t z = 0; z < roots[2]; z++)
        for (uint64_t y = 0; y < roots[1]; y++)
            for (uint64_t x = 0; x < roots[0]; x++) {
                oct_cell *cell = &cur.v[cur.n++];
                cell->x = (uint32_t)(x * root_units);
                cell->y = (uint32_t)(y * root_units);
                cell->z = (uint32_t)(z * root_units);
                cell->lg = (uint8_t)c->root_lg;
                cell->flags = 0;
            }

    const double p0 = 0.10, p1 = 0.45;
    for (int32_t lg = (int32_t)c->root_lg; lg >= 0 && cur.n > 0; lg--) {
        double f0 = p0 + (p1 - p0) * (double)(c->root_lg - (uint32_t)lg) / (c->root_lg + 1);
        double f1 = p0 + (p1 - p0) * (double)(c->root_lg - (uint32_t)lg + 1) / (c->root_lg + 1);
        free(res);
        free(flg);
        res = malloc(cur.n);
        flg = malloc(cur.n);
        if (!res || !flg) {
            r = pb_error_set(c->err, PB_ERROR_OUT_OF_MEMORY, "out of memory for %zu octree cells", cur.n);
            goto done;
        }
        classify_job job = {cur.v, res, flg};
        if (!parallel_for(c, cur.n, 256, classify_range, &job, f0, f1, "octree")) {
            r = cancelled(c, "the octree build");
            goto done;
        }
        size_t nsplit = 0, nleaf = 0;
        for (size_t i = 0; i < cur.n; i++) {
            nsplit += res[i] == CLS_SPLIT;
            nleaf += res[i] == CLS_LEAF;
        }
        if (!cell_vec_reserve(leaves, leaves->n + nleaf) || (nsplit && !cell_vec_reserve(&next, 8 * nsplit))) {
            r = pb_error_set(c->err, PB_ERROR_OUT_OF_MEMORY, "out of memory for the octree (%zu cells)",
                             leaves->n + nleaf + 8 * nsplit);
            goto done;
        }
        next.n = 0;
        uint32_t half = lg > 0 ? UINT32_C(1) << (lg - 1) : 0;
        for (size_t i = 0; i < cur.n; i++) {
            const oct_cell *cell = &cur.v[i];
            if (res[i] == CLS_LEAF) {
                oct_cell *l = &leaves->v[leaves->n++];
                *l = *cell;
                l->flags = flg[i];
            } else if (res[i] == CLS_SPLIT) {
                for (uint32_t o = 0; o < 8; o++) {
                    uint32_t x = cell->x + ((o & 1u) ? half : 0);
                    uint32_t y = cell->y + ((o & 2u) ? half : 0);
                    uint32_t z = cell->z + ((o & 4u) ? half : 0);
                    /* Children past the grid lie outside the volumes' bounding box. */
                    if (x >= c->dims[0] || y >= c->dims[1] || z >= c->dims[2]) continue;
                    oct_cell *ch = &next.v[next.n++];
                    ch->x = x;
                    ch->y = y;
                    ch->z = z;
                    ch->lg = (uint8_t)(lg - 1);
                    ch->flags = flg[i] & CELL_FULL;
                }
            }
        }
        cell_vec t = cur;
        cur = next;
        next = t;
    }
    qsort(leaves->v, leaves->n, sizeof *leaves->v, cmp_cell_morton);
done:
    free(res);
    free(flg);
    free(cur.v);
    free(next.v);
    return r;
}

/* ---------------------------------------------------------------------------------------------- */
/* Stage 4: solid test                                                                              */

typedef struct solid_job {
    oct_cell *leaves;
    float *ratio;
} solid_job;

/* Back-face hits and hits of the solid test's rays from `ctr` (relative coordinates). */
static void solid_count(oct_ctx *c, const double ctr[3], uint32_t *hits_out, uint32_t *back_out)
{
    pb_occluder_backface_count(c->geo, ctr, (const float(*)[3])c->ray_dirs, c->solid_rays, hits_out, back_out);
}

static void solid_range(oct_ctx *c, void *user, uint64_t begin, uint64_t end)
{
    solid_job *j = (solid_job *)user;
    for (uint64_t i = begin; i < end; i++) {
        oct_cell *leaf = &j->leaves[i];
        j->ratio[i] = 0.0f;
        if (!(leaf->flags & CELL_CENTRE_IN) || !c->geo) continue;
        double ctr[3], h;
        cell_geometry(c, leaf->x, leaf->y, leaf->z, leaf->lg, ctr, &h);
        uint32_t hits = 0, back = 0;
        solid_count(c, ctr, &hits, &back);
        float ratio = hits ? (float)back / (float)hits : 0.0f;
        j->ratio[i] = ratio;
        if ((double)back > c->solid_ratio * (double)hits) leaf->flags |= CELL_PRUNED;
    }
}

/* ---------------------------------------------------------------------------------------------- */
/* Stage 5: occupancy grid                                                                          */

typedef struct grid_job {
    const oct_cell *leaves;
    const int32_t *leaf_probe; /* probe index or −1 */
    int32_t *grid;
} grid_job;

static void grid_write_box(const oct_ctx *c, int32_t *grid, uint64_t x0, uint64_t y0, uint64_t z0, uint64_t n,
                           int32_t value)
{
    uint64_t x1 = x0 + n < c->dims[0] ? x0 + n : c->dims[0];
    uint64_t y1 = y0 + n < c->dims[1] ? y0 + n : c->dims[1];
    uint64_t z1 = z0 + n < c->dims[2] ? z0 + n : c->dims[2];
    size_t X = c->dims[0], XY = (size_t)c->dims[0] * c->dims[1];
    for (uint64_t z = z0; z < z1; z++)
        for (uint64_t y = y0; y < y1; y++)
            for (uint64_t x = x0; x < x1; x++) grid[x + y * X + z * XY] = value;
}

/* Fills the part of a leaf that straddles the volume surface: sub-boxes no volume triangle crosses
 * are classified by their centre, the others split down to single grid cells. */
static void grid_fill_straddling(const oct_ctx *c, int32_t *grid, uint64_t x, uint64_t y, uint64_t z, uint32_t lg,
                                 int32_t inside_value)
{
    if (x >= c->dims[0] || y >= c->dims[1] || z >= c->dims[2]) return;
    double ctr[3], h;
    cell_geometry(c, x, y, z, lg, ctr, &h);
    if (lg == 0 || !box_straddles_volumes(c, ctr, h)) {
        grid_write_box(c, grid, x, y, z, UINT64_C(1) << lg, point_inside(c, ctr) ? inside_value : -1);
        return;
    }
    uint64_t half = UINT64_C(1) << (lg - 1);
    for (uint32_t o = 0; o < 8; o++)
        grid_fill_straddling(c, grid, x + ((o & 1u) ? half : 0), y + ((o & 2u) ? half : 0), z + ((o & 4u) ? half : 0),
                             lg - 1, inside_value);
}

static void grid_range(oct_ctx *c, void *user, uint64_t begin, uint64_t end)
{
    grid_job *j = (grid_job *)user;
    for (uint64_t i = begin; i < end; i++) {
        const oct_cell *leaf = &j->leaves[i];
        int32_t probe = j->leaf_probe[i];
        int32_t value = probe >= 0 ? probe : GRID_NEAREST;
        if (leaf->flags & CELL_FULL) {
            grid_write_box(c, j->grid, leaf->x, leaf->y, leaf->z, UINT64_C(1) << leaf->lg, value);
        } else if (leaf->lg == 0) {
            /* A single grid cell: its centre is the leaf centre, already classified. */
            grid_write_box(c, j->grid, leaf->x, leaf->y, leaf->z, 1, (leaf->flags & CELL_CENTRE_IN) ? value : -1);
        } else {
            grid_fill_straddling(c, j->grid, leaf->x, leaf->y, leaf->z, leaf->lg, value);
        }
    }
}

/* ---------------------------------------------------------------------------------------------- */
/* Stage 6: nearest valid probe                                                                    */

typedef struct nearest_job {
    const uint64_t *cells; /* flat grid indices */
    int32_t *grid;
    double slack;
} nearest_job;

static void nearest_range(oct_ctx *c, void *user, uint64_t begin, uint64_t end)
{
    nearest_job *j = (nearest_job *)user;
    uint64_t X = c->dims[0], XY = (uint64_t)c->dims[0] * c->dims[1];
    for (uint64_t i = begin; i < end; i++) {
        uint64_t g = j->cells[i];
        uint64_t z = g / XY, y = (g % XY) / X, x = g % X;
        double p[3], h;
        cell_geometry(c, x, y, z, 0, p, &h);
        double slack = j->slack + 1e-6 * fmax(fabs(p[0]), fmax(fabs(p[1]), fabs(p[2])));
        j->grid[g] = pb_point_index_nearest(c->probe_index, p, slack);
    }
}

/* ---------------------------------------------------------------------------------------------- */
/* Driver                                                                                           */

void pb_placement_destroy(pb_placement *placement)
{
    if (!placement) return;
    free(placement->positions);
    free(placement->cell_sizes);
    free(placement->backface_ratio);
    free(placement->grid);
    free(placement);
}

/* The volumes' occluder (robust, with the crossings of the inside test) and the geometry's (when
 * there is any). */
static pb_result build_scenes(oct_ctx *c)
{
    if (!report(c, 0.05, "building BVH", true)) return cancelled(c, "building BVH");
    pb_result r = build_occluder(c, c->desc->volumes, c->desc->volume_count,
                                 PB_OCCLUDER_FILTERABLE | PB_OCCLUDER_ROBUST, "probe volume", &c->vol);
    if (r) return r;
    bool any_geometry = false;
    for (uint32_t i = 0; i < c->desc->geometry_count; i++) any_geometry |= c->desc->geometry[i].triangle_count > 0;
    if (any_geometry) {
        r = build_occluder(c, c->desc->geometry, c->desc->geometry_count, 0, "scene geometry", &c->geo);
        if (r) return r;
    }
    if (!report(c, 0.10, "building BVH", true)) return cancelled(c, "building BVH");
    return PB_SUCCESS;
}

/* Spherical Fibonacci directions of the solid test (offset by 0.1 rad so that none lies in an axis
 * plane). */
static pb_result make_ray_dirs(oct_ctx *c)
{
    c->ray_dirs = malloc(sizeof *c->ray_dirs * c->solid_rays);
    if (!c->ray_dirs) return pb_error_set(c->err, PB_ERROR_OUT_OF_MEMORY, "out of memory");
    const double golden = 3.14159265358979323846 * (3.0 - sqrt(5.0));
    for (uint32_t k = 0; k < c->solid_rays; k++) {
        double zc = 1.0 - (2.0 * k + 1.0) / c->solid_rays, rr = sqrt(fmax(0.0, 1.0 - zc * zc));
        double phi = 0.1 + golden * k;
        c->ray_dirs[k][0] = (float)(rr * cos(phi));
        c->ray_dirs[k][1] = (float)(rr * sin(phi));
        c->ray_dirs[k][2] = (float)zc;
    }
    return PB_SUCCESS;
}

static pb_result place(oct_ctx *c, pb_placement *out)
{
    pb_result r;
    cell_vec leaves = {0};
    float *ratio = NULL;
    int32_t *leaf_probe = NULL;
    double *probe_rel = NULL;
    uint64_t *nearest_cells = NULL;
    int32_t *remap = NULL;
    uint32_t *refs = NULL;

    if (!report(c, 0.0, "checking meshes", true)) return cancelled(c, "checking meshes");
    r = setup(c);
    if (r) return r;
    r = build_scenes(c);
    if (r) return r;

    /* Octree. */
    r = build_octree(c, &leaves);
    if (r) goto done;
    r = embree_check(c, "building the octree");
    if (r) goto done;

    /* Solid test. */
    r = make_ray_dirs(c);
    ratio = malloc(sizeof *ratio * (leaves.n + 1));
    leaf_probe = malloc(sizeof *leaf_probe * (leaves.n + 1));
    if (r || !ratio || !leaf_probe) {
        r = pb_error_set(c->err, PB_ERROR_OUT_OF_MEMORY, "out of memory for %zu octree leaves", leaves.n);
        goto done;
    }
    solid_job sj = {leaves.v, ratio};
    if (!parallel_for(c, leaves.n, 64, solid_range, &sj, 0.45, 0.80, "solid test")) {
        r = cancelled(c, "the solid test");
        goto done;
    }

    /* Number the probes in leaf (Morton) order. */
    uint64_t nprobe = 0, npruned = 0;
    for (size_t i = 0; i < leaves.n; i++) {
        leaf_probe[i] = -1;
        if (!(leaves.v[i].flags & CELL_CENTRE_IN)) continue;
        if (leaves.v[i].flags & CELL_PRUNED) {
            npruned++;
            continue;
        }
        if (nprobe >= INT32_MAX) {
            r = pb_error_set(c->err, PB_ERROR_TOO_LARGE, "more than %d probes", INT32_MAX);
            goto done;
        }
        leaf_probe[i] = (int32_t)nprobe++;
    }

    /* Occupancy grid. */
    size_t ncells = (size_t)c->dims[0] * c->dims[1] * c->dims[2];
    out->grid = malloc(sizeof(int32_t) * ncells);
    if (!out->grid) {
        r = pb_error_set(c->err, PB_ERROR_OUT_OF_MEMORY, "out of memory for the occupancy grid (%zu cells)", ncells);
        goto done;
    }
    for (size_t i = 0; i < ncells; i++) out->grid[i] = -1;
    grid_job gj = {leaves.v, leaf_probe, out->grid};
    if (!parallel_for(c, leaves.n, 256, grid_range, &gj, 0.80, 0.95, "occupancy grid")) {
        r = cancelled(c, "filling the occupancy grid");
        goto done;
    }

    /* Probe positions (relative) in probe order. */
    probe_rel = malloc(sizeof(double) * 3 * (nprobe + 1));
    out->cell_sizes = malloc(sizeof(double) * (nprobe + 1));
    out->backface_ratio = malloc(sizeof(float) * (nprobe + 1));
    if (!probe_rel || !out->cell_sizes || !out->backface_ratio) {
        r = pb_error_set(c->err, PB_ERROR_OUT_OF_MEMORY, "out of memory for %llu probes", (unsigned long long)nprobe);
        goto done;
    }
    for (size_t i = 0; i < leaves.n; i++) {
        int32_t p = leaf_probe[i];
        if (p < 0) continue;
        double h;
        cell_geometry(c, leaves.v[i].x, leaves.v[i].y, leaves.v[i].z, leaves.v[i].lg, &probe_rel[3 * (size_t)p], &h);
        out->cell_sizes[p] = 2.0 * h;
        out->backface_ratio[p] = ratio[i];
    }

    /* Cells whose leaf has no valid probe: nearest valid probe. */
    size_t nnear = 0;
    for (size_t i = 0; i < ncells; i++) nnear += out->grid[i] == GRID_NEAREST;
    if (nnear > 0) {
        if (nprobe == 0) {
            r = pb_error_set(c->err, PB_ERROR_INVALID_ARGUMENT,
                             "no probe could be placed: all %llu candidate positions inside the "
                             "probe volumes are inside solid geometry (more than %.0f %% of their "
                             "rays hit back faces); check the volumes and the normals of the scene",
                             (unsigned long long)npruned, 100.0 * c->solid_ratio);
            goto done;
        }
        nearest_cells = malloc(sizeof *nearest_cells * nnear);
        if (!nearest_cells) {
            r = pb_error_set(c->err, PB_ERROR_OUT_OF_MEMORY, "out of memory for %zu grid cells", nnear);
            goto done;
        }
        for (size_t i = 0, k = 0; i < ncells; i++)
            if (out->grid[i] == GRID_NEAREST) nearest_cells[k++] = i;
        r = pb_point_index_create(probe_rel, (uint32_t)nprobe, c->eps, c->threads, &c->probe_index, c->err);
        if (r) goto done;
        nearest_job nj = {nearest_cells, out->grid, c->eps};
        if (!parallel_for(c, nnear, 1024, nearest_range, &nj, 0.95, 0.99, "nearest probe")) {
            r = cancelled(c, "the nearest-probe search");
            goto done;
        }
        r = embree_check(c, "searching the nearest probes");
        if (r) goto done;
    }

    /* Every probe must be referenced by the grid; a probe whose leaf has no grid-cell centre inside
     * the volumes (a sliver of volume thinner than a grid cell) is dropped. */
    refs = calloc(nprobe + 1, sizeof *refs);
    remap = malloc(sizeof *remap * (nprobe + 1));
    if (!refs || !remap) {
        r = pb_error_set(c->err, PB_ERROR_OUT_OF_MEMORY, "out of memory for %llu probes", (unsigned long long)nprobe);
        goto done;
    }
    for (size_t i = 0; i < ncells; i++)
        if (out->grid[i] >= 0) refs[out->grid[i]] = 1;
    uint32_t kept = 0;
    for (uint64_t p = 0; p < nprobe; p++) {
        remap[p] = refs[p] ? (int32_t)kept : -1;
        if (refs[p]) {
            for (int a = 0; a < 3; a++) probe_rel[3 * (size_t)kept + a] = probe_rel[3 * p + a];
            out->cell_sizes[kept] = out->cell_sizes[p];
            out->backface_ratio[kept] = out->backface_ratio[p];
            kept++;
        }
    }
    if (kept == 0) {
        r = pb_error_set(c->err, PB_ERROR_INVALID_ARGUMENT,
                         "no probe could be placed: no occupancy-grid cell centre (spacing %g m) lies "
                         "inside the probe volumes; are the volumes thinner than Min Cell Size?",
                         c->min_cell);
        goto done;
    }
    if (kept > PB_SHPROBE_MAX_PROBES) {
        r = pb_error_set(c->err, PB_ERROR_TOO_LARGE,
                         "%u probes are above the limit of %u probes a .shprobe file holds; use a larger Min "
                         "Cell Size or smaller probe volumes",
                         kept, PB_SHPROBE_MAX_PROBES);
        goto done;
    }
    if (kept != nprobe)
        for (size_t i = 0; i < ncells; i++)
            if (out->grid[i] >= 0) out->grid[i] = remap[out->grid[i]];

    out->positions = malloc(sizeof(double) * 3 * kept);
    if (!out->positions) {
        r = pb_error_set(c->err, PB_ERROR_OUT_OF_MEMORY, "out of memory for %u probes", kept);
        goto done;
    }
    for (size_t p = 0; p < kept; p++)
        for (int a = 0; a < 3; a++) out->positions[3 * p + a] = c->centre[a] + probe_rel[3 * p + a];
    out->probe_count = kept;
    for (int a = 0; a < 3; a++) {
        out->grid_dims[a] = c->dims[a];
        out->grid_origin[a] = c->bbmin[a];
    }
    out->grid_spacing = c->min_cell;
    out->leaf_count = leaves.n;
    out->pruned_count = npruned;
    if (!report(c, 1.0, "done", true)) r = cancelled(c, "the final step");

done:
    free(leaves.v);
    free(ratio);
    free(leaf_probe);
    free(probe_rel);
    free(nearest_cells);
    free(remap);
    free(refs);
    return r;
}

/* The context of one pb_placement_build / pb_placement_classify call: set up before, and every
 * Embree object, table and lock it gained released after (fields never made stay NULL / false). */
static void ctx_init(oct_ctx *c, const pb_placement_desc *desc, pb_error *err)
{
    c->desc = desc;
    c->err = err;
    atomic_init(&c->cancel, false);
    c->last_report = -1e300;
}

static void ctx_free(oct_ctx *c)
{
    pb_point_index_destroy(c->probe_index);
    pb_occluder_destroy(c->geo);
    pb_occluder_destroy(c->vol);
    free(c->ray_dirs);
    free(c);
}

pb_result pb_placement_build(const pb_placement_desc *desc, pb_placement **out, pb_error *err)
{
    if (out) *out = NULL;
    if (!desc || !out)
        return pb_error_set(err, PB_ERROR_INVALID_ARGUMENT, "pb_placement_build: desc and out must not be NULL");
    oct_ctx *c = calloc(1, sizeof *c);
    pb_placement *p = calloc(1, sizeof *p);
    if (!c || !p) {
        free(c);
        free(p);
        return pb_error_set(err, PB_ERROR_OUT_OF_MEMORY, "out of memory");
    }
    ctx_init(c, desc, err);
    pb_result r = place(c, p);
    ctx_free(c);
    if (r) {
        pb_placement_destroy(p);
        /* The error detail is already set; make sure a code is recorded even if err was NULL. */
        return r;
    }
    *out = p;
    return PB_SUCCESS;
}

/* ---------------------------------------------------------------------------------------------- */
/* Classification of arbitrary points and boxes (corner octree)                                    */

typedef struct classify_points_job {
    const pb_classify_query *q;
} classify_points_job;

static void classify_points_range(oct_ctx *c, void *user, uint64_t begin, uint64_t end)
{
    const pb_classify_query *q = ((classify_points_job *)user)->q;
    for (uint64_t i = begin; i < end; i++) {
        double p[3];
        for (int k = 0; k < 3; k++) p[k] = q->points[3 * i + (uint64_t)k] - c->centre[k];
        if (q->point_inside) q->point_inside[i] = point_inside(c, p) ? 1 : 0;
        if (q->backface_ratio) {
            uint32_t hits = 0, back = 0;
            if (c->geo) solid_count(c, p, &hits, &back);
            q->backface_ratio[i] = hits ? (float)back / (float)hits : 0.0f;
        }
    }
}

static void classify_boxes_range(oct_ctx *c, void *user, uint64_t begin, uint64_t end)
{
    const pb_classify_query *q = ((classify_points_job *)user)->q;
    for (uint64_t i = begin; i < end; i++) {
        const double *b = q->boxes + 4 * i;
        double ctr[3] = {b[0] - c->centre[0], b[1] - c->centre[1], b[2] - c->centre[2]};
        if (box_straddles_volumes(c, ctr, b[3]))
            q->box_class[i] = 2;
        else
            q->box_class[i] = point_inside(c, ctr) ? 1 : 0;
    }
}

static pb_result classify(oct_ctx *c, const pb_classify_query *q)
{
    if (!report(c, 0.0, "checking meshes", true)) return cancelled(c, "checking meshes");
    pb_result r = setup(c);
    if (r) return r;
    for (uint64_t i = 0; q->points && i < 3 * (uint64_t)q->point_count; i++)
        if (!isfinite(q->points[i]))
            return pb_error_set(c->err, PB_ERROR_NON_FINITE, "point %llu coordinate %llu is %g",
                                (unsigned long long)(i / 3), (unsigned long long)(i % 3), q->points[i]);
    for (uint64_t i = 0; q->boxes && i < 4 * (uint64_t)q->box_count; i++)
        if (!isfinite(q->boxes[i]) || (i % 4 == 3 && !(q->boxes[i] > 0)))
            return pb_error_set(c->err, isfinite(q->boxes[i]) ? PB_ERROR_INVALID_ARGUMENT : PB_ERROR_NON_FINITE,
                                "box %llu value %llu is %g (centre finite, half edge > 0)", (unsigned long long)(i / 4),
                                (unsigned long long)(i % 4), q->boxes[i]);
    r = build_scenes(c);
    if (r) return r;
    r = make_ray_dirs(c);
    if (r) return r;
    classify_points_job j = {q};
    if (q->points && (q->point_inside || q->backface_ratio) &&
        !parallel_for(c, q->point_count, 64, classify_points_range, &j, 0.10, 0.80, "classifying"))
        return cancelled(c, "classifying");
    if (q->boxes && q->box_class &&
        !parallel_for(c, q->box_count, 64, classify_boxes_range, &j, 0.80, 1.0, "classifying"))
        return cancelled(c, "classifying");
    r = embree_check(c, "classifying");
    if (r) return r;
    report(c, 1.0, "done", true);
    return PB_SUCCESS;
}

pb_result pb_placement_classify(const pb_placement_desc *desc, const pb_classify_query *query, pb_error *err)
{
    if (!desc || !query)
        return pb_error_set(err, PB_ERROR_INVALID_ARGUMENT, "pb_placement_classify: desc and query must not be NULL");
    if ((query->point_count && !query->points) || (query->box_count && !query->boxes))
        return pb_error_set(err, PB_ERROR_INVALID_ARGUMENT, "pb_placement_classify: NULL points or boxes");
    oct_ctx *c = calloc(1, sizeof *c);
    if (!c) return pb_error_set(err, PB_ERROR_OUT_OF_MEMORY, "out of memory");
    ctx_init(c, desc, err);
    pb_result r = classify(c, query);
    ctx_free(c);
    return r;
}
