/* Benchmark of probe placement (pb_placement_build): a 48 m × 12 m × 48 m hall (walls, floor and
 * ceiling as 0.2 m boxes) holding randomly placed icospheres (1280 triangles each, radius 0.3–1.5 m)
 * up to ~1M scene triangles, at the default cell sizes (0.5 m / 16 m). Prints the time of each stage
 * (taken from the progress callback's stage changes) and the counts.
 *
 *   build/native/bench_octree [threads=2] [triangles=1000000] [min_cell=0.5]
 *   build/native/bench_octree [threads=2] 10000,100000,300000,1000000 [min_cell=0.5]
 *
 * A comma-separated triangle list is a sweep: one scene and one placement per count, in one run,
 * printed as a Markdown table (stage seconds, process CPU seconds, probes, pruned leaf centres).
 * "solid test" is the pruning stage (leaf centres inside solid geometry are dropped).
 *
 * Results: bench/results/octree.md. Deterministic input (fixed xorshift seed).
 */
#include "schnee/pb_octree.h"

#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/resource.h>
#include <time.h>

static double now(void)
{
    struct timespec ts;
    clock_gettime(CLOCK_MONOTONIC, &ts);
    return (double)ts.tv_sec + 1e-9 * (double)ts.tv_nsec;
}

typedef struct mesh {
    double *pos;
    uint32_t *idx;
    uint32_t nv, nt, cap_v, cap_t;
} mesh;

static void *xrealloc(void *p, size_t n)
{
    void *q = realloc(p, n);
    if (!q) {
        fprintf(stderr, "out of memory\n");
        exit(2);
    }
    return q;
}

static uint32_t vtx(mesh *m, double x, double y, double z)
{
    if (m->nv == m->cap_v) {
        m->cap_v = m->cap_v ? 2 * m->cap_v : 1024;
        m->pos = xrealloc(m->pos, sizeof(double) * 3 * m->cap_v);
    }
    m->pos[3 * m->nv] = x;
    m->pos[3 * m->nv + 1] = y;
    m->pos[3 * m->nv + 2] = z;
    return m->nv++;
}

static void tri(mesh *m, uint32_t a, uint32_t b, uint32_t c)
{
    if (m->nt == m->cap_t) {
        m->cap_t = m->cap_t ? 2 * m->cap_t : 1024;
        m->idx = xrealloc(m->idx, sizeof(uint32_t) * 3 * m->cap_t);
    }
    m->idx[3 * m->nt] = a;
    m->idx[3 * m->nt + 1] = b;
    m->idx[3 * m->nt + 2] = c;
    m->nt++;
}

static void box(mesh *m, double x0, double y0, double z0, double x1, double y1, double z1)
{
    uint32_t v[8];
    for (int i = 0; i < 8; i++) v[i] = vtx(m, (i & 1) ? x1 : x0, (i & 2) ? y1 : y0, (i & 4) ? z1 : z0);
    static const int f[6][4] = {{0, 4, 6, 2}, {1, 3, 7, 5}, {0, 1, 5, 4}, {2, 6, 7, 3}, {0, 2, 3, 1}, {4, 5, 7, 6}};
    for (int k = 0; k < 6; k++) {
        tri(m, v[f[k][0]], v[f[k][1]], v[f[k][2]]);
        tri(m, v[f[k][0]], v[f[k][2]], v[f[k][3]]);
    }
}

/* Icosphere triangle, subdivided `level` times, vertices projected on the sphere (outward,
 * counter-clockwise). Vertices are not shared between triangles: the solid test needs no sharing. */
static void sphere_tri(mesh *m, const double c[3], double r, const double a[3], const double b[3], const double d[3],
                       int level)
{
    if (level == 0) {
        uint32_t i0 = vtx(m, c[0] + r * a[0], c[1] + r * a[1], c[2] + r * a[2]);
        uint32_t i1 = vtx(m, c[0] + r * b[0], c[1] + r * b[1], c[2] + r * b[2]);
        uint32_t i2 = vtx(m, c[0] + r * d[0], c[1] + r * d[1], c[2] + r * d[2]);
        tri(m, i0, i1, i2);
        return;
    }
    double ab[3], bd[3], da[3];
    for (int k = 0; k < 3; k++) {
        ab[k] = a[k] + b[k];
        bd[k] = b[k] + d[k];
        da[k] = d[k] + a[k];
    }
    double *vs[3] = {ab, bd, da};
    for (int i = 0; i < 3; i++) {
        double l = sqrt(vs[i][0] * vs[i][0] + vs[i][1] * vs[i][1] + vs[i][2] * vs[i][2]);
        for (int k = 0; k < 3; k++) vs[i][k] /= l;
    }
    sphere_tri(m, c, r, a, ab, da, level - 1);
    sphere_tri(m, c, r, ab, b, bd, level - 1);
    sphere_tri(m, c, r, da, bd, d, level - 1);
    sphere_tri(m, c, r, ab, bd, da, level - 1);
}

