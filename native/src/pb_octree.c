/* Probe placement: sparse adaptive octree over the union of closed probe volumes (DESIGN.md §6,
 * docs/placement.md).
 *
 * Stages (each reported through the progress callback, each cancellable):
 *   1. "checking meshes"  validate inputs, edge-manifold check of every volume, grid size/limits
 *                         (pb_placement_ctx.c).
 *   2. "building BVH"     two occluders (pb_occluder.h, threads = thread_count): volumes and scene
 *                         geometry (pb_placement_ctx.c); later a point index of the probes.
 *   3. "octree"           level by level from root cells of max_cell_size (rounded down to
 *                         min·2^k) aligned to the occupancy grid; a cell subdivides while its box
 *                         touches a scene triangle (exact SAT, candidates from a point query with
 *                         the box's bounding sphere) or straddles the volume surface with its
 *                         centre outside the volumes; cells entirely outside are dropped.
 *   4. "solid test"       fixed spherical-Fibonacci rays from each leaf centre inside the volumes;
 *                         more than solid_backface_ratio back-face hits → pruned (pb_solid.c).
 *   5. "occupancy grid"   every grid cell whose centre is inside the volumes gets its leaf's probe.
 *   6. "nearest probe"    grid cells whose leaf has no valid probe get the nearest valid probe
 *                         (pb_point_index over the probe points).
 * This file holds stages 3, 5 and 6 and the driver; pb_placement_internal.h lists the others.
 *
 * Precision: every input position is used relative to the centre of the volumes' bounding box,
 * computed in double; Embree sees floats of those relative positions (exact enough for candidate
 * search and rays), while the box-triangle tests and all outputs use doubles.
 *
 * Determinism: the result does not depend on the thread count or on Embree's traversal order:
 * per-item results go to per-item slots, probes are numbered in Morton order of their leaf cells,
 * and the nearest-probe search breaks distance ties by the smaller probe index.
 */
#include "pb_placement_internal.h"

#include "schnee/pb_shprobe.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>

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
            if (!pb_oct_box_straddles_volumes(c, ctr, h)) {
                if (!pb_oct_point_inside(c, ctr)) {
                    j->result[i] = CLS_DROP;
                    continue;
                }
                flags = CELL_FULL | CELL_CENTRE_IN;
            }
        } else {
            flags |= CELL_CENTRE_IN;
        }
        if (cell->lg > 0 && pb_oct_box_touches_geometry(c, ctr, h)) {
            j->result[i] = CLS_SPLIT;
            j->flags[i] = flags & CELL_FULL;
            continue;
        }
        if (!(flags & CELL_FULL)) {
            /* Straddles the volume surface: a centre outside would leave the inside part without a
             * probe, so such a cell subdivides. */
            if (pb_oct_point_inside(c, ctr)) {
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
        if (!pb_oct_parallel_for(c, cur.n, 256, classify_range, &job, f0, f1, "octree")) {
            r = pb_oct_cancelled(c, "the octree build");
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
    if (lg == 0 || !pb_oct_box_straddles_volumes(c, ctr, h)) {
        grid_write_box(c, grid, x, y, z, UINT64_C(1) << lg, pb_oct_point_inside(c, ctr) ? inside_value : -1);
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

/* Probe numbers in leaf (Morton) order: leaf_probe[i] = the probe of leaf i, −1 for a leaf whose
 * centre is outside the volumes or pruned (counted in *npruned). */
static pb_result number_probes(oct_ctx *c, const cell_vec *leaves, int32_t *leaf_probe, uint64_t *nprobe_out,
                               uint64_t *npruned_out)
{
    uint64_t nprobe = 0, npruned = 0;
    for (size_t i = 0; i < leaves->n; i++) {
        leaf_probe[i] = -1;
        if (!(leaves->v[i].flags & CELL_CENTRE_IN)) continue;
        if (leaves->v[i].flags & CELL_PRUNED) {
            npruned++;
            continue;
        }
        if (nprobe >= INT32_MAX) return pb_error_set(c->err, PB_ERROR_TOO_LARGE, "more than %d probes", INT32_MAX);
        leaf_probe[i] = (int32_t)nprobe++;
    }
    *nprobe_out = nprobe;
    *npruned_out = npruned;
    return PB_SUCCESS;
}

/* Stage 6 over the whole grid: cells marked GRID_NEAREST get the nearest of the nprobe probes. */
static pb_result fill_nearest(oct_ctx *c, int32_t *grid, size_t ncells, const double *probe_rel, uint64_t nprobe,
                              uint64_t npruned)
{
    size_t nnear = 0;
    for (size_t i = 0; i < ncells; i++) nnear += grid[i] == GRID_NEAREST;
    if (nnear == 0) return PB_SUCCESS;
    if (nprobe == 0)
        return pb_error_set(c->err, PB_ERROR_INVALID_ARGUMENT,
                            "no probe could be placed: all %llu candidate positions inside the "
                            "probe volumes are inside solid geometry (more than %.0f %% of their "
                            "rays hit back faces); check the volumes and the normals of the scene",
                            (unsigned long long)npruned, 100.0 * c->solid_ratio);
    uint64_t *nearest_cells = malloc(sizeof *nearest_cells * nnear);
    if (!nearest_cells) return pb_error_set(c->err, PB_ERROR_OUT_OF_MEMORY, "out of memory for %zu grid cells", nnear);
    for (size_t i = 0, k = 0; i < ncells; i++)
        if (grid[i] == GRID_NEAREST) nearest_cells[k++] = i;
    pb_result r = pb_point_index_create(probe_rel, (uint32_t)nprobe, c->eps, c->threads, &c->probe_index, c->err);
    if (!r) {
        nearest_job nj = {nearest_cells, grid, c->eps};
        if (!pb_oct_parallel_for(c, nnear, 1024, nearest_range, &nj, 0.95, 0.99, "nearest probe"))
            r = pb_oct_cancelled(c, "the nearest-probe search");
        else
            r = pb_oct_occluder_check(c, "searching the nearest probes");
    }
    free(nearest_cells);
    return r;
}

/* Every probe must be referenced by the grid; a probe whose leaf has no grid-cell centre inside
 * the volumes (a sliver of volume thinner than a grid cell) is dropped: the probe arrays are
 * compacted and the grid renumbered. *kept_out = the probes left. */
static pb_result drop_unreferenced(oct_ctx *c, pb_placement *out, double *probe_rel, uint64_t nprobe, size_t ncells,
                                   uint32_t *kept_out)
{
    uint32_t *refs = calloc(nprobe + 1, sizeof *refs);
    int32_t *remap = malloc(sizeof *remap * (nprobe + 1));
    pb_result r = PB_SUCCESS;
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
    *kept_out = kept;
done:
    free(refs);
    free(remap);
    return r;
}

static pb_result place(oct_ctx *c, pb_placement *out)
{
    pb_result r;
    cell_vec leaves = {0};
    float *ratio = NULL;
    int32_t *leaf_probe = NULL;
    double *probe_rel = NULL;

    if (!pb_oct_report(c, 0.0, "checking meshes", true)) return pb_oct_cancelled(c, "checking meshes");
    r = pb_oct_setup(c);
    if (r) return r;
    r = pb_oct_build_scenes(c);
    if (r) return r;

    /* Octree. */
    r = build_octree(c, &leaves);
    if (r) goto done;
    r = pb_oct_occluder_check(c, "building the octree");
    if (r) goto done;

    /* Solid test. */
    r = pb_oct_make_ray_dirs(c);
    ratio = malloc(sizeof *ratio * (leaves.n + 1));
    leaf_probe = malloc(sizeof *leaf_probe * (leaves.n + 1));
    if (r || !ratio || !leaf_probe) {
        r = pb_error_set(c->err, PB_ERROR_OUT_OF_MEMORY, "out of memory for %zu octree leaves", leaves.n);
        goto done;
    }
    solid_job sj = {leaves.v, ratio};
    if (!pb_oct_parallel_for(c, leaves.n, 64, pb_oct_solid_range, &sj, 0.45, 0.80, "solid test")) {
        r = pb_oct_cancelled(c, "the solid test");
        goto done;
    }
    uint64_t nprobe = 0, npruned = 0;
    r = number_probes(c, &leaves, leaf_probe, &nprobe, &npruned);
    if (r) goto done;

    /* Occupancy grid. */
    size_t ncells = (size_t)c->dims[0] * c->dims[1] * c->dims[2];
    out->grid = malloc(sizeof(int32_t) * ncells);
    if (!out->grid) {
        r = pb_error_set(c->err, PB_ERROR_OUT_OF_MEMORY, "out of memory for the occupancy grid (%zu cells)", ncells);
        goto done;
    }
    for (size_t i = 0; i < ncells; i++) out->grid[i] = -1;
    grid_job gj = {leaves.v, leaf_probe, out->grid};
    if (!pb_oct_parallel_for(c, leaves.n, 256, grid_range, &gj, 0.80, 0.95, "occupancy grid")) {
        r = pb_oct_cancelled(c, "filling the occupancy grid");
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

    /* Cells whose leaf has no valid probe: nearest valid probe; then only the referenced probes. */
    r = fill_nearest(c, out->grid, ncells, probe_rel, nprobe, npruned);
    if (r) goto done;
    uint32_t kept = 0;
    r = drop_unreferenced(c, out, probe_rel, nprobe, ncells, &kept);
    if (r) goto done;

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
    if (!pb_oct_report(c, 1.0, "done", true)) r = pb_oct_cancelled(c, "the final step");

done:
    free(leaves.v);
    free(ratio);
    free(leaf_probe);
    free(probe_rel);
    return r;
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
    pb_oct_ctx_init(c, desc, err);
    pb_result r = place(c, p);
    pb_oct_ctx_free(c);
    if (r) {
        pb_placement_destroy(p);
        /* The error detail is already set; make sure a code is recorded even if err was NULL. */
        return r;
    }
    *out = p;
    return PB_SUCCESS;
}