static void icosphere(mesh *m, const double c[3], double r, int level)
{
    const double t = (1.0 + sqrt(5.0)) / 2.0;
    double v[12][3] = {{-1, t, 0},  {1, t, 0},  {-1, -t, 0}, {1, -t, 0}, {0, -1, t},  {0, 1, t},
                       {0, -1, -t}, {0, 1, -t}, {t, 0, -1},  {t, 0, 1},  {-t, 0, -1}, {-t, 0, 1}};
    static const int f[20][3] = {{0, 11, 5},  {0, 5, 1},  {0, 1, 7},  {0, 7, 10}, {0, 10, 11}, {1, 5, 9}, {5, 11, 4},
                                 {11, 10, 2}, {10, 7, 6}, {7, 1, 8},  {3, 9, 4},  {3, 4, 2},   {3, 2, 6}, {3, 6, 8},
                                 {3, 8, 9},   {4, 9, 5},  {2, 4, 11}, {6, 2, 10}, {8, 6, 7},   {9, 8, 1}};
    for (int i = 0; i < 12; i++) {
        double l = sqrt(v[i][0] * v[i][0] + v[i][1] * v[i][1] + v[i][2] * v[i][2]);
        for (int k = 0; k < 3; k++) v[i][k] /= l;
    }
    for (int i = 0; i < 20; i++) sphere_tri(m, c, r, v[f[i][0]], v[f[i][1]], v[f[i][2]], level);
}

static double cpu_seconds(void)
{
    struct rusage ru;
    getrusage(RUSAGE_SELF, &ru);
    return (double)ru.ru_utime.tv_sec + 1e-6 * (double)ru.ru_utime.tv_usec + (double)ru.ru_stime.tv_sec +
           1e-6 * (double)ru.ru_stime.tv_usec;
}

static uint64_t rng = 0x9E3779B97F4A7C15ull;
static double urand(void)
{
    rng ^= rng << 13;
    rng ^= rng >> 7;
    rng ^= rng << 17;
    return (double)(rng >> 11) / 9007199254740992.0;
}

typedef struct stage_log {
    char stage[8][32];
    double t[8];
    int n;
} stage_log;

static bool on_progress(void *user, double fraction, const char *stage)
{
    stage_log *s = (stage_log *)user;
    (void)fraction;
    if (s->n == 0 || strcmp(s->stage[s->n - 1], stage) != 0) {
        if (s->n < 8) {
            snprintf(s->stage[s->n], sizeof s->stage[0], "%s", stage);
            s->t[s->n] = now();
            s->n++;
        }
    }
    return true;
}

/* Stages reported as table columns, in the order pb_placement_build reports them. */
static const char *const sweep_stages[] = {"checking meshes", "building BVH",   "octree",
                                           "solid test",      "occupancy grid", "nearest probe"};
#define SWEEP_STAGES (sizeof sweep_stages / sizeof sweep_stages[0])

/* Builds the scene for `target` triangles and places probes once. table = false prints the
 * original per-stage listing, true one Markdown table row. Returns 0 on success. */
static int run_one(uint32_t threads, long target, double min_cell, bool table)
{
    const double W = 48, H = 12, D = 48, T = 0.2;
    rng = 0x9E3779B97F4A7C15ull; /* same spheres, in the same order, for every count */
    mesh vol = {0}, geo = {0};
    box(&vol, 0, 0, 0, W, H, D);
    box(&geo, -T, -T, -T, W + T, 0, D + T);
    box(&geo, -T, H, -T, W + T, H + T, D + T);
    box(&geo, -T, -T, -T, 0, H + T, D + T);
    box(&geo, W, -T, -T, W + T, H + T, D + T);
    box(&geo, -T, -T, -T, W + T, H + T, 0);
    box(&geo, -T, -T, D, W + T, H + T, D + T);
    int spheres = 0;
    while ((long)geo.nt + 1280 <= target) {
        double r = 0.3 + 1.2 * urand();
        double c[3] = {r + (W - 2 * r) * urand(), r + (H - 2 * r) * urand(), r + (D - 2 * r) * urand()};
        icosphere(&geo, c, r, 3);
        spheres++;
    }
    pb_mesh_desc v = {"Hall", vol.pos, vol.nv, vol.idx, vol.nt};
    pb_mesh_desc g = {"Objects", geo.pos, geo.nv, geo.idx, geo.nt};
    stage_log log = {0};
    pb_placement_desc d = {0};
    d.volumes = &v;
    d.volume_count = 1;
    d.geometry = &g;
    d.geometry_count = 1;
    d.min_cell_size = min_cell;
    d.thread_count = threads;
    d.progress = on_progress;
    d.progress_user = &log;
    pb_placement *p = NULL;
    pb_error err = {0};
    double c0 = cpu_seconds();
    double t0 = now();
    pb_result r = pb_placement_build(&d, &p, &err);
    double t1 = now();
    double c1 = cpu_seconds();
    if (r != PB_SUCCESS) {
        fprintf(stderr, "pb_placement_build: %s: %s\n", pb_result_string(r), err.message);
        free(vol.pos);
        free(vol.idx);
        free(geo.pos);
        free(geo.idx);
        return 1;
    }
    if (!table) {
        printf("scene: %u triangles (%d icospheres + hall), %u vertices; threads %u; min cell %g m\n", geo.nt, spheres,
               geo.nv, threads, min_cell);
        printf("result: %u probes, %llu leaves, %llu pruned, grid %u x %u x %u\n", p->probe_count,
               (unsigned long long)p->leaf_count, (unsigned long long)p->pruned_count, p->grid_dims[0], p->grid_dims[1],
               p->grid_dims[2]);
        for (int i = 0; i < log.n; i++) {
            double end = i + 1 < log.n ? log.t[i + 1] : t1;
            if (strcmp(log.stage[i], "done") == 0) continue;
            printf("  %-16s %8.3f s\n", log.stage[i], end - log.t[i]);
        }
        printf("  %-16s %8.3f s\n", "total", t1 - t0);
        printf("  %-16s %8.3f s\n", "process CPU", c1 - c0);
    } else {
        printf("| %u | %u | %llu | %llu |", geo.nt, p->probe_count, (unsigned long long)p->leaf_count,
               (unsigned long long)p->pruned_count);
        for (size_t k = 0; k < SWEEP_STAGES; k++) {
            double sec = -1.0;
            for (int i = 0; i < log.n; i++)
                if (strcmp(log.stage[i], sweep_stages[k]) == 0) sec = (i + 1 < log.n ? log.t[i + 1] : t1) - log.t[i];
            if (sec < 0)
                printf(" — |");
            else
                printf(" %.3f |", sec);
        }
        printf(" **%.3f** | %.3f |\n", t1 - t0, c1 - c0);
        fflush(stdout);
    }
    pb_placement_destroy(p);
    free(vol.pos);
    free(vol.idx);
    free(geo.pos);
    free(geo.idx);
    return 0;
}

int main(int argc, char **argv)
{
    uint32_t threads = argc > 1 ? (uint32_t)atoi(argv[1]) : 2;
    const char *counts = argc > 2 ? argv[2] : "1000000";
    double min_cell = argc > 3 ? atof(argv[3]) : 0.5;
    if (!strchr(counts, ',')) return run_one(threads, atol(counts), min_cell, false);

    printf("threads %u, min cell %g m, max cell 16 m, 64 solid-test rays per leaf centre\n\n", threads, min_cell);
    printf("| triangles | probes | leaves | pruned |");
    for (size_t k = 0; k < SWEEP_STAGES; k++) printf(" %s (s) |", sweep_stages[k]);
    printf(" total wall (s) | process CPU (s) |\n|---|---|---|---|");
    for (size_t k = 0; k < SWEEP_STAGES + 2; k++) printf("---|");
    printf("\n");
    fflush(stdout);
    for (const char *c = counts; *c;) {
        char *end = NULL;
        long n = strtol(c, &end, 10);
        if (end == c || n <= 0) {
            fprintf(stderr, "bad triangle count list: %s\n", counts);
            return 2;
        }
        if (run_one(threads, n, min_cell, true) != 0) return 1;
        c = *end == ',' ? end + 1 : end;
    }
    return 0;
}
